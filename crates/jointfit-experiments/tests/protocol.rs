//! The synthetic protocol of Reinbolt et al. 2005 with the known truth as the oracle.

use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::workflow::FitSettings;
use jointfit_experiments::protocol::{synthetic_case, SyntheticSetup};
use jointfit_experiments::synth::{coordinates, synthesize, Motion, Noise};

fn model() -> Model {
    Model::compile(&lower_limb(Side::Right)).unwrap()
}

const CASES: [(&[&str], Motion); 4] = [
    (&["hip"], Motion::Hip),
    (&["knee"], Motion::Knee),
    (&["ankle"], Motion::Ankle),
    (&["all"], Motion::All),
];

/// Without noise every joint, and the full leg, is recovered from a start 20 mm / 10° away
/// to far below the paper's "arbitrarily tight tolerance" (Table 1, first data set).
#[test]
fn noiseless_recovery_of_every_joint() {
    let model = model();
    let truth = model.nominal_params();
    for (groups, motion) in CASES {
        let coords = coordinates(&model, motion, 50).unwrap();
        let setup = SyntheticSetup {
            groups,
            coords: &coords,
            rate: 10.0,
            perturb_mm: 20.0,
            perturb_deg: 10.0,
        };
        for seed in [1, 2] {
            let r = synthetic_case(
                &model,
                &truth,
                &setup,
                &Noise::none(),
                &FitSettings::default(),
                seed,
            )
            .unwrap();
            let tag = format!("{groups:?} seed {seed}");
            assert!(r.converged, "{tag}");
            assert_eq!(r.noise_rms_3d_mm, 0.0);
            assert!(r.marker_rms_mm <= 1e-6, "{tag}: {} mm", r.marker_rms_mm);
            assert!(r.position_rms_mm.unwrap() <= 1e-6, "{tag}: {r:?}");
            // The start really was away from the truth.
            assert!(r.start_position_rms_mm.unwrap() > 3.0, "{tag}: {r:?}");
            match r.orientation_rms_deg {
                Some(d) => {
                    assert!(d <= 1e-6, "{tag}: {d} deg");
                    assert!(r.start_orientation_rms_deg.unwrap() > 1.0, "{tag}");
                }
                None => assert_eq!(groups, &["hip"], "only the hip has no orientations"),
            }
        }
    }
}

/// With the paper's skin-artifact noise the fit beats the truth (its cost is lower than the
/// cost at the true parameters, as the paper's discussion notes) and the errors sit in the
/// paper's range: marker RMS comparable to the noise (~5 mm in the paper), parameters within
/// about the paper's 10.4° and 10 mm (bounds loose enough for a few seeds).
#[test]
fn noisy_fits_beat_the_truth_with_paper_sized_errors() {
    let model = model();
    let truth = model.nominal_params();
    for (groups, motion) in CASES {
        let coords = coordinates(&model, motion, 50).unwrap();
        let setup = SyntheticSetup {
            groups,
            coords: &coords,
            rate: 10.0,
            perturb_mm: 20.0,
            perturb_deg: 10.0,
        };
        let settings = FitSettings {
            starts: 2,
            ..FitSettings::default()
        };
        for seed in [3, 4] {
            let r = synthetic_case(&model, &truth, &setup, &Noise::skin(seed), &settings, seed)
                .unwrap();
            let tag = format!("{groups:?} seed {seed}: {r:?}");
            assert!(r.cost_fit < r.cost_truth, "{tag}");
            assert!(r.noise_rms_3d_mm > 4.0 && r.noise_rms_3d_mm < 10.0, "{tag}");
            assert!(
                r.marker_rms_mm > 3.0 && r.marker_rms_mm < r.noise_rms_3d_mm,
                "{tag}"
            );
            assert!(r.position_rms_mm.unwrap() < 20.0, "{tag}");
            assert!(
                r.position_rms_mm.unwrap() > 0.05,
                "noise must move the fit: {tag}"
            );
            if let Some(d) = r.orientation_rms_deg {
                assert!(d < 30.0 && d > 0.01, "{tag}");
            }
        }
    }
}

/// The injected noise statistics are what the samples show, per axis and in 3-D.
#[test]
fn noise_statistics_match_the_samples() {
    let model = model();
    let p = model.nominal_params();
    let q = coordinates(&model, Motion::Knee, 200).unwrap();
    let (clean, zero) = synthesize(&model, &p, &q, 50.0, &Noise::none());
    assert_eq!(zero.rms_3d, 0.0);
    for noise in [
        Noise::skin(7),
        Noise::white(0.001, 7),
        Noise::skin_and_white(
            Noise::skin(7).skin.unwrap(),
            Noise::white(0.001, 7).white.unwrap(),
        ),
    ] {
        let (noisy, stats) = synthesize(&model, &p, &q, 50.0, &noise);
        let mut sums = [0.0; 3];
        let n = clean.positions().len() as f64;
        for (a, b) in noisy.positions().iter().zip(clean.positions()) {
            for (k, sum) in sums.iter_mut().enumerate() {
                *sum += (a[k] - b[k]).powi(2);
            }
        }
        for (sum, rms) in sums.iter().zip(stats.rms_axis) {
            assert!(((sum / n).sqrt() - rms).abs() < 1e-12);
        }
        let r3 = (stats.rms_axis.iter().map(|v| v * v).sum::<f64>()).sqrt();
        assert!((r3 - stats.rms_3d).abs() < 1e-15);
        if noise.skin.is_none() {
            // White noise: per-axis RMS ≈ σ (3000 samples per axis).
            for rms in stats.rms_axis {
                assert!((rms - 0.001).abs() < 0.0001, "{stats:?}");
            }
        }
    }
    // Skin terms of a seed do not change when white noise is added on its own stream: the
    // difference of the two trials is pure white noise.
    let (skin, _) = synthesize(&model, &p, &q, 50.0, &Noise::skin(7));
    let both = Noise::skin_and_white(
        Noise::skin(7).skin.unwrap(),
        Noise::white(1e-6, 7).white.unwrap(),
    );
    let (sw, _) = synthesize(&model, &p, &q, 50.0, &both);
    let worst = skin
        .positions()
        .iter()
        .zip(sw.positions())
        .map(|(a, b)| (a - b).amax())
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "{worst}");
}
