//! Checks of command-line values and of loaded data, with the limits documented here.
//!
//! The value parsers are used as clap `value_parser`s, so a bad value is reported as
//! `invalid value 'NaN' for '--noise-mm <NOISE_MM>': must be a finite number` (naming the
//! option); numeric options also set `allow_negative_numbers` so that `--filter -6` reaches
//! the parser instead of clap's `-- -6` hint.
//!
//! Limits:
//! - `--filter`: at least [`MIN_FILTER_HZ`] Hz (a lower cutoff rings over the whole trial and
//!   smears gait into a drift); the Nyquist limit is checked against the trial's rate when it
//!   is filtered.
//! - frame counts of synthetic motions: at most [`MAX_FRAMES`]; of `bench` workloads at most
//!   [`MAX_BENCH_FRAMES`], its repetitions at most [`MAX_RUNS`].
//! - starts, seeds and stride of `reproduce`: at most [`MAX_RUNS`]; rates of synthetic
//!   motions at most [`MAX_RATE_HZ`].
//! - synthetic motions: `--amplitude` at most [`MAX_AMPLITUDE`], noise and perturbations at
//!   most [`MAX_NOISE_MM`] mm or 180°, `--skin-omega` at most [`MAX_OMEGA`] rad/s.
//! - bootstrap replicates: at most [`MAX_BOOTSTRAP`] (each is a refit).
//! - outer iterations of a calibration (`--max-iter`): 1 to [`MAX_ITERATIONS`].
//! - digits after the decimal point: at most [`MAX_DECIMALS`] (f64 has 17 significant digits).
//! - marker coordinates: within ±[`MAX_POSITION_M`] m; rates at most [`MAX_RATE_HZ`].

use std::path::Path;

use anyhow::{bail, Result};
use jointfit::trial::Trial;

/// Lowest accepted low-pass cutoff (Hz).
pub const MIN_FILTER_HZ: f64 = 0.1;
/// Most frames of a synthetic motion (1000 s at 100 Hz).
pub const MAX_FRAMES: usize = 100_000;
/// Most starts, seeds or stride of `reproduce`.
pub const MAX_RUNS: usize = 1_000;
/// Most frames of a `bench` workload (`--long-frames`, `--rss-frames`, `--io-frames`): five
/// times the largest default, about 1.5 GB of trial and text at the workload's markers.
pub const MAX_BENCH_FRAMES: usize = 500_000;
/// Most block-bootstrap replicates.
pub const MAX_BOOTSTRAP: usize = jointfit_app::fit::MAX_BOOTSTRAP;
/// Most outer iterations of a calibration (`--max-iter`).
pub const MAX_ITERATIONS: usize = jointfit_app::fit::MAX_ITERATIONS;
/// Most digits after the decimal point in written files.
pub const MAX_DECIMALS: usize = 12;
/// Largest plausible sampling rate (Hz).
pub const MAX_RATE_HZ: f64 = jointfit_app::read::MAX_RATE_HZ;
/// Largest factor on synthetic joint excursions.
pub const MAX_AMPLITUDE: f64 = 10.0;
/// Largest skin-artifact angular frequency (rad/s).
pub const MAX_OMEGA: f64 = 10_000.0;
/// Largest noise, artifact or perturbation amplitude (mm).
pub const MAX_NOISE_MM: f64 = jointfit_app::fit::MAX_NOISE_MM;

fn number(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if !v.is_finite() {
        return Err("must be a finite number".into());
    }
    Ok(v)
}

/// A finite number greater than zero.
pub fn positive(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v <= 0.0 {
        return Err(format!("must be greater than 0 (got {v})"));
    }
    Ok(v)
}

/// A finite number, zero or more.
pub fn non_negative(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v < 0.0 {
        return Err(format!("must not be negative (got {v})"));
    }
    Ok(v)
}

/// A low-pass cutoff in Hz, at least [`MIN_FILTER_HZ`].
pub fn cutoff_hz(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v < MIN_FILTER_HZ {
        return Err(format!("must be at least {MIN_FILTER_HZ} Hz (got {v})"));
    }
    Ok(v)
}

/// A noise amplitude or standard deviation in mm, greater than 0 and at most
/// [`MAX_NOISE_MM`].
pub fn noise_mm(s: &str) -> Result<f64, String> {
    let v = positive(s)?;
    if v > MAX_NOISE_MM {
        return Err(format!("must be at most {MAX_NOISE_MM} mm (got {v})"));
    }
    Ok(v)
}

/// A noise amplitude in mm that may be zero (noiseless), at most [`MAX_NOISE_MM`].
pub fn noise_mm_or_zero(s: &str) -> Result<f64, String> {
    let v = non_negative(s)?;
    if v > MAX_NOISE_MM {
        return Err(format!("must be at most {MAX_NOISE_MM} mm (got {v})"));
    }
    Ok(v)
}

fn count(s: &str, lo: usize, hi: usize) -> Result<usize, String> {
    let v: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a whole number from {lo} to {hi}"))?;
    if v < lo || v > hi {
        return Err(format!("must be from {lo} to {hi} (got {v})"));
    }
    Ok(v)
}

fn within(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v < lo || v > hi {
        return Err(format!("must be from {lo} to {hi}{unit} (got {v})"));
    }
    Ok(v)
}

/// A factor on the joint excursions of a synthetic motion: 0 to [`MAX_AMPLITUDE`].
pub fn amplitude(s: &str) -> Result<f64, String> {
    within(s, 0.0, MAX_AMPLITUDE, "")
}

/// A perturbation of positions in mm: 0 to [`MAX_NOISE_MM`].
pub fn perturb_mm(s: &str) -> Result<f64, String> {
    within(s, 0.0, MAX_NOISE_MM, " mm")
}

/// A perturbation of orientations in degrees: 0 to 180.
pub fn perturb_deg(s: &str) -> Result<f64, String> {
    within(s, 0.0, 180.0, " deg")
}

/// An angular frequency in rad/s: 0 to [`MAX_OMEGA`].
pub fn omega(s: &str) -> Result<f64, String> {
    within(s, 0.0, MAX_OMEGA, " rad/s")
}

/// Frames of a synthetic motion: 1 to [`MAX_FRAMES`].
pub fn frames(s: &str) -> Result<usize, String> {
    count(s, 1, MAX_FRAMES)
}

/// Frames of a timed `bench` workload: 0 (skip) to [`MAX_BENCH_FRAMES`].
pub fn bench_frames(s: &str) -> Result<usize, String> {
    count(s, 0, MAX_BENCH_FRAMES)
}

/// A repetition count of `bench` that may be 0 (skip): 0 to [`MAX_RUNS`].
pub fn runs_or_zero(s: &str) -> Result<usize, String> {
    count(s, 0, MAX_RUNS)
}

/// A run count (starts, seeds, stride): 1 to [`MAX_RUNS`].
pub fn runs(s: &str) -> Result<usize, String> {
    count(s, 1, MAX_RUNS)
}

/// A sampling rate in Hz: greater than 0, at most [`MAX_RATE_HZ`].
pub fn rate_hz(s: &str) -> Result<f64, String> {
    let v = positive(s)?;
    if v > MAX_RATE_HZ {
        return Err(format!("must be at most {MAX_RATE_HZ} Hz (got {v})"));
    }
    Ok(v)
}

/// Bootstrap replicates: 0 (none) to [`MAX_BOOTSTRAP`].
pub fn bootstrap(s: &str) -> Result<usize, String> {
    count(s, 0, MAX_BOOTSTRAP)
}

/// An outer iteration limit: 1 to [`MAX_ITERATIONS`].
pub fn iterations(s: &str) -> Result<usize, String> {
    count(s, 1, MAX_ITERATIONS)
}

/// Digits after the decimal point: 0 to [`MAX_DECIMALS`].
pub fn decimals(s: &str) -> Result<usize, String> {
    count(s, 0, MAX_DECIMALS)
}

/// A trial's data are plausible ([`jointfit_app::check_plausible`], the check every front end
/// runs): the error names the file, the frame (file numbering) and the marker, or the units.
pub fn check_trial(path: &Path, trial: &Trial) -> Result<()> {
    jointfit_app::check_plausible(trial, &path.display().to_string())
        .map_err(|e| anyhow::anyhow!("{e}"))
}

/// Names given to `option` (e.g. `--keep-markers`) that are not markers of `model` are
/// refused, listing the model's markers.
pub fn model_markers(option: &str, names: &[String], model: &jointfit::model::Model) -> Result<()> {
    let known: Vec<&str> = model.markers().iter().map(|m| m.name.as_str()).collect();
    let unknown: Vec<&str> = names
        .iter()
        .map(String::as_str)
        .filter(|n| !known.contains(n))
        .collect();
    if !unknown.is_empty() {
        bail!(
            "{option} {}: not a marker of the model {:?}; its markers are {}",
            unknown.join(","),
            model.spec().name,
            known.join(", ")
        );
    }
    Ok(())
}

/// Label swaps that touch the same marker in overlapping frames (the same pair twice, either
/// order, or two pairs sharing a marker) are refused: applied one after the other they would
/// cancel or chain, which no one means.
pub fn distinct_swaps(swaps: &[jointfit::repair::Swap]) -> Result<()> {
    let span = |s: &jointfit::repair::Swap| {
        (
            s.from.unwrap_or(i64::MIN),
            s.to.or(s.from.map(|_| i64::MAX)).unwrap_or(i64::MAX),
        )
    };
    for (i, x) in swaps.iter().enumerate() {
        for y in &swaps[..i] {
            let shared: Vec<&str> = [&x.a, &x.b]
                .into_iter()
                .filter(|n| **n == y.a || **n == y.b)
                .map(String::as_str)
                .collect();
            let ((xf, xt), (yf, yt)) = (span(x), span(y));
            if !shared.is_empty() && xf <= yt && yf <= xt {
                bail!(
                    "--swap-labels {},{} and {},{} both swap {} in the same frames; give each \
                     marker at most one swap per frame range",
                    y.a,
                    y.b,
                    x.a,
                    x.b,
                    shared.join(" and ")
                );
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn parsers_reject_non_finite_negative_and_out_of_range() {
        for bad in ["NaN", "nan", "inf", "-inf", "1e999", "x", ""] {
            assert!(positive(bad).is_err(), "{bad}");
            assert!(cutoff_hz(bad).is_err(), "{bad}");
        }
        assert!(noise_mm("-4").unwrap_err().contains("greater than 0"));
        assert_eq!(noise_mm("4").unwrap(), 4.0);
        assert!(noise_mm("1e300").is_err());
        assert!(cutoff_hz("1e-7").unwrap_err().contains("at least 0.1 Hz"));
        assert!(cutoff_hz("-6").is_err());
        assert_eq!(cutoff_hz("6").unwrap(), 6.0);
        assert!(frames("18446744073709551615").is_err());
        assert!(frames("4294967296").is_err());
        assert!(frames("0").is_err());
        assert_eq!(frames("100000").unwrap(), 100_000);
        assert!(bootstrap("100000000").is_err());
        assert_eq!(bootstrap("0").unwrap(), 0);
        assert!(decimals("1000000").is_err());
        assert_eq!(non_negative("0").unwrap(), 0.0);
        assert!(non_negative("-0.5").is_err());
    }

    #[test]
    fn absurd_positions_are_named_by_frame_and_marker() {
        let labels = vec!["A".to_string(), "B".to_string()];
        let mut pos = vec![Vector3::new(0.1, 0.2, 0.3); 6];
        let t = Trial::new(labels.clone(), 100.0, 1, pos.clone()).unwrap();
        check_trial(Path::new("t.trc"), &t).unwrap();
        pos[3] = Vector3::new(1e300, 0.0, 0.0);
        let t = Trial::new(labels.clone(), 100.0, 1, pos).unwrap();
        let e = check_trial(Path::new("t.trc"), &t).unwrap_err().to_string();
        assert!(e.contains("t.trc: frame 2, marker B"), "{e}");
        let t = Trial::new(labels.clone(), 1e300, 1, vec![Vector3::zeros(); 2]).unwrap();
        assert!(check_trial(Path::new("t.trc"), &t).is_err());
        let t = Trial::new(labels, 100.0, 1, vec![Vector3::repeat(f64::NAN); 4]).unwrap();
        check_trial(Path::new("t.trc"), &t).unwrap();
    }
}
