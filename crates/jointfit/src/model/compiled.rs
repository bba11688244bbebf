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

use nalgebra::{Matrix3, Unit as UnitVec, Vector3};

use super::spec::{ModelSpec, Unit};
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
    pub(super) fn motions(&self) -> Vec<(bool, Vector3<f64>)> {
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
    pub(super) spec: ModelSpec,
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
        super::validate::Compiler::new(spec)?.run()
    }
}

/// Rotation matrix `Rx(a)·Ry(b)·Rz(c)` of an offset frame.
pub fn offset_rotation(rx: f64, ry: f64, rz: f64) -> Matrix3<f64> {
    let mut p = Pose::identity();
    p.apply(&Motion::RotX, rx);
    p.apply(&Motion::RotY, ry);
    p.apply(&Motion::RotZ, rz);
    p.rot
}
