//! Tests of the global phase.

use super::super::calibration::calibrate;
use super::super::synthetic_tests::synthetic;
use super::super::{FitSettings, NoObserver};
use crate::calibrate::params_for_groups;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;

/// The whole global phase on a trial long enough for every parallel pass this module
/// and [`crate::calibrate::Problem`] run (probes on every 8th frame, two seeded chunks of
/// starting coordinates, inner passes in tasks, a finishing solve of a probe that is not
/// the given start): the same bits on 1, 2 and 3 threads.
#[test]
fn global_phase_gives_the_same_bits_on_any_thread_count() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let truth: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, x)| x.nominal + 0.12 * (x.upper - x.lower) * (k as f64 * 1.7).sin())
        .collect();
    let trial = synthetic(&model, &truth, 200, 0.004);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                calibrate(
                    &model,
                    &start,
                    &[&trial],
                    &free,
                    &FitSettings::default(),
                    &mut NoObserver,
                )
                .unwrap()
            })
    };
    let one = run(1);
    let g = one.global.clone().unwrap();
    assert_eq!(g.probe_frames, 25);
    assert!(g.finished.iter().any(|&k| k != 0), "{g:?}");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for threads in [2, 3] {
        let other = run(threads);
        assert_eq!(bits(&one.fit.p), bits(&other.fit.p), "{threads} threads");
        assert_eq!(one.cost_after.to_bits(), other.cost_after.to_bits());
        assert_eq!(one.cost_before.to_bits(), other.cost_before.to_bits());
        assert_eq!(one.global, other.global);
        for (a, b) in one.fit.coords.iter().zip(&other.fit.coords) {
            assert_eq!(bits(a), bits(b));
        }
    }
}

/// On a trial long enough for the σ stage's intermediate frames (300 frames: probes on every
/// 12th, the approach on every 3rd, `super::super::probes::approach`), the default MAP fit
/// with σ estimated agrees with the preliminary route (no global phase: a full fit to 0.01 SE
/// of the σ₀-optimum, σ estimated there, refitted) within the statistical resolution that the
/// σ stage's 0.1 SE allows (`super::super::map`'s module docs: σ within 0.3 %).
#[test]
fn sigma_stage_on_intermediate_frames_reaches_the_preliminary_fits_estimate() {
    let spec = super::super::refine_tests::spec_with_priors();
    let model = Model::compile(&spec).unwrap();
    let truth: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, x)| {
            let sd = x.prior_sd.unwrap_or(0.0);
            x.prior_mean + 0.7 * sd * (k as f64 * 2.3).sin()
        })
        .collect();
    let trial = synthetic(&model, &truth, 300, 0.006);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let fit = |probes: usize| {
        let settings = FitSettings {
            probes,
            uncertainty: Some(crate::calibrate::uncertainty::UncertaintyOptions::default()),
            ..FitSettings::default()
        };
        calibrate(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap()
    };
    let global = fit(FitSettings::default().probes);
    let preliminary = fit(0);
    assert!(
        global
            .convergence
            .iter()
            .any(|c| c.stage.ends_with(", every 3. frame")),
        "{:?}",
        global.convergence
    );
    let (s1, s0) = (
        global.prior_noise.unwrap(),
        preliminary.prior_noise.unwrap(),
    );
    assert!(global.prior_noise_estimated);
    assert!((s1 / s0 - 1.0).abs() < 3e-3, "σ {s1} vs {s0} mm");
    let worst = global
        .parameters
        .iter()
        .zip(&preliminary.parameters)
        .map(|(a, b)| (a.fitted - b.fitted).abs() / b.se.unwrap())
        .fold(0.0, f64::max);
    eprintln!("σ {s1:.4} vs {s0:.4} mm; parameters within {worst:.1e} SE");
    for (a, b) in global.parameters.iter().zip(&preliminary.parameters) {
        let se = b.se.expect("analysed");
        assert!(
            (a.fitted - b.fitted).abs() <= 0.02 * se,
            "{}: {} vs {} (SE {se})",
            a.name,
            a.fitted,
            b.fitted
        );
    }
}
