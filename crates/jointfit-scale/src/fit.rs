//! The scale fit: per-group scale factors, every free marker's offset from its scaled
//! generic placement, and each frame's pose, solved together by Levenberg–Marquardt.
//!
//! Unknowns `θ = (g, u, δ, q_1 … q_F)`: `g` one factor per group (or three, per axis), `u`
//! the log of the overall size (only with the anthropometric prior), `δ_j` the offset (m, in
//! its body) of each free marker `j` from `s_b ⊙ c_j` (`c_j` its generic position), `q_f` the
//! coordinates of frame `f`. The model marker is `x_j(θ) = T_b(q_f; s) (s_b ⊙ c_j + δ_j)`,
//! where the body poses `T_b` use the scaled model ([`crate::geometry`]). Residual rows:
//!
//! * data: `√w_fj (x_j − m_fj)/σ_d` for every present marker of every frame: in the static
//!   frame (`f = 0`) `w_0j` is the marker's given weight (a setup's marker-placer task; 1
//!   unless given), in motion frames 1. A setup's weights were chosen for one static pose
//!   (OpenSim's marker placer): landmarks at 10–1000, clusters at 0–1. Carried into every
//!   motion frame they leave the clusters without a say where they show the segments' poses
//!   best, and weights far above 1 on a few landmarks let their offsets absorb the misfit
//!   (each offset's prior is only `σ_m`), which bends the factors;
//!   The static weights are divided by their mean over the static markers in use, so the
//!   static frame weighs as one frame whatever the setup's scale of weights;
//! * a marker the static frame holds and no motion frame does is moved onto its measured
//!   place at the fitted static pose once the fit is done (registration, as OpenSim's marker
//!   placer moves every marker of the static trial); the reported misfit is the fit's, before
//!   this move;
//! * marker placement prior: `δ_j/σ_j` (the registered marker stays near its generic place);
//!   `σ_j = σ_m` for every marker at first; a marker the fit moves beyond `2σ_j` is taken for a
//!   tracking marker placed anywhere on its segment and its `σ_j` widens to half its offset,
//!   then the fit resumes (up to four rounds: a Huber-like reweighting that keeps landmarks
//!   tight and lets clusters go where the data put them);
//! * anthropometric prior (optional): `(ln g_k − u)/σ_p` for every factor (segment
//!   proportions of the generic model, spread `σ_p`), and with a stature `H`:
//!   `(u − ln(H/H_generic))/σ_H`.
//!
//! Marker positions and their exact derivatives in `q`, `g` and `δ` come from a linear basis
//! of models compiled once (`basis.rs`); each Levenberg–Marquardt step eliminates the
//! frames by the Schur complement (`normal.rs`). The covariance of the factors is
//! `(J_dᵀJ_d / c + J_pᵀJ_p)⁻¹` at the solution (Laplace approximation; data rows `d` weighted
//! down by the variance factor `c ≥ 1` their residuals show, prior rows `p` as they are;
//! `data_variance_factor`, `docs/scaling.md`).

use nalgebra::Vector3;

use crate::basis::{BasisData, FactorBasis, FramePoints};
use crate::geometry::{scaled_spec, ScaleFactors};
use crate::normal::{Normal, Step};
use jointfit::ik::lm::IkWorkspace;
use jointfit::ik::IkOptions;
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError};

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
    /// Levenberg–Marquardt iterations per robust round (a safeguard: the fit normally stops
    /// by its convergence test well before).
    pub max_iterations: usize,
    /// Widen the offset prior of markers the data move far (tracking markers; module docs).
    pub robust: bool,
    /// Bodies held at given factors (OpenSim's manual scales), in no group.
    pub fixed_factors: ScaleFactors,
    /// Weights `w_j` of markers' data rows in the static frame (frame 0:
    /// `√w_j (x_j − m_0j)/σ_d`; 0 leaves the marker's static data out), as OpenSim's marker
    /// placer weighs the static pose; unnamed: 1. They describe the static pose only: the
    /// motion frames weigh every marker 1 (module docs).
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
            max_iterations: 200,
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
    /// RMS distance to the data over the frames it is present in, at the fit's solution
    /// before registration (m; NaN: never present).
    pub rms: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaleFit {
    pub factors: ScaleFactors,
    pub groups: Vec<GroupFit>,
    pub markers: Vec<MarkerFit>,
    /// Coordinates of every frame at the solution.
    pub coords: Vec<Vec<f64>>,
    /// RMS marker distance over every present marker sample at the fit's solution, before the
    /// static-only markers are registered (m).
    pub rms: f64,
    /// `exp(u)`: the overall size (anthropometric prior only).
    pub size: Option<f64>,
    pub iterations: usize,
    /// Whether the last round stopped by its convergence test, not at
    /// [`ScaleOptions::max_iterations`].
    pub converged: bool,
}

struct Layout {
    /// Per group: first unknown and count (1 or 3); the factors come first, `0..k`.
    groups: Vec<(usize, usize)>,
    /// Number of factor unknowns.
    k: usize,
    size: Option<usize>,
    /// Per model marker: first unknown of its δ, if free.
    delta: Vec<Option<usize>>,
    /// Per frame: first unknown of its q; the shared unknowns are `0..q[0]`.
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
    /// Per model marker: the weight of its data rows in the static frame
    /// (`ScaleOptions::marker_weights`).
    weight: Vec<f64>,
    basis: FactorBasis,
}

/// SD (rad or m) of the weak rows that hold coordinates no marker determines (a toe joint
/// without toe markers) at their starting values; far wider than any determined one.
const POSE_SD: f64 = 1000.0;

/// One evaluation: `Σ r²`, the data rows' share and count, and with the Jacobian the normal
/// equations (the data rows' share weighted by `data_weight`).
struct Eval {
    cost: f64,
    data_cost: f64,
    data_rows: usize,
    normal: Option<Normal>,
}

impl Eval {
    /// A residual row on shared unknowns with its nonzero Jacobian entries.
    fn shared_row(&mut self, value: f64, entries: &[(usize, f64)]) {
        self.cost += value * value;
        if let Some(nm) = self.normal.as_mut() {
            for &(i, a) in entries {
                nm.g[i] += a * value;
                for &(j, b) in entries {
                    nm.a[(i, j)] += a * b;
                }
            }
        }
    }
}

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

    /// The scaled model with the markers moved by their offsets.
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

    fn deltas(&self, th: &[f64]) -> Vec<Vector3<f64>> {
        let at = |d: &Option<usize>| {
            d.map_or(Vector3::zeros(), |a| {
                Vector3::new(th[a], th[a + 1], th[a + 2])
            })
        };
        self.lay.delta.iter().map(at).collect()
    }

    /// Marker positions of frame `f` (with the Jacobians when `jac`).
    fn points(&self, th: &[f64], f: usize, jac: bool, ws: &mut BasisData) -> FramePoints {
        let q = &th[self.lay.q[f]..self.lay.q[f] + self.n_q];
        let g = &th[..self.lay.k];
        self.basis.points(g, &self.deltas(th), q, jac, ws)
    }

    /// The weight of marker `mi`'s data rows in frame `f` (module docs).
    fn weight(&self, f: usize, mi: usize) -> f64 {
        if f == 0 {
            self.weight[mi]
        } else {
            1.0
        }
    }

    /// Whether marker `mi`'s sample `m` in frame `f` makes data rows (present, weight above 0).
    fn used(&self, f: usize, mi: usize, m: &Vector3<f64>) -> bool {
        m.x.is_finite() && self.weight(f, mi) > 0.0
    }

    /// Data rows of frame `f`, added to `ev`.
    fn frame_rows(&self, th: &[f64], f: usize, w: f64, ev: &mut Eval, ws: &mut BasisData) {
        let pts = self.points(th, f, ev.normal.is_some(), ws);
        let k = self.lay.k;
        for (mi, m) in self.targets[f].iter().enumerate() {
            if !self.used(f, mi, m) {
                continue;
            }
            let sc = self.weight(f, mi).sqrt() / self.opts.noise_sd;
            let r = (pts.markers[mi] - m) * sc;
            ev.cost += r.norm_squared();
            ev.data_cost += r.norm_squared();
            ev.data_rows += 3;
            let Some(nm) = ev.normal.as_mut() else {
                continue;
            };
            let jq = pts.jq.rows(3 * mi, 3) * sc;
            let jg = pts.jg.rows(3 * mi, 3) * sc;
            let fr = &mut nm.frames[f];
            fr.d += w * jq.transpose() * &jq;
            fr.g += w * jq.transpose() * r;
            let mut gg = nm.a.view_mut((0, 0), (k, k));
            gg += w * jg.transpose() * &jg;
            let mut gr = nm.g.rows_mut(0, k);
            gr += w * jg.transpose() * r;
            let mut bq = fr.b.rows_mut(0, k);
            bq += w * jg.transpose() * &jq;
            if let Some(at) = self.lay.delta[mi] {
                let jd = pts.jd[mi] * sc;
                let mut dd = nm.a.view_mut((at, at), (3, 3));
                dd += w * jd.transpose() * jd;
                let dg = w * jd.transpose() * &jg;
                let mut a_dg = nm.a.view_mut((at, 0), (3, k));
                a_dg += &dg;
                let mut a_gd = nm.a.view_mut((0, at), (k, 3));
                a_gd += dg.transpose();
                let mut bd = fr.b.rows_mut(at, 3);
                bd += w * jd.transpose() * &jq;
                let mut gd = nm.g.rows_mut(at, 3);
                gd += w * jd.transpose() * r;
            }
        }
    }

    /// Marker placement rows `δ_j/σ_j`.
    fn placement_rows(&self, th: &[f64], ev: &mut Eval) {
        for (at, sd) in self.lay.delta.iter().zip(&self.msd) {
            let Some(at) = at else {
                continue;
            };
            for k in 0..3 {
                ev.shared_row(th[at + k] / sd, &[(at + k, 1.0 / sd)]);
            }
        }
    }

    /// Anthropometric rows: proportions about the overall size, and the stature.
    fn size_rows(&self, th: &[f64], ev: &mut Eval) {
        let Some(p) = &self.opts.prior else {
            return;
        };
        let u_at = self.lay.size.expect("a size unknown with the prior");
        let sd = p.proportion_sd;
        for k in 0..self.lay.k {
            ev.shared_row(
                (th[k].ln() - th[u_at]) / sd,
                &[(k, 1.0 / (th[k] * sd)), (u_at, -1.0 / sd)],
            );
        }
        if let Some((ratio, s)) = p.stature {
            ev.shared_row((th[u_at] - ratio.ln()) / s, &[(u_at, 1.0 / s)]);
        }
    }

    /// Weak rows holding undetermined coordinates at their starting values.
    fn pose_rows(&self, th: &[f64], ev: &mut Eval) {
        for (f, &at) in self.lay.q.iter().enumerate() {
            for c in 0..self.n_q {
                let r = (th[at + c] - self.start[at + c]) / POSE_SD;
                ev.cost += r * r;
                if let Some(nm) = ev.normal.as_mut() {
                    nm.frames[f].d[(c, c)] += 1.0 / (POSE_SD * POSE_SD);
                    nm.frames[f].g[c] += r / POSE_SD;
                }
            }
        }
    }

    /// Every row (module docs); with `jac` the normal equations, the data rows' share
    /// weighted by `data_weight`.
    fn evaluate(&self, th: &[f64], jac: bool, data_weight: f64, ws: &mut BasisData) -> Eval {
        let n_s = self.lay.q[0];
        let mut ev = Eval {
            cost: 0.0,
            data_cost: 0.0,
            data_rows: 0,
            normal: jac.then(|| Normal::zeros(n_s, self.n_q, self.lay.q.len())),
        };
        for f in 0..self.targets.len() {
            self.frame_rows(th, f, data_weight, &mut ev, ws);
        }
        self.placement_rows(th, &mut ev);
        self.size_rows(th, &mut ev);
        self.pose_rows(th, &mut ev);
        ev
    }

    /// `th` moved by a step.
    fn moved(&self, th: &[f64], step: &Step) -> Vec<f64> {
        let mut out = th.to_vec();
        for (x, d) in out.iter_mut().zip(step.shared.iter()) {
            *x += d;
        }
        for (&at, dq) in self.lay.q.iter().zip(&step.frames) {
            for (x, d) in out[at..at + self.n_q].iter_mut().zip(dq.iter()) {
                *x += d;
            }
        }
        out
    }
}

/// Prior SDs beyond which a marker's offset marks it as a tracking marker (module docs).
const ROBUST_IN_SD: f64 = 2.0;
/// Rounds of widening.
const ROBUST_ROUNDS: usize = 4;

/// The solution, its cost, the iterations taken and whether the convergence test stopped it
/// (not the iteration limit).
type Solved = (Vec<f64>, f64, usize, bool);

/// Convergence: the step's predicted decrease of the cost (`Σ r²`, residuals in SDs) below
/// `DECREMENT_TOL · min(1, cost / data rows)`; the optimum is then closer than `√1e-4 = 0.01`
/// standard deviations (of the Laplace approximation, with the assumed marker SD or the
/// smaller spread the residuals show) in every direction of the unknowns.
const DECREMENT_TOL: f64 = 1e-4;

/// The decrease of `Σ r²` the linear model predicts for `step` (solved with damping
/// `lambda`): `−2gᵀΔ − ΔᵀHΔ = −gᵀΔ + λ ΔᵀDΔ`, `D` Marquardt's diagonal.
fn predicted(nm: &Normal, step: &Step, lambda: f64) -> f64 {
    let diag = |h: &nalgebra::DMatrix<f64>, d: &nalgebra::DVector<f64>| -> f64 {
        d.iter()
            .enumerate()
            .map(|(k, x)| h[(k, k)].max(1e-9) * x * x)
            .sum()
    };
    let mut gd = nm.g.dot(&step.shared);
    let mut dd = diag(&nm.a, &step.shared);
    for (fr, dq) in nm.frames.iter().zip(&step.frames) {
        gd += fr.g.dot(dq);
        dd += diag(&fr.d, dq);
    }
    -gd + lambda * dd
}

/// Levenberg–Marquardt from `th` (Marquardt's diagonal scaling; the damping follows the
/// gain ratio of actual to predicted decrease, Nielsen 1999), each step solved by the
/// Schur complement over the frames (`normal.rs`). Converged when a step's predicted
/// decrease falls below its tolerance ([`DECREMENT_TOL`]; or the cost stops changing).
fn solve(pb: &Problem, mut th: Vec<f64>, ws: &mut BasisData) -> Solved {
    let mut ev = pb.evaluate(&th, true, 1.0, ws);
    let mut cost = ev.cost;
    let rows = ev.data_rows.max(1) as f64;
    let tol = |cost: f64| DECREMENT_TOL * (cost / rows).min(1.0);
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let mut iterations = 0;
    let mut converged = false;
    while iterations < pb.opts.max_iterations {
        iterations += 1;
        let nm = ev.normal.take().expect("normal equations");
        let mut improved = false;
        let mut done = false;
        for _ in 0..16 {
            let Some(step) = nm.step(lambda) else {
                lambda *= nu;
                nu *= 2.0;
                continue;
            };
            let pred = predicted(&nm, &step, lambda);
            if pred <= tol(cost).min(1e-12 * cost) {
                done = true;
                break;
            }
            let trial = pb.moved(&th, &step);
            if trial[..pb.lay.k].iter().any(|v| *v <= 0.05) {
                lambda *= nu;
                nu *= 2.0;
                continue;
            }
            let c2 = pb.evaluate(&trial, false, 1.0, ws).cost;
            let rho = (cost - c2) / pred;
            if c2 < cost {
                done = pred < tol(cost) || (cost - c2) <= 1e-12 * cost.max(1e-30);
                th = trial;
                cost = c2;
                lambda *= (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3));
                lambda = lambda.max(1e-12);
                nu = 2.0;
                improved = true;
                break;
            }
            lambda *= nu;
            nu *= 2.0;
        }
        if done || !improved {
            converged = true;
            break;
        }
        ev = pb.evaluate(&th, true, 1.0, ws);
    }
    (th, cost, iterations, converged)
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
    let k = n;
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
        k,
        size,
        delta,
        q,
        n,
    })
}

/// Markers the static frame holds and no motion frame does, moved onto their measured place
/// at the fitted static pose once the fit is done (module docs), as OpenSim's marker placer
/// moves every marker of the static trial: their weighted static data shaped the pose and the
/// factors; the subject's model carries them where they were measured.
fn register_static_only(pb: &Problem, th: &mut [f64]) -> Result<(), ScaleError> {
    let Some(stat) = pb.targets.first() else {
        return Ok(());
    };
    let model = pb.model(th)?;
    let q0 = &th[pb.lay.q[0]..pb.lay.q[0] + pb.n_q];
    let mut data = KinData::new(&model);
    forward_kinematics(
        &model,
        &model.nominal_params(),
        q0,
        Want::POSITIONS,
        &mut data,
    );
    let mut moves = Vec::new();
    for (j, (d, m)) in pb.lay.delta.iter().zip(stat).enumerate() {
        let in_motion = pb.targets[1..].iter().any(|t| t[j].x.is_finite());
        if let (Some(at), true, false) = (d, m.x.is_finite(), in_motion) {
            let rot = data.segment_poses[model.markers()[j].segment.0].rot;
            moves.push((*at, rot.transpose() * (m - data.markers[j])));
        }
    }
    for (at, step) in moves {
        for k in 0..3 {
            th[at + k] += step[k];
        }
    }
    Ok(())
}

/// Per model marker: its weight in the static frame (`ScaleOptions::marker_weights`, 1
/// unless named), divided by the mean weight of the static markers that make data rows, so
/// that the static frame weighs as much as one motion frame whatever the setup's scale of
/// weights (10–100 in one lab's setup, 1–1000 in another's).
fn static_weights(
    spec: &ModelSpec,
    targets: &[Vec<Vector3<f64>>],
    opts: &ScaleOptions,
) -> Vec<f64> {
    let given: Vec<f64> = spec
        .markers
        .iter()
        .map(|m| {
            opts.marker_weights
                .iter()
                .find(|(n, _)| *n == m.name)
                .map_or(1.0, |(_, w)| *w)
        })
        .collect();
    let used: Vec<f64> = given
        .iter()
        .zip(&targets[0])
        .filter(|(w, m)| **w > 0.0 && m.x.is_finite())
        .map(|(w, _)| *w)
        .collect();
    let mean = used.iter().sum::<f64>() / used.len().max(1) as f64;
    if mean > 0.0 {
        given.iter().map(|w| w / mean).collect()
    } else {
        given
    }
}

/// The problem at its starting point: factors 1 (or the stature ratio), offsets 0, each
/// frame's pose by inverse kinematics on the model at the starting size.
fn start<'a>(
    spec: &'a ModelSpec,
    targets: &'a [Vec<Vector3<f64>>],
    opts: &'a ScaleOptions,
) -> Result<(Problem<'a>, Vec<f64>), ScaleError> {
    for (f, t) in targets.iter().enumerate() {
        let present = t.iter().filter(|m| m.x.is_finite()).count();
        if present < 4 {
            return Err(ScaleError::TooFewMarkers { frame: f, present });
        }
    }
    let basis = FactorBasis::new(spec, &opts.groups, &opts.fixed_factors)?;
    let n_q = basis.base().n_q();
    let lay = layout(spec, opts, n_q, targets.len())?;
    let mut th = vec![0.0; lay.n];
    let size = opts
        .prior
        .and_then(|p| p.stature)
        .map_or(1.0, |(ratio, _)| ratio);
    th[..lay.k].fill(size);
    if let Some(u) = lay.size {
        th[u] = size.ln();
    }
    let weight = static_weights(spec, targets, opts);
    let mut pb = Problem {
        spec,
        opts,
        targets,
        lay,
        n_q,
        start: Vec::new(),
        msd: vec![opts.marker_sd; spec.markers.len()],
        weight,
        basis,
    };
    let m0 = pb.model(&th)?;
    let ik = IkOptions::default();
    let mut ws = IkWorkspace::new(&m0);
    let p0 = m0.nominal_params();
    for (f, t) in targets.iter().enumerate() {
        let mut q = ws.seed(&m0, &p0, t, &ik);
        ws.solve(&m0, &p0, t, &mut q, &ik);
        let at = pb.lay.q[f];
        th[at..at + n_q].copy_from_slice(&q);
    }
    pb.start = th.clone();
    Ok((pb, th))
}

/// Solves, widening the offset prior of markers whose offset the data pull beyond
/// `ROBUST_IN_SD` prior SDs (tracking markers placed anywhere on the segment, not landmarks:
/// a Huber-like reweighting), and solving again from where it stopped.
fn solve_robust(pb: &mut Problem, mut th: Vec<f64>, ws: &mut BasisData) -> Solved {
    let mut iterations = 0;
    for round in 0..ROBUST_ROUNDS {
        let (th2, cost, it, converged) = solve(pb, th, ws);
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
            return (th, cost, iterations, converged);
        }
    }
    unreachable!("at least one round")
}

/// The factor of the data rows' variance over the assumed `σ_d²` that the residuals show:
/// `c = max(1, χ²_data / (n_data − p))`, where `p = tr((JᵀJ)⁻¹ J_dᵀJ_d)` counts the
/// unknowns the data determine (those the priors determine do not use up data rows).
fn data_variance_factor(pb: &Problem, th: &[f64], ws: &mut BasisData) -> Result<f64, ScaleError> {
    let full = pb.evaluate(th, true, 1.0, ws);
    let prior = pb.evaluate(th, true, 0.0, ws);
    let (nm, pr) = (full.normal.expect("normal"), prior.normal.expect("normal"));
    let (sinv, diags) = nm.inverse_blocks().ok_or(ScaleError::Singular)?;
    let mut p = pb.lay.n as f64 - (sinv * &pr.a).trace();
    for (d, fr) in diags.iter().zip(&pr.frames) {
        p -= d
            .iter()
            .zip(fr.d.diagonal().iter())
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    let dof = full.data_rows as f64 - p;
    Ok(if dof >= 1.0 {
        (full.data_cost / dof).max(1.0)
    } else {
        1.0
    })
}

/// Each group's factors with their SDs: the diagonal of `(J_dᵀJ_d / c + J_pᵀJ_p)⁻¹` (data
/// rows `d` weighted down by [`data_variance_factor`], prior rows `p` as they are); then each
/// body held at given factors (SD 0).
fn group_fits(pb: &Problem, th: &[f64], ws: &mut BasisData) -> Result<Vec<GroupFit>, ScaleError> {
    let c = data_variance_factor(pb, th, ws)?;
    let nm = pb.evaluate(th, true, 1.0 / c, ws).normal.expect("normal");
    let (cov, _) = nm.inverse_blocks().ok_or(ScaleError::Singular)?;
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
                sd: std::array::from_fn(|k| cov[(pick(k), pick(k))].sqrt()),
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

/// The registered markers (their places from `placed`) with their errors at the fit's
/// solution `fitted`, and the RMS over every present sample (m).
fn marker_fits(
    pb: &Problem,
    fitted: &[f64],
    placed: &[f64],
    ws: &mut BasisData,
) -> Result<(Vec<MarkerFit>, f64), ScaleError> {
    let model = pb.model(placed)?;
    let mut sums = vec![(0.0, 0usize); pb.spec.markers.len()];
    for (f, t) in pb.targets.iter().enumerate() {
        let pts = pb.points(fitted, f, false, ws);
        for (mi, m) in t.iter().enumerate() {
            if m.x.is_finite() {
                sums[mi].0 += (pts.markers[mi] - m).norm_squared();
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
            moved: d.map_or([0.0; 3], |at| [placed[at], placed[at + 1], placed[at + 2]]),
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
    let mut ws = pb.basis.workspace();
    let (fitted, _, iterations, converged) = solve_robust(&mut pb, th, &mut ws);
    let groups = group_fits(&pb, &fitted, &mut ws)?;
    let mut placed = fitted.clone();
    register_static_only(&pb, &mut placed)?;
    // The misfit is the fit's, before the static-only markers are placed onto the data.
    let (markers, rms) = marker_fits(&pb, &fitted, &placed, &mut ws)?;
    let th = &placed;
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
        iterations,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::groups::default_groups;
    use jointfit::kinematics::{forward_kinematics, KinData, Want};
    use jointfit::model::lower_limb::{lower_limb, Side};

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
    /// The fit says whether its convergence test stopped it: the noiseless leg converges in
    /// the default budget, and a budget of two iterations stops it first.
    #[test]
    fn the_fit_tells_convergence_from_its_iteration_limit() {
        let (spec, groups, markers) = scaled_leg();
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        let fit = fit_scale(&spec, std::slice::from_ref(&markers), &opts).unwrap();
        assert!(fit.converged, "{} iterations", fit.iterations);
        opts.max_iterations = 2;
        let capped = fit_scale(&spec, &[markers], &opts).unwrap();
        assert!(!capped.converged);
        assert!(factor_error(&capped) > factor_error(&fit));
    }

    /// The static weights shift trust between markers only: the same weights times 50 give the
    /// same fit, and unequal weights give another one than none.
    #[test]
    fn static_marker_weights_are_relative() {
        let (spec, groups, mut markers) = scaled_leg();
        markers[0] += Vector3::new(0.01, -0.02, 0.0);
        let opts = |scale: f64| {
            let mut o = ScaleOptions::new(groups.clone());
            o.marker_weights = spec
                .markers
                .iter()
                .enumerate()
                .map(|(j, m)| (m.name.clone(), scale * (1.0 + (j % 3) as f64)))
                .collect();
            o
        };
        let a = fit_scale(&spec, std::slice::from_ref(&markers), &opts(1.0)).unwrap();
        let b = fit_scale(&spec, std::slice::from_ref(&markers), &opts(50.0)).unwrap();
        for (ga, gb) in a.groups.iter().zip(&b.groups) {
            for k in 0..3 {
                assert!(
                    (ga.factors[k] - gb.factors[k]).abs() < 1e-9,
                    "{ga:?} {gb:?}"
                );
            }
        }
        let plain = ScaleOptions::new(groups.clone());
        let unweighted = fit_scale(&spec, &[markers], &plain).unwrap();
        let differ = |u: &GroupFit, w: &GroupFit| (u.factors[0] - w.factors[0]).abs() > 1e-6;
        assert!(unweighted
            .groups
            .iter()
            .zip(&a.groups)
            .any(|(u, w)| differ(u, w)));
    }

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
        let fit = fit_scale(&spec, std::slice::from_ref(&markers), &opts).unwrap();
        assert!(factor_error(&fit) < 1e-6, "{:?}", fit.groups);
        // Registered where it was measured, as the marker placer moves every static marker.
        let m = &fit.markers[bad];
        let moved = Vector3::from(m.moved).norm();
        assert!((moved - 0.04).abs() < 1e-6, "{m:?}");
        // its misfit is the fit's, before registration
        assert!((m.rms - 0.04).abs() < 1e-6, "{m:?}");
        // In a motion frame the marker counts (weight 1): its data pull the factors again.
        let with_motion = fit_scale(&spec, &[markers.clone(), markers], &opts).unwrap();
        assert!(
            factor_error(&with_motion) > 1e-3,
            "{:?}",
            with_motion.groups
        );
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

    /// Frames of the leg scaled uniformly by `truth` (per group name) at `n` poses.
    fn leg_frames(
        truth: &[(&str, f64)],
        n: usize,
    ) -> (ModelSpec, Vec<ScaleGroup>, Vec<Vec<Vector3<f64>>>) {
        let spec = lower_limb(Side::Right);
        let groups = default_groups(&spec, false, false);
        let mut factors = ScaleFactors::new();
        for g in &groups {
            let s = truth.iter().find(|(n, _)| *n == g.name).unwrap().1;
            for b in &g.bodies {
                factors.insert(b.clone(), [s; 3]);
            }
        }
        let scaled = Model::compile(&scaled_spec(&spec, &factors)).unwrap();
        let mut data = KinData::new(&scaled);
        let frames = (0..n)
            .map(|f| {
                let mut q = scaled.default_coords();
                for (k, v) in q.iter_mut().enumerate() {
                    *v += 0.3 * ((k as f64) * 1.7 + f as f64 * 2.1).sin();
                }
                let p = scaled.nominal_params();
                forward_kinematics(&scaled, &p, &q, Want::POSITIONS, &mut data);
                data.markers.clone()
            })
            .collect();
        (spec, groups, frames)
    }

    /// Over seeded draws of marker noise, the spread of each fitted factor matches its
    /// reported SD: with noise of the assumed SD, and with twice that (the SD then grows
    /// with the spread the residuals show).
    #[test]
    fn reported_sds_match_the_spread_over_noise_draws() {
        use rand::{Rng, SeedableRng};
        let truth = [
            ("pelvis", 1.06),
            ("thigh", 1.1),
            ("shank", 0.92),
            ("foot", 1.04),
        ];
        let (spec, groups, clean) = leg_frames(&truth, 4);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        opts.fixed_markers = spec.markers.iter().map(|m| m.name.clone()).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(38);
        // A standard normal draw (Box–Muller).
        let mut normal = move || {
            let (u, v): (f64, f64) = (rng.gen_range(1e-300..1.0), rng.gen());
            (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
        };
        for noise in [opts.noise_sd, 2.0 * opts.noise_sd] {
            let draws = 200;
            let mut factors = vec![Vec::new(); truth.len()];
            let mut sds = vec![0.0; truth.len()];
            for _ in 0..draws {
                let noisy: Vec<Vec<Vector3<f64>>> = clean
                    .iter()
                    .map(|fr| {
                        fr.iter()
                            .map(|m| m + Vector3::from_fn(|_, _| noise * normal()))
                            .collect()
                    })
                    .collect();
                let fit = fit_scale(&spec, &noisy, &opts).unwrap();
                for (k, g) in fit.groups.iter().enumerate() {
                    factors[k].push(g.factors[0]);
                    sds[k] += g.sd[0] / draws as f64;
                }
            }
            for (k, f) in factors.iter().enumerate() {
                let mean = f.iter().sum::<f64>() / draws as f64;
                let spread =
                    (f.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (draws - 1) as f64).sqrt();
                let ratio = sds[k] / spread;
                assert!(
                    (0.75..=1.3).contains(&ratio),
                    "noise {noise}: group {k} reports SD {} for a spread of {spread}",
                    sds[k]
                );
            }
        }
    }

    /// With noisy motion frames the fit converges (its own test, not the limit) at a
    /// stationary point of its cost: the central-difference gradient of `Σ r²` in every
    /// unknown is below a hundredth of that unknown's curvature scale `√H_ii`, so no
    /// unknown alone could lower the cost by more than 1e-4.
    #[test]
    fn noisy_motion_frames_converge_to_a_stationary_point() {
        use rand::{Rng, SeedableRng};
        let truth = [
            ("pelvis", 1.06),
            ("thigh", 1.1),
            ("shank", 0.92),
            ("foot", 1.04),
        ];
        let (spec, groups, clean) = leg_frames(&truth, 6);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noisy: Vec<Vec<Vector3<f64>>> = clean
            .iter()
            .map(|fr| {
                fr.iter()
                    .map(|m| m + Vector3::from_fn(|_, _| rng.gen_range(-0.01..0.01)))
                    .collect()
            })
            .collect();
        let mut opts = ScaleOptions::new(groups);
        opts.robust = false;
        let fit = fit_scale(&spec, &noisy, &opts).unwrap();
        assert!(fit.converged, "{} iterations", fit.iterations);

        let (pb, th) = start(&spec, &noisy, &opts).unwrap();
        let mut ws = pb.basis.workspace();
        let (th, _, _, converged) = solve(&pb, th, &mut ws);
        assert!(converged);
        let nm = pb.evaluate(&th, true, 1.0, &mut ws).normal.unwrap();
        let mut curvature: Vec<f64> = nm.a.diagonal().iter().copied().collect();
        for fr in &nm.frames {
            curvature.extend(fr.d.diagonal().iter());
        }
        let cost = |t: &[f64], ws: &mut BasisData| pb.evaluate(t, false, 1.0, ws).cost;
        for (i, h_ii) in curvature.iter().enumerate() {
            let h = 1e-6 * th[i].abs().max(1e-3);
            let mut up = th.clone();
            up[i] += h;
            let mut down = th.clone();
            down[i] -= h;
            let grad = (cost(&up, &mut ws) - cost(&down, &mut ws)) / (2.0 * h);
            // the cost is Σ r², its gradient 2 Jᵀr: one unknown's best move lowers it by
            // (grad/2)² / H_ii
            let gain = (grad / 2.0).powi(2) / h_ii;
            assert!(gain < 1e-4, "unknown {i}: gradient {grad}, H_ii {h_ii}");
        }
        for g in &fit.groups {
            let (_, s) = truth.iter().find(|(n, _)| *n == g.name).unwrap();
            assert!((g.factors[0] - s).abs() < 4.0 * g.sd[0], "{g:?}");
        }
    }
}
