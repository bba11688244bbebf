//! Levenberg–Marquardt on one frame: marker weights, the damped Gauss-Newton loop and the
//! per-frame entry point.

use nalgebra::Vector3;

use super::normal::Moments;
use super::{FrameFit, FrameStatus, IkOptions};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::linalg::Cholesky;
use crate::model::Model;
use crate::solver::Termination;

/// Scratch space for one thread: reuse it across frames.
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
    pub(super) all: Vec<usize>,
    pub(super) moments: Moments,
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
pub(super) fn frame_weights(
    model: &Model,
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    w: &mut [f64],
) -> Result<(), FrameStatus> {
    let mut present = vec![0usize; model.segments().len()];
    let mut carries = vec![false; model.segments().len()];
    for (j, m) in model.markers().iter().enumerate() {
        let ok = !targets[j].x.is_nan() && m.weight > 0.0;
        w[j] = if ok { m.weight } else { 0.0 };
        if m.weight > 0.0 {
            carries[m.segment.0] = true;
            present[m.segment.0] += ok as usize;
        }
    }
    for s in 0..model.segments().len() {
        if carries[s] && present[s] < opts.min_markers_per_segment {
            return Err(FrameStatus::TooFewMarkers {
                segment: model.segments()[s].name.clone(),
                present: present[s],
            });
        }
    }
    Ok(())
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
