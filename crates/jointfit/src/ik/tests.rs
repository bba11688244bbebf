//! Inverse kinematics against known synthetic truth.

use crate::ik::lm::solve_frame;
use crate::ik::lm::IkWorkspace;
use crate::ik::trial_fit::{rms, solve_trial};
use crate::ik::{FrameStatus, IkOptions, MarkerMap};
use crate::kinematics::synth;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::trial::Trial;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

fn random_params(model: &Model, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    model
        .parameters()
        .iter()
        .map(|p| p.nominal + rng.gen_range(-0.3..0.3) * (p.upper - p.lower) / 2.0)
        .collect()
}

#[test]
fn recovers_known_coordinates_exactly() {
    for side in [Side::Right, Side::Left] {
        let model = Model::compile(&lower_limb(side)).unwrap();
        let p = random_params(&model, 7);
        // Heading 180°: the subject walks towards −x; the seed must still find the pelvis.
        for heading in [0.0, std::f64::consts::PI, 2.0] {
            let (trial, truth) = synthetic_trial(&model, &p, 60, heading);
            let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
            let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
            for (f, q) in truth.iter().enumerate() {
                assert_eq!(fit.frames[f].status, FrameStatus::Converged, "frame {f}");
                for (i, (a, b)) in fit.coords[f].iter().zip(q).enumerate() {
                    // Angles compared modulo 2π.
                    let d = (a - b + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                        - std::f64::consts::PI;
                    assert!(
                        d.abs() <= 1e-9,
                        "{side:?} heading {heading} frame {f} coordinate {} off by {d:e}",
                        model.coordinates()[i].name
                    );
                }
            }
            let overall = rms(fit.errors.iter().flatten().copied());
            assert!(overall < 1e-10, "rms {overall}");
        }
    }
}

#[test]
fn missing_markers_drop_out_and_sparse_frames_are_solved() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let (mut trial, truth) = synthetic_trial(&model, &p, 20, 0.0);
    let nan = Vector3::repeat(f64::NAN);
    let n = trial.labels().len();
    let col = |name: &str| trial.index_of(name).unwrap();
    let (thi, kne, tib, tia) = (col("RTHI"), col("RKNE"), col("RTIB"), col("RTIA"));
    let pos = trial.positions_mut();
    // Frame 5: one thigh marker missing (3 of 4 left): still solved exactly.
    pos[5 * n + thi] = nan;
    // Frame 9: two shank markers missing (2 of 4 left).
    pos[9 * n + tib] = nan;
    pos[9 * n + tia] = nan;
    // Frame 10 carries on from frame 8's solution.
    pos[10 * n + kne] = nan;
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    assert_eq!(fit.frames[5].status, FrameStatus::Converged);
    let rthi = model.markers().iter().position(|m| m.name == "RTHI");
    assert!(fit.errors[5][rthi.unwrap()].is_nan());
    assert!(fit.coords[5]
        .iter()
        .zip(&truth[5])
        .all(|(a, b)| (a - b).abs() < 1e-9));
    // Frame 9: two shank markers are enough for the knee's one coordinate (the chain
    // determines the rest): solved exactly.
    assert_eq!(fit.frames[9].status, FrameStatus::Converged);
    assert!(fit.coords[9]
        .iter()
        .zip(&truth[9])
        .all(|(a, b)| (a - b).abs() < 1e-9));
    assert!(fit.coords[10]
        .iter()
        .zip(&truth[10])
        .all(|(a, b)| (a - b).abs() < 1e-9));
    // Overall statistics skip the unsolved frame and the missing samples.
    assert!(rms(fit.errors.iter().flatten().copied()) < 1e-10);
}

#[test]
fn missing_model_markers_are_named() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let labels: Vec<String> = ["RASI", "LASI", "RPSI"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let e = MarkerMap::by_name(&model, &labels).unwrap_err().to_string();
    assert!(
        e.starts_with("the trial lacks model markers [\"LPSI\", \"RTHI\""),
        "{e}"
    );
    assert!(e.ends_with("it has: RASI, LASI, RPSI"), "{e}");
}

/// With noise, the solution is a stationary point of the weighted cost: the gradient JᵀWr
/// vanishes and no random nearby point has a lower cost.
/// The markers of frame `f` of [`motion`] with uniform noise of ±1 cm per axis.
fn noisy_targets(model: &Model, p: &[f64], f: usize, rng: &mut ChaCha8Rng) -> Vec<Vector3<f64>> {
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, &motion(model, f, 0.0), Want::Positions, &mut kin);
    kin.markers
        .iter()
        .map(|m| {
            m + Vector3::new(
                rng.gen_range(-0.01..0.01),
                rng.gen_range(-0.01..0.01),
                rng.gen_range(-0.01..0.01),
            )
        })
        .collect()
}

#[test]
fn noisy_frame_is_a_least_squares_minimum() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let q_true = motion(&model, 13, 0.0);
    let mut kin = KinData::new(&model);
    let targets = noisy_targets(&model, &p, 13, &mut rng);
    let mut q = q_true.clone();
    let mut ws = IkWorkspace::new(&model);
    let fit = solve_frame(&model, &p, &targets, &mut q, &IkOptions::default(), &mut ws);
    assert_eq!(fit.status, FrameStatus::Converged);
    forward_kinematics(&model, &p, &q, Want::Dq, &mut kin);
    let r: Vec<f64> = targets
        .iter()
        .zip(&kin.markers)
        .flat_map(|(t, x)| {
            let d = t - x;
            [d.x, d.y, d.z]
        })
        .collect();
    let grad = kin.jq.transpose() * nalgebra::DVector::from(r);
    // At the start the gradient is of order 1e-2 m²; the solver stops on a 1e-11 step.
    assert!(grad.amax() < 1e-9, "gradient {}", grad.amax());
    let cost = |q: &[f64], kin: &mut KinData| {
        forward_kinematics(&model, &p, q, Want::Positions, kin);
        targets
            .iter()
            .zip(&kin.markers)
            .map(|(t, x)| (t - x).norm_squared())
            .sum::<f64>()
    };
    let c0 = cost(&q, &mut kin);
    assert!((c0 - fit.cost).abs() < 1e-15);
    for _ in 0..50 {
        let qn: Vec<f64> = q.iter().map(|v| v + rng.gen_range(-1e-3..1e-3)).collect();
        assert!(cost(&qn, &mut kin) >= c0);
    }
}

/// A step tolerance no step can reach (0): the solve still ends at the minimum as converged,
/// once the step's predicted decrease is below the cost's rounding error, instead of damping
/// the step until the damping gives up (`Stalled`, 13 extra evaluations per frame on real
/// data at the calibration's tolerance of 1e-11). Its cost is the cost at that tolerance to
/// rounding, and every coordinate within 1e-10 of that solution.
#[test]
fn a_tolerance_below_working_precision_ends_converged_at_the_minimum() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut ws = IkWorkspace::new(&model);
    for f in [0, 13, 31, 47, 60, 77] {
        let targets = noisy_targets(&model, &p, f, &mut rng);
        let start = motion(&model, f, 0.0);
        let mut q_default = start.clone();
        let opts = IkOptions {
            step_tolerance: 1e-11,
            ..IkOptions::default()
        };
        let reference = solve_frame(&model, &p, &targets, &mut q_default, &opts, &mut ws);
        let exact = IkOptions {
            step_tolerance: 0.0,
            ..IkOptions::default()
        };
        let mut q = start.clone();
        let fit = solve_frame(&model, &p, &targets, &mut q, &exact, &mut ws);
        assert_eq!(fit.status, FrameStatus::Converged, "frame {f}");
        assert!(
            fit.iterations < 20,
            "frame {f}: {} iterations",
            fit.iterations
        );
        assert!(fit.cost <= reference.cost * (1.0 + 1e-12), "frame {f}");
        let apart = q.iter().zip(&q_default).map(|(a, b)| (a - b).abs());
        let apart = apart.fold(0.0, f64::max);
        assert!(apart < 1e-10, "frame {f}: {apart:e} apart");
    }
}
