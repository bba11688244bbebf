//! Covariance estimators: white, Newey–West HAC, moving-block bootstrap, delete-block
//! jackknife; quantiles; the conservative choice (see the parent module for the math).

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;

use super::super::{Fit, Problem};
use super::critical::{dof_of_critical, fixed_b_bartlett, mixed_critical};
use super::resampling::{block_bootstrap, block_jackknife};
use super::{BootstrapInfo, Reduced, SeMethod, UncertaintyOptions, NULL_RATIO};

/// Symmetric pseudo-inverse and, per index, whether it touches a null direction.
pub(super) fn pseudo_inverse(
    s: &DMatrix<f64>,
) -> (DMatrix<f64>, Vec<bool>, SymmetricEigen<f64, nalgebra::Dyn>) {
    let n = s.nrows();
    let eig = SymmetricEigen::new(s.clone());
    let max = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut inv = DMatrix::zeros(n, n);
    let mut null_weight = vec![0.0; n];
    for j in 0..n {
        let lam = eig.eigenvalues[j];
        let v = eig.eigenvectors.column(j);
        if lam > NULL_RATIO * max && lam > 0.0 {
            inv += (v * v.transpose()) / lam;
        } else {
            for k in 0..n {
                null_weight[k] += v[k] * v[k];
            }
        }
    }
    (inv, null_weight.iter().map(|w| *w > 1e-6).collect(), eig)
}

/// `S⁺ g` for a symmetric `S`: by Cholesky when `S` is positive definite and its 1-norm
/// condition number `‖S‖₁‖S⁻¹‖₁` is below `0.1/NULL_RATIO`, else by [`pseudo_inverse`]. For
/// a symmetric matrix the spectral norms are at most the 1-norms, so the condition number
/// bounds `λ_max/λ_min`: no eigenvalue is below `NULL_RATIO·λ_max`, and the pseudo-inverse is
/// the inverse. (The eigen-decomposition costs about ten Cholesky factorisations: the block
/// jackknife's ten solves were 4 % of the command's instructions on opencap walking1.)
pub(super) fn pseudo_solve(s: &DMatrix<f64>, g: &DVector<f64>) -> DVector<f64> {
    let norm1 = |m: &DMatrix<f64>| {
        m.column_iter()
            .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    };
    if let Some(ch) = s.clone().cholesky() {
        let inv = ch.inverse();
        if norm1(s) * norm1(&inv) < 0.1 / NULL_RATIO {
            return inv * g;
        }
    }
    pseudo_inverse(s).0 * g
}

/// Newey–West long-run covariance of the scores with Bartlett bandwidth `b`; lags only
/// within one trial (`same[i]`: frame i+1 follows frame i in the same trial):
///
/// `Ω = Σ_i s_i s_iᵀ + Σ_{l=1}^{L} (1 − l/b) Σ_i (s_i s_{i+l}ᵀ + s_{i+l} s_iᵀ)`, `L = ⌈b⌉ − 1`
/// (Newey & West 1987, Econometrica 55:703).
///
/// In O(N·n_f²) whatever the bandwidth: with the kernel-weighted sum of the frames ahead
/// `T_i = Σ_{l=1}^{L_i} (1 − l/b) s_{i+l} = A_i − B_i/b` (`A_i = Σ s_{i+l}`, `B_i = Σ l s_{i+l}`,
/// `L_i` the lags that stay in frame i's run), `Ω = M + Mᵀ` with `M = Σ_i s_i (s_i/2 + T_i)ᵀ`.
/// `A_i` and `B_i` slide backwards through a run in O(n_f) per frame (recomputed exactly every
/// `L` frames so that rounding does not accumulate); `M` is summed over fixed chunks of frames
/// in parallel and the chunks added in order, so the result does not depend on the thread
/// count.
pub(super) fn long_run(scores: &[DVector<f64>], same: &[bool], b: f64) -> DMatrix<f64> {
    let n = scores[0].len();
    let frames = scores.len();
    let max_lag = (b.ceil() as usize).min(frames);
    // Lags 1..=lags have a positive Bartlett weight.
    let lags = (1..max_lag)
        .take_while(|&l| 1.0 - l as f64 / b > 0.0)
        .count();
    // u_i = s_i/2 + T_i, column i of an n × N matrix.
    let mut u = vec![0.0; n * frames];
    let mut end = frames.saturating_sub(1);
    let mut a = vec![0.0; n];
    let mut bsum = vec![0.0; n];
    let mut since_exact = usize::MAX;
    for i in (0..frames).rev() {
        if i + 1 < frames && !same[i] {
            end = i;
            since_exact = usize::MAX;
        }
        let reach = lags.min(end - i);
        if since_exact >= lags.max(1) {
            // Exact window sums over frames i+1 ..= i+reach.
            a.fill(0.0);
            bsum.fill(0.0);
            for l in 1..=reach {
                let s = &scores[i + l];
                for k in 0..n {
                    a[k] += s[k];
                    bsum[k] += l as f64 * s[k];
                }
            }
            since_exact = 0;
        } else {
            // Slide from frame i+1's window (i+1, i+1+reach'] to frame i's (i, i+reach].
            let dropped = i + 1 + lags <= end;
            let next = &scores[i + 1];
            for k in 0..n {
                let out = if dropped {
                    scores[i + 1 + lags][k]
                } else {
                    0.0
                };
                a[k] += next[k] - out;
                bsum[k] += a[k] - lags as f64 * out;
            }
            since_exact += 1;
        }
        let col = &mut u[i * n..(i + 1) * n];
        for k in 0..n {
            col[k] = 0.5 * scores[i][k] + a[k] - bsum[k] / b;
        }
    }
    const CHUNK: usize = 512;
    let partial: Vec<DMatrix<f64>> = (0..frames.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let (lo, hi) = (c * CHUNK, ((c + 1) * CHUNK).min(frames));
            let s = DMatrix::from_fn(n, hi - lo, |k, j| scores[lo + j][k]);
            let uc = DMatrix::from_column_slice(n, hi - lo, &u[lo * n..hi * n]);
            s * uc.transpose()
        })
        .collect();
    let m = partial
        .into_iter()
        .fold(DMatrix::zeros(n, n), |acc, p| acc + p);
    &m + m.transpose()
}

/// The direct `O(N·b·n_f²)` form of [`long_run`]: the oracle of its tests.
#[cfg(test)]
pub(super) fn long_run_direct(scores: &[DVector<f64>], same: &[bool], b: f64) -> DMatrix<f64> {
    let n = scores[0].len();
    let mut omega = DMatrix::zeros(n, n);
    for s in scores {
        omega += s * s.transpose();
    }
    let max_lag = (b.ceil() as usize).min(scores.len());
    for l in 1..max_lag {
        let w = 1.0 - l as f64 / b;
        if w <= 0.0 {
            break;
        }
        for i in 0..scores.len().saturating_sub(l) {
            if (i..i + l).all(|k| same[k]) {
                let g = &scores[i] * scores[i + l].transpose();
                omega += (&g + g.transpose()) * w;
            }
        }
    }
    omega
}

/// Andrews (1991) AR(1) plug-in bandwidth for the Bartlett kernel, on standardised series,
/// at most `cap` frames.
pub(super) fn andrews_bandwidth(series: &[DVector<f64>], cap: f64) -> f64 {
    let n = series.len();
    if n < 3 {
        return 1.0;
    }
    let dim = series[0].len();
    let (mut num, mut den) = (0.0, 0.0);
    for a in 0..dim {
        let x: Vec<f64> = series.iter().map(|v| v[a]).collect();
        let sd = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        if sd == 0.0 || !sd.is_finite() {
            continue;
        }
        let x: Vec<f64> = x.iter().map(|v| v / sd).collect();
        let sxy: f64 = x.windows(2).map(|w| w[0] * w[1]).sum();
        let sxx: f64 = x[..n - 1].iter().map(|v| v * v).sum();
        let rho = (sxy / sxx).clamp(-0.97, 0.97);
        let s2 = x
            .windows(2)
            .map(|w| (w[1] - rho * w[0]).powi(2))
            .sum::<f64>()
            / (n - 1) as f64;
        num += 4.0 * rho * rho * s2 * s2 / ((1.0 - rho).powi(6) * (1.0 + rho).powi(2));
        den += s2 * s2 / (1.0 - rho).powi(4);
    }
    if den == 0.0 {
        return 1.0;
    }
    (1.1447 * (num / den * n as f64).cbrt()).clamp(1.0, cap.max(1.0))
}

/// Whether frame i+1 of the problem continues frame i's trial without a gap.
pub(super) fn continuity(prob: &Problem) -> Vec<bool> {
    prob.origin
        .windows(2)
        .map(|w| w[0].0 == w[1].0 && w[1].1 == w[0].1 + 1)
        .collect()
}

/// The covariance estimates (scaled units) of one analysis, before conversion.
pub(super) struct Covariances {
    /// The data parts of the estimators (`white`, `hac`, `boot`, `jack`) exclude the prior's
    /// part `prior` (`σ_p² S⁻¹ D S⁻¹`, none without a prior); the total is their sum.
    pub(super) white: DMatrix<f64>,
    pub(super) prior: Option<DMatrix<f64>>,
    /// Degrees of freedom of the Student t whose quantile is `hac_critical`, and of the
    /// jackknife's t.
    pub(super) hac_dof: f64,
    pub(super) jack_dof: f64,
    /// The upper quantile of the two-sided intervals, `(1 + level)/2`.
    pub(super) upper: f64,
    pub(super) null: Vec<bool>,
    pub(super) hac: Option<DMatrix<f64>>,
    pub(super) bandwidth: Option<f64>,
    /// Critical value of the HAC interval: fixed-b (Bartlett) for the bandwidth used.
    pub(super) hac_critical: f64,
    pub(super) boot: Option<(DMatrix<f64>, BootstrapInfo)>,
    pub(super) jack: Option<DMatrix<f64>>,
    pub(super) factor: f64,
    pub(super) eig: SymmetricEigen<f64, nalgebra::Dyn>,
}

/// `boot`: the problem and fit to refit for the bootstrap (none: no bootstrap). `same[i]`:
/// frame i+1 continues frame i's trial.
pub(super) fn covariances(
    red: &Reduced,
    same: &[bool],
    boot: Option<(&Problem, &Fit)>,
    opts: &UncertaintyOptions,
    center_scores: bool,
) -> Covariances {
    let nf = red.normal.nrows();
    let n = red.scores.len();
    let (inv, null, eig) = pseudo_inverse(&red.normal);
    let estimated = red.sigma2();
    let sigma2 = opts.assumed_sigma_m.map_or(estimated, |s| s * s);
    // Robust estimators scale with the residuals; rescale them to the assumed noise.
    let rescale = if estimated > 0.0 && estimated.is_finite() {
        sigma2 / estimated
    } else {
        1.0
    };
    // The prior's part of the variance: with the truth drawn from the prior, the prior term's
    // score `D(μ − s)` has covariance `σ_p² D` (`D` = diag of the prior information), so the
    // covariance is `S⁻¹ (Ω_data + σ_p² D) S⁻¹`: each estimator's own data part plus the
    // known `σ_p² S⁻¹ D S⁻¹` (kept apart: it is not estimated, so its critical value is the
    // normal one; see [`conservative`]). The white data part is `σ² S⁻¹ (S − D) S⁻¹`.
    let prior_part = (red.prior_information.iter().any(|d| *d > 0.0)).then(|| {
        let d = DMatrix::from_diagonal(&DVector::from_column_slice(&red.prior_information));
        &inv * d * &inv
    });
    let white = match &prior_part {
        Some(pd) => (&inv - pd) * sigma2,
        None => &inv * sigma2,
    };
    // The prior term's score `D(μ − s)` has covariance `σ_p² D A` when its weight carries
    // the factors `A` ([`Reduced::prior_inflation`]; `A = I` unless σ was estimated).
    let prior = prior_part.as_ref().map(|_| {
        let da: Vec<f64> = red
            .prior_information
            .iter()
            .zip(&red.prior_inflation)
            .map(|(d, a)| d * a)
            .collect();
        &inv * DMatrix::from_diagonal(&DVector::from_column_slice(&da))
            * &inv
            * red.prior_noise.powi(2)
    });
    let factor = if opts.small_sample {
        if n > nf {
            n as f64 / (n - nf) as f64
        } else {
            f64::INFINITY
        }
    } else {
        1.0
    };
    let mut scores = red.scores.clone();
    if center_scores && n > 0 {
        // Away from the optimum the scores carry the systematic misfit; its mean is not noise.
        let mean = scores.iter().fold(DVector::zeros(nf), |a, s| a + s) / n as f64;
        for s in &mut scores {
            *s -= &mean;
        }
    }
    // Fixed-b ratio: the bandwidth over the mean length of the runs of consecutive frames.
    let runs = 1 + same.iter().filter(|c| !**c).count();
    let run_length = n as f64 / runs as f64;
    // With no more frames than parameters the factor is infinite: no HAC or bootstrap.
    let (hac, bandwidth) = if opts.hac && n > 1 && factor.is_finite() {
        let b = opts.hac_bandwidth.unwrap_or_else(|| {
            let sd: Vec<f64> = (0..nf).map(|k| white[(k, k)].sqrt()).collect();
            let infl: Vec<DVector<f64>> = scores
                .iter()
                .map(|s| {
                    let h = &inv * s;
                    DVector::from_iterator(
                        nf,
                        h.iter()
                            .zip(&sd)
                            .map(|(v, d)| if *d > 0.0 { v / d } else { 0.0 }),
                    )
                })
                .collect();
            // Capped only by the trial: the fixed-b critical value below holds for any
            // `b/N ≤ 1` (see the `critical` module for why no smaller cap).
            andrews_bandwidth(&infl, run_length)
        });
        let omega = long_run(&scores, same, b);
        (Some(&inv * omega * &inv * (factor * rescale)), Some(b))
    } else {
        (None, None)
    };
    let hac_critical = fixed_b_bartlett(opts.level, bandwidth.map_or(0.0, |b| b / run_length));
    let upper = 0.5 + 0.5 * opts.level;
    // Only a prior's known part needs it ([`conservative`]).
    let hac_dof = if prior.is_some() {
        dof_of_critical(upper, hac_critical)
    } else {
        f64::INFINITY
    };
    let boot = match boot {
        Some((prob, fit)) if opts.bootstrap_replicates > 1 && factor.is_finite() => {
            let block = opts
                .block_length
                .unwrap_or_else(|| bandwidth.map_or(2, |b| (b.ceil() as usize).max(2)))
                .clamp(1, n.max(1));
            let (c, nc) = block_bootstrap(prob, fit, opts.bootstrap_replicates, block, opts.seed);
            Some((
                c * (factor * rescale),
                BootstrapInfo {
                    replicates: opts.bootstrap_replicates,
                    not_converged: nc,
                    block_length: block,
                    seed: opts.seed,
                },
            ))
        }
        _ => None,
    };
    let jack = (opts.jackknife_blocks > 1 && n >= opts.jackknife_blocks)
        .then(|| block_jackknife(red, &scores, opts.jackknife_blocks) * rescale);
    Covariances {
        white,
        prior,
        // Only a prior's known part needs it ([`conservative`]).
        hac_dof,
        jack_dof: (opts.jackknife_blocks.max(2) - 1) as f64,
        upper,
        null,
        hac,
        bandwidth,
        hac_critical,
        boot,
        jack,
        factor,
        eig,
    }
}

/// One estimator's `(se, half-width, method)`.
pub(super) type Estimate = (f64, f64, SeMethod);

/// Per estimator `(se, half-width, method)` of the quadratic form `f(C)` (a variance in
/// scaled units), and the most conservative one (largest half-width). `crit`: `z` (white,
/// bootstrap) and Student's t (jackknife); the HAC interval takes `cov.hac_critical`.
///
/// With a prior the variance is the estimator's random data part `v_r` plus the known prior
/// part `v_p`; the critical value of a studentized error whose variance is part estimated
/// (`ν` degrees of freedom) and part known is Student's t with the Welch–Satterthwaite
/// degrees of freedom `ν (v_r + v_p)²/v_r²` (the known part has infinitely many), from `ν`
/// when the prior does not matter to `z` when it is all ([`mixed_critical`]).
pub(super) fn conservative(
    cov: &Covariances,
    crit: (f64, f64),
    f: impl Fn(&DMatrix<f64>) -> f64,
) -> (Vec<Estimate>, Option<Estimate>) {
    let p = cov.upper;
    let vp = cov.prior.as_ref().map_or(0.0, |c| f(c).max(0.0));
    let one = |c: &DMatrix<f64>, cv: f64, dof: f64, m: SeMethod| {
        let vr = f(c).max(0.0);
        let cv = if vp > 0.0 && dof.is_finite() {
            mixed_critical(p, dof, vr, vp)
        } else {
            cv
        };
        ((vr + vp).sqrt(), cv, m)
    };
    let mut all = vec![one(&cov.white, crit.0, f64::INFINITY, SeMethod::White)];
    if let Some(h) = &cov.hac {
        all.push(one(h, cov.hac_critical, cov.hac_dof, SeMethod::Hac));
    }
    if let Some((b, _)) = &cov.boot {
        all.push(one(b, crit.0, f64::INFINITY, SeMethod::Bootstrap));
    }
    if let Some(j) = &cov.jack {
        all.push(one(j, crit.1, cov.jack_dof, SeMethod::Jackknife));
    }
    let out: Vec<Estimate> = all.iter().map(|(s, c, m)| (*s, s * c, *m)).collect();
    // An estimator that cannot be evaluated (e.g. fewer frames than parameters makes the
    // small-sample factor infinite) leaves the parameter undetermined rather than letting a
    // less conservative one speak for it.
    if out.iter().any(|v| !v.1.is_finite()) {
        return (out, None);
    }
    let best = out.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1));
    (out, best)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed generator of uniform numbers in [−½, ½) (a linear congruential one).
    fn uniform(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    #[test]
    fn long_run_equals_the_direct_sum() {
        // Autocorrelated scores (AR(1) from a fixed generator), three runs with gaps, and
        // bandwidths from below one lag to longer than a run.
        let n = 5;
        let frames = 700;
        let mut next = uniform(12345u64);
        let mut scores: Vec<DVector<f64>> = Vec::with_capacity(frames);
        let mut prev = DVector::zeros(n);
        for _ in 0..frames {
            let e = DVector::from_fn(n, |_, _| next());
            prev = &prev * 0.9 + e + DVector::from_element(n, 0.3);
            scores.push(prev.clone());
        }
        let mut same = vec![true; frames - 1];
        same[199] = false;
        same[200] = false;
        same[450] = false;
        for b in [0.5, 1.0, 1.7, 2.0, 7.3, 40.0, 260.0, 900.0] {
            let fast = long_run(&scores, &same, b);
            let direct = long_run_direct(&scores, &same, b);
            let scale = direct.amax();
            let err = (&fast - &direct).amax();
            assert!(err <= 1e-12 * scale, "b {b}: error {err:e} of {scale:e}");
        }
    }

    /// The Cholesky path of `pseudo_solve` agrees with the eigen-decomposition's
    /// pseudo-inverse on well-conditioned matrices (condition numbers 1 to 1e7), and a matrix
    /// with a direction below `NULL_RATIO` (condition 1e12, or exactly singular) takes the
    /// pseudo-inverse itself: that direction is dropped, not inverted.
    #[test]
    fn pseudo_solve_is_the_pseudo_inverse_applied() {
        let n = 7;
        let mut next = uniform(99u64);
        // A random orthogonal basis (QR of a random matrix).
        let q = DMatrix::from_fn(n, n, |_, _| next()).qr().q();
        let g = DVector::from_fn(n, |_, _| next());
        for (cond, cholesky) in [(1.0f64, true), (1e3, true), (1e7, true), (1e12, false)] {
            let lam = DVector::from_fn(n, |i, _| cond.powf(-(i as f64) / (n - 1) as f64));
            let s = &q * DMatrix::from_diagonal(&lam) * q.transpose();
            let s = (&s + s.transpose()) * 0.5;
            let want = pseudo_inverse(&s).0 * &g;
            let got = pseudo_solve(&s, &g);
            if cholesky {
                let err = (&got - &want).amax() / want.amax();
                assert!(err < 1e-14 * cond.max(10.0), "cond {cond:e}: {err:e}");
            } else {
                assert_eq!(got, want, "cond {cond:e}");
            }
        }
        // Exactly singular: one eigenvalue 0.
        let lam = DVector::from_fn(n, |i, _| if i == 0 { 0.0 } else { 1.0 });
        let rank_deficient = &q * DMatrix::from_diagonal(&lam) * q.transpose();
        let rank_deficient = (&rank_deficient + rank_deficient.transpose()) * 0.5;
        assert_eq!(
            pseudo_solve(&rank_deficient, &g),
            pseudo_inverse(&rank_deficient).0 * &g
        );
    }

    #[test]
    fn bartlett_long_run_of_white_scores_is_their_sum_of_squares() {
        let scores: Vec<DVector<f64>> = (0..5)
            .map(|i| DVector::from_vec(vec![i as f64, 1.0]))
            .collect();
        let same = vec![true; 4];
        let o = long_run(&scores, &same, 1.0);
        assert_eq!(o[(0, 0)], 30.0);
        // Bandwidth 2: lag-1 products get weight 1/2; not across a trial boundary.
        let o2 = long_run(&scores, &same, 2.0);
        assert_eq!(o2[(0, 0)], 30.0 + (0.0 + 2.0 + 6.0 + 12.0));
        let cut = vec![true, false, true, true];
        let o3 = long_run(&scores, &cut, 2.0);
        assert_eq!(o3[(0, 0)], 30.0 + (0.0 + 6.0 + 12.0));
    }
}
