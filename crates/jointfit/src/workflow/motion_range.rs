//! Joints a trial barely moves, held at their start (prior or landmark) values instead of
//! fitted: [`still_joints`] and [`hold_still_joints`].
//!
//! A hinge's axis is placed by the arcs its segment's markers trace about it. A marker at
//! distance `r` from the axis turned through `θ` bows out of the straight chord between its
//! end positions by the sagitta `s = r (1 − cos(θ/2)) ≈ r θ² / 8`. For a tracking marker
//! 0.1–0.2 m from the knee or ankle axis and `θ` = [`STILL_RANGE_DEG`] (15°), `s` is
//! 0.9–1.7 mm: no more than skin-marker noise. Below it the trial cannot place the axis; a
//! fit moves the joint only to follow noise and soft tissue, and its uncertainty analysis,
//! linearized at a noise-driven optimum, may still call the result determined. A ball joint
//! is judged by its largest rotation (its centre is placed by the spherical cap the markers
//! sweep, the same sagitta).
//!
//! The range of a joint is the largest 5–95 % range over the frames of its rotational
//! coordinates, from inverse kinematics of every trial at the start parameters (the
//! percentiles ignore a few badly tracked frames). A joint is held when its range is below
//! [`STILL_RANGE_DEG`] **and** the same joint of the other leg of a bilateral model (names
//! ending `_r` / `_l`) moves through at least [`MOVED_RANGE_DEG`]: the trial exercised that
//! joint on one side only (a one-sided functional trial, the other leg standing). Where both
//! legs move a joint little (the subtalar joint in gait, 10–20°), the trial carries what
//! information it has and the prior weighs it; nothing is held.

use serde::Serialize;

use super::WorkflowError;
use crate::calibrate::Problem;
use crate::model::{CoordKind, Model, ParamId};
use crate::trial::Trial;

/// A joint whose rotations stay below this (deg, 5–95 % range) is still (module docs).
pub(crate) const STILL_RANGE_DEG: f64 = 15.0;
/// The other leg's joint must move through at least this (deg) for a still joint to be held.
pub(crate) const MOVED_RANGE_DEG: f64 = 30.0;

/// A joint held at its start because the trials barely move it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldJoint {
    pub joint: String,
    /// Its range of motion in the trials (rad, largest 5–95 % range of its rotations).
    pub range: f64,
    /// The same joint of the other leg, and its range (rad).
    pub other_joint: String,
    pub other_range: f64,
    /// The free parameters held with it.
    pub parameters: Vec<String>,
}

/// The 5–95 % range of the finite values (0 when there are none).
fn central_range(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    at(0.95) - at(0.05)
}

/// Each moving joint's range of motion over the frames `qs` (rad): the largest 5–95 % range
/// of its rotational coordinates; joints without a rotational coordinate and the root joint
/// are left out.
pub(crate) fn joint_ranges(model: &Model, qs: &[Vec<f64>]) -> Vec<(String, f64)> {
    let mut out: Vec<(String, f64)> = Vec::new();
    for (c, coord) in model.coordinates().iter().enumerate() {
        let joint = &model.joints()[coord.joint];
        if joint.parent.is_none() || coord.kind != CoordKind::Rotational {
            continue;
        }
        let range = central_range(qs.iter().map(|q| q[c]).collect());
        match out.iter_mut().find(|(n, _)| *n == joint.name) {
            Some(entry) => entry.1 = entry.1.max(range),
            None => out.push((joint.name.clone(), range)),
        }
    }
    out
}

/// The name of the same joint on the other leg (`knee_r` ↔ `knee_l`).
fn other_side(joint: &str) -> Option<String> {
    if let Some(stem) = joint.strip_suffix("_r") {
        Some(format!("{stem}_l"))
    } else {
        joint.strip_suffix("_l").map(|stem| format!("{stem}_r"))
    }
}

/// The joints of `ranges` ([`joint_ranges`]) to hold (module docs), without their parameters.
pub(crate) fn still_joints(ranges: &[(String, f64)]) -> Vec<HeldJoint> {
    ranges
        .iter()
        .filter(|(_, range)| *range < STILL_RANGE_DEG.to_radians())
        .filter_map(|(joint, range)| {
            let other = other_side(joint)?;
            let (_, other_range) = ranges.iter().find(|(n, _)| *n == other)?;
            (*other_range >= MOVED_RANGE_DEG.to_radians()).then(|| HeldJoint {
                joint: joint.clone(),
                range: *range,
                other_joint: other,
                other_range: *other_range,
                parameters: Vec::new(),
            })
        })
        .collect()
}

/// Coordinates of trial `t`'s frame `f` known from another inverse kinematics, if any.
pub(crate) type Near<'a> = dyn Fn(usize, usize) -> Option<&'a [f64]> + Sync + 'a;

/// The parameters left to fit, the still joints held, and the starting coordinates.
pub(crate) type StillJoints = (Vec<ParamId>, Vec<HeldJoint>, Option<Vec<Vec<f64>>>);

/// Splits `free` into the parameters to fit and the still joints held with theirs: a
/// parameter is held when every joint that reads it is still. Inverse kinematics of `trials`
/// at `start` gives the ranges. Holding every free parameter is
/// [`WorkflowError::NothingIdentifiable`]. Also returns those coordinates
/// ([`Problem::initial_coords`] at `start`, `None` without a free parameter or a trial): the
/// calibration of the same model, start and trials starts from them instead of solving
/// them again. `near(t, f)`, where given, is another inverse kinematics of trial `t`'s frame
/// `f` at `start` that frame's solve starts from ([`Problem::initial_coords_near`]).
pub(crate) fn hold_still_joints(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    near: &Near,
) -> Result<StillJoints, WorkflowError> {
    if free.is_empty() || trials.is_empty() {
        return Ok((free.to_vec(), Vec::new(), None));
    }
    let prob = Problem::new(model, start.to_vec(), free, trials)?;
    let qs = prob.initial_coords_near(start, &|f| {
        let (t, frame) = prob.origin[f];
        near(t, frame)
    });
    let mut held = still_joints(&joint_ranges(model, &qs));
    if held.is_empty() {
        return Ok((free.to_vec(), held, Some(qs)));
    }
    let is_held = |id: &ParamId| {
        let uses = &model.parameters()[id.0].uses;
        !uses.is_empty()
            && uses
                .iter()
                .all(|u| held.iter().any(|h| model.joints()[u.joint].name == h.joint))
    };
    let (out, kept): (Vec<ParamId>, Vec<ParamId>) = free.iter().partition(|id| is_held(id));
    if kept.is_empty() {
        return Err(WorkflowError::NothingIdentifiable {
            groups: held_line(&held),
        });
    }
    for h in held.iter_mut() {
        h.parameters = out
            .iter()
            .map(|id| &model.parameters()[id.0])
            .filter(|p| {
                p.uses
                    .iter()
                    .any(|u| model.joints()[u.joint].name == h.joint)
            })
            .map(|p| p.name.clone())
            .collect();
    }
    held.retain(|h| !h.parameters.is_empty());
    Ok((kept, held, Some(qs)))
}

/// One line naming the held joints, their ranges, the other leg's and the thresholds.
pub(crate) fn held_line(held: &[HeldJoint]) -> String {
    let list = |f: &dyn Fn(&HeldJoint) -> String| held.iter().map(f).collect::<Vec<_>>().join(", ");
    format!(
        "held {} at the start values: the trial moved {} (5–95 % range), below {STILL_RANGE_DEG:.0}°, \
         while the other leg's moved {} (at least {MOVED_RANGE_DEG:.0}°)",
        list(&|h| h.joint.clone()),
        list(&|h| format!("{} {:.1}°", h.joint, h.range.to_degrees())),
        list(&|h| format!("{} {:.1}°", h.other_joint, h.other_range.to_degrees())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn central_range_of_a_sampled_sine() {
        // A sine sampled evenly over whole periods: its 5 % and 95 % quantiles are
        // ∓A sin(0.45 π).
        let a = 0.2;
        let v: Vec<f64> = (0..2000)
            .map(|i| a * (2.0 * std::f64::consts::PI * i as f64 / 1000.0).sin())
            .collect();
        let want = 2.0 * a * (0.45 * std::f64::consts::PI).sin();
        assert!((central_range(v) - want).abs() < 2e-3, "{want}");
        assert_eq!(central_range(vec![f64::NAN]), 0.0);
    }

    #[test]
    fn a_still_joint_is_held_only_when_the_other_leg_moves_it() {
        // Ranges given in degrees, passed in radians.
        let r = |v: &[(&str, f64)]| -> Vec<(String, f64)> {
            v.iter()
                .map(|(n, x)| (n.to_string(), x.to_radians()))
                .collect()
        };
        // One-sided knee trial: the left knee is held, the left ankle (other side 19°) not.
        let held = still_joints(&r(&[
            ("knee_r", 135.0),
            ("knee_l", 6.0),
            ("talocrural_r", 19.0),
            ("talocrural_l", 9.0),
        ]));
        assert_eq!(held.len(), 1);
        assert_eq!(
            (held[0].joint.as_str(), held[0].other_joint.as_str()),
            ("knee_l", "knee_r")
        );
        // Gait: both subtalar joints move a little; one leg's model: no other side.
        assert!(still_joints(&r(&[("subtalar_r", 20.0), ("subtalar_l", 10.0)])).is_empty());
        assert!(still_joints(&r(&[("knee", 3.0)])).is_empty());
    }
}
