//! The Levenberg–Marquardt loop that minimizes `F(θ) = Σ r²` (`fit::residuals`).
//!
//! **Step.** With `g = Jᵀr`, `H = JᵀJ` and Marquardt's diagonal `D = diag(max(H_kk, 10⁻⁹))`,
//! the step solves `(H + λD) Δ = −g` (Marquardt 1963, SIAM J. Appl. Math. 11:431–441), the
//! frames eliminated by the Schur complement (`crate::normal`). A step that would take a
//! factor to 0.05 or below is refused like a worse one.
//!
//! **Damping** (Nielsen 1999, *Damping parameter in Marquardt's method*, IMM-REP-1999-05;
//! Madsen, Nielsen & Tingleff 2004, *Methods for non-linear least squares problems*, §3.2).
//! The linear model predicts the decrease `L = −2gᵀΔ − ΔᵀHΔ = −gᵀΔ + λ ΔᵀDΔ`; the gain ratio
//! is `ρ = (F(θ) − F(θ + Δ))/L`. A step that lowers `F` is taken and
//! `λ ← λ · max(1/3, 1 − (2ρ − 1)³)` (at least 10⁻¹²), `ν ← 2`; a refused step (or a failed
//! factorisation) gives `λ ← λν`, `ν ← 2ν`. Starting values `λ = 10⁻³`, `ν = 2`; at most 16
//! trial steps an iteration.
//!
//! **Stop test.** Converged when a taken step's predicted decrease is below
//! `10⁻⁴ · min(1, F/n_d)` (`n_d` the data rows at the start): the optimum is then closer than
//! `√10⁻⁴ = 0.01` standard deviations (of the Laplace approximation, with the assumed marker
//! SD or the smaller spread the residuals show) in every direction of the unknowns; or when
//! the cost stops changing (relative decrease at most 10⁻¹², noise-free data); or when the
//! next step's predicted decrease is below both that tolerance and 10⁻¹² of the cost, or no
//! trial step lowers the cost (the point is already the optimum to working precision).
//!
//! **Iteration guard.** At most `ScaleOptions::max_iterations` iterations; a solve that
//! reaches it says it did not converge.

use super::problem::Problem;
use crate::basis::BasisData;
use crate::normal::{Normal, Step};

/// The stop test's relative tolerance on the predicted decrease (module docs).
const DECREMENT_TOL: f64 = 1e-4;
/// Trial steps an iteration, each with more damping than the one before.
const TRIAL_STEPS: usize = 16;
/// The least a factor may become in a taken step.
const MIN_FACTOR: f64 = 0.05;

/// A solve's result: the solution, the iterations taken and whether the stop test ended it
/// (not the iteration guard).
pub(super) struct Solved {
    pub(super) th: Vec<f64>,
    pub(super) iterations: usize,
    pub(super) converged: bool,
}

/// Nielsen's damping rule (module docs).
struct Damping {
    lambda: f64,
    nu: f64,
}

impl Damping {
    fn new() -> Self {
        Damping {
            lambda: 1e-3,
            nu: 2.0,
        }
    }

    /// After a refused step: `λ ← λν`, `ν ← 2ν`.
    fn refuse(&mut self) {
        self.lambda *= self.nu;
        self.nu *= 2.0;
    }

    /// After a taken step of gain ratio `rho`.
    fn take(&mut self, rho: f64) {
        self.lambda *= (1.0 / 3.0f64).max(1.0 - (2.0 * rho - 1.0).powi(3));
        self.lambda = self.lambda.max(1e-12);
        self.nu = 2.0;
    }
}

/// The stop test's tolerance on the predicted decrease at cost `cost`, `n_d` data rows.
fn tolerance(cost: f64, n_d: f64) -> f64 {
    DECREMENT_TOL * (cost / n_d).min(1.0)
}

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

/// A taken step: the new point, its cost, and whether the stop test holds.
struct Taken {
    th: Vec<f64>,
    cost: f64,
    done: bool,
}

/// One iteration's trial steps from `th` (cost `cost`, normal equations `nm`), damped more
/// after each refusal; the first that lowers the cost, or `None` when the predicted decrease
/// is already negligible or no trial step lowers the cost (module docs).
fn trial_steps(
    pb: &Problem,
    nm: &Normal,
    th: &[f64],
    cost: f64,
    n_d: f64,
    damping: &mut Damping,
    ws: &mut BasisData,
) -> Option<Taken> {
    for _ in 0..TRIAL_STEPS {
        let Some(step) = nm.step(damping.lambda) else {
            damping.refuse();
            continue;
        };
        let pred = predicted(nm, &step, damping.lambda);
        if pred <= tolerance(cost, n_d).min(1e-12 * cost) {
            return None;
        }
        let trial = pb.moved(th, &step);
        if trial[..pb.lay.k].iter().any(|v| *v <= MIN_FACTOR) {
            damping.refuse();
            continue;
        }
        let c2 = pb.evaluate(&trial, false, 1.0, ws).cost;
        if c2 < cost {
            damping.take((cost - c2) / pred);
            let done = pred < tolerance(cost, n_d) || (cost - c2) <= 1e-12 * cost.max(1e-30);
            return Some(Taken {
                th: trial,
                cost: c2,
                done,
            });
        }
        damping.refuse();
    }
    None
}

/// Levenberg–Marquardt from `th` (module docs).
pub(super) fn solve(pb: &Problem, mut th: Vec<f64>, ws: &mut BasisData) -> Solved {
    let mut ev = pb.evaluate(&th, true, 1.0, ws);
    let mut cost = ev.cost;
    let n_d = ev.data_rows.max(1) as f64;
    let mut damping = Damping::new();
    let mut iterations = 0;
    let mut converged = false;
    while iterations < pb.opts.max_iterations {
        iterations += 1;
        let nm = ev.normal.take().expect("normal equations");
        let Some(taken) = trial_steps(pb, &nm, &th, cost, n_d, &mut damping, ws) else {
            converged = true;
            break;
        };
        th = taken.th;
        cost = taken.cost;
        if taken.done {
            converged = true;
            break;
        }
        ev = pb.evaluate(&th, true, 1.0, ws);
    }
    Solved {
        th,
        iterations,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::super::markers::static_weights;
    use super::super::problem::start;
    use super::super::test_leg::{factor_error, leg_frames, scaled_leg, with_noise, UNIFORM_TRUTH};
    use super::super::{fit_scale, ScaleOptions};
    use super::*;

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

    /// With noisy motion frames the fit converges (its own test, not the limit) at a
    /// stationary point of its cost: the central-difference gradient of `Σ r²` in every
    /// unknown is below a hundredth of that unknown's curvature scale `√H_ii`, so no
    /// unknown alone could lower the cost by more than 1e-4.
    #[test]
    fn noisy_motion_frames_converge_to_a_stationary_point() {
        use rand::{Rng, SeedableRng};
        let (spec, groups, clean) = leg_frames(6);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noisy = with_noise(&clean, || rng.gen_range(-0.01..0.01));
        let mut opts = ScaleOptions::new(groups);
        opts.robust = false;
        let fit = fit_scale(&spec, &noisy, &opts).unwrap();
        assert!(fit.converged, "{} iterations", fit.iterations);

        let weight = static_weights(&spec, &noisy, &opts);
        let (pb, th) = start(&spec, &noisy, &opts, weight).unwrap();
        let mut ws = pb.basis.workspace();
        let solved = solve(&pb, th, &mut ws);
        assert!(solved.converged);
        let th = solved.th;
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
            let (_, s) = UNIFORM_TRUTH.iter().find(|(n, _)| *n == g.name).unwrap();
            assert!((g.factors[0] - s[0]).abs() < 4.0 * g.sd[0], "{g:?}");
        }
    }
}
