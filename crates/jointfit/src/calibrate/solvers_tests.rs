//! Outer level: parameter recovery from synthetic truth, and the solvers against each other.

use crate::calibrate::joint::{solve_joint, solve_joint_to, JointOptions, RESOLUTION_SE};
use crate::calibrate::pso::{solve_pso, PsoOptions};
use crate::calibrate::varpro::{gradient, solve_varpro, VarProOptions};
use crate::calibrate::{params_for_groups, Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::kinematics::synth::{synthetic_trial, Noise};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::spec::Unit;
use crate::model::{Model, ParamId};
use crate::solver::{NoObserver, Observer, Termination};
use crate::trial::Trial;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A motion exercising every joint axis: hip circumduction, knee and ankle cycles.
fn rich_motion(model: &Model, f: usize, frames: usize) -> Vec<f64> {
    let t = f as f64 / frames as f64;
    let w = 2.0 * std::f64::consts::PI;
    let mut q = model.default_coords();
    let set = |q: &mut Vec<f64>, name: &str, v: f64| q[model.coord_id(name).unwrap()] = v;
    set(&mut q, "pelvis_tx", 0.1 * t);
    set(&mut q, "pelvis_ty", 0.95);
    set(&mut q, "pelvis_rotation", 0.2 * (w * t).sin());
    set(&mut q, "pelvis_tilt", 0.1 * (w * t).cos());
    set(&mut q, "hip_flexion", 0.35 + 0.5 * (3.5 * w * t).sin());
    set(&mut q, "hip_adduction", 0.3 * (3.5 * w * t).cos());
    set(&mut q, "hip_rotation", 0.25 * (2.0 * w * t).sin());
    set(&mut q, "knee_flexion", 0.8 + 0.7 * (4.0 * w * t).sin());
    set(&mut q, "ankle_dorsiflexion", 0.3 * (2.75 * w * t).sin());
    set(&mut q, "subtalar_inversion", 0.25 * (2.75 * w * t).cos());
    q
}

/// Markers from `p_true` along the rich motion at 50 Hz, plus skin-artifact sinusoids of at
/// most `amplitude` metres per marker axis (the testkit's generator).
pub(crate) fn synthetic(
    model: &Model,
    p_true: &[f64],
    frames: usize,
    amplitude: f64,
    seed: u64,
) -> Trial {
    let noise = if amplitude > 0.0 {
        Noise::Skin { amplitude }
    } else {
        Noise::None
    };
    let motion = |f: usize| rich_motion(model, f, frames);
    synthetic_trial(model, p_true, frames, 50.0, motion, noise, seed).trial
}

/// True parameters: nominal moved by up to 40 % of the half-range of each bound.
pub(crate) fn perturbed(model: &Model, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    model
        .parameters()
        .iter()
        .map(|p| p.nominal + rng.gen_range(-0.4..0.4) * 0.5 * (p.upper - p.lower))
        .collect()
}

/// Largest parameter error in display units: (mm, deg).
fn errors(model: &Model, free: &[usize], a: &[f64], b: &[f64]) -> (f64, f64) {
    let (mut mm, mut deg) = (0.0f64, 0.0f64);
    for &i in free {
        let d = (a[i] - b[i]).abs();
        match model.parameters()[i].unit {
            Unit::Metre => mm = mm.max(d * 1e3),
            Unit::Radian => deg = deg.max(d.to_degrees()),
        }
    }
    (mm, deg)
}

/// `p_true` with the free parameters moved back to their nominal values: the start of a
/// fit whose fixed parameters are known.
fn nominal_start(model: &Model, p_true: &[f64], free: &[ParamId]) -> Vec<f64> {
    let mut base = p_true.to_vec();
    for id in free {
        base[id.0] = model.parameters()[id.0].nominal;
    }
    base
}

/// The joint solver (to working precision: the statistical stopping rule off) and the
/// two-level solver, from the same start.
pub(crate) fn joint_and_varpro(prob: &Problem, s0: &[f64], q0: Vec<Vec<f64>>) -> (Fit, Fit) {
    let joint = solve_joint_to(
        prob,
        s0,
        q0.clone(),
        &JointOptions::default(),
        0.0,
        &mut NoObserver,
    );
    let varpro = solve_varpro(prob, s0, q0, &VarProOptions::default(), &mut NoObserver);
    (joint, varpro)
}

/// Largest absolute difference of two vectors.
pub(crate) fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// The two solvers found the same optimum: scaled parameters within 1e-6, costs within
/// 1e-9 relative.
pub(crate) fn assert_same_optimum(joint: &Fit, varpro: &Fit, what: &str) {
    let ds = max_difference(&joint.s, &varpro.s);
    let dc = (joint.cost - varpro.cost).abs() / varpro.cost;
    assert!(ds <= 1e-6, "{what}: scaled parameters differ by {ds:e}");
    assert!(dc <= 1e-9, "{what}: costs differ by {dc:e} relative");
}

/// The fit is stationary: the outer gradient vanishes on interior parameters, relative to
/// its size at the start `s0` (coordinates solved at `base`).
pub(crate) fn assert_stationary(prob: &Problem, fit: &Fit, s0: &[f64], base: &[f64], what: &str) {
    let g0 = gradient(prob, s0, &prob.initial_coords(base));
    let g0_max = g0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let g = gradient(prob, &fit.s, &fit.coords);
    for (k, gk) in g.iter().enumerate() {
        if fit.s[k].abs() < 1.0 - 1e-9 {
            assert!(
                gk.abs() <= 1e-6 * g0_max,
                "{what}: gradient {k} = {gk:e} (start {g0_max:e})"
            );
        }
    }
}

/// The analytic outer gradient at scaled parameters `s` equals central finite differences
/// of the inner objective (step 1e-6, coordinates warm-started from `qs`).
pub(crate) fn assert_gradient_matches_differences(
    prob: &Problem,
    s: &[f64],
    qs: &[Vec<f64>],
    ws: &mut IkWorkspace,
) {
    let g = gradient(prob, s, qs);
    let h = 1e-6;
    for k in 0..s.len() {
        let mut e = |d: f64| {
            let mut sk = s.to_vec();
            sk[k] += d;
            let mut q = qs.to_vec();
            prob.inner(&prob.to_params(&sk), &mut q, ws)
        };
        let fd = (e(h) - e(-h)) / (2.0 * h);
        assert!(
            (fd - g[k]).abs() <= 1e-5 * g[k].abs().max(1e-4),
            "parameter {k}: analytic {:e}, finite difference {fd:e}",
            g[k]
        );
    }
}

#[test]
fn noiseless_recovery_joint_and_varpro() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 11);
    let trial = synthetic(&model, &p_true, 50, 0.0, 0);
    for groups in [&["hip"][..], &["knee"], &["ankle"], &["all"]] {
        let free = params_for_groups(&model, groups).unwrap();
        // Fixed parameters at their true values, free ones start at nominal.
        let base = nominal_start(&model, &p_true, &free);
        let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
        let s0 = prob.to_scaled(&base);
        let (joint, varpro) = joint_and_varpro(&prob, &s0, prob.initial_coords(&base));
        for (name, fit) in [("joint", &joint), ("varpro", &varpro)] {
            let (mm, deg) = errors(&model, &prob.free, &fit.p, &p_true);
            assert!(
                mm <= 1e-6 && deg <= 1e-6,
                "{groups:?} {name}: max error {mm:e} mm {deg:e} deg after {} iterations (cost {:e})",
                fit.iterations,
                fit.cost
            );
            assert_eq!(fit.termination, Termination::Converged, "{groups:?} {name}");
        }
    }
}

#[test]
fn joint_and_two_level_reach_the_same_noisy_optimum() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 5);
    let trial = synthetic(&model, &p_true, 50, 0.01, 9);
    for groups in [&["knee"][..], &["all"]] {
        let free = params_for_groups(&model, groups).unwrap();
        let base = nominal_start(&model, &p_true, &free);
        let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
        let s0 = prob.to_scaled(&base);
        let (joint, varpro) = joint_and_varpro(&prob, &s0, prob.initial_coords(&base));
        let what = format!("{groups:?}");
        assert_same_optimum(&joint, &varpro, &what);
        // The optimum fits the noisy data better than the truth does (the paper's observation).
        let mut ws = IkWorkspace::new(&model);
        let mut q_truth = prob.initial_coords(&p_true);
        let truth_cost = prob.inner(&p_true, &mut q_truth, &mut ws);
        assert!(
            joint.cost < truth_cost,
            "{groups:?}: {} vs truth {}",
            joint.cost,
            truth_cost
        );
        // And it is stationary.
        assert_stationary(&prob, &joint, &s0, &base, &what);
    }
}

#[test]
fn outer_gradient_matches_finite_differences() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 21);
    let trial = synthetic(&model, &p_true, 30, 0.008, 4);
    let free = params_for_groups(&model, &["ankle"]).unwrap();
    let prob = Problem::new(&model, model.nominal_params(), &free, &[&trial]).unwrap();
    let s = prob.to_scaled(&model.nominal_params());
    let mut ws = IkWorkspace::new(&model);
    let mut qs = prob.initial_coords(&model.nominal_params());
    prob.inner(&prob.to_params(&s), &mut qs, &mut ws);
    assert_gradient_matches_differences(&prob, &s, &qs, &mut ws);
}

#[test]
fn pso_then_local_polish_recovers_the_hip() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 3);
    let trial = synthetic(&model, &p_true, 40, 0.0, 0);
    let free = params_for_groups(&model, &["hip"]).unwrap();
    let mut base = p_true.clone();
    for id in &free {
        base[id.0] = model.parameters()[id.0].nominal;
    }
    let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let q0 = prob.initial_coords(&base);
    let opts = PsoOptions {
        max_iterations: 150,
        seed: 42,
        ..PsoOptions::default()
    };
    let swarm = solve_pso(&prob, &q0, &opts, &mut NoObserver);
    let again = solve_pso(&prob, &q0, &opts, &mut NoObserver);
    assert_eq!(swarm.s, again.s, "seeded swarm is reproducible");
    let (mm, _) = errors(&model, &prob.free, &swarm.p, &p_true);
    assert!(mm < 5.0, "swarm within 5 mm before polishing: {mm}");
    let polished = solve_joint(
        &prob,
        &swarm.s,
        swarm.coords.clone(),
        &JointOptions::default(),
        &mut NoObserver,
    );
    let (mm, _) = errors(&model, &prob.free, &polished.p, &p_true);
    assert!(mm <= 1e-6, "polished error {mm:e} mm");
}

/// Records what a solver reports.
#[derive(Default)]
struct Seen(Vec<(usize, f64)>);

impl Observer for Seen {
    fn iteration(&mut self, iteration: usize, objective: f64) {
        self.0.push((iteration, objective));
    }
}

#[test]
fn observers_see_the_history_and_do_not_change_the_result() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 3);
    let trial = synthetic(&model, &p_true, 30, 0.005, 4);
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let base = model.nominal_params();
    let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&base);
    let q0 = prob.initial_coords(&base);
    let mut seen = Seen::default();
    let joint = solve_joint(&prob, &s0, q0.clone(), &JointOptions::default(), &mut seen);
    let plain = solve_joint(
        &prob,
        &s0,
        q0.clone(),
        &JointOptions::default(),
        &mut NoObserver,
    );
    assert_eq!(joint.p, plain.p);
    assert_eq!(seen.0.len(), joint.iterations);
    assert!(seen.0.iter().enumerate().all(|(k, (i, _))| *i == k + 1));
    assert_eq!(
        seen.0.iter().map(|s| s.1).collect::<Vec<_>>(),
        joint.history
    );
    let mut seen = Seen::default();
    let varpro = solve_varpro(&prob, &s0, q0.clone(), &VarProOptions::default(), &mut seen);
    let plain = solve_varpro(&prob, &s0, q0, &VarProOptions::default(), &mut NoObserver);
    assert_eq!(varpro.p, plain.p);
    assert_eq!(
        seen.0.iter().map(|s| s.1).collect::<Vec<_>>(),
        varpro.history
    );
    assert!(varpro.history.windows(2).all(|w| w[1] <= w[0]));
}

/// A solver stopped by its budget says so instead of claiming convergence; the same solve
/// with its full budget converges.
#[test]
fn termination_tells_iteration_limit_from_convergence() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 3);
    let trial = synthetic(&model, &p_true, 30, 0.005, 4);
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let base = model.nominal_params();
    let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&base);
    let q0 = prob.initial_coords(&base);
    let short = JointOptions {
        max_iterations: 2,
        ..JointOptions::default()
    };
    let cut = solve_joint(&prob, &s0, q0.clone(), &short, &mut NoObserver);
    assert_eq!(cut.termination, Termination::IterationLimit);
    assert!(!cut.converged());
    let full = solve_joint(
        &prob,
        &s0,
        q0.clone(),
        &JointOptions::default(),
        &mut NoObserver,
    );
    assert_eq!(full.termination, Termination::Converged);
    assert!(full.cost < cut.cost);
    let short = VarProOptions {
        max_iterations: 1,
        ..VarProOptions::default()
    };
    let cut = solve_varpro(&prob, &s0, q0.clone(), &short, &mut NoObserver);
    assert_eq!(cut.termination, Termination::IterationLimit);
    let opts = PsoOptions {
        max_iterations: 3,
        ..PsoOptions::default()
    };
    let swarm = solve_pso(&prob, &q0, &opts, &mut NoObserver);
    assert_eq!(swarm.termination, Termination::IterationLimit);
}

/// The paper's protocol on noiseless data for the other single joints and the full leg: the
/// seeded swarm from the nominal parameters, then the joint solver from the swarm's best,
/// recovers the truth to 1e-6 mm / 1e-6 deg.
#[test]
fn pso_then_local_polish_recovers_knee_ankle_and_full_leg() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    for (group, seed) in [("knee", 5), ("ankle", 6), ("all", 7)] {
        let p_true = perturbed(&model, seed);
        let trial = synthetic(&model, &p_true, 40, 0.0, 0);
        let free = params_for_groups(&model, &[group]).unwrap();
        let mut base = p_true.clone();
        for id in &free {
            base[id.0] = model.parameters()[id.0].nominal;
        }
        let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
        let q0 = prob.initial_coords(&base);
        let opts = PsoOptions {
            max_iterations: 150,
            seed: 42,
            ..PsoOptions::default()
        };
        let swarm = solve_pso(&prob, &q0, &opts, &mut NoObserver);
        let polished = solve_joint(
            &prob,
            &swarm.s,
            swarm.coords.clone(),
            &JointOptions::default(),
            &mut NoObserver,
        );
        let (mm, deg) = errors(&model, &prob.free, &polished.p, &p_true);
        assert!(
            mm <= 1e-6 && deg <= 1e-6,
            "{group}: polished error {mm:e} mm, {deg:e} deg (swarm cost {:e})",
            swarm.cost
        );
    }
}

/// Runs `f` on a local pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn thread_count_never_changes_the_joint_fit_or_its_reduced_system() {
    // Long enough for many 32-frame chunks; noisy so that every digit matters.
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 21);
    let trial = synthetic(&model, &p_true, 333, 0.006, 4);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let prob = Problem::new(&model, start.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&start);
    let q0 = prob.initial_coords(&start);
    let opts = JointOptions {
        max_iterations: 12,
        ..JointOptions::default()
    };
    let run = |threads| {
        on_threads(threads, || {
            let fit = solve_joint(&prob, &s0, q0.clone(), &opts, &mut NoObserver);
            let red =
                crate::calibrate::uncertainty::reduced::reduced_system(&prob, &fit.p, &fit.coords);
            let grad = gradient(&prob, &fit.s, &fit.coords);
            (fit, red, grad)
        })
    };
    let (one, red_one, grad_one) = run(1);
    let (two, red_two, grad_two) = run(2);
    assert!(one.history.len() >= 5, "too few iterations to compare");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&one.s), bits(&two.s));
    assert_eq!(bits(&one.history), bits(&two.history));
    assert_eq!(one.cost.to_bits(), two.cost.to_bits());
    for (a, b) in one.coords.iter().zip(&two.coords) {
        assert_eq!(bits(a), bits(b));
    }
    assert_eq!(
        bits(red_one.normal.as_slice()),
        bits(red_two.normal.as_slice())
    );
    for (a, b) in red_one.scores.iter().zip(&red_two.scores) {
        assert_eq!(bits(a.as_slice()), bits(b.as_slice()));
    }
    assert_eq!(bits(&grad_one), bits(&grad_two));
}

/// Largest distance of `a` from `b` (scaled parameters) in the standard errors of the fit `b`
/// (white σ² and the reduced normal matrix, as [`crate::calibrate::uncertainty`]).
fn distance_in_se(prob: &Problem, a: &crate::calibrate::Fit, b: &crate::calibrate::Fit) -> f64 {
    let red = crate::calibrate::uncertainty::reduced::reduced_system(prob, &b.p, &b.coords);
    let cov = red.normal.clone().try_inverse().expect("invertible") * red.sigma2();
    (0..prob.n_free())
        .map(|k| (a.s[k] - b.s[k]).abs() / cov[(k, k)].sqrt())
        .fold(0.0, f64::max)
}

#[test]
fn statistical_stop_is_within_a_thousandth_of_a_standard_error() {
    // Oracle: the same solve run to working precision (the classical tolerances alone).
    // (perturbation seed, noise seed, frames, skin-noise amplitude m): the first ends on an
    // undamped step's predicted decrease; in the others (60 frames of 1–4 cm skin noise) the
    // damping stays above 1e-6 to the end and the undamped model at the last point decides
    // (a trace showed it; 16/11/63 iterations, the last step counted, against 21/17/76 run
    // out).
    let cases = [
        (5, 9, 50, 0.01),
        (3, 103, 60, 0.01),
        (4, 104, 60, 0.01),
        (1, 101, 60, 0.04),
    ];
    // Without a prior, and the maximum a posteriori problem of the leg with its landmark
    // priors (the prior's information counts in the SEs, as in the posterior's).
    let plain = Model::compile(&lower_limb(Side::Right)).unwrap();
    let with_priors = crate::calibrate::prior_tests::model_with_priors();
    for (seed, noise_seed, frames, amplitude) in cases {
        for (model, prior) in [(&plain, None), (&with_priors, Some(0.004))] {
            let free = params_for_groups(model, &["all"]).unwrap();
            let base = model.nominal_params();
            let p_true = perturbed(model, seed);
            let trial = synthetic(model, &p_true, frames, amplitude, noise_seed);
            let mut prob = Problem::new(model, base.clone(), &free, &[&trial]).unwrap();
            if let Some(sigma) = prior {
                prob = prob.with_model_prior(sigma);
                assert!(prob.prior.is_some());
            }
            let s0 = prob.to_scaled(&base);
            let q0 = prob.initial_coords(&base);
            let opts = JointOptions::default();
            let quick = solve_joint(&prob, &s0, q0.clone(), &opts, &mut NoObserver);
            let exact = solve_joint_to(&prob, &s0, q0, &opts, 0.0, &mut NoObserver);
            assert_eq!(quick.termination, Termination::Converged);
            assert!(quick.iterations < exact.iterations, "seed {seed}");
            let d = distance_in_se(&prob, &quick, &exact);
            assert!(
                d <= RESOLUTION_SE,
                "seed {seed}, prior {prior:?}: {d:e} SE from the optimum"
            );
        }
    }
}

#[test]
fn mixed_tail_reaches_the_plain_optimum_in_fewer_iterations() {
    // Oracle: plain Gauss–Newton Levenberg–Marquardt run to working precision (the classical
    // tolerances alone). Large skin noise gives the slow linear tail that mixing is for
    // (measured: 40, 18 and 72 iterations mixed against 75, 40 and 78 plain, at most 2.1e-4
    // SE from the optimum).
    let (mut mixed_total, mut plain_total) = (0, 0);
    let cases = [(3, 103, 0.02), (4, 104, 0.03), (1, 101, 0.04)];
    on_noisy_legs(&cases, |seed, prob, s0, q0| {
        let plain_opts = JointOptions {
            mixing: false,
            ..JointOptions::default()
        };
        let exact = solve_joint_to(prob, s0, q0.clone(), &plain_opts, 0.0, &mut NoObserver);
        let plain = solve_joint(prob, s0, q0.clone(), &plain_opts, &mut NoObserver);
        let mixed = solve_joint(prob, s0, q0, &JointOptions::default(), &mut NoObserver);
        assert_eq!(mixed.termination, Termination::Converged);
        let d = distance_in_se(prob, &mixed, &exact);
        assert!(d <= RESOLUTION_SE, "seed {seed}: {d:e} SE from the optimum");
        assert!(
            mixed.iterations <= plain.iterations,
            "seed {seed}: {} mixed, {} plain",
            mixed.iterations,
            plain.iterations
        );
        mixed_total += mixed.iterations;
        plain_total += plain.iterations;
    });
    assert!(
        mixed_total < plain_total,
        "{mixed_total} mixed, {plain_total} plain"
    );
}

#[test]
fn kept_curvature_reaches_the_optimum_of_the_solve_that_forms_it_every_step() {
    // Oracle: the same solve forming every step's curvature, run to working precision. The
    // kept curvature's steps (the undamped tail, `joint::KEEP_STEP`) must reach the same
    // optimum run out, stop within the resolution of it, and take no more than a few more
    // iterations and evaluations (skin noise 1–4 cm: the slow tails where it is used most;
    // measured 11, 26 and 73 iterations against 11, 40 and 71, 22, 56 and 178 evaluations
    // against 22, 92 and 169).
    let cases = [(5, 9, 0.01), (3, 103, 0.02), (1, 101, 0.04)];
    on_noisy_legs(&cases, |seed, prob, s0, q0| {
        let kept = JointOptions::default();
        let formed = JointOptions {
            keep_curvature: false,
            ..kept
        };
        let oracle = solve_joint_to(prob, s0, q0.clone(), &formed, 0.0, &mut NoObserver);
        let run_out = solve_joint_to(prob, s0, q0.clone(), &kept, 0.0, &mut NoObserver);
        let quick = solve_joint(prob, s0, q0.clone(), &kept, &mut NoObserver);
        let plain = solve_joint(prob, s0, q0, &formed, &mut NoObserver);
        let d = distance_in_se(prob, &run_out, &oracle);
        assert!(d <= 2e-5, "seed {seed}: run out {d:e} SE apart");
        let d = distance_in_se(prob, &quick, &oracle);
        assert!(
            d <= RESOLUTION_SE,
            "seed {seed}: stopped {d:e} SE from the optimum"
        );
        assert_eq!(quick.termination, Termination::Converged);
        assert!(
            quick.iterations <= plain.iterations + 2,
            "seed {seed}: {} iterations against {}",
            quick.iterations,
            plain.iterations
        );
        // A kept step that does not descend costs an evaluation: few may.
        let bound = plain.evaluations + plain.evaluations / 10 + 2;
        assert!(
            quick.evaluations <= bound,
            "seed {seed}: {} evaluations",
            quick.evaluations
        );
    });
}

/// Runs `check(seed, problem, scaled start, starting coordinates)` on the leg with its
/// landmark priors (σ 4 mm), fitted from nominal to 60 synthetic frames at the parameters of
/// each case's `(seed, noise seed, skin-noise amplitude m)`.
fn on_noisy_legs(
    cases: &[(u64, u64, f64)],
    mut check: impl FnMut(u64, &Problem, &[f64], Vec<Vec<f64>>),
) {
    let model = crate::calibrate::prior_tests::model_with_priors();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let base = model.nominal_params();
    for &(seed, noise_seed, amplitude) in cases {
        let p_true = perturbed(&model, seed);
        let trial = synthetic(&model, &p_true, 60, amplitude, noise_seed);
        let prob = Problem::new(&model, base.clone(), &free, &[&trial])
            .unwrap()
            .with_model_prior(0.004);
        let s0 = prob.to_scaled(&base);
        let q0 = prob.initial_coords(&base);
        check(seed, &prob, &s0, q0);
    }
}
