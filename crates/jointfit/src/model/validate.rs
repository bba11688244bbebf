//! Validation of a [`ModelSpec`]: names, duplicates, references, units, bounds, axes and
//! the tree shape. Every error names the offending item. The checks that need the joint
//! being compiled (coordinate counts, ranges, markers) run in [`super::compile`].

use std::collections::HashMap;

use nalgebra::Vector3;

use super::compiled::{JointKind, Source};
use super::spec::{AxisSpec, JointKindSpec, ModelSpec, ScalarSpec, Unit};
use super::ModelError;

/// Name lookups of a description under compilation (built by [`Compiler::new`] after the
/// name, duplicate and bounds checks).
pub(super) struct Compiler<'a> {
    pub(super) spec: &'a ModelSpec,
    pub(super) seg_index: HashMap<&'a str, usize>,
    pub(super) param_index: HashMap<&'a str, usize>,
}

impl<'a> Compiler<'a> {
    pub(super) fn new(spec: &'a ModelSpec) -> Result<Self, ModelError> {
        let mut seg_index = HashMap::new();
        for (i, s) in spec.segments.iter().enumerate() {
            check_name(&s.name, "segment")?;
            if s.name == "ground" {
                return Err(ModelError::Invalid(
                    "segment \"ground\" is implicit and must not be listed".into(),
                ));
            }
            if seg_index.insert(s.name.as_str(), i).is_some() {
                return Err(ModelError::Duplicate {
                    kind: "segment",
                    name: s.name.clone(),
                });
            }
        }
        let mut param_index = HashMap::new();
        for (i, p) in spec.parameters.iter().enumerate() {
            check_name(&p.name, "parameter")?;
            if param_index.insert(p.name.as_str(), i).is_some() {
                return Err(ModelError::Duplicate {
                    kind: "parameter",
                    name: p.name.clone(),
                });
            }
            check_prior_sd(p)?;
            let vals = [p.nominal, p.lower, p.upper];
            if vals.iter().any(|v| !v.is_finite()) || p.lower >= p.upper {
                return Err(ModelError::BadBounds {
                    name: p.name.clone(),
                    detail: format!("need finite lower < upper, got [{}, {}]", p.lower, p.upper),
                });
            }
            if p.prior_mean.is_some_and(|m| !m.is_finite()) {
                return Err(ModelError::BadBounds {
                    name: p.name.clone(),
                    detail: "prior_mean must be finite".into(),
                });
            }
            if p.nominal < p.lower || p.nominal > p.upper {
                return Err(ModelError::BadBounds {
                    name: p.name.clone(),
                    detail: format!(
                        "nominal {} lies outside [{}, {}]",
                        p.nominal, p.lower, p.upper
                    ),
                });
            }
        }
        Ok(Self {
            spec,
            seg_index,
            param_index,
        })
    }

    /// Orders joints so that every parent segment comes before its children.
    pub(super) fn topological_joints(&self) -> Result<Vec<usize>, ModelError> {
        let spec = self.spec;
        let mut joint_of_child: Vec<Option<usize>> = vec![None; spec.segments.len()];
        let mut joint_names = HashMap::new();
        for (j, js) in spec.joints.iter().enumerate() {
            check_name(&js.name, "joint")?;
            if joint_names.insert(js.name.as_str(), j).is_some() {
                return Err(ModelError::Duplicate {
                    kind: "joint",
                    name: js.name.clone(),
                });
            }
            let child = *self.seg_index.get(js.child.as_str()).ok_or_else(|| {
                ModelError::UnknownSegment {
                    segment: js.child.clone(),
                    used_by: format!("joint {:?} (child)", js.name),
                }
            })?;
            if js.parent != "ground" && !self.seg_index.contains_key(js.parent.as_str()) {
                return Err(ModelError::UnknownSegment {
                    segment: js.parent.clone(),
                    used_by: format!("joint {:?} (parent)", js.name),
                });
            }
            if js.parent == js.child {
                return Err(ModelError::Invalid(format!(
                    "joint {:?} connects segment {:?} to itself",
                    js.name, js.child
                )));
            }
            if let Some(other) = joint_of_child[child] {
                return Err(ModelError::Invalid(format!(
                    "segment {:?} is the child of two joints: {:?} and {:?}",
                    js.child, spec.joints[other].name, js.name
                )));
            }
            joint_of_child[child] = Some(j);
        }
        for (s, j) in joint_of_child.iter().enumerate() {
            if j.is_none() {
                return Err(ModelError::Invalid(format!(
                    "segment {:?} is not the child of any joint",
                    spec.segments[s].name
                )));
            }
        }
        // Depth-first from ground, children in spec order (looked up by parent name, so the
        // walk is linear in the number of joints).
        let mut children_of: HashMap<&str, Vec<usize>> = HashMap::new();
        for (j, js) in spec.joints.iter().enumerate() {
            children_of.entry(js.parent.as_str()).or_default().push(j);
        }
        let mut order = Vec::with_capacity(spec.joints.len());
        let mut stack = vec!["ground"];
        while let Some(parent) = stack.pop() {
            let children = children_of.remove(parent).unwrap_or_default();
            for &j in children.iter().rev() {
                stack.push(spec.joints[j].child.as_str());
            }
            order.extend(children);
        }
        if order.len() != spec.joints.len() {
            let reached: std::collections::HashSet<usize> = order.iter().copied().collect();
            let stray = (0..spec.joints.len())
                .find(|j| !reached.contains(j))
                .expect("some joint is unreached");
            return Err(ModelError::Invalid(format!(
                "joint {:?} is not connected to ground (a loop of segments?)",
                spec.joints[stray].name
            )));
        }
        Ok(order)
    }

    pub(super) fn scalar_source(
        &self,
        s: &ScalarSpec,
        sign: f64,
        unit: Unit,
        what: &str,
    ) -> Result<Source, ModelError> {
        match s {
            ScalarSpec::Fixed(v) => {
                if !v.is_finite() {
                    return Err(ModelError::Invalid(format!(
                        "{what}: value {v} is not finite"
                    )));
                }
                Ok(Source::Const(sign * v))
            }
            _ => {
                let (name, scale) = s.as_param().expect("non-fixed scalar is a parameter");
                let &index =
                    self.param_index
                        .get(name)
                        .ok_or_else(|| ModelError::UnknownParameter {
                            name: name.to_string(),
                            used_by: what.to_string(),
                        })?;
                if !scale.is_finite() || scale == 0.0 {
                    return Err(ModelError::Invalid(format!(
                        "{what}: scale of parameter {name:?} must be finite and non-zero"
                    )));
                }
                let declared = self.spec.parameters[index].unit;
                if declared != unit {
                    return Err(ModelError::UnitMismatch {
                        name: name.to_string(),
                        used_by: what.to_string(),
                        declared,
                        needed: unit,
                    });
                }
                Ok(Source::Param {
                    index,
                    scale: sign * scale,
                })
            }
        }
    }
}

/// A unit axis from `x`, `-y`, … or a non-zero vector (normalised).
pub(crate) fn parse_axis(axis: &AxisSpec, what: &str) -> Result<Vector3<f64>, ModelError> {
    match axis {
        AxisSpec::Named(s) => match s.trim() {
            "x" | "+x" => Ok(Vector3::x()),
            "y" | "+y" => Ok(Vector3::y()),
            "z" | "+z" => Ok(Vector3::z()),
            "-x" => Ok(-Vector3::x()),
            "-y" => Ok(-Vector3::y()),
            "-z" => Ok(-Vector3::z()),
            other => Err(ModelError::BadAxis {
                item: what.to_string(),
                axis: other.to_string(),
            }),
        },
        AxisSpec::Vector(v) => {
            let v = Vector3::from(*v);
            let n = v.norm();
            if !n.is_finite() || n < 1e-12 {
                return Err(ModelError::BadAxis {
                    item: what.to_string(),
                    axis: format!("{:?}", v.as_slice()),
                });
            }
            Ok(v / n)
        }
    }
}

/// The compiled joint kind with unit axes.
pub(super) fn joint_kind(spec: &JointKindSpec, joint: &str) -> Result<JointKind, ModelError> {
    let ax = |a: &AxisSpec, i: usize| parse_axis(a, &format!("joint {joint:?} axis {}", i + 1));
    Ok(match spec {
        JointKindSpec::Free { rotation_axes } => JointKind::Free {
            rotation_axes: [
                ax(&rotation_axes[0], 0)?,
                ax(&rotation_axes[1], 1)?,
                ax(&rotation_axes[2], 2)?,
            ],
        },
        JointKindSpec::Gimbal { axes } => JointKind::Gimbal {
            axes: [ax(&axes[0], 0)?, ax(&axes[1], 1)?, ax(&axes[2], 2)?],
        },
        JointKindSpec::Universal { axes } => JointKind::Universal {
            axes: [ax(&axes[0], 0)?, ax(&axes[1], 1)?],
        },
        JointKindSpec::Pin { axis } => JointKind::Pin { axis: ax(axis, 0)? },
        JointKindSpec::Slider { axis } => JointKind::Slider { axis: ax(axis, 0)? },
        JointKindSpec::Weld => JointKind::Weld,
        JointKindSpec::Custom { axes } => JointKind::Custom {
            axes: super::custom::compile_axes(axes, joint)?,
            dof: 0,
        },
    })
}

/// Names must be non-empty and carry no surrounding spaces.
pub(super) fn check_name(name: &str, kind: &'static str) -> Result<(), ModelError> {
    if name.trim().is_empty() || name.trim() != name {
        return Err(ModelError::Invalid(format!(
            "{kind} name {name:?} must be non-empty without surrounding spaces"
        )));
    }
    Ok(())
}

/// A parameter's prior SD must be finite, positive, and not below the spacing of doubles
/// across the parameter's values: `s ≥ ε · max(|nominal|, |lower|, |upper|, upper − lower)`
/// (ε = 2⁻⁵², [`f64::EPSILON`]). A smaller SD pins the parameter tighter than a double can
/// tell its values apart, and its weight σ²/s² in the objective overflows to infinity for
/// `s < σ·1e-154` (1e-200 mm would silently drop the prior from the fit).
fn check_prior_sd(p: &super::spec::ParameterSpec) -> Result<(), ModelError> {
    let Some(sd) = p.prior_sd else {
        return Ok(());
    };
    if !(sd.is_finite() && sd > 0.0) {
        return Err(ModelError::BadBounds {
            name: p.name.clone(),
            detail: format!("prior_sd must be finite and > 0, got {sd}"),
        });
    }
    let scale = [
        p.nominal.abs(),
        p.lower.abs(),
        p.upper.abs(),
        p.upper - p.lower,
    ]
    .into_iter()
    .filter(|v| v.is_finite())
    .fold(0.0, f64::max);
    let floor = f64::EPSILON * scale;
    if sd < floor {
        return Err(ModelError::BadBounds {
            name: p.name.clone(),
            detail: format!(
                "prior_sd {sd:e} is below what the fit can represent: at least {floor:.1e} \
                 (2^-52 of the parameter's values) is needed for the prior to weigh in"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod prior_sd_tests {
    use crate::model::lower_limb::builtin;
    use crate::model::{Model, ModelError};

    /// Prior SDs the fit cannot use are refused naming the parameter; 1e-200 mm is one of
    /// them (its weight σ²/s² at σ = 1 mm is infinite, which the objective would drop).
    #[test]
    fn prior_sds_the_fit_cannot_represent_are_refused() {
        assert!((1e-3f64 / 1e-203).powi(2).is_infinite());
        let spec = builtin("lower-limb-right").unwrap();
        let name = spec.parameters[0].name.clone();
        let value = spec.parameters[0]
            .nominal
            .abs()
            .max(spec.parameters[0].upper - spec.parameters[0].lower);
        let floor = f64::EPSILON * value;
        for (sd, ok) in [
            (1e-203, false),
            (0.0, false),
            (-1e-3, false),
            (f64::NAN, false),
            (f64::INFINITY, false),
            (floor * 0.5, false),
            (floor * 2.0, true),
            (5e-3, true),
        ] {
            let mut s = spec.clone();
            s.parameters[0].prior_sd = Some(sd);
            s.parameters[0].prior_mean = Some(s.parameters[0].nominal);
            match Model::compile(&s) {
                Ok(_) => assert!(ok, "{sd:e} accepted"),
                Err(e) => {
                    assert!(!ok, "{sd:e}: {e}");
                    assert!(matches!(e, ModelError::BadBounds { .. }), "{e}");
                    let msg = e.to_string();
                    assert!(msg.contains(&name) && msg.contains("prior_sd"), "{msg}");
                    assert_eq!(msg.lines().count(), 1);
                }
            }
        }
    }
}
