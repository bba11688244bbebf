//! Rust-only checks of the filter: the design's response, zero-phase behaviour on sines,
//! constants and linearity, the conventions, errors, and trials with gaps.

use std::f64::consts::PI;

use nalgebra::Vector3;
use proptest::prelude::*;

use super::*;
use jointfit::trial::Trial;

/// |H(f)|² of an order-`n` digital Butterworth (bilinear, pre-warped) with cutoff `fc`.
fn butterworth_power(n: usize, fc: f64, f: f64, fs: f64) -> f64 {
    let r = (PI * f / fs).tan() / (PI * fc / fs).tan();
    1.0 / (1.0 + r.powi(2 * n as i32))
}

fn sine(len: usize, freq: f64, rate: f64, amp: f64, phase: f64, offset: f64) -> Vec<f64> {
    (0..len)
        .map(|i| offset + amp * (2.0 * PI * freq * i as f64 / rate + phase).sin())
        .collect()
}

#[test]
fn design_response_is_butterworth() {
    for n in 1..=10 {
        for &(fc, fs) in &[(6.0, 100.0), (6.0, 1000.0), (20.0, 50.0), (0.5, 200.0)] {
            let sos = butter_lowpass(n, fc, fs).unwrap();
            assert_eq!(sos.sections().len(), n.div_ceil(2));
            assert_eq!(sos.ntaps(), n + 1);
            assert_eq!(sos.default_padlen(), 3 * (n + 1));
            assert!(
                (sos.dc_gain() - 1.0).abs() < 1e-12,
                "n={n} dc {}",
                sos.dc_gain()
            );
            assert!((sos.gain(fc, fs).powi(2) - 0.5).abs() < 1e-12);
            assert!(sos.gain(fs / 2.0, fs) < 1e-12);
            for k in 1..40 {
                let f = fs / 2.0 * k as f64 / 40.0;
                let want = butterworth_power(n, fc, f, fs);
                let got = sos.gain(f, fs).powi(2);
                assert!(
                    (got - want).abs() <= 1e-12 * want.max(1e-300) + 1e-15,
                    "n={n} fc={fc} fs={fs} f={f}: |H|² {got} vs {want}"
                );
            }
        }
    }
}

#[test]
fn sine_far_below_cutoff_passes_with_zero_phase() {
    let (fs, f) = (100.0, 0.25);
    for filter in [
        LowPass::default(),
        LowPass {
            convention: OrderConvention::Design,
            ..LowPass::default()
        },
    ] {
        let sos = filter.design(fs).unwrap();
        let x = sine(2000, f, fs, 0.05, 0.7, 0.0);
        let y = filter.apply(&x, fs).unwrap();
        let g = sos.gain(f, fs).powi(2);
        // |H|² = 1/(1 + r^(2N)), r = tan(π f/f_s)/tan(π f_c/f_s) ≈ 0.041: 1 − 3e-6 for N = 2.
        assert!((g - 1.0).abs() < 1e-5, "gain {g}");
        // A phase error δ would leave a residual of about 0.05·δ; 1e-9 m bounds δ to ~2e-8 rad.
        for i in 200..1800 {
            assert!(
                (y[i] - g * x[i]).abs() < 1e-9,
                "frame {i}: {} vs {}",
                y[i],
                x[i]
            );
        }
    }
}

#[test]
fn sine_above_cutoff_is_attenuated_by_squared_gain() {
    let fs = 100.0;
    for filter in [
        LowPass::default(),
        LowPass {
            convention: OrderConvention::Design,
            ..LowPass::default()
        },
        LowPass {
            winter_correction: true,
            ..LowPass::default()
        },
    ] {
        let sos = filter.design(fs).unwrap();
        for f in [6.0, 9.0, 15.0, 30.0, 45.0] {
            let x = sine(3000, f, fs, 0.01, 0.3, 0.0);
            let y = filter.apply(&x, fs).unwrap();
            let g = sos.gain(f, fs).powi(2);
            let g_formula = butterworth_power(
                filter.design_order().unwrap(),
                filter.design_cutoff_hz(fs).unwrap(),
                f,
                fs,
            );
            assert!((g - g_formula).abs() <= 1e-12 * g_formula);
            for i in 1000..2000 {
                assert!(
                    (y[i] - g * x[i]).abs() <= 1e-9 * 0.01,
                    "{filter:?} f={f} frame {i}: {} vs {}",
                    y[i],
                    g * x[i]
                );
            }
        }
    }
}

#[test]
fn winter_correction_puts_minus_3_db_of_the_double_pass_at_the_cutoff() {
    assert!((winter_correction_factor(2, 2) - 0.802_243_262_923_150_2).abs() < 1e-15);
    for convention in [OrderConvention::Effective, OrderConvention::Design] {
        for &(fc, fs) in &[(6.0, 100.0), (6.0, 60.0), (40.0, 100.0)] {
            let plain = LowPass {
                cutoff_hz: fc,
                convention,
                ..LowPass::default()
            };
            let corrected = LowPass {
                winter_correction: true,
                ..plain
            };
            let g_plain = plain.design(fs).unwrap().gain(fc, fs).powi(2);
            let g_corr = corrected.design(fs).unwrap().gain(fc, fs).powi(2);
            assert!((g_plain - 0.5).abs() < 1e-12);
            assert!((g_corr - 0.5f64.sqrt()).abs() < 1e-12, "{g_corr}");
            let fd = corrected.design_cutoff_hz(fs).unwrap();
            assert!(fd > fc && fd < fs / 2.0);
        }
    }
    // Far below Nyquist the pre-warped correction is the familiar fc / C.
    let f = LowPass {
        winter_correction: true,
        ..LowPass::default()
    };
    let fd = f.design_cutoff_hz(10_000.0).unwrap();
    assert!((fd - 6.0 / winter_correction_factor(2, 2)).abs() < 1e-5);
}

#[test]
fn conventions_and_defaults() {
    let d = LowPass::default();
    assert_eq!((d.cutoff_hz, d.order), (6.0, 4));
    assert_eq!(d.design_order(), Ok(2));
    assert_eq!(d.effective_order(), Ok(4));
    let design = LowPass {
        convention: OrderConvention::Design,
        ..d
    };
    assert_eq!(design.design_order(), Ok(4));
    assert_eq!(design.effective_order(), Ok(8));
    assert_eq!(
        d.design(100.0).unwrap(),
        butter_lowpass(2, 6.0, 100.0).unwrap()
    );
    // Settings read from a configuration file fall back to the defaults.
    let cfg: LowPass = toml::from_str("convention = \"design\"\nwinter_correction = true").unwrap();
    assert_eq!(cfg.convention, OrderConvention::Design);
    assert!(cfg.winter_correction);
    assert_eq!((cfg.cutoff_hz, cfg.order), (6.0, 4));
    assert!(toml::from_str::<LowPass>("cutof_hz = 5.0").is_err());
}

#[test]
fn invalid_settings_are_typed_errors() {
    let bad_cutoff = |cutoff_hz: f64, rate: f64| {
        matches!(
            LowPass {
                cutoff_hz,
                ..LowPass::default()
            }
            .design(rate),
            Err(SignalError::BadCutoff { .. })
        )
    };
    assert!(bad_cutoff(50.0, 100.0));
    assert!(bad_cutoff(60.0, 100.0));
    assert!(bad_cutoff(0.0, 100.0));
    assert!(bad_cutoff(-1.0, 100.0));
    assert!(bad_cutoff(f64::NAN, 100.0));
    assert!(!bad_cutoff(49.9, 100.0));
    let e = LowPass::default().design(10.0).unwrap_err();
    assert_eq!(
        e.to_string(),
        "cutoff frequency must be positive and below the Nyquist frequency (5 Hz at 10 Hz \
         sampling), got 6 Hz"
    );
    for rate in [0.0, -100.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            LowPass::default().design(rate),
            Err(SignalError::BadRate(_))
        ));
    }
    let order = |order, convention| {
        LowPass {
            order,
            convention,
            ..LowPass::default()
        }
        .design(100.0)
    };
    assert_eq!(
        order(3, OrderConvention::Effective),
        Err(SignalError::OddEffectiveOrder(3))
    );
    assert!(matches!(
        order(0, OrderConvention::Effective),
        Err(SignalError::BadDesignOrder { order: 0, .. })
    ));
    assert!(matches!(
        order(0, OrderConvention::Design),
        Err(SignalError::BadDesignOrder { order: 0, .. })
    ));
    assert!(matches!(
        order(MAX_DESIGN_ORDER + 1, OrderConvention::Design),
        Err(SignalError::BadDesignOrder { .. })
    ));
    assert!(order(3, OrderConvention::Design).is_ok());
    assert!(order(2 * MAX_DESIGN_ORDER, OrderConvention::Effective).is_ok());

    let sos = butter_lowpass(2, 6.0, 100.0).unwrap();
    assert_eq!(
        sosfiltfilt(&sos, &[1.0; 9]),
        Err(SignalError::TooShort { len: 9, padlen: 9 })
    );
    assert!(sosfiltfilt(&sos, &[1.0; 10]).is_ok());
    let mut x = vec![1.0; 20];
    x[7] = f64::NAN;
    assert!(matches!(
        sosfiltfilt(&sos, &x),
        Err(SignalError::NonFinite { index: 7, .. })
    ));
    let one = sosfiltfilt_padlen(&sos, &[2.0], 0).unwrap();
    assert!(one.len() == 1 && (one[0] - 2.0).abs() < 1e-12);
}

#[test]
fn odd_extension_reflects_about_the_end_samples() {
    let x = [1.0, 2.0, 4.0, 7.0];
    assert_eq!(
        odd_extend(&x, 2).unwrap(),
        vec![-2.0, 0.0, 1.0, 2.0, 4.0, 7.0, 10.0, 12.0]
    );
    assert_eq!(odd_extend(&x, 0).unwrap(), x.to_vec());
    assert!(odd_extend(&x, 4).is_err());
}

#[test]
fn steady_state_initial_conditions_hold_a_constant() {
    for n in 1..=8 {
        let sos = butter_lowpass(n, 3.0, 100.0).unwrap();
        let mut state = sosfilt_zi(&sos);
        for z in &mut state {
            z[0] *= 2.5;
            z[1] *= 2.5;
        }
        let start = state.clone();
        let mut x = vec![2.5; 50];
        sosfilt_in_place(&sos, &mut x, &mut state);
        for v in x {
            assert!((v - 2.5).abs() < 1e-12, "n={n}: {v}");
        }
        for (a, b) in start.iter().zip(&state) {
            assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn constant_stays_constant(
        c in -5.0f64..5.0,
        n in 1usize..=8,
        frac in 0.005f64..0.45,
        extra in 1usize..200,
    ) {
        let sos = butter_lowpass(n, frac * 100.0, 100.0).unwrap();
        let x = vec![c; sos.default_padlen() + extra];
        let y = sosfiltfilt(&sos, &x).unwrap();
        for v in y {
            prop_assert!((v - c).abs() <= 1e-10 * c.abs().max(1.0), "{} vs {}", v, c);
        }
    }

    #[test]
    fn filtering_is_linear(
        xs in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 10..300),
        a in -3.0f64..3.0,
        b in -3.0f64..3.0,
        n in 1usize..=4,
    ) {
        let sos = butter_lowpass(n, 6.0, 100.0).unwrap();
        let padlen = sos.default_padlen().min(xs.len() - 1);
        let x: Vec<f64> = xs.iter().map(|p| p.0).collect();
        let y: Vec<f64> = xs.iter().map(|p| p.1).collect();
        let mix: Vec<f64> = xs.iter().map(|p| a * p.0 + b * p.1).collect();
        let fx = sosfiltfilt_padlen(&sos, &x, padlen).unwrap();
        let fy = sosfiltfilt_padlen(&sos, &y, padlen).unwrap();
        let fm = sosfiltfilt_padlen(&sos, &mix, padlen).unwrap();
        for i in 0..x.len() {
            let want = a * fx[i] + b * fy[i];
            prop_assert!((fm[i] - want).abs() <= 1e-12 * (a.abs() + b.abs() + 1.0));
        }
    }
}

fn trial(rate: f64, columns: Vec<Vec<Vector3<f64>>>) -> Trial {
    let frames = columns[0].len();
    let labels = (0..columns.len()).map(|i| format!("M{i}")).collect();
    let positions = (0..frames)
        .flat_map(|f| columns.iter().map(move |c| c[f]))
        .collect();
    Trial::new(labels, rate, 1, positions).unwrap()
}

fn wobble(frames: usize, seed: f64) -> Vec<Vector3<f64>> {
    (0..frames)
        .map(|i| {
            let t = i as f64 / 100.0;
            Vector3::new(
                0.3 + 0.05 * (2.0 * PI * 1.1 * t + seed).sin() + 0.002 * (37.0 * t * t).sin(),
                0.9 + 0.02 * (2.0 * PI * 0.7 * t).cos(),
                -0.1 + 0.004 * (2.0 * PI * 23.0 * t + seed).sin(),
            )
        })
        .collect()
}

#[test]
fn trial_is_filtered_per_stretch_and_gaps_stay_missing() {
    let nan = Vector3::repeat(f64::NAN);
    let mut a = wobble(120, 0.0);
    // Stretches of marker A: 0..40 (40), 43..46 (3: raw), 50..56 (6: reduced pad 5), 57..120.
    for f in [40, 41, 42, 46, 47, 48, 49, 56] {
        a[f] = nan;
    }
    a[47].y = f64::INFINITY; // any non-finite coordinate makes the sample missing
    let b = vec![nan; 120];
    let c = wobble(120, 1.0);
    let t = trial(100.0, vec![a.clone(), b, c.clone()]);

    let (out, report) = filter_trial(&t, &LowPass::default()).unwrap();
    assert_eq!((report.design_order, report.default_padlen), (2, 9));
    assert_eq!(report.min_padlen, 3);
    let ma = &report.markers[0];
    assert_eq!(ma.label, "M0");
    assert_eq!(
        ma.filtered,
        vec![
            FilteredStretch {
                frames: 0..40,
                padlen: 9
            },
            FilteredStretch {
                frames: 50..56,
                padlen: 5
            },
            FilteredStretch {
                frames: 57..120,
                padlen: 9
            },
        ]
    );
    assert_eq!(ma.raw, vec![43..46]);
    assert!(report.markers[1].filtered.is_empty() && report.markers[1].raw.is_empty());
    assert_eq!(report.markers[1].max_displacement_frame, None);
    assert_eq!(report.markers[2].raw, Vec::<std::ops::Range<usize>>::new());
    assert_eq!(report.raw_stretch_count(), 1);

    let sos = LowPass::default().design(100.0).unwrap();
    let out_a = out.trajectory(0);
    for f in [40, 41, 42, 46, 47, 48, 49, 56] {
        assert!(out.get(f, 0).is_none());
        assert!(out_a[f].iter().all(|v| v.is_nan()));
    }
    for f in 43..46 {
        assert_eq!(out_a[f], a[f], "raw stretch keeps measured values");
    }
    let mut max_d: f64 = 0.0;
    for st in &ma.filtered {
        for axis in 0..3 {
            let x: Vec<f64> = a[st.frames.clone()].iter().map(|p| p[axis]).collect();
            let y = sosfiltfilt_padlen(&sos, &x, st.padlen).unwrap();
            for (k, f) in st.frames.clone().enumerate() {
                assert_eq!(out_a[f][axis], y[k]);
            }
        }
        for f in st.frames.clone() {
            max_d = max_d.max((out_a[f] - a[f]).norm());
        }
    }
    assert_eq!(ma.max_displacement_m, max_d);
    let fm = ma.max_displacement_frame.unwrap();
    assert_eq!((out_a[fm] - a[fm]).norm(), max_d);
    // The 23 Hz wobble of 4 mm in z is filtered out almost entirely.
    assert!(max_d > 0.003 && max_d < 0.01, "{max_d}");
    assert_eq!(report.moved_more_than(0.02).count(), 0);
    assert_eq!(report.moved_more_than(0.001).count(), 2);
    assert_eq!(
        report.max_displacement_m(),
        ma.max_displacement_m
            .max(report.markers[2].max_displacement_m)
    );

    // The untouched marker C equals the plain filter on its whole trajectory.
    let out_c = out.trajectory(2);
    let x: Vec<f64> = c.iter().map(|p| p.x).collect();
    assert_eq!(
        out_c.iter().map(|p| p.x).collect::<Vec<_>>(),
        LowPass::default().apply(&x, 100.0).unwrap()
    );

    // With LeaveRaw, the 6-frame stretch is not filtered either.
    let leave = LowPass {
        short_stretches: ShortStretches::LeaveRaw,
        ..LowPass::default()
    };
    let (out2, r2) = filter_trial(&t, &leave).unwrap();
    assert_eq!(r2.markers[0].raw, vec![43..46, 50..56]);
    for (f, p) in a.iter().enumerate().take(56).skip(50) {
        assert_eq!(out2.get(f, 0), Some(*p));
    }
}

#[test]
fn short_stretch_thresholds() {
    let reduce = LowPass::default();
    let sos = reduce.design(100.0).unwrap(); // ntaps 3, default padlen 9
    let leave = LowPass {
        short_stretches: ShortStretches::LeaveRaw,
        ..reduce
    };
    let got: Vec<_> = (0..12).map(|l| reduce.padlen_for(&sos, l)).collect();
    let want = [
        None,
        None,
        None,
        None,
        Some(3),
        Some(4),
        Some(5),
        Some(6),
        Some(7),
        Some(8),
        Some(9),
        Some(9),
    ];
    assert_eq!(got, want);
    let got: Vec<_> = (0..12).map(|l| leave.padlen_for(&sos, l)).collect();
    assert_eq!(&got[..10], &[None; 10]);
    assert_eq!(&got[10..], &[Some(9), Some(9)]);
}

#[test]
fn trial_errors_and_empty_trials() {
    let t = trial(10.0, vec![wobble(30, 0.0)]);
    assert!(matches!(
        filter_trial(&t, &LowPass::default()),
        Err(SignalError::BadCutoff { .. })
    ));
    let empty = Trial::new(vec!["A".into()], 100.0, 0, vec![]).unwrap();
    let (out, report) = filter_trial(&empty, &LowPass::default()).unwrap();
    assert_eq!(out.n_frames(), 0);
    assert_eq!(report.markers.len(), 1);
    assert_eq!(report.max_displacement_m(), 0.0);
}
