//! How much time-correlated residuals overstate the information of the marker term, and the
//! prior weights that correct for it (the factors the MAP refit of `crate::workflow` applies).

use super::{ParamUncertainty, Uncertainty};

/// How much time-correlated residuals (skin artefact, marker misplacement) overstate the
/// information of the marker term: `κ = tr(H⁻¹J)/n_f`, approximated by the arithmetic mean
/// over the free parameters of `(se_robust / se_white)²` (the diagonal of `H⁻¹J` in the
/// parameters' own scale), with `se_robust` the larger of the HAC and jackknife standard
/// errors of an analysis *without* the prior ([`super::analyze`]); at least 1.
///
/// Weighting the marker term by `1/(κσ²)` instead of `1/σ²` is the "magnitude adjustment"
/// of a misspecified (here: independence) likelihood (Pauli, Racugno & Ventura 2011,
/// Statistica Sinica 21:149–164; Ribatet, Cooley & Davison 2012, Statistica Sinica
/// 22:813–845): dividing the log-likelihood by `tr(H⁻¹J)/n_f` gives the likelihood-ratio
/// statistic its nominal mean `n_f`. `κ` is also the number of correlated frames that carry
/// the information of one independent frame (the trial's frames over its effective number
/// of independent frames). The arithmetic mean is the one that theory gives; a geometric
/// mean would let the many parameters whose residual correlation is mild dilute the few (hip
/// centre) that soak up most of the correlated artefact. Without `κ`, thousands of
/// correlated marker samples would count as independent and swamp any prior.
pub(crate) fn correlation_inflation(u: &Uncertainty) -> f64 {
    let ratios: Vec<f64> = u.params.iter().filter_map(variance_ratio).collect();
    if ratios.is_empty() {
        1.0
    } else {
        (ratios.iter().sum::<f64>() / ratios.len() as f64).max(1.0)
    }
}

/// `(se_robust / se_white)²` of one parameter (the rule of [`correlation_inflation`]), or
/// `None` when either is missing or not positive.
fn variance_ratio(p: &ParamUncertainty) -> Option<f64> {
    let robust = match (p.se_hac, p.se_jackknife) {
        (Some(a), Some(b)) => a.max(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => return None,
    };
    let w = p.se_white?;
    (w > 0.0 && robust.is_finite() && robust > 0.0).then(|| (robust / w).powi(2))
}

/// Per parameter named in `names` (the free parameters, in order): `max(r_k/κ, 1)`, with
/// `r_k = (se_robust/se_white)²` its own variance ratio in `u` and `κ` the trial's
/// ([`correlation_inflation`]); 1 for a parameter `u` lacks.
///
/// The trial-wide `κ` is the magnitude adjustment of the independence likelihood; the
/// adjustment that gives each parameter its own robust variance is the curvature adjustment
/// (Chandler & Bate 2007, Biometrika 94:167–183: rescale the likelihood so that its
/// curvature matches the sandwich (Godambe) information). Its diagonal part multiplies
/// parameter k's data information by `κ/r_k`, which is the same as multiplying its prior
/// weight by `r_k/κ`. Only factors above 1 are taken: where the correlated artefact
/// concentrates on a parameter (the hip centre in squats, sit-to-stand and ankle circles:
/// `r_k` 2–6 × `κ`, `docs/priors.md`) the trial counts for less there; elsewhere `κ` stays,
/// so the noisy `r_k` of one parameter never weakens its prior below the trial's rule.
pub(crate) fn parameter_inflation(u: &Uncertainty, names: &[&str], kappa: f64) -> Vec<f64> {
    names
        .iter()
        .map(|n| {
            u.params
                .iter()
                .find(|p| p.name == *n)
                .and_then(variance_ratio)
                .map_or(1.0, |r| (r / kappa).max(1.0))
        })
        .collect()
}
