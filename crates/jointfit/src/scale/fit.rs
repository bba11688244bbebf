//! The scale fit: per-group scale factors, every free marker's offset from its scaled
//! generic placement, and each frame's pose, solved together by Levenberg–Marquardt.
//!
//! Unknowns `θ = (g, u, δ, q_1 … q_F)`: `g` one factor per group (or three, per axis), `u`
//! the log of the overall size (only with the anthropometric prior), `δ_j` the offset (m, in
//! its body) of each free marker `j` from `s_b ⊙ c_j` (`c_j` its generic position), `q_f` the
//! coordinates of frame `f`. The model marker is `x_j(θ) = T_b(q_f; s) (s_b ⊙ c_j + δ_j)`,
//! where the body poses `T_b` use the scaled model ([`super::geometry`]). Residual rows:
//!
//! * data: `√w_j (x_j − m_fj)/σ_d` for every present marker of every frame (`w_j` the
//!   marker's weight, 1 unless given);
//! * marker placement prior: `δ_j/σ_j` (the registered marker stays near its generic place);
//!   `σ_j = σ_m` for every marker at first; a marker the fit moves beyond `2σ_j` is taken for a
//!   tracking marker placed anywhere on its segment and its `σ_j` widens to half its offset,
//!   then the fit resumes (up to four rounds: a Huber-like reweighting that keeps landmarks
//!   tight and lets clusters go where the data put them);
//! * anthropometric prior (optional): `(ln g_k − u)/σ_p` for every factor (segment
//!   proportions of the generic model, spread `σ_p`), and with a stature `H`:
//!   `(u − ln(H/H_generic))/σ_H`.
//!
//! `∂x/∂q` is the exact kinematic Jacobian, `∂x/∂δ_j = R_b`, and `∂x/∂g` a forward difference
//! over recompiled scaled models. The covariance of the factors is the inverse normal matrix
//! at the solution (Laplace approximation), inflated by `χ²/dof` when that exceeds 1.

use nalgebra::{DMatrix, DVector, Vector3};

use super::geometry::{scaled_spec, ScaleFactors};
use crate::ik::lm::solve_frame;
use crate::ik::lm::IkWorkspace;
use crate::ik::{seed_frame, IkOptions};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::spec::ModelSpec;
use crate::model::{Model, ModelError};

/// Bodies that share scale factors.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleGroup {
    pub name: String,
    pub bodies: Vec<String>,
    /// Three factors (x, y, z of the bodies' frames) instead of one.
    pub per_axis: bool,
}

/// The anthropometric prior (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizePrior {
    /// Spread of a segment's factor about the overall size (log units, ≈ relative).
    pub proportion_sd: f64,
    /// Subject stature over the generic model's stature, with its spread (log units).
    pub stature: Option<(f64, f64)>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaleOptions {
    pub groups: Vec<ScaleGroup>,
    /// Markers kept at their scaled generic place (OpenSim's `fixed`).
    pub fixed_markers: Vec<String>,
    /// Prior SD of a marker's offset from its scaled generic place (m).
    pub marker_sd: f64,
    /// Assumed SD of a marker sample about the model (m).
    pub noise_sd: f64,
    /// `None`: the pure fit (no anthropometric prior).
    pub prior: Option<SizePrior>,
    pub max_iterations: usize,
    /// Widen the offset prior of markers the data move far (tracking markers; module docs).
    pub robust: bool,
    /// Bodies held at given factors (OpenSim's manual scales), in no group.
    pub fixed_factors: ScaleFactors,
    /// Weights `w_j` of markers' data rows (`√w_j (x_j − m_fj)/σ_d`; 0 leaves the marker's
    /// data out, as OpenSim's marker placer does with a task of weight 0); unnamed: 1.
    pub marker_weights: Vec<(String, f64)>,
}

impl ScaleOptions {
    pub fn new(groups: Vec<ScaleGroup>) -> Self {
        ScaleOptions {
            groups,
            fixed_markers: Vec::new(),
            marker_sd: 0.01,
            noise_sd: 0.005,
            prior: Some(SizePrior {
                proportion_sd: 0.05,
                stature: None,
            }),
            max_iterations: 60,
            robust: true,
            marker_weights: Vec::new(),
            fixed_factors: ScaleFactors::new(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScaleError {
    #[error("the scaled model does not compile: {0}")]
    Model(#[from] ModelError),
    #[error("frame {frame}: {present} model markers have data, at least 4 are needed")]
    TooFewMarkers { frame: usize, present: usize },
    #[error("group {0:?} names body {1:?}, which the model does not have")]
    UnknownBody(String, String),
    #[error("body {0:?} is in two scale groups (or in one and held at given factors)")]
    TwiceGrouped(String),
    #[error(
        "the normal equations are singular: the data and priors leave the factors undetermined"
    )]
    Singular,
}

/// One group's fitted factors with their standard deviations.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GroupFit {
    pub name: String,
    pub bodies: Vec<String>,
    pub factors: [f64; 3],
    pub sd: [f64; 3],
}

/// One registered marker.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MarkerFit {
    pub name: String,
    pub body: String,
    /// Position in the scaled body (m).
    pub position: [f64; 3],
    /// Offset from the scaled generic position (m).
    pub moved: [f64; 3],
    /// RMS distance to the data over the frames it is present in (m; NaN: never present).
    pub rms: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaleFit {
    pub factors: ScaleFactors,
    pub groups: Vec<GroupFit>,
    pub markers: Vec<MarkerFit>,
    /// Coordinates of every frame at the solution.
    pub coords: Vec<Vec<f64>>,
    /// RMS marker distance over every present marker sample (m).
    pub rms: f64,
    /// `exp(u)`: the overall size (anthropometric prior only).
    pub size: Option<f64>,
    pub iterations: usize,
}

struct Layout {
    /// Per group: first unknown and count (1 or 3).
    groups: Vec<(usize, usize)>,
    size: Option<usize>,
    /// Per model marker: first unknown of its δ, if free.
    delta: Vec<Option<usize>>,
    /// Per frame: first unknown of its q.
    q: Vec<usize>,
    n: usize,
}

struct Problem<'a> {
    spec: &'a ModelSpec,
    opts: &'a ScaleOptions,
    targets: &'a [Vec<Vector3<f64>>],
    lay: Layout,
    n_q: usize,
    /// The starting θ; its coordinates anchor the weak pose rows.
    start: Vec<f64>,
    /// Per model marker: the SD of its offset prior (m).
    msd: Vec<f64>,
    /// Per model marker: the weight of its data rows (`ScaleOptions::marker_weights`).
    weight: Vec<f64>,
}

/// SD (rad or m) of the weak rows that hold coordinates no marker determines (a toe joint
/// without toe markers) at their starting values; far wider than any determined one.
const POSE_SD: f64 = 1000.0;

impl Problem<'_> {
    fn factors(&self, th: &[f64]) -> ScaleFactors {
        let mut f = self.opts.fixed_factors.clone();
        for (g, &(at, n)) in self.opts.groups.iter().zip(&self.lay.groups) {
            let s = if n == 3 {
                [th[at], th[at + 1], th[at + 2]]
            } else {
                [th[at]; 3]
            };
            for b in &g.bodies {
                f.insert(b.clone(), s);
            }
        }
        f
    }

    fn model(&self, th: &[f64]) -> Result<Model, ScaleError> {
        let mut spec = scaled_spec(self.spec, &self.factors(th));
        for (m, d) in spec.markers.iter_mut().zip(&self.lay.delta) {
            if let Some(at) = d {
                for k in 0..3 {
                    m.position[k] += th[at + k];
                }
            }
        }
        Ok(Model::compile(&spec)?)
    }

    /// Marker positions of every frame (and, with `dq`, the data Jacobians).
    fn markers(&self, model: &Model, th: &[f64], data: &mut KinData, f: usize, want: Want) {
        let q = &th[self.lay.q[f]..self.lay.q[f] + self.n_q];
        forward_kinematics(model, &model.nominal_params(), q, want, data);
    }

    /// Whether marker `mi`'s sample `m` makes data rows (present, weight above 0).
    fn used(&self, mi: usize, m: &Vector3<f64>) -> bool {
        m.x.is_finite() && self.weight[mi] > 0.0
    }

    fn n_rows(&self) -> usize {
        let data: usize = self
            .targets
            .iter()
            .map(|t| {
                3 * t
                    .iter()
                    .enumerate()
                    .filter(|(mi, m)| self.used(*mi, m))
                    .count()
            })
            .sum();
        let deltas = 3 * self.lay.delta.iter().flatten().count();
        let prior = match &self.opts.prior {
            Some(p) => {
                self.lay.groups.iter().map(|g| g.1).sum::<usize>()
                    + usize::from(p.stature.is_some())
            }
            None => 0,
        };
        data + deltas + prior + self.n_q * self.lay.q.len()
    }

    /// Data rows of every frame; returns `(row, frame, marker)` of each.
    fn data_rows(&self, model: &Model, th: &[f64], rows: &mut Rows) -> Vec<(usize, usize, usize)> {
        let mut data = KinData::new(model);
        let mut out = Vec::new();
        for (f, t) in self.targets.iter().enumerate() {
            let want = if rows.jac { Want::DQ } else { Want::POSITIONS };
            self.markers(model, th, &mut data, f, want);
            for (mi, m) in t.iter().enumerate() {
                if !self.used(mi, m) {
                    continue;
                }
                let scale = self.weight[mi].sqrt() / self.opts.noise_sd;
                let x = data.markers[mi];
                let row = rows.row;
                for k in 0..3 {
                    rows.r[row + k] = (x[k] - m[k]) * scale;
                }
                if rows.jac {
                    let q0 = self.lay.q[f];
                    for c in 0..self.n_q {
                        for k in 0..3 {
                            rows.j[(row + k, q0 + c)] = data.jq[(3 * mi + k, c)] * scale;
                        }
                    }
                    if let Some(at) = self.lay.delta[mi] {
                        let seg = model.markers()[mi].segment;
                        let rot = data.segment_poses[seg.0].rot;
                        for k in 0..3 {
                            for a in 0..3 {
                                rows.j[(row + k, at + a)] = rot[(k, a)] * scale;
                            }
                        }
                    }
                }
                out.push((row, f, mi));
                rows.row += 3;
            }
        }
        out
    }

    /// Marker placement rows `δ_j/σ_j`.
    fn placement_rows(&self, th: &[f64], rows: &mut Rows) {
        for (at, sd) in self.lay.delta.iter().zip(&self.msd) {
            let Some(at) = at else {
                continue;
            };
            for k in 0..3 {
                rows.push(th[at + k] / sd, &[(at + k, 1.0 / sd)]);
            }
        }
    }

    /// Anthropometric rows: proportions about the overall size, and the stature.
    fn size_rows(&self, th: &[f64], rows: &mut Rows) {
        let Some(p) = &self.opts.prior else {
            return;
        };
        let u_at = self.lay.size.expect("a size unknown with the prior");
        let sd = p.proportion_sd;
        for &(at, n) in &self.lay.groups {
            for k in at..at + n {
                rows.push(
                    (th[k].ln() - th[u_at]) / sd,
                    &[(k, 1.0 / (th[k] * sd)), (u_at, -1.0 / sd)],
                );
            }
        }
        if let Some((ratio, s)) = p.stature {
            rows.push((th[u_at] - ratio.ln()) / s, &[(u_at, 1.0 / s)]);
        }
    }

    /// Weak rows holding undetermined coordinates at their starting values.
    fn pose_rows(&self, th: &[f64], rows: &mut Rows) {
        for &at in &self.lay.q {
            let held = th[at..at + self.n_q].iter().zip(&self.start[at..]);
            for (c, (x, x0)) in held.enumerate() {
                rows.push((x - x0) / POSE_SD, &[(at + c, 1.0 / POSE_SD)]);
            }
        }
    }

    /// `∂r/∂g` of the data rows by forward differences over recompiled scaled models.
    fn factor_columns(
        &self,
        th: &[f64],
        data_rows: &[(usize, usize, usize)],
        rows: &mut Rows,
    ) -> Result<(), ScaleError> {
        for &(at, n) in &self.lay.groups {
            for k in at..at + n {
                let h = 1e-6 * th[k].abs().max(1.0);
                let mut t2 = th.to_vec();
                t2[k] += h;
                let m2 = self.model(&t2)?;
                let mut d2 = KinData::new(&m2);
                let mut last = usize::MAX;
                for &(rw, f, mi) in data_rows {
                    if f != last {
                        self.markers(&m2, &t2, &mut d2, f, Want::POSITIONS);
                        last = f;
                    }
                    let scale = self.weight[mi].sqrt() / self.opts.noise_sd;
                    let x = d2.markers[mi];
                    for a in 0..3 {
                        let r2 = (x[a] - self.targets[f][mi][a]) * scale;
                        rows.j[(rw + a, k)] = (r2 - rows.r[rw + a]) / h;
                    }
                }
            }
        }
        Ok(())
    }

    /// Residuals, and with `jac` the Jacobian (module docs).
    fn evaluate(&self, th: &[f64], jac: bool) -> Result<(DVector<f64>, DMatrix<f64>), ScaleError> {
        let nr = self.n_rows();
        let mut rows = Rows {
            r: DVector::zeros(nr),
            j: DMatrix::zeros(if jac { nr } else { 0 }, self.lay.n),
            row: 0,
            jac,
        };
        let model = self.model(th)?;
        let data_rows = self.data_rows(&model, th, &mut rows);
        self.placement_rows(th, &mut rows);
        self.size_rows(th, &mut rows);
        self.pose_rows(th, &mut rows);
        debug_assert_eq!(rows.row, nr);
        if jac {
            self.factor_columns(th, &data_rows, &mut rows)?;
        }
        Ok((rows.r, rows.j))
    }
}

/// Residuals and Jacobian being filled, row by row.
struct Rows {
    r: DVector<f64>,
    j: DMatrix<f64>,
    row: usize,
    jac: bool,
}

impl Rows {
    /// One residual row with its nonzero Jacobian entries `(column, value)`.
    fn push(&mut self, value: f64, entries: &[(usize, f64)]) {
        self.r[self.row] = value;
        if self.jac {
            for &(c, v) in entries {
                self.j[(self.row, c)] = v;
            }
        }
        self.row += 1;
    }
}

/// Prior SDs beyond which a marker's offset marks it as a tracking marker (module docs).
const ROBUST_IN_SD: f64 = 2.0;
/// Rounds of widening.
const ROBUST_ROUNDS: usize = 4;

type Solved = (Vec<f64>, DVector<f64>, DMatrix<f64>, f64, usize);

/// Levenberg–Marquardt from `th` (Marquardt's diagonal scaling).
fn solve(pb: &Problem, mut th: Vec<f64>) -> Result<Solved, ScaleError> {
    let (mut r, mut j) = pb.evaluate(&th, true)?;
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < pb.opts.max_iterations {
        iterations += 1;
        let jt = j.transpose();
        let a = &jt * &j;
        let g = &jt * &r;
        let mut improved = false;
        for _ in 0..12 {
            let mut damped = a.clone();
            for k in 0..damped.nrows() {
                damped[(k, k)] += lambda * a[(k, k)].max(1e-9);
            }
            let Some(ch) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = ch.solve(&(-&g));
            let trial: Vec<f64> = th.iter().zip(step.iter()).map(|(x, d)| x + d).collect();
            if pb
                .lay
                .groups
                .iter()
                .any(|&(at, n)| trial[at..at + n].iter().any(|v| *v <= 0.05))
            {
                lambda *= 4.0;
                continue;
            }
            let (r2, _) = pb.evaluate(&trial, false)?;
            let c2 = r2.norm_squared();
            if c2 < cost {
                let done = (cost - c2) <= 1e-12 * cost.max(1e-30) || step.amax() < 1e-10;
                th = trial;
                cost = c2;
                lambda = (lambda / 3.0).max(1e-12);
                improved = !done;
                let (r3, j3) = pb.evaluate(&th, true)?;
                r = r3;
                j = j3;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }

    Ok((th, r, j, cost, iterations))
}

fn layout(
    spec: &ModelSpec,
    opts: &ScaleOptions,
    n_q: usize,
    frames: usize,
) -> Result<Layout, ScaleError> {
    let mut n = 0;
    let mut groups = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for g in &opts.groups {
        for b in &g.bodies {
            if !spec.segments.iter().any(|s| s.name == *b) {
                return Err(ScaleError::UnknownBody(g.name.clone(), b.clone()));
            }
            if !seen.insert(b.clone()) || opts.fixed_factors.contains_key(b) {
                return Err(ScaleError::TwiceGrouped(b.clone()));
            }
        }
        let k = if g.per_axis { 3 } else { 1 };
        groups.push((n, k));
        n += k;
    }
    let size = opts.prior.map(|_| {
        n += 1;
        n - 1
    });
    let mut delta = Vec::new();
    for m in &spec.markers {
        if opts.fixed_markers.contains(&m.name) {
            delta.push(None);
        } else {
            delta.push(Some(n));
            n += 3;
        }
    }
    let mut q = Vec::new();
    for _ in 0..frames {
        q.push(n);
        n += n_q;
    }
    Ok(Layout {
        groups,
        size,
        delta,
        q,
        n,
    })
}

/// The problem at its starting point: factors 1 (or the stature ratio), offsets 0, each
/// frame's pose by inverse kinematics on the model at the starting size.
fn start<'a>(
    spec: &'a ModelSpec,
    targets: &'a [Vec<Vector3<f64>>],
    opts: &'a ScaleOptions,
) -> Result<(Problem<'a>, Vec<f64>), ScaleError> {
    let generic = Model::compile(spec)?;
    let n_q = generic.n_q();
    for (f, t) in targets.iter().enumerate() {
        let present = t.iter().filter(|m| m.x.is_finite()).count();
        if present < 4 {
            return Err(ScaleError::TooFewMarkers { frame: f, present });
        }
    }
    let lay = layout(spec, opts, n_q, targets.len())?;
    let mut th = vec![0.0; lay.n];
    let size = opts
        .prior
        .and_then(|p| p.stature)
        .map_or(1.0, |(ratio, _)| ratio);
    for &(at, n) in &lay.groups {
        th[at..at + n].fill(size);
    }
    if let Some(u) = lay.size {
        th[u] = size.ln();
    }
    let weight = spec
        .markers
        .iter()
        .map(|m| {
            opts.marker_weights
                .iter()
                .find(|(n, _)| *n == m.name)
                .map_or(1.0, |(_, w)| *w)
        })
        .collect();
    let mut pb = Problem {
        spec,
        opts,
        targets,
        lay,
        n_q,
        start: Vec::new(),
        msd: vec![opts.marker_sd; spec.markers.len()],
        weight,
    };
    let m0 = pb.model(&th)?;
    let ik = IkOptions::default();
    let mut ws = IkWorkspace::new(&m0);
    let p0 = m0.nominal_params();
    for (f, t) in targets.iter().enumerate() {
        let mut q = seed_frame(&m0, &p0, t, &ik, &mut ws);
        solve_frame(&m0, &p0, t, &mut q, &ik, &mut ws);
        let at = pb.lay.q[f];
        th[at..at + n_q].copy_from_slice(&q);
    }
    pb.start = th.clone();
    Ok((pb, th))
}

/// Solves, widening the offset prior of markers whose offset the data pull beyond
/// `ROBUST_IN_SD` prior SDs (tracking markers placed anywhere on the segment, not landmarks:
/// a Huber-like reweighting), and solving again from where it stopped.
fn solve_robust(pb: &mut Problem, mut th: Vec<f64>) -> Result<Solved, ScaleError> {
    let mut iterations = 0;
    for round in 0..ROBUST_ROUNDS {
        let (th2, r, j, cost, it) = solve(pb, th)?;
        th = th2;
        iterations += it;
        let mut widened = false;
        for (mi, at) in pb.lay.delta.iter().enumerate() {
            let Some(at) = at else {
                continue;
            };
            let d = (th[*at].powi(2) + th[at + 1].powi(2) + th[at + 2].powi(2)).sqrt();
            if pb.opts.robust && d > ROBUST_IN_SD * pb.msd[mi] * 1.05 {
                pb.msd[mi] = d / ROBUST_IN_SD;
                widened = true;
            }
        }
        if !widened || round + 1 == ROBUST_ROUNDS {
            return Ok((th, r, j, cost, iterations));
        }
    }
    unreachable!("at least one round")
}

/// Each group's factors with their SDs: the diagonal of `(JᵀJ)⁻¹`, inflated by `χ²/dof`
/// when that exceeds 1; then each body held at given factors (SD 0).
fn group_fits(pb: &Problem, sol: &Solved) -> Result<Vec<GroupFit>, ScaleError> {
    let (th, r, j, cost, _) = sol;
    let cov = (j.transpose() * j)
        .try_inverse()
        .ok_or(ScaleError::Singular)?;
    let dof = (r.len() as f64 - pb.lay.n as f64).max(1.0);
    let inflate = (cost / dof).max(1.0);
    let fitted = pb
        .opts
        .groups
        .iter()
        .zip(&pb.lay.groups)
        .map(|(g, &(at, n))| {
            let pick = |k: usize| if n == 3 { at + k } else { at };
            GroupFit {
                name: g.name.clone(),
                bodies: g.bodies.clone(),
                factors: std::array::from_fn(|k| th[pick(k)]),
                sd: std::array::from_fn(|k| (cov[(pick(k), pick(k))] * inflate).sqrt()),
            }
        });
    let held = pb.opts.fixed_factors.iter().map(|(b, f)| GroupFit {
        name: b.clone(),
        bodies: vec![b.clone()],
        factors: *f,
        sd: [0.0; 3],
    });
    Ok(fitted.chain(held).collect())
}

/// The registered markers with their errors, and the RMS over every present sample (m).
fn marker_fits(pb: &Problem, th: &[f64]) -> Result<(Vec<MarkerFit>, f64), ScaleError> {
    let model = pb.model(th)?;
    let mut data = KinData::new(&model);
    let mut sums = vec![(0.0, 0usize); pb.spec.markers.len()];
    for (f, t) in pb.targets.iter().enumerate() {
        pb.markers(&model, th, &mut data, f, Want::POSITIONS);
        for (mi, m) in t.iter().enumerate() {
            if m.x.is_finite() {
                sums[mi].0 += (data.markers[mi] - m).norm_squared();
                sums[mi].1 += 1;
            }
        }
    }
    let (total, count) = sums.iter().fold((0.0, 0), |(a, n), (s, k)| (a + s, n + k));
    let markers = pb
        .spec
        .markers
        .iter()
        .zip(&pb.lay.delta)
        .zip(model.markers())
        .zip(&sums)
        .map(|(((m, d), cm), (s, n))| MarkerFit {
            name: m.name.clone(),
            body: m.segment.clone(),
            position: [cm.local.x, cm.local.y, cm.local.z],
            moved: d.map_or([0.0; 3], |at| [th[at], th[at + 1], th[at + 2]]),
            rms: if *n > 0 {
                (s / *n as f64).sqrt()
            } else {
                f64::NAN
            },
        })
        .collect();
    Ok((markers, (total / count.max(1) as f64).sqrt()))
}

/// Fits the scale (module docs). `targets[f][j]`: the measured position (m, world) of model
/// marker `j` in frame `f` (NaN: absent); frame 0 is normally the averaged static trial.
pub fn fit_scale(
    spec: &ModelSpec,
    targets: &[Vec<Vector3<f64>>],
    opts: &ScaleOptions,
) -> Result<ScaleFit, ScaleError> {
    let (mut pb, th) = start(spec, targets, opts)?;
    let sol = solve_robust(&mut pb, th)?;
    let groups = group_fits(&pb, &sol)?;
    let th = &sol.0;
    let (markers, rms) = marker_fits(&pb, th)?;
    Ok(ScaleFit {
        factors: pb.factors(th),
        groups,
        markers,
        coords: pb
            .lay
            .q
            .iter()
            .map(|&at| th[at..at + pb.n_q].to_vec())
            .collect(),
        rms,
        size: pb.lay.size.map(|u| th[u].exp()),
        iterations: sol.4,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::scale::groups::default_groups;

    const TRUTH: [(&str, [f64; 3]); 4] = [
        ("pelvis", [1.06; 3]),
        ("thigh", [1.02, 1.13, 0.97]),
        ("shank", [0.92; 3]),
        ("foot", [1.04; 3]),
    ];

    /// The leg's groups (the thigh per axis) and its markers scaled by [`TRUTH`], at a pose
    /// away from the default.
    fn scaled_leg() -> (ModelSpec, Vec<ScaleGroup>, Vec<Vector3<f64>>) {
        let spec = lower_limb(Side::Right);
        let mut groups = default_groups(&spec, false, false);
        for g in groups.iter_mut() {
            g.per_axis = g.name == "thigh";
        }
        let mut factors = ScaleFactors::new();
        for (name, s) in TRUTH {
            let g = groups.iter().find(|g| g.name == name).unwrap();
            for b in &g.bodies {
                factors.insert(b.clone(), s);
            }
        }
        let scaled = Model::compile(&scaled_spec(&spec, &factors)).unwrap();
        let mut q = scaled.default_coords();
        for (k, v) in q.iter_mut().enumerate() {
            *v += 0.05 * ((k as f64) * 1.7).sin();
        }
        let mut data = KinData::new(&scaled);
        forward_kinematics(
            &scaled,
            &scaled.nominal_params(),
            &q,
            Want::POSITIONS,
            &mut data,
        );
        (spec, groups, data.markers.clone())
    }

    /// Largest difference between fitted and true factors.
    fn factor_error(fit: &ScaleFit) -> f64 {
        let mut worst: f64 = 0.0;
        for (name, s) in TRUTH {
            let g = fit.groups.iter().find(|g| g.name == name).unwrap();
            for (f, t) in g.factors.iter().zip(s) {
                worst = worst.max((f - t).abs());
            }
        }
        worst
    }

    /// The pure fit (no anthropometric prior) recovers the factors and the pose.
    #[test]
    fn recovers_known_factors_of_a_scaled_leg() {
        let (spec, groups, markers) = scaled_leg();
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        let fit = fit_scale(&spec, &[markers], &opts).unwrap();
        assert!(factor_error(&fit) < 1e-6, "{:?}", fit.groups);
        assert!(fit.rms < 1e-8, "rms {}", fit.rms);
        for m in &fit.markers {
            assert!(
                m.moved.iter().all(|d| d.abs() < 1e-6),
                "{}: {:?}",
                m.name,
                m.moved
            );
        }
    }

    /// A marker displaced by 4 cm biases the factors; with weight 0 its data are left out
    /// and the factors are the true ones again.
    #[test]
    fn a_marker_of_weight_zero_does_not_pull_the_factors() {
        let (spec, groups, mut markers) = scaled_leg();
        let bad = spec
            .markers
            .iter()
            .position(|m| m.segment == spec.segments[2].name)
            .unwrap();
        markers[bad] += Vector3::new(0.0, 0.04, 0.0);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        opts.robust = false;
        let biased = fit_scale(&spec, std::slice::from_ref(&markers), &opts).unwrap();
        assert!(factor_error(&biased) > 1e-3, "{:?}", biased.groups);
        opts.marker_weights = vec![(spec.markers[bad].name.clone(), 0.0)];
        let fit = fit_scale(&spec, &[markers], &opts).unwrap();
        assert!(factor_error(&fit) < 1e-6, "{:?}", fit.groups);
    }

    /// A body held at its true factors while the others are fitted: they are recovered, and
    /// the held body is reported with SD 0.
    #[test]
    fn bodies_held_at_given_factors_stay_there() {
        let (spec, mut groups, markers) = scaled_leg();
        let k = groups.iter().position(|g| g.name == "shank").unwrap();
        let shank = groups.remove(k);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        for b in &shank.bodies {
            opts.fixed_factors.insert(b.clone(), [0.92; 3]);
        }
        let fit = fit_scale(&spec, &[markers], &opts).unwrap();
        let held = fit.groups.iter().find(|g| g.bodies == shank.bodies[..1]);
        assert_eq!(held.map(|g| (g.factors, g.sd)), Some(([0.92; 3], [0.0; 3])));
        for b in &shank.bodies {
            assert_eq!(fit.factors[b], [0.92; 3]);
        }
        let others = fit.groups.iter().filter(|g| g.sd[0] > 0.0);
        for g in others {
            let (_, s) = TRUTH.iter().find(|(n, _)| *n == g.name).unwrap();
            assert!((g.factors[0] - s[0]).abs() < 1e-6, "{g:?}");
        }
    }
}
