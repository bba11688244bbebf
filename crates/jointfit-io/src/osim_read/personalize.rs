//! Joint parameters of a read `.osim`: free the offset frames of named joints, and write
//! fitted values back into the user's file.
//!
//! [`parameterize`] turns scalars of a joint's parent and/or child offset frame into
//! parameters named `JOINT.parent.tx` … `JOINT.child.rz` (group `JOINT`), nominal at the
//! file's value, with bounds of ±[`TRANSLATION_BOUND`] m and ±[`ORIENTATION_BOUND`] rad around
//! it and a Gaussian prior centred on the file's value with SD [`TRANSLATION_PRIOR_SD`] or
//! [`ORIENTATION_PRIOR_SD`] (see `docs/priors.md`, "OpenSim offset frames": the file's
//! value is a scaled generic model's, whose joint centres and axes carry errors of the order of
//! the landmark methods': about 8–12 mm per axis for hip centres, 5° for knee axes).
//! [`fitted_text`] writes a parameter vector back with [`super::write_back`]: only the
//! `<translation>`/`<orientation>` elements whose values changed are edited.
//!
//! Selection syntax (`--joints` / `--params` of `jointfit calibrate`), each item one of
//!
//! ```text
//! JOINT                                   both offset frames, all 6 scalars each (12)
//! JOINT.parent | JOINT.child              one frame, 6 scalars
//! JOINT.SIDE.translation | .orientation   one frame, 3 scalars
//! JOINT.SIDE.translation.x | .y | .z      one scalar (also JOINT.SIDE.orientation.x …)
//! ```

use jointfit::model::spec::{ModelSpec, ParameterSpec, ScalarSpec, Unit, OFFSET_SCALARS};
use thiserror::Error;

use super::{OsimModel, Side, WriteBackError};

/// Default half-width of a translation parameter's bounds (m): three prior SDs.
pub const TRANSLATION_BOUND: f64 = 0.03;
/// Default half-width of an orientation parameter's bounds (rad, 15°: three prior SDs).
pub const ORIENTATION_BOUND: f64 = 15.0 * std::f64::consts::PI / 180.0;
/// Default prior SD of an offset translation, per axis (m).
pub const TRANSLATION_PRIOR_SD: f64 = 0.010;
/// Default prior SD of an offset orientation angle (rad, 5°).
pub const ORIENTATION_PRIOR_SD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// A selection the model cannot satisfy.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum SelectionError {
    #[error("{item:?}: {reason}")]
    Syntax { item: String, reason: String },
    #[error("{item:?}: the model has no joint {joint:?}; its joints: {available}")]
    NoJoint {
        item: String,
        joint: String,
        available: String,
    },
    #[error("{item:?}: joint {joint:?} has no {side} offset frame to personalize")]
    NoFrame {
        item: String,
        joint: String,
        side: &'static str,
    },
    #[error("nothing selected: name joints (e.g. --joints hip_r,knee_r) or offset-frame parameters; the model's joints: {available}")]
    Empty { available: String },
}

/// The scalars (indices into [`OFFSET_SCALARS`]) and sides one selection item names.
fn parse_item(item: &str) -> Result<(String, Vec<Side>, Vec<usize>), SelectionError> {
    let syntax = |reason: String| SelectionError::Syntax {
        item: item.to_string(),
        reason,
    };
    let mut parts = item.trim().split('.');
    let joint = parts.next().unwrap_or("").to_string();
    if joint.is_empty() {
        return Err(syntax("no joint name".into()));
    }
    let sides = match parts.next() {
        None => vec![Side::Parent, Side::Child],
        Some("parent") => vec![Side::Parent],
        Some("child") => vec![Side::Child],
        Some(o) => return Err(syntax(format!("{o:?} is not parent or child"))),
    };
    let base = match parts.next() {
        None => None,
        Some("translation") => Some(0),
        Some("orientation") => Some(3),
        Some(o) => return Err(syntax(format!("{o:?} is not translation or orientation"))),
    };
    let scalars = match (base, parts.next()) {
        (None, _) => (0..6).collect(),
        (Some(b), None) => vec![b, b + 1, b + 2],
        (Some(b), Some(axis)) => match axis {
            "x" => vec![b],
            "y" => vec![b + 1],
            "z" => vec![b + 2],
            o => return Err(syntax(format!("{o:?} is not x, y or z"))),
        },
    };
    if parts.next().is_some() {
        return Err(syntax(
            "expected JOINT[.parent|.child[.translation|.orientation[.x|.y|.z]]]".into(),
        ));
    }
    Ok((joint, sides, scalars))
}

/// The model's joints with at least one offset frame, comma-separated (for messages).
pub fn available_joints(model: &OsimModel) -> String {
    let mut names: Vec<&str> = Vec::new();
    for j in &model.spec.joints {
        if model.offsets.iter().any(|s| s.joint == j.name) && !names.contains(&j.name.as_str()) {
            names.push(&j.name);
        }
    }
    names.join(", ")
}

/// The model with the selected offset scalars as parameters (module docs). Every selection
/// must name a joint of the file whose frame is a `PhysicalOffsetFrame`. Parameters come
/// out in the order of the selection, parent before child, each frame tx … rz.
pub fn parameterize(model: &OsimModel, selections: &[&str]) -> Result<ModelSpec, SelectionError> {
    if selections.iter().all(|s| s.trim().is_empty()) {
        return Err(SelectionError::Empty {
            available: available_joints(model),
        });
    }
    let mut spec = model.spec.clone();
    for item in selections.iter().filter(|s| !s.trim().is_empty()) {
        let (joint, sides, scalars) = parse_item(item)?;
        let j = spec
            .joints
            .iter()
            .position(|js| js.name == joint)
            .ok_or_else(|| SelectionError::NoJoint {
                item: item.to_string(),
                joint: joint.clone(),
                available: available_joints(model),
            })?;
        for side in sides {
            let site = model
                .site(&joint, side)
                .ok_or_else(|| SelectionError::NoFrame {
                    item: item.to_string(),
                    joint: joint.clone(),
                    side: side_word(side),
                })?;
            for &k in &scalars {
                let name = format!("{joint}.{}.{}", side_word(side), OFFSET_SCALARS[k]);
                if spec.parameters.iter().any(|p| p.name == name) {
                    continue;
                }
                let (unit, half, sd) = if k < 3 {
                    (Unit::Metre, TRANSLATION_BOUND, TRANSLATION_PRIOR_SD)
                } else {
                    (Unit::Radian, ORIENTATION_BOUND, ORIENTATION_PRIOR_SD)
                };
                let v = site.value[k];
                spec.parameters.push(ParameterSpec {
                    name: name.clone(),
                    group: joint.clone(),
                    unit,
                    nominal: v,
                    lower: v - half,
                    upper: v + half,
                    description: format!("{} frame {:?} of {joint}", side_word(side), site.frame),
                    prior_sd: Some(sd),
                    prior_mean: None,
                });
                let offset = match side {
                    Side::Parent => &mut spec.joints[j].parent_offset,
                    Side::Child => &mut spec.joints[j].child_offset,
                };
                *offset.scalars_mut()[k] = ScalarSpec::param(&name, 1.0);
            }
        }
    }
    Ok(spec)
}

fn side_word(side: Side) -> &'static str {
    match side {
        Side::Parent => "parent",
        Side::Child => "child",
    }
}

/// The user's file with the parameter values `p` (in `spec.parameters` order, as made by
/// [`parameterize`]) written into their offset frames; everything else byte for byte.
pub fn fitted_text(
    model: &OsimModel,
    spec: &ModelSpec,
    p: &[f64],
) -> Result<String, WriteBackError> {
    let mut offsets: Vec<(&str, Side, [f64; 6])> = Vec::new();
    for (ps, &v) in spec.parameters.iter().zip(p) {
        let mut parts = ps.name.rsplitn(3, '.');
        let (Some(scalar), Some(side), Some(joint)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let side = match side {
            "parent" => Side::Parent,
            "child" => Side::Child,
            _ => continue,
        };
        let Some(k) = OFFSET_SCALARS.iter().position(|s| *s == scalar) else {
            continue;
        };
        let Some(site) = model.site(joint, side) else {
            continue;
        };
        let entry = match offsets
            .iter()
            .position(|(j, s, _)| *j == joint && *s == side)
        {
            Some(i) => i,
            None => {
                offsets.push((site.joint.as_str(), side, site.value));
                offsets.len() - 1
            }
        };
        offsets[entry].2[k] = v;
    }
    super::write_back(model, &offsets, &[])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_syntax() {
        let (j, s, k) = parse_item("hip_r").unwrap();
        assert_eq!(
            (j.as_str(), s.len(), k),
            ("hip_r", 2, vec![0, 1, 2, 3, 4, 5])
        );
        let (_, s, k) = parse_item("knee_r.child").unwrap();
        assert_eq!((s, k.len()), (vec![Side::Child], 6));
        let (_, s, k) = parse_item("knee_r.parent.orientation").unwrap();
        assert_eq!((s, k), (vec![Side::Parent], vec![3, 4, 5]));
        let (_, _, k) = parse_item("knee_r.child.translation.y").unwrap();
        assert_eq!(k, vec![1]);
        let (_, _, k) = parse_item("knee_r.child.orientation.z").unwrap();
        assert_eq!(k, vec![5]);
        for bad in [
            "",
            ".parent",
            "knee_r.middle",
            "knee_r.child.scale",
            "knee_r.child.translation.w",
            "knee_r.child.translation.x.y",
        ] {
            assert!(parse_item(bad).is_err(), "{bad}");
        }
    }
}
