//! One verdict on every calibration: `ok`, `caution` or `reject`, with its reasons.
//!
//! A fit's own cost says how well the model follows the markers, not whether the model is
//! right: a static trial of another session, a wrong marker map or refined markers can make
//! any cost small. The verdict therefore judges the inputs against each other and the result
//! against anatomy, in two steps that every front end shares:
//!
//! 1. **Before the fit** ([`check_inputs`]): each trial's marker placement against the
//!    model's ([`crate::placement`]: units, a segment of another build, labels naming other
//!    markers). A mismatch refuses the fit ([`WorkflowError::Mismatch`]).
//! 2. **After the fit** ([`judge`]), from the calibration and its side results:
//!    * `reject` when the markers sat further from the model
//!      before the fit than a same-session trial does ([`REJECT_RMS_BEFORE_MM`]) or still do
//!      after it ([`REJECT_RMS_AFTER_MM`]); when a fitted joint is outside twice its
//!      anatomical envelope ([`crate::plausibility`]);
//!    * `caution` for a fit that did not converge (kept on request), a joint outside its
//!      envelope, a hip held at the envelope's bound, a
//!      strong prior–data conflict ([`STRONG_CONFLICT_P`]; a weaker one is listed without
//!      raising the level), markers refined by more than [`CAUTION_REFINE_MM`] (beyond
//!      [`REFINE_CAP_MM`] only a re-attached cluster explains it) or left out,
//!      an optimum not known to be global, many skipped frames, an RMS above the movement
//!      bar of OpenSim's best practice ([`CAUTION_RMS_AFTER_MM`]), or motion outside the
//!      anatomical range (knee hyperextension beyond [`KNEE_HYPEREXTENSION_DEG`], a hip
//!      rotated by more than [`HIP_ROTATION_DEG`] through a whole trial);
//!    * `ok` otherwise; notes beside the level: a weak prior–data conflict, and the joints
//!      held because the trial barely moved them on one leg of a bilateral model
//!      ([`super::motion_range`]).
//!
//! The thresholds of the RMS are OpenSim's best-practice bars for a movement trial (RMS
//! below 2 cm, the largest error below 4 cm; Hicks et al. 2015, J Biomech Eng 137:020905)
//! and the bar of a different session read off the shared data (a same-session gait, squat,
//! jump or run starts below 30 mm with a personalized model). The RMS is the one every
//! command prints ([`super::marker_rms`]). User documentation: `docs/verdict.md`.

use serde::{Deserialize, Serialize};

use super::conflict::JointConflict;
use super::envelope::EnvelopeBound;
use super::marker_policy::{MarkerAction, MarkerDecision};
use super::refine::RefinedMarker;
use super::{Calibration, WorkflowError};
use crate::ik::MarkerMap;
use crate::model::spec::MM_PER_M;
use crate::model::Model;
use crate::trial::Trial;

/// Before the fit, markers this far from the model (RMS, mm) mean the model is not of this
/// trial's session or marker set.
pub(crate) const REJECT_RMS_BEFORE_MM: f64 = 50.0;
/// After the fit: twice the movement bar of OpenSim's best practice (mm).
pub(crate) const REJECT_RMS_AFTER_MM: f64 = 40.0;
/// After the fit: the movement bar of OpenSim's best practice (mm).
pub(crate) const CAUTION_RMS_AFTER_MM: f64 = 20.0;
/// A single re-attached marker lands within this distance (mm) of where it was; the marker
/// policy leaves a marker further off out when its segment keeps enough markers, and a
/// refinement beyond it is said in the verdict.
pub(crate) const REFINE_CAP_MM: f64 = 30.0;
/// Refined markers moved further than this (mm) are a caution.
pub(crate) const CAUTION_REFINE_MM: f64 = 15.0;
/// A prior–data conflict (flagged at p < 0.01, [`super::conflict`]) stronger than this is a
/// caution; a weaker one is listed beside the level without raising it.
pub(crate) const STRONG_CONFLICT_P: f64 = 1e-4;
/// Share of frames the fit skipped above which the result is a caution.
pub(crate) const CAUTION_SKIPPED: f64 = 0.1;
/// Knee extension beyond this (deg, negative flexion) in any frame is a caution: passive
/// hyperextension of healthy knees rarely exceeds 5–10° (Soucie et al. 2011, Haemophilia
/// 17:500–507).
pub(crate) const KNEE_HYPEREXTENSION_DEG: f64 = -10.0;
/// A hip rotated by more than this (deg) in the median frame of a trial: gait keeps the hip
/// within about ±15° of neutral (Kadaba et al. 1990, J Orthop Res 8:383–392), so a fitted
/// joint frame that holds it at 20° or more through a trial has turned the thigh's axes.
pub(crate) const HIP_ROTATION_DEG: f64 = 20.0;

/// How far to trust a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// Nothing found that argues against the result.
    Ok,
    /// Usable, with the reasons read first.
    Caution,
    /// Not to be used: the inputs do not belong together or the result is implausible.
    Reject,
}

impl Level {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Level::Ok => "ok",
            Level::Caution => "caution",
            Level::Reject => "reject",
        }
    }
}

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The verdict: its level and the reasons, the gravest first, one sentence each.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Verdict {
    pub level: Level,
    pub reasons: Vec<String>,
    /// The level of each reason (same order).
    #[serde(skip)]
    grades: Vec<Level>,
}

/// Two verdicts are equal when they say the same (a verdict read back from JSON has lost the
/// grade of each reason, which its order keeps).
impl PartialEq for Verdict {
    fn eq(&self, other: &Self) -> bool {
        self.level == other.level && self.reasons == other.reasons
    }
}

impl Default for Verdict {
    fn default() -> Self {
        Verdict {
            level: Level::Ok,
            reasons: Vec::new(),
            grades: Vec::new(),
        }
    }
}

impl Verdict {
    /// Adds a reason of `level` after those at least as grave (an `ok` reason is a note: it
    /// is listed without raising the level).
    pub(crate) fn add(&mut self, level: Level, reason: String) {
        let at = self
            .grades
            .iter()
            .position(|&g| g < level)
            .unwrap_or(self.grades.len());
        self.grades.insert(at, level);
        self.reasons.insert(at, reason);
        self.level = self.level.max(level);
    }
}

/// A trial whose marker placement does not match the model's ([`crate::placement`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct TrialMismatch {
    /// Index of the trial in the calibration's trials.
    pub trial: usize,
    pub mismatch: crate::placement::Mismatch,
}

/// Step 1 of the module docs: each trial's marker placement against the model's.
pub(crate) fn placement_mismatches(model: &Model, trials: &[&Trial]) -> Vec<TrialMismatch> {
    trials
        .iter()
        .enumerate()
        .filter_map(|(k, t)| {
            let (map, _) = MarkerMap::allowing_absent(model, t.labels());
            crate::placement::compare(model, t, &map)
                .mismatch()
                .map(|mismatch| TrialMismatch { trial: k, mismatch })
        })
        .collect()
}

/// Step 1 as a refusal: the first mismatch as [`WorkflowError::Mismatch`], unless
/// `refuse` is off (then the mismatches are returned, to become reasons of a `reject`).
pub(crate) fn check_inputs(
    model: &Model,
    trials: &[&Trial],
    refuse: bool,
) -> Result<Vec<TrialMismatch>, WorkflowError> {
    let found = placement_mismatches(model, trials);
    match found.first() {
        Some(m) if refuse => Err(WorkflowError::Mismatch {
            trial: m.trial,
            cause: m.mismatch.cause(),
        }),
        _ => Ok(found),
    }
}

/// What [`judge`] weighs besides the calibration.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Evidence<'a> {
    /// Placement mismatches kept by an override of the refusal.
    pub mismatches: &'a [TrialMismatch],
    pub refined: &'a [RefinedMarker],
    pub decisions: &'a [MarkerDecision],
    pub conflict: &'a [JointConflict],
    pub envelope: &'a [EnvelopeBound],
    /// Joints held because the trials barely move them ([`super::motion_range`]).
    pub held: &'a [super::motion_range::HeldJoint],
}

/// Step 2 of the module docs: the verdict on `cal`, a calibration of `model`.
pub(crate) fn judge(model: &Model, cal: &Calibration, e: &Evidence) -> Verdict {
    let mut v = Verdict::default();
    for m in e.mismatches {
        v.add(
            Level::Reject,
            format!("trial {}: {}", m.trial + 1, m.mismatch.cause()),
        );
    }
    // Convergence has its own gate in front ends (kept only on request): here a caution.
    if !cal.converged {
        v.add(
            Level::Caution,
            format!("the fit did not converge ({})", cal.termination),
        );
    }
    judge_rms(cal, &mut v);
    judge_markers(e, &mut v);
    judge_anatomy(cal, e.envelope, &mut v);
    // A flagged conflict has its intervals widened already (the estimate stays honest): a
    // note beside an `ok`, a caution only when the trial contradicts the prior strongly.
    for c in e.conflict.iter().filter(|c| c.flagged) {
        let level = match c.p_value < STRONG_CONFLICT_P {
            true => Level::Caution,
            false => Level::Ok,
        };
        v.add(level, c.to_string());
    }
    if let Some(w) = &cal.global_warning {
        v.add(Level::Caution, w.clone());
    }
    let all = cal.frames + cal.skipped_frames;
    if all > 0 && cal.skipped_frames as f64 > CAUTION_SKIPPED * all as f64 {
        v.add(
            Level::Caution,
            format!(
                "{} of {all} frames could not be fitted and were skipped",
                cal.skipped_frames
            ),
        );
    }
    judge_motion(model, cal, &mut v);
    // A note: the held joints keep their prior values, which the fit does not claim to have
    // determined.
    if !e.held.is_empty() {
        v.add(Level::Ok, super::motion_range::held_line(e.held));
    }
    v
}

fn judge_rms(cal: &Calibration, v: &mut Verdict) {
    let (before, after) = (cal.rms_before * MM_PER_M, cal.rms_after * MM_PER_M);
    if before > REJECT_RMS_BEFORE_MM {
        v.add(
            Level::Reject,
            format!(
                "the markers sat {before:.1} mm (RMS) from the model before the fit, more than \
                 {REJECT_RMS_BEFORE_MM:.0} mm: the model is not of this trial's session or \
                 marker set"
            ),
        );
    }
    if after > REJECT_RMS_AFTER_MM {
        v.add(
            Level::Reject,
            format!(
                "the fitted model misses the markers by {after:.1} mm (RMS), more than \
                 {REJECT_RMS_AFTER_MM:.0} mm"
            ),
        );
    } else if after > CAUTION_RMS_AFTER_MM {
        v.add(
            Level::Caution,
            format!(
                "the fitted model misses the markers by {after:.1} mm (RMS), above the \
                 {CAUTION_RMS_AFTER_MM:.0} mm of a good movement-trial fit"
            ),
        );
    }
}

fn judge_markers(e: &Evidence, v: &mut Verdict) {
    if let Some(worst) = e.refined.iter().max_by(|a, b| a.shift.total_cmp(&b.shift)) {
        let shift_mm = worst.shift * MM_PER_M;
        let line = format!(
            "refined {} marker position{} by up to {:.1} mm ({})",
            e.refined.len(),
            if e.refined.len() == 1 { "" } else { "s" },
            shift_mm,
            worst.name
        );
        // Past the cap only a re-attached cluster explains it (another build or labels that
        // name other markers were refused before the fit, [`check_inputs`]): a caution.
        if shift_mm > REFINE_CAP_MM {
            v.add(
                Level::Caution,
                format!(
                    "{line}: more than a single re-attached marker moves \
                     ({REFINE_CAP_MM:.0} mm); check that the cluster was re-attached between \
                     the static trial and this one"
                ),
            );
        } else if shift_mm > CAUTION_REFINE_MM {
            v.add(Level::Caution, line);
        }
    }
    let left_out: Vec<&str> = e
        .decisions
        .iter()
        .filter(|d| d.action == MarkerAction::Exclude)
        .map(|d| d.marker.as_str())
        .collect();
    if !left_out.is_empty() {
        v.add(
            Level::Caution,
            format!(
                "left out marker{} {}: broken in many frames or placed elsewhere than in the \
                 static trial (the marker policy's lines say which)",
                if left_out.len() == 1 { "" } else { "s" },
                left_out.join(", "),
            ),
        );
    }
}

fn judge_anatomy(cal: &Calibration, envelope: &[EnvelopeBound], v: &mut Verdict) {
    for c in cal.plausibility.iter().filter(|c| !c.ok) {
        let line = format!(
            "{}: {:.1} {u} against at most {:.1} {u} ({})",
            c.check,
            c.value,
            c.limit,
            c.parameters.join(", "),
            u = c.unit
        );
        match c.value > 2.0 * c.limit {
            true => v.add(Level::Reject, format!("implausible anatomy: {line}")),
            false => v.add(
                Level::Caution,
                format!("outside the anatomical envelope: {line}"),
            ),
        }
    }
    for b in envelope.iter().filter(|b| b.active) {
        v.add(
            Level::Caution,
            format!(
                "{}: held at the anatomical bound {:.1} mm (the trial pulls it further out)",
                b.parameter,
                b.limit * MM_PER_M
            ),
        );
    }
}

/// The fitted motion against the anatomical ranges (coordinates of the leg template: knee
/// flexion positive, hip rotation; a bilateral model's carry `_r` / `_l`).
fn judge_motion(model: &Model, cal: &Calibration, v: &mut Verdict) {
    let coords = &cal.fit.coords;
    if coords.is_empty() {
        return;
    }
    for (k, c) in model.coordinates().iter().enumerate() {
        let base = ["_r", "_l"]
            .iter()
            .find_map(|s| c.name.strip_suffix(s))
            .unwrap_or(&c.name);
        let mut deg: Vec<f64> = coords
            .iter()
            .filter_map(|q| q.get(k).copied())
            .filter(|x| x.is_finite())
            .map(f64::to_degrees)
            .collect();
        if deg.is_empty() {
            continue;
        }
        match base {
            "knee_flexion" => {
                let beyond = deg.iter().filter(|&&x| x < KNEE_HYPEREXTENSION_DEG).count();
                let least = deg.iter().copied().fold(f64::INFINITY, f64::min);
                if beyond > 0 {
                    v.add(
                        Level::Caution,
                        format!(
                            "{} reaches {least:.1}° (hyperextension beyond \
                             {KNEE_HYPEREXTENSION_DEG:.0}°) in {beyond} frames",
                            c.name
                        ),
                    );
                }
            }
            "hip_rotation" => {
                let mid = deg.len() / 2;
                let median = *deg.select_nth_unstable_by(mid, f64::total_cmp).1;
                if median.abs() > HIP_ROTATION_DEG {
                    v.add(
                        Level::Caution,
                        format!(
                            "{} stays near {median:.1}° through the trial (median frame): the \
                             fitted hip frame may have turned the thigh's axes",
                            c.name
                        ),
                    );
                }
            }
            _ => {}
        }
    }
}
