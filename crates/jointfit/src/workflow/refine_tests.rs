//! Marker refinement against synthetic truth with deliberately misplaced markers.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::refine::calibrate_refined;
use super::synthetic_tests::synthetic;
use super::*;
use crate::calibrate::params_for_groups;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::population::{fill_landmark_priors, HipCentreMethod};
use crate::model::spec::ModelSpec;
use crate::model::Model;

/// The built-in right leg with the landmark priors `personalize` writes (Bell).
pub(super) fn spec_with_priors() -> ModelSpec {
    let mut spec = lower_limb(Side::Right);
    fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    spec
}

/// The truth: `misplaced` markers moved 20 mm in seeded directions in their segments (the
/// static trial did not see it), every marker a further ≤ 1 mm, joint parameters moved by
/// up to 8 mm / 4° from the landmark values.
fn truth(spec: &ModelSpec, model: &Model, seed: u64, misplaced: usize) -> (ModelSpec, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = spec.clone();
    let n = t.markers.len();
    let mut chosen: Vec<usize> = Vec::new();
    while chosen.len() < misplaced {
        let j = rng.gen_range(0..n);
        if !chosen.contains(&j) {
            chosen.push(j);
        }
    }
    for (j, m) in t.markers.iter_mut().enumerate() {
        let mut d = [0.0; 3];
        for v in &mut d {
            *v = rng.gen_range(-0.001..0.001);
        }
        if chosen.contains(&j) {
            let u: [f64; 3] = [(); 3].map(|_| rng.gen_range(-1.0..1.0));
            let norm = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt().max(1e-9);
            for (dk, uk) in d.iter_mut().zip(u) {
                *dk += 0.020 * uk / norm;
            }
        }
        for (x, dk) in m.position.iter_mut().zip(d) {
            *x += dk;
        }
    }
    let idx: Vec<usize> = (0..model.parameters().len()).collect();
    let p = perturb(model, &model.nominal_params(), &idx, 8.0, 4.0, seed + 100);
    (t, p)
}

/// RMS error of the joint parameters (mm and degrees together).
pub(super) fn joint_error(model: &Model, fitted: &[f64], truth: &[f64]) -> f64 {
    let e: f64 = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(i, p)| p.unit.to_display(fitted[i] - truth[i]).powi(2))
        .sum();
    (e / model.parameters().len() as f64).sqrt()
}

#[test]
fn refinement_recovers_joints_better_when_markers_are_misplaced() {
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let (mut plain_sum, mut refined_sum) = (0.0, 0.0);
    for seed in [11u64, 12, 13, 14, 15] {
        let (truth_spec, p_true) = truth(&spec, &model, seed, 6);
        let truth_model = Model::compile(&truth_spec).unwrap();
        let trial = synthetic(&truth_model, &p_true, 60, 0.0003);
        let base = FitSettings {
            marker_noise: Some(0.001),
            ..FitSettings::default()
        };
        let plain = calibrate(&model, &start, &[&trial], &free, &base, &mut NoObserver).unwrap();
        let refined_settings = FitSettings {
            refine_markers: Some(0.010),
            ..base.clone()
        };
        let r = calibrate_refined(
            &model,
            &start,
            &[&trial],
            &free,
            &refined_settings,
            &mut NoObserver,
        )
        .unwrap();
        let (e_plain, e_ref) = (
            joint_error(&model, &plain.fit.p, &p_true),
            joint_error(
                &model,
                &r.calibration.fit.p[..model.parameters().len()],
                &p_true,
            ),
        );
        eprintln!("seed {seed}: joint RMS error {e_plain:.2} without, {e_ref:.2} with refinement");
        plain_sum += e_plain;
        refined_sum += e_ref;
        // The fitted model carries the markers it refined; they moved toward the truth.
        assert_eq!(r.fitted.markers.len(), spec.markers.len());
        let moved_toward = |j: usize| {
            let d = |a: [f64; 3], b: [f64; 3]| {
                (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
            };
            d(r.fitted.markers[j].position, truth_spec.markers[j].position)
                < d(spec.markers[j].position, truth_spec.markers[j].position)
        };
        let misplaced: Vec<usize> = (0..spec.markers.len())
            .filter(|&j| {
                let a = spec.markers[j].position;
                let b = truth_spec.markers[j].position;
                (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt() > 0.01
            })
            .collect();
        assert_eq!(misplaced.len(), 6);
        assert!(
            misplaced.iter().filter(|&&j| moved_toward(j)).count() >= 4,
            "seed {seed}: {:?}",
            r.markers
        );
    }
    assert!(
        refined_sum < 0.6 * plain_sum,
        "joint error {refined_sum:.2} with refinement, {plain_sum:.2} without"
    );
}

#[test]
fn identifiability_names_marker_offsets_that_trade_off_with_joints() {
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let (truth_spec, p_true) = truth(&spec, &model, 21, 2);
    let trial = synthetic(&Model::compile(&truth_spec).unwrap(), &p_true, 60, 0.0003);
    let settings = FitSettings {
        marker_noise: Some(0.001),
        refine_markers: Some(0.010),
        uncertainty: Some(crate::calibrate::uncertainty::UncertaintyOptions::default()),
        ..FitSettings::default()
    };
    let r =
        calibrate_refined(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap();
    assert!(!r.trade_offs.is_empty());
    for t in &r.trade_offs {
        assert!(t.marker_parameter.starts_with("marker_"), "{t:?}");
        assert!(model.param_id(&t.joint_parameter).is_some(), "{t:?}");
        assert!(t.correlation.abs() >= 0.5 && t.correlation.abs() <= 1.0);
    }
    eprintln!(
        "strongest trade-offs: {:?}",
        &r.trade_offs[..r.trade_offs.len().min(5)]
    );
    // Rows for the marker parameters are in the calibration, group `markers`.
    assert!(r
        .calibration
        .parameters
        .iter()
        .any(|p| p.group == crate::model::refine::MARKER_GROUP));
    // Without priors refinement is refused (a marker trades off exactly with its joint).
    let no_prior = FitSettings {
        priors: false,
        ..settings
    };
    assert_eq!(
        calibrate_refined(&model, &start, &[&trial], &free, &no_prior, &mut NoObserver)
            .unwrap_err(),
        WorkflowError::RefineNeedsPriors
    );
}

/// The problem a calibration keeps for its later steps is the one its σ (m) and factors
/// define: the analysis, the prior–data conflict test and the widened intervals on it equal
/// those on a problem built afresh from the calibration's σ and factors, bit for bit.
#[test]
fn the_kept_problem_equals_one_rebuilt_from_the_fits_sigma() {
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let free = params_for_groups(&model, &["hip", "knee"]).unwrap();
    let start = model.nominal_params();
    let (truth_spec, p_true) = truth(&spec, &model, 5, 0);
    let trial = synthetic(&Model::compile(&truth_spec).unwrap(), &p_true, 40, 0.002);
    // σ estimated by the global phase, the analysis on: the default command's path.
    let settings = FitSettings {
        uncertainty: Some(super::tests::five_mm_five_deg()),
        ..FitSettings::default()
    };
    let kept = super::calibration::calibrate_keeping_system(
        &model,
        &start,
        &[&trial],
        &free,
        &settings,
        None,
        &mut NoObserver,
    )
    .unwrap();
    let cal = &kept.calibration;
    assert!(cal.prior_noise_estimated);
    let sigma = cal.prior_noise.unwrap();
    assert_eq!(kept.problem.prior.as_ref().unwrap().noise, sigma);
    let (mut rebuilt, used, _) = super::map::map_problem_with(
        &model,
        &start,
        &[&trial],
        &cal.free,
        &settings,
        super::map::Known {
            noise: Some(sigma),
            coords: None,
        },
        false,
    )
    .unwrap();
    assert_eq!(used, Some(sigma));
    super::map::set_inflation(&mut rebuilt, &cal.prior_inflation);
    let opts = settings.uncertainty.as_ref().unwrap();
    let on = |prob: &crate::calibrate::Problem| {
        let red = crate::calibrate::uncertainty::reduced::reduced_system(
            prob,
            &cal.fit.p,
            &cal.fit.coords,
        );
        crate::calibrate::uncertainty::analyze_reduced(prob, &cal.fit, opts, &red)
    };
    assert_eq!(on(&kept.problem), on(&rebuilt));
    assert_eq!(cal.uncertainty.as_ref(), Some(&on(&rebuilt)));
    let conflicts = super::conflict::assess(&kept.problem, cal, kept.system.as_ref()).unwrap();
    assert!(!conflicts.is_empty());
    assert_eq!(
        conflicts,
        super::conflict::assess(&rebuilt, cal, None).unwrap()
    );
    // Widened as if every joint conflicted: the same intervals from either problem.
    let widened: Vec<_> = conflicts
        .into_iter()
        .map(|c| super::conflict::JointConflict {
            interval_scale: 2.0,
            ..c
        })
        .collect();
    let widen = |prob: &crate::calibrate::Problem| {
        let mut c = cal.clone();
        super::conflict::analyze_widened(prob, &settings, &mut c, &widened, None, &mut NoObserver);
        c.uncertainty
    };
    let a = widen(&kept.problem);
    assert_eq!(a, widen(&rebuilt));
    assert_ne!(a, cal.uncertainty, "the widening changed the intervals");
}
