//! The model description as written by people: names instead of indices, readable as TOML.
//!
//! A [`ModelSpec`] is validated and compiled once into an index-based [`crate::model::Model`]
//! (see [`crate::model::Model::compile`]). All values are SI: metres and radians.
//!
//! ```toml
//! name = "two-link"
//! segments = [{ name = "upper" }, { name = "lower" }]
//!
//! [[joints]]
//! name = "shoulder"
//! parent = "ground"
//! child = "upper"
//! kind = { type = "pin", axis = "z" }
//! coordinates = ["shoulder_angle"]
//!
//! [[joints]]
//! name = "elbow"
//! parent = "upper"
//! child = "lower"
//! kind = { type = "pin", axis = "z" }
//! coordinates = [{ name = "elbow_angle", range = [0.0, 2.5] }]
//! parent_offset = { ty = "upper_length", rx = 0.1 }
//!
//! [[parameters]]
//! name = "upper_length"
//! group = "elbow"
//! unit = "m"
//! nominal = -0.3
//! lower = -0.35
//! upper = -0.25
//!
//! [[markers]]
//! name = "wrist"
//! segment = "lower"
//! position = [0.0, -0.25, 0.0]
//! ```
//!
//! A joint places a *parent joint frame* inside the parent segment and a *child joint frame*
//! inside the child segment ([`OffsetSpec`]), and moves the child joint frame relative to the
//! parent joint frame by its coordinates ([`JointKindSpec`]):
//!
//! `parent_from_child = parent_from_pjf · motion(q) · (child_from_cjf)⁻¹`.
//!
//! Each of the six scalars of each offset is fixed or a named [`ParameterSpec`].

use serde::{Deserialize, Serialize};

pub(crate) use super::functions::FunctionSpec;

/// A whole model: segments, the joints that connect them, parameters and markers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    pub segments: Vec<SegmentSpec>,
    pub joints: Vec<JointSpec>,
    /// Joint parameters, in the order of the parameter vector `p`.
    #[serde(default)]
    pub parameters: Vec<ParameterSpec>,
    #[serde(default)]
    pub markers: Vec<MarkerSpec>,
    /// Coordinates that follow others (OpenSim's `CoordinateCouplerConstraint`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub couplers: Vec<CouplerSpec>,
    /// The vertical axis of the laboratory whose static trial built this subject model
    /// (`"y"`, `"-y"`, `"z"`, `"-z"`, `"x"`, `"-x"`; written by `personalize`, detected from
    /// the marker layout by [`crate::vertical::detect_up`] or given by `--up`). Trials read for
    /// this model are rotated from this axis to Y up unless told otherwise. Absent: `y`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lab_up: Option<crate::spatial::UpAxis>,
}

/// `dependent = function(independent)`: the dependent coordinate leaves the coordinate vector
/// `q` and follows its independent coordinate exactly (the chain rule carries ∂/∂q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CouplerSpec {
    pub name: String,
    pub dependent: String,
    pub independent: String,
    pub function: FunctionSpec,
}

/// One elementary motion of a [`JointKindSpec::Custom`] joint: a rotation about, or a
/// translation along, `axis` of the frame produced by the axes before it, by
/// `function(coordinate)` (or the constant `function` when no coordinate is named).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformAxisSpec {
    pub motion: AxisMotion,
    pub axis: AxisSpec,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coordinate: Option<String>,
    #[serde(default = "FunctionSpec::identity")]
    pub function: FunctionSpec,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisMotion {
    Rotation,
    Translation,
}

/// A rigid segment. `ground` is implicit and must not be listed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
}

/// A joint between `parent` (a segment or `ground`) and `child`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    pub name: String,
    pub parent: String,
    pub child: String,
    pub kind: JointKindSpec,
    /// One coordinate per degree of freedom, in the order the kind lists its motions.
    #[serde(default)]
    pub coordinates: Vec<CoordinateSpec>,
    /// The parent joint frame expressed in the parent segment.
    #[serde(default, skip_serializing_if = "OffsetSpec::is_identity")]
    pub parent_offset: OffsetSpec,
    /// The child joint frame expressed in the child segment.
    #[serde(default, skip_serializing_if = "OffsetSpec::is_identity")]
    pub child_offset: OffsetSpec,
}

/// How the child joint frame moves relative to the parent joint frame.
///
/// Rotations are intrinsic: each axis is expressed in the frame produced by the motions
/// before it. Axes are written `"x"`, `"-y"`, … or as a vector `[ax, ay, az]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum JointKindSpec {
    /// Six DOF: translations along the parent joint frame's x, y, z, then three rotations.
    Free { rotation_axes: [AxisSpec; 3] },
    /// Three intersecting rotations in the given order (e.g. `["z", "x", "y"]`).
    Gimbal { axes: [AxisSpec; 3] },
    /// Two intersecting rotations in the given order.
    Universal { axes: [AxisSpec; 2] },
    /// One rotation about a fixed axis.
    Pin { axis: AxisSpec },
    /// One translation along a fixed axis.
    Slider { axis: AxisSpec },
    /// No motion.
    Weld,
    /// Any sequence of transform axes, each a function of one coordinate (OpenSim's
    /// `CustomJoint`, and every other OpenSim joint written that way). Coordinates may be
    /// locked; a coordinate may drive several axes.
    Custom { axes: Vec<TransformAxisSpec> },
}

/// An axis: `"x"`, `"+y"`, `"-z"` or an arbitrary non-zero vector (normalised on compile).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AxisSpec {
    Named(String),
    Vector([f64; 3]),
}

impl AxisSpec {
    pub(crate) fn named(s: &str) -> Self {
        AxisSpec::Named(s.to_string())
    }
}

/// A generalized coordinate: a bare name, or a name with its range (rad or m) and default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum CoordinateSpec {
    Name(String),
    Full {
        name: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        range: Option<[f64; 2]>,
        #[serde(default, skip_serializing_if = "is_zero")]
        default: f64,
        /// Held at `default` (custom joints only): not part of `q`.
        #[serde(default, skip_serializing_if = "is_false")]
        locked: bool,
        /// OpenSim's flag that the value should stay in `range` (carried, informative).
        #[serde(default, skip_serializing_if = "is_false")]
        clamped: bool,
    },
}

fn is_false(x: &bool) -> bool {
    !*x
}

impl CoordinateSpec {
    pub fn name(&self) -> &str {
        match self {
            CoordinateSpec::Name(n) | CoordinateSpec::Full { name: n, .. } => n,
        }
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// An offset frame: translation (tx, ty, tz) then the body-fixed X-Y-Z rotation (rx, ry, rz),
/// `segment_from_joint_frame = T(tx, ty, tz) · Rx(rx) · Ry(ry) · Rz(rz)` (OpenSim's
/// `PhysicalOffsetFrame` convention). Missing scalars are fixed at 0.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OffsetSpec {
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub tx: ScalarSpec,
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub ty: ScalarSpec,
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub tz: ScalarSpec,
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub rx: ScalarSpec,
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub ry: ScalarSpec,
    #[serde(default, skip_serializing_if = "ScalarSpec::is_zero")]
    pub rz: ScalarSpec,
}

/// The six scalars of an offset, in the order (tx, ty, tz, rx, ry, rz).
pub const OFFSET_SCALARS: [&str; 6] = ["tx", "ty", "tz", "rx", "ry", "rz"];

impl OffsetSpec {
    pub(crate) fn is_identity(&self) -> bool {
        self.scalars().iter().all(|s| s.is_zero())
    }
    /// The scalars in the order of [`OFFSET_SCALARS`].
    pub fn scalars(&self) -> [&ScalarSpec; 6] {
        [&self.tx, &self.ty, &self.tz, &self.rx, &self.ry, &self.rz]
    }
    pub fn scalars_mut(&mut self) -> [&mut ScalarSpec; 6] {
        [
            &mut self.tx,
            &mut self.ty,
            &mut self.tz,
            &mut self.rx,
            &mut self.ry,
            &mut self.rz,
        ]
    }
}

/// One offset scalar: a fixed value (m or rad), a parameter name, or a scaled parameter
/// (`value = scale · p`, e.g. `scale = -1` for a left leg's "lateral" along −z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ScalarSpec {
    Fixed(f64),
    Param(String),
    Scaled {
        param: String,
        #[serde(default = "one")]
        scale: f64,
    },
}

fn one() -> f64 {
    1.0
}

impl Default for ScalarSpec {
    fn default() -> Self {
        ScalarSpec::Fixed(0.0)
    }
}

impl ScalarSpec {
    pub(crate) fn is_zero(&self) -> bool {
        matches!(self, ScalarSpec::Fixed(v) if *v == 0.0)
    }
    /// A parameter reference with a scale (written as a bare name when the scale is 1).
    pub fn param(name: &str, scale: f64) -> Self {
        if scale == 1.0 {
            ScalarSpec::Param(name.to_string())
        } else {
            ScalarSpec::Scaled {
                param: name.to_string(),
                scale,
            }
        }
    }
    /// The parameter name and scale, if this scalar is a parameter.
    pub fn as_param(&self) -> Option<(&str, f64)> {
        match self {
            ScalarSpec::Fixed(_) => None,
            ScalarSpec::Param(n) => Some((n, 1.0)),
            ScalarSpec::Scaled { param, scale } => Some((param, *scale)),
        }
    }
}

/// Physical unit of a parameter: metres for translations, radians for rotations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Unit {
    #[serde(rename = "m")]
    Metre,
    #[serde(rename = "rad")]
    Radian,
}

/// Millimetres per metre: lengths are stored in metres and shown in millimetres.
pub(crate) const MM_PER_M: f64 = 1e3;
/// Metres per millimetre: lengths given in millimetres (file units, thresholds) to metres.
pub(crate) const M_PER_MM: f64 = 1e-3;

impl Unit {
    /// The unit values are shown in: `mm` for metres, `deg` for radians.
    pub(crate) fn display_suffix(self) -> &'static str {
        match self {
            Unit::Metre => "mm",
            Unit::Radian => "deg",
        }
    }

    /// Shown units per SI unit: 1000 mm per m, 180/π degrees per radian.
    pub(crate) fn display_scale(self) -> f64 {
        match self {
            Unit::Metre => MM_PER_M,
            Unit::Radian => 180.0 / std::f64::consts::PI,
        }
    }

    /// An SI value (m, rad) in shown units (mm, deg).
    pub(crate) fn to_display(self, si: f64) -> f64 {
        si * self.display_scale()
    }
}

impl std::fmt::Display for Unit {
    /// The unit values are shown in: `mm` for metres, `deg` for radians.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.display_suffix())
    }
}

/// A joint parameter: a free scalar of one or more offset frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    pub name: String,
    /// A group name used to select parameters together (e.g. `hip`, `knee`, `ankle`).
    pub group: String,
    pub unit: Unit,
    pub nominal: f64,
    pub lower: f64,
    pub upper: f64,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Standard deviation of the parameter's prior (m or rad): the accuracy of the method
    /// that gave its nominal value (see `docs/priors.md`). None: no prior (a flat prior
    /// inside the bounds, as in Reinbolt et al. 2005).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_sd: Option<f64>,
    /// Mean of the prior (m or rad); None: the nominal value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_mean: Option<f64>,
}

/// A marker fixed in a segment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerSpec {
    pub name: String,
    pub segment: String,
    /// Position in the segment frame, metres.
    pub position: [f64; 3],
    /// Weight of the marker's squared error (default 1).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub weight: f64,
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

impl ModelSpec {
    /// Parses a TOML model description (not yet validated: see `Model::compile`).
    pub fn from_toml(text: &str) -> Result<Self, toml::de::Error> {
        toml::from_str(text)
    }

    /// Writes the description as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a model spec always serializes to TOML")
    }
}
