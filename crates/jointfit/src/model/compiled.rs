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
//!
//! # Conventions of every field below
//!
//! * Units are SI: lengths in metres, angles in radians (display code converts).
//! * Frames: *world* is the ground frame (model convention: x anterior, y superior, z to the
//!   right; see `docs/architecture.md`). Each segment has its own body-fixed frame; the *parent
//!   joint frame* of a joint is fixed in the parent segment (the parent offset `t_p, r_p`), the
//!   *child joint frame* is fixed in the child segment (the child offset `t_c, r_c`), and the
//!   joint's coordinates move the second relative to the first.
//! * Shapes: `n_seg = n_joint` (one joint per segment), `n_q` coordinates, `n_p` parameters,
//!   `n_mrk` markers. Indices are the typed ids [`SegmentId`] and [`ParamId`] or, for
//!   joints (joint `i` moves segment `i`), coordinates (positions in `q`) and markers, a plain
//!   `usize`.
//! * A [`Model`] is read-only after [`Model::compile`]: its fields are private and the
//!   accessors hand out shared slices. To change a model, edit its [`ModelSpec`]
//!   ([`Model::spec`], [`Model::spec_with_nominal`]) and compile again.

use nalgebra::Vector3;

use super::spec::{ModelSpec, Unit};
use super::ModelError;
use crate::spatial::Motion;

/// Index of a segment in [`Model::segments`] (topological order: parents first).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SegmentId(pub usize);
/// Index of a parameter in the parameter vector `p`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParamId(pub usize);

/// A rigid body of the chain (pelvis, thigh, …). Its frame is body-fixed; the child offset of
/// the joint of the same index ([`Model::joints`]) places the joint frame in it.
#[derive(Debug, Clone)]
pub struct Segment {
    /// Unique name, as in the description (never `ground`).
    pub name: String,
    /// The parent segment; `None` when the segment is attached to ground (the world frame).
    /// Always a lower index than the segment itself (topological order).
    pub parent: Option<SegmentId>,
}

/// The kind of motion a joint allows, with unit axes (dimensionless, norm 1).
///
/// Successive motions act about / along the axes of the *current* frame (body-fixed,
/// intrinsic order): the first axis is expressed in the parent joint frame, the second in the
/// frame after the first motion, and so on. Each motion reads one coordinate, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum JointKind {
    /// 6 coordinates: translations along x, y, z of the parent joint frame (m), then rotations
    /// about `rotation_axes[0..3]` (rad).
    Free { rotation_axes: [Vector3<f64>; 3] },
    /// 3 coordinates: rotations about `axes[0]`, `axes[1]`, `axes[2]` in turn (rad).
    Gimbal { axes: [Vector3<f64>; 3] },
    /// 2 coordinates: rotations about `axes[0]`, then `axes[1]` (rad).
    Universal { axes: [Vector3<f64>; 2] },
    /// 1 coordinate: rotation about `axis` (rad).
    Pin { axis: Vector3<f64> },
    /// 1 coordinate: translation along `axis` (m).
    Slider { axis: Vector3<f64> },
    /// No coordinate: the child joint frame coincides with the parent joint frame.
    Weld,
    /// Transform axes driven by functions of coordinates ([`super::custom`]); `dof` counts
    /// the joint's coordinates in `q` (locked and coupled ones are not).
    Custom {
        axes: Vec<super::custom::TransformAxis>,
        dof: usize,
    },
}

impl JointKind {
    /// Number of coordinates (degrees of freedom): 6, 3, 2, 1, 1 or 0.
    pub(crate) fn dof(&self) -> usize {
        match self {
            JointKind::Free { .. } => 6,
            JointKind::Gimbal { .. } => 3,
            JointKind::Universal { .. } => 2,
            JointKind::Pin { .. } | JointKind::Slider { .. } => 1,
            JointKind::Weld => 0,
            JointKind::Custom { dof, .. } => *dof,
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
            JointKind::Weld | JointKind::Custom { .. } => vec![],
        }
    }
}

/// The name used in model descriptions: `free`, `gimbal`, `universal`, `pin`, `slider`,
/// `weld` or `custom`.
impl std::fmt::Display for JointKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            JointKind::Free { .. } => "free",
            JointKind::Gimbal { .. } => "gimbal",
            JointKind::Universal { .. } => "universal",
            JointKind::Pin { .. } => "pin",
            JointKind::Slider { .. } => "slider",
            JointKind::Weld => "weld",
            JointKind::Custom { .. } => "custom",
        })
    }
}

/// A joint: moves the child joint frame relative to the parent joint frame,
/// `parent_from_child = T(t_p) R(r_p) · motion(q) · (T(t_c) R(r_c))⁻¹`.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Unique name, as in the description.
    pub name: String,
    /// The segment the parent joint frame is fixed in; `None` for ground.
    pub parent: Option<SegmentId>,
    /// The segment this joint moves; `child.0 ==` this joint's index.
    pub child: SegmentId,
    /// Motion type and unit axes.
    pub kind: JointKind,
    /// Indices in `q` of the joint's coordinates: contiguous, in motion order, as many as
    /// the joint's degrees of freedom (6, 3, 2, 1, 1 or 0; a custom joint's coordinates that
    /// are neither locked nor coupled).
    pub coords: std::ops::Range<usize>,
}

/// Whether a coordinate is an angle (rad) or a length (m).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoordKind {
    Rotational,
    Translational,
}

/// One generalized coordinate: one entry of the per-frame vector `q` that inverse
/// kinematics solves for.
#[derive(Debug, Clone)]
pub struct Coordinate {
    /// Unique name (e.g. `hip_flexion`).
    pub name: String,
    /// Index in [`Model::joints`] of the joint whose motion reads this coordinate.
    pub joint: usize,
    /// Angle (rad) or length (m).
    pub kind: CoordKind,
    /// OpenSim's motion type (the unit in `.mot` files; `kind` for built-in joint kinds).
    pub motion: super::custom::MotionType,
    /// `[lower, upper]` limit in rad or m, `lower < upper`; a bound of inverse kinematics
    /// only when [`Coordinate::clamped`], else informative. Default `[−π, π]` or `[−10, 10]` m.
    pub range: [f64; 2],
    /// OpenSim's `<clamped>`: the value must stay inside `range`. Inverse kinematics bounds
    /// such coordinates to their range (`crate::ik`, as OpenSim's IK does); false for every
    /// built-in model.
    pub clamped: bool,
    /// Value in the default pose (rad or m); 0 unless the description says otherwise.
    pub default: f64,
}

/// One place a parameter enters the model: offset scalar `scalar` of one joint offset
/// takes the value `scale · p[k]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamUse {
    /// Index in [`Model::joints`] of the joint whose offset reads the parameter.
    pub joint: usize,
    /// The segment the offset frame is fixed in: the joint's parent for a parent offset
    /// (`None`: ground), its child for a child offset.
    pub segment: Option<SegmentId>,
    /// True for the parent offset `(t_p, r_p)`, false for the child offset `(t_c, r_c)`.
    pub in_parent_offset: bool,
    /// Which of the six offset scalars: `"tx"`, `"ty"`, `"tz"` (m, along the axes of the
    /// segment frame) or `"rx"`, `"ry"`, `"rz"` (rad, the body-fixed `Rx·Ry·Rz` sequence).
    pub scalar: &'static str,
    /// Dimensionless factor as written in the description (non-zero; often 1 or −1, e.g. a
    /// left-side mirror of a right-side parameter).
    pub scale: f64,
}

/// One joint parameter: one entry of the vector `p` that calibration fits, shared by every
/// frame of every trial (Reinbolt et al. 2005: joint positions and orientations in the
/// segments).
#[derive(Debug, Clone)]
pub struct Parameter {
    /// Unique name (e.g. `hip_pelvis_anterior`).
    pub name: String,
    /// Selection group (e.g. `hip`, `knee`, `ankle`); `calibrate --joints GROUP` frees a
    /// whole group.
    pub group: String,
    /// Metre for offset translations, radian for offset rotations.
    pub unit: Unit,
    /// Value in the uncalibrated (generic or scaled) model, in `unit`.
    pub nominal: f64,
    /// Lower bound for calibration, in `unit`; finite, `lower < upper`.
    pub lower: f64,
    /// Upper bound for calibration, in `unit`; finite.
    pub upper: f64,
    /// Free text shown in reports and in identifiability explanations.
    pub description: String,
    /// Prior standard deviation (m or rad), if the parameter has a prior.
    pub prior_sd: Option<f64>,
    /// Prior mean (m or rad): the spec's `prior_mean`, else its nominal value.
    pub prior_mean: f64,
    /// Every offset scalar that reads this parameter (at least one).
    pub uses: Vec<ParamUse>,
}

/// A model marker: a point fixed in a segment, matched by name to a measured trajectory.
#[derive(Debug, Clone)]
pub struct Marker {
    /// Unique name; the trial's marker label it is compared with.
    pub name: String,
    /// The segment the marker is fixed in (never ground).
    pub segment: SegmentId,
    /// Position in the segment frame (m), 3-vector.
    pub local: Vector3<f64>,
    /// Non-negative weight of the marker's squared residual in IK and calibration
    /// (dimensionless; 0 ignores the marker).
    pub weight: f64,
}

/// Where an elementary step takes its scalar from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Source {
    Const(f64),
    Coord {
        index: usize,
        scale: f64,
    },
    Param {
        index: usize,
        scale: f64,
    },
    /// `scale · functions[fun](q[index])` ([`super::custom`]).
    Func {
        index: usize,
        fun: usize,
        scale: f64,
    },
}

impl Source {
    /// Whether the step reads a coordinate.
    pub(crate) fn is_coordinate(&self) -> bool {
        matches!(self, Source::Coord { .. } | Source::Func { .. })
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Step {
    pub motion: Motion,
    pub source: Source,
}

/// A validated, immutable, index-based kinematic model (`Send + Sync`).
///
/// Built only by [`Model::compile`]; read through the accessors below. Per-frame state
/// (poses, marker positions, Jacobians) lives in [`crate::kinematics::KinData`], never here.
///
/// ```
/// use jointfit::model::lower_limb::{lower_limb, Side};
/// use jointfit::model::Model;
///
/// let model = Model::compile(&lower_limb(Side::Right)).unwrap();
/// assert_eq!((model.coordinates().len(), model.parameters().len()), (12, 27));
/// assert_eq!(model.segments()[model.joints()[1].child.0].name, "thigh");
/// ```
///
/// A compiled model cannot be changed; edit its description and compile again:
///
/// ```compile_fail
/// # use jointfit::model::lower_limb::{lower_limb, Side};
/// # use jointfit::model::Model;
/// let mut model = Model::compile(&lower_limb(Side::Right)).unwrap();
/// model.parameters[0].nominal = 0.0; // error[E0616]: field `parameters` is private
/// ```
#[derive(Debug, Clone)]
pub struct Model {
    /// Model name (free text, used in file names and reports).
    pub(super) name: String,
    /// Free-text description.
    pub(super) description: String,
    /// `n_seg` segments in topological order (every parent before its children).
    pub(super) segments: Vec<Segment>,
    /// `n_seg` joints; `joints[i]` attaches `segments[i]` to its parent.
    pub(super) joints: Vec<Joint>,
    /// `n_q` coordinates, joint by joint in joint order (see [`Joint::coords`]).
    pub(super) coordinates: Vec<Coordinate>,
    /// `n_p` parameters, in the order of the description.
    pub(super) parameters: Vec<Parameter>,
    /// `n_mrk` markers, in the order of the description.
    pub(super) markers: Vec<Marker>,
    /// Coordinates outside `q`: locked, or coupled to one in `q`.
    pub(super) dependents: Vec<super::custom::DependentCoordinate>,
    /// The functions of [`Source::Func`] steps.
    pub(crate) functions: Vec<super::custom::AxisFn>,
    /// Elementary steps of all segments, segment by segment.
    pub(crate) steps: Vec<Step>,
    /// How forward kinematics walks the steps (blocks, Jacobian columns).
    pub(crate) plan: super::plan::Plan,
    /// The description this model was compiled from.
    pub(super) spec: ModelSpec,
}

impl Model {
    /// Model name (users read it, like the description, from [`Model::spec`]).
    #[inline]
    pub(crate) fn name(&self) -> &str {
        &self.name
    }
    /// Free-text description (users read it from [`Model::spec`]).
    #[inline]
    pub(crate) fn description(&self) -> &str {
        &self.description
    }
    /// Segments in topological order (`n_seg`), indexed by [`SegmentId`].
    #[inline]
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }
    /// Joints (`n_seg`); joint `i` moves segment `i`.
    #[inline]
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }
    /// Coordinates (`n_q`); the layout of every `q` vector.
    #[inline]
    pub fn coordinates(&self) -> &[Coordinate] {
        &self.coordinates
    }
    /// Coordinates outside `q` (locked, or coupled to one in `q`), in joint order; their
    /// values follow from `q` ([`super::custom::DependentCoordinate::value`]).
    #[inline]
    pub fn dependents(&self) -> &[super::custom::DependentCoordinate] {
        &self.dependents
    }
    /// Parameters (`n_p`), indexed by [`ParamId`]; the layout of every `p` vector.
    #[inline]
    pub fn parameters(&self) -> &[Parameter] {
        &self.parameters
    }
    /// Markers (`n_mrk`); the layout of every marker-position vector.
    #[inline]
    pub fn markers(&self) -> &[Marker] {
        &self.markers
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
    /// The parameter of that name.
    pub fn param_id(&self, name: &str) -> Option<ParamId> {
        self.parameters
            .iter()
            .position(|s| s.name == name)
            .map(ParamId)
    }
    /// Index in `q` of the coordinate of that name.
    pub fn coord_id(&self, name: &str) -> Option<usize> {
        self.coordinates.iter().position(|s| s.name == name)
    }
    /// Ids of the parameters in the given group, in parameter order.
    pub(crate) fn params_in_group(&self, group: &str) -> Vec<ParamId> {
        (0..self.parameters().len())
            .filter(|&i| self.parameters[i].group == group)
            .map(ParamId)
            .collect()
    }
    /// Distinct group names in order of first appearance.
    pub(crate) fn groups(&self) -> Vec<String> {
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
            // A fitted value mapped back from the solver's scaled variables can land one
            // rounding step outside its bound; the description must stay loadable.
            ps.nominal = if ps.lower <= ps.upper {
                v.clamp(ps.lower, ps.upper)
            } else {
                *v
            };
        }
        spec
    }

    /// Validates and compiles a description. Every error names the offending item.
    pub fn compile(spec: &ModelSpec) -> Result<Model, ModelError> {
        super::fields::validate_fields(spec)?;
        super::validate::Compiler::new(spec)?.run()
    }
}

#[cfg(test)]
mod tests {
    use super::Model;
    use crate::model::lower_limb::{lower_limb, Side};

    #[test]
    fn groups_in_order_of_first_appearance() {
        for side in [Side::Right, Side::Left] {
            let model = Model::compile(&lower_limb(side)).unwrap();
            assert_eq!(model.groups(), ["hip", "knee", "ankle"]);
        }
    }
}
