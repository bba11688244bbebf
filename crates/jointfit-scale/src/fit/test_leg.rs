//! The sample leg scaled by known factors, seen by markers without noise: the truth the fit's
//! tests recover.

use nalgebra::Vector3;

use super::{ScaleFit, ScaleGroup};
use crate::geometry::{scaled_spec, ScaleFactors};
use crate::groups::default_groups;
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;

/// Factors per group, the thigh's per axis.
pub(super) const TRUTH: [(&str, [f64; 3]); 4] = [
    ("pelvis", [1.06; 3]),
    ("thigh", [1.02, 1.13, 0.97]),
    ("shank", [0.92; 3]),
    ("foot", [1.04; 3]),
];

/// One factor per group.
pub(super) const UNIFORM_TRUTH: [(&str, [f64; 3]); 4] = [
    ("pelvis", [1.06; 3]),
    ("thigh", [1.1; 3]),
    ("shank", [0.92; 3]),
    ("foot", [1.04; 3]),
];

/// The leg's markers with each group's bodies at `truth`'s factors, in `n` poses: frame `f`
/// puts coordinate `k` at its default plus `amplitude · sin(1.7k + 2.1f)`.
fn frames_at(
    spec: &ModelSpec,
    groups: &[ScaleGroup],
    truth: &[(&str, [f64; 3])],
    amplitude: f64,
    n: usize,
) -> Vec<Vec<Vector3<f64>>> {
    let mut factors = ScaleFactors::new();
    for (name, s) in truth {
        let g = groups.iter().find(|g| g.name == *name).unwrap();
        for b in &g.bodies {
            factors.insert(b.clone(), *s);
        }
    }
    let scaled = Model::compile(&scaled_spec(spec, &factors)).unwrap();
    let mut data = KinData::new(&scaled);
    (0..n)
        .map(|f| {
            let mut q = scaled.default_coords();
            for (k, v) in q.iter_mut().enumerate() {
                *v += amplitude * ((k as f64) * 1.7 + f as f64 * 2.1).sin();
            }
            let p = scaled.nominal_params();
            forward_kinematics(&scaled, &p, &q, Want::Positions, &mut data);
            data.markers.clone()
        })
        .collect()
}

/// The leg's groups (the thigh per axis) and its markers scaled by [`TRUTH`], at a pose
/// away from the default.
pub(super) fn scaled_leg() -> (ModelSpec, Vec<ScaleGroup>, Vec<Vector3<f64>>) {
    let spec = lower_limb(Side::Right);
    let mut groups = default_groups(&spec, false, false);
    for g in groups.iter_mut() {
        g.per_axis = g.name == "thigh";
    }
    let mut frames = frames_at(&spec, &groups, &TRUTH, 0.05, 1);
    (spec, groups, frames.remove(0))
}

/// `n` frames of the leg scaled by [`UNIFORM_TRUTH`], at poses far apart.
pub(super) fn leg_frames(n: usize) -> (ModelSpec, Vec<ScaleGroup>, Vec<Vec<Vector3<f64>>>) {
    let spec = lower_limb(Side::Right);
    let groups = default_groups(&spec, false, false);
    let frames = frames_at(&spec, &groups, &UNIFORM_TRUTH, 0.3, n);
    (spec, groups, frames)
}

/// Largest difference between fitted and true ([`TRUTH`]) factors.
pub(super) fn factor_error(fit: &ScaleFit) -> f64 {
    let mut worst: f64 = 0.0;
    for (name, s) in TRUTH {
        let g = fit.groups.iter().find(|g| g.name == name).unwrap();
        for (f, t) in g.factors.iter().zip(s) {
            worst = worst.max((f - t).abs());
        }
    }
    worst
}

/// `frames` with `noise()` added to every coordinate of every marker (m).
pub(super) fn with_noise(
    frames: &[Vec<Vector3<f64>>],
    mut noise: impl FnMut() -> f64,
) -> Vec<Vec<Vector3<f64>>> {
    frames
        .iter()
        .map(|fr| {
            fr.iter()
                .map(|m| m + Vector3::from_fn(|_, _| noise()))
                .collect()
        })
        .collect()
}
