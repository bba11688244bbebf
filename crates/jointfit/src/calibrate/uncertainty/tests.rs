//! Uncertainty and identifiability against independent oracles: a dense Schur
//! complement of finite-difference Jacobians, the empirical scatter of fits over noise seeds,
//! interval coverage of the known truth, and a trial that cannot determine the hip.
//!
//! This file holds the synthetic trials the tests share (also used by `status.rs`) and the
//! algebraic checks (the dense finite-difference Schur complement, few frames, grouped
//! normals); the comparisons with the scatter of actual fits are in `uncertainty/scatter.rs`.

use crate::calibrate::joint::{solve_joint, JointOptions};
use crate::calibrate::uncertainty::analyze;
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::{params_for_groups, Fit, Problem};
use crate::kinematics::fd::{jacobian_p, jacobian_q};
use crate::kinematics::synth;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::spec::Unit;
use crate::model::Model;
use crate::solver::NoObserver;
use crate::trial::Trial;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod scatter;

/// Which joints move, and how much (1: the full synthetic excursion).
#[derive(Clone, Copy)]
pub(crate) struct Motion {
    pub(crate) hip: f64,
    pub(crate) knee: f64,
    pub(crate) ankle: f64,
}

pub(crate) const ALL: Motion = Motion {
    hip: 1.0,
    knee: 1.0,
    ankle: 1.0,
};

fn pose(model: &Model, m: Motion, t: f64) -> Vec<f64> {
    let w = std::f64::consts::TAU;
    let mut q = model.default_coords();
    let set = |q: &mut Vec<f64>, name: &str, v: f64| q[model.coord_id(name).unwrap()] = v;
    set(&mut q, "pelvis_ty", 0.95);
    set(&mut q, "pelvis_tilt", 0.05 * (w * t).sin());
    set(&mut q, "pelvis_rotation", 0.1 * (w * t).cos());
    set(
        &mut q,
        "hip_flexion",
        0.35 + m.hip * 0.5 * (3.5 * w * t).sin(),
    );
    set(&mut q, "hip_adduction", m.hip * 0.3 * (3.5 * w * t).cos());
    set(&mut q, "hip_rotation", m.hip * 0.2 * (1.75 * w * t).sin());
    set(
        &mut q,
        "knee_flexion",
        0.8 + m.knee * 0.7 * (4.0 * w * t).sin(),
    );
    set(
        &mut q,
        "ankle_dorsiflexion",
        m.ankle * 0.3 * (2.75 * w * t).sin(),
    );
    set(
        &mut q,
        "subtalar_inversion",
        m.ankle * 0.25 * (2.75 * w * t).cos(),
    );
    q
}

/// Noise models: skin artifact `A sin(ωt + φ)` per marker axis (A ≤ amplitude, ω ≤ 25
/// rad/s), or white Gaussian with standard deviation `amplitude`.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Noise {
    Skin,
    White,
}

/// Markers from `p_true` along motion `m` at 50 Hz with the testkit's generator.
pub(crate) fn synthetic(
    model: &Model,
    p_true: &[f64],
    m: Motion,
    frames: usize,
    noise: Noise,
    amplitude: f64,
    seed: u64,
) -> Trial {
    let noise = match noise {
        Noise::Skin => synth::Noise::Skin { amplitude },
        Noise::White => synth::Noise::White { sd: amplitude },
    };
    let motion = |f: usize| pose(model, m, f as f64 / frames as f64);
    synth::synthetic_trial(model, p_true, frames, 50.0, motion, noise, seed).trial
}

/// Truth: nominal moved by up to 30 % of each half-range (seeded).
pub(crate) fn perturbed(model: &Model, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    model
        .parameters()
        .iter()
        .map(|p| p.nominal + rng.gen_range(-0.3..0.3) * 0.5 * (p.upper - p.lower))
        .collect()
}

/// 60 frames of knee flexion alone (hip and ankle still) at parameters perturbed with seed
/// 41, with 5 mm skin noise (seed 7): a trial that cannot determine the hip. Returns the
/// trial and the true parameters.
pub(crate) fn knee_only_trial(model: &Model) -> (Trial, Vec<f64>) {
    let p_true = perturbed(model, 41);
    let knee_only = Motion {
        hip: 0.0,
        knee: 1.0,
        ankle: 0.0,
    };
    let trial = synthetic(model, &p_true, knee_only, 60, Noise::Skin, 0.005, 7);
    (trial, p_true)
}

pub(crate) fn fit_from_nominal<'m>(
    model: &'m Model,
    trial: &'m Trial,
    groups: &[&str],
) -> (Problem<'m>, Fit) {
    let free = params_for_groups(model, groups).unwrap();
    let start = model.nominal_params();
    let prob = Problem::new(model, start.clone(), &free, &[trial]).unwrap();
    let q0 = prob.initial_coords(&start);
    let fit = solve_joint(
        &prob,
        &prob.to_scaled(&start),
        q0,
        &JointOptions::default(),
        &mut NoObserver,
    );
    (prob, fit)
}

fn display(model: &Model, i: usize) -> f64 {
    match model.parameters()[i].unit {
        Unit::Metre => 1e3,
        Unit::Radian => 180.0 / std::f64::consts::PI,
    }
}
#[test]
fn uncertainty_reduced_matrix_matches_dense_finite_difference_schur_complement() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 3);
    let trial = synthetic(&model, &p_true, ALL, 12, Noise::Skin, 0.008, 5);
    let (prob, fit) = fit_from_nominal(&model, &trial, &["all"]);
    // At the fit, and at the nominal model with its own inner solutions (where the scores
    // do not sum to zero, so they are compared as numbers, not as noise).
    let start = model.nominal_params();
    let q_nominal = prob.initial_coords(&start);
    check_against_dense_fd(&model, &prob, &fit.p, &fit.coords);
    check_against_dense_fd(&model, &prob, &start, &q_nominal);
}

fn check_against_dense_fd(model: &Model, prob: &Problem, p: &[f64], qs: &[Vec<f64>]) {
    let red = reduced_system(prob, p, qs);
    // Oracle: the stacked residual Jacobian over (q_1 … q_N, s) from central differences
    // of forward kinematics, its dense normal matrix, and nalgebra's inverse for the Schur
    // complement onto s.
    let (nq, nf, n) = (model.coordinates().len(), prob.n_free(), prob.frames.len());
    let rows = 3 * model.markers().len();
    let mut j = DMatrix::zeros(n * rows, n * nq + nf);
    let mut r = nalgebra::DVector::zeros(n * rows);
    let mut kin = KinData::new(model);
    for f in 0..n {
        let jq = jacobian_q(model, p, &qs[f], 1e-6);
        let jp = jacobian_p(model, p, &qs[f], 1e-6);
        forward_kinematics(model, p, &qs[f], Want::Positions, &mut kin);
        for a in 0..rows {
            let (mk, axis) = (a / 3, a % 3);
            r[f * rows + a] = prob.frames.get(f)[mk][axis] - kin.markers[mk][axis];
            for c in 0..nq {
                j[(f * rows + a, f * nq + c)] = jq[(a, c)];
            }
            for (k, &i) in prob.free.iter().enumerate() {
                j[(f * rows + a, n * nq + k)] = jp[(a, i)] * prob.half_range(k);
            }
        }
    }
    let big = j.transpose() * &j;
    let nqq = n * nq;
    let a = big.view((0, 0), (nqq, nqq)).into_owned();
    let b = big.view((0, nqq), (nqq, nf)).into_owned();
    let d = big.view((nqq, nqq), (nf, nf)).into_owned();
    let schur = &d - b.transpose() * a.try_inverse().unwrap() * &b;
    let scale = schur.diagonal().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = (&schur - &red.normal).abs().max();
    assert!(
        diff <= 1e-6 * scale,
        "reduced normal matrix differs from the FD oracle by {diff:e} (scale {scale:e})"
    );
    // Per-frame profile scores ψ_i = J_s,iᵀr_i − (J_q,iᵀJ_s,i)ᵀ(J_q,iᵀJ_q,i)⁻¹J_q,iᵀr_i from
    // the dense blocks; their sum is the envelope gradient.
    let g = j.transpose() * &r;
    let g_scale = (0..n * nq + nf).fold(0.0f64, |m, k| m.max(g[k].abs()));
    for f in 0..n {
        let jf = j.view((f * rows, 0), (rows, n * nq + nf));
        let jq = jf.columns(f * nq, nq).into_owned();
        let js = jf.columns(n * nq, nf).into_owned();
        let rf = r.rows(f * rows, rows).into_owned();
        let psi = js.transpose() * &rf
            - (jq.transpose() * &js).transpose()
                * (jq.transpose() * &jq).try_inverse().unwrap()
                * (jq.transpose() * &rf);
        let d = (&psi - &red.scores[f]).abs().max();
        assert!(
            d <= 1e-6 * g_scale.max(1e-12),
            "frame {f}: scores differ by {d:e} (gradient scale {g_scale:e})"
        );
    }
    assert_eq!(red.observations, n * rows);
    assert_eq!(red.dof(), n * rows - n * nq - nf);
    assert!((red.cost - r.norm_squared()).abs() <= 1e-12 * red.cost.max(1e-30));
}

#[test]
fn uncertainty_with_fewer_frames_than_parameters_stays_conservative() {
    // 15 frames for 27 parameters: the score-based sandwich cannot be formed (its
    // small-sample factor N/(N − n_f) is undefined), so it is left out, never a panic; the
    // white estimate and the 10-block jackknife (blocks of 1–2 frames) remain, no interval
    // is narrower than the white one, and the JSON form still serializes.
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 12);
    let trial = synthetic(&model, &p_true, ALL, 15, Noise::Skin, 0.01, 13);
    let (prob, fit) = fit_from_nominal(&model, &trial, &["all"]);
    let u = analyze(&prob, &fit, &UncertaintyOptions::default());
    assert!(u.hac_bandwidth.is_none());
    for p in &u.params {
        assert!(p.se_hac.is_none(), "{}", p.name);
        if let Some(h) = p.half_width {
            let white = u.z * p.se_white.unwrap();
            assert!(h >= white * (1.0 - 1e-12), "{}", p.name);
        }
    }
    let json = serde_json::to_string(&u).unwrap();
    assert!(json.contains("\"params\""));
}

/// Long trials keep the frames' shares of `S` summed over groups of consecutive frames (at
/// most `MAX_GROUPS` matrices, not one per frame): the groups partition the frames in order
/// and their shares add up to `S` (no prior), on one thread as on two.
#[test]
fn uncertainty_group_normals_partition_a_long_trial() {
    use crate::calibrate::uncertainty::reduced::group_size;
    use crate::calibrate::uncertainty::reduced::MAX_GROUPS;
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 31);
    for (frames, size) in [(300, 1), (9000, 3)] {
        assert_eq!(group_size(frames), size);
        let trial = synthetic(&model, &p_true, ALL, frames, Noise::Skin, 0.004, 5);
        let free = params_for_groups(&model, &["all"]).unwrap();
        let prob = Problem::new(&model, p_true.clone(), &free, &[&trial]).unwrap();
        let qs = prob.initial_coords(&p_true);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| reduced_system(&prob, &p_true, &qs))
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one.group_size, size);
        assert_eq!(one.group_normals.len(), frames.div_ceil(size));
        assert!(one.group_normals.len() <= MAX_GROUPS);
        assert_eq!(one.group_normals, two.group_normals);
        let sum = one
            .group_normals
            .iter()
            .fold(DMatrix::zeros(free.len(), free.len()), |a, g| a + g);
        let scale = one.normal.abs().max();
        let diff = (&sum - &one.normal).abs().max();
        assert!(
            diff <= 1e-12 * scale,
            "{frames} frames: {diff:e} of {scale:e}"
        );
    }
}
