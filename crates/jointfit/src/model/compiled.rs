//! The compiled, immutable, index-based model.
//!
//! Compilation flattens every joint into a chain of *elementary steps*, each a rotation
//! about, or a translation along, one axis of the current frame by one scalar. A scalar is a
//! constant, `scale · q[i]` or `scale · p[k]`. Consecutive constant steps are merged into one
//! fixed rigid transform. The pose of a segment is the pose of its parent times its steps:
//!
//! `world_from_child = world_from_parent · T(t_p) Rx Ry Rz · motion(q) · Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t_c)`.
//!
//! Because parameters and coordinates enter the same way, ∂/∂q and ∂/∂p are computed by the
//! same geometric rule (see [`crate::kinematics`]).

use std::collections::HashMap;

use nalgebra::{Matrix3, Unit as UnitVec, Vector3};

use super::spec::{
    AxisSpec, CoordinateSpec, JointKindSpec, ModelSpec, OffsetSpec, ScalarSpec, Unit,
    OFFSET_SCALARS,
};
use super::ModelError;
use crate::kinematics::Pose;

/// Index of a segment in [`Model::segments`] (topological order: parents first).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SegmentId(pub usize);
/// Index of a joint in [`Model::joints`]; joint `i` attaches segment `i` to its parent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct JointId(pub usize);
/// Index of a parameter in the parameter vector `p`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParamId(pub usize);
/// Index of a coordinate in the coordinate vector `q`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CoordId(pub usize);

#[derive(Debug, Clone)]
pub struct Segment {
    pub name: String,
    /// `None` for a segment attached to ground.
    pub parent: Option<SegmentId>,
    pub joint: JointId,
}

/// The kind of motion a joint allows, with unit axes.
#[derive(Debug, Clone, PartialEq)]
pub enum JointKind {
    Free { rotation_axes: [Vector3<f64>; 3] },
    Gimbal { axes: [Vector3<f64>; 3] },
    Universal { axes: [Vector3<f64>; 2] },
    Pin { axis: Vector3<f64> },
    Slider { axis: Vector3<f64> },
    Weld,
}

impl JointKind {
    pub fn dof(&self) -> usize {
        match self {
            JointKind::Free { .. } => 6,
            JointKind::Gimbal { .. } => 3,
            JointKind::Universal { .. } => 2,
            JointKind::Pin { .. } | JointKind::Slider { .. } => 1,
            JointKind::Weld => 0,
        }
    }
    pub fn type_name(&self) -> &'static str {
        match self {
            JointKind::Free { .. } => "free",
            JointKind::Gimbal { .. } => "gimbal",
            JointKind::Universal { .. } => "universal",
            JointKind::Pin { .. } => "pin",
            JointKind::Slider { .. } => "slider",
            JointKind::Weld => "weld",
        }
    }
    /// The elementary motions in order: (is_rotation, unit axis).
    fn motions(&self) -> Vec<(bool, Vector3<f64>)> {
        match self {
            JointKind::Free { rotation_axes } => [Vector3::x(), Vector3::y(), Vector3::z()]
                .into_iter()
                .map(|a| (false, a))
                .chain(rotation_axes.iter().map(|a| (true, *a)))
                .collect(),
            JointKind::Gimbal { axes } => axes.iter().map(|a| (true, *a)).collect(),
            JointKind::Universal { axes } => axes.iter().map(|a| (true, *a)).collect(),
            JointKind::Pin { axis } => vec![(true, *axis)],
            JointKind::Slider { axis } => vec![(false, *axis)],
            JointKind::Weld => vec![],
        }
    }
}

#[derive(Debug, Clone)]
pub struct Joint {
    pub name: String,
    pub parent: Option<SegmentId>,
    pub child: SegmentId,
    pub kind: JointKind,
    /// Coordinates of this joint: `first..first + kind.dof()`.
    pub first_coord: usize,
}

/// Whether a coordinate is an angle (rad) or a length (m).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoordKind {
    Rotational,
    Translational,
}

#[derive(Debug, Clone)]
pub struct Coordinate {
    pub name: String,
    pub joint: JointId,
    pub kind: CoordKind,
    /// Lower and upper limit (rad or m); informative, IK does not clamp.
    pub range: [f64; 2],
    pub default: f64,
}

/// Where a parameter sits: which joint, which offset, which scalar.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamUse {
    pub joint: JointId,
    /// The segment whose offset frame the scalar belongs to (`None`: ground).
    pub segment: Option<SegmentId>,
    /// True for the parent offset, false for the child offset.
    pub in_parent_offset: bool,
    /// `"tx"`, …, `"rz"`.
    pub scalar: &'static str,
    pub scale: f64,
}

#[derive(Debug, Clone)]
pub struct Parameter {
    pub name: String,
    pub group: String,
    pub unit: Unit,
    pub nominal: f64,
    pub lower: f64,
    pub upper: f64,
    pub description: String,
    /// Prior standard deviation (m or rad), if the parameter has a prior.
    pub prior_sd: Option<f64>,
    /// Prior mean (m or rad): the spec's `prior_mean`, else its nominal value.
    pub prior_mean: f64,
    /// Every offset scalar that reads this parameter (at least one).
    pub uses: Vec<ParamUse>,
}

#[derive(Debug, Clone)]
pub struct Marker {
    pub name: String,
    pub segment: SegmentId,
    /// Position in the segment frame (m).
    pub local: Vector3<f64>,
    pub weight: f64,
}

/// The elementary motion of one step of a segment's chain.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Motion {
    RotX,
    RotY,
    RotZ,
    Rot(UnitVec<Vector3<f64>>),
    TransX,
    TransY,
    TransZ,
    Trans(UnitVec<Vector3<f64>>),
    Fixed(Pose),
}

impl Motion {
    pub(crate) fn is_rotation(&self) -> bool {
        matches!(
            self,
            Motion::RotX | Motion::RotY | Motion::RotZ | Motion::Rot(_)
        )
    }
}

/// Where an elementary step takes its scalar from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Source {
    Const(f64),
    Coord { index: usize, scale: f64 },
    Param { index: usize, scale: f64 },
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Step {
    pub motion: Motion,
    pub source: Source,
}

/// A validated, immutable, index-based kinematic model (`Send + Sync`).
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub description: String,
    /// Segments in topological order (every parent before its children).
    pub segments: Vec<Segment>,
    /// `joints[i]` attaches `segments[i]` to its parent.
    pub joints: Vec<Joint>,
    pub coordinates: Vec<Coordinate>,
    pub parameters: Vec<Parameter>,
    pub markers: Vec<Marker>,
    /// Elementary steps of all segments, segment by segment.
    pub(crate) steps: Vec<Step>,
    /// How forward kinematics walks the steps (blocks, Jacobian columns).
    pub(crate) plan: super::plan::Plan,
    /// The description this model was compiled from.
    spec: ModelSpec,
}

impl Model {
    pub fn n_q(&self) -> usize {
        self.coordinates.len()
    }
    pub fn n_p(&self) -> usize {
        self.parameters.len()
    }
    pub fn n_markers(&self) -> usize {
        self.markers.len()
    }
    /// The description this model was compiled from.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }
    /// Nominal parameter vector.
    pub fn nominal_params(&self) -> Vec<f64> {
        self.parameters.iter().map(|p| p.nominal).collect()
    }
    /// Default coordinate vector.
    pub fn default_coords(&self) -> Vec<f64> {
        self.coordinates.iter().map(|c| c.default).collect()
    }
    pub fn segment_id(&self, name: &str) -> Option<SegmentId> {
        self.segments
            .iter()
            .position(|s| s.name == name)
            .map(SegmentId)
    }
    pub fn param_id(&self, name: &str) -> Option<ParamId> {
        self.parameters
            .iter()
            .position(|s| s.name == name)
            .map(ParamId)
    }
    pub fn coord_id(&self, name: &str) -> Option<CoordId> {
        self.coordinates
            .iter()
            .position(|s| s.name == name)
            .map(CoordId)
    }
    pub fn marker_index(&self, name: &str) -> Option<usize> {
        self.markers.iter().position(|m| m.name == name)
    }
    /// Ids of the parameters in the given group, in parameter order.
    pub fn params_in_group(&self, group: &str) -> Vec<ParamId> {
        (0..self.n_p())
            .filter(|&i| self.parameters[i].group == group)
            .map(ParamId)
            .collect()
    }
    /// Distinct group names in order of first appearance.
    pub fn groups(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for p in &self.parameters {
            if !out.contains(&p.group) {
                out.push(p.group.clone());
            }
        }
        out
    }

    /// A copy of the description with the given parameter values written in as nominal values
    /// (bounds unchanged). Used to save a fitted model. A parameter with a prior keeps its
    /// prior mean (written out as `prior_mean` when it was the nominal value).
    pub fn spec_with_nominal(&self, p: &[f64]) -> ModelSpec {
        let mut spec = self.spec.clone();
        for (ps, v) in spec.parameters.iter_mut().zip(p) {
            if ps.prior_sd.is_some() && ps.prior_mean.is_none() {
                ps.prior_mean = Some(ps.nominal);
            }
            ps.nominal = *v;
        }
        spec
    }

    /// Validates and compiles a description. Every error names the offending item.
    pub fn compile(spec: &ModelSpec) -> Result<Model, ModelError> {
        Compiler::new(spec)?.run()
    }
}

fn parse_axis(axis: &AxisSpec, what: &str) -> Result<Vector3<f64>, ModelError> {
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

fn joint_kind(spec: &JointKindSpec, joint: &str) -> Result<JointKind, ModelError> {
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
    })
}

/// The elementary motion for a unit axis; principal axes get the fast specialised form and a
/// negative principal axis flips the sign of the scalar instead.
fn motion_for(rotation: bool, axis: &Vector3<f64>) -> (Motion, f64) {
    let principal = [
        (Vector3::x(), Motion::RotX, Motion::TransX),
        (Vector3::y(), Motion::RotY, Motion::TransY),
        (Vector3::z(), Motion::RotZ, Motion::TransZ),
    ];
    for (a, r, t) in principal {
        for sign in [1.0f64, -1.0] {
            if (axis - a * sign).norm() < 1e-15 {
                return (if rotation { r } else { t }, sign);
            }
        }
    }
    let u = UnitVec::new_normalize(*axis);
    (
        if rotation {
            Motion::Rot(u)
        } else {
            Motion::Trans(u)
        },
        1.0,
    )
}

fn offset_motion(k: usize) -> Motion {
    [
        Motion::TransX,
        Motion::TransY,
        Motion::TransZ,
        Motion::RotX,
        Motion::RotY,
        Motion::RotZ,
    ][k]
        .clone()
}

struct Compiler<'a> {
    spec: &'a ModelSpec,
    seg_index: HashMap<&'a str, usize>,
    param_index: HashMap<&'a str, usize>,
}

impl<'a> Compiler<'a> {
    fn new(spec: &'a ModelSpec) -> Result<Self, ModelError> {
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
    fn topological_joints(&self) -> Result<Vec<usize>, ModelError> {
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
        // Depth-first from ground, children in spec order.
        let mut order = Vec::with_capacity(spec.joints.len());
        let mut stack = vec!["ground"];
        while let Some(parent) = stack.pop() {
            let children: Vec<usize> = (0..spec.joints.len())
                .filter(|&j| spec.joints[j].parent == parent)
                .collect();
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

    fn scalar_source(
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

    fn run(self) -> Result<Model, ModelError> {
        let spec = self.spec;
        let order = self.topological_joints()?;
        // Segment i of the model is the child of the i-th joint in topological order.
        let new_seg_of: HashMap<&str, usize> = order
            .iter()
            .enumerate()
            .map(|(i, &j)| (spec.joints[j].child.as_str(), i))
            .collect();
        let seg_id = |name: &str| -> Option<SegmentId> {
            if name == "ground" {
                None
            } else {
                Some(SegmentId(new_seg_of[name]))
            }
        };

        let mut segments = Vec::new();
        let mut joints = Vec::new();
        let mut coordinates: Vec<Coordinate> = Vec::new();
        let mut steps: Vec<Step> = Vec::new();
        let mut step_ranges = Vec::new();
        let mut uses: Vec<Vec<ParamUse>> = vec![Vec::new(); spec.parameters.len()];
        let mut coord_names = HashMap::new();

        for (ji, &j) in order.iter().enumerate() {
            let js = &spec.joints[j];
            let kind = joint_kind(&js.kind, &js.name)?;
            if js.coordinates.len() != kind.dof() {
                return Err(ModelError::Invalid(format!(
                    "joint {:?} is {} with {} degrees of freedom but lists {} coordinates",
                    js.name,
                    kind.type_name(),
                    kind.dof(),
                    js.coordinates.len()
                )));
            }
            let parent = seg_id(&js.parent);
            let child = SegmentId(ji);
            segments.push(super::compiled::Segment {
                name: js.child.clone(),
                parent,
                joint: JointId(ji),
            });
            let first_coord = coordinates.len();
            let start = steps.len();

            // Parent offset: T(t) Rx Ry Rz.
            self.offset_steps(
                &js.parent_offset,
                false,
                &js.name,
                parent,
                JointId(ji),
                &mut steps,
                &mut uses,
            )?;
            // Joint motion.
            for (k, ((rotation, axis), cs)) in
                kind.motions().into_iter().zip(&js.coordinates).enumerate()
            {
                let name = cs.name();
                check_name(name, "coordinate")?;
                if coord_names.insert(name.to_string(), ()).is_some() {
                    return Err(ModelError::Duplicate {
                        kind: "coordinate",
                        name: name.to_string(),
                    });
                }
                let ckind = if rotation {
                    CoordKind::Rotational
                } else {
                    CoordKind::Translational
                };
                let (range, default) = match cs {
                    CoordinateSpec::Name(_) => (None, 0.0),
                    CoordinateSpec::Full { range, default, .. } => (*range, *default),
                };
                let range = range.unwrap_or(match ckind {
                    CoordKind::Rotational => [-std::f64::consts::PI, std::f64::consts::PI],
                    CoordKind::Translational => [-10.0, 10.0],
                });
                if !(range[0].is_finite()
                    && range[1].is_finite()
                    && range[0] < range[1]
                    && default.is_finite())
                {
                    return Err(ModelError::Invalid(format!(
                        "coordinate {name:?}: range {range:?} / default {default} invalid"
                    )));
                }
                coordinates.push(Coordinate {
                    name: name.to_string(),
                    joint: JointId(ji),
                    kind: ckind,
                    range,
                    default,
                });
                let (motion, sign) = motion_for(rotation, &axis);
                steps.push(Step {
                    motion,
                    source: Source::Coord {
                        index: first_coord + k,
                        scale: sign,
                    },
                });
            }
            // Child offset, inverted: Rz⁻¹ Ry⁻¹ Rx⁻¹ T(−t).
            self.offset_steps(
                &js.child_offset,
                true,
                &js.name,
                Some(child),
                JointId(ji),
                &mut steps,
                &mut uses,
            )?;
            joints.push(Joint {
                name: js.name.clone(),
                parent,
                child,
                kind,
                first_coord,
            });
            let merged = merge_constants(steps.split_off(start));
            steps.extend(merged);
            step_ranges.push(start..steps.len());
        }

        let mut parameters = Vec::with_capacity(spec.parameters.len());
        for (ps, u) in spec.parameters.iter().zip(uses) {
            if u.is_empty() {
                return Err(ModelError::Invalid(format!(
                    "parameter {:?} is not used by any joint offset",
                    ps.name
                )));
            }
            parameters.push(Parameter {
                name: ps.name.clone(),
                group: ps.group.clone(),
                unit: ps.unit,
                nominal: ps.nominal,
                lower: ps.lower,
                upper: ps.upper,
                description: ps.description.clone(),
                prior_sd: ps.prior_sd,
                prior_mean: ps.prior_mean.unwrap_or(ps.nominal),
                uses: u,
            });
        }

        let mut markers = Vec::with_capacity(spec.markers.len());
        let mut marker_names = HashMap::new();
        for m in &spec.markers {
            check_name(&m.name, "marker")?;
            if marker_names.insert(m.name.as_str(), ()).is_some() {
                return Err(ModelError::Duplicate {
                    kind: "marker",
                    name: m.name.clone(),
                });
            }
            if m.segment == "ground" || !new_seg_of.contains_key(m.segment.as_str()) {
                return Err(ModelError::UnknownSegment {
                    segment: m.segment.clone(),
                    used_by: format!("marker {:?}", m.name),
                });
            }
            if m.position.iter().any(|v| !v.is_finite())
                || !(m.weight.is_finite() && m.weight >= 0.0)
            {
                return Err(ModelError::Invalid(format!(
                    "marker {:?}: position and weight must be finite, weight ≥ 0",
                    m.name
                )));
            }
            markers.push(Marker {
                name: m.name.clone(),
                segment: SegmentId(new_seg_of[m.segment.as_str()]),
                local: Vector3::from(m.position),
                weight: m.weight,
            });
        }

        let plan = super::plan::Plan::new(
            &steps,
            &step_ranges,
            &segments
                .iter()
                .map(|s| s.parent.map(|p| p.0))
                .collect::<Vec<_>>(),
            &markers.iter().map(|m| m.segment.0).collect::<Vec<_>>(),
        );

        Ok(Model {
            name: spec.name.clone(),
            description: spec.description.clone(),
            segments,
            joints,
            coordinates,
            parameters,
            markers,
            steps,
            plan,
            spec: spec.clone(),
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn offset_steps(
        &self,
        offset: &OffsetSpec,
        inverse: bool,
        joint: &str,
        segment: Option<SegmentId>,
        joint_id: JointId,
        steps: &mut Vec<Step>,
        uses: &mut [Vec<ParamUse>],
    ) -> Result<(), ModelError> {
        let scalars = offset.scalars();
        let which = if inverse {
            "child_offset"
        } else {
            "parent_offset"
        };
        // Forward order tx ty tz rx ry rz; inverse order rz ry rx tx ty tz with negated values.
        let order: [usize; 6] = if inverse {
            [5, 4, 3, 0, 1, 2]
        } else {
            [0, 1, 2, 3, 4, 5]
        };
        let sign = if inverse { -1.0 } else { 1.0 };
        for k in order {
            let unit = if k < 3 { Unit::Metre } else { Unit::Radian };
            let what = format!("joint {joint:?} {which}.{}", OFFSET_SCALARS[k]);
            let source = self.scalar_source(scalars[k], sign, unit, &what)?;
            if let Source::Param { index, scale } = source {
                uses[index].push(ParamUse {
                    joint: joint_id,
                    segment,
                    in_parent_offset: !inverse,
                    scalar: OFFSET_SCALARS[k],
                    scale: scale * sign,
                });
            }
            if source != Source::Const(0.0) {
                steps.push(Step {
                    motion: offset_motion(k),
                    source,
                });
            }
        }
        Ok(())
    }
}

/// Replaces runs of constant steps by one fixed transform (dropped when it is the identity).
fn merge_constants(steps: Vec<Step>) -> Vec<Step> {
    let mut out: Vec<Step> = Vec::with_capacity(steps.len());
    let mut acc: Option<Pose> = None;
    let flush = |acc: &mut Option<Pose>, out: &mut Vec<Step>| {
        if let Some(p) = acc.take() {
            if !p.is_identity() {
                out.push(Step {
                    motion: Motion::Fixed(p),
                    source: Source::Const(0.0),
                });
            }
        }
    };
    for s in steps {
        match s.source {
            Source::Const(v) => {
                let mut p = acc.take().unwrap_or_else(Pose::identity);
                p.apply(&s.motion, v);
                acc = Some(p);
            }
            _ => {
                flush(&mut acc, &mut out);
                out.push(s);
            }
        }
    }
    flush(&mut acc, &mut out);
    out
}

fn check_name(name: &str, kind: &'static str) -> Result<(), ModelError> {
    if name.trim().is_empty() || name.trim() != name {
        return Err(ModelError::Invalid(format!(
            "{kind} name {name:?} must be non-empty without surrounding spaces"
        )));
    }
    Ok(())
}

/// Rotation matrix `Rx(a)·Ry(b)·Rz(c)` of an offset frame.
pub fn offset_rotation(rx: f64, ry: f64, rz: f64) -> Matrix3<f64> {
    let mut p = Pose::identity();
    p.apply(&Motion::RotX, rx);
    p.apply(&Motion::RotY, ry);
    p.apply(&Motion::RotZ, rz);
    p.rot
}
