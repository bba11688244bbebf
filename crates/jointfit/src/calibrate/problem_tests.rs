//! Tests of [`super::Problem`] and [`super::params_for_groups`].

use super::*;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use nalgebra::Vector3;

/// An unknown group name is answered with every name `params_for_groups` accepts: `all`,
/// the side-less names, then the model's groups; each listed name is accepted.
#[test]
fn unknown_group_lists_the_accepted_names() {
    for spec in [
        lower_limb(Side::Right),
        crate::model::lower_limb::bilateral::bilateral(),
    ] {
        let model = Model::compile(&spec).unwrap();
        let e = params_for_groups(&model, &["knees"])
            .unwrap_err()
            .to_string();
        let list = e.split("the groups are: ").nth(1).unwrap();
        assert!(e.starts_with("unknown parameter group \"knees\""), "{e}");
        assert!(list.starts_with("all, hip, knee, ankle"), "{e}");
        for g in model.groups() {
            assert!(list.split(", ").any(|n| n == g), "{g}: {e}");
        }
        for name in list.split(", ") {
            assert!(params_for_groups(&model, &[name]).is_ok(), "{name}");
        }
    }
}

/// The chunked passes give the same bits on 1, 2 and 3 threads, and the starting
/// coordinates are those of the IK's own chunked warm start on the copied targets.
#[test]
fn inner_and_initial_coords_do_not_depend_on_the_thread_count() {
    // 2100 frames: four seeded chunks, nine partial sums; 150: two chunks, one sum.
    for frames in [2100, 150] {
        thread_count_case(frames);
    }
}

/// A smooth motion of `frames` frames at the nominal parameters, every marker 2 mm off in a
/// pattern of its own; with the coordinates that made it.
fn wavy_trial(model: &Model, frames: usize) -> (Trial, Vec<Vec<f64>>) {
    let p = model.nominal_params();
    let mut kin = KinData::new(model);
    let mut positions = Vec::new();
    let mut truth = Vec::new();
    for f in 0..frames {
        let mut q = model.default_coords();
        for (i, v) in q.iter_mut().enumerate() {
            *v += 0.3 * (0.01 * f as f64 + i as f64).sin();
        }
        forward_kinematics(model, &p, &q, Want::Positions, &mut kin);
        for (j, x) in kin.markers.iter().enumerate() {
            positions.push(x + Vector3::repeat(0.002 * ((f * 7 + j) as f64).sin()));
        }
        truth.push(q);
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    (Trial::new(labels, 100.0, 1, positions).unwrap(), truth)
}

/// Frames started from another solution near theirs (here the coordinates that made the
/// trial) reach the solutions of the warm-started chain, to the starting tolerance; the
/// others too, and the given starts were used (the bits differ).
#[test]
fn starting_coordinates_near_another_solution_reach_the_same_solutions() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let (trial, truth) = wavy_trial(&model, 150);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, p.clone(), &free, &[&trial]).unwrap();
    let chain = prob.initial_coords(&p);
    let near = prob.initial_coords_near(&p, &|f| (f % 3 != 0).then_some(truth[f].as_slice()));
    let mut worst: f64 = 0.0;
    for (a, b) in chain.iter().zip(&near) {
        for (x, y) in a.iter().zip(b) {
            worst = worst.max((x - y).abs());
        }
    }
    assert!(worst < 1e-4, "{worst}");
    assert!((0..150).any(|f| f % 3 != 0 && chain[f] != near[f]));
}

fn thread_count_case(frames: usize) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let (trial, _) = wavy_trial(&model, frames);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, p.clone(), &free, &[&trial]).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut q = prob.initial_coords(&p);
            let q0 = q.clone();
            let cost = prob.inner(&p, &mut q, &mut IkWorkspace::new(&model));
            (q0, q, cost.to_bits())
        })
    };
    let one = run(1);
    assert_eq!(one.0.len(), frames);
    assert!(f64::from_bits(one.2) > 0.0);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    // Oracle: the frames solved one after the other with one workspace, summed in frame
    // order within each chunk of INNER_CHUNK frames (the sum of the serial code before
    // the frames were split into tasks).
    let mut ws = IkWorkspace::new(&model);
    let mut q = one.0.clone();
    let mut buf = Vec::new();
    let mut sums = Vec::new();
    for (f, q) in q.iter_mut().enumerate() {
        if f % INNER_CHUNK == 0 {
            sums.push(0.0);
        }
        let targets = prob.frames.fill(f, &mut buf);
        *sums.last_mut().unwrap() += solve_frame(&model, &p, targets, q, &prob.ik, &mut ws).cost;
    }
    let serial: f64 = sums.iter().sum::<f64>() + prob.prior_cost(&p);
    assert_eq!(serial.to_bits(), one.2);
    assert_eq!(q, one.1);
    if frames >= 1024 {
        // Here the IK's chunks are the calibration's.
        let copied: Vec<Vec<Vector3<f64>>> = prob.frames.iter().collect();
        let ik = crate::ik::warm_started_coords(&model, &p, &copied, |f| f == 0, &prob.start_ik());
        assert_eq!(one.0, ik);
    }
}

/// `Problem::inner`'s tasks: never longer than `INNER_TASK`, and an even number of them on a
/// short trial (two threads take half each).
#[test]
fn inner_tasks_split_a_short_trial_evenly() {
    assert_eq!(inner_task_len(143), 15);
    for n in INNER_TASK + 1..=2000 {
        let len = inner_task_len(n);
        let tasks = n.div_ceil(len);
        assert!(len <= INNER_TASK, "{n} frames: {tasks} × {len}");
        if n <= 224 {
            assert_eq!(tasks % 2, 0, "{n} frames: {tasks} tasks of {len}");
        }
    }
}
