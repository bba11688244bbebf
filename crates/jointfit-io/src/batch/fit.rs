//! One calibration of a job, values in and values out: the free parameters by group, the
//! outer solve, the uncertainty of the optimum (`jointfit::calibrate::uncertainty`).
//!
//! The calibration is [`jointfit::workflow::calibrate`] with the command line's settings
//! ([`FitOptions::settings`]), so the fitted parameters equal `jointfit calibrate`'s bit for
//! bit for the same options; this module only converts to SI rows and warning lines.

use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::uncertainty::Identifiability;
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, Unit, MM_PER_M};
use jointfit::trial::Trial;
use jointfit::workflow::{self, uncertainty_options, FitSettings, NoObserver, WorkflowError};
use serde::{Deserialize, Serialize};

/// The outer optimizer (as `jointfit calibrate --method`).
pub use jointfit::workflow::Method;

/// Settings of one calibration: the options of `jointfit calibrate`, with its defaults.
/// Fields added after the first release default when absent from a saved result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Parameter groups to fit (`hip`, `knee`, `ankle`, `all`).
    pub joints: Vec<String>,
    pub method: Method,
    /// Seed of the particle swarm, of the extra starts and of the bootstrap.
    pub seed: u64,
    /// Length parameters whose 95 % half-width exceeds this are flagged (mm).
    pub threshold_mm: f64,
    /// Angle parameters whose 95 % half-width exceeds this are flagged (deg).
    pub threshold_deg: f64,
    /// Moving-block bootstrap replicates of the intervals (0: none).
    pub bootstrap: usize,
    /// Starts of the fit (`--starts`: the given one and seeded moves; the best is kept).
    #[serde(default = "one")]
    pub starts: usize,
    /// Refit with the undetermined parameters held (`--fix-unidentifiable`).
    #[serde(default)]
    pub fix_unidentifiable: bool,
    /// Use the model file's parameter priors (`--prior model`; `false`: `--prior none`).
    #[serde(default = "yes")]
    pub priors: bool,
    /// Marker noise SD (mm) weighing the priors (`--marker-noise-mm`; `None`: estimated).
    #[serde(default)]
    pub marker_noise_mm: Option<f64>,
    /// Outer iteration limit (`--max-iter`; `None`: the solver's default).
    #[serde(default)]
    pub max_iterations: Option<usize>,
    /// Keep a fit whose verdict is `reject` (`--accept-rejected`); otherwise the job fails
    /// with the verdict's first reason.
    #[serde(default)]
    pub accept_rejected: bool,
}

fn one() -> usize {
    1
}

fn yes() -> bool {
    true
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            joints: vec!["all".into()],
            method: Method::Joint,
            seed: 1,
            threshold_mm: 5.0,
            threshold_deg: 5.0,
            bootstrap: 0,
            starts: 1,
            fix_unidentifiable: false,
            priors: true,
            marker_noise_mm: None,
            max_iterations: None,
            accept_rejected: false,
        }
    }
}

/// Most starts of one fit (each is a full fit).
pub const MAX_STARTS: usize = 1_000;
/// Most block-bootstrap replicates (each is a refit).
pub const MAX_BOOTSTRAP: usize = 2_000;
/// Most outer iterations of one fit.
pub const MAX_ITERATIONS: usize = 10_000;
/// Largest marker noise SD (mm).
pub const MAX_NOISE_MM: f64 = 1_000.0;

impl FitOptions {
    /// The options are within their documented limits (the command line's): `starts` 1 to
    /// [`MAX_STARTS`], `bootstrap` at most [`MAX_BOOTSTRAP`], `max_iterations` 1 to
    /// [`MAX_ITERATIONS`], thresholds finite and positive, `marker_noise_mm` finite, positive
    /// and at most [`MAX_NOISE_MM`]. The error is one line naming the option.
    pub fn check(&self) -> Result<(), String> {
        let count = |name: &str, v: usize, lo: usize, hi: usize| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(format!("{name} must be from {lo} to {hi} (got {v})"))
            }
        };
        let positive = |name: &str, v: f64, hi: f64| {
            if v.is_finite() && v > 0.0 && v <= hi {
                Ok(())
            } else {
                Err(format!(
                    "{name} must be a finite number greater than 0 and at most {hi} (got {v})"
                ))
            }
        };
        count("starts", self.starts, 1, MAX_STARTS)?;
        count("bootstrap", self.bootstrap, 0, MAX_BOOTSTRAP)?;
        if let Some(n) = self.max_iterations {
            count("max_iter", n, 1, MAX_ITERATIONS)?;
        }
        positive("threshold_mm", self.threshold_mm, f64::MAX)?;
        positive("threshold_deg", self.threshold_deg, f64::MAX)?;
        if let Some(mm) = self.marker_noise_mm {
            positive("marker_noise_mm", mm, MAX_NOISE_MM)?;
        }
        Ok(())
    }

    /// The workflow's settings for these options: the same as `jointfit calibrate` builds
    /// from the same command-line options, so the results are equal bit for bit.
    pub fn settings(&self) -> FitSettings {
        FitSettings {
            method: self.method,
            seed: self.seed,
            starts: self.starts,
            uncertainty: Some(uncertainty_options(
                self.threshold_mm,
                self.threshold_deg,
                self.bootstrap,
                self.seed,
            )),
            fix_unidentifiable: self.fix_unidentifiable,
            priors: self.priors,
            marker_noise: self
                .marker_noise_mm
                .map(|mm| mm * jointfit::model::M_PER_MM),
            max_iterations: self.max_iterations,
            refuse_mismatch: !self.accept_rejected,
            ..FitSettings::default()
        }
    }
}

/// One free parameter of a calibration, SI units (m or rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamRow {
    pub name: String,
    pub group: String,
    /// `m` or `rad`.
    pub unit: String,
    pub start: f64,
    pub fitted: f64,
    /// Standard error; `None` when the trials do not determine the parameter.
    pub se: Option<f64>,
    /// 95 % interval `[low, high]`.
    pub ci95: Option<[f64; 2]>,
    pub identifiability: Option<Identifiability>,
}

/// The result of [`calibrate`]: the fitted model and what a results table needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// The fitted model description (its nominal parameters are the fitted values).
    pub model: ModelSpec,
    pub method: Method,
    pub frames: usize,
    pub skipped_frames: usize,
    /// The free parameters, in model order.
    pub parameters: Vec<ParamRow>,
    /// RMS marker distance over all present samples at the start and at the optimum (m).
    pub rms_before: f64,
    pub rms_after: f64,
    /// Objective `e_inner` (m²) at the start and at the optimum.
    pub cost_before: f64,
    pub cost_after: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    /// Reading and fitting warnings, one line each.
    pub warnings: Vec<String>,
    /// How far to trust the fit ([`jointfit::workflow::verdict`]).
    #[serde(default)]
    pub verdict: jointfit::workflow::Verdict,
}

/// Fits the `opts.joints` parameters of `model` to `trials`, starting from `start`.
pub fn calibrate(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    opts: &FitOptions,
) -> Result<Calibration, WorkflowError> {
    calibrate_observed(model, start, trials, opts, &mut NoObserver)
}

/// [`calibrate`] reporting its solver's progress to `observer`.
pub fn calibrate_observed(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    opts: &FitOptions,
    observer: &mut dyn workflow::Observer,
) -> Result<Calibration, WorkflowError> {
    let groups: Vec<&str> = opts.joints.iter().map(String::as_str).collect();
    let free = params_for_groups(model, &groups)?;
    let settings = opts.settings();
    // The command's calibration (`jointfit calibrate`): with a prior, the anatomical envelope
    // and the marker policy ([`workflow::refine::calibrate_refined`]).
    let refined =
        workflow::refine::calibrate_refined(model, &start, trials, &free, &settings, observer)?;
    // The fitted model may carry marker parameters after the input's (start: their nominal).
    let mut start_all = refined.model.nominal_params();
    start_all[..start.len()].copy_from_slice(&start);
    let mut out = summarize(
        &refined.model,
        &start_all,
        &refined.calibration,
        opts.method,
    );
    // The fitted description as the command writes it: the input's structure (its priors and
    // bounds), the fitted joint parameters, the refined marker positions.
    let mut fitted = model.spec_with_nominal(&refined.calibration.fit.p[..model.n_p()]);
    fitted.markers = refined.fitted.markers.clone();
    fitted.name = format!("{} (fitted)", model.spec().name);
    out.model = fitted;
    let mut notes: Vec<String> = refined
        .marker_decisions
        .iter()
        .map(|d| format!("marker policy: {}", d.line()))
        .collect();
    notes.extend(conflict_lines(&refined.conflict));
    for b in &refined.envelope {
        if b.active {
            notes.push(format!(
                "{}: {} (bound {:.1} mm)",
                b.parameter,
                workflow::envelope::HELD_AT_LIMIT,
                b.limit_mm
            ));
        } else if let Some(x) = b.unbounded_fit_mm {
            notes.push(format!(
                "{}: the fit without the anatomical envelope ended at {x:.1} mm, lateral of the \
                 bound {:.1} mm; refitted with the bound, it ends inside",
                b.parameter, b.limit_mm
            ));
        }
    }
    notes.append(&mut out.warnings);
    out.warnings = notes;
    out.verdict = refined.calibration.verdict.clone();
    Ok(out)
}

/// One warning per joint the prior–data conflict step flagged ([`workflow::conflict`]).
pub fn conflict_lines(conflicts: &[workflow::conflict::JointConflict]) -> Vec<String> {
    conflicts
        .iter()
        .filter(|c| c.flagged)
        .map(|c| c.line())
        .collect()
}

/// SI rows, warnings and the fitted description of a finished calibration of `model` from
/// `start` (every parameter).
pub fn summarize(
    model: &Model,
    start: &[f64],
    cal: &workflow::Calibration,
    method: Method,
) -> Calibration {
    let u = cal
        .uncertainty
        .as_ref()
        .expect("the settings ask for the uncertainty");
    let fit = &cal.fit;
    let mut warnings = Vec::new();
    for pu in u.flagged() {
        // The status is judged by the trial-alone half-width (`status_half_width`), not by
        // the interval's: say both, the deciding one first, as `jointfit calibrate` does.
        let hw = match (pu.status_half_width, pu.half_width) {
            (Some(s), Some(h)) => format!(
                "trial alone ±{s:.1} {u}, which decides; interval ±{h:.1} {u}",
                u = pu.unit
            ),
            (None, Some(h)) => format!(
                "trial alone unbounded, which decides; interval ±{h:.1} {}",
                pu.unit
            ),
            (_, None) => "unbounded".to_string(),
        };
        warnings.push(format!(
            "{} {} by these trials ({hw}){}",
            pu.name,
            if pu.status == Identifiability::Undetermined {
                "not determined"
            } else {
                "poorly determined"
            },
            pu.reason
                .as_deref()
                .map_or(String::new(), |r| format!(": {r}"))
        ));
    }
    if !fit.converged() {
        warnings.push(format!(
            "the outer solver stopped before converging ({})",
            fit.termination
        ));
    }
    let parameters = cal
        .free
        .iter()
        .map(|id| id.0)
        .zip(&u.params)
        .map(|(i, pu)| {
            let par = &model.parameters()[i];
            // The uncertainty rows are in display units (mm, deg): back to SI.
            let (unit, to_si) = match par.unit {
                Unit::Metre => ("m", 1e-3),
                Unit::Radian => ("rad", std::f64::consts::PI / 180.0),
            };
            ParamRow {
                name: par.name.clone(),
                group: par.group.clone(),
                unit: unit.into(),
                start: start[i],
                fitted: fit.p[i],
                se: pu.se.map(|v| v * to_si),
                ci95: pu.ci.map(|[lo, hi]| [lo * to_si, hi * to_si]),
                identifiability: Some(pu.status),
            }
        })
        .collect();
    let mut fitted = model.spec_with_nominal(&fit.p);
    fitted.name = format!("{} (fitted)", model.spec().name);
    Calibration {
        model: fitted,
        method,
        frames: cal.frames,
        skipped_frames: cal.skipped_frames,
        parameters,
        rms_before: cal.rms_before_mm / MM_PER_M,
        rms_after: cal.rms_after_mm / MM_PER_M,
        cost_before: cal.cost_before,
        cost_after: fit.cost,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        converged: fit.converged(),
        warnings,
        verdict: cal.verdict.clone(),
    }
}
