//! [`calibrate`]: one calibration from start to parameter table (see the module docs).

use serde::Serialize;

use super::starts::{full_starts, multi_start_summary};
use super::{FitSettings, Method, Observer, Termination, WorkflowError};
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::uncertainty::Identifiability;
use crate::calibrate::uncertainty::SeMethod;
use crate::calibrate::uncertainty::Uncertainty;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::uncertainty::{analyze_reduced, unidentifiable_subset, Reduced};
use crate::calibrate::{Fit, Problem};
use crate::model::spec::Unit;
use crate::model::spec::MM_PER_M;
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// One free parameter of a calibration, in SI: metres or radians (`unit`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamRow {
    pub name: String,
    pub group: String,
    /// The unit of every value of the row: [`Unit::Metre`] or [`Unit::Radian`].
    pub unit: Unit,
    pub start: f64,
    pub fitted: f64,
    /// `fitted − start`.
    pub change: f64,
    /// Standard error (same unit), from `uncertainty_method`; `None`: not determined. The
    /// uncertainty record's value ([`Uncertainty::params`], in the shown unit) in SI.
    pub se: Option<f64>,
    /// 95 % interval (same unit, from the uncertainty record likewise).
    pub ci95: Option<[f64; 2]>,
    /// `determined`, `poor` or `undetermined`.
    pub identifiability: Option<Identifiability>,
    pub uncertainty_method: Option<SeMethod>,
    /// Prior SD and mean (same unit), when the fit used a prior on this parameter.
    pub prior_sd: Option<f64>,
    pub prior_mean: Option<f64>,
    /// Share of the posterior information that came from the trial (0–1), and in words.
    pub data_share: Option<f64>,
    pub source: Option<crate::calibrate::prior::Source>,
}

/// One optimizer stage (e.g. the particle swarm, then its polish).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConvergenceStage {
    pub stage: String,
    /// `e_inner` (m²) at the start of the stage, then after each of its iterations.
    pub objective: Vec<f64>,
}

/// One start of a (multi-start) fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartRun {
    /// 0 is the given start.
    pub start: usize,
    /// Final objective (m²).
    pub objective: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub termination: Termination,
    /// The objective per stage of this start.
    pub convergence: Vec<ConvergenceStage>,
}

/// What several starts found (`starts > 1`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MultiStart {
    pub starts: usize,
    /// Final objective of every start (m²); start 0 is the given start.
    pub objective: Vec<f64>,
    /// Starts whose objective is within 1e-9 (relative) of the best.
    pub reached_best: usize,
    /// Per free parameter: the range (max − min) of its fitted value over the starts
    /// (m or rad).
    pub spread: Vec<(String, f64)>,
}

/// The result of [`calibrate`], in SI: lengths in metres, angles in radians, objectives
/// (`e_inner`) in m². The front ends show them in mm, degrees and mm² (the uncertainty record
/// [`Uncertainty::params`] alone carries its shown unit, named in each row).
#[derive(Debug, Clone, Serialize)]
pub struct Calibration {
    pub method: Method,
    /// The seed of the run ([`FitSettings::seed`]).
    pub seed: u64,
    pub frames: usize,
    pub skipped_frames: usize,
    pub free_parameters: usize,
    pub parameters: Vec<ParamRow>,
    /// RMS marker distance over every present sample at the start and at the fit (m).
    pub rms_before: f64,
    pub rms_after: f64,
    /// The same per model marker, in model order (m; NaN: never present).
    pub marker_rms_before: Vec<(String, f64)>,
    pub marker_rms_after: Vec<(String, f64)>,
    /// `e_inner` at the start and at the fit (m²).
    pub cost_before: f64,
    pub cost_after: f64,
    /// Of the best start (the particle swarm: swarm and polish together).
    pub iterations: usize,
    pub evaluations: usize,
    /// `termination == Converged`.
    pub converged: bool,
    /// How the best start's last stage ended.
    pub termination: Termination,
    /// The objective after every outer iteration, per stage, of the best start.
    pub convergence: Vec<ConvergenceStage>,
    /// Which start won (0: the given start).
    pub best_start: usize,
    /// Every start, in order.
    pub start_runs: Vec<StartRun>,
    /// Uncertainty and identifiability of the free parameters.
    pub uncertainty: Option<Uncertainty>,
    /// Parameters held at their starting values by `fix_unidentifiable`.
    pub fixed_unidentifiable: Vec<String>,
    /// Several starts: the optima they reached.
    pub multistart: Option<MultiStart>,
    /// The default's global phase: short probes from several starts, the best finished
    /// ([`super::global`]); `None` when not run (`probes` 0, several full starts, the swarm).
    pub global: Option<super::global::GlobalSearch>,
    /// Set when the fit is not known to be the global optimum (the finished starts of the
    /// global phase, or the full starts, ended at different optima).
    pub global_warning: Option<String>,
    /// Marker noise SD per axis (m) that weighed the prior; `None`: no prior
    /// (unregularized fit).
    pub prior_noise: Option<f64>,
    /// Whether that noise was estimated from the residuals (else given).
    pub prior_noise_estimated: bool,
    /// The free parameters whose prior weight was multiplied by a factor above 1, with the
    /// factor ([`crate::calibrate::uncertainty::parameter_inflation`]); empty when σ was given.
    pub prior_inflation: Vec<(String, f64)>,
    /// Anatomical plausibility of the fitted joints ([`crate::plausibility`]).
    pub plausibility: Vec<crate::plausibility::Plausibility>,
    /// How far to trust the fit ([`super::verdict`]): set by the calibrations that judge
    /// their inputs and result ([`super::refine::calibrate_refined`],
    /// [`super::calibrate_holding_redundant`]); `ok` without reasons elsewhere.
    pub verdict: super::verdict::Verdict,
    /// The fitted solution (SI), the start and the free parameters finally fitted.
    #[serde(skip)]
    pub fit: Fit,
    #[serde(skip)]
    pub start: Vec<f64>,
    #[serde(skip)]
    pub free: Vec<ParamId>,
}

impl Calibration {
    /// Takes `u` as the calibration's uncertainty: each parameter row's SE, interval,
    /// identifiability and method from it.
    pub(super) fn set_uncertainty(&mut self, u: Uncertainty) {
        for (row, pu) in self.parameters.iter_mut().zip(&u.params) {
            let k = shown_to_si(row.unit);
            row.se = pu.se.map(|v| v * k);
            row.ci95 = pu.ci.map(|[lo, hi]| [lo * k, hi * k]);
            row.identifiability = Some(pu.status);
            row.uncertainty_method = Some(pu.method);
        }
        self.uncertainty = Some(u);
    }
}

/// e_inner (m²) in mm², for a message.
pub(super) fn mm2(cost: f64) -> f64 {
    cost * MM_PER_M * MM_PER_M
}

/// The factor from a value in the shown unit of `unit` (mm, deg) to SI (m, rad).
fn shown_to_si(unit: Unit) -> f64 {
    match unit {
        Unit::Metre => crate::model::spec::M_PER_MM,
        Unit::Radian => std::f64::consts::PI / 180.0,
    }
}

/// Per-model-marker RMS distance (m) for parameters `p` and per-frame coordinates.
fn per_marker_rms(prob: &Problem, p: &[f64], qs: &[Vec<f64>]) -> Vec<f64> {
    let mut sums = vec![(0.0, 0usize); prob.model.markers().len()];
    prob.visit_marker_errors(p, qs, |j, e| {
        if !e.x.is_nan() {
            sums[j].0 += e.norm_squared();
            sums[j].1 += 1;
        }
    });
    sums.iter()
        .map(|(s, n)| {
            if *n == 0 {
                f64::NAN
            } else {
                (s / *n as f64).sqrt()
            }
        })
        .collect()
}

/// Fits the free parameters `free` of `model` to `trials` from `start` (every start of
/// `settings`), without the uncertainty analysis; the prior weighed by the given noise (m) and
/// per-parameter factors, or by estimated ones (`noise` `None`: [`super::map`]). Returns the
/// calibration and the problem it solved, its prior weighed by the σ and factors the fit
/// ended with (what the analysis and the conflict step of this fit use).
fn fit_free<'m>(
    model: &'m Model,
    start: &[f64],
    trials: &[&'m Trial],
    free: &[ParamId],
    settings: &FitSettings,
    (known, inflation): (super::map::Known, &[(String, f64)]),
    observer: &mut dyn Observer,
) -> Result<(Calibration, Problem<'m>), WorkflowError> {
    // With the global phase the σ estimate is finished there (`super::map`'s module docs).
    let global_phase = settings.effective_probes() > 0;
    let (mut prob, _, pre) =
        super::map::map_problem_with(model, start, trials, free, settings, known, global_phase)?;
    super::map::set_inflation(&mut prob, inflation);
    let (fits, runs, global, q_before, cost_before) = if global_phase {
        let out = super::global::run(&mut prob, start, settings, pre, None, observer);
        (
            out.fits,
            out.runs,
            Some(out.summary),
            out.q_before,
            out.cost_before,
        )
    } else {
        let (fits, runs, q, c) = full_starts(&prob, start, settings, observer);
        (fits, runs, None, q, c)
    };
    let mut fits = fits;
    // The first of equal minima wins.
    let best = (0..fits.len())
        .min_by(|&a, &b| fits[a].cost.total_cmp(&fits[b].cost))
        .expect("at least one start");
    let multistart =
        (global.is_none() && fits.len() > 1).then(|| multi_start_summary(&prob, &fits, best));
    let global_warning = match (&global, &multistart) {
        (Some(g), _) => super::global::warning(g),
        (None, Some(ms)) if ms.reached_best < 2 => Some(format!(
            "the fit is not known to be the global optimum: only 1 of {} starts reached \
             the lowest objective",
            ms.starts
        )),
        _ => None,
    };
    let fit = fits.swap_remove(best);
    let names = |v: Vec<f64>| -> Vec<(String, f64)> {
        model
            .markers()
            .iter()
            .zip(v)
            .map(|(m, r)| (m.name.clone(), r))
            .collect()
    };
    let parameters = param_rows(model, &prob, start, &fit);
    let tg = std::time::Instant::now();
    let ((rms_before, rms_after), (per_marker_before, per_marker_after)) =
        rms_before_after(&prob, start, &q_before, &fit);
    if std::env::var("JF_T").is_ok() {
        eprintln!("T rms {:.3}", tg.elapsed().as_secs_f64() * 1e3);
    }
    let cal = Calibration {
        method: settings.method,
        seed: settings.seed,
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
        free_parameters: prob.n_free(),
        parameters,
        rms_before,
        rms_after,
        marker_rms_before: names(per_marker_before),
        marker_rms_after: names(per_marker_after),
        cost_before,
        cost_after: fit.cost,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        converged: fit.converged(),
        termination: fit.termination,
        convergence: runs[best].convergence.clone(),
        best_start: best,
        start_runs: runs,
        uncertainty: None,
        fixed_unidentifiable: Vec::new(),
        multistart,
        global,
        global_warning,
        prior_noise: prob.prior.as_ref().map(|p| p.noise),
        prior_noise_estimated: known.noise.is_none(),
        prior_inflation: super::map::inflation_of(&prob),
        plausibility: crate::plausibility::assess(model, &fit.p),
        verdict: super::verdict::Verdict::default(),
        fit,
        start: start.to_vec(),
        free: free.to_vec(),
    };
    Ok((cal, prob))
}

/// The free parameters' rows of a fit from `start` (SI, no uncertainty yet).
/// The marker RMS before (`start`, coordinates `q_before`) and after the fit, overall and
/// per marker: four passes of forward kinematics over the frames, two on each thread (each
/// pass's sums in frame order, as alone).
#[allow(clippy::type_complexity)]
fn rms_before_after(
    prob: &Problem,
    start: &[f64],
    q_before: &[Vec<f64>],
    fit: &Fit,
) -> ((f64, f64), (Vec<f64>, Vec<f64>)) {
    rayon::join(
        || {
            rayon::join(
                || prob.marker_rms(start, q_before),
                || prob.marker_rms(&fit.p, &fit.coords),
            )
        },
        || {
            rayon::join(
                || per_marker_rms(prob, start, q_before),
                || per_marker_rms(prob, &fit.p, &fit.coords),
            )
        },
    )
}

fn param_rows(model: &Model, prob: &Problem, start: &[f64], fit: &Fit) -> Vec<ParamRow> {
    prob.free
        .iter()
        .map(|&i| {
            let par = &model.parameters()[i];
            let prior_sd = prob.prior.as_ref().and(par.prior_sd);
            ParamRow {
                name: par.name.clone(),
                group: par.group.clone(),
                unit: par.unit,
                start: start[i],
                fitted: fit.p[i],
                change: fit.p[i] - start[i],
                se: None,
                ci95: None,
                identifiability: None,
                uncertainty_method: None,
                prior_sd,
                prior_mean: prior_sd.map(|_| par.prior_mean),
                data_share: None,
                source: None,
            }
        })
        .collect()
}

/// Calibrates the parameters `free` of `model` on `trials` from `start` (a full parameter
/// vector; the others stay at their `start` values) as `settings` say: every start, the
/// best kept, then (with `settings.uncertainty`) the uncertainty analysis and, with
/// `fix_unidentifiable`, up to three rounds of holding the parameters the trials cannot
/// determine at their start and refitting the rest (subset selection plans on the reduced
/// normal matrix of the current fit; a refit moves the optimum a little, so it is repeated).
pub fn calibrate(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<Calibration, WorkflowError> {
    calibrate_keeping_system(model, start, trials, free, settings, None, observer)
        .map(|k| k.calibration)
}

/// [`fit_keeping_system`] with its uncertainty analysis (`settings.uncertainty`) on the
/// fit's prior as it is.
pub(crate) fn calibrate_keeping_system<'m>(
    model: &'m Model,
    start: &[f64],
    trials: &[&'m Trial],
    free: &[ParamId],
    settings: &FitSettings,
    seed: Option<&[Vec<f64>]>,
    observer: &mut dyn Observer,
) -> Result<Kept<'m>, WorkflowError> {
    let mut kept = fit_keeping_system(model, start, trials, free, settings, seed, observer)?;
    if let (Some(opts), Some(red)) = (&settings.uncertainty, &kept.system) {
        analysis_stage(&kept.problem, &mut kept.calibration, opts, red, observer);
    }
    Ok(kept)
}

/// The uncertainty analysis of `cal` (the fit of `prob`) from its reduced system `red`, into
/// `cal`, as the [`Observer`]'s stage [`UNCERTAINTY_STAGE`].
pub(crate) fn analysis_stage(
    prob: &Problem,
    cal: &mut Calibration,
    opts: &UncertaintyOptions,
    red: &Reduced,
    observer: &mut dyn Observer,
) {
    // A stage of its own: with the bootstrap it refits the model once per replicate (its
    // budget: the replicates).
    let (stage, budget) = match opts.bootstrap_replicates {
        n if n > 1 => (
            format!("{UNCERTAINTY_STAGE} ({n} bootstrap refits)"),
            Some(n),
        ),
        _ => (UNCERTAINTY_STAGE.to_string(), None),
    };
    observer.stage_started(&stage, budget);
    let u = analyze_reduced(prob, &cal.fit, opts, red);
    observer.stage_ended(Termination::Converged);
    cal.set_uncertainty(u);
}

/// A finished calibration with what later steps reuse: the problem of its final fit (its
/// prior weighed by the fit's σ in metres and per-parameter factors) and the reduced system
/// of its uncertainty analysis (`None` without the analysis).
pub(crate) struct Kept<'m> {
    pub(crate) calibration: Calibration,
    pub(crate) system: Option<Reduced>,
    pub(crate) problem: Problem<'m>,
}

/// Every free parameter unidentifiable: the error naming their groups.
fn nothing_identifiable(model: &Model, free: &[ParamId]) -> WorkflowError {
    let mut groups: Vec<&str> = Vec::new();
    for id in free {
        let g = model.parameters()[id.0].group.as_str();
        if !groups.contains(&g) {
            groups.push(g);
        }
    }
    WorkflowError::NothingIdentifiable {
        groups: groups.join(","),
    }
}

/// [`calibrate`] up to its uncertainty analysis: the fit, with the problem of the final fit
/// and (with `settings.uncertainty`) the reduced system the analysis is formed from
/// ([`Kept`]; [`reduced_system`] at the fit, on that problem) and the data shares it gives.
/// The prior–data conflict step ([`super::conflict`]) needs the same problem and
/// marker-term information, which costs as much as the rest of the analysis (opencap
/// walking1: one reduced system is about 1.5 % of the command's instructions, and the step
/// formed it twice more); it then runs the analysis once, with the prior it widens
/// ([`super::conflict::analyze_widened`]).
pub(crate) fn fit_keeping_system<'m>(
    model: &'m Model,
    start: &[f64],
    trials: &[&'m Trial],
    free: &[ParamId],
    settings: &FitSettings,
    seed: Option<&[Vec<f64>]>,
    observer: &mut dyn Observer,
) -> Result<Kept<'m>, WorkflowError> {
    let mut free = free.to_vec();
    let noise = settings.marker_noise;
    let known = super::map::Known {
        noise,
        coords: seed,
    };
    let (mut cal, mut prob) = fit_free(
        model,
        start,
        trials,
        &free,
        settings,
        (known, &[]),
        observer,
    )?;
    // Refits and the analysis weigh the prior by the noise (m, and per-parameter factors) of
    // the first fit.
    let noise_used = cal.prior_noise;
    let inflation = cal.prior_inflation.clone();
    let estimated = cal.prior_noise_estimated;
    let Some(opts) = &settings.uncertainty else {
        return Ok(Kept {
            calibration: cal,
            system: None,
            problem: prob,
        });
    };
    let mut fixed = Vec::new();
    for _ in 0..if settings.fix_unidentifiable { 3 } else { 0 } {
        let drop = unidentifiable_subset(&prob, &cal.fit, opts);
        if drop.is_empty() {
            break;
        }
        if drop.len() == free.len() {
            return Err(nothing_identifiable(model, &free));
        }
        fixed.extend(
            drop.iter()
                .map(|&k| model.parameters()[free[k].0].name.clone()),
        );
        free = free
            .iter()
            .enumerate()
            .filter(|(k, _)| !drop.contains(k))
            .map(|(_, id)| *id)
            .collect();
        // Fewer free parameters: a problem of their own (its free set, scaling and prior
        // differ), weighed by the first fit's σ and factors.
        let known = super::map::Known {
            noise: noise_used,
            coords: None,
        };
        let weights = (known, inflation.as_slice());
        (cal, prob) = fit_free(model, start, trials, &free, settings, weights, observer)?;
        cal.prior_noise_estimated = estimated;
    }
    // One reduced system for the analysis, the data shares and the conflict step.
    let ta = std::time::Instant::now();
    let red = reduced_system(&prob, &cal.fit.p, &cal.fit.coords);
    if std::env::var("JF_T").is_ok() {
        eprintln!("T red-final {:.3}", ta.elapsed().as_secs_f64() * 1e3);
    }
    let share = prob
        .prior
        .is_some()
        .then(|| crate::calibrate::prior::data_share(&prob, &red.normal));
    if let Some(share) = share {
        for (row, (&sh, &i)) in cal.parameters.iter_mut().zip(share.iter().zip(&prob.free)) {
            if model.parameters()[i].prior_sd.is_some() && sh.is_finite() {
                row.data_share = Some(sh);
                row.source = Some(crate::calibrate::prior::Source::of(sh));
            }
        }
    }
    cal.fixed_unidentifiable = fixed;
    Ok(Kept {
        calibration: cal,
        system: Some(red),
        problem: prob,
    })
}

/// The name of the uncertainty analysis stage reported to the [`Observer`] by [`calibrate`]
/// (followed by the bootstrap replicates, when there are any).
pub const UNCERTAINTY_STAGE: &str = "uncertainty analysis";
