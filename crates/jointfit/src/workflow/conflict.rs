//! Prior–data conflict per joint: does the trial disagree with the landmark model
//! by more than the prior's stated SD allows?
//!
//! **The statistic.** Linearize the maximum a posteriori fit at its optimum `m` (scaled
//! units, [`crate::calibrate::Problem::to_scaled`]): with `N` the reduced normal matrix of
//! the marker term alone, `D` the prior's diagonal as the fit weighed it (σ² and the
//! per-parameter factors included, [`crate::calibrate::Problem::prior_information`]) and `d`
//! the data-only estimate, `(N + D)(m − μ) = N(d − μ)`. With the data-only error `d − θ` of
//! covariance `σ²N⁻¹` (σ the κ-inflated marker noise of the fit: the robust, magnitude-adjusted
//! data covariance, `workflow::map`) and the truth `θ ~ N(μ, τ²S₀)` (`S₀` the stated prior
//! variances), the posterior shift has the prior-predictive covariance
//!
//! `Σ(τ) = A⁻¹ (σ²N + τ² N S₀ N) A⁻¹`,   `A = N + D`,
//!
//! which needs no inverse of `N` (a trial that leaves a joint undetermined has a singular
//! `N`). For `τ = 1`, on the directions the trial determines, `(m − μ)ᵀ Σ⁻¹ (m − μ)` equals
//! `(d − μ)ᵀ (C_d + S₀)⁻¹ (d − μ)`, the classical prior-predictive check (Box 1980, J R Stat
//! Soc A 143:383–430; Evans & Moshonov 2006, Bayesian Analysis 1:893–914): χ² with as many
//! degrees of freedom as directions kept. Per joint the block of `Σ` and of `m − μ` is taken
//! (the marginal), whitened by the prior SDs, and only the eigen-directions whose
//! prior-predictive variance is at least [`MIN_DIRECTION_VARIANCE`] prior variances are kept
//! (elsewhere the prior holds the estimate and the shift carries no information).
//!
//! **The prior scale.** The type-II maximum-likelihood (empirical Bayes) scale of the prior
//! of one joint, `τ̂ = argmax_{1 ≤ τ ≤ cap} log N(m_g − μ_g; 0, Σ_g(τ))` over the same
//! directions (a grid of log τ refined by golden section), is how much wider the joint's prior
//! would have to be for this trial to be typical of it. In one dimension it is the closed
//! form `τ̂² = ((d − μ)² − c_d)/s₀²` clipped to `[1, cap²]` (Morris 1983, JASA 78:47–55).
//!
//! **The rule** ([`assess`], [`widen_intervals`]): a joint whose χ² exceeds the
//! `1 − `[`CONFLICT_ALPHA`] quantile is *flagged*; its intervals are computed for a truth
//! spread `τ̂` (at most [`TAU_CAP`]) times the prior SD about the prior mean (the prior's part
//! of the interval variance scaled by `τ̂²`, [`crate::calibrate::prior::Prior::spread`]). The
//! estimate keeps the stated prior: refitting with the flagged joint's SDs widened failed the
//! held-out check on real gait at every cap tried (3, 2, 1.5), because the statistic flags
//! real gait (correlated skin artefact) as often as a landmark model that is truly off
//! (`docs/priors.md`, "The prior–data conflict step"). `--prior none` has no prior and so no
//! conflict. [`assess_and_widen`] is the step as both the jointfit-model and the OpenSim-model
//! calibrations run it.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

use super::calibration::analysis_stage;
use super::{FitSettings, Observer, WorkflowError};
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::uncertainty::{ln_gamma, Reduced};
use crate::calibrate::Problem;

/// Directions of a joint's whitened posterior shift with a smaller prior-predictive variance
/// (in prior variances) are left out of its statistic.
pub(crate) const MIN_DIRECTION_VARIANCE: f64 = 0.05;
/// Significance level of the conflict test.
pub(crate) const CONFLICT_ALPHA: f64 = 0.01;
/// The largest factor by which a prior SD is widened.
pub(crate) const TAU_CAP: f64 = 3.0;

/// The conflict of one joint's prior with the trial.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointConflict {
    /// `hip`, `knee`, `talocrural`, `subtalar` (with `_r` / `_l` on a two-leg model), or the
    /// parameter group of another model's joint.
    pub joint: String,
    pub parameters: Vec<String>,
    /// The prior-predictive χ² and its degrees of freedom (directions the trial determines).
    pub chi2: f64,
    pub dof: usize,
    /// Upper-tail probability of `chi2` under χ²(dof).
    pub p_value: f64,
    /// The type-II maximum-likelihood prior scale (1 ≤ τ ≤ [`TAU_CAP`]).
    pub tau: f64,
    /// Whether the test rejects this joint's prior (p < [`CONFLICT_ALPHA`], τ > 1).
    pub flagged: bool,
    /// The factor on the prior SDs that the intervals assume (the truth's spread about the
    /// prior mean; `tau` when widened, else 1).
    pub interval_scale: f64,
}

/// One line for the verdict, the text output and the report.
impl std::fmt::Display for JointConflict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "prior–data conflict at the {}: intervals widened for a prior ×{:.2} as wide (the \
             estimate keeps the prior): the trial disagrees with the model file's prior means by \
             χ² = {:.1} ({} dof, p = {:.1e})",
            self.joint, self.interval_scale, self.chi2, self.dof, self.p_value
        )
    }
}

/// The joint a parameter belongs to (module docs); `None` for refined marker offsets. An
/// OpenSim model's offset scalar (`JOINT.parent.tx`, the dotted names of
/// `jointfit_io::osim_read`) belongs to its group, the joint named in the file (`hip_r`,
/// `walker_knee_l`).
pub(crate) fn joint_of(name: &str, group: &str) -> Option<String> {
    if group == crate::model::refine::MARKER_GROUP {
        return None;
    }
    if name.contains('.') {
        return Some(group.to_string());
    }
    for j in ["hip", "knee", "talocrural", "subtalar"] {
        if name.starts_with(j) && name[j.len()..].starts_with('_') {
            let side = ["_r", "_l"].into_iter().find(|s| name.ends_with(s));
            return Some(format!("{j}{}", side.unwrap_or("")));
        }
    }
    Some(group.to_string())
}

/// Per group of indices: (χ², dof, τ̂) of the linear-Gaussian problem of the module docs, all
/// in one parameterization: `n` the data normal matrix, `d` the prior diagonal as the fit
/// weighed it, `inflation` the per-parameter factors `a_k` it carries (the score covariance
/// is taken as `σ² Λ^½ N Λ^½`, `Λ = diag(a_k)`: the curvature adjustment's robust data
/// covariance, [`crate::calibrate::uncertainty::parameter_inflation`]), `s0` the stated prior variances, `sigma2` the data variance factor, `shift`
/// the posterior mean minus the prior mean.
#[allow(clippy::too_many_arguments)]
pub(crate) fn statistics(
    n: &DMatrix<f64>,
    d: &[f64],
    inflation: &[f64],
    s0: &[f64],
    sigma2: f64,
    shift: &[f64],
    groups: &[Vec<usize>],
    cap: f64,
) -> Vec<(f64, usize, f64)> {
    let a = n + DMatrix::from_diagonal(&DVector::from_column_slice(d));
    let Some(ainv) = a.cholesky().map(|c| c.inverse()) else {
        return groups.iter().map(|_| (f64::NAN, 0, 1.0)).collect();
    };
    let g = &ainv * n; // A⁻¹N
                       // The robust score covariance Ω = σ² Λ^½ N Λ^½ (Λ = diag of the per-parameter factors).
    let root = DMatrix::from_diagonal(&DVector::from_iterator(
        inflation.len(),
        inflation.iter().map(|x| x.max(1.0).sqrt()),
    ));
    let noise = &ainv * &root * n * &root * &ainv * sigma2; // A⁻¹ Ω A⁻¹
    let s0m = DMatrix::from_diagonal(&DVector::from_column_slice(s0));
    let prior = &g * s0m * g.transpose(); // A⁻¹ N S₀ N A⁻¹
                                          // The joints are independent: side by side, collected in order.
    groups
        .par_iter()
        .map(|idx| {
            let k = idx.len();
            let w = |i: usize| 1.0 / s0[idx[i]].sqrt();
            let block =
                |m: &DMatrix<f64>| DMatrix::from_fn(k, k, |i, j| m[(idx[i], idx[j])] * w(i) * w(j));
            let (bn, bp) = (block(&noise), block(&prior));
            let u = DVector::from_fn(k, |i, _| shift[idx[i]] * w(i));
            let eig = (&bn + &bp).symmetric_eigen();
            let keep: Vec<usize> = (0..k)
                .filter(|&i| eig.eigenvalues[i] >= MIN_DIRECTION_VARIANCE)
                .collect();
            if keep.is_empty() {
                return (0.0, 0, 1.0);
            }
            let v = DMatrix::from_fn(k, keep.len(), |i, j| eig.eigenvectors[(i, keep[j])]);
            let (pn, pp, pu) = (
                v.transpose() * &bn * &v,
                v.transpose() * &bp * &v,
                v.transpose() * &u,
            );
            let chi2: f64 = keep
                .iter()
                .enumerate()
                .map(|(j, &i)| pu[j].powi(2) / eig.eigenvalues[i])
                .sum();
            let loglik = |tau: f64| -> f64 {
                let s = &pn + &pp * (tau * tau);
                match s.cholesky() {
                    Some(c) => {
                        let logdet: f64 = c.l().diagonal().iter().map(|x| 2.0 * x.ln()).sum();
                        -0.5 * (logdet + pu.dot(&c.solve(&pu)))
                    }
                    None => f64::NEG_INFINITY,
                }
            };
            (chi2, keep.len(), maximize_log_scale(loglik, cap))
        })
        .collect()
}

/// `argmax` of `f` over `[1, cap]`: the best of 64 points equally spaced in log τ, refined by
/// golden section between its neighbours (deterministic).
fn maximize_log_scale(f: impl Fn(f64) -> f64, cap: f64) -> f64 {
    let hi = cap.max(1.0).ln();
    if hi == 0.0 {
        return 1.0;
    }
    let steps = 64;
    let x = |i: usize| hi * i as f64 / steps as f64;
    let grid: Vec<f64> = (0..=steps).map(|i| f(x(i).exp())).collect();
    let best = (0..=steps)
        .max_by(|&a, &b| grid[a].total_cmp(&grid[b]).then(b.cmp(&a)))
        .unwrap_or(0);
    let (mut lo, mut up) = (x(best.saturating_sub(1)), x((best + 1).min(steps)));
    let r = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..40 {
        let (c, d) = (up - r * (up - lo), lo + r * (up - lo));
        if f(c.exp()) >= f(d.exp()) {
            up = d;
        } else {
            lo = c;
        }
    }
    let t = (0.5 * (lo + up)).exp();
    match f(t) >= grid[best] {
        true => t,
        false => x(best).exp(),
    }
}

/// Upper tail `P(X > x)` of χ²(k): the regularized incomplete gamma `Q(k/2, x/2)` (series
/// below `a + 1`, continued fraction above; Abramowitz & Stegun 6.5.29 and 6.5.31).
pub(crate) fn chi2_upper_tail(x: f64, k: usize) -> f64 {
    if k == 0 || !x.is_finite() {
        return if x.is_finite() { 1.0 } else { 0.0 };
    }
    let (a, x) = (k as f64 / 2.0, x / 2.0);
    if x <= 0.0 {
        return 1.0;
    }
    let front = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..500 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term < sum * 1e-15 {
                break;
            }
        }
        (1.0 - front * sum).max(0.0)
    } else {
        // Lentz's continued fraction for Γ(a, x).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut dd = 1.0 / b;
        let mut h = dd;
        for i in 1..500 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            dd = an * dd + b;
            dd = if dd.abs() < tiny { tiny } else { dd };
            c = b + an / c;
            c = if c.abs() < tiny { tiny } else { c };
            dd = 1.0 / dd;
            let del = dd * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (front * h).clamp(0.0, 1.0)
    }
}

/// The conflict of every joint of a maximum a posteriori calibration `cal` on `prob`, the
/// problem of its fit (its prior weighed by the fit's σ and per-parameter factors,
/// [`super::calibration::Kept`]): takes the marker term's reduced
/// normal matrix at the fitted point (from `system`, the reduced system of `cal`'s own uncertainty analysis,
/// when the caller kept it; else formed here), and applies [`statistics`] per joint;
/// `flagged` marks the joints the rule of the module docs widens. Empty without a prior.
pub(crate) fn assess(
    prob: &Problem,
    cal: &super::Calibration,
    system: Option<&Reduced>,
) -> Result<Vec<JointConflict>, WorkflowError> {
    let model = prob.model;
    if cal.prior_noise.is_none() {
        return Ok(Vec::new());
    }
    let Some(pr) = prob.prior.clone() else {
        return Ok(Vec::new());
    };
    // The marker term's information at the fit: the analysis' (`system`), else formed here.
    let formed;
    let data_normal = match system {
        Some(red) => &red.data_normal,
        None => {
            formed = reduced_system(prob, &cal.fit.p, &cal.fit.coords);
            &formed.data_normal
        }
    };
    let d = prob.prior_information();
    let nf = prob.n_free();
    let h: Vec<f64> = (0..nf).map(|k| prob.half_range(k)).collect();
    let s0: Vec<f64> = (0..nf).map(|k| (pr.sd[k] / h[k]).powi(2)).collect();
    let shift: Vec<f64> = prob
        .free
        .iter()
        .enumerate()
        .map(|(k, &i)| (cal.fit.p[i] - pr.mean[k]) / h[k])
        .collect();
    let mut joints: Vec<(String, Vec<usize>)> = Vec::new();
    for (k, &i) in prob.free.iter().enumerate() {
        let par = &model.parameters()[i];
        if !pr.sd[k].is_finite() || d[k] <= 0.0 {
            continue;
        }
        let Some(j) = joint_of(&par.name, &par.group) else {
            continue;
        };
        match joints.iter_mut().find(|(n, _)| *n == j) {
            Some((_, v)) => v.push(k),
            None => joints.push((j, vec![k])),
        }
    }
    let groups: Vec<Vec<usize>> = joints.iter().map(|(_, v)| v.clone()).collect();
    let stats = statistics(
        data_normal,
        &d,
        &pr.inflation,
        &s0,
        pr.noise.powi(2),
        &shift,
        &groups,
        TAU_CAP,
    );
    Ok(joints
        .into_iter()
        .zip(stats)
        .map(|((joint, idx), (chi2, dof, tau))| {
            let p_value = chi2_upper_tail(chi2, dof);
            let flagged = dof > 0 && p_value < CONFLICT_ALPHA && tau > 1.0 + 1e-6;
            JointConflict {
                joint,
                parameters: idx
                    .iter()
                    .map(|&k| model.parameters()[prob.free[k]].name.clone())
                    .collect(),
                chi2,
                dof,
                p_value,
                tau,
                flagged,
                interval_scale: if flagged { tau } else { 1.0 },
            }
        })
        .collect())
}

/// The uncertainty analysis of `cal` (its fit's problem `prob`, reduced system `system`:
/// [`super::calibration::fit_keeping_system`]) with the truth's spread about the prior mean
/// that each flagged joint of `conflicts` states: the prior's part of the interval variance
/// of its parameters scaled by `interval_scale²`
/// ([`crate::calibrate::prior::Prior::spread`]); the estimate and the data shares are
/// unchanged. The plain analysis when no joint needs it; nothing without
/// `settings.uncertainty`.
pub(crate) fn analyze_widened(
    prob: &Problem,
    settings: &FitSettings,
    cal: &mut super::Calibration,
    conflicts: &[JointConflict],
    system: Option<Reduced>,
    observer: &mut dyn Observer,
) {
    let Some(opts) = &settings.uncertainty else {
        return;
    };
    let model = prob.model;
    let spread = |name: &str| {
        conflicts
            .iter()
            .find(|c| c.parameters.iter().any(|p| p == name))
            .map_or(1.0, |c| c.interval_scale.powi(2))
    };
    let mut red = system.unwrap_or_else(|| reduced_system(prob, &cal.fit.p, &cal.fit.coords));
    if cal.prior_noise.is_none() || cal.parameters.iter().all(|r| spread(&r.name) <= 1.0) {
        analysis_stage(prob, cal, opts, &red, observer);
        return;
    }
    // The fit's problem with the prior's spread widened (its σ and factors unchanged).
    let mut prob = prob.clone();
    let names: Vec<String> = prob
        .free
        .iter()
        .map(|&i| model.parameters()[i].name.clone())
        .collect();
    if let Some(pr) = prob.prior.as_mut() {
        for (k, n) in names.iter().enumerate() {
            pr.spread[k] = spread(n).max(1.0);
        }
    }
    // The reduced system with the widened prior (its marker term unchanged).
    red.set_prior_of(&prob);
    analysis_stage(&prob, cal, opts, &red, observer);
}

/// The conflict step of a maximum a posteriori calibration `cal` (its fit's problem `prob`,
/// reduced system `system`: [`super::calibration::fit_keeping_system`]) with nothing between
/// the test and the intervals: [`assess`] every joint, then the analysis with the flagged
/// ones widened ([`analyze_widened`]). Without `settings.prior_conflict` or a prior, no
/// joint is assessed and the analysis is the plain one. (The jointfit-model calibration,
/// [`super::calibrate_refined`], runs the two halves around its envelope refit.)
pub(crate) fn assess_and_widen(
    prob: &Problem,
    settings: &FitSettings,
    cal: &mut super::Calibration,
    system: Option<Reduced>,
    observer: &mut dyn Observer,
) -> Result<Vec<JointConflict>, WorkflowError> {
    let conflicts = match settings.prior_conflict {
        true => assess(prob, cal, system.as_ref())?,
        false => Vec::new(),
    };
    analyze_widened(prob, settings, cal, &conflicts, system, observer);
    Ok(conflicts)
}
