//! Joint parameters of a read `.osim`: free the offset frames of named joints, and write
//! fitted values back into the user's file.
//!
//! [`parameterize`] turns the six scalars of a joint's parent and/or child offset frame into
//! parameters named `JOINT.parent.tx` … `JOINT.child.rz`, nominal at the file's value, with
//! default bounds of ±[`TRANSLATION_BOUND`] m and ±[`ORIENTATION_BOUND`] rad around it.
//! [`fitted_text`] writes a parameter vector back with [`super::write_back`]: only the
//! `<translation>`/`<orientation>` elements whose values changed are edited.

use jointfit::model::spec::{ModelSpec, ParameterSpec, ScalarSpec, Unit, OFFSET_SCALARS};

use super::{OsimModel, Side, WriteBackError};

/// Default half-width of a translation parameter's bounds (m).
pub const TRANSLATION_BOUND: f64 = 0.03;
/// Default half-width of an orientation parameter's bounds (rad, about 11.5°).
pub const ORIENTATION_BOUND: f64 = 0.2;

/// One selection: `JOINT` (both frames, all six scalars each), or
/// `JOINT.parent|child[.translation|.orientation]`.
fn parse_selection(sel: &str) -> Result<(String, Vec<Side>, Vec<usize>), String> {
    let mut parts = sel.trim().split('.');
    let joint = parts.next().unwrap_or("").to_string();
    let sides = match parts.next() {
        None => vec![Side::Parent, Side::Child],
        Some("parent") => vec![Side::Parent],
        Some("child") => vec![Side::Child],
        Some(o) => return Err(format!("{sel:?}: {o:?} is not parent or child")),
    };
    let scalars = match parts.next() {
        None => (0..6).collect(),
        Some("translation") => vec![0, 1, 2],
        Some("orientation") => vec![3, 4, 5],
        Some(o) => return Err(format!("{sel:?}: {o:?} is not translation or orientation")),
    };
    if parts.next().is_some() || joint.is_empty() {
        return Err(format!(
            "{sel:?}: expected JOINT, JOINT.parent|child or JOINT.parent|child.translation|orientation"
        ));
    }
    Ok((joint, sides, scalars))
}

/// The model with the selected offset scalars as parameters (module docs). Every selection
/// must name a joint of the file whose frame is a `PhysicalOffsetFrame`.
pub fn parameterize(model: &OsimModel, selections: &[&str]) -> Result<ModelSpec, String> {
    let mut spec = model.spec.clone();
    for sel in selections {
        let (joint, sides, scalars) = parse_selection(sel)?;
        let j = spec
            .joints
            .iter()
            .position(|js| js.name == joint)
            .ok_or_else(|| format!("{sel:?}: the model has no joint {joint:?}"))?;
        for side in sides {
            let site = model.site(&joint, side).ok_or_else(|| {
                format!(
                    "{sel:?}: joint {joint:?} has no {} offset frame to personalize",
                    side_word(side)
                )
            })?;
            for &k in &scalars {
                let name = format!("{joint}.{}.{}", side_word(side), OFFSET_SCALARS[k]);
                if spec.parameters.iter().any(|p| p.name == name) {
                    continue;
                }
                let (unit, half) = if k < 3 {
                    (Unit::Metre, TRANSLATION_BOUND)
                } else {
                    (Unit::Radian, ORIENTATION_BOUND)
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
                    prior_sd: None,
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
