//! A data check that needs a fit: markers that sit, in every frame, at the same wrong place
//! of their segment (a cluster moved since the static trial, or labelled differently there).
//!
//! Distances inside a segment's cluster do not change when the whole cluster moves, so the
//! distance checks of [`crate::checks`] cannot see it; inverse kinematics then absorbs part of
//! the move into the coordinates and a calibration into the joint parameters. After inverse
//! kinematics at the model's nominal parameters, the residual of marker `j` in frame `i`,
//! expressed in the frame of the segment `s` the marker is fixed in,
//!
//! ```text
//! r_ij = R_s(q_i)ᵀ (m_ij − x_j(q_i)),
//! ```
//!
//! has over the frames a mean `μ_j` and a spread `σ_j = sqrt(mean_i ‖r_ij − μ_j‖²)`. Noise
//! and skin motion give a mean comparable to the spread (it changes with the pose); a marker
//! that sits elsewhere on its segment gives a large mean with a small spread: a systematic
//! offset. A marker is *displaced* when `‖μ_j‖ ≥` [`MIN_OFFSET`] and
//! `‖μ_j‖ ≥` [`MIN_RATIO`]` · σ_j`; when at least two markers of one segment and at least
//! half of its present markers are displaced, the finding names the segment's cluster.
//! The thresholds and the statistic on every shared motion trial are in
//! `docs/moved_clusters.md`.
//!
//! The inverse kinematics is the robust one of [`crate::ik`] (gross errors rejected per
//! frame; the residuals here are taken of every present marker, rejected or not) on at most
//! [`MAX_FRAMES`] consecutive frames from the middle of the trial, which bounds the cost (on
//! a short trial it is one more IK of the trial: one seeding, then warm-started frames). A
//! front end that runs that same IK anyway (`workflow::ik::ik_checked`, the `ik` command) hands
//! its fit to [`marker_offsets`] or [`check_offsets`], which read the statistic from it instead.

use nalgebra::Vector3;

use crate::checks::{CheckKind, Finding, Severity};
use crate::ik::trial_fit::solve_trial;
use crate::ik::trial_fit::TrialFit;
use crate::ik::{IkOptions, MarkerMap};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::refine::BOUND_IN_SD;
use crate::model::Model;
use crate::trial::Trial;

/// Smallest mean residual (m) in the segment frame that counts as a displaced marker. The
/// clean shared trials stay below 22 mm (`docs/moved_clusters.md`).
pub(crate) const MIN_OFFSET: f64 = 0.03;
/// Smallest ratio of the mean residual to its spread that counts as systematic.
pub(crate) const MIN_RATIO: f64 = 2.0;
/// Frames a marker must be present (and its frame solved) in for its statistic.
pub(crate) const MIN_FRAMES: usize = 10;
/// Frames looked at, at most (consecutive, from the middle of a longer trial: 2 s at 100 Hz,
/// a gait cycle).
pub(crate) const MAX_FRAMES: usize = 200;

/// The residual statistic of one model marker over a trial.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerOffset {
    /// Model marker index.
    pub marker: usize,
    /// Mean residual `μ_j` in the marker's segment frame (m).
    pub mean: Vector3<f64>,
    /// RMS distance of the residuals from their mean, `σ_j` (m).
    pub spread: f64,
    /// Frames that entered.
    pub frames: usize,
}

impl MarkerOffset {
    /// `‖μ_j‖` (m).
    pub(crate) fn size(&self) -> f64 {
        self.mean.norm()
    }
    /// `‖μ_j‖ / σ_j` (infinite when the spread is zero).
    pub(crate) fn ratio(&self) -> f64 {
        if self.spread > 0.0 {
            self.size() / self.spread
        } else {
            f64::INFINITY
        }
    }
    /// Whether the offset is large and systematic (see the module docs).
    pub(crate) fn displaced(&self) -> bool {
        self.frames >= MIN_FRAMES && self.size() >= MIN_OFFSET && self.ratio() >= MIN_RATIO
    }
}

/// The statistic of every model marker the trial has (in at least [`MIN_FRAMES`] solved
/// frames), after inverse kinematics at parameters `p` with `opts` of the frames
/// [`frames_looked_at`] picks. `fit`: an inverse kinematics of the whole trial at `p` with
/// `opts` already at hand, whose frames are read instead of solved again when it is the IK
/// this statistic runs (`p` the nominal parameters, `opts` the default ones; see
/// [`offsets_from_ik`]). Empty when the IK cannot run (wrong parameter length).
pub fn marker_offsets(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    fit: Option<&TrialFit>,
) -> Vec<MarkerOffset> {
    if let Some(offsets) = fit.and_then(|fit| offsets_from_ik(model, p, trial, map, opts, fit)) {
        return offsets;
    }
    let (start, end) = frames_looked_at(trial.n_frames());
    let sub = trial.slice_frames(start, end);
    match solve_trial(model, p, &sub, map, opts) {
        Ok(fit) => offsets_of_fit(model, p, &sub, map, &fit),
        Err(_) => Vec::new(),
    }
}

/// The statistic from an inverse kinematics `fit` of `trial` already at hand (every solved
/// frame enters): what [`marker_offsets`] computes after its own IK.
pub(crate) fn offsets_of_fit(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    fit: &TrialFit,
) -> Vec<MarkerOffset> {
    offsets_over(model, p, trial, map, fit, 0..fit.frames.len())
}

/// The statistic over frames `frames` of `fit` (an IK of `trial`). The residuals of each
/// frame are computed in parallel chunks and summed in frame order, so the result is the
/// same on any number of threads.
fn offsets_over(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    fit: &TrialFit,
    frames: std::ops::Range<usize>,
) -> Vec<MarkerOffset> {
    use rayon::prelude::*;
    let nm = model.markers().len();
    if nm == 0 {
        return Vec::new();
    }
    // Per frame, the residual of every model marker (NaN where missing or not solved).
    let frame_residuals = |f: usize, kin: &mut KinData, out: &mut Vec<Vector3<f64>>| {
        let start = out.len();
        out.resize(start + nm, Vector3::repeat(f64::NAN));
        if !fit.frames[f].solved() {
            return;
        }
        forward_kinematics(model, p, &fit.coords[f], Want::Positions, kin);
        let row = trial.frame(f);
        for (j, marker) in model.markers().iter().enumerate() {
            let Some(c) = map.columns[j] else { continue };
            let m = row[c];
            if !m.x.is_finite() {
                continue;
            }
            let rot = kin.segment_poses[marker.segment.0].rot;
            out[start + j] = rot.transpose() * (m - kin.markers[j]);
        }
    };
    let chunk = OFFSET_CHUNK_FRAMES;
    let starts: Vec<usize> = frames.clone().step_by(chunk).collect();
    let pieces: Vec<Vec<Vector3<f64>>> = starts
        .into_par_iter()
        .map(|s| {
            let mut kin = KinData::new(model);
            let mut out = Vec::with_capacity(chunk * nm);
            for f in s..(s + chunk).min(frames.end) {
                frame_residuals(f, &mut kin, &mut out);
            }
            out
        })
        .collect();
    let mut residuals: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); nm];
    for r in pieces.iter().flat_map(|piece| piece.chunks(nm)) {
        for (j, x) in r.iter().enumerate() {
            if !x.x.is_nan() {
                residuals[j].push(*x);
            }
        }
    }
    residuals
        .into_iter()
        .enumerate()
        .filter(|(_, r)| r.len() >= MIN_FRAMES)
        .map(|(j, r)| {
            let mean = r.iter().sum::<Vector3<f64>>() / r.len() as f64;
            let var = r.iter().map(|x| (x - mean).norm_squared()).sum::<f64>() / r.len() as f64;
            MarkerOffset {
                marker: j,
                mean,
                spread: var.sqrt(),
                frames: r.len(),
            }
        })
        .collect()
}

/// Frames per parallel chunk of [`offsets_of_fit`] (a forward kinematics each).
const OFFSET_CHUNK_FRAMES: usize = 64;

/// The statistic of [`marker_offsets`] taken from the inverse kinematics `fit` of the whole
/// of `trial` at parameters `p` with options `opts`, when that is the same inverse
/// kinematics [`marker_offsets`] would run itself: `p` the model's nominal parameters and
/// `opts` the default ones. It then reads the frames [`frames_looked_at`] picks from `fit`
/// instead of solving them again. On a trial of at most [`MAX_FRAMES`] frames the two IKs
/// are one and the same computation, so the statistic is identical bit for bit; on a
/// longer one the frames of the window were warm-started from the frames before it rather
/// than seeded at its start, which moves each solution by about the solver's tolerance
/// (`IkOptions::step_tolerance`, 1e-8), far below the millimetres the findings print
/// (checked on every shared trial by jointfit-cli's `offsets` test). `None` when the IK
/// differs (other parameters or options): the statistic then needs its own IK.
pub(crate) fn offsets_from_ik(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    fit: &TrialFit,
) -> Option<Vec<MarkerOffset>> {
    let same = p == model.nominal_params().as_slice()
        && *opts == IkOptions::default()
        && fit.frames.len() == trial.n_frames();
    if !same {
        return None;
    }
    let (start, end) = frames_looked_at(trial.n_frames());
    Some(offsets_over(model, p, trial, map, fit, start..end))
}

/// The frames [`marker_offsets`] looks at, `start..end`: the whole trial up to
/// [`MAX_FRAMES`] frames, else the [`MAX_FRAMES`] consecutive frames in its middle.
/// Consecutive, so that they are warm-started frame to frame as `ik` does (a stride through a
/// fast motion starts frames far from their solution, and more runs cost a seeding each,
/// which costs more than the frames).
pub(crate) fn frames_looked_at(n: usize) -> (usize, usize) {
    if n <= MAX_FRAMES {
        return (0, n);
    }
    let start = (n - MAX_FRAMES) / 2;
    (start, start + MAX_FRAMES)
}

/// The displaced markers of `offsets` as findings: one per segment whose cluster moved (at
/// least two displaced markers, at least half of the segment's markers in `offsets`), one
/// per other displaced marker. `reference` names what the marker positions come from
/// (e.g. "the subject model (static trial)").
pub(crate) fn offset_findings(
    model: &Model,
    offsets: &[MarkerOffset],
    reference: &str,
) -> Vec<Finding> {
    let mut out = Vec::new();
    for (s, seg) in model.segments().iter().enumerate() {
        let here: Vec<&MarkerOffset> = offsets
            .iter()
            .filter(|o| model.markers()[o.marker].segment.0 == s)
            .collect();
        let moved: Vec<&MarkerOffset> = here.iter().copied().filter(|o| o.displaced()).collect();
        if moved.is_empty() {
            continue;
        }
        let name = |o: &MarkerOffset| model.markers()[o.marker].name.clone();
        let frames = moved.iter().map(|o| o.frames).max().unwrap_or(0);
        if moved.len() >= 2 && 2 * moved.len() >= here.len() {
            let names: Vec<String> = moved.iter().map(|o| name(o)).collect();
            // Markers of the segment off by half the threshold or more, but less steadily:
            // the IK, pulled by the moved ones, may hide how far these moved too.
            let also: Vec<String> = here
                .iter()
                .filter(|o| !o.displaced() && o.size() >= MIN_OFFSET / 2.0)
                .map(|o| format!("{} ({:.0} mm)", name(o), o.size() * 1e3))
                .collect();
            let also_text = if also.is_empty() {
                String::new()
            } else {
                format!(
                    "; {} {} off too, less steadily",
                    also.join(", "),
                    if also.len() == 1 { "is" } else { "are" }
                )
            };
            let mut excluded = names.clone();
            excluded.extend(
                here.iter()
                    .filter(|o| !o.displaced() && o.size() >= MIN_OFFSET / 2.0)
                    .map(|o| name(o)),
            );
            let mean_mm = moved.iter().map(|o| o.size()).sum::<f64>() / moved.len() as f64 * 1e3;
            let spread_mm = moved.iter().map(|o| o.spread).sum::<f64>() / moved.len() as f64 * 1e3;
            out.push(Finding {
                kind: CheckKind::Offset,
                severity: Severity::Warning,
                message: format!(
                    "the {} cluster ({}) sits {mean_mm:.0} mm from its place in {reference} in \
                     every frame (spread {spread_mm:.0} mm over {frames} frames){also_text}: it \
                     moved, or the labels differ from the static trial's; fitted as it is, the \
                     offset bends the joint parameters",
                    seg.name,
                    names.join(", "),
                ),
                fix: Some(format!(
                    "{}, or --exclude-marker for each of {}, or re-run personalize \
                     with a static trial of this session",
                    refine_option(&moved),
                    excluded.join(", ")
                )),
            });
        } else {
            for o in moved {
                out.push(Finding {
                    kind: CheckKind::Offset,
                    severity: Severity::Warning,
                    message: format!(
                        "{}: {} sits {:.0} mm from its place in {reference} in every frame \
                         (spread {:.0} mm over {} frames): it moved or was re-attached",
                        seg.name,
                        name(o),
                        o.size() * 1e3,
                        o.spread * 1e3,
                        o.frames,
                    ),
                    fix: Some(format!(
                        "--exclude-marker {}, or {}",
                        name(o),
                        refine_option(&[o])
                    )),
                });
            }
        }
    }
    out
}

/// `calibrate --refine-markers`, with a prior SD large enough for the refinement to reach
/// the largest of these offsets: the refined positions are bounded to
/// [`BOUND_IN_SD`] prior SDs per axis around the static positions, and the default SD
/// (10 mm) reaches 50 mm. On walking1's left thigh (offsets up to 142 mm) the default leaves
/// the knee axis implausible; 25 or 40 mm brings the RMS from 57 to 3.5 mm.
fn refine_option(moved: &[&MarkerOffset]) -> String {
    let largest_mm = moved.iter().map(|o| o.size()).fold(0.0, f64::max) * 1e3;
    let sd = (largest_mm / BOUND_IN_SD / 5.0).ceil() * 5.0;
    if sd > 10.0 {
        format!("calibrate --refine-markers --marker-prior-sd-mm {sd:.0}")
    } else {
        "calibrate --refine-markers".to_string()
    }
}

/// The check of the module docs for `trial` against `model` at its nominal parameters, with
/// the default inverse-kinematics options. `ik`: the parameters, options and fit of an
/// inverse kinematics of the whole trial already at hand, read instead of a second one when
/// it is the check's own ([`marker_offsets`]); `None`: the check runs its own. The findings
/// name what the model's marker positions come from: the OpenSim file a model was read from
/// ([`OSIM_DESCRIPTION`]), else the static trial of a subject model.
pub fn check_offsets(
    model: &Model,
    trial: &Trial,
    map: &MarkerMap,
    ik: Option<(&[f64], &IkOptions, &TrialFit)>,
) -> Vec<Finding> {
    let reused = ik.and_then(|(p, opts, fit)| offsets_from_ik(model, p, trial, map, opts, fit));
    let offsets = reused.unwrap_or_else(|| {
        let (p, opts) = (model.nominal_params(), IkOptions::default());
        marker_offsets(model, &p, trial, map, &opts, None)
    });
    offset_findings(model, &offsets, &reference_name(model))
}

/// What a model's marker positions come from, for messages: "the model (NAME.osim)" for a
/// model read from an OpenSim file (its description says so), else "the subject model
/// (static trial)" (`personalize` places the markers where the static trial has them).
pub(crate) fn reference_name(model: &Model) -> String {
    match model.description().strip_prefix(OSIM_DESCRIPTION) {
        Some(path) => {
            let file = path.rsplit(['/', '\\']).next().unwrap_or(path);
            format!("the model ({file})")
        }
        None => "the subject model (static trial)".to_string(),
    }
}

/// How the OpenSim reader describes a model it read (`jointfit_io::osim_read`): this prefix,
/// then the file's path. The offset findings name that file.
pub const OSIM_DESCRIPTION: &str = "OpenSim model read from ";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{check_trial, CheckKind};

    /// The right-leg model, and a trial of `frames` frames with skin noise (≤ 8 mm per axis,
    /// seed 11) of the same model with its three thigh markers shifted by `by` (m, thigh
    /// frame).
    fn moved_thigh_cluster(moved: &[&str], by: [f64; 3], frames: usize) -> (Model, Trial) {
        let spec = crate::model::lower_limb::lower_limb(crate::model::lower_limb::Side::Right);
        let model = Model::compile(&spec).unwrap();
        let mut shifted = spec.clone();
        for m in &mut shifted.markers {
            if moved.contains(&m.name.as_str()) {
                for (x, d) in m.position.iter_mut().zip(by) {
                    *x += d;
                }
            }
        }
        let truth = Model::compile(&shifted).unwrap();
        let p = truth.nominal_params();
        let s = crate::kinematics::synth::synthetic_trial(
            &truth,
            &p,
            frames,
            100.0,
            |f| crate::ik::tests::motion(&truth, f, 0.3),
            crate::kinematics::synth::Noise::Skin { amplitude: 0.008 },
            11,
        );
        (model, s.trial)
    }

    /// `crate::workflow::ik::ik_checked` takes the moved-cluster statistic from its own IK instead of a
    /// second one, and gives the findings `check_trial` gives: bit for bit on a trial of at most
    /// 200 frames (the two IKs are the same computation); on a 700-frame trial (the check looks
    /// at the middle 200 frames, warm-started from the frames before them in the whole-trial
    /// IK, seeded in the check's own) the statistic agrees to 1e-6 m and the findings are the
    /// same. With other parameters than the nominal ones the check runs its own IK.
    #[test]
    fn ik_checked_reuses_the_fit_with_the_same_findings() {
        let opts = IkOptions::default();
        for frames in [150, 700] {
            let (model, trial) =
                moved_thigh_cluster(&["RTHI", "RTHA", "RTHP"], [0.08, -0.04, 0.0], frames);
            let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
            let p = model.nominal_params();
            let (run, findings) = crate::workflow::ik::ik_checked(&model, &p, &trial, &opts);
            let run = run.unwrap();
            let alone = check_trial(&model, &trial, &map);
            assert!(alone.iter().any(|f| f.kind == CheckKind::Offset));
            assert_eq!(
                format!("{findings:?}"),
                format!("{alone:?}"),
                "{frames} frames"
            );
            let reused = offsets_from_ik(&model, &p, &trial, &map, &opts, &run.fit).unwrap();
            let own = marker_offsets(&model, &p, &trial, &map, &opts, None);
            assert_eq!(reused.len(), own.len());
            for (a, b) in reused.iter().zip(&own) {
                // The check looks at the whole trial up to 200 frames, else the middle 200.
                assert_eq!(a.frames, frames.min(200));
                assert_eq!((a.marker, a.frames), (b.marker, b.frames));
                let (dm, ds) = ((a.mean - b.mean).norm(), (a.spread - b.spread).abs());
                if frames <= 200 {
                    assert_eq!((dm, ds), (0.0, 0.0), "{a:?} {b:?}");
                } else {
                    assert!(dm < 1e-6 && ds < 1e-6, "{a:?} {b:?}");
                }
            }
            // Another parameter vector: not the check's IK, so no reuse, same findings.
            let mut q = p.clone();
            q[0] += 0.01;
            let fit = crate::ik::trial_fit::solve_trial(&model, &q, &trial, &map, &opts).unwrap();
            assert!(offsets_from_ik(&model, &q, &trial, &map, &opts, &fit).is_none());
            let (_, other) = crate::workflow::ik::ik_checked(&model, &q, &trial, &opts);
            assert_eq!(format!("{other:?}"), format!("{alone:?}"));
        }
    }

    /// A model without markers has no offsets to report: the checks return instead of
    /// dividing the residuals into chunks of zero markers.
    #[test]
    fn a_model_without_markers_has_no_offsets() {
        let mut spec = crate::model::lower_limb::builtin("lower-limb-right").unwrap();
        spec.markers.clear();
        let model = Model::compile(&spec).unwrap();
        let labels = vec!["A".to_string(), "B".to_string()];
        let positions = (0..200)
            .flat_map(|i| {
                let t = i as f64 * 0.01;
                [Vector3::new(t, 1.0, 0.0), Vector3::new(t, 0.5, 0.1)]
            })
            .collect();
        let trial = Trial::new(labels.clone(), 100.0, 1, positions).unwrap();
        let (map, _) = MarkerMap::allowing_absent(&model, &labels);
        let findings = crate::checks::check_trial(&model, &trial, &map);
        assert!(findings
            .iter()
            .all(|f| f.kind != crate::checks::CheckKind::Offset));
    }
}
