//! The options of a calibration ([`FitOptions`], and the one mapping to the core's
//! settings) and its result in SI units ([`Calibration`]): the summary stage.
//!
//! The summary turns the core's result (display units: mm, degrees) into SI rows, one per
//! free parameter, and the warnings a results table or a Python user reads, one line each.

use crate::present::{mm, M_PER_MM};
use jointfit::calibrate::uncertainty::Identifiability;
use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::spec::ModelSpec;
use jointfit::model::spec::Unit;
use jointfit::model::Model;
use jointfit::workflow::refine::RefinedCalibration;
use jointfit::workflow::{self, FitSettings};
use serde::{Deserialize, Serialize};

use crate::osim::OsimFit;

/// The outer optimizer (as `jointfit calibrate --method`).
pub use jointfit::workflow::Method;

/// Settings of one calibration: the options of `jointfit calibrate`, with its defaults.
/// Fields added after the first release default when absent from a saved result, and are
/// left out of the saved text at their default (a batch's saved results stay valid).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Parameter groups to fit (`hip`, `knee`, `ankle`, `all`); of an `.osim` model, the
    /// joints whose offset frames to personalize (`all`: none by name).
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
    /// Starts of the fit (the given one and seeded moves; the best is kept).
    #[serde(default = "one")]
    pub starts: usize,
    /// Refit with the undetermined parameters held at their start.
    #[serde(default)]
    pub fix_unidentifiable: bool,
    /// Use the model file's parameter priors (a maximum a posteriori fit); `false`: the
    /// unregularized least squares of Reinbolt et al. (2005).
    #[serde(default = "yes")]
    pub priors: bool,
    /// Marker noise SD (mm) weighing the priors (`None`: estimated from the residuals).
    #[serde(default)]
    pub marker_noise_mm: Option<f64>,
    /// Outer iteration limit (`None`: the solver's default).
    #[serde(default)]
    pub max_iterations: Option<usize>,
    /// Keep a fit whose verdict is `reject`; otherwise the request fails with the verdict's
    /// first reason.
    #[serde(default)]
    pub accept_rejected: bool,
    /// Extra starts of the global phase of a single-start joint fit (0: one local fit).
    #[serde(default = "five", skip_serializing_if = "is_five")]
    pub probes: usize,
    /// Refine every tracking marker's position with this prior SD (mm per axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_markers_mm: Option<f64>,
    /// With a prior: bound the hip centre medial to the ASIS.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub anatomical_envelope: bool,
    /// With a prior: refine the markers displaced since the static trial, leave out broken
    /// ones.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub marker_policy: bool,
    /// Markers the marker policy leaves as they are.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keep_markers: Vec<String>,
    /// With a prior: widen the prior of a joint the trial disagrees with.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub prior_conflict: bool,
    /// An `.osim` model's finer selection of offset scalars
    /// (`JOINT[.parent|.child[.translation|.orientation[.x|.y|.z]]]`), after `joints`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<String>,
}

fn one() -> usize {
    1
}

fn five() -> usize {
    5
}

fn is_five(n: &usize) -> bool {
    *n == 5
}

fn yes() -> bool {
    true
}

fn is_true(b: &bool) -> bool {
    *b
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            joints: vec!["all".into()],
            method: Method::Joint,
            seed: 1,
            threshold_mm: THRESHOLD_MM,
            threshold_deg: THRESHOLD_DEG,
            bootstrap: 0,
            starts: 1,
            fix_unidentifiable: false,
            priors: true,
            marker_noise_mm: None,
            max_iterations: None,
            accept_rejected: false,
            probes: five(),
            refine_markers_mm: None,
            anatomical_envelope: true,
            marker_policy: true,
            keep_markers: Vec::new(),
            prior_conflict: true,
            params: Vec::new(),
        }
    }
}

/// The default flag thresholds of a 95 % interval's half-width (mm, deg): a parameter whose
/// interval is wider is reported as not determined by the trials.
pub const THRESHOLD_MM: f64 = 5.0;
pub const THRESHOLD_DEG: f64 = 5.0;

/// Uncertainty options in the units people give them: flag thresholds in mm and degrees,
/// `bootstrap` moving-block replicates, `seed` of the bootstrap.
pub fn uncertainty_options(
    threshold_mm: f64,
    threshold_deg: f64,
    bootstrap: usize,
    seed: u64,
) -> UncertaintyOptions {
    UncertaintyOptions {
        threshold_m: crate::present::from_shown(threshold_mm, Unit::Metre),
        threshold_rad: crate::present::from_shown(threshold_deg, Unit::Radian),
        bootstrap_replicates: bootstrap,
        seed,
        ..UncertaintyOptions::default()
    }
}

/// Most starts of one fit (each is a full fit).
pub const MAX_STARTS: usize = 1_000;
/// Most probes of the global phase.
pub const MAX_PROBES: usize = 1_000;
/// Most block-bootstrap replicates (each is a refit).
pub const MAX_BOOTSTRAP: usize = 2_000;
/// Most outer iterations of one fit.
pub const MAX_ITERATIONS: usize = 10_000;
/// Largest marker noise SD (mm).
pub const MAX_NOISE_MM: f64 = 1_000.0;

impl FitOptions {
    /// The options are within their documented limits (the command line's): `starts` 1 to
    /// [`MAX_STARTS`], `probes` at most [`MAX_PROBES`], `bootstrap` at most
    /// [`MAX_BOOTSTRAP`], `max_iterations` 1 to [`MAX_ITERATIONS`], thresholds and the
    /// refined markers' prior SD finite and positive, `marker_noise_mm` finite, positive and
    /// at most [`MAX_NOISE_MM`]. The error is one line naming the option.
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
        count("probes", self.probes, 0, MAX_PROBES)?;
        count("bootstrap", self.bootstrap, 0, MAX_BOOTSTRAP)?;
        if let Some(n) = self.max_iterations {
            count("max_iter", n, 1, MAX_ITERATIONS)?;
        }
        positive("threshold_mm", self.threshold_mm, f64::MAX)?;
        positive("threshold_deg", self.threshold_deg, f64::MAX)?;
        if let Some(mm) = self.marker_noise_mm {
            positive("marker_noise_mm", mm, MAX_NOISE_MM)?;
        }
        if let Some(mm) = self.refine_markers_mm {
            positive("marker_prior_sd_mm", mm, f64::MAX)?;
        }
        Ok(())
    }

    /// The core's settings for these options: the one mapping from options to
    /// [`FitSettings`] (every front end's). The default options give what `jointfit calibrate`
    /// runs with no options (and `jointfit bench` times): the core's default settings (joint
    /// method, global phase, priors, marker policy, envelope) plus the uncertainty analysis
    /// with [`THRESHOLD_MM`] and [`THRESHOLD_DEG`], no bootstrap, seed 1.
    pub fn settings(&self) -> FitSettings {
        FitSettings {
            method: self.method,
            seed: self.seed,
            starts: self.starts,
            probes: self.probes,
            uncertainty: Some(uncertainty_options(
                self.threshold_mm,
                self.threshold_deg,
                self.bootstrap,
                self.seed,
            )),
            fix_unidentifiable: self.fix_unidentifiable,
            priors: self.priors,
            marker_noise: self.marker_noise_mm.map(|mm| mm * M_PER_MM),
            refine_markers: self.refine_markers_mm.map(|mm| mm * M_PER_MM),
            max_iterations: self.max_iterations,
            anatomical_envelope: self.anatomical_envelope,
            marker_policy: self.marker_policy,
            keep_markers: self.keep_markers.clone(),
            prior_conflict: self.prior_conflict,
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
    pub verdict: jointfit::workflow::verdict::Verdict,
}

/// The summary of a native model's fit ([`crate::fit()`]): the rows from `start`, the fitted
/// description in the input's structure (its priors and bounds, the fitted joint parameters,
/// the refined marker positions), and the warnings: the marker policy's decisions, the
/// prior–data conflicts, the anatomical envelope, then the uncertainty and convergence.
pub fn summarize_refined(
    model: &Model,
    start: &[f64],
    refined: &RefinedCalibration,
    method: Method,
) -> Calibration {
    // The fitted model may carry marker parameters after the input's (start: their nominal).
    let mut start_all = refined.model.nominal_params();
    start_all[..start.len()].copy_from_slice(start);
    let mut out = summarize(&refined.model, &start_all, &refined.calibration, method);
    let mut fitted =
        model.spec_with_nominal(&refined.calibration.fit.p[..model.parameters().len()]);
    fitted.markers = refined.fitted.markers.clone();
    fitted.name = format!("{} (fitted)", model.spec().name);
    out.model = fitted;
    let mut notes: Vec<String> = refined
        .marker_decisions
        .iter()
        .map(|d| format!("marker policy: {}", crate::present::marker_decision(d)))
        .collect();
    notes.extend(conflict_lines(&refined.conflict));
    for b in &refined.envelope {
        if b.active {
            notes.push(format!(
                "{}: {} (bound {:.1} mm)",
                b.parameter,
                crate::present::held_at_limit(b),
                mm(b.limit)
            ));
        } else if let Some(x) = b.unbounded_fit {
            notes.push(format!(
                "{}: the fit without the anatomical envelope ended at {:.1} mm, lateral of the \
                 bound {:.1} mm; refitted with the bound, it ends inside",
                b.parameter,
                mm(x),
                mm(b.limit)
            ));
        }
    }
    notes.append(&mut out.warnings);
    out.warnings = notes;
    out
}

/// The summary of an `.osim` personalization ([`crate::osim::personalize`]): the fitted
/// description (priors centred on the file's values), and the warnings: the prior–data
/// conflicts, the parameters held as redundant, then the uncertainty and convergence.
pub fn summarize_osim(done: &OsimFit, method: Method) -> Calibration {
    let mut cal = summarize(
        &done.model,
        &done.model.nominal_params(),
        &done.result.calibration,
        method,
    );
    cal.model = done.fitted_spec();
    let mut warnings = conflict_lines(&done.result.prior_conflict);
    for r in &done.result.held_redundant {
        warnings.push(if r.with.is_empty() {
            format!(
                "{} held at its start value: the joint's coordinates absorb it",
                r.parameter
            )
        } else {
            format!(
                "{} held at its start value: redundant with {}",
                r.parameter,
                r.with.join(", ")
            )
        });
    }
    warnings.append(&mut cal.warnings);
    cal.warnings = warnings;
    cal
}

/// One warning per joint the prior–data conflict step flagged ([`workflow::conflict`]).
pub fn conflict_lines(conflicts: &[workflow::conflict::JointConflict]) -> Vec<String> {
    conflicts
        .iter()
        .filter(|c| c.flagged)
        .map(|c| c.to_string())
        .collect()
}

/// SI rows, warnings and the fitted description of a finished calibration of `model` from
/// `start` (every parameter).
pub fn summarize(
    model: &Model,
    start: &[f64],
    cal: &jointfit::workflow::calibration::Calibration,
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
    if !cal.converged {
        warnings.push(format!(
            "the outer solver stopped before converging ({})",
            fit.termination
        ));
    }
    let parameters = cal
        .free
        .iter()
        .map(|id| id.0)
        .zip(&cal.parameters)
        .map(|(i, row)| ParamRow {
            name: row.name.clone(),
            group: row.group.clone(),
            unit: match row.unit {
                Unit::Metre => "m",
                Unit::Radian => "rad",
            }
            .into(),
            start: start[i],
            fitted: fit.p[i],
            se: row.se,
            ci95: row.ci95,
            identifiability: row.identifiability,
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
        rms_before: cal.rms_before,
        rms_after: cal.rms_after,
        cost_before: cal.cost_before,
        cost_after: fit.cost,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        converged: cal.converged,
        warnings,
        verdict: cal.verdict.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_convert_to_si() {
        let o = uncertainty_options(5.0, 2.0, 7, 3);
        assert!((o.threshold_m - 0.005).abs() < 1e-18);
        assert!((o.threshold_rad - 2f64.to_radians()).abs() < 1e-18);
        assert_eq!((o.bootstrap_replicates, o.seed), (7, 3));
    }

    /// The default options analyse the uncertainty with the documented thresholds and leave
    /// every other setting at the core's default.
    #[test]
    fn default_options_are_the_core_defaults_with_the_uncertainty_analysis() {
        let s = FitOptions::default().settings();
        let u = s.uncertainty.clone().unwrap();
        assert!((u.threshold_m - THRESHOLD_MM * 1e-3).abs() < 1e-18);
        assert!((u.threshold_rad - THRESHOLD_DEG.to_radians()).abs() < 1e-18);
        assert_eq!((u.bootstrap_replicates, u.seed), (0, 1));
        assert_eq!(
            s,
            FitSettings {
                uncertainty: Some(u),
                ..FitSettings::default()
            }
        );
    }
}
