//! Critical values of the intervals: the normal and Student-t quantiles and the fixed-b
//! critical value of the Newey–West (Bartlett) HAC interval.
//!
//! # Why the HAC interval needs its own critical value
//!
//! The HAC bandwidth `b` is not small against the trial: on synthetic skin-noise trials of
//! 100 frames Andrews' rule asks for 20–100 frames, `b/N` from 0.2 to 1. The usual normal
//! critical value assumes `b/N → 0`, where the long-run variance estimate is consistent.
//! With `b/N` fixed it is not: it stays random (few effective degrees of freedom) and biased
//! downwards (the scores of a fitted model sum to zero), and the studentized estimate
//! `t = (θ̂ − θ)/se_HAC` converges to a nonstandard limit, a ratio of a normal and a
//! functional of a Brownian bridge (Kiefer & Vogelsang 2005, "A new asymptotic theory for
//! heteroskedasticity-autocorrelation robust tests", Econometric Theory 21:1130–1164). Its
//! two-sided 95 % critical value for the Bartlett kernel is, to a cubic fit in `ρ = b/N`
//! (their Table 1 response surface):
//!
//! `cv(ρ) = 1.9600 + 2.9694 ρ + 0.4160 ρ² − 0.5324 ρ³`
//!
//! (1.96 at `ρ → 0`, 2.57 at `ρ = 0.2`, 4.81 at `ρ = 1`). The test
//! `fixed_b_value_covers_in_simulation` checks it against a seeded simulation of the
//! statistic itself. At another level the excess over `z` is scaled by `z/1.96`
//! (simulated: 90.3–91.4 % at 0.90 and 98.2–98.8 % at 0.99 for `ρ` 0.05–0.5). With several
//! trials the ratio is the bandwidth over the mean trial length (lags never cross trials).
//!
//! # Why the bandwidth is capped only by the trial length
//!
//! With the normal critical value a bandwidth near the trial length is unusable (the
//! estimate shrinks to zero), so Andrews' rule used to be capped at `N/5`. The fixed-b value
//! accounts for that shrinkage and randomness at every `ρ ≤ 1`, so the cap has no reason left,
//! and it costs coverage: what fixed-b does not account for is the kernel's smoothing bias,
//! the part of the scores' spectrum near frequency zero that a window of `b` frames does not
//! see (a spectrum peaked at zero, i.e. dependence longer than the window). That bias shrinks
//! as `b` grows (Kiefer & Vogelsang 2005 §5: the size distortion is smallest at `b = N`), so
//! capping Andrews' choice below what the data ask for brings back exactly the
//! under-coverage. Measured (`docs/global.md`): the full-leg ankle's HAC interval covered
//! 90.2 % at the cap `N/5` and 92.4 % with Andrews' own choice (mean 41 of 100 frames), and
//! the reported interval 92.4 → 94.4 %.

use super::UncertaintyOptions;

/// Largest `b/N` of the fixed-b response surface.
const MAX_RATIO: f64 = 1.0;

/// Two-sided critical value at `level` of the Bartlett-kernel HAC interval with bandwidth
/// `ratio = b/N` of the trial length, under fixed-b asymptotics (Kiefer & Vogelsang 2005;
/// see the module docs). `ratio = 0` gives the normal quantile.
pub(crate) fn fixed_b_bartlett(level: f64, ratio: f64) -> f64 {
    let r = ratio.clamp(0.0, MAX_RATIO);
    let cv95 = 1.9600 + 2.9694 * r + 0.4160 * r * r - 0.5324 * r * r * r;
    let z = normal_quantile(0.5 + 0.5 * level);
    z * cv95 / 1.96
}

/// Inverse of the standard normal CDF (Acklam's rational approximation, |error| < 1.2e-9).
pub(crate) fn normal_quantile(p: f64) -> f64 {
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
pub(crate) fn t_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7, z9) = (z.powi(3), z.powi(5), z.powi(7), z.powi(9));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
        + (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / (92160.0 * nu.powi(4))
}

/// Cumulative distribution of Student's t with `nu > 0` degrees of freedom at `x`:
/// `1 − I_{ν/(ν+x²)}(ν/2, 1/2)/2` for `x ≥ 0` (Abramowitz & Stegun 26.7.1, 26.5.27).
pub(crate) fn t_cdf(x: f64, nu: f64) -> f64 {
    let tail = 0.5 * incomplete_beta(0.5 * nu, 0.5, nu / (nu + x * x));
    if x >= 0.0 {
        1.0 - tail
    } else {
        tail
    }
}

/// Quantile of Student's t with `nu` degrees of freedom (any `nu > 0`), `p > 0.5`: the root
/// of [`t_cdf`] by Newton steps on its density, kept inside a bisection bracket (a few
/// evaluations); the normal quantile beyond `1e7` degrees of freedom.
pub(crate) fn t_quantile_any(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    if nu > 1e7 {
        return z;
    }
    // t's quantile lies above the normal one; double the bracket until it holds the root.
    let (mut lo, mut hi) = (z * (1.0 - 1e-9), z.max(1.0) * 2.0);
    while t_cdf(hi, nu) < p && hi < 1e12 {
        lo = hi;
        hi *= 2.0;
    }
    let ln_norm =
        ln_gamma(0.5 * (nu + 1.0)) - ln_gamma(0.5 * nu) - 0.5 * (nu * std::f64::consts::PI).ln();
    let density = |x: f64| (ln_norm - 0.5 * (nu + 1.0) * (1.0 + x * x / nu).ln()).exp();
    let mut x = if nu >= 3.0 {
        t_quantile(p, nu).clamp(lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    for _ in 0..100 {
        let g = t_cdf(x, nu) - p;
        if g < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let step = x - g / density(x);
        let next = if step > lo && step < hi {
            step
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= 1e-12 * x.abs() || hi - lo <= 1e-12 * hi {
            return next;
        }
        x = next;
    }
    x
}

/// The degrees of freedom `ν` of the Student t whose `p` quantile is `cv` (infinite when `cv`
/// is the normal quantile or below), to 1e-6 relative: the t that matches an interval's
/// critical value, e.g. the fixed-b one, at its level.
pub(crate) fn dof_of_critical(p: f64, cv: f64) -> f64 {
    if cv <= normal_quantile(p) * (1.0 + 1e-12) {
        return f64::INFINITY;
    }
    // The quantile falls as ν grows; bisect on ln ν.
    let (mut lo, mut hi) = ((0.05f64).ln(), (1e7f64).ln());
    while hi - lo > 1e-6 {
        let mid = 0.5 * (lo + hi);
        if t_quantile_any(p, mid.exp()) > cv {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// Critical value at the `p` quantile of `e/√(v̂_r + v_p)` when `e ~ N(0, v_r + v_p)`, the
/// part `v_r` estimated with `nu` degrees of freedom and `v_p` known: Student's t with the
/// Welch–Satterthwaite degrees of freedom `ν (v_r + v_p)²/v_r²` (Satterthwaite 1946,
/// Biometrics 2:110–114). `t_ν`'s quantile when `v_p = 0`, the normal one when `v_r = 0`.
pub(crate) fn mixed_critical(p: f64, nu: f64, v_random: f64, v_known: f64) -> f64 {
    if v_random <= 0.0 {
        return normal_quantile(p);
    }
    let r = (v_random + v_known) / v_random;
    t_quantile_any(p, nu * r * r)
}

/// Regularized incomplete beta `I_x(a, b)` by its continued fraction (A&S 26.5.8), evaluated
/// with the modified Lentz method, on the side where it converges fast.
fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(a, b, x) / a
    } else {
        1.0 - front * beta_fraction(b, a, 1.0 - x) / b
    }
}

/// The continued fraction `1/(1+ d₁/(1+ d₂/(1+ …)))` of A&S 26.5.8, `d_{2m+1} =
/// −(a+m)(a+b+m)x/((a+2m)(a+2m+1))`, `d_{2m} = m(b−m)x/((a+2m−1)(a+2m))`, by the modified
/// Lentz method on `f = 1 + d₁/(1 + d₂/(1 + …))`.
fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (mut f, mut c, mut d) = (1.0, 1.0, 0.0);
    for i in 1..10_000 {
        let m = (i / 2) as f64;
        let num = if i % 2 == 1 {
            -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0))
        } else {
            m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m))
        };
        d = 1.0 + num * d;
        if d.abs() < TINY {
            d = TINY;
        }
        d = 1.0 / d;
        c = 1.0 + num / c;
        if c.abs() < TINY {
            c = TINY;
        }
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    1.0 / f
}

/// `ln Γ(x)`, `x > 0`, by Lanczos' approximation (g = 7, 9 terms; relative error ≈ 1e-15).
pub(crate) fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x)Γ(1−x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).abs().ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
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
    fn t_distribution_matches_closed_forms_and_tables() {
        // ν = 1 (Cauchy): F(x) = 1/2 + atan(x)/π; ν = 2: F(x) = 1/2 + x/(2√(2 + x²)).
        for x in [0.3f64, 1.0, 4.0, 30.0] {
            let cauchy = 0.5 + x.atan() / std::f64::consts::PI;
            assert!((t_cdf(x, 1.0) - cauchy).abs() < 1e-12, "ν 1, x {x}");
            let two = 0.5 + x / (2.0 * (2.0 + x * x).sqrt());
            assert!((t_cdf(x, 2.0) - two).abs() < 1e-12, "ν 2, x {x}");
        }
        // Tabulated 0.975 quantiles: ν 1 12.7062, 2 4.3027, 3 3.1824, 9 2.2622, 30 2.0423.
        for (nu, q) in [
            (1.0, 12.7062),
            (2.0, 4.3027),
            (3.0, 3.1824),
            (9.0, 2.2622),
            (30.0, 2.0423),
        ] {
            assert!((t_quantile_any(0.975, nu) - q).abs() < 1e-4, "ν {nu}");
            assert!((dof_of_critical(0.975, q) - nu).abs() < 1e-3 * nu, "ν {nu}");
        }
        assert!(dof_of_critical(0.975, 1.95).is_infinite());
    }

    /// Oracle: a seeded simulation of `e/√(v̂_r + v_p)` with `v̂_r ~ v_r χ²_ν/ν`; the
    /// Welch–Satterthwaite critical value covers at its level, at most 1.5 points above it (the
    /// approximation is slightly conservative at few degrees of freedom); Monte Carlo error
    /// ±0.3 points (2 SE).
    #[test]
    fn mixed_critical_value_covers_in_simulation() {
        let mut rng = ChaCha8Rng::seed_from_u64(1946);
        let mut normal = || {
            let u1: f64 = 1.0 - rng.gen::<f64>();
            let u2: f64 = rng.gen();
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let reps = 20_000;
        for (nu, share) in [(3usize, 0.5), (9, 0.3), (3, 0.9)] {
            let (vr, vp) = (share, 1.0 - share);
            let cv = mixed_critical(0.975, nu as f64, vr, vp);
            assert!(cv > normal_quantile(0.975) && cv < t_quantile_any(0.975, nu as f64));
            let mut hit = 0usize;
            for _ in 0..reps {
                let e = normal() * (vr + vp).sqrt();
                let chi2: f64 = (0..nu).map(|_| normal().powi(2)).sum();
                let v_hat = vr * chi2 / nu as f64;
                hit += (e.abs() <= cv * (v_hat + vp).sqrt()) as usize;
            }
            let covered = hit as f64 / reps as f64;
            assert!(
                (0.947..=0.965).contains(&covered),
                "ν {nu}, share {share}: {covered}"
            );
        }
        assert_eq!(mixed_critical(0.975, 5.0, 0.0, 1.0), normal_quantile(0.975));
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
