//! Forward kinematics and exact marker Jacobians with respect to coordinates and parameters.
//!
//! ## Math
//! The pose of a segment is a product of elementary transforms `E_k(s_k)`, each a rotation
//! about, or a translation along, a unit axis `a_k` of the frame it acts in, by a scalar
//! `s_k = c_k · x_k` where `x_k` is a coordinate `q_i`, a parameter `p_j` or a constant
//! (see [`crate::model`]). For a marker at world position `m`, downstream of step `k`,
//!
//! * rotation step: `∂m/∂s_k = ω_k × (m − o_k)`,
//! * translation step: `∂m/∂s_k = ω_k`,
//!
//! where `ω_k = R_k a_k` is the step's axis and `o_k` the origin of the frame it acts in, both
//! in world coordinates (`R_k`, `o_k`: the pose accumulated just before step `k`). By the
//! chain rule `∂m/∂x = Σ_k c_k ∂m/∂s_k` over the steps that read `x`. These are the usual
//! geometric (screw) Jacobian columns; the same rule serves `q` and `p`, which is why the
//! model treats parameters as inputs like coordinates (docs/architecture.md §2).
//!
//! `fd.rs` (in test builds) holds the central finite-difference twins used as test oracles.

#[cfg(test)]
pub(crate) mod fd;
#[cfg(test)]
pub(crate) mod synth;
pub(crate) mod twist;

use nalgebra::{DMatrix, Vector3};

use crate::model::plan::JCol;
use crate::model::{Item, Model, Source};
use crate::spatial::Pose;

/// Per-evaluation workspace: one per thread or particle. The model stays immutable.
#[derive(Debug, Clone)]
pub struct KinData {
    /// `world_from_segment` for every segment.
    pub segment_poses: Vec<Pose>,
    /// Marker positions in world coordinates (m), model marker order.
    pub markers: Vec<Vector3<f64>>,
    /// `∂(marker coordinates)/∂q` of the last evaluation that asked for it: `3·n_markers × n_q`,
    /// row `3j + k` is axis k (x, y, z) of marker j, metres per unit of q.
    pub jq: DMatrix<f64>,
    /// `∂(marker coordinates)/∂p` of the last evaluation that asked for it: `3·n_markers × n_p`,
    /// same row layout.
    pub jp: DMatrix<f64>,
    /// Per step: world axis `ω_k` of the last evaluation (variable steps only).
    step_axis: Vec<Vector3<f64>>,
    /// Per step: world origin `o_k` of the frame the step acts in.
    step_origin: Vec<Vector3<f64>>,
    /// The parameter vector the block cache below was computed for (NaN: none yet).
    cached_p: Vec<f64>,
    /// Whether the block cache holds anything (a model without parameters has an empty
    /// `cached_p` that always equals `p`).
    blocks_ready: bool,
    /// Per block: its composed transform for `cached_p`.
    block_pose: Vec<Pose>,
    /// Per parameter step: axis and origin in the frame at the start of its block.
    step_local: Vec<(Vector3<f64>, Vector3<f64>)>,
}

impl KinData {
    /// World axis `ω_k` and origin `o_k` of step `k` at the last evaluation (module docs);
    /// valid for coordinate steps when the evaluation wanted axes, for parameter steps when
    /// it wanted `dp` or was [`forward_kinematics_frames`].
    pub(crate) fn step_frame(&self, k: usize) -> (Vector3<f64>, Vector3<f64>) {
        (self.step_axis[k], self.step_origin[k])
    }

    /// A workspace sized for `model` (its segments, markers, coordinates and parameters).
    pub fn new(model: &Model) -> Self {
        let nm = model.markers().len();
        let ns = model.steps.len();
        KinData {
            segment_poses: vec![Pose::identity(); model.segments().len()],
            markers: vec![Vector3::zeros(); nm],
            jq: DMatrix::zeros(3 * nm, model.coordinates().len()),
            jp: DMatrix::zeros(3 * nm, model.parameters().len()),
            step_axis: vec![Vector3::zeros(); ns],
            step_origin: vec![Vector3::zeros(); ns],
            cached_p: vec![f64::NAN; model.parameters().len()],
            blocks_ready: false,
            block_pose: vec![Pose::identity(); model.plan.n_blocks],
            step_local: vec![(Vector3::zeros(), Vector3::zeros()); ns],
        }
    }

    /// Recomputes the parameter-only blocks when `p` differs from the cached one.
    fn update_blocks(&mut self, model: &Model, p: &[f64]) {
        if self.blocks_ready && self.cached_p.as_slice() == p {
            return;
        }
        self.blocks_ready = true;
        for items in &model.plan.items {
            for item in items {
                let Item::Block { id, steps } = item else {
                    continue;
                };
                let mut pose = Pose::identity();
                for k in steps.clone() {
                    let step = &model.steps[k];
                    if matches!(step.source, Source::Param { .. }) {
                        self.step_local[k] = (pose.axis_of(&step.motion), pose.trans);
                    }
                    pose.apply(&step.motion, source_value(model, &step.source, p, &[]));
                }
                self.block_pose[*id] = pose;
            }
        }
        self.cached_p.copy_from_slice(p);
    }
}

/// Which Jacobians [`forward_kinematics`] computes besides the segment poses and marker
/// positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Want {
    /// Poses and marker positions only.
    Positions,
    /// And `∂x/∂q` ([`KinData::jq`]).
    Dq,
    /// And both `∂x/∂q` and `∂x/∂p` ([`KinData::jq`], [`KinData::jp`]).
    DqDp,
}

/// What one evaluation fills besides poses and marker positions.
#[derive(Debug, Clone, Copy)]
struct Outputs {
    dq: bool,
    dp: bool,
    /// World axes and origins of the coordinate steps (implied by `dq`).
    axes: bool,
    /// World axes and origins of the parameter steps (implied by `dp`).
    param_frames: bool,
}

impl From<Want> for Outputs {
    fn from(want: Want) -> Self {
        let (dq, dp) = match want {
            Want::Positions => (false, false),
            Want::Dq => (true, false),
            Want::DqDp => (true, true),
        };
        Outputs {
            dq,
            dp,
            axes: dq,
            param_frames: dp,
        }
    }
}

#[inline]
fn source_value(model: &Model, source: &Source, p: &[f64], q: &[f64]) -> f64 {
    match *source {
        Source::Const(v) => v,
        Source::Coord { index, scale } => scale * q[index],
        Source::Param { index, scale } => scale * p[index],
        Source::Func { index, fun, scale } => scale * model.functions[fun].eval(q[index]).0,
    }
}

/// Computes segment poses and marker positions for parameters `p` (len `n_p`) and
/// coordinates `q` (len `n_q`), and the Jacobians that `want` asks for, into `data`
/// (read them with [`KinData::jq`] and [`KinData::jp`]).
///
/// # Panics
/// When `p`, `q` or `data` do not match the model's sizes (a programming error).
pub fn forward_kinematics(model: &Model, p: &[f64], q: &[f64], want: Want, data: &mut KinData) {
    kinematics(model, p, q, want.into(), data);
}

/// Segment poses, marker positions and the world axis and origin of every coordinate step
/// ([`KinData::step_frame`]), without the Jacobian matrices: what inverse kinematics needs to
/// form its normal equations from segment moments.
pub(crate) fn forward_kinematics_axes(model: &Model, p: &[f64], q: &[f64], data: &mut KinData) {
    let only_axes = Outputs {
        dq: false,
        dp: false,
        axes: true,
        param_frames: false,
    };
    kinematics(model, p, q, only_axes, data);
}

/// Segment poses, marker positions and the world axis and origin of every variable step,
/// coordinates' and parameters' alike ([`KinData::step_frame`]), without filling either
/// Jacobian matrix: what the calibration's twist kernel (`calibrate::kernel_twist`) reads.
pub(crate) fn forward_kinematics_frames(model: &Model, p: &[f64], q: &[f64], data: &mut KinData) {
    let frames = Outputs {
        dq: false,
        dp: false,
        axes: true,
        param_frames: true,
    };
    kinematics(model, p, q, frames, data);
}

/// [`forward_kinematics`] with the outputs spelled out.
#[inline(always)]
fn kinematics(model: &Model, p: &[f64], q: &[f64], want: Outputs, data: &mut KinData) {
    assert_eq!(p.len(), model.parameters().len(), "parameter vector length");
    assert_eq!(
        q.len(),
        model.coordinates().len(),
        "coordinate vector length"
    );
    assert_eq!(
        data.markers.len(),
        model.markers().len(),
        "workspace built for another model"
    );
    data.update_blocks(model, p);
    for (s, seg) in model.segments().iter().enumerate() {
        let mut pose = match seg.parent {
            Some(parent) => data.segment_poses[parent.0],
            None => Pose::identity(),
        };
        for item in &model.plan.items[s] {
            match item {
                Item::Block { id, steps } => {
                    if want.param_frames {
                        for k in steps.clone() {
                            if matches!(model.steps[k].source, Source::Param { .. }) {
                                let (axis, origin) = data.step_local[k];
                                data.step_axis[k] = pose.rot * axis;
                                data.step_origin[k] = pose.transform_point(&origin);
                            }
                        }
                    }
                    pose = pose * data.block_pose[*id];
                }
                &Item::Coord(k) => {
                    let step = &model.steps[k];
                    let frames = want.dq || want.dp || want.axes;
                    if frames {
                        data.step_axis[k] = pose.axis_of(&step.motion);
                        data.step_origin[k] = pose.trans;
                    }
                    let value = match step.source {
                        // A step through functions: its axis carries ∂s/∂q
                        // (crate::model::custom), the Jacobian column scale is 1.
                        Source::Func { index, fun, scale } => {
                            let (v, d) = model.functions[fun].eval(q[index]);
                            if frames {
                                data.step_axis[k] *= scale * d;
                            }
                            scale * v
                        }
                        ref source => source_value(model, source, p, q),
                    };
                    pose.apply(&step.motion, value);
                }
            }
        }
        data.segment_poses[s] = pose;
    }
    for (m, marker) in model.markers().iter().enumerate() {
        data.markers[m] = data.segment_poses[marker.segment.0].transform_point(&marker.local);
    }
    if want.dq {
        fill_jacobian(model, &model.plan.cols_q, data, true);
    }
    if want.dp {
        fill_jacobian(model, &model.plan.cols_p, data, false);
    }
}

/// Writes the geometric Jacobian columns (module docs) of every marker.
fn fill_jacobian(model: &Model, cols: &[Vec<JCol>], data: &mut KinData, of_q: bool) {
    let nrows = 3 * model.markers().len();
    let target = if of_q {
        data.jq.as_mut_slice()
    } else {
        data.jp.as_mut_slice()
    };
    for (s, markers) in model.plan.markers_by_segment.iter().enumerate() {
        for &m in markers {
            let x = data.markers[m];
            for c in &cols[s] {
                let axis = data.step_axis[c.step];
                let d = if c.rotation {
                    axis.cross(&(x - data.step_origin[c.step]))
                } else {
                    axis
                } * c.scale;
                let out = &mut target[c.col * nrows + 3 * m..c.col * nrows + 3 * m + 3];
                if c.first {
                    out.copy_from_slice(d.as_slice());
                } else {
                    out[0] += d.x;
                    out[1] += d.y;
                    out[2] += d.z;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
