//! The default marker policy of a maximum a posteriori calibration: what to do with a
//! tracking marker that the data checks find sitting differently in the motion trial than in
//! the static trial, or broken.
//!
//! Each trial gets one robust inverse kinematics at the start parameters (the landmark
//! model) on the frames [`frames_looked_at`] picks, and from it the residual statistic of
//! [`crate::checks::offsets`] (mean `μ_j` and spread `σ_j` of marker `j`'s residual in its
//! segment's frame) and the share of the frames in which the robust IK rejected the marker
//! as a gross error ([`crate::ik::FrameFit::rejected`]):
//!
//! * **refine** the markers of a segment whose cluster moved: at least two of its markers
//!   *displaced* (`‖μ_j‖ ≥ 30 mm` and `≥ 2 σ_j`: each sits at the same wrong place of its
//!   segment in every frame, [`MarkerOffset::displaced`]) and at least half of them, the
//!   segment not attached to ground (its markers define its pose: the pelvis cluster
//!   "moved" 30–39 mm in synthetic trials whose hip centre was off, none on the shared
//!   trials); then the
//!   displaced ones and every other marker of it off by `≥ 15 mm` (the moved ones pull the IK
//!   and hide how far the others moved); and a lone displaced marker on a segment with more
//!   than [`MIN_OTHERS`] markers in the trial. On a smaller segment a lone marker's residual
//!   after IK at the landmark model is the landmark joints' error as much as its own: on
//!   synthetic trials with the joints drawn from their landmark priors and no marker moved,
//!   the heel (the foot's three markers) sat 30–35 mm off in 5 % of the trials
//!   (`docs/priors.md`, "The policy and the envelope on synthetic trials"); there only the
//!   leave-one-out test below could refine it, and it needs four markers. A displaced marker
//!   is never left out (a steady offset is not a broken marker). Only these markers get position parameters
//!   ([`crate::model::refine`]), with the prior SD that lets the refinement reach the offset
//!   (`max(10 mm, ⌈‖μ‖_max / 5 / 5 mm⌉ · 5 mm)`, the bound being 5 SDs, as the offset
//!   finding's own advice); the joints then stop absorbing the offset. Refining every marker
//!   (`--refine-markers`) fixed the marker RMS on such trials but moved the hip by up to
//!   27 mm on squats and sit-to-stand, where no marker was displaced (`notebook/gait_table.md`).
//! * **leave out** (of that trial) a marker that is not displaced but that the robust IK
//!   rejected in at least [`BROKEN_SHARE`] of its frames: it jumps or sits far from its
//!   segment in many frames without a steady offset, so no fixed position explains it.
//!
//! Every decision is one line ([`MarkerDecision::line`]) and a JSON object; markers named in
//! `FitSettings::keep_markers` are left as they are, and `FitSettings::marker_policy = false`
//! turns the policy off. The marker RMS before and after the fit are then over the markers
//! the fit used (a left-out marker is in neither).

use serde::Serialize;

use crate::checks::offsets::{frames_looked_at, offsets_of_fit, MarkerOffset, MIN_FRAMES};
use crate::checks::offsets::{MIN_OFFSET, MIN_RATIO};
use crate::ik::trial_fit::{solve_trial, TrialFit};
use crate::ik::{IkOptions, MarkerMap};
use crate::model::refine::{BOUND_IN_SD, DEFAULT_MARKER_PRIOR_SD};
use crate::model::spec::MM_PER_M;
use crate::model::Model;
use crate::trial::Trial;

use super::marker_rigid::{rigid_displaced, RigidOffset, MIN_OTHERS};

/// Smallest mean of the leave-one-out residual ([`super::marker_rigid`]) that refines a
/// marker (m), and its smallest ratio to the spread (module docs).
pub(crate) const RIGID_MIN_OFFSET: f64 = 0.012;
pub(crate) const RIGID_MIN_RATIO: f64 = 3.0;

/// Share of a marker's frames in which the robust IK rejected it, from which a marker that
/// is not displaced counts as broken.
pub(crate) const BROKEN_SHARE: f64 = 0.25;

/// What the policy does with a marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MarkerAction {
    /// Its position in its segment is fitted, with a prior around the static position.
    Refine,
    /// It is left out of the fit (of the trial named).
    Exclude,
}

/// One decision of the policy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerDecision {
    pub marker: String,
    pub segment: String,
    pub action: MarkerAction,
    /// The trial (index into the calibration's trials) the statistic came from; for
    /// [`MarkerAction::Exclude`] the trial the marker leaves.
    pub trial: usize,
    /// Prior SD of the refined position (m per axis), for [`MarkerAction::Refine`].
    pub prior_sd: Option<f64>,
    /// `‖μ_j‖` and `σ_j` (m), frames that entered, and the share of them in which the
    /// robust IK rejected the marker.
    pub offset: f64,
    pub spread: f64,
    pub frames: usize,
    pub rejected_share: f64,
    /// Why, in words.
    pub reason: String,
}

/// The prior SD (m) that lets a refinement reach an offset of `size` (m).
fn prior_sd_for(size: f64) -> f64 {
    let mm = (size * MM_PER_M / BOUND_IN_SD / 5.0).ceil() * 5.0;
    (mm / MM_PER_M).max(DEFAULT_MARKER_PRIOR_SD)
}

/// The decisions gathered over the trials: refinements (one per marker) and exclusions.
#[derive(Default)]
struct Decisions {
    refine: Vec<MarkerDecision>,
    exclude: Vec<MarkerDecision>,
}

impl Decisions {
    /// A refinement; a marker refined for several trials keeps the largest prior SD.
    fn refine(&mut self, d: MarkerDecision) {
        match self.refine.iter_mut().find(|r| r.marker == d.marker) {
            Some(r) if r.prior_sd < d.prior_sd => *r = d,
            Some(_) => {}
            None => self.refine.push(d),
        }
    }
}

/// The policy's decisions for `trials` fitted with `model` from `start`, markers named in
/// `keep` left alone. Refinements first (one per marker, the largest prior SD over the
/// trials), then exclusions, each in model marker order.
pub fn decide(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    keep: &[String],
) -> Vec<MarkerDecision> {
    decide_on(model, start, trials, keep, &robust_ik(model, start, trials))
}

/// The robust inverse kinematics the policy reads: of each trial at `start` on the frames
/// [`frames_looked_at`] picks (`None` where it fails).
pub(crate) fn robust_ik(model: &Model, start: &[f64], trials: &[&Trial]) -> Vec<Option<LookedAt>> {
    trials
        .iter()
        .map(|trial| {
            let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
            let (a, b) = frames_looked_at(trial.n_frames());
            let sub = trial.slice_frames(a, b);
            let fit = solve_trial(model, start, &sub, &map, &IkOptions::default()).ok()?;
            Some(LookedAt { first: a, sub, fit })
        })
        .collect()
}

/// A trial's frames the policy looks at and their robust inverse kinematics ([`robust_ik`]).
pub(crate) struct LookedAt {
    /// The trial's frame that is the first of `sub`.
    pub(crate) first: usize,
    pub(crate) sub: Trial,
    pub(crate) fit: TrialFit,
}

impl LookedAt {
    /// The solved coordinates of the trial's frame `frame`, when it is looked at.
    pub(crate) fn coords(&self, frame: usize) -> Option<&[f64]> {
        let i = frame.checked_sub(self.first)?;
        self.fit
            .frames
            .get(i)
            .filter(|f| f.solved())
            .map(|_| self.fit.coords[i].as_slice())
    }
}

/// [`decide`] on the robust inverse kinematics `looked` ([`robust_ik`] of the same trials).
pub(crate) fn decide_on(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    keep: &[String],
    looked: &[Option<LookedAt>],
) -> Vec<MarkerDecision> {
    let mut dec = Decisions::default();
    for (t, (trial, at)) in trials.iter().zip(looked).enumerate() {
        if let Some(at) = at {
            trial_decisions(model, start, trial, at, t, keep, &mut dec);
        }
    }
    cap_refinements(model, trials, &mut dec);
    let Decisions {
        mut refine,
        mut exclude,
    } = dec;
    // A marker refined for one trial is not also left out of another: its fitted position
    // serves every trial.
    exclude.retain(|e| !refine.iter().any(|r| r.marker == e.marker));
    let order = |d: &MarkerDecision| {
        model
            .markers()
            .iter()
            .position(|m| m.name == d.marker)
            .unwrap_or(usize::MAX)
    };
    refine.sort_by_key(order);
    exclude.sort_by_key(|d| (d.trial, order(d)));
    refine.extend(exclude);
    refine
}

/// Trial `t`'s decisions: its markers' offsets after IK at `start` (on the frames looked
/// at), segment by segment, then the markers its segment's other markers put elsewhere.
fn trial_decisions(
    model: &Model,
    start: &[f64],
    trial: &Trial,
    LookedAt { sub, fit, .. }: &LookedAt,
    t: usize,
    keep: &[String],
    dec: &mut Decisions,
) {
    let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
    let offsets = offsets_of_fit(model, start, sub, &map, fit);
    let rejected = |j: usize| {
        fit.frames
            .iter()
            .filter(|f| f.solved() && f.rejected.contains(&j))
            .count()
    };
    for s in 0..model.segments().len() {
        segment_decisions(model, s, t, &offsets, keep, &rejected, dec);
    }
    rigid_decisions(model, trial, t, keep, &offsets, &rejected, dec);
}

/// The decisions for segment `s`'s markers in trial `t` (`rejected`: in how many frames the
/// IK rejected a model marker as a gross error).
fn segment_decisions(
    model: &Model,
    s: usize,
    t: usize,
    offsets: &[MarkerOffset],
    keep: &[String],
    rejected: &dyn Fn(usize) -> usize,
    dec: &mut Decisions,
) {
    let name = |o: &MarkerOffset| model.markers()[o.marker].name.clone();
    let segment = |o: &MarkerOffset| {
        let s = model.markers()[o.marker].segment.0;
        model.segments()[s].name.clone()
    };
    let here: Vec<&MarkerOffset> = offsets
        .iter()
        .filter(|o| model.markers()[o.marker].segment.0 == s)
        .filter(|o| !keep.contains(&name(o)))
        .collect();
    let moved: Vec<&MarkerOffset> = here.iter().copied().filter(|o| o.displaced()).collect();
    // The markers of a segment attached to ground define its pose: all of them
    // off means the IK put the segment elsewhere, which only the joints' error
    // does (a moved pelvis cluster is the hip centre moving); no cluster there.
    let rooted = model.segments()[s].parent.is_none();
    // Enough markers of the segment in the trial for the leave-one-out test.
    let checkable = here.len() > MIN_OTHERS;
    let cluster = !rooted && moved.len() >= 2 && 2 * moved.len() >= here.len();
    let largest = moved.iter().map(|o| o.size()).fold(0.0, f64::max);
    for o in &here {
        let share = rejected(o.marker) as f64 / o.frames.max(1) as f64;
        let decision = |action, prior_sd, reason| MarkerDecision {
            marker: name(o),
            segment: segment(o),
            action,
            trial: t,
            prior_sd,
            offset: o.size(),
            spread: o.spread,
            frames: o.frames,
            rejected_share: share,
            reason,
        };
        if let Some((sd, reason)) = refinement(o, &segment(o), t, cluster, checkable, largest) {
            dec.refine(decision(MarkerAction::Refine, Some(sd), reason));
        } else if !o.displaced() && o.frames >= MIN_FRAMES && share >= BROKEN_SHARE {
            let reason = format!(
                "rejected as a gross error in {:.0} % of {} frames of trial {} without a \
                 steady offset ({:.0} mm, spread {:.0} mm, < {MIN_RATIO:.0}× or \
                 < {:.0} mm): no fixed position explains it",
                100.0 * share,
                o.frames,
                t + 1,
                o.size() * MM_PER_M,
                o.spread * MM_PER_M,
                MIN_OFFSET * MM_PER_M
            );
            dec.exclude
                .push(decision(MarkerAction::Exclude, None, reason));
        }
    }
}

/// The prior SD (m) and reason of a refinement of marker `o` of segment `segment` in trial
/// `t`, or `None`. A lone displaced marker on a segment too small for the leave-one-out test
/// (`checkable`) is not refined: its residual after IK at the landmark model is the landmark
/// joints' error as much as its own (module docs).
fn refinement(
    o: &MarkerOffset,
    segment: &str,
    t: usize,
    cluster: bool,
    checkable: bool,
    largest: f64,
) -> Option<(f64, String)> {
    if o.displaced() && (cluster || checkable) {
        let steady = format!(
            "sits {:.0} mm from its static-trial place in every frame (spread {:.0} mm \
             over {} frames of trial {})",
            o.size() * MM_PER_M,
            o.spread * MM_PER_M,
            o.frames,
            t + 1
        );
        let sd = prior_sd_for(if cluster { largest } else { o.size() });
        Some((sd, steady))
    } else if cluster && o.size() >= MIN_OFFSET / 2.0 {
        let reason = format!(
            "its {segment} cluster moved; it sits {:.0} mm off (spread {:.0} mm) in trial {}",
            o.size() * MM_PER_M,
            o.spread * MM_PER_M,
            t + 1
        );
        Some((prior_sd_for(largest), reason))
    } else {
        None
    }
}

/// Refinements of the markers of trial `t` that sit steadily away from where their
/// segment's other markers put them (the static-trial layout), unless kept or refined.
fn rigid_decisions(
    model: &Model,
    trial: &Trial,
    t: usize,
    keep: &[String],
    offsets: &[MarkerOffset],
    rejected: &dyn Fn(usize) -> usize,
    dec: &mut Decisions,
) {
    let steady = |o: &RigidOffset| {
        o.frames >= MIN_FRAMES && o.size() >= RIGID_MIN_OFFSET && o.ratio() >= RIGID_MIN_RATIO
    };
    for o in rigid_displaced(model, trial, steady) {
        let m = &model.markers()[o.marker];
        if keep.contains(&m.name) || dec.refine.iter().any(|r| r.marker == m.name) {
            continue;
        }
        let share = offsets
            .iter()
            .find(|x| x.marker == o.marker)
            .map_or(0.0, |x| rejected(o.marker) as f64 / x.frames.max(1) as f64);
        dec.refine.push(MarkerDecision {
            marker: m.name.clone(),
            segment: model.segments()[m.segment.0].name.clone(),
            action: MarkerAction::Refine,
            trial: t,
            prior_sd: Some(prior_sd_for(o.size())),
            offset: o.size(),
            spread: o.spread,
            frames: o.frames,
            rejected_share: share,
            reason: format!(
                "sits {:.0} mm from where its segment's other markers put it (static-trial \
                 layout) in every frame (spread {:.0} mm over {} frames of trial {})",
                o.size() * MM_PER_M,
                o.spread * MM_PER_M,
                o.frames,
                t + 1
            ),
        });
    }
}

/// A marker further from its place than a re-attachment moves is not refined: its label
/// names another marker in this trial (e.g. two cluster markers swapped), and refining it
/// would absorb that mismatch ([`super::verdict::REFINE_CAP_MM`]). It is left out when
/// its segment keeps three markers in that trial; otherwise it stays refined and the
/// verdict judges the refinement.
fn cap_refinements(model: &Model, trials: &[&Trial], dec: &mut Decisions) {
    let cap = super::verdict::REFINE_CAP_MM;
    let cap_m = cap / MM_PER_M;
    let mut left: Vec<(usize, String)> = dec
        .exclude
        .iter()
        .map(|d| (d.trial, d.marker.clone()))
        .collect();
    let mut capped = Vec::new();
    for d in dec.refine.iter().filter(|d| d.offset > cap_m) {
        let kept = model
            .markers()
            .iter()
            .filter(|m| model.segments()[m.segment.0].name == d.segment)
            .filter(|m| trials[d.trial].labels().contains(&m.name))
            .filter(|m| !left.iter().any(|(t, n)| *t == d.trial && *n == m.name))
            .count();
        if kept > 3 {
            left.push((d.trial, d.marker.clone()));
            capped.push(d.marker.clone());
        }
    }
    for mut d in dec.refine.extract_if(.., |d| capped.contains(&d.marker)) {
        d.action = MarkerAction::Exclude;
        d.prior_sd = None;
        d.reason = format!(
            "{}; more than the {cap:.0} mm a re-attached marker moves, so its label may name \
             another marker: not refined",
            d.reason
        );
        dec.exclude.push(d);
    }
}

/// The trials without the markers the decisions leave out of them.
pub(crate) fn without_excluded(trials: &[&Trial], decisions: &[MarkerDecision]) -> Vec<Trial> {
    trials
        .iter()
        .enumerate()
        .map(|(t, trial)| {
            let out: Vec<&str> = decisions
                .iter()
                .filter(|d| d.action == MarkerAction::Exclude && d.trial == t)
                .map(|d| d.marker.as_str())
                .collect();
            if out.is_empty() {
                return (*trial).clone();
            }
            let keep: Vec<&str> = trial
                .labels()
                .iter()
                .map(String::as_str)
                .filter(|l| !out.contains(l))
                .collect();
            trial.select(&keep).expect("labels of the trial")
        })
        .collect()
}

/// The refined markers with their prior SD (m), from the decisions.
pub(crate) fn refined(decisions: &[MarkerDecision]) -> Vec<(&str, f64)> {
    decisions
        .iter()
        .filter(|d| d.action == MarkerAction::Refine)
        .map(|d| {
            let sd = d.prior_sd.unwrap_or(DEFAULT_MARKER_PRIOR_SD);
            (d.marker.as_str(), sd)
        })
        .collect()
}
