//! The walking-like motion of the leg model that the integration tests share (the core's
//! inverse-kinematics unit tests, `src/ik/tests.rs`, solve along the same motion).

use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_testkit::synth;

/// A smooth gait-like motion: q(t) for frame `f` (rad, m).
pub fn motion(model: &Model, f: usize, heading: f64) -> Vec<f64> {
    let t = f as f64 / 100.0;
    let w = 2.0 * std::f64::consts::PI;
    let mut q = model.default_coords();
    let set = |q: &mut Vec<f64>, name: &str, v: f64| q[model.coord_id(name).unwrap()] = v;
    set(&mut q, "pelvis_tx", 1.2 * t * heading.cos());
    set(&mut q, "pelvis_tz", -1.2 * t * heading.sin());
    set(&mut q, "pelvis_ty", 0.93 + 0.02 * (2.0 * w * t).sin());
    set(&mut q, "pelvis_rotation", heading + 0.1 * (w * t).sin());
    set(&mut q, "pelvis_tilt", 0.05 * (2.0 * w * t).cos());
    set(&mut q, "pelvis_list", 0.04 * (w * t).sin());
    set(&mut q, "hip_flexion", 0.3 + 0.45 * (w * t).sin());
    set(&mut q, "hip_adduction", 0.08 * (w * t + 0.5).sin());
    set(&mut q, "hip_rotation", 0.1 * (w * t).cos());
    set(&mut q, "knee_flexion", 0.6 + 0.55 * (w * t - 1.0).sin());
    set(&mut q, "ankle_dorsiflexion", 0.15 * (w * t + 0.3).sin());
    set(&mut q, "subtalar_inversion", 0.1 * (w * t).sin());
    q
}

/// Exact markers along the walking-like motion at 100 Hz, and the true coordinates.
pub fn synthetic_trial(
    model: &Model,
    p: &[f64],
    frames: usize,
    heading: f64,
) -> (Trial, Vec<Vec<f64>>) {
    let motion = |f: usize| motion(model, f, heading);
    let s = synth::synthetic_trial(model, p, frames, 100.0, motion, synth::Noise::None, 0);
    (s.trial, s.coords)
}
