//! The maximum a posteriori objective: its gradient, the solvers' agreement on it, and what
//! the prior buys on synthetic truth drawn from it.

use super::solvers_tests::{
    assert_gradient_matches_differences, assert_same_optimum, assert_stationary, joint_and_varpro,
    max_difference, perturbed, synthetic,
};
use crate::calibrate::joint::{solve_joint, JointOptions};
use crate::calibrate::{params_for_groups, Problem};
use crate::ik::lm::IkWorkspace;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::population::{fill_landmark_priors, HipCentreMethod};
use crate::model::Model;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr_free::standard_normal;

/// Box–Muller normal draws (no extra dependency).
mod rand_distr_free {
    use rand::Rng;
    pub fn standard_normal(rng: &mut impl Rng) -> f64 {
        let u: f64 = rng.gen_range(f64::EPSILON..1.0);
        let v: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        (-2.0 * u.ln()).sqrt() * v.cos()
    }
}

/// The built-in right leg with the landmark priors (Bell's hip-centre method).
pub(crate) fn model_with_priors() -> Model {
    let mut spec = lower_limb(Side::Right);
    fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    Model::compile(&spec).unwrap()
}

#[test]
fn map_gradient_matches_finite_differences() {
    let model = model_with_priors();
    let p_true = perturbed(&model, 21);
    let trial = synthetic(&model, &p_true, 30, 0.008, 4);
    let free = params_for_groups(&model, &["ankle", "knee"]).unwrap();
    let prob = Problem::new(&model, model.nominal_params(), &free, &[&trial])
        .unwrap()
        .with_model_prior(0.004);
    assert!(prob.prior.is_some());
    // Away from the prior mean, so the prior's gradient is not zero.
    let s = prob.to_scaled(&p_true);
    let mut ws = IkWorkspace::new(&model);
    let mut qs = prob.initial_coords(&p_true);
    prob.inner(&prob.to_params(&s), &mut qs, &mut ws);
    assert!(prob.prior_cost(&prob.to_params(&s)) > 0.0);
    assert_gradient_matches_differences(&prob, &s, &qs, &mut ws);
}

#[test]
fn joint_and_two_level_reach_the_same_map_optimum() {
    let model = model_with_priors();
    let p_true = perturbed(&model, 5);
    let trial = synthetic(&model, &p_true, 50, 0.01, 9);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let base = model.nominal_params();
    let prob = Problem::new(&model, base.clone(), &free, &[&trial])
        .unwrap()
        .with_model_prior(0.004);
    let unreg = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&base);
    let q0 = prob.initial_coords(&base);
    let (joint, varpro) = joint_and_varpro(&prob, &s0, q0.clone());
    let plain = solve_joint(
        &unreg,
        &s0,
        q0,
        &JointOptions::default(),
        &mut crate::solver::NoObserver,
    );
    assert_same_optimum(&joint, &varpro, "MAP");
    // The MAP optimum is stationary for the posterior and differs from the plain fit.
    assert_stationary(&prob, &joint, &s0, &base, "MAP");
    let moved = max_difference(&joint.s, &plain.s);
    assert!(moved > 1e-3, "the prior changed nothing ({moved:e})");
    // Each minimizes its own objective: the plain fit has the smaller marker term, the MAP
    // fit the smaller posterior objective.
    let data = |p: &[f64]| joint.cost - prob.prior_cost(p);
    assert!(plain.cost <= data(&joint.p) * (1.0 + 1e-12));
    let mut ws = IkWorkspace::new(&model);
    let mut q = plain.coords.clone();
    assert!(joint.cost <= prob.inner(&plain.p, &mut q, &mut ws) * (1.0 + 1e-9));
}

#[test]
fn a_tight_prior_holds_the_mean_and_an_infinite_one_changes_nothing() {
    let model = model_with_priors();
    let p_true = perturbed(&model, 11);
    let trial = synthetic(&model, &p_true, 40, 0.0, 0);
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let mut base = p_true.clone();
    for id in &free {
        base[id.0] = model.parameters()[id.0].nominal;
    }
    let mut prob = Problem::new(&model, base.clone(), &free, &[&trial])
        .unwrap()
        .with_model_prior(0.004);
    let s0 = prob.to_scaled(&base);
    let q0 = prob.initial_coords(&base);
    // σ/s = 1e4: the prior dominates, the fit stays at the mean.
    prob.prior
        .as_mut()
        .unwrap()
        .sd
        .iter_mut()
        .for_each(|s| *s = 4e-7);
    let held = solve_joint(
        &prob,
        &s0,
        q0.clone(),
        &JointOptions::default(),
        &mut crate::solver::NoObserver,
    );
    for &i in &prob.free {
        let d = (held.p[i] - model.parameters()[i].prior_mean).abs();
        assert!(d < 1e-5, "{}: {d:e}", model.parameters()[i].name);
    }
    // No prior information at all: noiseless data give the truth exactly.
    prob.prior
        .as_mut()
        .unwrap()
        .sd
        .iter_mut()
        .for_each(|s| *s = f64::INFINITY);
    let free_fit = solve_joint(
        &prob,
        &s0,
        q0,
        &JointOptions::default(),
        &mut crate::solver::NoObserver,
    );
    for &i in &prob.free {
        let d = (free_fit.p[i] - p_true[i]).abs();
        assert!(d < 1e-9, "{}: {d:e}", model.parameters()[i].name);
    }
}

#[test]
fn the_prior_reduces_errors_when_truth_follows_it() {
    // Truth drawn from the prior itself (mean = nominal, SD = the table), skin artefact up to
    // 10 mm; over 8 seeds the summed squared standardized error of the 27 parameters is
    // smaller with the prior than without (Bayes risk is minimal for the posterior).
    let model = model_with_priors();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let (mut with, mut without) = (0.0, 0.0);
    for seed in 1..=8u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        let p_true: Vec<f64> = model
            .parameters()
            .iter()
            .map(|p| {
                let sd = p.prior_sd.unwrap();
                (p.prior_mean + sd * standard_normal(&mut rng)).clamp(p.lower, p.upper)
            })
            .collect();
        let trial = synthetic(&model, &p_true, 50, 0.01, seed);
        let base = model.nominal_params();
        let plain = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
        let map = plain.clone().with_model_prior(0.004);
        let s0 = plain.to_scaled(&base);
        let q0 = plain.initial_coords(&base);
        let f_map = solve_joint(
            &map,
            &s0,
            q0.clone(),
            &JointOptions::default(),
            &mut crate::solver::NoObserver,
        );
        let f_plain = solve_joint(
            &plain,
            &s0,
            q0,
            &JointOptions::default(),
            &mut crate::solver::NoObserver,
        );
        for (i, p) in model.parameters().iter().enumerate() {
            let sd = p.prior_sd.unwrap();
            with += ((f_map.p[i] - p_true[i]) / sd).powi(2);
            without += ((f_plain.p[i] - p_true[i]) / sd).powi(2);
        }
    }
    eprintln!("standardized squared error: with prior {with:.1}, without {without:.1}");
    assert!(with < without, "with prior {with}, without {without}");
}
