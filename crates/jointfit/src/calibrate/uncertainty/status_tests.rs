//! The identifiability status rule (`calibrate::uncertainty`, private `status` module): recomputed from the analysis' public fields by an independent path, and the
//! prior's part kept out of it.

use crate::calibrate::prior::{data_share, Source};
use crate::calibrate::uncertainty::correlation_inflation;
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::uncertainty::Identifiability;
use crate::calibrate::uncertainty::SeMethod;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::uncertainty::{analyze, predict};
use crate::calibrate::{params_for_groups, Problem};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::population::{fill_landmark_priors, HipCentreMethod};
use crate::model::Model;

use super::tests::{fit_from_nominal, knee_only_trial, perturbed, synthetic, Motion, Noise, ALL};

#[test]
fn status_is_the_fisher_half_width_with_the_trials_mean_correlation_factor() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 5);
    let trial = synthetic(&model, &p_true, ALL, 100, Noise::Skin, 0.01, 6);
    let (prob, fit) = fit_from_nominal(&model, &trial, &["all"]);
    let u = analyze(&prob, &fit, &UncertaintyOptions::default());
    // κ: the prior module's mean of (se_robust/se_white)², from the printed standard errors.
    let kappa = correlation_inflation(&u);
    assert!(
        kappa > 1.5,
        "skin artefact is correlated in time: κ {kappa}"
    );
    assert!(
        (u.correlation_factor / kappa - 1.0).abs() < 1e-9,
        "{} vs {kappa}",
        u.correlation_factor
    );
    let (mut determined, mut poor) = (0, 0);
    for p in &u.params {
        // Without a prior the data-alone Fisher error is the white one.
        let expected = u.z * kappa.sqrt() * p.se_white.unwrap();
        let h = p.status_half_width.unwrap();
        assert!(
            (h / expected - 1.0).abs() < 1e-9,
            "{}: {h} vs {expected}",
            p.name
        );
        let threshold = if p.unit == "mm" {
            u.threshold_m * 1e3
        } else {
            u.threshold_rad.to_degrees()
        };
        let want = if h <= threshold && !p.at_bound {
            determined += 1;
            Identifiability::Determined
        } else {
            poor += 1;
            Identifiability::Poor
        };
        assert_eq!(p.status, want, "{}", p.name);
    }
    // Both outcomes occur on this trial (knee angles determined, ankle positions not).
    assert!(
        determined > 0 && poor > 0,
        "{determined} determined, {poor} poor"
    );
}

#[test]
fn a_parameter_held_by_a_tight_prior_is_not_determined_by_the_trial() {
    // A knee motion tells nothing about the hip centre; a 0.5 mm prior on
    // hip_thigh_superior makes its interval narrow, but the trial did not determine it.
    let mut spec = lower_limb(Side::Right);
    fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    let tight = "hip_thigh_superior";
    for p in &mut spec.parameters {
        if p.name == tight {
            p.prior_sd = Some(0.0005);
        }
    }
    let model = Model::compile(&spec).unwrap();
    let (trial, _) = knee_only_trial(&model);
    let (prob, fit) = fit_from_nominal(&model, &trial, &["hip", "knee"]);
    let prob = prob.with_model_prior(0.005);
    let u = analyze(&prob, &fit, &UncertaintyOptions::default());
    let share = data_share(&prob, &reduced_system(&prob, &fit.p, &fit.coords).normal);
    let k = u.params.iter().position(|p| p.name == tight).unwrap();
    let p = &u.params[k];
    assert!(
        p.half_width.unwrap() < u.threshold_m * 1e3,
        "{:?}",
        p.half_width
    );
    assert_eq!(
        Source::of(share[k]),
        Source::HeldByPrior,
        "share {}",
        share[k]
    );
    assert_eq!(p.status, Identifiability::Poor);
    // Never "determined" where the information label says "held by the prior".
    for (p, s) in u.params.iter().zip(&share) {
        if Source::of(*s) == Source::HeldByPrior {
            assert_ne!(p.status, Identifiability::Determined, "{}", p.name);
        }
    }
}

/// `κ` is the trial's: a fit of the hip alone reports the correlation factor that the
/// analysis with every parameter free gives at the same point and bandwidth (`predict`, the
/// independent path: its own reduced system and estimators), not the mean over its six
/// parameters' own ratios.
#[test]
fn correlation_factor_is_pooled_over_every_parameter_whatever_is_free() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p_true = perturbed(&model, 5);
    let trial = synthetic(&model, &p_true, ALL, 100, Noise::Skin, 0.01, 6);
    let (prob, fit) = fit_from_nominal(&model, &trial, &["hip"]);
    let u = analyze(&prob, &fit, &UncertaintyOptions::default());
    let every = params_for_groups(&model, &["all"]).unwrap();
    let all = Problem::new(&model, fit.p.clone(), &every, &[&trial]).unwrap();
    let opts = UncertaintyOptions {
        hac_bandwidth: u.hac_bandwidth,
        ..UncertaintyOptions::default()
    };
    let v = predict(&all, &fit.p, &fit.coords, &opts);
    assert!(
        (u.correlation_factor / v.correlation_factor - 1.0).abs() < 1e-9,
        "{} vs {}",
        u.correlation_factor,
        v.correlation_factor
    );
    let own = correlation_inflation(&u);
    assert!(
        (own / u.correlation_factor - 1.0).abs() > 1e-3,
        "pooled over the hip only: {own}"
    );
}

/// The floor: a determined parameter whose label would not hold with the jackknife's
/// `t_{K−1}` in place of `z` (`t·h/z > T`) prints an interval of at least its status
/// half-width `h` (method `Pooled`); every other parameter keeps the widest of its
/// estimators, recomputed here from the printed standard errors and critical values. Hip
/// motion, hip free, 100 frames of 10 mm skin noise (case C of `docs/global.md`), 20 seeds:
/// 9 marginal parameter-fits, of which 1 has its robust interval below `h`.
#[test]
fn a_marginally_determined_parameters_interval_is_at_least_its_status_half_width() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let hip_only = Motion {
        hip: 1.0,
        knee: 0.0,
        ankle: 0.0,
    };
    let hip = params_for_groups(&model, &["hip"]).unwrap();
    let (mut floored, mut marginal_seen) = (0, 0);
    for seed in 1..=20 {
        // Only the hip is wrong: the fixed joints sit at the truth.
        let mut p_true = model.nominal_params();
        let moved = perturbed(&model, seed);
        for id in &hip {
            p_true[id.0] = moved[id.0];
        }
        let trial = synthetic(
            &model,
            &p_true,
            hip_only,
            100,
            Noise::Skin,
            0.01,
            100 + seed,
        );
        let (prob, fit) = fit_from_nominal(&model, &trial, &["hip"]);
        let u = analyze(&prob, &fit, &UncertaintyOptions::default());
        let t = u.t_jackknife.expect("jackknife");
        for p in &u.params {
            let widest = [
                p.se_white.map(|s| s * u.z),
                p.se_hac.zip(u.z_hac).map(|(s, c)| s * c),
                p.se_jackknife.map(|s| s * t),
            ]
            .into_iter()
            .flatten()
            .fold(0.0, f64::max);
            let h = p.status_half_width.unwrap();
            let threshold = u.threshold_m * 1e3;
            let marginal = p.status == Identifiability::Determined && t * h / u.z > threshold;
            let want = if marginal { widest.max(h) } else { widest };
            let got = p.half_width.unwrap();
            assert!(
                (got / want - 1.0).abs() < 1e-9,
                "seed {seed} {}: {got} vs {want}",
                p.name
            );
            marginal_seen += marginal as usize;
            if marginal && h > widest {
                floored += 1;
                assert_eq!(p.method, SeMethod::Pooled, "{}", p.name);
                assert!((p.se.unwrap() * u.z / h - 1.0).abs() < 1e-9);
            } else {
                assert_ne!(p.method, SeMethod::Pooled, "{}", p.name);
            }
        }
    }
    assert!(floored > 0, "{floored} floored of {marginal_seen} marginal");
}
