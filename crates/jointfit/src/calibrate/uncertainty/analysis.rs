//! The analysis itself: from the reduced system of a fit (or of a start) to the standard
//! errors, statuses and explanations of [`super::Uncertainty`] (the mathematics: the module
//! docs of [`super`]).

use super::critical::critical;
use super::estimators::{conservative, continuity, covariances, Covariances};
use super::explain::{coordinate_ranges, reason, weak_directions};
use super::reduced::{reduced_system, Reduced};
use super::status;
use super::{
    CoordRange, Identifiability, ParamUncertainty, SeMethod, Uncertainty, UncertaintyOptions,
};
use crate::calibrate::{Fit, Problem};
use crate::model::spec::Unit;

/// Eigenvalues of `S` below this fraction of the largest count as zero (not determined).
pub(super) const NULL_RATIO: f64 = 1e-10;

/// Display factor and unit of a parameter or coordinate.
pub(super) fn display(unit: Unit) -> (f64, &'static str) {
    (unit.display_scale(), unit.display_suffix())
}

/// Uncertainty of the fitted free parameters of `fit` (a solution of `prob`).
pub(crate) fn analyze(prob: &Problem, fit: &Fit, opts: &UncertaintyOptions) -> Uncertainty {
    analyze_reduced(prob, fit, opts, &reduced_system(prob, &fit.p, &fit.coords))
}

/// [`analyze`] from the reduced system `red` of `prob` at `fit`
/// ([`reduced_system`]`(prob, &fit.p, &fit.coords)`, formed once where a workflow needs it
/// for more than the analysis).
pub(crate) fn analyze_reduced(
    prob: &Problem,
    fit: &Fit,
    opts: &UncertaintyOptions,
    red: &Reduced,
) -> Uncertainty {
    let est = estimates(prob, (&fit.p, &fit.coords), red, opts, || {
        covariances(red, &continuity(prob), Some((prob, fit)), opts, false)
    });
    build(prob, &fit.p, &fit.s, &fit.coords, red, &est, opts)
}

/// Predicted uncertainty at parameters `p` with inner solutions `qs` (one per frame of
/// `prob`), before any fit: white, HAC and jackknife estimates (no bootstrap, which needs a
/// fit), the scores centred on their mean so that the systematic misfit of a nominal model
/// does not count as noise. `σ²` comes from the residuals at `p`, which include that misfit,
/// so the prediction is conservative; set [`UncertaintyOptions::assumed_sigma_m`] when the
/// noise level is known.
pub(crate) fn predict(
    prob: &Problem,
    p: &[f64],
    qs: &[Vec<f64>],
    opts: &UncertaintyOptions,
) -> Uncertainty {
    let red = reduced_system(prob, p, qs);
    let est = estimates(prob, (p, qs), &red, opts, || {
        covariances(&red, &continuity(prob), None, opts, true)
    });
    build(prob, p, &prob.to_scaled(p), qs, &red, &est, opts)
}

/// The covariances (`cov`), and beside them, on another thread when one is free, what the
/// status rule reads of the reduced system `red` alone: the data-alone variances, the data
/// shares and the system with every parameter free ([`status::extended_system`] at `at`, the
/// parameters and coordinates of `red`). None of these depends on another, so the result is
/// the same on any number of threads.
struct Estimates {
    cov: Covariances,
    alone: Vec<Option<f64>>,
    share: Vec<f64>,
    ext: Option<Reduced>,
}

fn estimates(
    prob: &Problem,
    (p, qs): (&[f64], &[Vec<f64>]),
    red: &Reduced,
    opts: &UncertaintyOptions,
    cov: impl FnOnce() -> Covariances + Send,
) -> Estimates {
    let sigma2 = opts.assumed_sigma_m.map_or(red.sigma2(), |s| s * s);
    let (cov, (alone, share, ext)) = rayon::join(cov, || {
        (
            status::data_alone_variance(red, sigma2),
            crate::calibrate::prior::data_share(prob, &red.normal),
            status::extended_system(prob, p, qs),
        )
    });
    Estimates {
        cov,
        alone,
        share,
        ext,
    }
}

fn build(
    prob: &Problem,
    p: &[f64],
    s: &[f64],
    qs: &[Vec<f64>],
    red: &Reduced,
    est: &Estimates,
    opts: &UncertaintyOptions,
) -> Uncertainty {
    let (cov, alone, share) = (&est.cov, &est.alone, &est.share);
    let model = prob.model;
    let nf = prob.n_free();
    let crit = critical(opts.level, opts);
    let z = crit.0;
    let ranges = coordinate_ranges(model, qs);
    let scale: Vec<f64> = (0..nf)
        .map(|k| prob.half_range(k) * display(model.parameters()[prob.free[k]].unit).0)
        .collect();
    let threshold = |k: usize| {
        let unit = model.parameters()[prob.free[k]].unit;
        unit.to_display(opts.threshold(unit))
    };
    // The white covariance with the prior's part: the posterior's under independent noise.
    let white = match &cov.prior {
        Some(pr) => &cov.white + pr,
        None => cov.white.clone(),
    };
    // The status rule (the `status` module): the trial alone, pooled noise and correlation.
    let sigma2 = opts.assumed_sigma_m.map_or(red.sigma2(), |s| s * s);
    let kappa = status::trial_correlation(prob, est.ext.as_ref(), cov, red, sigma2, opts);
    let corr = correlations(&cov.null, &white);
    let params = (0..nf)
        .map(|k| {
            let i = prob.free[k];
            let par = &model.parameters()[i];
            let (f, unit) = display(par.unit);
            let value = p[i] * f;
            let at_bound = s[k].abs() >= 1.0 - 1e-9;
            let (all, best) = conservative(cov, crit, |c| c[(k, k)]);
            let of = |m: SeMethod| {
                all.iter()
                    .find(|v| v.2 == m && !cov.null[k])
                    .map(|v| v.0 * scale[k])
            };
            let (se, half_width, method) = match best {
                Some((v, h, m)) if !cov.null[k] => (Some(v * scale[k]), Some(h * scale[k]), m),
                _ => (None, None, SeMethod::Undetermined),
            };
            let status_half_width = alone[k]
                .map(|v| z * (kappa * v).sqrt() * scale[k])
                .filter(|h| h.is_finite());
            let (status, (se, half_width, method)) = status::label(
                (se, half_width, method),
                status_half_width,
                (z, cov.jack.as_ref().map(|_| crit.1), threshold(k)),
                at_bound || status::held(share[k]),
            );
            let reason = (status != Identifiability::Determined).then(|| {
                let sigma_mm = opts.assumed_sigma_m.map_or(red.sigma2(), |s| s * s).sqrt() * 1e3;
                let bounds = (scale[k], unit);
                let why = Why {
                    k,
                    at_bound,
                    ranges: &ranges,
                    corr: &corr,
                    sigma_mm,
                };
                why_not_determined(prob, &why, half_width, bounds, status)
            });
            ParamUncertainty {
                name: par.name.clone(),
                group: par.group.clone(),
                description: par.description.clone(),
                unit: unit.to_string(),
                value,
                se,
                half_width,
                ci: half_width.map(|h| [value - h, value + h]),
                method,
                se_white: of(SeMethod::White),
                se_hac: of(SeMethod::Hac),
                se_bootstrap: of(SeMethod::Bootstrap),
                se_jackknife: of(SeMethod::Jackknife),
                at_bound,
                status_half_width,
                status,
                reason,
            }
        })
        .collect();
    let weak_directions = weak_directions(prob, cov, &scale, crit, opts);
    Uncertainty {
        level: opts.level,
        z,
        z_hac: cov.hac.as_ref().map(|_| cov.hac_critical),
        t_jackknife: cov.jack.as_ref().map(|_| crit.1),
        jackknife_blocks: cov.jack.as_ref().map(|_| opts.jackknife_blocks),
        frames: red.scores.len(),
        observations: red.observations,
        dof: red.dof(),
        sigma: sigma2.sqrt(),
        sigma_assumed: opts.assumed_sigma_m.is_some(),
        small_sample_factor: cov.factor,
        hac_bandwidth: cov.bandwidth,
        correlation_factor: kappa,
        bootstrap: cov.boot.as_ref().map(|(_, b)| b.clone()),
        threshold_m: opts.threshold_m,
        threshold_rad: opts.threshold_rad,
        params,
        corr,
        weak_directions,
        ranges,
    }
}

/// The correlations of the free parameters from the covariance `white` (`None` where either
/// is in the null space).
fn correlations(null: &[bool], white: &nalgebra::DMatrix<f64>) -> Vec<Vec<Option<f64>>> {
    let nf = null.len();
    (0..nf)
        .map(|a| {
            (0..nf)
                .map(|b| {
                    if null[a] || null[b] {
                        None
                    } else {
                        let d = (white[(a, a)] * white[(b, b)]).sqrt();
                        Some(if d > 0.0 { white[(a, b)] / d } else { 0.0 })
                    }
                })
                .collect()
        })
        .collect()
}

/// What [`why_not_determined`] reads of free parameter `k`.
struct Why<'a> {
    k: usize,
    at_bound: bool,
    ranges: &'a [CoordRange],
    corr: &'a [Vec<Option<f64>>],
    sigma_mm: f64,
}

/// Why free parameter `why.k` is not determined: [`reason`] with its most correlated
/// partner (|r| ≥ 0.9), and whether its interval is wider than its search bounds (`bounds`:
/// their half-width and unit, for display).
fn why_not_determined(
    prob: &Problem,
    why: &Why,
    half_width: Option<f64>,
    (bound, unit): (f64, &str),
    status: Identifiability,
) -> String {
    let (model, k) = (prob.model, why.k);
    let partner = (0..prob.n_free())
        .filter(|&b| b != k)
        .filter_map(|b| why.corr[k][b].map(|r| (b, r)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .filter(|(_, r)| r.abs() >= 0.9)
        .map(|(b, r)| (model.parameters()[prob.free[b]].name.as_str(), r));
    let i = prob.free[k];
    let mut text = reason(model, i, why.at_bound, why.ranges, partner, why.sigma_mm);
    // `bound` is the bounds' half-width in display units.
    if half_width.is_some_and(|h| h > bound) {
        text.push_str(&format!(
            "; the interval is wider than the search bounds (±{bound:.0} {unit}), so \
             the trial adds little to them"
        ));
    }
    if status == Identifiability::Undetermined {
        format!("not determined by this trial at all: {text}")
    } else {
        text
    }
}
