//! Intervals of a maximum a posteriori fit (`calibrate::uncertainty` with a prior) against
//! the prior the model file states: a parameter the trial cannot see must get the prior's own
//! interval, `± z·sd·√(1 − data share)`, however the marker noise that weighs the prior
//! compares with the residuals; and a parameter the trial determines must not be held to it.

use crate::calibrate::joint::{solve_joint, JointOptions};
use crate::calibrate::prior::data_share;
use crate::calibrate::uncertainty::analyze;
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::{params_for_groups, Problem};
use crate::kinematics::synth;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::population::{fill_landmark_priors, HipCentreMethod};
use crate::model::Model;
use crate::solver::NoObserver;

#[test]
fn posterior_interval_of_a_parameter_the_trial_cannot_see_is_the_priors() {
    hip_only_trial_against_the_prior(1.0);
}

/// With the prior weights multiplied by factors `a_k` (the per-parameter correlation
/// adjustment of an estimated σ, [`crate::calibrate::uncertainty::parameter_inflation`]), what
/// the trial cannot see still gets the prior's own interval (times `√(1 − share)`), not one
/// `√a_k` narrower: the prior term's score variance carries the factor too.
#[test]
fn inflated_prior_weights_keep_the_priors_interval_where_the_trial_sees_nothing() {
    hip_only_trial_against_the_prior(4.0);
}

/// The hip-only trial of the tests above, the prior weights multiplied by `inflation`.
fn hip_only_trial_against_the_prior(inflation: f64) {
    let mut spec = lower_limb(Side::Right);
    fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    let model = Model::compile(&spec).unwrap();
    let truth = model.nominal_params();
    // Only the hip moves: the knee and ankle axes are invisible to the markers.
    let w = std::f64::consts::TAU;
    let motion = |f: usize| {
        let t = f as f64 / 120.0;
        let mut q = model.default_coords();
        let mut set = |name: &str, v: f64| q[model.coord_id(name).unwrap()] = v;
        set("pelvis_ty", 0.95);
        set("hip_flexion", 0.35 + 0.5 * (3.5 * w * t).sin());
        set("hip_adduction", 0.3 * (3.5 * w * t).cos());
        set("hip_rotation", 0.2 * (1.75 * w * t).sin());
        set("knee_flexion", 0.3);
        q
    };
    let noise = synth::Noise::Skin { amplitude: 0.005 };
    let trial = synth::synthetic_trial(&model, &truth, 120, 50.0, motion, noise, 23).trial;
    let free = params_for_groups(&model, &["hip", "knee", "ankle"]).unwrap();
    // The prior weighed by a noise 3× the residuals' (as the correlation factor κ does).
    let mut prob = Problem::new(&model, truth.clone(), &free, &[&trial])
        .unwrap()
        .with_model_prior(0.01);
    if let Some(prior) = prob.prior.as_mut() {
        prior.inflation = vec![inflation; free.len()];
    }
    let fit = solve_joint(
        &prob,
        &prob.to_scaled(&truth),
        prob.initial_coords(&truth),
        &JointOptions::default(),
        &mut NoObserver,
    );
    let u = analyze(&prob, &fit, &UncertaintyOptions::default());
    assert!(u.sigma < 0.005, "residual σ {} m", u.sigma);
    let share = data_share(&prob, &reduced_system(&prob, &fit.p, &fit.coords).normal);
    let (mut unseen, mut seen) = (0, 0);
    for (k, p) in u.params.iter().enumerate() {
        let par = &model.parameters()[free[k].0];
        // The uncertainty rows are in the shown unit (mm or deg).
        let shown = match par.unit {
            crate::model::spec::Unit::Metre => 1e3,
            crate::model::spec::Unit::Radian => 180.0 / std::f64::consts::PI,
        };
        let prior_hw = u.z * (par.prior_sd.unwrap() * shown);
        let hw = p.half_width.unwrap();
        if share[k] < 0.6 {
            // What the trial sees of it is a combination it pins down (an offset in the
            // thigh against the same offset in the shank, a joint that does not move), so
            // the posterior along the rest is the prior's: variance `(1 − share)·sd²`, the
            // Gaussian identity behind the share, and a normal critical value.
            unseen += 1;
            let expected = (1.0 - share[k]).sqrt();
            assert!(
                (hw / prior_hw - expected).abs() < 0.03,
                "{}: ±{hw:.3} against the prior's ±{prior_hw:.3} × {expected:.3}",
                p.name
            );
        }
        if share[k] > 0.9 {
            seen += 1;
            assert!(
                hw < 0.7 * prior_hw,
                "{}: ±{hw:.3} vs ±{prior_hw:.3}",
                p.name
            );
        }
    }
    // Stronger prior weights leave fewer parameters to the trial alone.
    let least_seen = if inflation == 1.0 { 5 } else { 0 };
    assert!(
        unseen >= 15 && seen >= least_seen,
        "unseen {unseen}, seen {seen}"
    );
}
