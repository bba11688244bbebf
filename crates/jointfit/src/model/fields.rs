//! Field validation of a model description before it is compiled: every number finite
//! and of a plausible size, every nominal value inside its bounds (and blamed on itself, not on
//! the bounds), every joint's axes independent.
//!
//! A rotation sequence whose consecutive axes are parallel (`["z", "z", "z"]`) is degenerate:
//! the two coordinates move the segment in the same way everywhere, so the Jacobian of the
//! markers with respect to the coordinates is rank-deficient at every configuration and
//! inverse kinematics cannot tell them apart. Proper Euler sequences such as z-x-z are fine
//! (consecutive axes differ), as are the three translations of a free joint. Two axes count
//! as parallel when the sine of their angle is below [`MIN_AXIS_SINE`].

use nalgebra::Vector3;

use super::spec::{AxisSpec, JointKindSpec, ModelSpec, ScalarSpec, Unit};
use super::ModelError;

/// Largest magnitude of a length in a model file (m): a leg model is a couple of metres long,
/// so anything beyond 100 m is a unit or typing error, not a subject.
pub(crate) const MAX_LENGTH_M: f64 = 100.0;
/// Largest magnitude of an angle in a model file (rad), about 16 turns.
pub(crate) const MAX_ANGLE_RAD: f64 = 100.0;
/// Consecutive rotation axes whose angle has a smaller sine are taken as parallel (0.06°).
pub(crate) const MIN_AXIS_SINE: f64 = 1e-3;

fn invalid(msg: String) -> ModelError {
    ModelError::Invalid(msg)
}

/// Checks the fields of `spec` that compilation takes for granted (see the module docs).
pub(crate) fn validate_fields(spec: &ModelSpec) -> Result<(), ModelError> {
    spec.parameters.iter().try_for_each(validate_parameter)?;
    spec.joints.iter().try_for_each(validate_joint)?;
    spec.markers.iter().try_for_each(validate_marker)
}

/// A parameter's bounds and nominal value: finite and of a plausible size for its unit.
fn validate_parameter(p: &super::spec::ParameterSpec) -> Result<(), ModelError> {
    let limit = match p.unit {
        Unit::Metre => MAX_LENGTH_M,
        Unit::Radian => MAX_ANGLE_RAD,
    };
    for (what, v) in [("lower", p.lower), ("upper", p.upper)] {
        if !v.is_finite() {
            return Err(ModelError::BadBounds {
                name: p.name.clone(),
                detail: format!("{what} bound {v} is not a finite number"),
            });
        }
        if v.abs() > limit {
            return Err(ModelError::BadBounds {
                name: p.name.clone(),
                detail: format!("{what} bound {v:e} is implausibly large (limit ±{limit})"),
            });
        }
    }
    if !p.nominal.is_finite() {
        return Err(invalid(format!(
            "parameter {:?}: nominal {} is not a finite number",
            p.name, p.nominal
        )));
    }
    if p.nominal.abs() > limit {
        return Err(invalid(format!(
            "parameter {:?}: nominal {:e} is implausibly large (limit ±{limit})",
            p.name, p.nominal
        )));
    }
    Ok(())
}

/// A joint's offsets (finite, plausible sizes), its coordinates' ranges and defaults
/// (finite) and its rotation axes (no two consecutive ones parallel).
fn validate_joint(s: &super::spec::JointSpec) -> Result<(), ModelError> {
    let joint = &s.name;
    for (side, off) in [
        ("parent_offset", &s.parent_offset),
        ("child_offset", &s.child_offset),
    ] {
        for (k, v) in off.scalars().iter().enumerate() {
            let value = match v {
                ScalarSpec::Fixed(x) => *x,
                ScalarSpec::Scaled { scale, .. } => *scale,
                ScalarSpec::Param(_) => 1.0,
            };
            let limit = if k < 3 { MAX_LENGTH_M } else { MAX_ANGLE_RAD };
            if !value.is_finite() || value.abs() > limit {
                return Err(invalid(format!(
                    "joint {joint:?}: {side}.{} = {value:e} is not a finite number of \
                     plausible size (limit ±{limit})",
                    super::spec::OFFSET_SCALARS[k]
                )));
            }
        }
    }
    for c in &s.coordinates {
        if let super::spec::CoordinateSpec::Full {
            name,
            range,
            default,
            ..
        } = c
        {
            let mut vals = vec![*default];
            if let Some(r) = range {
                vals.extend_from_slice(r);
            }
            if vals.iter().any(|v| !v.is_finite()) {
                return Err(invalid(format!(
                    "joint {joint:?}: coordinate {name:?} has a range or default that is \
                     not a finite number"
                )));
            }
        }
    }
    let rotations: &[AxisSpec] = match &s.kind {
        JointKindSpec::Free { rotation_axes } => rotation_axes,
        JointKindSpec::Gimbal { axes } => axes,
        JointKindSpec::Universal { axes } => axes,
        _ => &[],
    };
    let dirs: Vec<Option<Vector3<f64>>> = rotations.iter().map(axis_direction).collect();
    for i in 1..dirs.len() {
        if let (Some(a), Some(b)) = (dirs[i - 1], dirs[i]) {
            if a.cross(&b).norm() < MIN_AXIS_SINE {
                return Err(invalid(format!(
                    "joint {joint:?}: rotation axes {} and {} are parallel, so the two \
                     rotations cannot be told apart",
                    i,
                    i + 1
                )));
            }
        }
    }
    Ok(())
}

/// A marker's position (finite, plausible size) and weight (finite, non-negative).
fn validate_marker(m: &super::spec::MarkerSpec) -> Result<(), ModelError> {
    if m.position
        .iter()
        .any(|v| !v.is_finite() || v.abs() > MAX_LENGTH_M)
    {
        return Err(invalid(format!(
            "marker {:?}: position {:?} is not finite or implausibly large (limit ±{} m)",
            m.name, m.position, MAX_LENGTH_M
        )));
    }
    if !m.weight.is_finite() || m.weight < 0.0 {
        return Err(invalid(format!(
            "marker {:?}: weight {} must be finite and non-negative",
            m.name, m.weight
        )));
    }
    Ok(())
}

/// The unit direction of an axis, or `None` when it does not parse (compilation reports that).
fn axis_direction(axis: &AxisSpec) -> Option<Vector3<f64>> {
    match axis {
        AxisSpec::Named(s) => match s.trim().trim_start_matches(['+', '-']) {
            "x" => Some(Vector3::x()),
            "y" => Some(Vector3::y()),
            "z" => Some(Vector3::z()),
            _ => None,
        },
        AxisSpec::Vector(v) => {
            let v = Vector3::from(*v);
            let n = v.norm();
            (n.is_finite() && n > 1e-12).then(|| v / n)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::builtin;
    use crate::model::Model;

    fn leg() -> ModelSpec {
        builtin("lower-limb-right").unwrap()
    }

    #[test]
    fn builtin_models_pass() {
        for name in crate::model::lower_limb::BUILTIN_NAMES {
            validate_fields(&builtin(name).unwrap()).unwrap();
        }
    }

    #[test]
    fn nan_nominal_is_blamed_on_the_nominal() {
        let mut s = leg();
        s.parameters[0].nominal = f64::NAN;
        let e = Model::compile(&s).unwrap_err().to_string();
        assert!(e.contains("nominal NaN is not a finite number"), "{e}");
        assert!(!e.contains("lower <"), "{e}");
    }

    #[test]
    fn huge_nominal_is_rejected() {
        let mut s = leg();
        s.parameters[0].nominal = 1e300;
        let e = Model::compile(&s).unwrap_err().to_string();
        assert!(e.contains("nominal 1e300 is implausibly large"), "{e}");
        let mut s = leg();
        s.parameters[0].upper = 1e300;
        let e = Model::compile(&s).unwrap_err().to_string();
        assert!(e.contains("upper bound 1e300 is implausibly large"), "{e}");
    }

    #[test]
    fn parallel_rotation_axes_are_rejected_but_euler_sequences_pass() {
        let mut s = leg();
        let free = s
            .joints
            .iter()
            .position(|j| matches!(j.kind, JointKindSpec::Free { .. }))
            .expect("the leg has a free joint");
        let z = || AxisSpec::named("z");
        s.joints[free].kind = JointKindSpec::Free {
            rotation_axes: [z(), z(), z()],
        };
        let e = Model::compile(&s).unwrap_err().to_string();
        assert!(e.contains("are parallel"), "{e}");
        s.joints[free].kind = JointKindSpec::Free {
            rotation_axes: [
                z(),
                AxisSpec::Vector([1.0, 0.0, 1e-5]),
                AxisSpec::named("-x"),
            ],
        };
        let e = Model::compile(&s).unwrap_err().to_string();
        assert!(e.contains("rotation axes 2 and 3 are parallel"), "{e}");
        s.joints[free].kind = JointKindSpec::Free {
            rotation_axes: [z(), AxisSpec::named("x"), z()],
        };
        Model::compile(&s).unwrap();
    }

    #[test]
    fn marker_positions_must_be_finite() {
        let mut s = leg();
        s.markers[0].position[1] = f64::INFINITY;
        assert!(Model::compile(&s).is_err());
    }
}
