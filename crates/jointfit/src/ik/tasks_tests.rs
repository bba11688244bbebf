//! Coordinate tasks in the objective and the solvability rule, against an independent
//! evaluation of the stated objective (forward kinematics and central differences) and the
//! explicit marker Jacobian.

use nalgebra::{DMatrix, Vector3};

use super::{solve_frame, CoordinateTask, FrameStatus, IkOptions, IkWorkspace};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::spec::MarkerSpec;
use crate::model::Model;

/// A pose away from the defaults (rad, m).
fn pose(model: &Model) -> Vec<f64> {
    let mut q = model.default_coords();
    for (name, v) in [
        ("pelvis_tilt", 0.1),
        ("pelvis_list", -0.05),
        ("pelvis_rotation", 0.2),
        ("hip_flexion", 0.4),
        ("hip_adduction", 0.1),
        ("hip_rotation", -0.15),
        ("knee_flexion", 0.6),
        ("ankle_dorsiflexion", 0.2),
        ("subtalar_inversion", -0.1),
    ] {
        q[model.coord_id(name).unwrap()] = v;
    }
    q
}

fn markers_at(model: &Model, p: &[f64], q: &[f64]) -> Vec<Vector3<f64>> {
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::Positions, &mut kin);
    kin.markers.clone()
}

/// The objective of `super::tasks`, evaluated from scratch:
/// `Σ w_j ‖x_j(q) − m_j‖² + W Σ w_c (q_c − q̂_c)²`, `W = Σ w_j` over present markers.
fn objective(
    model: &Model,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    goals: &[(usize, f64, f64)],
) -> f64 {
    let x = markers_at(model, p, q);
    let mut cost = 0.0;
    let mut total = 0.0;
    for (j, m) in model.markers().iter().enumerate() {
        if targets[j].x.is_nan() {
            continue;
        }
        cost += m.weight * (x[j] - targets[j]).norm_squared();
        total += m.weight;
    }
    cost + goals
        .iter()
        .map(|&(c, w, v)| total * w * (q[c] - v).powi(2))
        .sum::<f64>()
}

/// With coordinate tasks pulling the knee and the hip away from where the markers put them,
/// the solution is a stationary point of the stated objective (central differences, step
/// 1e-6), its reported cost is that objective, and each task coordinate lies between the
/// markers-only solution and its task's target.
#[test]
fn coordinate_tasks_minimise_the_stated_objective() {
    let mut spec = lower_limb(Side::Right);
    // Unequal marker weights, so the task scale W = Σ w_j is not the marker count.
    for (j, m) in spec.markers.iter_mut().enumerate() {
        m.weight = 0.5 + 0.25 * (j % 4) as f64;
    }
    let model = Model::compile(&spec).unwrap();
    let p = model.nominal_params();
    let truth = pose(&model);
    let mut targets = markers_at(&model, &p, &truth);
    // A few millimetres of fixed, uneven "noise".
    for (j, t) in targets.iter_mut().enumerate() {
        let s = j as f64;
        *t += Vector3::new(
            0.003 * (s * 1.3).sin(),
            0.002 * (s * 0.7).cos(),
            -0.002 * s.sin(),
        );
    }
    let knee = model.coord_id("knee_flexion").unwrap();
    let hip = model.coord_id("hip_flexion").unwrap();
    let opts = IkOptions {
        step_tolerance: 1e-12,
        outlier_distance: f64::INFINITY,
        ..IkOptions::default()
    };
    let mut ws = IkWorkspace::new(&model);
    let mut free = truth.clone();
    solve_frame(&model, &p, &targets, &mut free, &opts, &mut ws);
    let tasks = vec![
        CoordinateTask {
            coordinate: knee,
            weight: 0.3,
            values: vec![truth[knee] + 0.3],
        },
        CoordinateTask {
            coordinate: hip,
            weight: 2.0,
            values: vec![truth[hip] - 0.2],
        },
    ];
    let goals = [(knee, 0.3, truth[knee] + 0.3), (hip, 2.0, truth[hip] - 0.2)];
    ws.set_coordinate_goals(&tasks, 0);
    let mut q = truth.clone();
    let fit = solve_frame(&model, &p, &targets, &mut q, &opts, &mut ws);
    assert_eq!(fit.status, FrameStatus::Converged);
    let f0 = objective(&model, &p, &q, &targets, &goals);
    assert!((fit.cost - f0).abs() <= 1e-12 * f0, "{} vs {f0}", fit.cost);
    let h = 1e-6;
    for i in 0..model.coordinates().len() {
        let mut a = q.clone();
        let mut b = q.clone();
        a[i] += h;
        b[i] -= h;
        let grad = (objective(&model, &p, &a, &targets, &goals)
            - objective(&model, &p, &b, &targets, &goals))
            / (2.0 * h);
        assert!(grad.abs() < 1e-7, "coordinate {i}: dF/dq = {grad}");
    }
    for &(c, _, v) in &goals {
        let (lo, hi) = if free[c] < v {
            (free[c], v)
        } else {
            (v, free[c])
        };
        assert!(
            q[c] > lo + 1e-4 && q[c] < hi - 1e-4,
            "{c}: {} not in ({lo}, {hi})",
            q[c]
        );
    }
    // Without tasks again, the same workspace gives the markers-only solution.
    ws.set_coordinate_goals(&[], 0);
    let mut again = truth.clone();
    solve_frame(&model, &p, &targets, &mut again, &opts, &mut ws);
    for (a, b) in again.iter().zip(&free) {
        assert!((a - b).abs() < 1e-9);
    }
}

/// A coordinate with a task is determined whatever the markers: without foot markers the
/// ankle and subtalar angles are undetermined, with tasks on them the frame is solved and
/// they sit exactly at the tasks' targets (no marker depends on them).
#[test]
fn a_task_determines_its_coordinate() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let truth = pose(&model);
    let mut targets = markers_at(&model, &p, &truth);
    for (j, m) in model.markers().iter().enumerate() {
        if ["RHEE", "RTOE", "RMT5"].contains(&m.name.as_str()) {
            targets[j] = Vector3::repeat(f64::NAN);
        }
    }
    let ankle = model.coord_id("ankle_dorsiflexion").unwrap();
    let subtalar = model.coord_id("subtalar_inversion").unwrap();
    let opts = IkOptions::default();
    let mut ws = IkWorkspace::new(&model);
    let mut q = truth.clone();
    let fit = solve_frame(&model, &p, &targets, &mut q, &opts, &mut ws);
    assert!(
        matches!(fit.status, FrameStatus::Undetermined { .. }),
        "{:?}",
        fit.status
    );
    let tasks: Vec<CoordinateTask> = [(ankle, 0.15), (subtalar, -0.05)]
        .iter()
        .map(|&(c, v)| CoordinateTask {
            coordinate: c,
            weight: 1.0,
            values: vec![v],
        })
        .collect();
    ws.set_coordinate_goals(&tasks, 0);
    let mut q = truth.clone();
    q[ankle] = 0.0;
    q[subtalar] = 0.0;
    let fit = solve_frame(&model, &p, &targets, &mut q, &opts, &mut ws);
    assert_eq!(fit.status, FrameStatus::Converged);
    assert!((q[ankle] - 0.15).abs() < 1e-9 && (q[subtalar] + 0.05).abs() < 1e-9);
    for (c, (a, b)) in q.iter().zip(&truth).enumerate() {
        if c != ankle && c != subtalar {
            assert!((a - b).abs() < 1e-7, "coordinate {c}: {a} vs {b}");
        }
    }
}

/// A single shank marker 17 mm from the knee axis (the lever of a wrist marker about the
/// pronation axis) determines the knee once the thigh is known: 1 mm of noise moves the knee
/// by 1/17 rad (3.4°), far inside the rank tolerance. The explicit Jacobian confirms the
/// lever and the full rank; the frame is solved exactly with only the foot held. Under the
/// earlier rule (2° per mm) the knee was undetermined.
#[test]
fn a_single_marker_off_a_pin_axis_determines_it() {
    let mut spec = lower_limb(Side::Right);
    spec.markers
        .retain(|m| m.segment != "shank" && m.segment != "foot");
    spec.markers.push(MarkerSpec {
        name: "RSHK".into(),
        segment: "shank".into(),
        position: [0.017, 0.0, 0.06],
        weight: 1.0,
    });
    let model = Model::compile(&spec).unwrap();
    let p = model.nominal_params();
    let truth = pose(&model);
    let targets = markers_at(&model, &p, &truth);
    let knee = model.coord_id("knee_flexion").unwrap();
    let ankle = model.coord_id("ankle_dorsiflexion").unwrap();
    let subtalar = model.coord_id("subtalar_inversion").unwrap();
    // Oracle: the explicit Jacobian at the truth.
    let mut kin = KinData::new(&model);
    forward_kinematics(&model, &p, &truth, Want::Dq, &mut kin);
    let jq = kin.jq;
    let shk = model
        .markers()
        .iter()
        .position(|m| m.name == "RSHK")
        .unwrap();
    let lever = (0..3)
        .map(|k| jq[(3 * shk + k, knee)].powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((lever - 0.017).abs() < 0.002, "lever {lever}");
    let cols: Vec<usize> = (0..model.coordinates().len())
        .filter(|&c| c != ankle && c != subtalar)
        .collect();
    let j = DMatrix::from_fn(jq.nrows(), cols.len(), |r, c| jq[(r, cols[c])]);
    assert!(j.singular_values().min() > 1e-3);
    let weights = vec![1.0; model.markers().len()];
    let known = vec![false; model.coordinates().len()];
    let mut ws = IkWorkspace::new(&model);
    let mut verdict = ws
        .solvability
        .undetermined(&model, &p, &weights, &known, &IkOptions::default())
        .to_vec();
    verdict.sort();
    let mut foot = vec![ankle, subtalar];
    foot.sort();
    assert_eq!(verdict, foot);
    let strict = IkOptions {
        max_angle_per_mm: 2f64.to_radians(),
        max_translation_per_mm: 0.01,
        ..IkOptions::default()
    };
    let mut ws_strict = IkWorkspace::new(&model);
    assert!(ws_strict
        .solvability
        .undetermined(&model, &p, &weights, &known, &strict)
        .contains(&knee));
    let opts = IkOptions {
        hold_undetermined: true,
        ..IkOptions::default()
    };
    let mut q = truth.clone();
    q[knee] += 0.2;
    let fit = solve_frame(&model, &p, &targets, &mut q, &opts, &mut ws);
    assert!(fit.solved(), "{:?}", fit.status);
    assert!((q[knee] - truth[knee]).abs() < 1e-8);
}

/// With `hold_undetermined`, a trial whose markers never determine the foot is solved from
/// its first frame on, the foot held where the seed puts it (its defaults), as OpenSim's IK
/// leaves a coordinate no goal depends on; the other coordinates are exact.
#[test]
fn held_from_the_first_frame_at_the_defaults() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let ankle = model.coord_id("ankle_dorsiflexion").unwrap();
    let subtalar = model.coord_id("subtalar_inversion").unwrap();
    let knee = model.coord_id("knee_flexion").unwrap();
    let truth: Vec<Vec<f64>> = (0..20)
        .map(|f| {
            let mut q = pose(&model);
            q[knee] += 0.02 * f as f64;
            q
        })
        .collect();
    let mut positions = Vec::new();
    for q in &truth {
        for (j, x) in markers_at(&model, &p, q).into_iter().enumerate() {
            let foot = ["RHEE", "RTOE", "RMT5"].contains(&model.markers()[j].name.as_str());
            positions.push(if foot { Vector3::repeat(f64::NAN) } else { x });
        }
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = crate::trial::Trial::new(labels, 100.0, 1, positions).unwrap();
    let map = super::MarkerMap::by_name(&model, trial.labels()).unwrap();
    let opts = IkOptions {
        hold_undetermined: true,
        ..IkOptions::default()
    };
    let fit = super::trial_fit::solve_trial(&model, &p, &trial, &map, &opts).unwrap();
    let defaults = model.default_coords();
    for (f, q) in fit.coords.iter().enumerate() {
        assert!(
            fit.frames[f].solved(),
            "frame {f}: {:?}",
            fit.frames[f].status
        );
        assert_eq!(
            (q[ankle], q[subtalar]),
            (defaults[ankle], defaults[subtalar])
        );
        for c in (0..model.coordinates().len()).filter(|&c| c != ankle && c != subtalar) {
            assert!(
                (q[c] - truth[f][c]).abs() < 1e-7,
                "frame {f}, coordinate {c}"
            );
        }
    }
}
