//! Joint sparse Levenberg–Marquardt over all frames' coordinates and the parameters.
//!
//! See the parent module for the objective and [`super::schur`] for the linear algebra. Bounds
//! are handled by projection: a step is clamped to `[−1, 1]`, the coordinate steps are
//! recomputed for the clamped parameter step, and parameters at a bound whose descent
//! direction points outward are held for the step.

use super::schur::{active_bounds, assemble, back_substitute, cost_at, solve, Blocks};
use super::{Fit, Problem};
use crate::solver::{Observer, Termination};

/// Settings of the joint solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointOptions {
    pub max_iterations: usize,
    /// Converged when every parameter step (scaled units) and coordinate step (rad, m) is
    /// below this.
    pub tolerance: f64,
}

impl Default for JointOptions {
    fn default() -> Self {
        JointOptions {
            max_iterations: 200,
            tolerance: 1e-10,
        }
    }
}

/// Relative decrease of the objective below which an accepted step ends the solve.
const COST_TOLERANCE: f64 = 1e-14;

/// Minimises the objective from scaled parameters `s0` and coordinates `q0` (one per frame).
/// `observer.iteration(iteration, cost)` is called after every outer iteration (the same
/// values as [`Fit::history`]); it cannot change the result.
///
/// Ends [`Termination::Converged`] on a step below `tolerance` or a relative decrease below
/// 1e-14, [`Termination::Stalled`] when no damping up to 1e16 gives a step that does not
/// raise the objective, [`Termination::IterationLimit`] after `max_iterations`.
pub fn solve_joint(
    prob: &Problem,
    s0: &[f64],
    q0: Vec<Vec<f64>>,
    opts: &JointOptions,
    observer: &mut dyn Observer,
) -> Fit {
    let nq = prob.model.n_q();
    let nf = prob.n_free();
    let frames = prob.frames.len();
    let mut blocks = Blocks::new(prob);
    let mut s: Vec<f64> = s0.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
    let mut qs = q0;
    let mut ds = vec![0.0; nf];
    let mut dq = vec![vec![0.0; nq]; frames];
    let mut lambda = 1e-4;
    // Nielsen's damping update: the growth factor for a rejected step doubles each time.
    let mut nu = 2.0;
    let mut history = Vec::new();
    let mut evaluations = 0;
    let mut iterations = 0;
    let mut termination = Termination::IterationLimit;
    let mut p = prob.to_params(&s);
    assemble(prob, &p, &qs, &mut blocks);
    evaluations += 1;
    let mut cost = blocks.cost;
    while iterations < opts.max_iterations {
        iterations += 1;
        let fixed = active_bounds(&s, &blocks.gs);
        let mut accepted = false;
        let mut step = 0.0f64;
        let mut decrease = 0.0;
        while lambda < 1e16 {
            if !solve(prob, &qs, &mut blocks, lambda, &fixed, &mut ds) {
                lambda *= 10.0;
                continue;
            }
            let s_try: Vec<f64> = s
                .iter()
                .zip(&ds)
                .map(|(a, d)| (a + d).clamp(-1.0, 1.0))
                .collect();
            let ds_eff: Vec<f64> = s_try.iter().zip(&s).map(|(a, b)| a - b).collect();
            let predicted = back_substitute(prob, &qs, &blocks, &ds_eff, &mut dq);
            let q_try: Vec<Vec<f64>> = qs
                .iter()
                .zip(&dq)
                .map(|(q, d)| q.iter().zip(d).map(|(a, b)| a + b).collect())
                .collect();
            let p_try = prob.to_params(&s_try);
            let c = cost_at(prob, &blocks, &p_try, &q_try);
            evaluations += 1;
            if c <= cost {
                step = ds_eff
                    .iter()
                    .chain(dq.iter().flatten())
                    .fold(0.0f64, |m, v| m.max(v.abs()));
                // Gain ratio ρ = actual / predicted decrease: near 1 the quadratic model is
                // good and the damping shrinks by up to 3; a poor model keeps it.
                let rho = if predicted > 0.0 {
                    (cost - c) / predicted
                } else {
                    0.0
                };
                lambda = (lambda * (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0)).max(1e-12);
                nu = 2.0;
                decrease = cost - c;
                s = s_try;
                qs = q_try;
                p = p_try;
                cost = c;
                accepted = true;
                break;
            }
            lambda *= nu;
            nu *= 2.0;
        }
        history.push(cost);
        observer.iteration(iterations, cost);
        if !accepted {
            termination = Termination::Stalled;
            break;
        }
        // Converged on a negligible step, or when the objective no longer moves at working
        // precision (the last digits of a linearly converging tail change nothing).
        if step < opts.tolerance || decrease <= COST_TOLERANCE * cost {
            termination = Termination::Converged;
            break;
        }
        assemble(prob, &p, &qs, &mut blocks);
        evaluations += 1;
        cost = blocks.cost;
    }
    Fit {
        s,
        p,
        coords: qs,
        cost,
        iterations,
        evaluations,
        history,
        termination,
    }
}
