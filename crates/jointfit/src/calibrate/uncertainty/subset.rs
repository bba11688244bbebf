//! Subset selection: the parameters to hold fixed (see [`unidentifiable_subset`]).

use nalgebra::{DMatrix, DVector};

use super::super::{Fit, Problem};
use super::critical::critical;
use super::estimators::{continuity, covariances};
use super::status::{data_alone_variance, score_correlation};
use super::{reduced_system, Reduced, UncertaintyOptions};

/// Subset selection: which free parameters (indices into `prob.free`) to hold fixed so that
/// the others are determined within the thresholds, by the status rule of the analysis (the
/// private `status` module; its correlation factor `κ` is taken once, from the whole fit).
///
/// Greedy, on the reduced normal matrix at the fit: the reduced matrix of a subset is the
/// sub-block `S[keep, keep]` (the coordinates are projected out column by column) and the
/// HAC meat is the same sub-block of `Ω`, so no refit is needed to plan. While a kept
/// parameter is flagged, the flagged one with the largest weight in the weakest eigenvector
/// of `S[keep, keep]` is removed (Golub, Klema & Stewart 1976 style). The caller refits with
/// the rest and re-analyses.
pub(crate) fn unidentifiable_subset(
    prob: &Problem,
    fit: &Fit,
    opts: &UncertaintyOptions,
) -> Vec<usize> {
    let red = reduced_system(prob, &fit.p, &fit.coords);
    let same = continuity(prob);
    let z = critical(opts.level, opts).0;
    let sigma2 = opts.assumed_sigma_m.map_or(red.sigma2(), |s| s * s);
    let kappa = score_correlation(&covariances(&red, &same, None, opts, false), &red, sigma2);
    let threshold = |k: usize| opts.threshold(prob.model.parameters()[prob.free[k]].unit);
    let mut keep: Vec<usize> = (0..prob.n_free()).collect();
    let mut removed = Vec::new();
    while !keep.is_empty() {
        let m = keep.len();
        let pick = |v: &DVector<f64>| DVector::from_iterator(m, keep.iter().map(|&k| v[k]));
        let sub = Reduced {
            normal: DMatrix::from_fn(m, m, |a, b| red.normal[(keep[a], keep[b])]),
            data_normal: DMatrix::from_fn(m, m, |a, b| red.data_normal[(keep[a], keep[b])]),
            scores: red.scores.iter().map(pick).collect(),
            group_normals: red
                .group_normals
                .iter()
                .map(|a| DMatrix::from_fn(m, m, |x, y| a[(keep[x], keep[y])]))
                .collect(),
            group_size: red.group_size,
            cost: red.cost,
            observations: red.observations,
            n_q: red.n_q,
            prior_information: keep.iter().map(|&k| red.prior_information[k]).collect(),
            prior_noise: red.prior_noise,
            prior_inflation: keep.iter().map(|&k| red.prior_inflation[k]).collect(),
        };
        let cov = covariances(&sub, &same, None, opts, false);
        let alone = data_alone_variance(&sub, sigma2);
        let flagged: Vec<usize> = (0..m)
            .filter(|&a| {
                let hw = alone[a].map(|v| z * (kappa * v).sqrt() * prob.half_range(keep[a]));
                cov.null[a] || hw.is_none_or(|h| h.is_nan() || h > threshold(keep[a]))
            })
            .collect();
        if flagged.is_empty() {
            break;
        }
        let weakest = (0..m)
            .min_by(|&a, &b| cov.eig.eigenvalues[a].total_cmp(&cov.eig.eigenvalues[b]))
            .unwrap_or(0);
        let v = cov.eig.eigenvectors.column(weakest);
        let worst = *flagged
            .iter()
            .max_by(|&&a, &&b| v[a].abs().total_cmp(&v[b].abs()))
            .unwrap_or(&flagged[0]);
        removed.push(keep.remove(worst));
    }
    removed.sort();
    removed
}
