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
//! Frames are solved in order, each warm-started from the previous solution (the paper's
//! scheme). The first frame is seeded from the root segment's markers alone: the root joint's
//! coordinates are fitted from several starting orientations and the best fit is kept, the
//! other coordinates start at their defaults. A frame in which some segment that carries
//! markers has fewer than three of them present is reported, not guessed.

use nalgebra::Vector3;
use thiserror::Error;

use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::model::{CoordKind, Model};
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
    /// Stop when the largest accepted step component is below this (rad or m).
    pub step_tolerance: f64,
    /// Minimum present markers on every segment that carries markers.
    pub min_markers_per_segment: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            max_iterations: 100,
            step_tolerance: 1e-11,
            min_markers_per_segment: 3,
        }
    }
}

/// Which trial column feeds each model marker.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerMap {
    /// `columns[j]`: trial column of model marker `j`.
    pub columns: Vec<usize>,
}

impl MarkerMap {
    /// Matches model markers to trial labels by name; every model marker must be present.
    pub fn by_name(model: &Model, labels: &[String]) -> Result<MarkerMap, IkError> {
        let mut columns = Vec::with_capacity(model.n_markers());
        let mut missing = Vec::new();
        for m in &model.markers {
            match labels.iter().position(|l| l == &m.name) {
                Some(c) => columns.push(c),
                None => missing.push(m.name.clone()),
            }
        }
        if !missing.is_empty() {
            return Err(IkError::MissingMarkers {
                missing,
                available: labels.join(", "),
            });
        }
        Ok(MarkerMap { columns })
    }

    /// The model-ordered targets of one trial frame (NaN where missing).
    pub fn targets(&self, trial: &Trial, frame: usize, out: &mut Vec<Vector3<f64>>) {
        let row = trial.frame(frame);
        out.clear();
        out.extend(self.columns.iter().map(|&c| row[c]));
    }
}

/// How a frame ended.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameStatus {
    Converged,
    /// The iteration budget ran out (the result is the best point found).
    MaxIterations,
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
    q_trial: Vec<f64>,
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
            q_trial: vec![0.0; n],
        }
    }
    /// Kinematics at the last solution (markers, Jacobian of the last accepted point).
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
/// weights already in `ws.weights`. Returns (cost, iterations, converged).
fn lm(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    q: &mut [f64],
    active: &[usize],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> (f64, usize, bool) {
    let n = active.len();
    let nrows = 3 * model.n_markers();
    forward_kinematics(model, p, q, Want::DQ, &mut ws.cur);
    let mut cost = cost_of(&ws.cur.markers, targets, &ws.weights);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < opts.max_iterations {
        iterations += 1;
        // Normal equations over the active columns.
        let jq = ws.cur.jq().as_slice();
        for (ai, &ca) in active.iter().enumerate() {
            let col_a = &jq[ca * nrows..(ca + 1) * nrows];
            let mut g = 0.0;
            for (j, &w) in ws.weights.iter().enumerate() {
                if w > 0.0 {
                    let r = targets[j] - ws.cur.markers[j];
                    g += w * (col_a[3 * j] * r.x + col_a[3 * j + 1] * r.y + col_a[3 * j + 2] * r.z);
                }
            }
            ws.g[ai] = g;
            for (bi, &cb) in active.iter().enumerate().take(ai + 1) {
                let col_b = &jq[cb * nrows..(cb + 1) * nrows];
                let mut s = 0.0;
                for (j, &w) in ws.weights.iter().enumerate() {
                    if w > 0.0 {
                        s += w
                            * (col_a[3 * j] * col_b[3 * j]
                                + col_a[3 * j + 1] * col_b[3 * j + 1]
                                + col_a[3 * j + 2] * col_b[3 * j + 2]);
                    }
                }
                ws.a[bi * n + ai] = s;
                ws.a[ai * n + bi] = s;
            }
        }
        let max_diag = (0..n).fold(0.0f64, |m, i| m.max(ws.a[i * n + i]));
        // Try steps with growing damping until the cost drops.
        let mut accepted = false;
        let mut step_max = 0.0f64;
        while lambda < 1e12 {
            ws.l[..n * n].copy_from_slice(&ws.a[..n * n]);
            for i in 0..n {
                ws.l[i * n + i] += lambda * ws.a[i * n + i] + 1e-14 * max_diag + 1e-300;
            }
            if !cholesky_in_place(&mut ws.l[..n * n], n) {
                lambda *= 10.0;
                continue;
            }
            let mut delta = ws.g[..n].to_vec();
            cholesky_solve(&ws.l[..n * n], n, &mut delta);
            ws.q_trial.copy_from_slice(q);
            for (i, &c) in active.iter().enumerate() {
                ws.q_trial[c] += delta[i];
            }
            forward_kinematics(model, p, &ws.q_trial, Want::DQ, &mut ws.trial);
            let trial_cost = cost_of(&ws.trial.markers, targets, &ws.weights);
            if trial_cost <= cost {
                step_max = delta.iter().fold(0.0f64, |m, d| m.max(d.abs()));
                q.copy_from_slice(&ws.q_trial);
                std::mem::swap(&mut ws.cur, &mut ws.trial);
                cost = trial_cost;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                break;
            }
            lambda *= 10.0;
        }
        if !accepted || step_max < opts.step_tolerance {
            // No descent possible at machine precision, or the step vanished: converged.
            return (cost, iterations, true);
        }
    }
    (cost, iterations, false)
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
    let active: Vec<usize> = (0..model.n_q()).collect();
    let (cost, iterations, converged) = lm(model, p, targets, q, &active, opts, ws);
    FrameFit {
        cost,
        iterations,
        status: if converged {
            FrameStatus::Converged
        } else {
            FrameStatus::MaxIterations
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
        // Translations start at the centroid offset; rotations from a grid.
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
        let starts = grid.len().pow(rot.len() as u32);
        let mut best: Option<(f64, Vec<f64>)> = None;
        let seed_opts = IkOptions {
            max_iterations: 50,
            ..*opts
        };
        for s in 0..starts {
            let mut qs = q.clone();
            let mut k = s;
            for &c in &rot {
                qs[c] = grid[k % grid.len()];
                k /= grid.len();
            }
            let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &seed_opts, ws);
            if best.as_ref().is_none_or(|(b, _)| cost < *b) {
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

/// Solves every frame of `trial` in order with warm starts (see the module docs).
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
    let mut q: Option<Vec<f64>> = None;
    let mut out = TrialFit {
        coords: Vec::with_capacity(trial.n_frames()),
        frames: Vec::with_capacity(trial.n_frames()),
        errors: Vec::with_capacity(trial.n_frames()),
    };
    for f in 0..trial.n_frames() {
        map.targets(trial, f, &mut targets);
        let mut qf = match &q {
            Some(prev) => prev.clone(),
            None => seed_frame(model, p, &targets, opts, &mut ws),
        };
        let fit = solve_frame(model, p, &targets, &mut qf, opts, &mut ws);
        if fit.solved() {
            let errs = (0..model.n_markers())
                .map(|j| (targets[j] - ws.cur.markers[j]).norm())
                .collect();
            out.errors.push(errs);
            out.coords.push(qf.clone());
            q = Some(qf);
        } else {
            out.errors.push(vec![f64::NAN; model.n_markers()]);
            out.coords.push(vec![f64::NAN; model.n_q()]);
        }
        out.frames.push(fit);
    }
    Ok(out)
}
