//! Critical values of the intervals: the normal and Student-t quantiles and the fixed-b
//! critical value of the Newey–West (Bartlett) HAC interval.
//!
//! # Why the HAC interval needs its own critical value
//!
//! The HAC bandwidth `b` is not small against the trial: Andrews' rule asks for more than
//! the cap `N/5` on every synthetic skin-noise trial tried, so `b/N = 0.2`. The usual
//! normal critical value assumes `b/N → 0`, where the long-run variance estimate is
//! consistent. With `b/N` fixed it is not: it stays random (few effective degrees of
//! freedom) and biased downwards (the scores of a fitted model sum to zero), and the
//! studentized estimate `t = (θ̂ − θ)/se_HAC` converges to a nonstandard limit, a ratio of a
//! normal and a functional of a Brownian bridge (Kiefer & Vogelsang 2005, "A new asymptotic
//! theory for heteroskedasticity-autocorrelation robust tests", Econometric Theory
//! 21:1130–1164). Its two-sided 95 % critical value for the Bartlett kernel is, to a cubic
//! fit in `ρ = b/N` (their Table 1 response surface):
//!
//! `cv(ρ) = 1.9600 + 2.9694 ρ + 0.4160 ρ² − 0.5324 ρ³`
//!
//! (1.96 at `ρ → 0`, 2.57 at the cap `ρ = 0.2`, 4.81 at `ρ = 1`). The test
//! `fixed_b_value_covers_in_simulation` checks it against a seeded simulation of the
//! statistic itself. At another level the excess over `z` is scaled by `z/1.96`
//! (simulated: 90.3–91.4 % at 0.90 and 98.2–98.8 % at 0.99 for `ρ` 0.05–0.5). With several
//! trials the ratio is the bandwidth over the mean trial length (lags never cross trials).

use super::UncertaintyOptions;

/// Largest `b/N` of the fixed-b response surface.
const MAX_RATIO: f64 = 1.0;

/// Two-sided critical value at `level` of the Bartlett-kernel HAC interval with bandwidth
/// `ratio = b/N` of the trial length, under fixed-b asymptotics (Kiefer & Vogelsang 2005;
/// see the module docs). `ratio = 0` gives the normal quantile.
pub fn fixed_b_bartlett(level: f64, ratio: f64) -> f64 {
    let r = ratio.clamp(0.0, MAX_RATIO);
    let cv95 = 1.9600 + 2.9694 * r + 0.4160 * r * r - 0.5324 * r * r * r;
    let z = normal_quantile(0.5 + 0.5 * level);
    z * cv95 / 1.96
}

/// Inverse of the standard normal CDF (Acklam's rational approximation, |error| < 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        let t = (-2.0 * q.ln()).sqrt();
        (((((C[0] * t + C[1]) * t + C[2]) * t + C[3]) * t + C[4]) * t + C[5])
            / ((((D[0] * t + D[1]) * t + D[2]) * t + D[3]) * t + 1.0)
    };
    if p <= 0.0 {
        f64::NEG_INFINITY
    } else if p >= 1.0 {
        f64::INFINITY
    } else if p < 0.02425 {
        tail(p)
    } else if p > 1.0 - 0.02425 {
        -tail(1.0 - p)
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Quantile of Student's t with `nu` degrees of freedom from the normal one (Cornish–Fisher
/// expansion, Abramowitz & Stegun 26.7.5; relative error < 1e-4 for `nu ≥ 5` at 0.975).
pub fn t_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7, z9) = (z.powi(3), z.powi(5), z.powi(7), z.powi(9));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
        + (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / (92160.0 * nu.powi(4))
}

/// Critical values: `z` for white, HAC and bootstrap; Student's t with `K − 1` degrees of
/// freedom for the `K`-block jackknife.
pub(super) fn critical(level: f64, opts: &UncertaintyOptions) -> (f64, f64) {
    let p = 0.5 + 0.5 * level;
    let k = opts.jackknife_blocks.max(2) as f64;
    (normal_quantile(p), t_quantile(p, k - 1.0))
}

#[cfg(test)]
mod tests {
    use super::super::estimators::long_run;
    use super::*;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn t_quantile_matches_tables() {
        // Student t 0.975 quantiles: 9 dof 2.262157, 19 dof 2.093024, 4 dof 2.776445.
        assert!((t_quantile(0.975, 9.0) - 2.262157).abs() < 2e-4);
        assert!((t_quantile(0.975, 19.0) - 2.093024).abs() < 1e-5);
        assert!((t_quantile(0.975, 4.0) - 2.776445).abs() < 5e-3);
    }

    #[test]
    fn normal_quantile_matches_known_values() {
        assert!((normal_quantile(0.975) - 1.959963984540054).abs() < 1e-8);
        assert!((normal_quantile(0.5)).abs() < 1e-12);
        assert!((normal_quantile(0.005) + 2.5758293035489).abs() < 1e-8);
    }

    /// Oracle: the distribution of the HAC t statistic itself, simulated (seeded) on
    /// independent normal series of 200 frames with the mean estimated, as a fit estimates
    /// its parameters; the fixed-b critical value must cover at its level within Monte
    /// Carlo error (4000 replicates: ±0.7 points at 95 %, 2 SE).
    #[test]
    fn fixed_b_value_covers_in_simulation() {
        let (n, reps) = (200usize, 4000usize);
        let mut rng = ChaCha8Rng::seed_from_u64(20050);
        let mut normal = || {
            // Box–Muller.
            let u1: f64 = 1.0 - rng.gen::<f64>();
            let u2: f64 = rng.gen();
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let series: Vec<Vec<f64>> = (0..reps)
            .map(|_| (0..n).map(|_| normal()).collect())
            .collect();
        let same = vec![true; n - 1];
        for ratio in [0.1, 0.2, 0.5] {
            let b = ratio * n as f64;
            let stats: Vec<f64> = series
                .iter()
                .map(|x| {
                    let mean = x.iter().sum::<f64>() / n as f64;
                    let scores: Vec<DVector<f64>> = x
                        .iter()
                        .map(|v| DVector::from_element(1, v - mean))
                        .collect();
                    let omega = long_run(&scores, &same, b)[(0, 0)];
                    (mean * (n as f64).sqrt() / (omega / n as f64).sqrt()).abs()
                })
                .collect();
            for (level, tol) in [(0.95, 0.007), (0.90, 0.02)] {
                let cv = fixed_b_bartlett(level, ratio);
                let covered = stats.iter().filter(|t| **t <= cv).count() as f64 / reps as f64;
                assert!(
                    (covered - level).abs() <= tol,
                    "b/N {ratio}, level {level}: cv {cv:.3} covers {covered:.4}"
                );
                // The normal quantile undercovers whenever b/N is not small.
                let z = normal_quantile(0.5 + 0.5 * level);
                let with_z = stats.iter().filter(|t| **t <= z).count() as f64 / reps as f64;
                assert!(with_z < level - 0.02, "b/N {ratio}: z covers {with_z:.4}");
            }
        }
        assert_eq!(fixed_b_bartlett(0.95, 0.0), normal_quantile(0.975));
    }
}
