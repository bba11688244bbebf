//! Presentation at the edge: the units a person reads (mm, degrees) and the hints that name a
//! front end's own options. The core and the pipeline work in SI and name settings, never a
//! command-line flag; the command line, the report and the Python package turn values and
//! errors into text here.

use jointfit::calibrate::prior::Source;
use jointfit::calibrate::uncertainty::{
    BootstrapInfo, CoordRange, Identifiability, ParamUncertainty, SeMethod, Uncertainty,
    WeakDirection,
};
use jointfit::model::spec::Unit;
use jointfit::plausibility::Measure;
use jointfit::solver::Termination;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::{Calibration, ConvergenceStage, MultiStart, StartRun};
use jointfit::workflow::envelope::EnvelopeBound;
use jointfit::workflow::marker_policy::{MarkerAction, MarkerDecision};
use jointfit::workflow::predict::Prediction;
use jointfit::workflow::refine::RefinedMarker;
use jointfit::workflow::verdict::Verdict;
use jointfit::workflow::HeldJoint;
use jointfit::workflow::{GlobalSearch, Method, WorkflowError};
use serde::Serialize;

/// Who reads the text: the command line (flags) or Python (keyword arguments; the batch
/// manifest's keys are the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Front {
    Cli,
    Python,
}

/// Millimetres per metre: lengths are SI (m) inside and shown in millimetres.
pub const MM_PER_M: f64 = 1e3;
/// Metres per millimetre: lengths given in millimetres (options, thresholds) to metres.
pub const M_PER_MM: f64 = 1e-3;

/// The unit values of `unit` are shown in: `mm` for metres, `deg` for radians.
pub fn unit_name(unit: Unit) -> &'static str {
    match unit {
        Unit::Metre => "mm",
        Unit::Radian => "deg",
    }
}

/// Shown units per SI unit: 1000 mm per m, 180/π degrees per radian.
pub fn unit_scale(unit: Unit) -> f64 {
    match unit {
        Unit::Metre => MM_PER_M,
        Unit::Radian => 180.0 / std::f64::consts::PI,
    }
}

/// A value in SI (m or rad) in the unit a person reads (mm or deg), with that unit's name.
pub fn shown(value_si: f64, unit: Unit) -> (f64, &'static str) {
    match unit {
        Unit::Metre => (value_si * MM_PER_M, "mm"),
        Unit::Radian => (value_si.to_degrees(), "deg"),
    }
}

/// A value given in the shown unit of `unit` (mm or deg) in SI (m or rad).
pub fn from_shown(value: f64, unit: Unit) -> f64 {
    match unit {
        Unit::Metre => value / MM_PER_M,
        Unit::Radian => value.to_radians(),
    }
}

/// A length in mm as m.
pub fn metres(millimetres: f64) -> f64 {
    millimetres * M_PER_MM
}

/// A length in m as mm.
pub fn mm(metres: f64) -> f64 {
    metres * MM_PER_M
}

/// An objective `e_inner` in m² as mm² (two factors of 10³, as every output converts it).
pub fn mm2(square_metres: f64) -> f64 {
    square_metres * MM_PER_M * MM_PER_M
}

/// A value in SI of `unit` in its shown unit (mm or deg), the number alone.
pub fn shown_value(value_si: f64, unit: Unit) -> f64 {
    value_si * unit_scale(unit)
}

/// A marker-policy decision in one line (no trailing period), e.g. `r_thigh3 (thigh):
/// position refined (prior SD 15 mm): sits 59 mm from its static-trial place in every frame
/// (spread 11 mm over 135 frames)`.
pub fn marker_decision(d: &MarkerDecision) -> String {
    let what = match (d.action, d.prior_sd) {
        (MarkerAction::Refine, Some(sd)) => {
            format!("position refined (prior SD {:.0} mm)", sd * MM_PER_M)
        }
        (MarkerAction::Refine, None) => "position refined".to_string(),
        (MarkerAction::Exclude, _) => format!("left out of trial {}", d.trial + 1),
    };
    format!("{} ({}): {what}: {}", d.marker, d.segment, d.reason)
}

/// A body measurement outside the adult range, e.g. `thigh length (right) 120 mm, outside
/// the 300–570 mm of adults` (a ratio, with no unit, with two decimals).
pub fn implausible_measure(m: &Measure) -> String {
    let u = if m.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", m.unit)
    };
    let d = if m.unit.is_empty() { 2 } else { 0 };
    format!(
        "{} {:.d$}{u}, outside the {:.d$}–{:.d$}{u} of adults",
        m.what, m.value, m.range[0], m.range[1]
    )
}

/// What an active bound of the anatomical envelope did to its parameter:
/// `held at the anatomical limit: hip centre medial to the ASIS`.
pub fn held_at_limit(b: &EnvelopeBound) -> String {
    format!("held at the anatomical limit: {}", b.what)
}

/// How to read a trial with `axis` up, as the pipeline's warnings say it (Python's keyword
/// and the batch manifest's key are both `up`).
pub fn read_with_up(axis: UpAxis) -> String {
    format!("read it with up=\"{axis}\"")
}

/// One line per source class: which parameters (grouped by joint) the trial determined,
/// which it partly determined, and which the prior held.
pub fn information_summary(rows: &[(String, String, Option<Source>)]) -> Vec<String> {
    let mut out = Vec::new();
    for src in [
        Source::DeterminedByTrial,
        Source::Partly,
        Source::HeldByPrior,
        Source::HeldAtLimit,
    ] {
        let mut by_group: Vec<(String, Vec<String>)> = Vec::new();
        for (group, name, s) in rows {
            if *s != Some(src) {
                continue;
            }
            match by_group.iter_mut().find(|(g, _)| g == group) {
                Some((_, v)) => v.push(name.clone()),
                None => by_group.push((group.clone(), vec![name.clone()])),
            }
        }
        if by_group.is_empty() {
            continue;
        }
        let total = |g: &str| rows.iter().filter(|r| r.0 == g).count();
        let parts: Vec<String> = by_group
            .iter()
            .map(|(g, v)| {
                if v.len() == total(g) {
                    format!("{g} (all {})", v.len())
                } else if v.len() > 8 {
                    // Long groups (refined marker offsets) by count only.
                    format!("{g} ({} of {})", v.len(), total(g))
                } else {
                    format!("{g}: {}", v.join(", "))
                }
            })
            .collect();
        out.push(format!("{src}: {}", parts.join("; ")));
        if src == Source::HeldByPrior {
            let hints: Vec<&str> = by_group.iter().filter_map(|(g, _)| trial_hint(g)).collect();
            if !hints.is_empty() {
                out.push(format!("to determine them: {}", hints.join("; ")));
            }
        }
    }
    out
}

/// Which trial would determine a group's parameters (what its joint must do that gait does
/// little of).
fn trial_hint(group: &str) -> Option<&'static str> {
    match group {
        "hip" => Some(
            "hip: a functional hip trial (flexion, abduction and circumduction of 30° or more, \
             e.g. the star-arc motion; Camomilla et al. 2006)",
        ),
        "knee" => Some("knee: a trial with deep knee flexion (a squat or a sit-to-stand)"),
        "ankle" => Some(
            "ankle: a trial with large inversion-eversion as well as dorsi-plantar flexion \
             (foot circles or heel raises on an inclined board)",
        ),
        _ => None,
    }
}

/// The warning for a trial as recorded (`raw`, lab frame) that is about to be read with `up`
/// (`given` says where `up` came from, e.g. `up z`): `None` when its markers agree or say
/// nothing ([`jointfit::vertical::detect_up`]), else a sentence naming the axis they put up,
/// and that axis (a front end says how to read the trial with it).
pub fn rotation_warning(raw: &Trial, up: UpAxis, given: &str) -> Option<(String, UpAxis)> {
    let d = jointfit::vertical::detect_up(raw)?;
    (d.up != up).then(|| {
        let line = format!(
            "the trial looks rotated relative to the subject: its markers put lab axis {d} up, \
             but it is read with {given}"
        );
        (line, d.up)
    })
}

/// The option of `front` that resolves a workflow error, when one does.
pub fn hint(e: &WorkflowError, front: Front) -> Option<&'static str> {
    match (e, front) {
        (WorkflowError::RefineNeedsPriors, Front::Cli) => Some("drop --prior none"),
        (WorkflowError::RefineNeedsPriors, Front::Python) => Some("pass prior=\"model\""),
        _ => None,
    }
}

/// A calibration as `jointfit calibrate --json` writes it: the core's [`Calibration`] (SI)
/// with lengths in mm, angles in degrees and objectives in mm², under the field names that
/// say so (`rms_before_mm`, `objective_mm2`, ...).
#[derive(Serialize)]
pub struct CalibrationShown<'a> {
    pub method: Method,
    pub seed: u64,
    pub frames: usize,
    pub skipped_frames: usize,
    pub free_parameters: usize,
    pub parameters: Vec<ParamRowShown<'a>>,
    pub rms_before_mm: f64,
    pub rms_after_mm: f64,
    pub marker_rms_before_mm: Vec<(&'a str, f64)>,
    pub marker_rms_after_mm: Vec<(&'a str, f64)>,
    /// `e_inner` (m²).
    pub cost_before: f64,
    pub cost_after: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    pub termination: Termination,
    pub convergence: Vec<StageShown<'a>>,
    pub best_start: usize,
    pub start_runs: Vec<StartRunShown<'a>>,
    pub uncertainty: Option<UncertaintyShown<'a>>,
    pub fixed_unidentifiable: &'a [String],
    pub multistart: Option<MultiStartShown<'a>>,
    pub global: Option<GlobalShown<'a>>,
    pub global_warning: &'a Option<String>,
    pub prior_noise_mm: Option<f64>,
    pub prior_noise_estimated: bool,
    pub prior_inflation: &'a [(String, f64)],
    pub plausibility: &'a [jointfit::plausibility::Plausibility],
    pub verdict: &'a Verdict,
}

/// One parameter row in its shown unit; its SE and interval are the uncertainty record's.
#[derive(Serialize)]
pub struct ParamRowShown<'a> {
    pub name: &'a str,
    pub group: &'a str,
    pub unit: &'static str,
    pub start: f64,
    pub fitted: f64,
    pub change: f64,
    pub se: Option<f64>,
    pub ci95: Option<[f64; 2]>,
    pub identifiability: Option<Identifiability>,
    pub uncertainty_method: Option<SeMethod>,
    pub prior_sd: Option<f64>,
    pub prior_mean: Option<f64>,
    pub data_share: Option<f64>,
    pub source: Option<jointfit::calibrate::prior::Source>,
}

/// One optimizer stage, objectives in mm².
#[derive(Serialize)]
pub struct StageShown<'a> {
    pub stage: &'a str,
    pub objective_mm2: Vec<f64>,
}

/// One start, objectives in mm².
#[derive(Serialize)]
pub struct StartRunShown<'a> {
    pub start: usize,
    pub objective_mm2: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub termination: Termination,
    pub convergence: Vec<StageShown<'a>>,
}

/// What several starts found: objectives in mm², spreads in mm or deg.
#[derive(Serialize)]
pub struct MultiStartShown<'a> {
    pub starts: usize,
    pub objective_mm2: Vec<f64>,
    pub reached_best: usize,
    pub spread: Vec<(&'a str, f64)>,
}

/// The global phase, objectives in mm².
#[derive(Serialize)]
pub struct GlobalShown<'a> {
    pub starts: usize,
    pub probe_iterations: usize,
    pub probe_frames: usize,
    pub probe_objective_mm2: Vec<f64>,
    pub finished: &'a [usize],
    pub finished_objective_mm2: Vec<f64>,
    pub agree: bool,
}

/// The uncertainty record with σ in mm and the thresholds in mm and degrees (its rows are
/// in their shown unit already).
#[derive(Serialize)]
pub struct UncertaintyShown<'a> {
    pub level: f64,
    pub z: f64,
    pub z_hac: Option<f64>,
    pub t_jackknife: Option<f64>,
    pub jackknife_blocks: Option<usize>,
    pub frames: usize,
    pub observations: usize,
    pub dof: usize,
    pub sigma_mm: f64,
    pub sigma_assumed: bool,
    pub small_sample_factor: f64,
    pub hac_bandwidth: Option<f64>,
    pub correlation_factor: f64,
    pub bootstrap: &'a Option<BootstrapInfo>,
    pub threshold_mm: f64,
    pub threshold_deg: f64,
    pub params: &'a [ParamUncertainty],
    pub corr: &'a [Vec<Option<f64>>],
    pub weak_directions: &'a [WeakDirection],
    pub ranges: &'a [CoordRange],
}

/// An anatomical-envelope bound in mm.
#[derive(Serialize)]
pub struct EnvelopeShown<'a> {
    pub parameter: &'a str,
    pub what: &'static str,
    pub limit_mm: f64,
    pub model_upper_mm: f64,
    pub active: bool,
    pub unbounded_fit_mm: Option<f64>,
}

/// A refined marker's positions and shift in mm.
#[derive(Serialize)]
pub struct RefinedMarkerShown<'a> {
    pub name: &'a str,
    pub segment: &'a str,
    pub start_mm: [f64; 3],
    pub fitted_mm: [f64; 3],
    pub shift_mm: f64,
}

/// A marker-policy decision with its prior SD, offset and spread in mm.
#[derive(Serialize)]
pub struct MarkerDecisionShown<'a> {
    pub marker: &'a str,
    pub segment: &'a str,
    pub action: MarkerAction,
    pub trial: usize,
    pub prior_sd_mm: Option<f64>,
    pub offset_mm: f64,
    pub spread_mm: f64,
    pub frames: usize,
    pub rejected_share: f64,
    pub reason: &'a str,
}

/// A prediction as `jointfit check --json` writes it: the RMS in mm, the uncertainty as
/// [`UncertaintyShown`].
#[derive(Serialize)]
pub struct PredictionShown<'a> {
    pub frames: usize,
    pub skipped_frames: usize,
    pub ik_rms_mm: f64,
    pub ranges: &'a [CoordRange],
    pub prediction: UncertaintyShown<'a>,
    pub determined: &'a [String],
    pub not_determined: &'a [String],
}

impl<'a> PredictionShown<'a> {
    pub fn of(p: &'a Prediction) -> PredictionShown<'a> {
        PredictionShown {
            frames: p.frames,
            skipped_frames: p.skipped_frames,
            ik_rms_mm: mm(p.ik_rms),
            ranges: &p.ranges,
            prediction: UncertaintyShown::of(&p.prediction),
            determined: &p.determined,
            not_determined: &p.not_determined,
        }
    }
}

/// A joint held as still, its ranges of motion in degrees.
#[derive(Serialize)]
pub struct HeldJointShown<'a> {
    pub joint: &'a str,
    pub range_deg: f64,
    pub other_joint: &'a str,
    pub other_range_deg: f64,
    pub parameters: &'a [String],
}

impl<'a> HeldJointShown<'a> {
    pub fn of(h: &'a HeldJoint) -> HeldJointShown<'a> {
        HeldJointShown {
            joint: &h.joint,
            range_deg: h.range.to_degrees(),
            other_joint: &h.other_joint,
            other_range_deg: h.other_range.to_degrees(),
            parameters: &h.parameters,
        }
    }
}

/// Objectives (m²) in mm².
pub fn objectives_mm2(v: &[f64]) -> Vec<f64> {
    v.iter().map(|&c| mm2(c)).collect()
}

fn stages(v: &[ConvergenceStage]) -> Vec<StageShown<'_>> {
    v.iter()
        .map(|c| StageShown {
            stage: &c.stage,
            objective_mm2: objectives_mm2(&c.objective),
        })
        .collect()
}

fn named_mm(v: &[(String, f64)]) -> Vec<(&str, f64)> {
    v.iter().map(|(n, x)| (n.as_str(), mm(*x))).collect()
}

impl<'a> CalibrationShown<'a> {
    /// `cal` in the units a person reads.
    pub fn of(cal: &'a Calibration) -> CalibrationShown<'a> {
        let u = cal.uncertainty.as_ref();
        CalibrationShown {
            method: cal.method,
            seed: cal.seed,
            frames: cal.frames,
            skipped_frames: cal.skipped_frames,
            free_parameters: cal.free_parameters,
            parameters: cal
                .parameters
                .iter()
                .enumerate()
                .map(|(k, row)| ParamRowShown::of(row, u.and_then(|u| u.params.get(k))))
                .collect(),
            rms_before_mm: mm(cal.rms_before),
            rms_after_mm: mm(cal.rms_after),
            marker_rms_before_mm: named_mm(&cal.marker_rms_before),
            marker_rms_after_mm: named_mm(&cal.marker_rms_after),
            cost_before: cal.cost_before,
            cost_after: cal.cost_after,
            iterations: cal.iterations,
            evaluations: cal.evaluations,
            converged: cal.converged,
            termination: cal.termination,
            convergence: stages(&cal.convergence),
            best_start: cal.best_start,
            start_runs: cal.start_runs.iter().map(StartRunShown::of).collect(),
            uncertainty: u.map(UncertaintyShown::of),
            fixed_unidentifiable: &cal.fixed_unidentifiable,
            multistart: cal.multistart.as_ref().map(|m| MultiStartShown::of(m, cal)),
            global: cal.global.as_ref().map(GlobalShown::of),
            global_warning: &cal.global_warning,
            prior_noise_mm: cal.prior_noise.map(mm),
            prior_noise_estimated: cal.prior_noise_estimated,
            prior_inflation: &cal.prior_inflation,
            plausibility: &cal.plausibility,
            verdict: &cal.verdict,
        }
    }
}

impl<'a> ParamRowShown<'a> {
    /// `row` in its shown unit; `pu` its uncertainty record (in that unit already), whose SE
    /// and interval are shown as computed.
    pub fn of(
        row: &'a jointfit::workflow::calibration::ParamRow,
        pu: Option<&ParamUncertainty>,
    ) -> ParamRowShown<'a> {
        let k = unit_scale(row.unit);
        let (se, ci95) = match pu {
            Some(pu) => (pu.se, pu.ci),
            None => (row.se.map(|v| v * k), row.ci95.map(|[a, b]| [a * k, b * k])),
        };
        ParamRowShown {
            name: &row.name,
            group: &row.group,
            unit: unit_name(row.unit),
            start: row.start * k,
            fitted: row.fitted * k,
            change: row.change * k,
            se,
            ci95,
            identifiability: row.identifiability,
            uncertainty_method: row.uncertainty_method,
            prior_sd: row.prior_sd.map(|v| v * k),
            prior_mean: row.prior_mean.map(|v| v * k),
            data_share: row.data_share,
            source: row.source,
        }
    }
}

impl<'a> StartRunShown<'a> {
    pub fn of(r: &'a StartRun) -> StartRunShown<'a> {
        StartRunShown {
            start: r.start,
            objective_mm2: mm2(r.objective),
            iterations: r.iterations,
            evaluations: r.evaluations,
            termination: r.termination,
            convergence: stages(&r.convergence),
        }
    }
}

impl<'a> MultiStartShown<'a> {
    /// `m` of `cal`, each spread in its parameter's shown unit.
    pub fn of(m: &'a MultiStart, cal: &Calibration) -> MultiStartShown<'a> {
        let unit = |name: &str| {
            cal.parameters
                .iter()
                .find(|r| r.name == name)
                .map_or(Unit::Metre, |r| r.unit)
        };
        MultiStartShown {
            starts: m.starts,
            objective_mm2: objectives_mm2(&m.objective),
            reached_best: m.reached_best,
            spread: m
                .spread
                .iter()
                .map(|(n, x)| (n.as_str(), shown_value(*x, unit(n))))
                .collect(),
        }
    }
}

impl<'a> GlobalShown<'a> {
    pub fn of(g: &'a GlobalSearch) -> GlobalShown<'a> {
        GlobalShown {
            starts: g.starts,
            probe_iterations: g.probe_iterations,
            probe_frames: g.probe_frames,
            probe_objective_mm2: objectives_mm2(&g.probe_objective),
            finished: &g.finished,
            finished_objective_mm2: objectives_mm2(&g.finished_objective),
            agree: g.agree,
        }
    }
}

impl<'a> UncertaintyShown<'a> {
    pub fn of(u: &'a Uncertainty) -> UncertaintyShown<'a> {
        UncertaintyShown {
            level: u.level,
            z: u.z,
            z_hac: u.z_hac,
            t_jackknife: u.t_jackknife,
            jackknife_blocks: u.jackknife_blocks,
            frames: u.frames,
            observations: u.observations,
            dof: u.dof,
            sigma_mm: mm(u.sigma),
            sigma_assumed: u.sigma_assumed,
            small_sample_factor: u.small_sample_factor,
            hac_bandwidth: u.hac_bandwidth,
            correlation_factor: u.correlation_factor,
            bootstrap: &u.bootstrap,
            threshold_mm: mm(u.threshold_m),
            threshold_deg: u.threshold_rad.to_degrees(),
            params: &u.params,
            corr: &u.corr,
            weak_directions: &u.weak_directions,
            ranges: &u.ranges,
        }
    }
}

impl<'a> EnvelopeShown<'a> {
    pub fn of(b: &'a EnvelopeBound) -> EnvelopeShown<'a> {
        EnvelopeShown {
            parameter: &b.parameter,
            what: b.what,
            limit_mm: mm(b.limit),
            model_upper_mm: mm(b.model_upper),
            active: b.active,
            unbounded_fit_mm: b.unbounded_fit.map(mm),
        }
    }
}

impl<'a> RefinedMarkerShown<'a> {
    pub fn of(m: &'a RefinedMarker) -> RefinedMarkerShown<'a> {
        RefinedMarkerShown {
            name: &m.name,
            segment: &m.segment,
            start_mm: m.start.map(mm),
            fitted_mm: m.fitted.map(mm),
            shift_mm: mm(m.shift),
        }
    }
}

impl<'a> MarkerDecisionShown<'a> {
    pub fn of(d: &'a MarkerDecision) -> MarkerDecisionShown<'a> {
        MarkerDecisionShown {
            marker: &d.marker,
            segment: &d.segment,
            action: d.action,
            trial: d.trial,
            prior_sd_mm: d.prior_sd.map(mm),
            offset_mm: mm(d.offset),
            spread_mm: mm(d.spread),
            frames: d.frames,
            rejected_share: d.rejected_share,
            reason: &d.reason,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Display units against the definitions: 1 mm = 1e-3 m, 180° = π rad.
    #[test]
    fn shown_units() {
        let (mm, u) = shown(0.0125, Unit::Metre);
        assert!((mm - 12.5).abs() < 1e-12 && u == "mm");
        let (deg, u) = shown(std::f64::consts::PI / 4.0, Unit::Radian);
        assert!((deg - 45.0).abs() < 1e-12 && u == "deg");
        assert_eq!(
            (unit_name(Unit::Metre), unit_name(Unit::Radian)),
            ("mm", "deg")
        );
        assert_eq!(from_shown(12.5, Unit::Metre), 0.0125);
        assert!((from_shown(45.0, Unit::Radian) - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!(metres(20.0), 0.02);
        assert!((shown_value(1.0, Unit::Radian) - 180.0 / std::f64::consts::PI).abs() < 1e-12);
    }

    /// A refined marker names its prior SD in mm, an excluded one the trial it leaves
    /// (counted from 1).
    #[test]
    fn marker_decisions_in_one_line() {
        let mut d = MarkerDecision {
            marker: "r_thigh3".into(),
            segment: "thigh".into(),
            action: MarkerAction::Refine,
            trial: 0,
            prior_sd: Some(0.015),
            offset: 0.059,
            spread: 0.011,
            frames: 135,
            rejected_share: 0.0,
            reason: "sits 59 mm from its static-trial place".into(),
        };
        assert_eq!(
            marker_decision(&d),
            "r_thigh3 (thigh): position refined (prior SD 15 mm): sits 59 mm from its \
             static-trial place"
        );
        d.action = MarkerAction::Exclude;
        d.trial = 1;
        assert_eq!(
            marker_decision(&d),
            "r_thigh3 (thigh): left out of trial 2: sits 59 mm from its static-trial place"
        );
    }

    /// An active envelope bound says what it holds, as the text output always printed it.
    #[test]
    fn a_bound_held_at_the_limit() {
        let b = EnvelopeBound {
            parameter: "hip_pelvis_lateral".into(),
            what: "hip centre medial to the ASIS",
            limit: 0.0885,
            model_upper: 0.12,
            active: true,
            unbounded_fit: None,
        };
        assert_eq!(
            held_at_limit(&b),
            "held at the anatomical limit: hip centre medial to the ASIS"
        );
    }

    /// Lengths in whole mm with their unit, a ratio (no unit) with two decimals.
    #[test]
    fn implausible_measures_in_one_line() {
        let thigh = Measure {
            what: "thigh length (right)".into(),
            value: 120.4,
            range: [300.0, 570.0],
            unit: "mm",
        };
        assert_eq!(
            implausible_measure(&thigh),
            "thigh length (right) 120 mm, outside the 300–570 mm of adults"
        );
        let ratio = Measure {
            what: "thigh/shank length ratio (left)".into(),
            value: 1.5,
            range: [0.7, 1.45],
            unit: "",
        };
        assert_eq!(
            implausible_measure(&ratio),
            "thigh/shank length ratio (left) 1.50, outside the 0.70–1.45 of adults"
        );
    }

    /// A real calibration (knee of the built-in leg, noise-free synthetic trial, two starts,
    /// the analysis): every shown number is its SI value in mm, degrees or mm², the SE and
    /// interval are the uncertainty record's, and the names are the JSON's.
    #[test]
    fn a_calibration_is_shown_in_mm_degrees_and_mm2() {
        use crate::fit::uncertainty_options;
        use jointfit::model::lower_limb::{lower_limb, Side};
        use jointfit::model::Model;
        use jointfit::workflow::calibration::calibrate;
        use jointfit::workflow::FitSettings;
        use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion};

        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let free = jointfit::calibrate::params_for_groups(&model, &["knee"]).unwrap();
        let moved = perturbed_params(&model, 0.3, 3);
        let mut truth = model.nominal_params();
        for id in &free {
            truth[id.0] = moved[id.0];
        }
        let coords = coordinates(&model, Motion::Knee, 40).unwrap();
        let (trial, _) = markers(&model, &truth, &coords, 50.0, None);
        let settings = FitSettings {
            starts: 2,
            probes: 0,
            uncertainty: Some(uncertainty_options(5.0, 5.0, 0, 1)),
            ..FitSettings::default()
        };
        let start = model.nominal_params();
        let cal = calibrate(
            &model,
            &start,
            &[&trial],
            &free,
            &settings,
            &mut jointfit::solver::NoObserver,
        )
        .unwrap();
        let json = serde_json::to_value(CalibrationShown::of(&cal)).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-300);
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        assert!(close(num(&json["rms_before_mm"]), cal.rms_before * 1e3));
        assert!(close(num(&json["rms_after_mm"]), cal.rms_after * 1e3));
        let u = cal.uncertainty.as_ref().unwrap();
        assert!(close(num(&json["uncertainty"]["sigma_mm"]), u.sigma * 1e3));
        assert_eq!(num(&json["uncertainty"]["threshold_mm"]), 5.0);
        assert!(close(num(&json["uncertainty"]["threshold_deg"]), 5.0));
        for (k, row) in cal.parameters.iter().enumerate() {
            let shown = &json["parameters"][k];
            let (scale, unit) = match row.unit {
                Unit::Metre => (1e3, "mm"),
                Unit::Radian => (180.0 / std::f64::consts::PI, "deg"),
            };
            assert_eq!(shown["unit"], unit);
            assert!(close(num(&shown["start"]), start[free[k].0] * scale));
            assert!(close(num(&shown["fitted"]), cal.fit.p[free[k].0] * scale));
            assert!(close(num(&shown["change"]), row.change * scale));
            // The shown SE is the record's; the row's SI SE is that in SI.
            let se = u.params[k].se.unwrap();
            assert_eq!(num(&shown["se"]), se);
            assert!(close(row.se.unwrap() * scale, se));
        }
        let last = json["convergence"][0]["objective_mm2"]
            .as_array()
            .unwrap()
            .last()
            .map(num)
            .unwrap();
        assert!(close(last, cal.cost_after * 1e6));
        let ms = &json["multistart"];
        for (k, run) in cal.start_runs.iter().enumerate() {
            assert!(close(num(&ms["objective_mm2"][k]), run.objective * 1e6));
            assert!(close(
                num(&json["start_runs"][k]["objective_mm2"]),
                run.objective * 1e6
            ));
        }
        for (name, v) in json["marker_rms_after_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                let p = p.as_array().unwrap();
                (p[0].as_str().unwrap().to_string(), p[1].clone())
            })
        {
            let si = cal.marker_rms_after.iter().find(|m| m.0 == name).unwrap().1;
            assert!(
                v.is_null() && si.is_nan() || close(num(&v), si * 1e3),
                "{name}"
            );
        }
        assert!(json.get("rms_before").is_none() && json.get("prior_noise").is_none());
    }

    /// The envelope's, a refined marker's and a held joint's SI fields shown.
    #[test]
    fn the_fit_notes_are_shown_in_mm_and_degrees() {
        let b = EnvelopeBound {
            parameter: "hip_pelvis_lateral".into(),
            what: "hip centre medial to the ASIS",
            limit: 0.107,
            model_upper: 0.15,
            active: true,
            unbounded_fit: Some(0.112),
        };
        let v = serde_json::to_value(EnvelopeShown::of(&b)).unwrap();
        assert_eq!(v["limit_mm"], 107.0);
        assert_eq!(v["model_upper_mm"], 150.0);
        assert_eq!(v["unbounded_fit_mm"], 112.0);
        let m = RefinedMarker {
            name: "r_thigh3".into(),
            segment: "thigh".into(),
            start: [0.01, -0.2, 0.05],
            fitted: [0.02, -0.2, 0.05],
            shift: 0.01,
        };
        let v = serde_json::to_value(RefinedMarkerShown::of(&m)).unwrap();
        assert_eq!(v["start_mm"], serde_json::json!([10.0, -200.0, 50.0]));
        assert_eq!(v["shift_mm"], 10.0);
        let h = HeldJoint {
            joint: "knee_l".into(),
            range: std::f64::consts::PI / 18.0,
            other_joint: "knee_r".into(),
            other_range: std::f64::consts::FRAC_PI_3,
            parameters: vec!["knee_l_x".into()],
        };
        let v = serde_json::to_value(HeldJointShown::of(&h)).unwrap();
        assert!((v["range_deg"].as_f64().unwrap() - 10.0).abs() < 1e-12);
        assert!((v["other_range_deg"].as_f64().unwrap() - 60.0).abs() < 1e-12);
    }

    #[test]
    fn hints_name_each_front_ends_own_option() {
        let e = WorkflowError::RefineNeedsPriors;
        assert!(!e.to_string().contains("--"), "{e}");
        assert_eq!(hint(&e, Front::Cli), Some("drop --prior none"));
        assert!(hint(&e, Front::Python).unwrap().contains("prior="));
        assert_eq!(read_with_up(UpAxis::NegZ), "read it with up=\"-z\"");
    }
}
