//! Levenberg–Marquardt on one frame: marker weights, the damped Gauss-Newton loop and the
//! per-frame entry point.

use nalgebra::Vector3;

use super::normal::Moments;
use super::solvable::Solvability;
use super::tasks::goal_cost;
use super::{FrameFit, FrameStatus, IkOptions};
use crate::kinematics::{forward_kinematics_axes, KinData};
use crate::linalg::Cholesky;
use crate::model::Model;
use crate::solver::Termination;

/// Scratch space for one thread, and the per-frame solver: reuse it across frames. A frame
/// with no solution at hand starts from [`IkWorkspace::seed`]; [`IkWorkspace::solve`] then
/// solves it (or solves from the previous frame's solution).
#[derive(Debug, Clone)]
pub struct IkWorkspace {
    pub(super) cur: KinData,
    pub(super) trial: KinData,
    pub(super) weights: Vec<f64>,
    pub(super) a: Vec<f64>,
    pub(super) l: Vec<f64>,
    pub(super) g: Vec<f64>,
    pub(super) delta: Vec<f64>,
    pub(super) q_trial: Vec<f64>,
    pub(super) active: Vec<usize>,
    pub(super) start: Vec<f64>,
    pub(super) moments: Moments,
    pub(super) solvability: Solvability,
    /// Per coordinate, `[lower, upper]` for OpenSim-`clamped` coordinates, `[−∞, ∞]` else.
    pub(super) bounds: Vec<[f64; 2]>,
    /// Whether any coordinate is clamped.
    pub(super) any_clamped: bool,
    /// The coordinate tasks of the current frame: `(coordinate, weight, target)`
    /// ([`super::tasks`]); empty unless set by [`IkWorkspace::set_coordinate_goals`].
    pub(super) goals: Vec<(usize, f64, f64)>,
    /// Per coordinate: whether a task of the current frame determines it.
    pub(super) known: Vec<bool>,
}

impl IkWorkspace {
    pub fn new(model: &Model) -> Self {
        let n = model.coordinates().len();
        IkWorkspace {
            cur: KinData::new(model),
            trial: KinData::new(model),
            weights: vec![0.0; model.markers().len()],
            a: vec![0.0; n * n],
            l: vec![0.0; n * n],
            g: vec![0.0; n],
            delta: vec![0.0; n],
            q_trial: vec![0.0; n],
            active: Vec::with_capacity(n),
            start: vec![0.0; n],
            moments: Moments::new(model),
            solvability: Solvability::new(model),
            bounds: model
                .coordinates()
                .iter()
                .map(|c| {
                    if c.clamped {
                        c.range
                    } else {
                        [f64::NEG_INFINITY, f64::INFINITY]
                    }
                })
                .collect(),
            any_clamped: model.coordinates().iter().any(|c| c.clamped),
            goals: Vec::new(),
            known: vec![false; n],
        }
    }
    /// A start for the frame whose model-ordered marker `targets` (m, NaN when missing) are
    /// given, without a solution at hand: the root segment's coordinates fitted to its
    /// markers from several starting orientations, the other coordinates at their defaults
    /// (see the module docs of [`crate::ik`]).
    pub fn seed(
        &mut self,
        model: &Model,
        p: &[f64],
        targets: &[Vector3<f64>],
        opts: &IkOptions,
    ) -> Vec<f64> {
        super::seed_frame(model, p, targets, opts, self)
    }
    /// Solves one frame in place from the start `q` (the solution on exit), with one
    /// target per model marker (m, NaN when missing): Levenberg–Marquardt once the present
    /// markers are found to determine the coordinates, with gross errors rejected (see the
    /// module docs of [`crate::ik`]).
    pub fn solve(
        &mut self,
        model: &Model,
        p: &[f64],
        targets: &[Vector3<f64>],
        q: &mut [f64],
        opts: &IkOptions,
    ) -> FrameFit {
        solve_frame(model, p, targets, q, opts, self)
    }
    /// Sets the coordinate tasks the next frames solved with this workspace obey: those of
    /// trial frame `frame` ([`super::CoordinateTask`]; an empty slice: none).
    pub(crate) fn set_coordinate_goals(&mut self, tasks: &[super::CoordinateTask], frame: usize) {
        super::tasks::frame_goals(tasks, frame, &mut self.goals, &mut self.known);
    }
    /// Kinematics at the last solution (marker positions of the last accepted point).
    pub(crate) fn kin(&self) -> &KinData {
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

/// A marker sample farther than this from the laboratory origin (m) is a gross error.
const ABSURD_DISTANCE: f64 = 1e3;

/// The present marker farthest from its model position when it is a gross error (see
/// [`IkOptions::outlier_distance`]).
fn gross_error(targets: &[Vector3<f64>], ws: &IkWorkspace, opts: &IkOptions) -> Option<usize> {
    let mut worst = None;
    let mut farthest = opts.outlier_distance;
    for (j, &w) in ws.weights.iter().enumerate() {
        if w > 0.0 {
            let d = (targets[j] - ws.cur.markers[j]).norm();
            if d > farthest {
                farthest = d;
                worst = Some(j);
            }
        }
    }
    // Rare path: only frames with a large residual pay for the median.
    worst?;
    let mut d: Vec<f64> = (0..targets.len())
        .filter(|&j| ws.weights[j] > 0.0)
        .map(|j| (targets[j] - ws.cur.markers[j]).norm())
        .collect();
    d.sort_by(f64::total_cmp);
    let median = if d.len() % 2 == 1 {
        d[d.len() / 2]
    } else {
        0.5 * (d[d.len() / 2 - 1] + d[d.len() / 2])
    };
    worst.filter(|_| farthest > opts.outlier_ratio * median)
}

/// Whether a (non-NaN) marker sample is a gross error: not finite, or farther than 1 km from
/// the laboratory origin.
pub(crate) fn is_gross(t: &Vector3<f64>) -> bool {
    let d = t.norm();
    !d.is_finite() || d >= ABSURD_DISTANCE
}

/// The first coordinate the present markers of `targets` leave undetermined at parameters
/// `p` ([`super::solvable`]); `None` when the frame is solvable.
pub(crate) fn undetermined_coordinate(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> Option<usize> {
    let mut rejected = Vec::new();
    frame_weights(model, targets, &mut ws.weights, &mut rejected);
    ws.solvability
        .undetermined(model, p, &ws.weights, &ws.known, opts)
        .first()
        .copied()
}

/// Sets marker weights for a frame: the model weight, 0 when missing (any coordinate NaN) or
/// absurd (not finite, or beyond [`ABSURD_DISTANCE`]); absurd samples are listed in `rejected`.
pub(super) fn frame_weights(
    model: &Model,
    targets: &[Vector3<f64>],
    w: &mut [f64],
    rejected: &mut Vec<usize>,
) {
    rejected.clear();
    for (j, m) in model.markers().iter().enumerate() {
        let t = &targets[j];
        w[j] = 0.0;
        if m.weight <= 0.0 || t.iter().any(|v| v.is_nan()) {
            continue;
        }
        if is_gross(t) {
            rejected.push(j);
            continue;
        }
        w[j] = m.weight;
    }
}

/// Levenberg–Marquardt over the coordinates listed in `active` (others fixed), with the
/// weights already in `ws.weights`. Returns (cost, iterations, how it ended).
pub(super) fn lm(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    q: &mut [f64],
    active: &[usize],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> (f64, usize, Termination) {
    let n = active.len();
    let bounded = opts.clamp && ws.any_clamped;
    if bounded {
        for &c in active {
            q[c] = q[c].clamp(ws.bounds[c][0], ws.bounds[c][1]);
        }
    }
    ws.moments.set_active(active);
    forward_kinematics_axes(model, p, q, &mut ws.cur);
    // The coordinate tasks' scale: the frame's total marker weight ([`super::tasks`]).
    let total: f64 = if ws.goals.is_empty() {
        0.0
    } else {
        ws.weights.iter().sum()
    };
    let mut cost = cost_of(&ws.cur.markers, targets, &ws.weights) + goal_cost(q, &ws.goals, total);
    let mut lambda = 1e-6;
    let mut iterations = 0;
    // Largest component of the last accepted step (for the contraction estimate).
    let mut last_step = f64::INFINITY;
    while iterations < opts.max_iterations {
        iterations += 1;
        normal_equations(targets, q, active, total, bounded, ws);
        let max_diag = (0..n).fold(0.0f64, |m, i| m.max(ws.a[i * n + i]));
        // Try steps with growing damping until the cost drops.
        loop {
            ws.l[..n * n].copy_from_slice(&ws.a[..n * n]);
            for i in 0..n {
                ws.l[i * n + i] += lambda * ws.a[i * n + i] + 1e-14 * max_diag + 1e-300;
            }
            let Some(chol) = Cholesky::factor(&mut ws.l[..n * n], n) else {
                last_step = f64::INFINITY;
                lambda *= 10.0;
                if lambda > 1e10 {
                    return (cost, iterations, Termination::Stalled);
                }
                continue;
            };
            ws.delta[..n].copy_from_slice(&ws.g[..n]);
            chol.solve(&mut ws.delta[..n]);
            let step_max = trial_point(q, active, bounded, ws);
            forward_kinematics_axes(model, p, &ws.q_trial, &mut ws.trial);
            let trial_cost = cost_of(&ws.trial.markers, targets, &ws.weights)
                + goal_cost(&ws.q_trial, &ws.goals, total);
            if trial_cost <= cost {
                q.copy_from_slice(&ws.q_trial);
                std::mem::swap(&mut ws.cur, &mut ws.trial);
                cost = trial_cost;
                lambda = (lambda / 10.0).max(1e-12);
                if step_max < opts.step_tolerance
                    || remaining_error(step_max, last_step) < opts.step_tolerance
                {
                    return (cost, iterations, Termination::Converged);
                }
                last_step = step_max;
                break;
            }
            if step_max < opts.step_tolerance || below_roundoff(n, cost, ws) {
                // Even a negligible step does not lower the cost, or the step's predicted
                // decrease is below what the cost resolves: minimum to working precision.
                return (cost, iterations, Termination::Converged);
            }
            // A damped step is shorter than the iteration's own: no contraction estimate
            // across it.
            last_step = f64::INFINITY;
            lambda *= 10.0;
            if lambda > 1e10 {
                return (cost, iterations, Termination::Stalled);
            }
        }
    }
    (cost, iterations, Termination::IterationLimit)
}

/// The frame's Gauss–Newton normal equations at `ws.cur` into `ws.a`, `ws.g` (over the
/// `active` coordinates), with the coordinate tasks weighed by `total` and, when `bounded`,
/// the coordinates at a bound held there.
fn normal_equations(
    targets: &[Vector3<f64>],
    q: &[f64],
    active: &[usize],
    total: f64,
    bounded: bool,
    ws: &mut IkWorkspace,
) {
    let n = active.len();
    ws.moments
        .normal_equations(&ws.cur, targets, &ws.weights, n, &mut ws.a, &mut ws.g);
    for &(c, w, v) in &ws.goals {
        if let Some(i) = active.iter().position(|&a| a == c) {
            ws.a[i * n + i] += total * w;
            ws.g[i] += total * w * (v - q[c]);
        }
    }
    if bounded {
        hold_at_bounds(q, active, &ws.bounds, &mut ws.a, &mut ws.g);
    }
}

/// The trial point `q + δ` (`δ` in `ws.delta`) in `ws.q_trial`, projected into the bounds
/// when `bounded`; returns the step's length (its largest component, after projection).
fn trial_point(q: &[f64], active: &[usize], bounded: bool, ws: &mut IkWorkspace) -> f64 {
    let n = active.len();
    let mut step_max = ws.delta[..n].iter().fold(0.0f64, |m, d| m.max(d.abs()));
    ws.q_trial.copy_from_slice(q);
    for (i, &c) in active.iter().enumerate() {
        ws.q_trial[c] += ws.delta[i];
    }
    if bounded {
        // Projected step: the box's nearest point, and its length as the step.
        step_max = 0.0;
        for &c in active {
            let [lo, hi] = ws.bounds[c];
            ws.q_trial[c] = ws.q_trial[c].clamp(lo, hi);
            step_max = step_max.max((ws.q_trial[c] - q[c]).abs());
        }
    }
    step_max
}

/// Relative rounding error of a marker position from forward kinematics, in units of the
/// machine epsilon: a few rotations and translations in a chain of about five segments.
const POSITION_ROUNDOFF_EPS: f64 = 16.0;

/// Whether the rejected step `δ` (`ws.delta`, before any projection into the bounds) is below what
/// the cost can resolve: its Gauss–Newton predicted decrease `2 gᵀδ − δᵀAδ` (`A`, `g` of this
/// iteration in `ws`) is smaller than the cost's own rounding error. (A projected step decreases
/// the model by less than the model's own step, so nothing resolvable is lost; its own prediction
/// would not do: a projection can make it negative far from any minimum.) A marker position `x_j`
/// carries an absolute error of about `c ε ‖x_j‖` (positions are measured from the laboratory
/// origin, metres away), so `w_j ‖t_j − x_j‖²` carries `2 c ε w_j ‖t_j − x_j‖ ‖x_j‖`, and by
/// Cauchy–Schwarz the cost at most `2 c ε √(cost · Σ w_j ‖x_j‖²)`. Damping such a step further
/// cannot produce a decrease the cost would show (a trial's cost differs from the current one by
/// rounding alone): on opencap walking1, with the calibration's step tolerance of 1e-11, 5 200 of
/// the inner level's 13 300 forward kinematics were such retries.
fn below_roundoff(n: usize, cost: f64, ws: &IkWorkspace) -> bool {
    let d = &ws.delta[..n];
    let mut predicted = 0.0;
    for i in 0..n {
        let ad: f64 = (0..n).map(|k| ws.a[k * n + i] * d[k]).sum();
        predicted += d[i] * (2.0 * ws.g[i] - ad);
    }
    let scale: f64 = ws
        .weights
        .iter()
        .zip(&ws.cur.markers)
        .filter(|(&w, _)| w > 0.0)
        .map(|(&w, x)| w * x.norm_squared())
        .sum();
    predicted <= 2.0 * POSITION_ROUNDOFF_EPS * f64::EPSILON * (cost * scale).sqrt()
}

/// Projected Gauss-Newton for box bounds (Bertsekas, *SIAM J. Control Optim.* 20:221–246,
/// 1982): a coordinate at a bound whose descent direction (`g = JᵀW r`, the step's right-hand
/// side) points out of the box is held for this iteration: its row and column of the normal
/// matrix are zeroed (the diagonal kept) and its `g` set to 0, so its step is exactly 0 and
/// the other coordinates are solved with it fixed. The trial point is then projected into
/// the box ([`lm`]).
fn hold_at_bounds(q: &[f64], active: &[usize], bounds: &[[f64; 2]], a: &mut [f64], g: &mut [f64]) {
    let n = active.len();
    for (i, &c) in active.iter().enumerate() {
        let [lo, hi] = bounds[c];
        if (q[c] <= lo && g[i] < 0.0) || (q[c] >= hi && g[i] > 0.0) {
            g[i] = 0.0;
            for k in 0..n {
                if k != i {
                    a[i * n + k] = 0.0;
                    a[k * n + i] = 0.0;
                }
            }
        }
    }
}

/// Largest contraction ratio of two successive steps for which [`remaining_error`] trusts
/// the estimate: above it the iteration is not yet contracting steadily.
const MAX_CONTRACTION: f64 = 0.5;

/// The distance still to go after an accepted step of size `step` that followed one of size
/// `last` (largest components), estimated from their ratio `ρ = step / last`: where the
/// iteration contracts linearly with rate `ρ`, the steps still to come sum to at most
/// `step · ρ / (1 − ρ)` (a geometric series; the a-posteriori bound of a contraction, e.g.
/// Kelley, *Iterative Methods for Linear and Nonlinear Equations*, SIAM 1995, §4.2), and
/// where it converges faster the bound holds all the more. Infinite (no estimate) before two
/// steps or when `ρ > MAX_CONTRACTION`.
fn remaining_error(step: f64, last: f64) -> f64 {
    let rho = step / last;
    if last.is_finite() && rho <= MAX_CONTRACTION {
        step * rho / (1.0 - rho)
    } else {
        f64::INFINITY
    }
}

/// Solves one frame in place: `q` is the starting point on entry, the solution on exit.
/// `targets` holds one position per model marker (NaN when missing).
///
/// Checks that the present markers determine the coordinates ([`super::solvable`]); rejects
/// gross errors (see the module docs): after each fit, while the marker farthest from its
/// model position is a gross error ([`IkOptions::outlier_distance`]), it is dropped and the
/// frame solved again from the entry point.
pub(crate) fn solve_frame(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    q: &mut [f64],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> FrameFit {
    let mut rejected = Vec::new();
    frame_weights(model, targets, &mut ws.weights, &mut rejected);
    ws.start.copy_from_slice(q);
    let mut iterations = 0;
    loop {
        let undetermined =
            ws.solvability
                .undetermined_at(model, p, &ws.weights, &ws.known, &ws.start, opts);
        if let Some(&c) = undetermined.first() {
            if !opts.hold_undetermined {
                return FrameFit {
                    cost: f64::NAN,
                    iterations,
                    status: FrameStatus::Undetermined {
                        coordinate: model.coordinates()[c].name.clone(),
                    },
                    held: Vec::new(),
                    rejected,
                };
            }
        }
        let held = undetermined;
        let mut active = std::mem::take(&mut ws.active);
        active.clear();
        active.extend((0..model.coordinates().len()).filter(|c| !held.contains(c)));
        q.copy_from_slice(&ws.start);
        let (cost, its, end) = lm(model, p, targets, q, &active, opts, ws);
        ws.active = active;
        iterations += its;
        if !cost.is_finite() || q.iter().any(|v| !v.is_finite()) {
            return FrameFit {
                cost,
                iterations,
                status: FrameStatus::Diverged,
                held,
                rejected,
            };
        }
        let worst = gross_error(targets, ws, opts);
        match worst {
            Some(j) => {
                ws.weights[j] = 0.0;
                rejected.push(j);
            }
            None => {
                return FrameFit {
                    cost,
                    iterations,
                    status: match end {
                        Termination::Converged => FrameStatus::Converged,
                        Termination::Stalled => FrameStatus::Stalled,
                        Termination::IterationLimit => FrameStatus::MaxIterations,
                    },
                    held,
                    rejected,
                }
            }
        }
    }
}
