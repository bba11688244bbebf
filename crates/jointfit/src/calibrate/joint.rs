//! Joint sparse Levenberg–Marquardt over all frames' coordinates and the parameters.
//!
//! See the parent module for the objective and [`super::schur`] for the linear algebra. Bounds
//! are handled by projection: a step is clamped to `[−1, 1]`, the coordinate steps are
//! recomputed for the clamped parameter step, and parameters at a bound whose descent
//! direction points outward are held for the step.
//!
//! **Stopping where the data stop resolving.** Near the optimum the objective is, to second
//! order, `F(x) − F* ≈ δᵀ H δ` with `H = JᵀWJ` (`x` all unknowns, `δ` its distance to the
//! optimum), and the covariance of the estimate is `σ² H⁻¹` for marker noise σ (with a prior
//! `F` is `2σ²` times the negative log posterior, [`super::prior`], so the same holds for the
//! posterior). The Gauss–Newton step's predicted decrease `2hᵀδ − δᵀHδ = hᵀH⁻¹h` therefore
//! equals `σ² d²`, `d` the Mahalanobis distance of the current point to the model's optimum;
//! eliminating the coordinates only shrinks it for the parameters (`δ_pᵀ S δ_p ≤ δᵀHδ`, `S`
//! the reduced normal matrix), and every parameter's distance in its own standard errors is
//! at most `d` (`|δ_k| ≤ d · SE_k`). An accepted step whose predicted decrease is below
//! `τ² σ²` thus started within `τ` standard errors of the optimum of its model, and the solve
//! ends there ([`RESOLUTION_SE`], τ = 1e-3: a thousandth of what the data can resolve). σ² is
//! the smaller of the white residual variance `e / (m − N·n_q − n_f)` and the prior's σ²,
//! both conservative (the robust standard errors of [`super::uncertainty`] are larger than the
//! white ones on time-correlated residuals). The rule is used only for steps taken at damping
//! λ ≤ 1e-6 (relative to the diagonal), where the damped step's predicted decrease equals the
//! Gauss–Newton one up to a factor `1 − (λ/μ)²` for every direction of scaled information
//! `μ` (Madsen, Nielsen & Tingleff, *Methods for non-linear least squares problems*, 2004,
//! §3.2). The model alone can be fooled where the iterations converge slowly (a linear tail
//! of ratio r near 1: large residuals, a flat valley), so the observed decreases must agree:
//! with the last two decreases `D_{k−1}, D_k` and `r = D_k/D_{k−1} < 1`, the decrease still
//! to come if the tail stays geometric, `D_k r/(1 − r)`, must also be below `τ² σ²` (on
//! synthetic ankle data, seed 7429 of `examples/global_optimum.rs`, the model alone stopped
//! one start 1.4 mm² above its optimum). Noise-free data (σ² = 0) keep the classical
//! tolerances below.
//!
//! **A tail that stays damped.** On long, large-residual trials the gain ratio can stay
//! below ½ to the end, so the damping never falls to 1e-6 and the rule above never applies:
//! on Hamner running the finishing solve met the geometric-tail test at its 25th iteration
//! and ran on to its 35th, where the relative decrease fell below 1e-14. So when the tail
//! test passes after a step taken at larger damping, the undamped Gauss–Newton model is
//! formed at the new point (one more reduction, λ = 0, the same bound handling as a step):
//! its predicted decrease `hᵀH⁻¹h = σ² d²` is the distance of this very point, and at most
//! `τ² σ²` ends the solve, after its step (when that stays inside the bounds and lowers the
//! objective: one more evaluation, counted as an iteration). On 36 synthetic full-leg solves
//! (60 frames, 1–4 cm skin noise, seeds 1–12) the check ended 17; they ended at most
//! 8.7e-4 SE from the optimum of the solve run out (1.5e-3 without the last step), and the
//! 36 took 18 % fewer iterations. On the shared walking1, gait2392 walk1 and Hamner
//! running the command's iterations went 25 → 23, 39 → 38 and 74 → 63 (evaluations
//! 52 → 48, 86 → 84, 172 → 150), the parameters moving by at most 3.5e-3, 2.7e-4 and
//! 1.3e-3 SE (through σ, which the σ stage estimates at 0.1 SE of its optimum).
//!
//! On the shared opencap_expert1 walking1 full-leg and `.osim` hip + knee fits the parameters
//! moved by at most 2e-4 of their standard errors against running the classical tolerances
//! out.
//!
//! **The second-order term.** On large residuals (running) the Gauss–Newton model misses
//! `Σ rᵢ∇²rᵢ` and the iterations crawl (ρ → 2 at the damping floor for tens of
//! iterations). [`solve_joint_with`] can add a secant matrix `A` on the Schur-reduced
//! parameters' system for the missing term, chosen against Gauss–Newton each iteration by
//! which model predicted the last step better and limited to keep the model convex
//! ([`secant`], after NL2SOL; Dennis, Gay & Welsch 1981). The coordinates are still
//! eliminated exactly; a rejected augmented step is retried with Gauss–Newton's at the same
//! damping before the damping grows. It is off in [`solve_joint`] and [`solve_joint_to`]:
//! on identical inputs it saved iterations on long trials (Hamner running 119 → 77 before
//! the σ estimate moved into the global phase), but the command's fit is cheaper without
//! it, used everywhere or only in the σ stage and the finishing solves (the latter +7.0 to
//! +18.6 % instructions on opencap walking1, gait2392 walk1 and Hamner running;
//! `notebook/performance_fit.md`, "The joint solver on long trials", and `notebook/solver_tail.md`,
//! which also traces the remaining linear tail to the second-order term of the ankle's
//! coordinates and axes).
//!
//! **The tail, mixed.** What the secant model could not do on the parameters alone, Anderson
//! mixing of the whole step (parameters and every frame's coordinates) does in the tail: it
//! combines the last steps so that the slow modes of the linear tail cancel ([`mixing`]). On
//! gait2392 walk1 the final solve took 11 iterations instead of 19, on Hamner running (a tail
//! that stays damped) the best start 49 instead of 60; on synthetic legs with 2–4 cm skin
//! noise 40, 18 and 72 instead of 75, 40 and 78.
//!
//! **The tail on a kept curvature.** In the undamped tail the blocks' curvature (every
//! frame's `U_i`, `W_i`, `V`, the damped factors and `S`) barely changes between steps, so
//! while the point stays within [`KEEP_STEP`] of where it was formed only the gradient is
//! formed at each new point, and the step is the chord Gauss–Newton step of that earlier
//! point (Ortega & Rheinboldt 1970, §7.1). Its contraction differs from Gauss–Newton's by the
//! distance moved, and Gauss–Newton's own tail rate is set by the second-order term it leaves
//! out. A kept step that raises the objective is dropped and the blocks are formed at the
//! point. On six shared trials every stage took as many iterations as before and the
//! parameters moved by at most 3.4e-5 SE; the fit's instructions fell by 6.7 % on gait2392
//! walk1 (`docs/stopping.md`, "The tail on a kept curvature").

use rayon::prelude::*;

use super::schur::{
    active_bounds, assemble, assemble_gradient, back_substitute, cost_at, project_coords, reduce,
    reduce_gradient, solve_reduced_at_bounds, Blocks,
};
use mixing::Mixing;
use secant::Secant;

#[path = "mixing.rs"]
mod mixing;
#[path = "secant.rs"]
mod secant;
use super::{Fit, Problem};
use crate::solver::{Observer, Termination};

/// Settings of the joint solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct JointOptions {
    pub max_iterations: usize,
    /// Converged when every parameter step (scaled units) and coordinate step (rad, m) is
    /// below this.
    pub tolerance: f64,
    /// Anderson mixing of the tail's steps ([`mixing`]).
    pub mixing: bool,
    /// The damping λ (relative to the diagonal) of the first step: 1e-4, or
    /// [`RESOLUTION_MAX_DAMPING`] from a point known to be near the optimum, where the
    /// Gauss–Newton step is trusted from the start.
    pub initial_damping: f64,
    /// The undamped tail may keep the curvature of a nearby point ([`KEEP_STEP`]).
    pub keep_curvature: bool,
}

impl Default for JointOptions {
    fn default() -> Self {
        JointOptions {
            max_iterations: 200,
            tolerance: 1e-10,
            mixing: true,
            initial_damping: 1e-4,
            keep_curvature: true,
        }
    }
}

/// Frames per parallel task of the solver's own element-wise passes (the trial point, the
/// largest step): below this a pass runs on the calling thread.
const PAR_FRAMES: usize = 1024;

/// Relative decrease of the objective below which an accepted step ends the solve.
const COST_TOLERANCE: f64 = 1e-14;

/// Distance to the optimum, in standard errors, that no longer matters (the statistical
/// stopping rule of [`solve_joint`]).
pub(crate) const RESOLUTION_SE: f64 = 1e-3;

/// Largest damping (relative to the diagonal) at which the statistical stopping rule trusts
/// a step's predicted decrease as the Gauss–Newton one.
pub(crate) const RESOLUTION_MAX_DAMPING: f64 = 1e-6;

/// How far (the sum of the accepted steps' largest components: scaled parameter units,
/// rad, m) the undamped tail moves on the curvature of one point before the blocks are
/// formed again ([`Solve::advance`]).
const KEEP_STEP: f64 = 2e-2;

/// Largest damping (relative to the diagonal) at which the reduced system of a step also
/// serves as the undamped one of the secant model ([`secant`]); above it the model's data
/// come from a reduction at λ = 0 (one more pass over the frames).
const SECANT_MAX_DAMPING: f64 = 1e-6;

/// Marker noise variance σ² (m²) that the statistical stopping rule measures distances
/// against: the white residual variance `e / (m − N·n_q − n_f)` of the marker term `data`
/// (m²) over `observations` scalar residuals, or the prior's σ² when that is smaller (0: no
/// degrees of freedom, the rule is off).
fn noise_variance(prob: &Problem, data: f64, observations: usize) -> f64 {
    let used = prob.frames.len() * prob.model.coordinates().len() + prob.n_free();
    let white = match observations.checked_sub(used) {
        Some(dof) if dof > 0 => data.max(0.0) / dof as f64,
        _ => return 0.0,
    };
    match &prob.prior {
        Some(pr) => white.min(pr.noise * pr.noise),
        None => white,
    }
}

/// Scalar residuals of the marker term: 3 per present marker of positive weight.
pub(crate) fn observations(prob: &Problem) -> usize {
    let markers = prob.model.markers();
    prob.frames
        .iter()
        .map(|t| {
            t.iter()
                .zip(markers)
                .filter(|(x, m)| !x.x.is_nan() && m.weight > 0.0)
                .count()
                * 3
        })
        .sum()
}

/// `q_try = qs + dq`, frame by frame in parallel (each frame's sum alone: the same bits on any
/// number of threads), projected into the range of every bounded coordinate (`bounds`,
/// [`super::schur::coordinate_bounds`]); `dq` becomes the projected step.
pub(crate) fn trial_coords(
    q_try: &mut [Vec<f64>],
    qs: &[Vec<f64>],
    dq: &mut [Vec<f64>],
    bounds: &[(usize, f64, f64)],
) {
    q_try
        .par_iter_mut()
        .zip(qs.par_iter().zip(dq.par_iter_mut()))
        .with_min_len(PAR_FRAMES)
        .for_each(|(t, (q, d))| {
            for ((t, a), b) in t.iter_mut().zip(q).zip(d.iter()) {
                *t = a + b;
            }
            for &(c, lo, hi) in bounds {
                t[c] = t[c].clamp(lo, hi);
                d[c] = t[c] - q[c];
            }
        });
}

/// The predicted decrease `hᵀH⁻¹h` of the undamped Gauss–Newton step from the point
/// `blocks` were assembled at (`s`, `qs`; parameters at a bound that the step would push out
/// held, as a step holds them). `None` when it is no distance to the optimum of the model:
/// the undamped system is singular, the step leaves the bounds (the model's optimum is not
/// the bounded problem's), or rounding made the decrease negative. Overwrites the reduction
/// and `ds`, `dq`.
fn undamped_decrease(
    prob: &Problem,
    qs: &[Vec<f64>],
    blocks: &mut Blocks,
    s: &[f64],
    ds: &mut [f64],
    dq: &mut [Vec<f64>],
) -> Option<f64> {
    if !reduce(prob, qs, blocks, 0.0) {
        return None;
    }
    let mut fixed = active_bounds(s, &blocks.gs);
    if !solve_reduced_at_bounds(blocks, None, s, &mut fixed, ds) {
        return None;
    }
    if s.iter().zip(ds.iter()).any(|(a, d)| (a + d).abs() > 1.0) {
        return None;
    }
    Some(back_substitute(prob, qs, blocks, ds, dq)).filter(|&d| d >= 0.0)
}

/// Minimises the objective from scaled parameters `s0` and coordinates `q0` (one per frame).
/// `observer.iteration(iteration, cost)` is called after every outer iteration (the same
/// values as [`Fit::history`]); it cannot change the result.
///
/// Ends [`Termination::Converged`] on a step below `tolerance`, a relative decrease below
/// 1e-14, or a predicted decrease below `(RESOLUTION_SE · σ)²` (module docs), [`Termination::Stalled`] when no damping up to 1e16 gives a step that does not
/// raise the objective, [`Termination::IterationLimit`] after `max_iterations`.
pub(crate) fn solve_joint(
    prob: &Problem,
    s0: &[f64],
    q0: Vec<Vec<f64>>,
    opts: &JointOptions,
    observer: &mut dyn Observer,
) -> Fit {
    solve_joint_to(prob, s0, q0, opts, RESOLUTION_SE, observer)
}

/// [`solve_joint`] with the statistical stopping rule at `resolution` standard errors
/// instead of [`RESOLUTION_SE`] (0: off, only the step and cost tolerances end the solve).
pub(crate) fn solve_joint_to(
    prob: &Problem,
    s0: &[f64],
    q0: Vec<Vec<f64>>,
    opts: &JointOptions,
    resolution: f64,
    observer: &mut dyn Observer,
) -> Fit {
    solve_joint_with(prob, s0, q0, opts, resolution, false, observer)
}

/// [`solve_joint_to`] with the secant model of the second-order term ([`secant`], module
/// docs) on (`use_secant`) or off (the plain Gauss–Newton Levenberg–Marquardt that
/// [`solve_joint`] and [`solve_joint_to`] run, bit for bit as before the model existed).
pub(crate) fn solve_joint_with(
    prob: &Problem,
    s0: &[f64],
    q0: Vec<Vec<f64>>,
    opts: &JointOptions,
    resolution: f64,
    use_secant: bool,
    observer: &mut dyn Observer,
) -> Fit {
    let observations = observations(prob);
    let mut st = Solve::new(prob, s0, q0, opts);
    let mut history = Vec::new();
    // The previous accepted step's decrease (for the geometric tail of the stopping rule).
    let mut last_decrease = f64::INFINITY;
    let mut iterations = 0;
    let mut termination = Termination::IterationLimit;
    while iterations < opts.max_iterations {
        iterations += 1;
        st.noise = noise_variance(prob, st.cost - prob.prior_cost(&st.p), observations);
        let accepted = st.iterate(use_secant);
        history.push(st.cost);
        observer.iteration(iterations, st.cost);
        let Some(Accepted {
            step,
            decrease,
            model_decrease,
        }) = accepted
        else {
            termination = Termination::Stalled;
            break;
        };
        // Converged on a negligible step, or when the objective no longer moves at working
        // precision (the last digits of a linearly converging tail change nothing).
        // Or when the Gauss–Newton model puts the optimum closer than `resolution` standard
        // errors (the module docs).
        let sigma2 = noise_variance(prob, st.cost - prob.prior_cost(&st.p), observations);
        // The decrease still to come if the objective keeps falling geometrically at the
        // last ratio r: D r / (1 − r) (infinite when it is not falling faster).
        let r = decrease / last_decrease;
        let tail = if r < 1.0 {
            decrease * r / (1.0 - r)
        } else {
            f64::INFINITY
        };
        last_decrease = decrease;
        let limit = resolution * resolution * sigma2;
        let resolved = resolution > 0.0 && sigma2 > 0.0 && model_decrease <= limit && tail <= limit;
        if step < opts.tolerance || decrease <= COST_TOLERANCE * st.cost || resolved {
            termination = Termination::Converged;
            break;
        }
        st.advance(step, use_secant);
        // The observed tail is within the resolution but the step was too damped for its
        // predicted decrease to stand for Gauss–Newton's: the undamped model at the new point
        // decides (one more reduction), and its step ends the solve when it lowers the
        // objective (one more evaluation; module docs). (The tail needs two decreases: `r`
        // of the first step is 0.)
        let damped = model_decrease == f64::INFINITY && r > 0.0;
        if resolution > 0.0 && sigma2 > 0.0 && damped && tail <= limit && st.undamped_within(limit)
        {
            termination = Termination::Converged;
            if iterations < opts.max_iterations && st.undamped_step() {
                iterations += 1;
                history.push(st.cost);
                observer.iteration(iterations, st.cost);
            }
            break;
        }
    }
    Fit {
        s: st.s,
        p: st.p,
        coords: st.qs,
        cost: st.cost,
        iterations,
        evaluations: st.evaluations,
        history,
        termination,
    }
}

/// What an accepted step did: its largest component, the decrease of the objective, and the
/// decrease its model predicted (infinite when the step was too damped to stand for
/// Gauss–Newton's, [`RESOLUTION_MAX_DAMPING`]).
struct Accepted {
    step: f64,
    decrease: f64,
    model_decrease: f64,
}

/// How a trial step ended: taken; rejected (`retry_plain`: it was augmented or mixed, and
/// Gauss–Newton's own step at the same damping comes next); or the reduced system was not
/// positive definite at this damping.
enum Attempt {
    Taken(Accepted),
    Rejected { retry_plain: bool },
    Singular,
}

/// A trial step: the parameters it leads to and its step (clamped into the bounds), the
/// decreases the models predict for it, and whether it is a tail step (remembered for
/// mixing) or a mixed one.
struct Step {
    s_try: Vec<f64>,
    ds: Vec<f64>,
    gauss_newton: f64,
    augmented: f64,
    predicted: f64,
    tail: bool,
    mixed: bool,
}

/// The state of a joint solve between iterations: the point (scaled parameters `s`,
/// parameters `p`, coordinates `qs`), its objective and blocks, the damping, and the buffers
/// of the steps.
struct Solve<'a, 'm> {
    prob: &'a Problem<'m>,
    blocks: Blocks,
    s: Vec<f64>,
    p: Vec<f64>,
    qs: Vec<Vec<f64>>,
    cost: f64,
    ds: Vec<f64>,
    dq: Vec<Vec<f64>>,
    /// The trial point's coordinates, allocated once here on the calling thread and filled
    /// in parallel (each frame's sum alone: the same bits on any number of threads); swapped
    /// with `qs` when a step is accepted.
    q_try: Vec<Vec<f64>>,
    lambda: f64,
    /// Nielsen's damping update: the growth factor for a rejected step doubles each time.
    nu: f64,
    evaluations: usize,
    secant: Secant,
    /// Anderson mixing of the tail's steps ([`mixing`]).
    mixing: Mixing,
    /// The Gauss–Newton coordinate steps of the current iteration while a mixed step is
    /// tried or remembered.
    f_q: Vec<Vec<f64>>,
    /// The marker noise variance σ² at the current point ([`noise_variance`]; 0: unknown):
    /// a step whose predicted decrease is below it starts within a standard error of the
    /// model's optimum.
    noise: f64,
    /// The blocks' curvature (`U_i`, `W_i`, `V`, the damped factors and `S`) is kept from an
    /// earlier point: only the gradient and objective are this point's ([`KEEP_STEP`]).
    kept: bool,
    /// How far the point moved since the blocks' curvature was formed: the sum of the
    /// accepted steps' largest components.
    moved: f64,
    /// The damping of the last accepted step.
    lambda_used: f64,
    /// [`JointOptions::keep_curvature`].
    keep_curvature: bool,
}

impl<'a, 'm> Solve<'a, 'm> {
    /// The solve at `s0` (clamped into the bounds) and `q0` (projected into theirs),
    /// assembled there.
    fn new(prob: &'a Problem<'m>, s0: &[f64], q0: Vec<Vec<f64>>, opts: &JointOptions) -> Self {
        let (nq, nf, frames) = (
            prob.model.coordinates().len(),
            prob.n_free(),
            prob.frames.len(),
        );
        let mut blocks = Blocks::new(prob);
        let s: Vec<f64> = s0.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
        let mut qs = q0;
        project_coords(&mut qs, &blocks.bounds);
        let q_try = qs.clone();
        let p = prob.to_params(&s);
        assemble(prob, &p, &qs, &mut blocks);
        let cost = blocks.cost;
        Solve {
            prob,
            blocks,
            s,
            p,
            qs,
            cost,
            ds: vec![0.0; nf],
            dq: vec![vec![0.0; nq]; frames],
            q_try,
            lambda: opts.initial_damping,
            nu: 2.0,
            evaluations: 1,
            secant: Secant::new(nf),
            mixing: Mixing::new(frames, nq, opts.mixing),
            f_q: Vec::new(),
            noise: 0.0,
            kept: false,
            moved: 0.0,
            lambda_used: f64::INFINITY,
            keep_curvature: opts.keep_curvature,
        }
    }

    /// The blocks at the current point (one more evaluation).
    fn assemble(&mut self) {
        assemble(self.prob, &self.p, &self.qs, &mut self.blocks);
        self.evaluations += 1;
        self.cost = self.blocks.cost;
        self.moved = 0.0;
    }

    /// After an accepted step of largest component `step`: the blocks at the new point, or,
    /// in the undamped tail while the point stays within [`KEEP_STEP`] of where the curvature
    /// was formed, only the gradient there with the curvature kept (one more evaluation
    /// either way).
    fn advance(&mut self, step: f64, use_secant: bool) {
        self.moved += step;
        let keep = self.keep_curvature
            && !use_secant
            && self.lambda_used <= RESOLUTION_MAX_DAMPING
            && self.moved <= KEEP_STEP
            && self.blocks.can_keep();
        if !keep {
            return self.assemble();
        }
        assemble_gradient(self.prob, &self.p, &self.qs, &mut self.blocks);
        self.evaluations += 1;
        self.cost = self.blocks.cost;
        self.kept = true;
    }

    /// One Levenberg–Marquardt iteration: steps at growing damping until one lowers the
    /// objective (then taken), or `None` when the damping runs out. With the curvature kept
    /// ([`Solve::kept`]) the first step is the kept model's; when that does not lower the
    /// objective the blocks are formed at this point and the iteration goes on as usual.
    fn iterate(&mut self, use_secant: bool) -> Option<Accepted> {
        let prob = self.prob;
        let mut fixed = active_bounds(&self.s, &self.blocks.gs);
        if std::mem::take(&mut self.kept) {
            reduce_gradient(&mut self.blocks);
            self.lambda = self.blocks.damping();
            if let Attempt::Taken(a) = self.attempt(None, false, use_secant, &mut fixed) {
                return Some(a);
            }
            self.assemble();
            fixed = active_bounds(&self.s, &self.blocks.gs);
        }
        let mut reduced_at = if use_secant {
            self.observe_secant()
        } else {
            None
        };
        // Gauss–Newton only for the rest of this iteration (an augmented or mixed step was
        // rejected).
        let mut plain = false;
        while self.lambda < 1e16 {
            if reduced_at != Some(self.lambda) {
                reduced_at = None;
                if !reduce(prob, &self.qs, &mut self.blocks, self.lambda) {
                    self.lambda *= 10.0;
                    continue;
                }
                reduced_at = Some(self.lambda);
            }
            let limited = self.secant.limited(&self.blocks.schur);
            match self.attempt(limited.as_deref(), plain, use_secant, &mut fixed) {
                Attempt::Singular => self.lambda *= 10.0,
                Attempt::Taken(accepted) => return Some(accepted),
                // The augmented or mixed step failed: Gauss–Newton's at the same damping
                // first.
                Attempt::Rejected { retry_plain: true } => plain = true,
                Attempt::Rejected { retry_plain: false } => {
                    self.lambda *= self.nu;
                    self.nu *= 2.0;
                }
            }
        }
        None
    }

    /// One trial step at the reduced system of the blocks (damping `self.lambda`), with the
    /// secant term `limited` added when the secant model leads ([`secant`]) and mixed in the
    /// tail ([`mixing`]), unless `plain` (Gauss–Newton's alone); taken when it does not raise
    /// the objective.
    fn attempt(
        &mut self,
        limited: Option<&[f64]>,
        plain: bool,
        use_secant: bool,
        fixed: &mut [bool],
    ) -> Attempt {
        let prob = self.prob;
        let extra = limited.filter(|_| self.secant.augmented() && !plain);
        let (blocks, s) = (&self.blocks, &self.s);
        if !solve_reduced_at_bounds(blocks, extra, s, fixed, &mut self.ds) {
            return Attempt::Singular;
        }
        let s_try: Vec<f64> = s
            .iter()
            .zip(&self.ds)
            .map(|(a, d)| (a + d).clamp(-1.0, 1.0))
            .collect();
        let ds_eff: Vec<f64> = s_try.iter().zip(s).map(|(a, b)| a - b).collect();
        let gauss_newton = back_substitute(prob, &self.qs, blocks, &ds_eff, &mut self.dq);
        let augmented = match limited {
            Some(a) => gauss_newton - self.secant.curvature(a, &ds_eff),
            None => gauss_newton,
        };
        // Mixed where the step is Gauss–Newton's, or within a standard error of the model's
        // optimum at a settled damping ([`mixing`]).
        let tail = !use_secant
            && self.mixing.on()
            && (self.lambda <= RESOLUTION_MAX_DAMPING || gauss_newton <= self.noise);
        let mut step = Step {
            s_try,
            ds: ds_eff,
            gauss_newton,
            augmented,
            // The model that chose the step predicts its decrease.
            predicted: if extra.is_some() {
                augmented
            } else {
                gauss_newton
            },
            tail,
            mixed: false,
        };
        if tail {
            mixing::copy_frames(&mut self.f_q, &self.dq);
            if !plain {
                self.mix(&mut step, fixed);
            }
        }
        trial_coords(&mut self.q_try, &self.qs, &mut self.dq, &self.blocks.bounds);
        let p_try = prob.to_params(&step.s_try);
        let c = cost_at(prob, &self.blocks, &p_try, &self.q_try);
        self.evaluations += 1;
        if c <= self.cost {
            return Attempt::Taken(self.take(step, p_try, c, fixed));
        }
        self.mixing.clear();
        Attempt::Rejected {
            retry_plain: step.mixed || extra.is_some(),
        }
    }

    /// The secant model's data at this point: the reduced system at the step's damping when
    /// that is small (then equal to the undamped one to 1e-6), else at λ = 0. Returns the
    /// damping the blocks are now reduced at.
    fn observe_secant(&mut self) -> Option<f64> {
        let data_lambda = if self.lambda <= SECANT_MAX_DAMPING {
            self.lambda
        } else {
            0.0
        };
        if reduce(self.prob, &self.qs, &mut self.blocks, data_lambda) {
            self.secant.observe(&self.blocks.schur, &self.blocks.rhs);
            Some(data_lambda)
        } else {
            self.secant.forget();
            None
        }
    }

    /// Replaces the Gauss–Newton step (`step`, `self.dq`) by the mixed one when the history
    /// allows ([`mixing`]); the Gauss–Newton parameter step is then kept in `self.ds`.
    fn mix(&mut self, step: &mut Step, fixed: &[bool]) {
        let s = &self.s;
        if !self.mixing.mix(
            &step.ds,
            &self.f_q,
            fixed,
            self.lambda,
            &mut self.ds,
            &mut self.dq,
        ) {
            return;
        }
        step.mixed = true;
        step.s_try = s
            .iter()
            .zip(&self.ds)
            .map(|(a, d)| (a + d).clamp(-1.0, 1.0))
            .collect();
        std::mem::swap(&mut step.ds, &mut self.ds);
        for ((d, a), b) in step.ds.iter_mut().zip(&step.s_try).zip(s) {
            *d = a - b;
        }
    }

    /// Takes `step` (to parameters `p_try`, objective `c`, coordinates in `q_try`): the
    /// history, the damping's update and the new point.
    fn take(&mut self, step: Step, p_try: Vec<f64>, c: f64, fixed: &[bool]) -> Accepted {
        let lambda_used = self.lambda;
        self.lambda_used = lambda_used;
        if step.tail {
            // The Gauss–Newton parameter step is in `self.ds` after a mixed step (swapped),
            // else it is the step taken.
            let f_s = if step.mixed { &self.ds } else { &step.ds };
            self.mixing
                .push(f_s, &self.f_q, &step.ds, &self.dq, fixed, lambda_used);
        } else {
            self.mixing.clear();
        }
        let largest = self.largest_step(&step.ds);
        // Gain ratio ρ = actual / predicted decrease: near 1 the quadratic model is good and
        // the damping shrinks by up to 3; a poor model keeps it.
        let rho = if step.predicted > 0.0 {
            (self.cost - c) / step.predicted
        } else {
            0.0
        };
        self.lambda = (self.lambda * (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0)).max(1e-12);
        self.nu = 2.0;
        let model_decrease = if lambda_used <= RESOLUTION_MAX_DAMPING {
            step.predicted
        } else {
            f64::INFINITY
        };
        let decrease = self.cost - c;
        self.secant
            .accepted(&step.ds, decrease, step.gauss_newton, step.augmented);
        self.s = step.s_try;
        std::mem::swap(&mut self.qs, &mut self.q_try);
        self.p = p_try;
        self.cost = c;
        Accepted {
            step: largest,
            decrease,
            model_decrease,
        }
    }

    /// The largest component of the step (`ds` and the coordinates' `dq`; a maximum: the
    /// same in any order of evaluation).
    fn largest_step(&self, ds: &[f64]) -> f64 {
        let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        self.dq
            .par_iter()
            .with_min_len(PAR_FRAMES)
            .map(|d| largest(d))
            .reduce(|| 0.0, f64::max)
            .max(largest(ds))
    }

    /// The undamped model's predicted decrease at the current point is within `limit` (its
    /// step left in `ds`, `dq`).
    fn undamped_within(&mut self, limit: f64) -> bool {
        let (prob, s) = (self.prob, &self.s);
        undamped_decrease(
            prob,
            &self.qs,
            &mut self.blocks,
            s,
            &mut self.ds,
            &mut self.dq,
        )
        .is_some_and(|d| d <= limit)
    }

    /// Takes the undamped step of [`Solve::undamped_within`] when it does not raise the
    /// objective (one more evaluation).
    fn undamped_step(&mut self) -> bool {
        let prob = self.prob;
        let s_try: Vec<f64> = self.s.iter().zip(&self.ds).map(|(a, d)| a + d).collect();
        trial_coords(&mut self.q_try, &self.qs, &mut self.dq, &self.blocks.bounds);
        let p_try = prob.to_params(&s_try);
        let c = cost_at(prob, &self.blocks, &p_try, &self.q_try);
        self.evaluations += 1;
        if c > self.cost {
            return false;
        }
        self.s = s_try;
        std::mem::swap(&mut self.qs, &mut self.q_try);
        self.p = p_try;
        self.cost = c;
        true
    }
}
