//! Which joint parameters a trial determines: standard errors, intervals, identifiability.
//!
//! Reinbolt et al. 2005 (doi:10.1016/j.jbiomech.2004.03.031) close with an open problem: "a
//! systematic methodology for determining which joint parameters can and cannot be found
//! accurately from a particular noisy experimental data set". This module answers it for a
//! fitted (or nominal) parameter set.
//!
//! # The reduced normal matrix
//!
//! With `J_i = [J_q,i | J_s,i]` the weighted Jacobian of frame i (coordinates `q_i`, scaled
//! free parameters `s`) and `r_i = m_i − x_i`, projecting the per-frame coordinates out gives
//! the reduced (variable-projection) Jacobian `J_red,i = (I − J_q (J_qᵀWJ_q)⁻¹ J_qᵀW) J_s` and
//! the reduced normal matrix, the Schur complement of the block-arrow system of
//! the private `schur` module:
//!
//! `S = Σ_i J_red,iᵀ W J_red,i = V − Σ_i W_iᵀ U_i⁻¹ W_i`.
//!
//! It is the Fisher information of `s` with the coordinates as nuisance parameters.
//!
//! # Covariance estimators
//!
//! * **white** (independent, equal-variance residuals): `C = σ² S⁻¹` with
//!   `σ² = e / (m − N·n_q − n_f)`, `e` the weighted squared residual sum, `m` the number of
//!   scalar residuals (3 per present marker sample), `N` frames, `n_q` coordinates per frame.
//! * **HAC sandwich** (Newey & West 1987): the per-frame profile score
//!   `ψ_i = J_red,iᵀ W r_i = J_s,iᵀWr_i − W_iᵀU_i⁻¹ J_q,iᵀWr_i` (at the optimum the second term
//!   vanishes, every `q_i` being an inner optimum) gives `C = c · S⁻¹ Ω S⁻¹` with the Bartlett
//!   long-run covariance `Ω = Σ_|l|<b (1 − |l|/b) Σ_i ψ_i ψ_{i+l}ᵀ`, pairs taken only within
//!   one trial. The bandwidth `b` is Andrews' (1991) AR(1) plug-in rule on the standardised
//!   influence series `S⁻¹ψ_i`, capped only by the trial length, unless given. At such a
//!   bandwidth (b/N up to 1) the estimate stays random and biased low (the scores sum to
//!   zero at the optimum), so its interval takes the fixed-b critical value of Kiefer &
//!   Vogelsang (2005) instead of `z` (2.57 at b/N = 0.2, 4.81 at b/N = 1; see the private
//!   `critical` module, which also says why the bandwidth is not capped lower).
//! * **moving-block bootstrap** (Künsch 1989), opt-in: blocks of consecutive frames are drawn
//!   with replacement until the trial length is reached, and the joint solver refits from
//!   the optimum; `C = c · cov(ŝ*)` over replicates. Seeded; replicates run in parallel but
//!   each has its own stream, so results do not depend on the thread count.
//! * **delete-block jackknife** (cluster-robust "CR3" with contiguous blocks of frames as
//!   clusters): `K` blocks (default 10); dropping block k moves the optimum by
//!   `δ_k = (S − A_k)⁻¹ B_k`, with `A_k`, `B_k` the block's share of `S` and of the scores,
//!   and `C = (K−1)/K Σ_k (δ_k − δ̄)(δ_k − δ̄)ᵀ`; intervals use Student's t on `K − 1`
//!   degrees of freedom.
//!
//! Skin artifact is correlated in time, so the white formula understates the uncertainty;
//! the robust estimators see that correlation. They estimate the scatter from fitted
//! residuals, which the fit has pulled towards the model: with `n_f` parameters and `N`
//! frames the scores lose about `n_f/N` of their variance (the frame-level leverages sum to
//! `n_f`). The HAC and bootstrap estimates are therefore scaled by `c = N/(N − n_f)` (the
//! usual cluster small-sample factor); the jackknife removes each block's own influence
//! instead.
//!
//! Each parameter's reported interval is the **widest** of the available estimates (the
//! white and bootstrap ones with the normal quantile, HAC with its fixed-b critical value,
//! the jackknife with t), and the
//! report names the method that produced it. Monte Carlo check:
//! `jointfit-experiments/examples/coverage.rs` (figures in `docs/identifiability.md`).
//! Drift slower than a block (skin sinusoids with less than a cycle per trial) looks like
//! a parameter change to every estimator built from one trial, which is why coverage stays
//! a few points under nominal.
//!
//! # Identifiability
//!
//! Parameters are converted to physical units with `∂p/∂s = (hi − lo)/2`. A parameter is
//! *determined* when the trial alone pins it within a threshold (default 5 mm / 5°): its
//! Fisher half-width `z·√(κ σ² [S_d⁻¹]_kk)`, with the pooled residual variance `σ²` and the
//! trial's time-correlation factor `κ` (the mean robust-to-white variance ratio over every
//! parameter of the model, free or not), is within it, it is not at a bound, and no prior holds
//! it; else it is *poorly determined*. A determined parameter whose label hinges on `κ`'s
//! noise reports an interval of at least that half-width ([`SeMethod::Pooled`]). The status is judged from these pooled quantities, not from the parameter's own
//! robust interval, because a label chosen on that noisy interval selects the trials in which
//! it came out too narrow (the private `status` module; `docs/identifiability.md`). One with weight on a
//! numerically null direction of `S` (eigenvalue below `1e-10·λ_max`) is *not determined* at
//! all. The eigenvectors of `S` with the smallest eigenvalues name the
//! worst-determined combinations; their dominant components (squared weight ≥ 0.1) are put
//! into words from the parameters' descriptions, and each flagged parameter gets a reason
//! built from the range of motion of its joint's coordinates in the trial.
//! [`unidentifiable_subset`] chooses the parameters to hold at their starting values so that
//! the rest are determined (subset selection on `S`).

mod analysis;
mod critical;
mod estimators;
mod explain;
mod inflation;
pub(crate) mod reduced;
mod resampling;
mod status;
mod subset;

use serde::{Deserialize, Serialize};

use crate::model::spec::Unit;
pub(crate) use analysis::{analyze, analyze_reduced, predict};
use analysis::{display, NULL_RATIO};
pub(crate) use critical::ln_gamma;
pub(crate) use inflation::correlation_inflation;
pub(crate) use inflation::parameter_inflation;
use reduced::reduced_system;
pub(crate) use reduced::Reduced;
pub(crate) use subset::unidentifiable_subset;

// The results and options of the analysis: which estimator produced a number, a parameter's
// status, the options, and the per-parameter, per-direction and per-coordinate records of
// [`Uncertainty`].

/// Which estimator produced a number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SeMethod {
    /// `σ² S⁻¹`, independent residuals.
    White,
    /// Newey–West sandwich over frames.
    Hac,
    /// Moving-block bootstrap over frames with refits.
    Bootstrap,
    /// Delete-block jackknife over contiguous blocks of frames (linearised).
    Jackknife,
    /// The trial-alone half-width the status was judged by,
    /// [`ParamUncertainty::status_half_width`]: the floor of a marginally determined
    /// parameter's interval (the private `status` module).
    Pooled,
    /// The parameter lies on a null direction of `S`: no finite error.
    Undetermined,
}

/// How well the trial determines a parameter (the rule: the private `status` module).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Identifiability {
    /// The trial alone pins it within the threshold ([`ParamUncertainty::status_half_width`]),
    /// not at a bound, not held by a prior.
    Determined,
    /// That half-width above the threshold, at a bound, or held by the prior.
    Poor,
    /// No information in the trial at all (null direction of `S`).
    Undetermined,
}

/// Settings of [`analyze`](super::analyze).
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyOptions {
    /// Coverage of the intervals (0.95).
    pub level: f64,
    /// Compute the Newey–West sandwich.
    pub hac: bool,
    /// Bartlett bandwidth in frames (lags `< b` get weight); `None`: Andrews' AR(1) rule.
    pub hac_bandwidth: Option<f64>,
    /// Bootstrap replicates (0, the default: no bootstrap; each replicate is a refit).
    pub bootstrap_replicates: usize,
    /// Block length in frames; `None`: the HAC bandwidth rounded up, at least 2.
    pub block_length: Option<usize>,
    /// Seed of the bootstrap.
    pub seed: u64,
    /// Contiguous blocks of the delete-block jackknife (0: no jackknife).
    pub jackknife_blocks: usize,
    /// Apply the small-sample factor `N/(N − n_f)` to the robust estimators.
    pub small_sample: bool,
    /// Assumed residual standard deviation per axis (m) instead of the one estimated from
    /// the residuals; the robust estimators are rescaled by the same variance ratio. For
    /// predictions at a nominal model, whose residuals include its misfit.
    pub assumed_sigma_m: Option<f64>,
    /// Half-width above which a length parameter is flagged (m).
    pub threshold_m: f64,
    /// Half-width above which an angle parameter is flagged (rad).
    pub threshold_rad: f64,
}

impl UncertaintyOptions {
    /// The flag threshold of a parameter of `unit` (SI: m or rad).
    pub(crate) fn threshold(&self, unit: Unit) -> f64 {
        match unit {
            Unit::Metre => self.threshold_m,
            Unit::Radian => self.threshold_rad,
        }
    }
}

impl Default for UncertaintyOptions {
    fn default() -> Self {
        UncertaintyOptions {
            level: 0.95,
            hac: true,
            hac_bandwidth: None,
            bootstrap_replicates: 0,
            block_length: None,
            seed: 1,
            jackknife_blocks: 10,
            small_sample: true,
            assumed_sigma_m: None,
            threshold_m: 0.005,
            threshold_rad: 5f64.to_radians(),
        }
    }
}

/// One free parameter's uncertainty, in its shown unit (mm or deg, named by `unit`): the
/// intervals are formed in the scaled units of the solver and converted once, to the unit a
/// person reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamUncertainty {
    pub name: String,
    pub group: String,
    pub description: String,
    /// `"mm"` or `"deg"`.
    pub unit: String,
    /// Fitted (or evaluated) value.
    pub value: f64,
    /// Standard error of the estimator whose interval is widest; `None` when not determined.
    pub se: Option<f64>,
    /// Interval half-width: `se` times that estimator's critical value (`z`, or Student's t
    /// for the jackknife); `None` when not determined.
    pub half_width: Option<f64>,
    /// Interval `value ± half_width` at the report's level; `None` when not determined.
    pub ci: Option<[f64; 2]>,
    /// Which estimator `se` and the interval come from (the most conservative one; `Pooled`:
    /// the floor of a marginally determined parameter, `se = status_half_width / z`).
    pub method: SeMethod,
    pub se_white: Option<f64>,
    pub se_hac: Option<f64>,
    pub se_bootstrap: Option<f64>,
    pub se_jackknife: Option<f64>,
    /// The value sits at a bound of the search box (the linear interval is then doubtful).
    pub at_bound: bool,
    /// The half-width the status is judged by: what the trial alone determines,
    /// `z·√(κ σ² [S_d⁻¹]_kk)` (Fisher information without the prior, pooled residual noise
    /// σ, the trial's time-correlation factor [`Uncertainty::correlation_factor`]); `None`
    /// when the trial alone does not determine the parameter. Not an interval: the interval
    /// is `half_width`.
    #[serde(default)]
    pub status_half_width: Option<f64>,
    pub status: Identifiability,
    /// Why a flagged parameter is poorly determined and which motion would determine it.
    pub reason: Option<String>,
}

/// One parameter's part in a weak direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DirectionComponent {
    pub name: String,
    /// Component of the unit eigenvector (scaled units).
    pub coefficient: f64,
    /// Interval half-width of this parameter along the direction (mm or deg); `None` for a
    /// null direction.
    pub half_width: Option<f64>,
    pub unit: String,
}

/// A poorly determined combination of parameters: an eigenvector of `S` with a small
/// eigenvalue.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeakDirection {
    /// Eigenvalue of `S` (m² per scaled unit²).
    pub eigenvalue: f64,
    /// Dominant components, largest first.
    pub components: Vec<DirectionComponent>,
    /// The combination in words.
    pub description: String,
}

/// Range of motion of one coordinate over the fitted frames, display units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoordRange {
    pub name: String,
    pub joint: String,
    /// `"deg"` or `"mm"`.
    pub unit: String,
    pub min: f64,
    pub max: f64,
    pub range: f64,
}

/// Bootstrap settings as used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BootstrapInfo {
    pub replicates: usize,
    /// Replicates whose refit did not converge (kept).
    pub not_converged: usize,
    pub block_length: usize,
    pub seed: u64,
}

/// Uncertainty and identifiability of the free parameters of one fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Interval coverage, e.g. 0.95.
    pub level: f64,
    /// Normal quantile: the critical value of the white and bootstrap intervals.
    pub z: f64,
    /// Critical value of the HAC interval: the fixed-b quantile for the Bartlett kernel at
    /// the bandwidth used (Kiefer & Vogelsang 2005), when computed.
    pub z_hac: Option<f64>,
    /// Student-t quantile with `K − 1` degrees of freedom: the jackknife's critical value.
    pub t_jackknife: Option<f64>,
    /// Blocks `K` of the delete-block jackknife, when computed.
    pub jackknife_blocks: Option<usize>,
    pub frames: usize,
    /// Scalar residuals `m`.
    pub observations: usize,
    /// Residual degrees of freedom `m − N·n_q − n_f`.
    pub dof: usize,
    /// Residual standard deviation per coordinate axis (m): estimated, or as assumed.
    pub sigma: f64,
    /// Whether `sigma` was assumed (given) rather than estimated from the residuals.
    pub sigma_assumed: bool,
    /// Small-sample factor applied to the robust estimators.
    pub small_sample_factor: f64,
    /// Bartlett bandwidth of the HAC estimator (frames), when computed.
    pub hac_bandwidth: Option<f64>,
    /// The trial's time-correlation factor `κ` (≥ 1) that the status rule applies to the
    /// Fisher variances: the mean robust-to-white variance ratio over every parameter of the
    /// model, free or not (private `status` module).
    #[serde(default = "status::one")]
    pub correlation_factor: f64,
    pub bootstrap: Option<BootstrapInfo>,
    /// Flag thresholds of a length (m) and of an angle (rad).
    pub threshold_m: f64,
    pub threshold_rad: f64,
    /// Per free parameter, in the problem's order.
    pub params: Vec<ParamUncertainty>,
    /// Correlation matrix of the free parameters from the white (Fisher) covariance; `None`
    /// entries involve an undetermined parameter.
    pub corr: Vec<Vec<Option<f64>>>,
    /// The weakest directions of `S` (smallest eigenvalue first) whose half-width exceeds
    /// the threshold for some component, at most 5.
    pub weak_directions: Vec<WeakDirection>,
    /// Range of motion of every coordinate over the frames.
    pub ranges: Vec<CoordRange>,
}

impl Uncertainty {
    /// Parameters flagged poor or undetermined.
    pub fn flagged(&self) -> impl Iterator<Item = &ParamUncertainty> {
        self.params
            .iter()
            .filter(|p| p.status != Identifiability::Determined)
    }
}

#[cfg(test)]
mod posterior_tests;
#[cfg(test)]
mod status_tests;
#[cfg(test)]
mod tests;
