//! Kinematic models: the description people write ([`spec`]), the compiled model
//! ([`Model`]), and the built-in sample models ([`lower_limb`]).

mod compile;
mod compiled;
pub mod custom;
pub(crate) mod fields;
pub mod functions;
pub mod lower_limb;
pub(crate) mod plan;
pub mod population;
pub(crate) mod refine;
mod sample;
pub mod spec;
mod splines;
mod validate;

pub(crate) use crate::spatial::Motion;
pub(crate) use compiled::Source;
pub use compiled::{CoordKind, Coordinate, JointKind, Model, ParamId, SegmentId};
pub(crate) use plan::Item;
use spec::Unit;

use nalgebra::Matrix3;
use thiserror::Error;

use crate::spatial::Pose;

/// Rotation matrix `Rx(rx)·Ry(ry)·Rz(rz)` of an offset frame: the body-fixed X-Y-Z sequence of
/// [`spec::OffsetSpec`] (OpenSim's `PhysicalOffsetFrame` orientation).
pub fn offset_rotation(rx: f64, ry: f64, rz: f64) -> Matrix3<f64> {
    let mut p = Pose::identity();
    p.apply(&Motion::RotX, rx);
    p.apply(&Motion::RotY, ry);
    p.apply(&Motion::RotZ, rz);
    p.rot
}

/// Why a model description was rejected. Every message names the offending item.
#[derive(Debug, Error, PartialEq)]
pub enum ModelError {
    #[error("{kind} {name:?} is defined twice")]
    Duplicate { kind: &'static str, name: String },
    #[error("{used_by} refers to segment {segment:?}, which is not defined")]
    UnknownSegment { segment: String, used_by: String },
    #[error("{used_by} refers to parameter {name:?}, which is not defined")]
    UnknownParameter { name: String, used_by: String },
    #[error("parameter {name:?} is declared in {declared:?} but {used_by} needs {needed:?}")]
    UnitMismatch {
        name: String,
        used_by: String,
        declared: Unit,
        needed: Unit,
    },
    #[error("parameter {name:?}: {detail}")]
    BadBounds { name: String, detail: String },
    #[error("{item}: axis {axis:?} is not x, y, z, -x, -y, -z or a non-zero vector")]
    BadAxis { item: String, axis: String },
    #[error("{0}")]
    Invalid(String),
    #[error("unknown built-in model {name:?}; built-in models: {available}")]
    UnknownBuiltin { name: String, available: String },
}
