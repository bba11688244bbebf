//! Comparisons with `scipy.signal`: live through `$JOINTFIT_PYTHON` and
//! `scripts/filter_reference.py` (skipped with a notice outside CI when it is unset), and
//! offline against the committed `testdata/signal_scipy_reference.json` made by that script.

use std::io::Write;
use std::process::{Command, Stdio};

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use super::*;
use jointfit::trial::Trial;

/// Runs `scripts/filter_reference.py` on `request`; `None` when there is no Python oracle.
fn scipy(request: &Value) -> Option<Value> {
    let python = jointfit_testkit::env::python()?;
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scripts/filter_reference.py"
    );
    let mut child = Command::new(&python)
        .arg(script)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    // The script reads all of its input before it writes anything.
    child
        .stdin
        .take()
        .unwrap()
        .write_all(request.to_string().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "filter_reference.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("filter_reference.py answers JSON"))
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// Largest deviation of our coefficients from scipy's, each relative to the largest coefficient
/// of its polynomial (numerator or denominator of that section).
fn coefficient_deviation(ours: &Sos, theirs: &Value) -> f64 {
    let rows: Vec<Vec<f64>> = theirs.as_array().unwrap().iter().map(floats).collect();
    assert_eq!(rows.len(), ours.sections().len(), "number of sections");
    let mut worst: f64 = 0.0;
    for (mine, row) in ours.to_rows().iter().zip(&rows) {
        for half in [0..3, 3..6] {
            let scale = row[half.clone()].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in half {
                worst = worst.max((mine[i] - row[i]).abs() / scale);
            }
        }
    }
    worst
}

/// max |ours − theirs| / max |theirs|.
fn relative_deviation(ours: &[f64], theirs: &[f64]) -> f64 {
    assert_eq!(ours.len(), theirs.len());
    let scale = theirs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    ours.iter()
        .zip(theirs)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
        / scale
}

/// A slow sine on an offset plus uniform noise, like a marker coordinate in metres.
fn noisy_sine(rng: &mut ChaCha8Rng, len: usize, rate: f64) -> Vec<f64> {
    let (offset, amp) = (rng.gen_range(-1.0..1.0), rng.gen_range(0.01..0.2));
    let (freq, phase) = (rng.gen_range(0.3..3.0), rng.gen_range(0.0..6.3));
    (0..len)
        .map(|i| {
            let t = i as f64 / rate;
            offset
                + amp * (2.0 * std::f64::consts::PI * freq * t + phase).sin()
                + rng.gen_range(-0.005..0.005)
        })
        .collect()
}

#[test]
fn design_matches_scipy_butter() {
    let settings = [
        (6.0, 100.0),
        (6.0, 1000.0),
        (6.0, 60.0),
        (0.5, 200.0),
        (20.0, 100.0),
        (25.0, 100.0),
        (40.0, 100.0),
        (48.0, 100.0),
    ];
    let mut cases = Vec::new();
    for order in 1..=8 {
        for &(cutoff_hz, rate_hz) in &settings {
            cases.push((order, cutoff_hz, rate_hz));
        }
    }
    let request = json!({
        "butter": cases.iter().map(|&(o, f, r)| json!({"order": o, "cutoff_hz": f, "rate_hz": r}))
            .collect::<Vec<_>>()
    });
    let Some(answer) = scipy(&request) else {
        return;
    };
    let mut worst: f64 = 0.0;
    for (&(order, cutoff, rate), theirs) in cases.iter().zip(answer["butter"].as_array().unwrap()) {
        let ours = butter_lowpass(order, cutoff, rate).unwrap();
        let d = coefficient_deviation(&ours, theirs);
        assert!(
            d <= 1e-12,
            "butter({order}, {cutoff}/({rate}/2)): deviation {d:e}\nours {:?}\nscipy {theirs}",
            ours.to_rows()
        );
        worst = worst.max(d);
    }
    eprintln!(
        "design vs scipy {}: max coefficient deviation {worst:e} over {} designs",
        answer["scipy"],
        cases.len()
    );
}

#[test]
fn sosfiltfilt_matches_scipy() {
    let mut rng = ChaCha8Rng::seed_from_u64(20050621);
    let conventions = [
        (2, OrderConvention::Effective),
        (4, OrderConvention::Effective),
        (2, OrderConvention::Design),
        (4, OrderConvention::Design),
    ];
    let mut cases = Vec::new(); // (filter, rate, x, padlen)
    for &(order, convention) in &conventions {
        for winter_correction in [false, true] {
            for &(cutoff_hz, rate) in &[(6.0, 100.0), (6.0, 1000.0), (12.0, 50.0)] {
                let filter = LowPass {
                    cutoff_hz,
                    order,
                    convention,
                    winter_correction,
                    ..LowPass::default()
                };
                let sos = filter.design(rate).unwrap();
                let (ntaps, pad) = (sos.ntaps(), sos.default_padlen());
                for len in [pad + 1, pad + 2, pad + 7, 100, 1500] {
                    cases.push((filter, rate, noisy_sine(&mut rng, len, rate), None));
                }
                // Reduced padding, as filter_trial uses for short stretches, and none at all.
                for (len, padlen) in [(ntaps + 1, ntaps), (pad, pad - 1), (2 * pad, 0)] {
                    let x = noisy_sine(&mut rng, len, rate);
                    cases.push((filter, rate, x, Some(padlen)));
                }
            }
        }
    }
    let request = json!({
        "sosfiltfilt": cases.iter().map(|(filter, rate, x, padlen)| json!({
            "order": filter.design_order().unwrap(),
            "cutoff_hz": filter.design_cutoff_hz(*rate).unwrap(),
            "rate_hz": rate,
            "x": x,
            "padlen": padlen,
        })).collect::<Vec<_>>()
    });
    let Some(answer) = scipy(&request) else {
        return;
    };
    let mut worst: f64 = 0.0;
    for ((filter, rate, x, padlen), theirs) in
        cases.iter().zip(answer["sosfiltfilt"].as_array().unwrap())
    {
        let ours = match padlen {
            None => filter.apply(x, *rate).unwrap(),
            Some(p) => sosfiltfilt_padlen(&filter.design(*rate).unwrap(), x, *p).unwrap(),
        };
        let d = relative_deviation(&ours, &floats(theirs));
        assert!(
            d <= 1e-9,
            "{filter:?} at {rate} Hz, {} samples, padlen {padlen:?}: relative deviation {d:e}",
            x.len()
        );
        worst = worst.max(d);
    }
    eprintln!(
        "sosfiltfilt vs scipy: max relative deviation {worst:e} over {} signals",
        cases.len()
    );
}

/// A trial of noisy sines at `rate` with one marker per gap pattern (missing frame ranges),
/// and each marker's trajectory.
fn gapped_trial(
    rng: &mut ChaCha8Rng,
    rate: f64,
    frames: usize,
    gaps: &[&[(usize, usize)]],
) -> (Trial, Vec<Vec<Vector3<f64>>>) {
    let labels: Vec<String> = (0..gaps.len()).map(|i| format!("M{i}")).collect();
    let columns: Vec<Vec<Vector3<f64>>> = gaps
        .iter()
        .map(|g| {
            let (x, y, z) = (
                noisy_sine(rng, frames, rate),
                noisy_sine(rng, frames, rate),
                noisy_sine(rng, frames, rate),
            );
            (0..frames)
                .map(|f| {
                    if g.iter().any(|&(a, b)| (a..b).contains(&f)) {
                        Vector3::repeat(f64::NAN)
                    } else {
                        Vector3::new(x[f], y[f], z[f])
                    }
                })
                .collect()
        })
        .collect();
    let positions = (0..frames)
        .flat_map(|f| columns.iter().map(move |c| c[f]))
        .collect();
    (Trial::new(labels, rate, 1, positions).unwrap(), columns)
}

/// Which stretch-coordinates scipy is asked to filter: (marker, frames, axis).
type Requests = Vec<(usize, std::ops::Range<usize>, usize)>;

/// Walks every marker's stretches: gaps stay missing in `out`, stretches left raw are
/// unchanged, and the filtered ones become scipy requests (with the padding scipy's
/// default rule gives: a design of order n has ntaps = n + 1 and pads 3·ntaps, restated
/// independently of `LowPass::padlen_for`); the report counts both.
fn stretch_requests(
    filter: &LowPass,
    columns: &[Vec<Vector3<f64>>],
    out: &Trial,
    report: &FilterReport,
) -> (Requests, Vec<serde_json::Value>) {
    let ntaps = filter.design_order().unwrap() + 1;
    let expected_padlen = |len: usize| {
        if len > 3 * ntaps {
            Some(None)
        } else if filter.short_stretches == ShortStretches::ReducePadding && len > ntaps {
            Some(Some(len - 1))
        } else {
            None
        }
    };
    let mut requests = Vec::new();
    let mut items = Vec::new();
    for (m, col) in columns.iter().enumerate() {
        let frames = col.len();
        let present: Vec<bool> = col.iter().map(|p| !p.x.is_nan()).collect();
        let mut f = 0;
        let (mut n_filtered, mut n_raw) = (0, 0);
        while f < frames {
            if !present[f] {
                assert!(
                    out.get(f, m).is_none(),
                    "gap at frame {f} of M{m} stays missing"
                );
                f += 1;
                continue;
            }
            let start = f;
            while f < frames && present[f] {
                f += 1;
            }
            match expected_padlen(f - start) {
                None => {
                    n_raw += 1;
                    for (k, p) in col.iter().enumerate().take(f).skip(start) {
                        assert_eq!(out.get(k, m), Some(*p));
                    }
                }
                Some(padlen) => {
                    n_filtered += 1;
                    for axis in 0..3 {
                        let x: Vec<f64> = col[start..f].iter().map(|p| p[axis]).collect();
                        items.push(json!({
                            "order": filter.design_order().unwrap(),
                            "cutoff_hz": filter.cutoff_hz,
                            "rate_hz": out.rate(),
                            "x": x,
                            "padlen": padlen,
                        }));
                        requests.push((m, start..f, axis));
                    }
                }
            }
        }
        assert_eq!(report.markers[m].filtered.len(), n_filtered, "M{m}");
        assert_eq!(report.markers[m].raw.len(), n_raw, "M{m}");
    }
    (requests, items)
}

#[test]
fn trial_filter_matches_scipy_per_stretch() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    // Gap patterns (missing frame ranges) giving stretches of many lengths around the thresholds.
    let gaps: [&[(usize, usize)]; 4] = [
        &[],
        &[(20, 25), (28, 30), (34, 40), (50, 52), (62, 63), (79, 90)],
        &[
            (0, 3),
            (6, 8),
            (13, 14),
            (30, 31),
            (47, 60),
            (76, 77),
            (155, 160),
        ],
        &[(3, 150)],
    ];
    let (trial, columns) = gapped_trial(&mut rng, 100.0, 160, &gaps);
    for filter in [
        LowPass::default(),
        LowPass {
            convention: OrderConvention::Design,
            ..LowPass::default()
        },
        LowPass {
            short_stretches: ShortStretches::LeaveRaw,
            ..LowPass::default()
        },
    ] {
        let (out, report) = filter_trial(&trial, &filter).unwrap();
        let (requests, items) = stretch_requests(&filter, &columns, &out, &report);
        let Some(answer) = scipy(&json!({ "sosfiltfilt": items })) else {
            return;
        };
        let mut worst: f64 = 0.0;
        for ((m, frames, axis), theirs) in requests
            .iter()
            .zip(answer["sosfiltfilt"].as_array().unwrap())
        {
            let ours: Vec<f64> = frames
                .clone()
                .map(|f| out.get(f, *m).unwrap()[*axis])
                .collect();
            let d = relative_deviation(&ours, &floats(theirs));
            assert!(d <= 1e-9, "M{m} frames {frames:?} axis {axis}: {d:e}");
            worst = worst.max(d);
        }
        eprintln!(
            "filter_trial vs scipy per stretch ({:?}, {:?}): max relative deviation {worst:e} \
             over {} stretch-coordinates",
            filter.convention,
            filter.short_stretches,
            requests.len()
        );
    }
}

#[test]
fn committed_reference_matches() {
    let text = include_str!("../testdata/signal_scipy_reference.json");
    let reference: Value = serde_json::from_str(text).unwrap();
    for case in reference["butter"].as_array().unwrap() {
        let ours = butter_lowpass(
            case["order"].as_u64().unwrap() as usize,
            case["cutoff_hz"].as_f64().unwrap(),
            case["rate_hz"].as_f64().unwrap(),
        )
        .unwrap();
        let d = coefficient_deviation(&ours, &case["sos"]);
        assert!(d <= 1e-12, "{case}: {d:e}");
    }
    for case in reference["sosfiltfilt"].as_array().unwrap() {
        let rate = case["rate_hz"].as_f64().unwrap();
        let sos = butter_lowpass(
            case["order"].as_u64().unwrap() as usize,
            case["cutoff_hz"].as_f64().unwrap(),
            rate,
        )
        .unwrap();
        let x = floats(&case["x"]);
        let ours = match case["padlen"].as_u64() {
            None => sosfiltfilt(&sos, &x).unwrap(),
            Some(p) => sosfiltfilt_padlen(&sos, &x, p as usize).unwrap(),
        };
        let d = relative_deviation(&ours, &floats(&case["y"]));
        assert!(
            d <= 1e-9,
            "order {} length {}: {d:e}",
            case["order"],
            x.len()
        );
    }
}
