//! The joint geometry of the export: offsets evaluated for the parameters, and the six
//! `SpatialTransform` axes of each joint kind (see the parent module for why they agree).

use jointfit::model::spec::{OffsetSpec, ScalarSpec};
use jointfit::model::{JointKind, Model};
use nalgebra::Vector3;

use super::OsimError;

/// Cross-product norm below which OpenSim calls two `CustomJoint` axes collinear.
const COLLINEAR_TOL: f64 = 1e-5;

/// An offset's translation (m) and X-Y-Z body-fixed angles (rad) for parameters `p`.
pub(super) struct Offset {
    pub translation: [f64; 3],
    pub orientation: [f64; 3],
}

pub(super) fn eval_offset(
    model: &Model,
    p: &[f64],
    offset: &OffsetSpec,
    joint: &str,
) -> Result<Offset, OsimError> {
    let mut v = [0.0; 6];
    for (out, s) in v.iter_mut().zip(offset.scalars()) {
        *out = match s {
            ScalarSpec::Fixed(x) => *x,
            _ => {
                let (name, scale) = s.as_param().expect("non-fixed scalar is a parameter");
                let id = model
                    .param_id(name)
                    .ok_or_else(|| OsimError::UnknownParameter {
                        joint: joint.to_string(),
                        param: name.to_string(),
                    })?;
                scale * p[id.0]
            }
        };
    }
    Ok(Offset {
        translation: [v[0], v[1], v[2]],
        orientation: [v[3], v[4], v[5]],
    })
}

/// A transform axis: unit direction and the coordinate driving it (`None`: constant 0).
pub(super) type Axis<'a> = (Vector3<f64>, Option<&'a str>);

/// The six transform axes (rotation1..3, translation1..3) with the coordinate driving each.
pub(super) fn spatial_axes<'a>(
    kind: &JointKind,
    coords: &[&'a str],
    joint: &str,
) -> Result<[Axis<'a>; 6], OsimError> {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let fixed_xyz = [(x, None), (y, None), (z, None)];
    let one = |a: Vector3<f64>, c: &'a str| {
        let (u, v) = complete_basis(&a);
        [(a, Some(c)), (u, None), (v, None)]
    };
    let (rot, trans): ([Axis; 3], _) = match kind {
        JointKind::Free { rotation_axes: a } => (
            [
                (a[0], Some(coords[3])),
                (a[1], Some(coords[4])),
                (a[2], Some(coords[5])),
            ],
            [
                (x, Some(coords[0])),
                (y, Some(coords[1])),
                (z, Some(coords[2])),
            ],
        ),
        JointKind::Gimbal { axes: a } => (
            [
                (a[0], Some(coords[0])),
                (a[1], Some(coords[1])),
                (a[2], Some(coords[2])),
            ],
            fixed_xyz,
        ),
        JointKind::Universal { axes: a } => {
            let n = a[0].cross(&a[1]);
            if n.norm() < COLLINEAR_TOL {
                return Err(OsimError::ParallelAxes {
                    joint: joint.to_string(),
                    what: "rotation",
                    first: 1,
                    second: 2,
                });
            }
            (
                [
                    (a[0], Some(coords[0])),
                    (a[1], Some(coords[1])),
                    (n.normalize(), None),
                ],
                fixed_xyz,
            )
        }
        JointKind::Pin { axis } => (one(*axis, coords[0]), fixed_xyz),
        JointKind::Slider { axis } => (fixed_xyz, one(*axis, coords[0])),
        JointKind::Weld => unreachable!("a weld joint is a WeldJoint"),
        JointKind::Custom { .. } => {
            return Err(OsimError::CustomJoint {
                joint: joint.to_string(),
            })
        }
    };
    for (what, set) in [("rotation", &rot), ("translation", &trans)] {
        for i in 0..3 {
            for k in i + 1..3 {
                if set[i].0.cross(&set[k].0).norm() < COLLINEAR_TOL {
                    return Err(OsimError::ParallelAxes {
                        joint: joint.to_string(),
                        what,
                        first: i + 1,
                        second: k + 1,
                    });
                }
            }
        }
    }
    Ok([rot[0], rot[1], rot[2], trans[0], trans[1], trans[2]])
}

/// Two unit vectors that make `a` (a unit vector) part of a right-handed orthonormal basis.
pub(super) fn complete_basis(a: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    // The principal axis least aligned with `a` is far from parallel to it.
    let k = a.iamin();
    let e = Vector3::ith(k, 1.0);
    let u = a.cross(&e).normalize();
    let v = a.cross(&u);
    (u, v)
}
