//! The two-level method with an exact outer gradient (variable projection).
//!
//! Every outer iterate solves all inner problems first (`q_i(p)`, warm-started), then takes a
//! Levenberg–Marquardt step on `s` with the reduced Gauss-Newton matrix `S` (the Schur
//! complement of [`super::schur`], which equals `Σ J_red,iᵀ W J_red,i` with the reduced
//! Jacobian `J_red = (I − J_q (J_qᵀWJ_q)⁻¹ J_qᵀW) J_p`) and the envelope-theorem gradient
//! `Σ J_p,iᵀ W r_i`. A step is accepted when the re-solved `e_inner` drops.

use super::schur::{
    active_bounds, assemble, back_substitute, reduce, solve_reduced_at_bounds, Blocks,
};
use super::{Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::solver::{Observer, Termination};

/// Settings of the two-level gradient solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct VarProOptions {
    pub max_iterations: usize,
    /// Converged when every parameter step is below this (scaled units).
    pub tolerance: f64,
}

impl Default for VarProOptions {
    fn default() -> Self {
        VarProOptions {
            max_iterations: 200,
            tolerance: 1e-10,
        }
    }
}

/// The envelope-theorem gradient `∂e_inner/∂s` at `s` with inner solutions `qs`:
/// `−2 Σ_i J_s,iᵀ W r_i` (valid where every `q_i` is an inner optimum).
#[cfg(test)]
pub(crate) fn gradient(prob: &Problem, s: &[f64], qs: &[Vec<f64>]) -> Vec<f64> {
    let mut blocks = Blocks::with_budget(prob, 0);
    assemble(prob, &prob.to_params(s), qs, &mut blocks);
    blocks.gs.iter().map(|g| -2.0 * g).collect()
}

/// Minimises `e_inner` from scaled parameters `s0` with inner solutions warm-started at `q0`.
/// `observer.iteration(iteration, cost)` is called after every outer iteration (the same
/// values as [`Fit::history`]); it cannot change the result.
///
/// Ends [`Termination::Converged`] on a parameter step below `tolerance`,
/// [`Termination::Stalled`] when no damping up to 1e16 lowers `e_inner`,
/// [`Termination::IterationLimit`] after `max_iterations`.
pub(crate) fn solve_varpro(
    prob: &Problem,
    s0: &[f64],
    q0: Vec<Vec<f64>>,
    opts: &VarProOptions,
    observer: &mut dyn Observer,
) -> Fit {
    let nq = prob.model.coordinates().len();
    let nf = prob.n_free();
    let frames = prob.frames.len();
    let mut ws = IkWorkspace::new(prob.model);
    let mut blocks = Blocks::new(prob);
    let mut s: Vec<f64> = s0.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
    let mut p = prob.to_params(&s);
    let mut qs = q0;
    let mut cost = prob.inner(&p, &mut qs, &mut ws);
    let mut evaluations = 1;
    let mut ds = vec![0.0; nf];
    let mut dq = vec![vec![0.0; nq]; frames];
    let mut lambda = 1e-4;
    let mut history = Vec::new();
    let mut iterations = 0;
    let mut termination = Termination::IterationLimit;
    while iterations < opts.max_iterations {
        iterations += 1;
        assemble(prob, &p, &qs, &mut blocks);
        // Held: parameters at a bound pushed out by the gradient or by the coupled step
        // (`schur::solve_reduced_at_bounds`, as in the joint solver).
        let mut fixed = active_bounds(&s, &blocks.gs);
        let mut accepted = false;
        let mut step = 0.0f64;
        while lambda < 1e16 {
            if !(reduce(prob, &qs, &mut blocks, lambda)
                && solve_reduced_at_bounds(&blocks, None, &s, &mut fixed, &mut ds))
            {
                lambda *= 10.0;
                continue;
            }
            back_substitute(prob, &qs, &blocks, &ds, &mut dq);
            let s_try: Vec<f64> = s
                .iter()
                .zip(&ds)
                .map(|(a, d)| (a + d).clamp(-1.0, 1.0))
                .collect();
            let p_try = prob.to_params(&s_try);
            // Warm start from the linearised prediction of the new inner solutions.
            let mut q_try: Vec<Vec<f64>> = qs
                .iter()
                .zip(&dq)
                .map(|(q, d)| q.iter().zip(d).map(|(a, b)| a + b).collect())
                .collect();
            let c = prob.inner(&p_try, &mut q_try, &mut ws);
            evaluations += 1;
            if c <= cost {
                step = s_try
                    .iter()
                    .zip(&s)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                s = s_try;
                p = p_try;
                qs = q_try;
                cost = c;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                break;
            }
            lambda *= 10.0;
        }
        history.push(cost);
        observer.iteration(iterations, cost);
        if !accepted {
            termination = Termination::Stalled;
            break;
        }
        if step < opts.tolerance {
            termination = Termination::Converged;
            break;
        }
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
