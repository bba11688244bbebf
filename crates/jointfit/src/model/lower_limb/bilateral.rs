//! Both legs and the pelvis in one model: 18 coordinates, 54 joint parameters.
//!
//! The bilateral model is the two one-sided models of [`super::lower_limb`] joined at the
//! pelvis ([`join_legs`]): one `ground_pelvis` joint and one `pelvis` segment (with its six
//! coordinates and its markers, taken from the right-side description), and each leg's
//! segments, joints, coordinates, parameters and parameter groups renamed with the side
//! suffix `_r` or `_l`, OpenSim's convention (`hip_flexion_r`, `knee_thigh_superior_l`,
//! segment `thigh_r`, joint `knee_l`, group `ankle_r`). Nothing else changes: every
//! parameter of the left leg reads its offset scalar with the same mirroring as the one-sided
//! left model (`docs/architecture.md` §6), so a leg of the bilateral model has, parameter for
//! parameter, the forward kinematics of the one-sided model of that side.
//!
//! Markers keep their names (they are the laboratory's labels and must differ between the
//! legs); markers of the pelvis come from the right-side description.

use super::{lower_limb, Side};
use crate::model::spec::{
    CoordinateSpec, JointKindSpec, JointSpec, MarkerSpec, ModelSpec, OffsetSpec, ScalarSpec,
};
use crate::model::ModelError;

/// The segment and the joint the two legs share.
pub const PELVIS_SEGMENT: &str = "pelvis";
/// The joint between the ground and the pelvis (6 coordinates).
pub(crate) const PELVIS_JOINT: &str = "ground_pelvis";

/// The built-in bilateral model `lower-limb`: the generic right and left legs joined.
pub(crate) fn bilateral() -> ModelSpec {
    let mut spec = join_legs(&lower_limb(Side::Right), &lower_limb(Side::Left))
        .expect("the built-in legs share their pelvis");
    spec.name = "lower-limb".into();
    spec.description = "Reinbolt et al. 2005 sample model, both legs and the pelvis: 18 \
                        coordinates, 54 joint parameters (27 per leg: hip 6, knee 9, ankle 12; \
                        names suffixed _r and _l); generic adult nominal geometry"
        .into();
    spec
}

/// Joins a right-leg and a left-leg description (each a pelvis with one leg, as
/// [`super::lower_limb`] or the landmark method builds them) into one bilateral description
/// (see the module docs). Name and description are the right one's.
pub fn join_legs(right: &ModelSpec, left: &ModelSpec) -> Result<ModelSpec, ModelError> {
    for spec in [right, left] {
        let root = spec.joints.iter().find(|j| j.name == PELVIS_JOINT);
        if !matches!(root, Some(j) if j.child == PELVIS_SEGMENT) {
            return Err(ModelError::Invalid(format!(
                "model {:?}: joining two legs needs a joint {PELVIS_JOINT:?} whose child is \
                 segment {PELVIS_SEGMENT:?}",
                spec.name
            )));
        }
    }
    let mut out = ModelSpec {
        name: right.name.clone(),
        description: right.description.clone(),
        segments: Vec::new(),
        joints: Vec::new(),
        parameters: Vec::new(),
        markers: Vec::new(),
        couplers: Vec::new(),
        lab_up: right.lab_up,
    };
    for (side, spec) in [(Side::Right, right), (Side::Left, left)] {
        let s = side.suffix();
        let seg = |n: &str| {
            if n == PELVIS_SEGMENT || n == "ground" {
                n.to_string()
            } else {
                format!("{n}{s}")
            }
        };
        for g in &spec.segments {
            if g.name != PELVIS_SEGMENT || side == Side::Right {
                let mut g = g.clone();
                g.name = seg(&g.name);
                out.segments.push(g);
            }
        }
        for j in &spec.joints {
            let is_root = j.name == PELVIS_JOINT;
            if is_root && side == Side::Left {
                continue;
            }
            let mut j: JointSpec = j.clone();
            if !is_root {
                j.name = format!("{}{s}", j.name);
                for c in &mut j.coordinates {
                    rename_coordinate(c, s);
                }
                if let JointKindSpec::Custom { axes } = &mut j.kind {
                    for a in axes {
                        if let Some(c) = &mut a.coordinate {
                            *c = format!("{c}{s}");
                        }
                    }
                }
            }
            j.parent = seg(&j.parent);
            j.child = seg(&j.child);
            rename_params(&mut j.parent_offset, s);
            rename_params(&mut j.child_offset, s);
            out.joints.push(j);
        }
        for p in &spec.parameters {
            let mut p = p.clone();
            p.name = format!("{}{s}", p.name);
            p.group = format!("{}{s}", p.group);
            out.parameters.push(p);
        }
        for m in &spec.markers {
            if m.segment == PELVIS_SEGMENT && side == Side::Left {
                continue;
            }
            out.markers.push(MarkerSpec {
                segment: seg(&m.segment),
                ..m.clone()
            });
        }
        for c in &spec.couplers {
            let mut c = c.clone();
            c.name = format!("{}{s}", c.name);
            c.dependent = format!("{}{s}", c.dependent);
            c.independent = format!("{}{s}", c.independent);
            out.couplers.push(c);
        }
    }
    Ok(out)
}

fn rename_coordinate(c: &mut CoordinateSpec, s: &str) {
    match c {
        CoordinateSpec::Name(n) | CoordinateSpec::Full { name: n, .. } => *n = format!("{n}{s}"),
    }
}

fn rename_params(o: &mut OffsetSpec, s: &str) {
    for x in o.scalars_mut() {
        if let Some((name, scale)) = x.as_param() {
            *x = ScalarSpec::param(&format!("{name}{s}"), scale);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{forward_kinematics, KinData, Want};
    use crate::model::Model;

    #[test]
    fn sizes_and_names() {
        let m = Model::compile(&bilateral()).unwrap();
        assert_eq!(m.parameters().len(), 54);
        assert_eq!(m.coordinates().len(), 18);
        assert!(m.coord_id("hip_flexion_r").is_some());
        assert!(m.coord_id("subtalar_inversion_l").is_some());
        assert!(m.coord_id("pelvis_tilt").is_some());
        assert_eq!(m.params_in_group("knee_l").len(), 9);
        assert_eq!(m.params_in_group("ankle_r").len(), 12);
        assert_eq!(m.markers().len(), 4 + 2 * 11);
    }

    /// Each leg of the bilateral model moves its markers exactly as the one-sided model of
    /// that side does, for the same parameters and coordinates.
    #[test]
    fn each_leg_matches_the_one_sided_model() {
        let both = Model::compile(&bilateral()).unwrap();
        let pb = both.nominal_params();
        let mut qb = both.default_coords();
        for (i, q) in qb.iter_mut().enumerate() {
            *q += 0.1 * ((i as f64) * 1.7).sin();
        }
        let mut kb = KinData::new(&both);
        forward_kinematics(&both, &pb, &qb, Want::Positions, &mut kb);
        for (side, s) in [(Side::Right, "_r"), (Side::Left, "_l")] {
            let one = Model::compile(&lower_limb(side)).unwrap();
            let p: Vec<f64> = one
                .parameters()
                .iter()
                .map(|p| pb[both.param_id(&format!("{}{s}", p.name)).unwrap().0])
                .collect();
            let q: Vec<f64> = one
                .coordinates()
                .iter()
                .map(|c| {
                    let n = if c.name.starts_with("pelvis_") {
                        c.name.clone()
                    } else {
                        format!("{}{s}", c.name)
                    };
                    qb[both.coord_id(&n).unwrap()]
                })
                .collect();
            let mut k = KinData::new(&one);
            forward_kinematics(&one, &p, &q, Want::Positions, &mut k);
            for (m, x) in one.markers().iter().zip(&k.markers) {
                let j = both
                    .markers()
                    .iter()
                    .position(|n| n.name == m.name)
                    .unwrap();
                assert!((x - kb.markers[j]).norm() < 1e-14, "{}", m.name);
            }
        }
    }
}
