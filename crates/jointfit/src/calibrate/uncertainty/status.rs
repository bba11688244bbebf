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
//! cases against 94–97 % for all intervals (`docs/global.md`, "The determined label"). Any
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
//! that also weighs the prior: [`crate::calibrate::prior::correlation_inflation`]). It must
//! also not sit at a bound and, with a prior, not be held by the prior (data share `< 0.3`,
//! [`crate::calibrate::prior::Source`]), so that the status never says "determined" where
//! the information label says "held by the prior". The interval printed next to the label
//! stays the robust one ([`super::ParamUncertainty::half_width`]).
//!
//! `σ²` and `κ` pool many residuals and parameters, so the label hardly follows one
//! parameter's robust-variance noise, and the selected intervals keep (most of) their
//! coverage. With few free parameters (six, a hip alone) `κ` is made largely of the ratios
//! of the very parameters it labels and some selection remains (`docs/global.md`).

use nalgebra::{DMatrix, DVector};

use super::estimators::{pseudo_inverse, Covariances};
use super::Reduced;

/// The trial's time-correlation factor from the parameters' scores: the arithmetic mean over
/// the free parameters that the data alone determine of
/// `r_k = max(HAC, jackknife)_kk / white_kk`, at least 1 (1 without a robust estimate), with
/// every covariance taken for the data alone: a data-part covariance `C = S⁻¹ M S⁻¹` of the
/// posterior (`M` the scores' long-run covariance, or `σ² S_d` for the white one) becomes
/// `S_d⁻¹ S C S S_d⁻¹ = S_d⁻¹ M S_d⁻¹` (`S_d = S − D`; `S_d = S` without a prior). This is
/// [`crate::calibrate::prior::correlation_inflation`]'s `κ`, the one that weighs the prior,
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
