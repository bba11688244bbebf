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
            let vals = [p.nominal, p.lower, p.upper];
            if vals.iter().any(|v| !v.is_finite()) || p.lower >= p.upper {
                return Err(ModelError::BadBounds {
                    name: p.name.clone(),
                    detail: format!("need finite lower < upper, got [{}, {}]", p.lower, p.upper),
                });
            }
            if let Some(sd) = p.prior_sd {
                if !(sd.is_finite() && sd > 0.0) {
                    return Err(ModelError::BadBounds {
                        name: p.name.clone(),
                        detail: format!("prior_sd must be finite and > 0, got {sd}"),
                    });
                }
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
