//! IK of a trial and the calibration by each outer solver (one local fit from the nominal
//! parameters, no prior: the paper's protocol, through [`jointfit::workflow::calibration::calibrate`])
//! on a synthetic 150-frame trial of the leg model.
//!
//! `cargo bench -p jointfit --bench solvers`

use criterion::{criterion_group, criterion_main, Criterion};
use jointfit::calibrate::params_for_groups;
use jointfit::ik::trial_fit::solve_trial;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::{FitSettings, Method};
use nalgebra::Vector3;

/// Gait-like motion with ±5 mm sinusoidal marker noise, true parameters off nominal.
fn trial(model: &Model, p: &[f64], frames: usize) -> Trial {
    let w = std::f64::consts::TAU;
    let mut kin = KinData::new(model);
    let mut pos = Vec::new();
    for f in 0..frames {
        let t = f as f64 / frames as f64;
        let mut q = model.default_coords();
        let mut set = |n: &str, v: f64| q[model.coord_id(n).unwrap()] = v;
        set("pelvis_tx", 1.2 * t);
        set("pelvis_ty", 0.93);
        set("hip_flexion", 0.3 + 0.45 * (w * t).sin());
        set("hip_adduction", 0.1 * (w * t).cos());
        set("hip_rotation", 0.1 * (w * t).sin());
        set("knee_flexion", 0.6 + 0.55 * (w * t - 1.0).sin());
        set("ankle_dorsiflexion", 0.2 * (w * t).sin());
        set("subtalar_inversion", 0.1 * (w * t).cos());
        forward_kinematics(model, p, &q, Want::Positions, &mut kin);
        for (j, x) in kin.markers.iter().enumerate() {
            let a = 0.005 * ((j * 7 % 5) as f64 / 5.0);
            pos.push(
                x + Vector3::new(
                    a * (9.0 * t + j as f64).sin(),
                    a * (13.0 * t).cos(),
                    a * (5.0 * t + 1.0).sin(),
                ),
            );
        }
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    Trial::new(labels, 100.0, 1, pos).unwrap()
}

fn benches(c: &mut Criterion) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let mut truth = model.nominal_params();
    for (i, v) in truth.iter_mut().enumerate() {
        let par = &model.parameters()[i];
        *v += 0.2 * (par.upper - par.lower) * if i % 2 == 0 { 0.5 } else { -0.5 };
    }
    let gait = trial(&model, &truth, 150);
    let map = MarkerMap::by_name(&model, gait.labels()).unwrap();
    let nominal = model.nominal_params();
    let mut g = c.benchmark_group("solvers");
    g.sample_size(10);
    g.bench_function("ik_150_frames", |b| {
        b.iter(|| solve_trial(&model, &nominal, &gait, &map, &IkOptions::default()).unwrap())
    });
    let all = params_for_groups(&model, &["all"]).unwrap();
    // One local fit from the start, no prior, no uncertainty analysis.
    let paper = |method| FitSettings {
        method,
        probes: 0,
        priors: false,
        ..FitSettings::default()
    };
    let fit = |method, free: &[jointfit::model::ParamId], trial: &Trial| {
        calibrate(
            &model,
            &nominal,
            &[trial],
            free,
            &paper(method),
            &mut NoObserver,
        )
        .unwrap()
    };
    g.bench_function("joint_27_params_150_frames", |b| {
        b.iter(|| fit(Method::Joint, &all, &gait))
    });
    g.bench_function("gradient_27_params_150_frames", |b| {
        b.iter(|| fit(Method::Gradient, &all, &gait))
    });
    let short = gait.slice_frames(0, 50);
    let hip = params_for_groups(&model, &["hip"]).unwrap();
    g.bench_function("pso_hip_50_frames", |b| {
        b.iter(|| fit(Method::Pso, &hip, &short))
    });
    g.finish();
}

criterion_group!(solver_benches, benches);
criterion_main!(solver_benches);
