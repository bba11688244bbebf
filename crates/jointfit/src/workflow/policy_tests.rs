//! The default marker policy and the anatomical envelope against synthetic truth.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::envelope::HELD_AT_LIMIT;
use super::marker_policy::{decide, MarkerAction};
use super::refine::calibrate_refined;
use super::refine_tests::{joint_error, spec_with_priors};
use super::synthetic_tests::synthetic;
use super::*;
use crate::calibrate::params_for_groups;
use crate::calibrate::prior::Source;
use crate::model::spec::ModelSpec;
use crate::model::Model;

/// The truth of seed `seed`: one thigh or shank marker (seeded) moved 20 mm in a seeded
/// direction since the static trial, joint parameters moved up to 8 mm / 4° from the
/// landmark values.
fn one_moved(spec: &ModelSpec, model: &Model, seed: u64) -> (ModelSpec, Vec<f64>, String) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = spec.clone();
    let candidates: Vec<usize> = (0..t.markers.len())
        .filter(|&j| ["thigh", "shank"].contains(&t.markers[j].segment.as_str()))
        .collect();
    let j = candidates[rng.gen_range(0..candidates.len())];
    let u: [f64; 3] = [(); 3].map(|_| rng.gen_range(-1.0..1.0));
    let norm = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt().max(1e-9);
    for (x, uk) in t.markers[j].position.iter_mut().zip(u) {
        *x += 0.020 * uk / norm;
    }
    let idx: Vec<usize> = (0..model.parameters().len()).collect();
    let p = perturb(model, &model.nominal_params(), &idx, 8.0, 4.0, seed + 100);
    (t.clone(), p, t.markers[j].name.clone())
}

#[test]
fn policy_refines_the_marker_displaced_by_20_mm() {
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let (mut with_sum, mut without_sum) = (0.0, 0.0);
    for seed in [31u64, 32, 33, 34, 35] {
        let (truth_spec, p_true, moved) = one_moved(&spec, &model, seed);
        let trial = synthetic(&Model::compile(&truth_spec).unwrap(), &p_true, 60, 0.0003);
        let base = FitSettings {
            marker_noise: Some(0.001),
            ..FitSettings::default()
        };
        let with =
            calibrate_refined(&model, &start, &[&trial], &free, &base, &mut NoObserver).unwrap();
        let off = FitSettings {
            marker_policy: false,
            ..base.clone()
        };
        let without =
            calibrate_refined(&model, &start, &[&trial], &free, &off, &mut NoObserver).unwrap();
        let e_with = joint_error(
            &model,
            &with.calibration.fit.p[..model.parameters().len()],
            &p_true,
        );
        let e_without = joint_error(&model, &without.calibration.fit.p, &p_true);
        eprintln!(
            "seed {seed}: joint RMS error {e_without:.2} without the policy, {e_with:.2} with"
        );
        // The displaced marker, and only it, is refined; nothing is left out.
        assert_eq!(
            with.marker_decisions.len(),
            1,
            "{:?}",
            with.marker_decisions
        );
        let dec = &with.marker_decisions[0];
        assert_eq!(
            (dec.marker.as_str(), dec.action),
            (moved.as_str(), MarkerAction::Refine)
        );
        assert_eq!(with.markers.len(), 1);
        assert!(without.marker_decisions.is_empty() && without.markers.is_empty());
        // Its fitted position is closer to the truth than the static trial's.
        let j = spec.markers.iter().position(|m| m.name == moved).unwrap();
        let dist =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            dist(
                with.fitted.markers[j].position,
                truth_spec.markers[j].position
            ) < 0.5 * dist(spec.markers[j].position, truth_spec.markers[j].position),
            "seed {seed}: {:?}",
            with.markers
        );
        assert!(e_with < e_without, "seed {seed}: {e_with} ≥ {e_without}");
        with_sum += e_with;
        without_sum += e_without;
    }
    eprintln!("joint RMS error summed over seeds: {without_sum:.2} without, {with_sum:.2} with");
    // A clean trial: no decision.
    let trial = synthetic(&model, &start, 60, 0.0003);
    assert!(decide(&model, &start, &[&trial], &[]).is_empty());
}

#[test]
fn envelope_holds_a_hip_beyond_it_on_every_solver_and_says_so() {
    // The template's ASIS at ±120 mm: plausibility limit 108 mm, bound 107 mm. The truth
    // puts the hip centre 113 mm lateral, 5 mm beyond the limit, which the data show.
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let lat = model.param_id("hip_pelvis_lateral").unwrap().0;
    let mut p_true = start.clone();
    p_true[lat] = 0.113;
    let trial = synthetic(&model, &p_true, 60, 0.0003);
    for method in Method::ALL {
        let settings = FitSettings {
            method,
            marker_noise: Some(0.001),
            uncertainty: Some(crate::calibrate::uncertainty::UncertaintyOptions::default()),
            ..FitSettings::default()
        };
        let r = calibrate_refined(&model, &start, &[&trial], &free, &settings, &mut NoObserver)
            .unwrap();
        let fitted = r.calibration.fit.p[lat];
        eprintln!(
            "{method}: hip lateral {:.2} mm, {:?}",
            fitted * 1e3,
            r.envelope
        );
        assert_eq!(r.envelope.len(), 1);
        assert!(r.envelope[0].active, "{method}: {:?}", r.envelope);
        assert!((fitted - 0.107).abs() < 1e-9, "{method}: {fitted}");
        let row = &r.calibration.parameters[lat];
        assert_eq!(row.source, Some(Source::HeldAtLimit), "{method}");
        assert_ne!(
            row.identifiability,
            Some(crate::calibrate::uncertainty::Identifiability::Determined)
        );
        let check = &r.calibration.plausibility[0];
        assert!(check.check.contains(HELD_AT_LIMIT) && check.ok, "{check:?}");
        // The fitted description keeps the input's bounds.
        assert_eq!(r.fitted.parameters[lat].upper, spec.parameters[lat].upper);
        // Without the envelope the same data push the hip past the limit.
        let off = FitSettings {
            anatomical_envelope: false,
            ..settings.clone()
        };
        if method == Method::Joint {
            let free_fit =
                calibrate_refined(&model, &start, &[&trial], &free, &off, &mut NoObserver).unwrap();
            let x = free_fit.calibration.fit.p[lat];
            assert!(x > 0.108 && free_fit.envelope.is_empty(), "{x}");
            assert!(!free_fit.calibration.plausibility[0].ok);
        }
    }
    // A truth inside the envelope: the bound is reported inactive only if reached (here it
    // is not), and the fit is the unbounded one.
    let trial = synthetic(&model, &start, 60, 0.0003);
    let settings = FitSettings {
        marker_noise: Some(0.001),
        ..FitSettings::default()
    };
    let r =
        calibrate_refined(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap();
    assert!(r.envelope.iter().all(|b| !b.active));
    assert_eq!(
        r.model.parameters()[lat].upper,
        model.parameters()[lat].upper
    );
}

#[test]
fn no_decision_on_clean_trials_with_the_joints_off_their_landmarks() {
    // No marker moved; the joints off the landmark model by prior-sized errors. A marker's
    // residual after IK at the landmark model then carries the joints' error (the heel, far
    // from the ankle axes on a three-marker foot, sat 30–35 mm off in 5 % of such trials in
    // `coverage --prior --default`), which the policy refined as a displaced marker.
    use crate::checks::offsets::marker_offsets;
    use crate::ik::{IkOptions, MarkerMap};
    let spec = spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let start = model.nominal_params();
    assert!(model.parameters().iter().all(|par| par.prior_sd.is_some()));
    let mut ik_says_displaced = Vec::new();
    for seed in 1..=40u64 {
        // The landmark model wrong by the landmark method's published error.
        let p = model.sample_priors(seed);
        let trial = synthetic(&model, &p, 60, 0.0003);
        let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
        for o in marker_offsets(&model, &start, &trial, &map, &IkOptions::default(), None) {
            if o.displaced() {
                ik_says_displaced.push((seed, model.markers()[o.marker].name.clone()));
            }
        }
        let d = decide(&model, &start, &[&trial], &[]);
        assert!(d.is_empty(), "seed {seed}: {d:?}");
    }
    eprintln!("displaced by the IK statistic alone: {ik_says_displaced:?}");
    // The case is exercised: the IK statistic alone calls some correct marker displaced.
    assert!(!ik_says_displaced.is_empty());
}
