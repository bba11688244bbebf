//! Gaussian priors on the joint parameters: the maximum a posteriori (MAP) objective.
//!
//! With markers measured with independent noise of SD σ per coordinate and a prior
//! `p_k ~ N(μ_k, s_k²)` on each free parameter, the negative log posterior is, up to a
//! constant and the factor `1/(2σ²)`,
//!
//! `F(p, q) = Σ_i Σ_j w_j ‖m_ij − x_j(p, q_i)‖²  +  σ² Σ_k ((p_k − μ_k)/s_k)²`.
//!
//! The first term is Reinbolt et al.'s objective; the second behaves like one extra residual
//! `σ (μ_k − p_k)/s_k` per parameter, so every solver keeps its structure: the joint solver's
//! reduced normal matrix gains the diagonal `σ² h_k²/s_k²` (`h_k = ∂p_k/∂s_k`, the half-range
//! of the bounds) and its gradient the term `σ² h_k (μ_k − p_k)/s_k²`; the two-level solvers
//! and the particle swarm add the term to `e_inner`. Without a prior (`Problem::prior` is
//! `None`) the fit is the paper's unregularized least squares. Parameters without a prior
//! SD (`s_k = ∞`) contribute nothing.
//!
//! σ is the marker noise in metres. It is either given (`--marker-noise-mm`) or estimated
//! from the residuals of a fit, `σ² = e / (m − N·n_q − n_f)` (see
//! [`super::uncertainty`]); the front end iterates fit → σ → fit once.

use super::Problem;
use crate::model::Model;

/// A Gaussian prior on the free parameters of a [`Problem`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Prior {
    /// Per free parameter (order of `Problem::free`): prior mean (m or rad).
    pub mean: Vec<f64>,
    /// Per free parameter: prior SD (m or rad); `f64::INFINITY` for no prior.
    pub sd: Vec<f64>,
    /// Marker noise σ (m): weight of the prior term relative to the marker term.
    pub noise: f64,
    /// Per free parameter: how much more than the trial as a whole the time-correlated
    /// residuals overstate this parameter's information (≥ 1; [`parameter_inflation`]); the
    /// prior weight is multiplied by it. All 1 unless σ was estimated.
    pub inflation: Vec<f64>,
    /// Per free parameter: the variance of the truth about the prior mean in units of
    /// `s_k²` that the intervals assume (`τ_k² ≥ 1`); it scales only the prior's part of the
    /// interval variance ([`super::uncertainty`]), not the fit. All 1 unless the prior–data
    /// conflict step (`workflow::conflict`) found the trial at odds with this joint's prior.
    pub spread: Vec<f64>,
}

impl Prior {
    /// The prior that the model file states (`prior_sd`, `prior_mean`) for the parameters
    /// `free`; `None` when none of them has a prior SD.
    pub(crate) fn from_model(model: &Model, free: &[usize], noise: f64) -> Option<Prior> {
        let pars: Vec<_> = free.iter().map(|&i| &model.parameters()[i]).collect();
        if pars.iter().all(|p| p.prior_sd.is_none()) {
            return None;
        }
        Some(Prior {
            mean: pars.iter().map(|p| p.prior_mean).collect(),
            sd: pars
                .iter()
                .map(|p| p.prior_sd.unwrap_or(f64::INFINITY))
                .collect(),
            noise,
            inflation: vec![1.0; pars.len()],
            spread: vec![1.0; pars.len()],
        })
    }

    /// Weight `a_k σ²/s_k²` of parameter k's prior residual (`a_k`: [`Prior::inflation`];
    /// 0 without a prior).
    pub(crate) fn weight(&self, k: usize) -> f64 {
        let w = (self.noise / self.sd[k]).powi(2) * self.inflation[k];
        if w.is_finite() {
            w
        } else {
            0.0
        }
    }
}

impl Problem<'_> {
    /// The prior term `σ² Σ_k ((p_k − μ_k)/s_k)²` at the full parameter vector `p` (m²); 0
    /// without a prior.
    pub(crate) fn prior_cost(&self, p: &[f64]) -> f64 {
        let Some(pr) = &self.prior else {
            return 0.0;
        };
        self.free
            .iter()
            .enumerate()
            .map(|(k, &i)| pr.weight(k) * (p[i] - pr.mean[k]).powi(2))
            .sum()
    }

    /// Attaches the model file's prior with marker noise `noise` (m); without any `prior_sd`
    /// among the free parameters the problem stays unregularized.
    pub(crate) fn with_model_prior(mut self, noise: f64) -> Self {
        self.prior = Prior::from_model(self.model, &self.free, noise);
        self
    }

    /// The prior term's share of the normal equations in scaled units: adds
    /// `σ²h_k(μ_k − p_k)/s_k²` to `gs[k]` and `σ²h_k²/s_k²` to the diagonal of `v` (n_f × n_f,
    /// column-major); returns the prior cost.
    pub(crate) fn add_prior(&self, p: &[f64], gs: &mut [f64], v: &mut [f64]) -> f64 {
        let Some(pr) = &self.prior else {
            return 0.0;
        };
        let nf = self.n_free();
        let mut cost = 0.0;
        for (k, &i) in self.free.iter().enumerate() {
            let w = pr.weight(k);
            let h = self.half_range(k);
            let r = pr.mean[k] - p[i];
            cost += w * r * r;
            gs[k] += w * h * r;
            v[k * nf + k] += w * h * h;
        }
        cost
    }

    /// Prior information of the free parameters in scaled units (`σ²h_k²/s_k²`, the
    /// diagonal the prior adds to the reduced normal matrix); zeros without a prior.
    pub(crate) fn prior_information(&self) -> Vec<f64> {
        (0..self.n_free())
            .map(|k| match &self.prior {
                Some(pr) => pr.weight(k) * self.half_range(k).powi(2),
                None => 0.0,
            })
            .collect()
    }
}

/// Where a parameter's posterior information came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// ≥ 80 % of the information is the trial's: the prior barely matters.
    DeterminedByTrial,
    /// 30–80 %: trial and prior both shape the estimate.
    Partly,
    /// < 30 %: the estimate is essentially the prior's (landmark/functional) value.
    HeldByPrior,
    /// The estimate sits on a bound of the anatomical envelope (`workflow::envelope`): the
    /// limit, not the trial, decided it.
    HeldAtLimit,
}

impl Source {
    pub(crate) fn of(share: f64) -> Source {
        if share >= 0.8 {
            Source::DeterminedByTrial
        } else if share >= 0.3 {
            Source::Partly
        } else {
            Source::HeldByPrior
        }
    }
}

/// The source in words ("determined by the trial", "held by the prior", …).
impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Source::DeterminedByTrial => "determined by the trial",
            Source::Partly => "partly determined",
            Source::HeldByPrior => "held by the prior",
            Source::HeldAtLimit => "held at the anatomical limit (hip centre medial to the ASIS)",
        })
    }
}

/// Per free parameter, the share of its posterior information that came from the data:
/// `1 − var_post/var_prior = 1 − d_k [S⁻¹]_kk`, with `S` the reduced normal matrix including
/// the prior's diagonal `d` ([`Problem::prior_information`]); 1 for a parameter without a
/// prior, NaN when `S` is singular. Posterior variances are never larger than prior ones
/// (`S ⪰ D`), so the share lies in [0, 1].
pub(crate) fn data_share(prob: &Problem, normal: &nalgebra::DMatrix<f64>) -> Vec<f64> {
    let d = prob.prior_information();
    let inv = normal.clone().cholesky().map(|c| c.inverse());
    (0..prob.n_free())
        .map(|k| {
            if d[k] == 0.0 {
                return 1.0;
            }
            match &inv {
                Some(inv) => (1.0 - d[k] * inv[(k, k)]).clamp(0.0, 1.0),
                None => f64::NAN,
            }
        })
        .collect()
}
