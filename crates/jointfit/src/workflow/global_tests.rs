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

/// The σ₀-optimum's coordinates carried by the re-probe's change of its frames
/// ([`super::super::probes::carried`]): a change linear along each trial is carried exactly
/// between two re-probe frames of a trial, held from the nearest one outside them and never
/// across a trial's end; and coordinates solved at other parameters, carried by the solution
/// at the new parameters on every 4th frame, fit the new parameters almost as well as their
/// own solution (the finishing solve's start).
#[test]
fn coordinates_carried_by_a_subsample_follow_the_new_parameters() {
    use crate::calibrate::Problem;
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p1 = model.nominal_params();
    let (a, b) = (
        synthetic(&model, &p1, 23, 0.002),
        synthetic(&model, &p1, 17, 0.002),
    );
    let free = params_for_groups(&model, &["all"]).unwrap();
    let prob = Problem::new(&model, p1.clone(), &free, &[&a, &b]).unwrap();
    let n = prob.frames.len();
    assert_eq!(n, 40);
    let stride = 4;
    // A change linear in each trial's frame number: 0.01·(trial + 1)·(1 + frame / 10) per
    // coordinate c, times (c + 1).
    let delta = |f: usize, c: usize| {
        let (t, frame) = prob.origin[f];
        0.01 * (t + 1) as f64 * (1.0 + frame as f64 / 10.0) * (c + 1) as f64
    };
    let nq = model.coordinates().len();
    let at: Vec<Vec<f64>> = (0..n).map(|f| vec![0.1 * f as f64; nq]).collect();
    let moved: Vec<Vec<f64>> = (0..n)
        .step_by(stride)
        .map(|f| (0..nq).map(|c| at[f][c] + delta(f, c)).collect())
        .collect();
    let out = super::super::probes::carried(&prob, &at, &moved, stride);
    // Trial 1 is frames 0..23 (re-probe frames 0, 4, …, 20), trial 2 frames 23..40 (24, …, 36).
    for f in 0..n {
        let reference = match f {
            21 | 22 => 20,
            23 => 24,
            37..=39 => 36,
            _ => f,
        };
        for c in 0..nq {
            let want = at[f][c] + delta(reference, c);
            assert!((out[f][c] - want).abs() < 1e-12, "frame {f} coordinate {c}");
        }
    }
    // The hip centre and the knee axis elsewhere, on trials of a gait cycle each at
    // 150 and 120 frames, every 7th frame re-solved (gait2392 walk1's probes).
    let (a, b) = (
        synthetic(&model, &p1, 150, 0.002),
        synthetic(&model, &p1, 120, 0.002),
    );
    let prob = Problem::new(&model, p1.clone(), &free, &[&a, &b]).unwrap();
    let stride = 7;
    let mut p2 = p1.clone();
    for (k, x) in model.parameters().iter().enumerate().take(6) {
        p2[k] += 0.05 * (x.upper - x.lower);
    }
    let q1 = prob.initial_coords(&p1);
    let q2 = prob.initial_coords(&p2);
    let coarse = super::super::probes::subsample(&prob, stride);
    let moved = coarse.initial_coords(&p2);
    let out = super::super::probes::carried(&prob, &q1, &moved, stride);
    let (stale, carried, own) = (
        prob.marker_rms(&p2, &q1),
        prob.marker_rms(&p2, &out),
        prob.marker_rms(&p2, &q2),
    );
    assert!(stale > own + 1e-3, "{stale} {own}");
    assert!(
        carried - own < 0.1 * (stale - own),
        "{stale} {carried} {own}"
    );
}
