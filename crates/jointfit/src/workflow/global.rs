//! The global phase of the default calibration: short probes from several starts, then full
//! iterations only for the most promising (a coarse-to-fine multi-start).
//!
//! The two-level objective of a full leg has several local minima within the spread of
//! landmark estimates: on synthetic legs whose joints were moved up to 30 mm / 15° from the
//! nominal model (skin-artifact noise), one local fit from the nominal model ended 3–5 %
//! above the objective at the true parameters, while some seeded starts reached an optimum
//! below it (`examples/global_optimum.rs` of `jointfit-experiments`). Full iterations from
//! many starts would cost their number times a fit, so the default
//!
//! 1. runs the given start and `probes` seeded starts for `probe_iterations`
//!    Levenberg–Marquardt iterations each on every k-th frame (k the smallest that leaves at
//!    most `probe_frames`; the prior's weight scaled by k so the posterior keeps its
//!    balance), in parallel: each start is deterministic and the results are combined in
//!    start order, so the thread count never changes the result;
//! 2. ranks them by the objective they reached (ties: the lower start index) and continues
//!    the best to convergence on every frame, and a second start unless the probes put it
//!    within [`SAME_BASIN`] of the best: the given start when it is not the best (so the
//!    result is never worse than one local fit from it), else the runner-up;
//! 3. keeps the lowest objective, and warns when the finished starts ended at different
//!    optima: the fit is then not known to be the global optimum.
//!
//! When the marker noise σ is to be estimated ([`super::map`]'s module docs), the probes run
//! on the prior weighed by the starting σ₀, and the best start's finishing solve first
//! reaches the σ₀-optimum (to 0.1 SE; on a long trial first on every `round(√k)`-th frame,
//! [`super::probes::approach`]), where σ is estimated; then one more probe from there
//! on the re-weighed prior, and the finishing solves on every frame with it. A second start
//! that the σ₀ probes put apart is told apart again on the re-weighed prior (its probe and
//! the best start's continued alike there).
//!
//! When the given start is already in the best basin (a landmark model on real gait, as a
//! rule), the cost is the probes alone: on opencap_expert1 walking1 (143 frames) every start
//! was within 1e-6 of the others after the probes and only one was finished.
//!
//! Starts are drawn from the prior where the problem has one (`N(μ_k, s_k²)` truncated at
//! ±2 `s_k`: where the anatomy says the joint is), else moved from the given start by up to
//! `restart_m` / `restart_rad` ([`super::restart_point`]); always clamped into the bounds.
//! After a few iterations the basins are told apart: in the study above the starts that
//! ended in the best optimum were within 0.5 % of it after six iterations, those in worse
//! optima 5–30 % above it.
//!
//! Levenberg–Marquardt never raises the objective, so continuing a probe only lowers it; a
//! start that converged within its probe needs no continuation.

use rayon::prelude::*;

use super::calibration::{ConvergenceStage, StartRun};
use super::map::{Preliminary, SIGMA_POINT_RESOLUTION_SE};
pub(crate) use super::probes::ProbeStarts;
use super::probes::{approach_stride, carried, probe_stride, seeded_start, subsample};
pub(crate) use super::summary::warning;
pub(crate) use super::summary::GlobalSearch;
pub(crate) use super::summary::SAME_OPTIMUM;
use super::{FitSettings, Observer};
use crate::calibrate::joint::{solve_joint, solve_joint_to, JointOptions, RESOLUTION_MAX_DAMPING};
use crate::calibrate::{Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::solver::Termination;

/// The two best probes are taken to be in the same basin (only the best is finished) when
/// their objectives differ by less than this (relative).
pub(crate) const SAME_BASIN: f64 = 1e-4;

/// The stage of the best start's finishing solve on the prior weighed by the starting σ₀,
/// at whose end σ is estimated (`super::map`).
pub(crate) const SIGMA_STAGE: &str = "joint Levenberg-Marquardt at the starting σ (σ estimate)";

/// The probe from the σ₀-optimum on the re-weighed prior, before the best start's
/// finishing solve.
pub(crate) const REPROBE_STAGE: &str = "probe at the estimated σ";

/// The best start's σ estimate ([`run`]): the σ₀-optimum it was estimated at and the
/// objectives on the way, and the probe at the estimated σ from there (with its objectives;
/// `None` when the probes ran on every frame).
struct SigmaStage {
    /// The probe continued on every `m`-th frame first: (m, fit, objectives).
    approach: Option<(usize, Fit, Vec<f64>)>,
    at: Fit,
    history: Vec<f64>,
    reprobe: Option<Run>,
    /// The second start's probe continued on the re-weighed prior.
    candidate: Option<Candidate>,
}

/// The objective before the fit: the marker term alone (the prior term is added once σ is
/// final), or the whole objective.
enum Before {
    Data(f64),
    Cost(f64),
}

/// Records the objective after each iteration (m²) of a solver run on another thread.
#[derive(Default)]
struct History(Vec<f64>);

impl Observer for History {
    fn iteration(&mut self, _iteration: usize, objective: f64) {
        self.0.push(objective);
    }
}

/// The outcome of [`run`]: every start's fit and record (start order), the global phase's
/// summary, and the given start's inner solutions and objective before any iteration.
pub(crate) struct Outcome {
    pub fits: Vec<Fit>,
    pub runs: Vec<StartRun>,
    pub summary: GlobalSearch,
    pub q_before: Vec<Vec<f64>>,
    pub cost_before: f64,
}

/// From this many frames on the finishing solves run one after the other, each on every
/// thread (its per-frame passes are parallel), instead of side by side: two solves at once
/// would hold two sets of per-frame coordinates and two block caches, and with this many
/// frames one solve keeps the threads busy. The result is the same either way.
pub(crate) const SEQUENTIAL_FINISH_FRAMES: usize = 4096;

/// A solver run: its fit and the objective after each iteration (m²).
type Run = (Fit, Vec<f64>);

/// The second start's probe continued on the re-weighed prior: (start, fit, objectives, and
/// the objective of the best start's probe continued alike).
type Candidate = (usize, Fit, Vec<f64>, f64);

/// Runs the global phase on `prob` from `start` with `settings.probes` extra starts (the
/// module docs), from `starts` (each [`seeded_start`] of the same problem, start and
/// settings) when given; progress goes to `observer` in start order.
pub(crate) fn run(
    prob: &mut Problem,
    start: &[f64],
    settings: &FitSettings,
    pre: Option<Preliminary>,
    starts: Option<ProbeStarts>,
    observer: &mut dyn Observer,
) -> Outcome {
    let n = settings.probes + 1;
    let (finish, short) = solver_options(settings);
    let stride = probe_stride(prob, settings);
    let coarse = subsample(prob, stride);
    observer.progress(0, n + 1);
    let probes = match starts.filter(|s| s.len() == n) {
        Some(starts) => probe(&coarse, starts, &short),
        None => seed_and_probe(prob, &coarse, start, settings, &short),
    };
    // The observer hears of every probe after the fact, in start order.
    for (k, (fit, hist)) in probes.iter().enumerate() {
        let stage = format!("probe {} of {n}", k + 1);
        replay(
            observer,
            &stage,
            Some(short.max_iterations),
            hist,
            fit.termination,
        );
    }
    observer.progress(n, n + 1);
    let (best, second) = rank(&probes);
    let probe_objective = probes.iter().map(|p| p.0.cost).collect();
    // (The σ estimate computed the objective before the fit at the same start on the same
    // frames; the prior term is added once σ is final.)
    let estimate = pre.as_ref().is_some_and(|p| p.pending) && prob.prior.is_some();
    let (q_before_start, q_before, before) = before_fit(prob, start, pre);
    let probed = Probed {
        runs: probes,
        stride,
        best,
        second,
        seeded: std::sync::Mutex::new(Some(q_before_start)),
    };
    let sigma_stage = estimate.then(|| estimate_sigma(prob, &probed, &finish, &short));
    let prob: &Problem = prob;
    let order = finish_order(&probed, sigma_stage.as_ref());
    let continued = finish_all(prob, &probed, sigma_stage.as_ref(), &order, &finish);
    let cost_before = match before {
        Before::Data(data) => data + prob.prior_cost(start),
        Before::Cost(cost) => cost,
    };
    if let Some(st) = &sigma_stage {
        report_sigma(observer, st, order[0], &short);
    }
    for (&k, (fit, hist)) in order.iter().zip(&continued) {
        let stage = format!("start {}: joint Levenberg-Marquardt", k + 1);
        replay(observer, &stage, None, hist, fit.termination);
    }
    observer.progress(n + 1, n + 1);
    let (fits, runs) = records(probed, sigma_stage.as_ref(), &order, &continued);
    let summary = summarize(&fits, order, probe_objective, &short, coarse.frames.len());
    Outcome {
        fits,
        runs,
        summary,
        q_before,
        cost_before,
    }
}

/// The finishing solves' options (the user's iteration limit, `FitSettings::max_iterations`)
/// and the probes' (at most as many iterations).
fn solver_options(settings: &FitSettings) -> (JointOptions, JointOptions) {
    let finish = JointOptions {
        max_iterations: settings
            .max_iterations
            .unwrap_or(JointOptions::default().max_iterations),
        ..JointOptions::default()
    };
    let short = JointOptions {
        max_iterations: settings.probe_iterations.max(1).min(finish.max_iterations),
        ..JointOptions::default()
    };
    (finish, short)
}

/// Tells `observer` of a run that ended on another thread, as one stage.
fn replay(
    observer: &mut dyn Observer,
    stage: &str,
    budget: Option<usize>,
    history: &[f64],
    termination: Termination,
) {
    observer.stage_started(stage, budget);
    for (i, &c) in history.iter().enumerate() {
        observer.iteration(i + 1, c);
    }
    observer.stage_ended(termination);
}

/// Every start probed on the subsampled problem `coarse`, in parallel, in start order.
fn probe(coarse: &Problem, starts: ProbeStarts, short: &JointOptions) -> Vec<Run> {
    starts
        .into_par_iter()
        .map(|(p0, q0)| {
            let mut h = History::default();
            let fit = solve_joint(coarse, &coarse.to_scaled(&p0), q0, short, &mut h);
            (fit, h.0)
        })
        .collect()
}

/// Every start seeded on the probes' frames `coarse` ([`seeded_start`]) and probed there,
/// one task per start, in start order: each probe begins as soon as its own start's seeded
/// inverse kinematics is done (the same numbers as seeding every start first).
fn seed_and_probe(
    prob: &Problem,
    coarse: &Problem,
    start: &[f64],
    settings: &FitSettings,
    short: &JointOptions,
) -> Vec<Run> {
    (0..settings.probes + 1)
        .into_par_iter()
        .map(|k| {
            let (p0, q0) = seeded_start(prob, coarse, start, settings, k);
            let mut h = History::default();
            let fit = solve_joint(coarse, &coarse.to_scaled(&p0), q0, short, &mut h);
            (fit, h.0)
        })
        .collect()
}

/// The best probe (lowest objective, ties: the lower start) and the second start to finish
/// unless the probes put it in the best's basin: the given start (so the result is never
/// worse than one local fit from it), else the runner-up.
fn rank(probes: &[Run]) -> (usize, Option<usize>) {
    let mut order: Vec<usize> = (0..probes.len()).collect();
    order.sort_by(|&a, &b| {
        probes[a]
            .0
            .cost
            .total_cmp(&probes[b].0.cost)
            .then(a.cmp(&b))
    });
    let best = order[0];
    let second = if best != 0 {
        Some(0)
    } else {
        order.get(1).copied()
    };
    (best, second)
}

/// The given start on every frame before any iteration: its seeded coordinates, its inner
/// solutions and the objective there (from the σ estimate's preliminary pass when given).
fn before_fit(
    prob: &Problem,
    start: &[f64],
    pre: Option<Preliminary>,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, Before) {
    match pre {
        Some(pre) => (pre.q_seed, pre.q_inner, Before::Data(pre.data_cost)),
        None => {
            let q_seed = prob.initial_coords(start);
            let mut q = q_seed.clone();
            let cost = prob.inner(start, &mut q, &mut IkWorkspace::new(prob.model));
            (q_seed, q, Before::Cost(cost))
        }
    }
}

/// The probes and what the later stages read of them.
struct Probed {
    /// Every start's probe, in start order.
    runs: Vec<Run>,
    /// The probes ran on every `stride`-th frame.
    stride: usize,
    best: usize,
    second: Option<usize>,
    /// The given start's seeded coordinates on every frame, moved (not copied) into its
    /// finishing solve.
    seeded: std::sync::Mutex<Option<Vec<Vec<f64>>>>,
}

impl Probed {
    /// Where start `k`'s finishing solve begins on every frame.
    fn coords_of(&self, prob: &Problem, k: usize) -> Vec<Vec<f64>> {
        let f = &self.runs[k].0;
        let seeded = (self.stride > 1 && k == 0)
            .then(|| self.seeded.lock().ok()?.take())
            .flatten();
        if self.stride == 1 {
            f.coords.clone()
        } else if let Some(q) = seeded {
            q
        } else {
            prob.initial_coords(&f.p)
        }
    }

    /// The probes put start `k` outside the best's basin.
    fn apart(&self, k: usize) -> bool {
        let (c1, c2) = (self.runs[self.best].0.cost, self.runs[k].0.cost);
        c2 - c1 > SAME_BASIN * c1.abs()
    }
}

/// σ still to be estimated (`super::map`'s module docs): the best start finished on the
/// prior weighed by the starting σ₀ to the preliminary resolution, σ and the per-parameter
/// factors estimated there, and (on a subsample) the probes continued on the re-weighed prior.
fn estimate_sigma(
    prob: &mut Problem,
    probed: &Probed,
    finish: &JointOptions,
    short: &JointOptions,
) -> SigmaStage {
    let (k, stride) = (probed.best, probed.stride);
    let f = &probed.runs[k].0;
    let mut h = History::default();
    let mut approach = None;
    let at = if stride == 1 && f.termination != Termination::IterationLimit {
        f.clone()
    } else {
        // On a long trial first on intermediate frames (`super::probes::approach`).
        let (s0, q0) = match approach_stride(stride) {
            Some(m) => {
                // The given start's seeded coordinates are no longer needed (it is this
                // start): not two coordinate sets of the whole trial at once.
                if k == 0 {
                    drop(probed.seeded.lock().ok().and_then(|mut q| q.take()));
                }
                let mut ha = History::default();
                let fm = super::probes::approach(prob, m, f, finish, &mut ha);
                let start = (fm.s.clone(), prob.initial_coords(&fm.p));
                approach = Some((m, fm, ha.0));
                start
            }
            None => (f.s.clone(), probed.coords_of(prob, k)),
        };
        solve_joint_to(prob, &s0, q0, finish, SIGMA_POINT_RESOLUTION_SE, &mut h)
    };
    super::map::estimate_noise(prob, &at);
    let (reprobe, candidate) = if stride > 1 {
        let (r, c) = reprobe(prob, probed, &at, short);
        (Some(r), c)
    } else {
        (None, None)
    };
    SigmaStage {
        approach,
        at,
        history: h.0,
        reprobe,
        candidate,
    }
}

/// A probe on the re-weighed prior from the σ₀-optimum `at` (its frames' coordinates are
/// the σ₀-optimum's): the finishing solve begins near its optimum for a few coarse
/// iterations' cost. Beside it the second start's probe is continued on the re-weighed
/// prior, so that the two are told apart on the prior of the finishing solves, as without
/// the σ estimate (only when the probes on σ₀ put it apart: on the same prior weighed a
/// little differently the two stay in one basin).
fn reprobe(
    prob: &Problem,
    probed: &Probed,
    at: &Fit,
    short: &JointOptions,
) -> (Run, Option<Candidate>) {
    let stride = probed.stride;
    let coarse = subsample(prob, stride);
    let reprobe = || {
        let q0: Vec<Vec<f64>> = at.coords.iter().step_by(stride).cloned().collect();
        let mut h = History::default();
        let fit = solve_joint(&coarse, &at.s, q0, short, &mut h);
        (fit, h.0)
    };
    let candidate = || {
        probed.second.filter(|&j| probed.apart(j)).map(|j| {
            let on = |k: usize, h: &mut History| {
                let f = &probed.runs[k].0;
                solve_joint(&coarse, &f.s, f.coords.clone(), short, h)
            };
            let mut h = History::default();
            let fit = on(j, &mut h);
            // The best start's probe continued alike: like compared with like.
            let best_cost = on(probed.best, &mut History::default()).cost;
            (j, fit, h.0, best_cost)
        })
    };
    rayon::join(reprobe, candidate)
}

/// The starts to finish: the best, and the second unless the probes put it in the best's
/// basin (told apart by their probes on the re-weighed prior when σ was estimated).
fn finish_order(probed: &Probed, sigma: Option<&SigmaStage>) -> Vec<usize> {
    let apart = |k: usize| {
        let (c1, c2) = match sigma.map(|st| (&st.reprobe, &st.candidate)) {
            Some((_, Some((j, c, _, b)))) if *j == k => (*b, c.cost),
            _ => return probed.apart(k),
        };
        c2 - c1 > SAME_BASIN * c1.abs()
    };
    std::iter::once(probed.best)
        .chain(probed.second.filter(|&k| apart(k)))
        .collect()
}

/// The finishing solves on every frame of the starts in `order` (side by side unless the
/// trial is long, [`SEQUENTIAL_FINISH_FRAMES`]).
fn finish_all(
    prob: &Problem,
    probed: &Probed,
    sigma: Option<&SigmaStage>,
    order: &[usize],
    finish: &JointOptions,
) -> Vec<Run> {
    let finish_one = |k: usize| {
        let mut h = History::default();
        if let Some(st) = sigma.filter(|_| k == order[0]) {
            let (s0, q0, near) = final_start(prob, st, probed.stride);
            // From a point consistent to first order the Gauss–Newton step is trusted from
            // the first iteration.
            let opts = JointOptions {
                initial_damping: match near {
                    true => RESOLUTION_MAX_DAMPING,
                    false => finish.initial_damping,
                },
                ..*finish
            };
            let fit = solve_joint(prob, s0, q0, &opts, &mut h);
            return (fit, h.0);
        }
        let f = &probed.runs[k].0;
        if probed.stride == 1 && f.termination != Termination::IterationLimit {
            return (f.clone(), Vec::new());
        }
        let q0 = probed.coords_of(prob, k);
        let fit = solve_joint(prob, &f.s, q0, finish, &mut h);
        (fit, h.0)
    };
    if prob.frames.len() >= SEQUENTIAL_FINISH_FRAMES {
        order.iter().map(|&k| finish_one(k)).collect()
    } else {
        order.par_iter().map(|&k| finish_one(k)).collect()
    }
}

/// Where the finishing solve of the start the σ stage continued begins: the re-probe's
/// parameters (the σ₀-optimum's without one) and the σ₀-optimum's coordinates, carried along
/// with the re-probe's change of its frames' coordinates ([`carried`]) when that fits the
/// re-probe's parameters better than the coordinates as they were. The carried coordinates
/// are consistent with the parameters to first order: on gait2392 walk1 they start the solve
/// at an objective of 0.068 m² where the coordinates as they were gave 3.3 m² (0.062 at the
/// optimum), and it takes 10 iterations instead of 13. (Polishing the coordinates by an
/// inner pass instead cost more than it saved.) Also whether the point is that near.
fn final_start<'a>(
    prob: &Problem,
    st: &'a SigmaStage,
    stride: usize,
) -> (&'a [f64], Vec<Vec<f64>>, bool) {
    let Some((r, _)) = &st.reprobe else {
        return (&st.at.s, st.at.coords.clone(), true);
    };
    let moved = carried(prob, &st.at.coords, &r.coords, stride);
    let near = prob.marker_cost(&r.p, &moved) < prob.marker_cost(&r.p, &st.at.coords);
    // Never two new coordinate sets of the whole trial at once.
    let q0 = if near {
        moved
    } else {
        drop(moved);
        st.at.coords.clone()
    };
    (&r.s, q0, near)
}

/// Tells `observer` of the σ estimate's stages of the start `first` finished first.
fn report_sigma(observer: &mut dyn Observer, st: &SigmaStage, first: usize, short: &JointOptions) {
    if let Some((m, fit, hist)) = &st.approach {
        let stage = format!("start {}: {SIGMA_STAGE}, every {m}. frame", first + 1);
        replay(observer, &stage, None, hist, fit.termination);
    }
    let stage = format!("start {}: {SIGMA_STAGE}", first + 1);
    replay(observer, &stage, None, &st.history, st.at.termination);
    if let Some((fit, hist)) = &st.reprobe {
        let stage = format!("start {}: {REPROBE_STAGE}", first + 1);
        replay(
            observer,
            &stage,
            Some(short.max_iterations),
            hist,
            fit.termination,
        );
    }
}

/// One stage of a start's record, its objectives in m².
fn stage(name: String, history: &[f64]) -> ConvergenceStage {
    ConvergenceStage {
        stage: name,
        objective: history.to_vec(),
    }
}

/// Every start's fit and record, in start order: its probe, the continued probe on the
/// re-weighed prior, and for a finished start the σ estimate's stages and its finishing
/// solve (iterations and evaluations summed over them all).
fn records(
    probed: Probed,
    sigma: Option<&SigmaStage>,
    order: &[usize],
    continued: &[Run],
) -> (Vec<Fit>, Vec<StartRun>) {
    let stride = probed.stride;
    let mut fits = Vec::with_capacity(probed.runs.len());
    let mut runs = Vec::with_capacity(probed.runs.len());
    for (k, (fit, hist)) in probed.runs.into_iter().enumerate() {
        let name = format!("probe (joint Levenberg-Marquardt, every {stride}. frame)");
        let mut convergence = vec![stage(name, &hist)];
        let mut fit = fit;
        if let Some((_, c, hist, _)) = sigma
            .and_then(|st| st.candidate.as_ref())
            .filter(|c| c.0 == k)
        {
            let name = format!("{REPROBE_STAGE} (every {stride}. frame)");
            convergence.push(stage(name, hist));
            fit.iterations += c.iterations;
            fit.evaluations += c.evaluations;
        }
        if let Some(j) = order.iter().position(|&o| o == k) {
            let pre = sigma.filter(|_| j == 0);
            if let Some(st) = pre {
                sigma_stages(st, stride, &mut fit, &mut convergence);
            }
            let (done, hist) = &continued[j];
            if !hist.is_empty() || stride > 1 || pre.is_some() {
                convergence.push(stage("joint Levenberg-Marquardt".to_string(), hist));
                let probe_iterations = fit.iterations;
                let probe_evaluations = fit.evaluations;
                fit = done.clone();
                fit.iterations += probe_iterations;
                fit.evaluations += probe_evaluations;
            }
        } else if stride > 1 {
            // A probe on a subsample: its objective is not comparable with a fit's.
            fit.cost = f64::INFINITY;
        }
        runs.push(StartRun {
            start: k,
            objective: fit.cost,
            iterations: fit.iterations,
            evaluations: fit.evaluations,
            termination: fit.termination,
            convergence,
        });
        fits.push(fit);
    }
    (fits, runs)
}

/// The σ estimate's stages in the record of the start finished first: the approach on
/// intermediate frames, the solve on the σ₀-weighed prior and the probe on the re-weighed one.
fn sigma_stages(
    st: &SigmaStage,
    stride: usize,
    fit: &mut Fit,
    convergence: &mut Vec<ConvergenceStage>,
) {
    if let Some((m, a, hist)) = &st.approach {
        convergence.push(stage(format!("{SIGMA_STAGE}, every {m}. frame"), hist));
        fit.iterations += a.iterations;
        fit.evaluations += a.evaluations;
    }
    convergence.push(stage(SIGMA_STAGE.to_string(), &st.history));
    if !st.history.is_empty() {
        fit.iterations += st.at.iterations;
        fit.evaluations += st.at.evaluations;
    }
    if let Some((r, hist)) = &st.reprobe {
        convergence.push(stage(
            format!("{REPROBE_STAGE} (every {stride}. frame)"),
            hist,
        ));
        fit.iterations += r.iterations;
        fit.evaluations += r.evaluations;
    }
}

/// The global phase's summary: the finished starts' objectives and whether they agree.
fn summarize(
    fits: &[Fit],
    order: Vec<usize>,
    probe_objective: Vec<f64>,
    short: &JointOptions,
    probe_frames: usize,
) -> GlobalSearch {
    let finished_objective: Vec<f64> = order.iter().map(|&k| fits[k].cost).collect();
    let best = finished_objective
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let agree = finished_objective
        .iter()
        .all(|&c| c - best <= SAME_OPTIMUM * best.abs());
    GlobalSearch {
        starts: fits.len(),
        probe_iterations: short.max_iterations,
        probe_frames,
        probe_objective,
        finished: order,
        finished_objective,
        agree,
    }
}

#[cfg(test)]
#[path = "global_tests.rs"]
mod tests;
