//! From segment frames to the model: offset scalars, nominal parameters, bounds, the talus
//! levelling angle, and the coordinates of the static pose.
//!
//! Every offset is first computed as the values of its six scalars (tx, ty, tz, rx, ry, rz;
//! metres and radians, `T·Rx·Ry·Rz`). The template [`lower_limb`] then decides which scalar is a
//! parameter (value = scale · p, so p = value / scale: this applies the left leg's mirroring)
//! and which is fixed. A pin about z tilted by (rx, ry) has the axis
//! `(sin ry, −sin rx cos ry, cos rx cos ry)`, so an axis direction d gives
//! `ry = asin(d_x)`, `rx = atan2(−d_y, d_z)`.
//!
//! [`lower_limb`]: jointfit::model::lower_limb::lower_limb

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

use super::frames::Anatomy;
use super::LandmarkError;
use jointfit::model::lower_limb::Side;
use jointfit::model::spec::Unit;
use jointfit::model::spec::{ModelSpec, ScalarSpec};
use jointfit::model::{offset_rotation, JointKind, Model};
use jointfit::spatial::Pose;

/// Values of the six scalars of an offset.
pub(crate) type Offset = [f64; 6];

/// The parent and child offsets of every joint of the leg model, by joint name.
#[derive(Debug, Clone)]
pub(crate) struct Offsets(pub Vec<(&'static str, Offset, Offset)>);

impl Offsets {
    fn get(&self, joint: &str) -> Option<(&Offset, &Offset)> {
        self.0
            .iter()
            .find(|(n, _, _)| *n == joint)
            .map(|(_, p, c)| (p, c))
    }
}

fn pose_of(o: &Offset) -> Pose {
    Pose {
        rot: offset_rotation(o[3], o[4], o[5]),
        trans: Vector3::new(o[0], o[1], o[2]),
    }
}

/// (rx, ry) of a z axis turned onto the unit direction `d`.
fn pin_z_angles(d: &Vector3<f64>) -> (f64, f64) {
    ((-d.y).atan2(d.z), d.x.clamp(-1.0, 1.0).asin())
}

/// Values below this (m or rad) are construction round-off and are written as exact zeros.
const SNAP: f64 = 1e-12;

fn snap(v: f64) -> f64 {
    if v.abs() < SNAP {
        0.0
    } else {
        v
    }
}

/// The offsets of every joint for the given anatomy; the talocrural child offset's fixed rz
/// is the levelling angle ([`levelling_angle`]).
pub(crate) fn offsets(an: &Anatomy, side: Side) -> Result<Offsets, LandmarkError> {
    let f = &an.frames;
    let local = |frame: &Pose, v: &Vector3<f64>| frame.rot.transpose() * v;
    let in_frame = |frame: &Pose, x: &Vector3<f64>| frame.inverse().transform_point(x);

    let hip_parent = [
        an.hip_in_pelvis.x,
        an.hip_in_pelvis.y,
        an.hip_in_pelvis.z,
        0.0,
        0.0,
        0.0,
    ];

    let h = an.hip_in_thigh;
    let hip_child = [h.x, h.y, h.z, 0.0, 0.0, 0.0];

    let kt = in_frame(&f.thigh, &an.knee_centre);
    let (krx, kry) = pin_z_angles(&local(&f.thigh, &an.knee_axis));
    let knee_parent = [kt.x, kt.y, kt.z, krx, kry, 0.0];
    let ks = in_frame(&f.shank, &an.knee_centre);
    let (srx, sry) = pin_z_angles(&local(&f.shank, &an.knee_axis));
    let knee_child = [ks.x, ks.y, ks.z, srx, sry, 0.0];

    let at = in_frame(&f.shank, &an.ankle_centre);
    let (arx, ary) = pin_z_angles(&local(&f.shank, &an.ankle_axis));
    let talo_parent = [at.x, at.y, at.z, arx, ary, 0.0];

    let st = in_frame(&f.talus, &an.subtalar_point);
    let ut = local(&f.talus, &an.subtalar_axis);
    let sub_parent = [st.x, st.y, st.z, 0.0, (-ut.z).atan2(ut.x), 0.0];
    let sf = in_frame(&f.foot, &an.subtalar_point);
    let uf = local(&f.foot, &an.subtalar_axis);
    // u_foot = (cos ry cos rz, sin rz, −sin ry cos rz): the Inman angles back.
    let sub_child = [
        sf.x,
        sf.y,
        sf.z,
        0.0,
        (-uf.z).atan2(uf.x),
        uf.y.clamp(-1.0, 1.0).asin(),
    ];

    let level = levelling_angle(
        &knee_parent,
        &knee_child,
        &talo_parent,
        &sub_parent,
        &sub_child,
    )
    .ok_or_else(|| {
        LandmarkError::Implausible(format!(
            "the {} foot's long axis cannot be levelled by a rotation about the talocrural \
                 axis (the axis is nearly parallel to the foot): check the malleolus, heel and \
                 forefoot labels",
            super::markerset::side_name(side)
        ))
    })?;
    let zero = [0.0; 6];
    Ok(Offsets(
        vec![
            ("ground_pelvis", zero, zero),
            ("hip", hip_parent, hip_child),
            ("knee", knee_parent, knee_child),
            ("talocrural", talo_parent, [0.0, 0.0, 0.0, 0.0, 0.0, level]),
            ("subtalar", sub_parent, sub_child),
        ]
        .into_iter()
        .map(|(n, p, c)| (n, p.map(snap), c.map(snap)))
        .collect(),
    ))
}

/// The fixed rotation `c` about the talocrural axis between its joint frame and the talus
/// (talocrural child offset `rz`) that makes the foot's long axis horizontal in the pelvis
/// frame when every coordinate is 0 (the template's convention: standing with the foot flat
/// reads 0° of dorsiflexion). With `M = R_knee,thigh · R_knee,shankᵀ · R_talocrural` and
/// `v = R_subtalar,talus · R_subtalar,footᵀ · x̂`, the pelvis-frame foot axis is
/// `M · Rz(−c) · v`; its y component `A cos c + B sin c + C` vanishes at two angles, of which
/// the one with the foot pointing anterior is returned (`None` if no angle levels the foot).
pub(crate) fn levelling_angle(
    knee_parent: &Offset,
    knee_child: &Offset,
    talo_parent: &Offset,
    sub_parent: &Offset,
    sub_child: &Offset,
) -> Option<f64> {
    let rot = |o: &Offset| offset_rotation(o[3], o[4], o[5]);
    let m: Matrix3<f64> = rot(knee_parent) * rot(knee_child).transpose() * rot(talo_parent);
    let v = rot(sub_parent) * rot(sub_child).transpose() * Vector3::x();
    let w = m.transpose() * Vector3::y();
    let a = w.x * v.x + w.y * v.y;
    let b = w.x * v.y - w.y * v.x;
    let c = w.z * v.z;
    let r = a.hypot(b);
    if r < 1e-9 || c.abs() > r {
        return None;
    }
    let phi = b.atan2(a);
    let delta = (-c / r).acos();
    let foot_x = |ang: f64| (m * offset_rotation(0.0, 0.0, -ang) * v).x;
    [phi + delta, phi - delta]
        .into_iter()
        .map(|ang| {
            (ang + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
        })
        .find(|&ang| foot_x(ang) > 0.0)
}

/// Writes the offsets into the template: parameter scalars become nominal values
/// (`p = value / scale`), fixed scalars take the value. Parameters that no offset reads keep
/// their template value.
pub(crate) fn fill_offsets(spec: &mut ModelSpec, offsets: &Offsets) {
    let mut values: HashMap<String, f64> = HashMap::new();
    for joint in &mut spec.joints {
        let Some((parent, child)) = offsets.get(&joint.name) else {
            continue;
        };
        for (offset, vals) in [
            (&mut joint.parent_offset, parent),
            (&mut joint.child_offset, child),
        ] {
            for (scalar, &v) in offset.scalars_mut().into_iter().zip(vals) {
                match scalar.as_param() {
                    Some((name, scale)) => {
                        // `+ 0.0` turns −0.0 (a mirrored zero) into 0.0.
                        values.insert(name.to_string(), v / scale + 0.0);
                    }
                    None => *scalar = ScalarSpec::Fixed(v),
                }
            }
        }
    }
    for p in &mut spec.parameters {
        if let Some(&v) = values.get(&p.name) {
            p.nominal = v;
        }
    }
}

/// Reinbolt's bounds around the nominal values: every angle ±30°; hip positions in a cube of
/// side 0.75·PW; knee positions in a cube of side knee width; ankle (talocrural and subtalar)
/// positions in a cube of side inter-malleolar distance.
pub(crate) fn set_bounds(spec: &mut ModelSpec, an: &Anatomy) {
    for p in &mut spec.parameters {
        let half = match (p.unit, p.group.as_str()) {
            (Unit::Radian, _) => 30f64.to_radians(),
            (Unit::Metre, "hip") => 0.375 * an.pelvis_width,
            (Unit::Metre, "knee") => 0.5 * an.knee_width,
            (Unit::Metre, _) => 0.5 * an.ankle_width,
        };
        p.lower = p.nominal - half;
        p.upper = p.nominal + half;
    }
}

/// `R = Rz(a)·Rx(b)·Ry(c)` → (a, b, c), with `b ∈ [−π/2, π/2]`.
pub(crate) fn decompose_zxy(r: &Matrix3<f64>) -> (f64, f64, f64) {
    let b = r[(2, 1)].clamp(-1.0, 1.0).asin();
    let a = (-r[(0, 1)]).atan2(r[(1, 1)]);
    let c = (-r[(2, 0)]).atan2(r[(2, 2)]);
    (a, b, c)
}

/// The rotation angle of `r` about the unit axis `axis` (r must be a rotation about it).
fn angle_about(r: &Matrix3<f64>, axis: &Vector3<f64>) -> f64 {
    let vee = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) * 0.5;
    axis.dot(&vee).atan2(0.5 * (r.trace() - 1.0))
}

/// The coordinates that put every segment of `model` on its frame in `poses` (by segment
/// name): each joint's motion `pjf⁻¹ · cjf` decomposed along the joint's own axes.
pub(crate) fn static_coordinates(
    model: &Model,
    offsets: &Offsets,
    poses: &[(&str, Pose)],
) -> Result<Vec<f64>, LandmarkError> {
    let pose = |name: &str| {
        poses
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| *p)
            .ok_or_else(|| LandmarkError::Internal(format!("no frame for segment {name:?}")))
    };
    let mut q = vec![0.0; model.coordinates().len()];
    for joint in model.joints() {
        let (po, co) = offsets
            .get(&joint.name)
            .ok_or_else(|| LandmarkError::Internal(format!("no offsets for {:?}", joint.name)))?;
        let parent = match joint.parent {
            Some(s) => pose(&model.segments()[s.0].name)?,
            None => Pose::identity(),
        };
        let child = pose(&model.segments()[joint.child.0].name)?;
        let m = (parent * pose_of(po)).inverse() * (child * pose_of(co));
        let k = joint.coords.start;
        let zxy = |axes: &[Vector3<f64>]| -> Result<[f64; 3], LandmarkError> {
            let signs = [axes[0].z, axes[1].x, axes[2].y];
            if signs.iter().any(|s| (s.abs() - 1.0).abs() > 1e-12) {
                return Err(LandmarkError::Internal(format!(
                    "joint {:?}: expected rotation axes ±z, ±x, ±y",
                    joint.name
                )));
            }
            // A rotation about −x by b is Rx(−b): decompose the plain z-x-y sequence and
            // apply each axis's sign to its angle.
            let (a, b, c) = decompose_zxy(&m.rot);
            Ok([signs[0] * a, signs[1] * b, signs[2] * c])
        };
        match &joint.kind {
            JointKind::Free { rotation_axes } => {
                q[k..k + 3].copy_from_slice(m.trans.as_slice());
                q[k + 3..k + 6].copy_from_slice(&zxy(rotation_axes)?);
            }
            JointKind::Gimbal { axes } => q[k..k + 3].copy_from_slice(&zxy(axes)?),
            JointKind::Pin { axis } => q[k] = angle_about(&m.rot, axis),
            other => {
                return Err(LandmarkError::Internal(format!(
                    "joint {:?}: unexpected kind {}",
                    joint.name, other
                )))
            }
        }
    }
    Ok(q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::lower_limb;

    #[test]
    fn zxy_round_trip() {
        for (a, b, c) in [(0.3, -0.2, 1.1), (2.9, 1.2, -3.0), (-1.0, 0.0, 0.5)] {
            let r = offset_rotation(0.0, 0.0, a)
                * offset_rotation(b, 0.0, 0.0)
                * offset_rotation(0.0, c, 0.0);
            let (x, y, z) = decompose_zxy(&r);
            assert!((x - a).abs() < 1e-12 && (y - b).abs() < 1e-12 && (z - c).abs() < 1e-12);
        }
    }

    #[test]
    fn pin_angles_invert_the_axis_formula() {
        let (rx, ry) = (0.2, -0.4);
        let d = offset_rotation(rx, ry, 0.0) * Vector3::z();
        let (a, b) = pin_z_angles(&d);
        assert!((a - rx).abs() < 1e-14 && (b - ry).abs() < 1e-14);
    }

    /// The closed form agrees with the template's bisection on its own nominal values.
    #[test]
    fn levelling_matches_the_template() {
        for side in [Side::Right, Side::Left] {
            let spec = lower_limb(side);
            let model = Model::compile(&spec).unwrap();
            let p = model.nominal_params();
            let val = |s: &ScalarSpec| match s {
                ScalarSpec::Fixed(v) => *v,
                _ => {
                    let (n, scale) = s.as_param().unwrap();
                    scale * p[model.param_id(n).unwrap().0]
                }
            };
            let off = |name: &str, parent: bool| -> Offset {
                let j = spec.joints.iter().find(|j| j.name == name).unwrap();
                let o = if parent {
                    &j.parent_offset
                } else {
                    &j.child_offset
                };
                o.scalars().map(val)
            };
            let c = levelling_angle(
                &off("knee", true),
                &off("knee", false),
                &off("talocrural", true),
                &off("subtalar", true),
                &off("subtalar", false),
            )
            .unwrap();
            let template = off("talocrural", false)[5];
            assert!((c - template).abs() < 1e-12, "{side:?}: {c} vs {template}");
        }
    }
}
