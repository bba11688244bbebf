//! The identifiability status: what the trial alone determines, judged from pooled
//! quantities rather than from one parameter's own robust variance.
//!
//! # Why not the interval's own half-width
//!
//! Labelling a parameter "determined" when its reported (robust) half-width is within the
//! threshold selects the trials in which that half-width came out small. One parameter's HAC
//! and jackknife variances from one trial are noisy while its actual error hardly follows
//! them (rank correlation of |error| with the half-width 0–0.2 over seeds), so for a
//! parameter whose precision sits near the threshold the selected intervals are the too
//! narrow ones: in Monte Carlo the selected intervals covered the truth in 53–87 % of the
//! cases against 94–97 % for all intervals (`docs/identifiability.md`, "The determined label"). Any
//! label that is a function of the interval's own noisy estimate has this bias.
//!
//! # The rule
//!
//! A parameter is *determined* when the trial alone (without a prior) pins it within the
//! threshold `T_k` (5 mm / 5°) at the report's level, judged from the Fisher information:
//!
//! `h_k = z · √(κ σ² [S_d⁻¹]_kk) ≤ T_k`,
//!
//! with `S_d` the data part of the reduced normal matrix (`S` without the prior's diagonal),
//! `σ²` the residual variance pooled over every marker sample, and `κ` the trial's
//! time-correlation factor pooled over the free parameters ([`score_correlation`], the `κ`
//! that also weighs the prior: [`crate::calibrate::uncertainty::correlation_inflation`]). It must
//! also not sit at a bound and, with a prior, not be held by the prior (data share `< 0.3`,
//! [`crate::calibrate::prior::Source`]), so that the status never says "determined" where
//! the information label says "held by the prior". The interval printed next to the label
//! is the robust one ([`super::ParamUncertainty::half_width`]), with the floor below.
//!
//! `σ²` and `κ` pool many residuals and parameters, so the label hardly follows one
//! parameter's robust-variance noise, and the selected intervals keep (most of) their
//! coverage.
//!
//! # κ is the trial's, pooled over every parameter of the model
//!
//! `κ` is a property of the trial's residuals, not of which parameters are fitted, so it is
//! pooled over every parameter of the model that the data determine, free or not
//! ([`trial_correlation`]: the all-free problem at the same point). Pooled over the free ones
//! only, a hip-alone fit's `κ` was the mean of six ratios, largely the labelled parameters'
//! own noisy estimates (rank correlation with a labelled parameter's own ratio 0.66 over
//! 200 seeds, against 0.30 pooled over all 27), and the label selected the trials where they
//! came out small: 91.4 % coverage of "determined" in 1000 seeds against 94.1 % for all its
//! intervals (`docs/identifiability.md`). With every parameter free nothing changes.
//! Held parameters away from the trial's optimum carry their misfit into their scores, which
//! varies with the motion like correlated noise (centring removes only its mean), so `κ` then
//! errs on the large, strict side (Hamner's running, hip alone: 8.4 against 3.2 all free).
//!
//! # The floor of a marginally determined parameter's interval
//!
//! `κ` is still an estimate. Its ratios come from the same few effectively independent
//! stretches of the trial as the jackknife's, so it has at least the jackknife's `K − 1`
//! degrees of freedom; where the label would not survive that noise — with Student's
//! `t_{K−1}` in place of `z` the status half-width would exceed the threshold,
//! `t·h_k/z > T_k` ([`marginal`]) — whether the parameter is labelled depends on `κ`'s
//! draw, and the labelled trials are those whose robust variances came out low. The
//! interval printed for such a parameter is therefore at least `h_k`, the half-width that
//! determined it ([`super::SeMethod::Pooled`]): never narrower than the evidence for its own
//! label. A parameter determined well inside the threshold is labelled whatever `κ`'s draw,
//! so no selection happens and its interval stays the robust one.

use nalgebra::{DMatrix, DVector};

use super::super::prior::Source;
use super::super::Problem;
use super::estimators::{continuity, covariances, pseudo_inverse, Covariances};
use super::reduced::reduced_system;
use super::{Identifiability, Reduced, SeMethod, UncertaintyOptions};

/// The trial's time-correlation factor `κ` over every parameter of the model, free or not:
/// [`score_correlation`] of the problem with all parameters free at the same point (no
/// prior: the data alone; its own residual variance, or the assumed one), its scores centred
/// (a fixed parameter away from its optimum has a mean score that is not noise), with the HAC
/// bandwidth the analysis used (`ext`: that problem's reduced system, [`extended_system`]).
/// With every parameter free (`ext` = `None`) it is [`score_correlation`] of the analysis
/// itself (`sigma2` its residual variance).
pub(super) fn trial_correlation(
    prob: &Problem,
    ext: Option<&Reduced>,
    cov: &Covariances,
    red: &Reduced,
    sigma2: f64,
    opts: &UncertaintyOptions,
) -> f64 {
    let Some(red_e) = ext else {
        return score_correlation(cov, red, sigma2);
    };
    let opts_e = UncertaintyOptions {
        hac_bandwidth: cov.bandwidth.or(opts.hac_bandwidth),
        bootstrap_replicates: 0,
        ..opts.clone()
    };
    let cov_e = covariances(red_e, &continuity(prob), None, &opts_e, true);
    let sigma2_e = opts.assumed_sigma_m.map_or(red_e.sigma2(), |s| s * s);
    score_correlation(&cov_e, red_e, sigma2_e)
}

/// The reduced system at `(p, qs)` of `prob` with every model parameter free and no prior,
/// which [`trial_correlation`] reads when `prob` leaves some parameter fixed (`None` when
/// every parameter is free). It depends on nothing the covariances compute, so it is formed
/// beside them.
pub(super) fn extended_system(prob: &Problem, p: &[f64], qs: &[Vec<f64>]) -> Option<Reduced> {
    let n_p = prob.model.parameters().len();
    if prob.free.len() == n_p {
        return None;
    }
    let ext = Problem {
        free: (0..n_p).collect(),
        prior: None,
        ..prob.clone()
    };
    Some(reduced_system(&ext, p, qs))
}

/// The trial's time-correlation factor from the parameters' scores: the arithmetic mean over
/// the free parameters that the data alone determine of
/// `r_k = max(HAC, jackknife)_kk / white_kk`, at least 1 (1 without a robust estimate), with
/// every covariance taken for the data alone: a data-part covariance `C = S⁻¹ M S⁻¹` of the
/// posterior (`M` the scores' long-run covariance, or `σ² S_d` for the white one) becomes
/// `S_d⁻¹ S C S S_d⁻¹ = S_d⁻¹ M S_d⁻¹` (`S_d = S − D`; `S_d = S` without a prior). This is
/// [`crate::calibrate::uncertainty::correlation_inflation`]'s `κ`, the one that weighs the prior,
/// computed at this fit: without a prior exactly its mean of `(se_robust/se_white)²`.
pub(super) fn score_correlation(cov: &Covariances, red: &Reduced, sigma2: f64) -> f64 {
    let d = DMatrix::from_diagonal(&DVector::from_column_slice(&red.prior_information));
    let (inv_d, null_d, _) = pseudo_inverse(&(&red.normal - d));
    let m = &inv_d * &red.normal;
    let robust: Vec<DMatrix<f64>> = [cov.hac.as_ref(), cov.jack.as_ref()]
        .into_iter()
        .flatten()
        .map(|c| &m * c * m.transpose())
        .collect();
    let ratios: Vec<f64> = (0..inv_d.nrows())
        .filter(|&k| !null_d[k] && inv_d[(k, k)] > 0.0)
        .filter_map(|k| {
            let r = robust.iter().map(|c| c[(k, k)]).fold(f64::NAN, f64::max);
            (r.is_finite() && r > 0.0).then(|| r / (sigma2 * inv_d[(k, k)]))
        })
        .collect();
    if ratios.is_empty() {
        1.0
    } else {
        (ratios.iter().sum::<f64>() / ratios.len() as f64).max(1.0)
    }
}

/// A parameter's status and its `(se, half-width, method)` with the floor of a marginally
/// determined one. `est`: the robust estimate (`None` half-width: not determined at all); `h`:
/// the status half-width; `crit`: `(z, the jackknife's t, the threshold T)`; `excluded`: at a
/// bound or held by the prior. Determined when `h ≤ T` and not excluded; then, when
/// [`marginal`] and `h` exceeds the robust half-width, the interval is `(h/z, h, Pooled)`.
pub(super) fn label(
    est: (Option<f64>, Option<f64>, SeMethod),
    h: Option<f64>,
    (z, t, threshold): (f64, Option<f64>, f64),
    excluded: bool,
) -> (Identifiability, (Option<f64>, Option<f64>, SeMethod)) {
    let status = match (est.1, h) {
        (None, _) => Identifiability::Undetermined,
        (Some(_), Some(h)) if h <= threshold && !excluded => Identifiability::Determined,
        _ => Identifiability::Poor,
    };
    let est = match (status, h, est.1) {
        (Identifiability::Determined, Some(h), Some(w))
            if w < h && marginal(h, z, t, threshold) =>
        {
            (Some(h / z), Some(h), SeMethod::Pooled)
        }
        _ => est,
    };
    (status, est)
}

/// Whether the prior holds a parameter of data share `share` (`< 0.3`; NaN: no prior).
pub(super) fn held(share: f64) -> bool {
    share.is_finite() && Source::of(share) == Source::HeldByPrior
}

/// Whether a determined parameter's label hinges on the noise of `κ`: with the jackknife's
/// critical value `t` (`K − 1` degrees of freedom, `None` without a jackknife) in place of
/// `z`, its status half-width `h` would exceed the threshold, `t·h/z > T`. Its interval is
/// then at least `h` (see the module docs).
pub(super) fn marginal(h: f64, z: f64, t: Option<f64>, threshold: f64) -> bool {
    t.is_some_and(|t| t * h / z > threshold)
}

/// The correlation factor of an analysis read without one (serde's default): none, 1.
pub(super) fn one() -> f64 {
    1.0
}

/// Per free parameter, the data-alone Fisher variance `σ² [S_d⁻¹]_kk` (scaled units), `S_d`
/// the reduced normal matrix without the prior's diagonal; `None` on a null direction of
/// `S_d` (the trial alone does not determine the parameter).
pub(super) fn data_alone_variance(red: &Reduced, sigma2: f64) -> Vec<Option<f64>> {
    let d = DMatrix::from_diagonal(&DVector::from_column_slice(&red.prior_information));
    let (inv, null, _) = pseudo_inverse(&(&red.normal - d));
    (0..inv.nrows())
        .map(|k| (!null[k]).then(|| sigma2 * inv[(k, k)]))
        .collect()
}
