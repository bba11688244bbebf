//! The results and options of the uncertainty analysis (the module docs of `uncertainty` state
//! the mathematics): which estimator produced a number, a parameter's status, the options,
//! and the per-parameter, per-direction and per-coordinate records of [`Uncertainty`].

use serde::{Deserialize, Serialize};

use crate::model::spec::Unit;

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
    #[serde(default = "super::status::one")]
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
