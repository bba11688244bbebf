//! OpenSim's `clamped` coordinates bound the IK (`IkOptions::clamp`, projected Gauss-Newton in
//! `ik/lm.rs`), against an independent oracle: the first-order optimality (KKT) conditions of
//! the box-bounded least squares by central finite differences of the cost, and random
//! feasible points that must not fit better.

use crate::ik::lm::solve_frame;
use crate::ik::lm::IkWorkspace;
use crate::ik::IkOptions;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::spec::CoordinateSpec;
use crate::model::Model;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The right leg with `knee_flexion` and `hip_adduction` clamped to the given ranges (deg).
pub(crate) fn clamped_leg(knee: [f64; 2], hip_adduction: [f64; 2]) -> Model {
    let mut spec = lower_limb(Side::Right);
    for j in &mut spec.joints {
        for c in &mut j.coordinates {
            if let CoordinateSpec::Full {
                name,
                range,
                clamped,
                ..
            } = c
            {
                let r = match name.as_str() {
                    "knee_flexion" => knee,
                    "hip_adduction" => hip_adduction,
                    _ => continue,
                };
                *range = Some([r[0] * DEG, r[1] * DEG]);
                *clamped = true;
            }
        }
    }
    Model::compile(&spec).unwrap()
}

fn cost(model: &Model, p: &[f64], q: &[f64], targets: &[Vector3<f64>]) -> f64 {
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::Positions, &mut kin);
    kin.markers
        .iter()
        .zip(targets)
        .zip(model.markers())
        .map(|((x, t), m)| m.weight * (t - x).norm_squared())
        .sum()
}

#[test]
fn clamped_coordinates_stop_at_their_bounds_and_the_rest_is_optimal() {
    // Truth: knee 40° and hip adduction −12°, outside the clamped ranges [0°, 25°] and
    // [−5°, 30°]; the markers carry 3 mm of noise. With the knee held at 25° the other
    // coordinates compensate (the adduction ends inside its range).
    let model = clamped_leg([0.0, 25.0], [-5.0, 30.0]);
    let p = model.nominal_params();
    let names: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let idx = |n: &str| names.iter().position(|x| *x == n).unwrap();
    let (knee, add) = (idx("knee_flexion"), idx("hip_adduction"));
    let mut truth: Vec<f64> = model.coordinates().iter().map(|c| c.default).collect();
    truth[idx("pelvis_ty")] = 0.9;
    truth[idx("hip_flexion")] = 20.0 * DEG;
    truth[add] = -12.0 * DEG;
    truth[knee] = 40.0 * DEG;
    truth[idx("ankle_dorsiflexion")] = 5.0 * DEG;
    let mut kin = KinData::new(&model);
    forward_kinematics(&model, &p, &truth, Want::Positions, &mut kin);
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let targets: Vec<Vector3<f64>> = kin
        .markers
        .iter()
        .map(|x| x + Vector3::from_fn(|_, _| rng.gen_range(-0.003..0.003)))
        .collect();

    let mut ws = IkWorkspace::new(&model);
    // Unbounded (`clamp: false`): near the truth, outside the ranges.
    let mut free = truth.clone();
    let plain = IkOptions {
        clamp: false,
        ..IkOptions::default()
    };
    assert!(solve_frame(&model, &p, &targets, &mut free, &plain, &mut ws).solved());
    assert!(
        free[knee] > 30.0 * DEG && free[add] < -8.0 * DEG,
        "{free:?}"
    );

    // Bounded, from the truth (outside the box) and from the default pose.
    for start in [truth.clone(), {
        let mut s = truth.clone();
        s[knee] = 0.0;
        s[add] = 0.0;
        s
    }] {
        let mut q = start;
        let fit = solve_frame(&model, &p, &targets, &mut q, &IkOptions::default(), &mut ws);
        assert!(fit.solved(), "{:?}", fit.status);
        assert_eq!(q[knee], 25.0 * DEG, "knee at its upper bound");
        assert!(q[add] >= -5.0 * DEG && q[add] <= 30.0 * DEG);
        // KKT by central differences: zero slope in every coordinate off its bounds; at a
        // bound the cost falls only outwards (knee up).
        let c0 = cost(&model, &p, &q, &targets);
        let h = 1e-6;
        let slope = |c: usize| {
            let (mut a, mut b) = (q.clone(), q.clone());
            a[c] += h;
            b[c] -= h;
            (cost(&model, &p, &a, &targets) - cost(&model, &p, &b, &targets)) / (2.0 * h)
        };
        for (c, name) in names.iter().enumerate() {
            let s = slope(c);
            if c == knee {
                assert!(s < -1e-4, "knee: the cost falls outwards, slope {s}");
            } else if c == add && q[add] == -5.0 * DEG {
                assert!(s > -1e-7, "adduction: the cost falls outwards, slope {s}");
            } else {
                assert!(s.abs() < 1e-7, "{name}: slope {s} at the optimum");
            }
        }
        // No feasible point nearby fits better.
        for _ in 0..300 {
            let mut x = q.clone();
            for v in x.iter_mut() {
                *v += rng.gen_range(-0.02..0.02);
            }
            x[knee] = x[knee].min(25.0 * DEG);
            x[add] = x[add].max(-5.0 * DEG);
            assert!(cost(&model, &p, &x, &targets) >= c0 - 1e-15);
        }
        assert!(c0 > cost(&model, &p, &free, &targets));
    }
}

/// A model without clamped coordinates solves to the same bits with `clamp` on and off.
#[test]
fn clamp_changes_nothing_without_clamped_coordinates() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    assert!(model.coordinates().iter().all(|c| !c.clamped));
    let p = model.nominal_params();
    let (trial, _) = super::tests::synthetic_trial(&model, &p, 20, 0.3);
    let map = crate::ik::MarkerMap::by_name(&model, trial.labels()).unwrap();
    let a =
        crate::ik::trial_fit::solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    let off = IkOptions {
        clamp: false,
        ..IkOptions::default()
    };
    let b = crate::ik::trial_fit::solve_trial(&model, &p, &trial, &map, &off).unwrap();
    assert_eq!(a.coords, b.coords);
}
