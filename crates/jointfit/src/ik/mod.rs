//! The inner level: per-frame inverse kinematics by damped Gauss-Newton (Levenberg–Marquardt).
//!
//! For parameters `p` and measured markers `m_j` (frame i), find
//!
//! `q_i = argmin_q Σ_j w_j ‖m_j − x_j(p, q)‖²`,
//!
//! Reinbolt et al. 2005, Eq. (1), with per-marker weights `w_j` (0 for a missing marker). Each
//! iteration solves `(JᵀWJ + λ·diag(JᵀWJ)) δ = JᵀW r` with the analytic Jacobian
//! `J = ∂x/∂q` ([`crate::kinematics`]) and `r = m − x`, accepts the step when the cost drops
//! and adapts `λ` (Marquardt's scaling). Without noise the residual vanishes at the solution
//! and Gauss-Newton converges quadratically.
//!
//! Frames are solved in order, each warm-started from the previous solutions (the paper's
//! scheme, with a linear extrapolation of the last two). The first frame is seeded from the root segment's markers alone: the root joint's
//! coordinates are fitted from several starting orientations and the best fit is kept, the
//! other coordinates start at their defaults. A frame in which some segment that carries
//! markers has fewer than three of them present is reported, not guessed.

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::linalg::Cholesky;
use crate::model::{CoordKind, Model};
use crate::solver::Termination;
use crate::trial::Trial;

/// Why IK could not start.
#[derive(Debug, Error, PartialEq)]
pub enum IkError {
    #[error("the trial lacks model markers {missing:?}; it has: {available}")]
    MissingMarkers {
        missing: Vec<String>,
        available: String,
    },
    #[error("parameter vector has {got} values, the model has {expected} parameters")]
    ParamLength { got: usize, expected: usize },
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    pub max_iterations: usize,
    /// Stop when the largest accepted step component is below this (rad or m). Gauss-Newton
    /// on noisy markers converges linearly (each step a fixed fraction of the last, about
    /// 0.1 on gait data), so the remaining error is about a tenth of this. The default,
    /// 1e-8, is far below what any marker data determines (1e-8 rad = 6e-7 deg, 1e-8 m =
    /// 1e-5 mm).
    pub step_tolerance: f64,
    /// Minimum present markers on every segment that carries markers.
    pub min_markers_per_segment: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            max_iterations: 100,
            step_tolerance: 1e-8,
            min_markers_per_segment: 3,
        }
    }
}

/// Which trial column feeds each model marker.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerMap {
    /// `columns[j]`: trial column of model marker `j` (`None`: the trial lacks it, and it is
    /// missing in every frame).
    pub columns: Vec<Option<usize>>,
}

impl MarkerMap {
    /// Matches model markers to trial labels by name; every model marker must be present.
    pub fn by_name(model: &Model, labels: &[String]) -> Result<MarkerMap, IkError> {
        let (map, absent) = Self::allowing_absent(model, labels);
        if !absent.is_empty() {
            return Err(IkError::MissingMarkers {
                missing: absent,
                available: labels.join(", "),
            });
        }
        Ok(map)
    }

    /// Matches model markers to trial labels by name; model markers the trial lacks are
    /// missing in every frame (a frame is still solved while each segment keeps enough
    /// markers). Returns the map and the names of the absent markers.
    pub fn allowing_absent(model: &Model, labels: &[String]) -> (MarkerMap, Vec<String>) {
        let mut absent = Vec::new();
        let columns = model
            .markers
            .iter()
            .map(|m| {
                let c = labels.iter().position(|l| l == &m.name);
                if c.is_none() {
                    absent.push(m.name.clone());
                }
                c
            })
            .collect();
        (MarkerMap { columns }, absent)
    }

    /// The model-ordered targets of one trial frame (NaN where missing).
    pub fn targets(&self, trial: &Trial, frame: usize, out: &mut Vec<Vector3<f64>>) {
        let row = trial.frame(frame);
        out.clear();
        out.extend(self.columns.iter().map(|c| match c {
            Some(c) => row[*c],
            None => Vector3::from_element(f64::NAN),
        }));
    }
}

/// How a frame ended.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameStatus {
    Converged,
    /// The iteration budget ran out (the result is the best point found).
    MaxIterations,
    /// No step lowered the cost even at damping 1e10 (the result is the best point found;
    /// not a verified minimum).
    Stalled,
    /// A segment with markers had fewer than the minimum present: not solved.
    TooFewMarkers {
        segment: String,
        present: usize,
    },
}

/// The outcome of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFit {
    /// Weighted sum of squared marker errors at the solution (m²).
    pub cost: f64,
    pub iterations: usize,
    pub status: FrameStatus,
}

impl FrameFit {
    pub fn solved(&self) -> bool {
        !matches!(self.status, FrameStatus::TooFewMarkers { .. })
    }
}

/// Scratch space for one thread: reuse it across frames.
#[derive(Debug, Clone)]
pub struct IkWorkspace {
    cur: KinData,
    trial: KinData,
    weights: Vec<f64>,
    a: Vec<f64>,
    l: Vec<f64>,
    g: Vec<f64>,
    delta: Vec<f64>,
    q_trial: Vec<f64>,
    all: Vec<usize>,
    moments: Moments,
}

/// The normal equations `JᵀWJ δ = JᵀW r` of one frame, formed from segment moments
/// instead of the `3·n_markers × n_q` Jacobian.
///
/// On segment `s`, column `a` of the marker Jacobian is a rigid velocity field: every step
/// that moves `s` contributes `c_k ω_k × (x − o_k)` (rotation) or `c_k ω_k` (translation)
/// ([`crate::kinematics`]), so `J_a(x) = ω_a × (x − x̄) + v_a` with the twist
/// `ω_a = Σ_rot c_k ω_k`, `v_a = Σ_rot c_k ω_k × (x̄ − o_k) + Σ_trans c_k ω_k` about the
/// weighted centroid `x̄` of the segment's present markers. With `d_j = x_j − x̄` (so
/// `Σ w_j d_j = 0`), the segment's share of the normal equations is
///
/// * `(JᵀWJ)_ab = ω_aᵀ Θ ω_b + M v_a·v_b`, `Θ = Σ w_j (‖d_j‖² I − d_j d_jᵀ)`, `M = Σ w_j`,
/// * `(JᵀW r)_a = ω_a·Σ w_j d_j × r_j + v_a·Σ w_j r_j`,
///
/// the marker cloud's inertia-like moments contracted with the column twists. The cost per
/// iteration no longer grows with markers × columns², and the Jacobian is never filled.
#[derive(Debug, Clone)]
struct Moments {
    segments: Vec<SegmentTerms>,
    /// Active index of each coordinate (`usize::MAX`: not active).
    active_index: Vec<usize>,
    /// Twists of one segment's columns: `(ω, v)`.
    twists: Vec<(Vector3<f64>, Vector3<f64>)>,
}

/// The coordinates that move one marker-carrying segment.
#[derive(Debug, Clone)]
struct SegmentTerms {
    markers: Vec<usize>,
    /// Distinct coordinate columns that move the segment.
    cols: Vec<usize>,
    /// `(local column, step, scale, rotation)` for every step contribution.
    steps: Vec<(usize, usize, f64, bool)>,
}

impl Moments {
    fn new(model: &Model) -> Self {
        let mut segments = Vec::new();
        let mut widest = 0;
        for (s, markers) in model.plan.markers_by_segment.iter().enumerate() {
            if markers.is_empty() {
                continue;
            }
            let mut cols: Vec<usize> = Vec::new();
            let mut steps = Vec::new();
            for c in &model.plan.cols_q[s] {
                let local = match cols.iter().position(|&x| x == c.col) {
                    Some(l) => l,
                    None => {
                        cols.push(c.col);
                        cols.len() - 1
                    }
                };
                steps.push((local, c.step, c.scale, c.rotation));
            }
            widest = widest.max(cols.len());
            segments.push(SegmentTerms {
                markers: markers.clone(),
                cols,
                steps,
            });
        }
        Moments {
            segments,
            active_index: vec![usize::MAX; model.n_q()],
            twists: vec![(Vector3::zeros(), Vector3::zeros()); widest],
        }
    }

    fn set_active(&mut self, active: &[usize]) {
        self.active_index.fill(usize::MAX);
        for (i, &c) in active.iter().enumerate() {
            self.active_index[c] = i;
        }
    }

    /// Writes `JᵀWJ` (n × n, column-major, n = active count) into `a` and `JᵀW r` into `g`.
    fn normal_equations(
        &mut self,
        kin: &KinData,
        targets: &[Vector3<f64>],
        weights: &[f64],
        n: usize,
        a: &mut [f64],
        g: &mut [f64],
    ) {
        a[..n * n].fill(0.0);
        g[..n].fill(0.0);
        for seg in &self.segments {
            let mut mass = 0.0;
            let mut centroid = Vector3::zeros();
            for &j in &seg.markers {
                let w = weights[j];
                if w > 0.0 {
                    mass += w;
                    centroid += w * kin.markers[j];
                }
            }
            if mass == 0.0 {
                continue;
            }
            centroid /= mass;
            let mut theta = Matrix3::zeros();
            let mut r0 = Vector3::zeros();
            let mut r1 = Vector3::zeros();
            for &j in &seg.markers {
                let w = weights[j];
                if w > 0.0 {
                    let d = kin.markers[j] - centroid;
                    let r = targets[j] - kin.markers[j];
                    theta +=
                        w * (Matrix3::from_diagonal_element(d.norm_squared()) - d * d.transpose());
                    r0 += w * r;
                    r1 += w * d.cross(&r);
                }
            }
            let twists = &mut self.twists[..seg.cols.len()];
            twists.fill((Vector3::zeros(), Vector3::zeros()));
            for &(local, step, scale, rotation) in &seg.steps {
                let (axis, origin) = kin.step_frame(step);
                let t = &mut twists[local];
                if rotation {
                    t.0 += scale * axis;
                    t.1 += scale * axis.cross(&(centroid - origin));
                } else {
                    t.1 += scale * axis;
                }
            }
            for (la, &ca) in seg.cols.iter().enumerate() {
                let ai = self.active_index[ca];
                if ai == usize::MAX {
                    continue;
                }
                let (wa, va) = twists[la];
                g[ai] += wa.dot(&r1) + va.dot(&r0);
                let theta_wa = theta * wa;
                for (lb, &cb) in seg.cols.iter().enumerate().take(la + 1) {
                    let bi = self.active_index[cb];
                    if bi == usize::MAX {
                        continue;
                    }
                    let (wb, vb) = twists[lb];
                    let value = theta_wa.dot(&wb) + mass * va.dot(&vb);
                    // Lower triangle (row ≥ column); mirrored below.
                    let (row, col) = if ai >= bi { (ai, bi) } else { (bi, ai) };
                    a[col * n + row] += value;
                }
            }
        }
        for col in 0..n {
            for row in col + 1..n {
                a[row * n + col] = a[col * n + row];
            }
        }
    }
}

impl IkWorkspace {
    pub fn new(model: &Model) -> Self {
        let n = model.n_q();
        IkWorkspace {
            cur: KinData::new(model),
            trial: KinData::new(model),
            weights: vec![0.0; model.n_markers()],
            a: vec![0.0; n * n],
            l: vec![0.0; n * n],
            g: vec![0.0; n],
            delta: vec![0.0; n],
            q_trial: vec![0.0; n],
            all: (0..n).collect(),
            moments: Moments::new(model),
        }
    }
    /// Kinematics at the last solution (marker positions of the last accepted point).
    pub fn kin(&self) -> &KinData {
        &self.cur
    }
}

fn cost_of(markers: &[Vector3<f64>], targets: &[Vector3<f64>], w: &[f64]) -> f64 {
    let mut c = 0.0;
    for j in 0..markers.len() {
        if w[j] > 0.0 {
            c += w[j] * (targets[j] - markers[j]).norm_squared();
        }
    }
    c
}

/// Sets marker weights for a frame (model weight, 0 when missing) and checks coverage.
fn frame_weights(
    model: &Model,
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    w: &mut [f64],
) -> Result<(), FrameStatus> {
    let mut present = vec![0usize; model.segments.len()];
    let mut carries = vec![false; model.segments.len()];
    for (j, m) in model.markers.iter().enumerate() {
        let ok = !targets[j].x.is_nan() && m.weight > 0.0;
        w[j] = if ok { m.weight } else { 0.0 };
        if m.weight > 0.0 {
            carries[m.segment.0] = true;
            present[m.segment.0] += ok as usize;
        }
    }
    for s in 0..model.segments.len() {
        if carries[s] && present[s] < opts.min_markers_per_segment {
            return Err(FrameStatus::TooFewMarkers {
                segment: model.segments[s].name.clone(),
                present: present[s],
            });
        }
    }
    Ok(())
}

/// Levenberg–Marquardt over the coordinates listed in `active` (others fixed), with the
/// weights already in `ws.weights`. Returns (cost, iterations, how it ended).
fn lm(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    q: &mut [f64],
    active: &[usize],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> (f64, usize, Termination) {
    let n = active.len();
    ws.moments.set_active(active);
    forward_kinematics(model, p, q, Want::AXES, &mut ws.cur);
    let mut cost = cost_of(&ws.cur.markers, targets, &ws.weights);
    let mut lambda = 1e-6;
    let mut iterations = 0;
    while iterations < opts.max_iterations {
        iterations += 1;
        ws.moments
            .normal_equations(&ws.cur, targets, &ws.weights, n, &mut ws.a, &mut ws.g);
        let max_diag = (0..n).fold(0.0f64, |m, i| m.max(ws.a[i * n + i]));
        // Try steps with growing damping until the cost drops.
        loop {
            ws.l[..n * n].copy_from_slice(&ws.a[..n * n]);
            for i in 0..n {
                ws.l[i * n + i] += lambda * ws.a[i * n + i] + 1e-14 * max_diag + 1e-300;
            }
            let Some(chol) = Cholesky::factor(&mut ws.l[..n * n], n) else {
                lambda *= 10.0;
                if lambda > 1e10 {
                    return (cost, iterations, Termination::Stalled);
                }
                continue;
            };
            ws.delta[..n].copy_from_slice(&ws.g[..n]);
            chol.solve(&mut ws.delta[..n]);
            let step_max = ws.delta[..n].iter().fold(0.0f64, |m, d| m.max(d.abs()));
            ws.q_trial.copy_from_slice(q);
            for (i, &c) in active.iter().enumerate() {
                ws.q_trial[c] += ws.delta[i];
            }
            forward_kinematics(model, p, &ws.q_trial, Want::AXES, &mut ws.trial);
            let trial_cost = cost_of(&ws.trial.markers, targets, &ws.weights);
            if trial_cost <= cost {
                q.copy_from_slice(&ws.q_trial);
                std::mem::swap(&mut ws.cur, &mut ws.trial);
                cost = trial_cost;
                lambda = (lambda / 10.0).max(1e-12);
                if step_max < opts.step_tolerance {
                    return (cost, iterations, Termination::Converged);
                }
                break;
            }
            if step_max < opts.step_tolerance {
                // Even a negligible step does not lower the cost: minimum to working precision.
                return (cost, iterations, Termination::Converged);
            }
            lambda *= 10.0;
            if lambda > 1e10 {
                return (cost, iterations, Termination::Stalled);
            }
        }
    }
    (cost, iterations, Termination::IterationLimit)
}

/// Solves one frame in place: `q` is the starting point on entry, the solution on exit.
/// `targets` holds one position per model marker (NaN when missing).
pub fn solve_frame(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    q: &mut [f64],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> FrameFit {
    if let Err(status) = frame_weights(model, targets, opts, &mut ws.weights) {
        return FrameFit {
            cost: f64::NAN,
            iterations: 0,
            status,
        };
    }
    let active = std::mem::take(&mut ws.all);
    let (cost, iterations, end) = lm(model, p, targets, q, &active, opts, ws);
    ws.all = active;
    FrameFit {
        cost,
        iterations,
        status: match end {
            Termination::Converged => FrameStatus::Converged,
            Termination::Stalled => FrameStatus::Stalled,
            Termination::IterationLimit => FrameStatus::MaxIterations,
        },
    }
}

/// A starting point for a frame with no previous solution: defaults everywhere, then the
/// coordinates of the joints of root segments fitted to those segments' markers alone from
/// several starting orientations (every rotational root coordinate at 0, ±90° or 180°).
pub fn seed_frame(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> Vec<f64> {
    let mut q = model.default_coords();
    let roots: Vec<usize> = (0..model.segments.len())
        .filter(|&s| model.segments[s].parent.is_none())
        .collect();
    let full_weights = {
        let _ = frame_weights(model, targets, opts, &mut ws.weights);
        ws.weights.clone()
    };
    for &root in &roots {
        let joint = &model.joints[model.segments[root].joint.0];
        let active: Vec<usize> =
            (joint.first_coord..joint.first_coord + joint.kind.dof()).collect();
        if active.is_empty() {
            continue;
        }
        // Only this root's markers count.
        for (j, m) in model.markers.iter().enumerate() {
            ws.weights[j] = if m.segment.0 == root {
                full_weights[j]
            } else {
                0.0
            };
        }
        if ws.weights.iter().filter(|&&w| w > 0.0).count() < 3 {
            continue;
        }
        // Translations start at their default values (the cost is quadratic in them, so the
        // first iterations carry them to the markers, however far); rotations from a grid.
        let rot: Vec<usize> = active
            .iter()
            .copied()
            .filter(|&c| model.coordinates[c].kind == CoordKind::Rotational)
            .collect();
        let grid = [
            0.0,
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::PI,
            -std::f64::consts::FRAC_PI_2,
        ];
        // Every start gets a few iterations; the most promising few are then converged
        // (the correct basin is clear long before convergence, and most starts are far).
        let starts = grid.len().pow(rot.len() as u32);
        let mut candidates: Vec<(f64, Vec<f64>)> = (0..starts)
            .map(|s| {
                let mut qs = q.clone();
                let mut k = s;
                for &c in &rot {
                    qs[c] = grid[k % grid.len()];
                    k /= grid.len();
                }
                let scout = IkOptions {
                    max_iterations: SEED_SCOUT_ITERATIONS,
                    ..*opts
                };
                let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &scout, ws);
                (cost, qs)
            })
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        candidates.truncate(SEED_FINALISTS);
        let mut best: Option<(f64, Vec<f64>)> = None;
        let seed_opts = IkOptions {
            max_iterations: 15,
            ..*opts
        };
        for (_, mut qs) in candidates {
            let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &seed_opts, ws);
            for &c in &rot {
                qs[c] = wrap_angle(qs[c]);
            }
            // Equal fits (e.g. the two Euler-angle solutions of one orientation): prefer the
            // one with the smaller angles, so results do not depend on the start order.
            let size: f64 = rot.iter().map(|&c| qs[c].abs()).sum();
            let better = match &best {
                None => true,
                Some((b, bq)) => {
                    let bsize: f64 = rot.iter().map(|&c| bq[c].abs()).sum();
                    let tie = (cost - b).abs() <= 1e-9 * b.max(1e-12);
                    if tie {
                        size < bsize - 1e-9
                    } else {
                        cost < *b
                    }
                }
            };
            if better {
                best = Some((cost, qs));
            }
        }
        if let Some((_, qs)) = best {
            for &c in &active {
                q[c] = qs[c];
            }
        }
    }
    ws.weights.copy_from_slice(&full_weights);
    q
}

/// Iterations every seeding start gets before the finalists are chosen.
const SEED_SCOUT_ITERATIONS: usize = 3;
/// Starts converged fully when seeding.
const SEED_FINALISTS: usize = 8;

/// The angle in (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

/// Inverse kinematics of a whole trial.
#[derive(Debug, Clone)]
pub struct TrialFit {
    /// Coordinates per frame (`n_q` each; NaN for frames not solved).
    pub coords: Vec<Vec<f64>>,
    pub frames: Vec<FrameFit>,
    /// Marker distance errors `‖m − x‖` per frame and model marker (m; NaN when missing).
    pub errors: Vec<Vec<f64>>,
}

impl TrialFit {
    /// RMS marker distance of one frame over its present markers (m).
    pub fn frame_rms(&self, frame: usize) -> f64 {
        rms(self.errors[frame].iter().copied())
    }
    /// RMS over all frames of one model marker (m).
    pub fn marker_rms(&self, marker: usize) -> f64 {
        rms(self.errors.iter().map(|e| e[marker]))
    }
    /// RMS marker distance over every present sample of the trial (m).
    pub fn overall_rms(&self) -> f64 {
        rms(self.errors.iter().flatten().copied())
    }
}

/// Root mean square of the non-NaN values (NaN when there are none).
pub fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for v in values.filter(|v| !v.is_nan()) {
        s += v * v;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// The start for the next frame: the last two solutions extrapolated linearly,
/// `q_i⁰ = 2 q_{i−1} − q_{i−2}`. At mocap rates the coordinates are smooth, so this starts
/// within `O(Δt²)` of the solution instead of `O(Δt)`, which saves about one Gauss-Newton
/// iteration per frame.
pub fn extrapolate(prev: &[f64], before: &[f64]) -> Vec<f64> {
    prev.iter().zip(before).map(|(a, b)| 2.0 * a - b).collect()
}

/// Solves every frame of `trial` in order with warm starts (see the module docs): the first
/// frame (and the first after a frame that could not be solved) from [`seed_frame`], the
/// second from the first, later ones from the linear extrapolation of the two before.
pub fn solve_trial(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
) -> Result<TrialFit, IkError> {
    if p.len() != model.n_p() {
        return Err(IkError::ParamLength {
            got: p.len(),
            expected: model.n_p(),
        });
    }
    let mut ws = IkWorkspace::new(model);
    let mut targets = Vec::with_capacity(model.n_markers());
    // The last two solutions when they belong to consecutive frames.
    let mut q: Option<Vec<f64>> = None;
    let mut q_before: Option<Vec<f64>> = None;
    let mut out = TrialFit {
        coords: Vec::with_capacity(trial.n_frames()),
        frames: Vec::with_capacity(trial.n_frames()),
        errors: Vec::with_capacity(trial.n_frames()),
    };
    for f in 0..trial.n_frames() {
        map.targets(trial, f, &mut targets);
        let mut qf = match (&q, &q_before) {
            (Some(prev), Some(before)) => extrapolate(prev, before),
            (Some(prev), None) => prev.clone(),
            (None, _) => seed_frame(model, p, &targets, opts, &mut ws),
        };
        let fit = solve_frame(model, p, &targets, &mut qf, opts, &mut ws);
        if fit.solved() {
            let errs = (0..model.n_markers())
                .map(|j| (targets[j] - ws.cur.markers[j]).norm())
                .collect();
            out.errors.push(errs);
            out.coords.push(qf.clone());
            q_before = q.replace(qf);
        } else {
            out.errors.push(vec![f64::NAN; model.n_markers()]);
            out.coords.push(vec![f64::NAN; model.n_q()]);
            // Across a gap the velocity is unknown: restart from the last solution alone.
            q_before = None;
        }
        out.frames.push(fit);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};

    /// The moment form of the normal equations against `JᵀWJ`, `JᵀW r` built from the
    /// explicit Jacobian (itself proven against finite differences), with missing markers,
    /// unequal weights and a subset of active coordinates.
    #[test]
    fn moments_match_explicit_jacobian() {
        let mut spec = lower_limb(Side::Left);
        for (k, m) in spec.markers.iter_mut().enumerate() {
            m.weight = 0.5 + (k % 3) as f64;
        }
        let model = Model::compile(&spec).unwrap();
        let p = model.nominal_params();
        let mut kin = KinData::new(&model);
        for case in 0..6 {
            let q: Vec<f64> = (0..model.n_q())
                .map(|i| 0.4 * ((i * 7 + case * 3) as f64).sin())
                .collect();
            forward_kinematics(&model, &p, &q, Want::DQ, &mut kin);
            let targets: Vec<Vector3<f64>> = kin
                .markers
                .iter()
                .enumerate()
                .map(|(j, x)| x + 0.01 * Vector3::new((j as f64).sin(), 0.3, (case as f64).cos()))
                .collect();
            let weights: Vec<f64> = model
                .markers
                .iter()
                .enumerate()
                .map(|(j, m)| if (j + case) % 5 == 0 { 0.0 } else { m.weight })
                .collect();
            let active: Vec<usize> = (0..model.n_q())
                .filter(|c| case % 2 == 0 || c % 3 != 1)
                .collect();
            let n = active.len();
            let mut moments = Moments::new(&model);
            moments.set_active(&active);
            let (mut a, mut g) = (vec![0.0; n * n], vec![0.0; n]);
            moments.normal_equations(&kin, &targets, &weights, n, &mut a, &mut g);
            let jq = kin.jq();
            let scale = jq.norm_squared();
            for (ai, &ca) in active.iter().enumerate() {
                let mut g_ref = 0.0;
                for (j, &w) in weights.iter().enumerate() {
                    let r = targets[j] - kin.markers[j];
                    for k in 0..3 {
                        g_ref += w * jq[(3 * j + k, ca)] * r[k];
                    }
                }
                assert!(
                    (g[ai] - g_ref).abs() <= 1e-12 * scale,
                    "g[{ai}] case {case}"
                );
                for (bi, &cb) in active.iter().enumerate() {
                    let mut a_ref = 0.0;
                    for (j, &w) in weights.iter().enumerate() {
                        for k in 0..3 {
                            a_ref += w * jq[(3 * j + k, ca)] * jq[(3 * j + k, cb)];
                        }
                    }
                    let got = a[bi * n + ai];
                    assert!(
                        (got - a_ref).abs() <= 1e-12 * scale,
                        "A[{ai},{bi}] case {case}: {got} vs {a_ref}"
                    );
                }
            }
        }
    }
}
