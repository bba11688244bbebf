//! The maximum a posteriori problem of a calibration ([`crate::calibrate::prior`]): the
//! marker term weighed against the parameter priors of the model file by the marker noise σ,
//! given ([`FitSettings::marker_noise`]) or estimated from the residuals.
//!
//! Estimation: σ² starts as the residual variance at the start, then one preliminary MAP fit
//! (joint solver) gives the residual variance of the reduced system, inflated by the
//! time-correlation factor κ of [`crate::calibrate::uncertainty::correlation_inflation`] (the ratio
//! of the robust to the white variance; without it thousands of correlated samples would
//! count as independent and swamp any prior), and per parameter by its own excess over κ
//! ([`crate::calibrate::uncertainty::parameter_inflation`]).
//!
//! The preliminary fit stops at [`PRELIMINARY_RESOLUTION_SE`] = 0.01 standard errors from
//! its optimum ([`crate::calibrate::joint`]'s statistical rule) instead of a thousandth: a
//! point `d` SE away raises the residual sum by `d²σ²`, so the white σ² by the fraction
//! `d²/dof`, far below σ²'s own sampling error `√(2/dof)`; the correlation factor κ moves more
//! (its scores are not centred away from the optimum): at 0.1 SE σ moved by up to 0.3 % and
//! the final parameters by up to 0.011 SE on opencap_expert1 walking2, at 0.01 SE by 0.03 %
//! and ≤ 1.02e-3 SE on walking1, walking2, squats1 and STS1 (hip_r + walker_knee_r of
//! hand_scaled.osim, against running the classical tolerances out).
//!
//! **With the global phase** ([`super::global`], the default) the σ estimate is not a fit of
//! its own (`defer` of [`map_problem_with`]): what it needs is a point near the optimum of
//! the MAP problem weighed by the starting σ₀ (the σ₀-optimum), and the global phase gets
//! there on its way. Its probes run on the prior weighed by σ₀, the best start is continued
//! on every frame to [`SIGMA_POINT_RESOLUTION_SE`] = 0.1 SE of the σ₀-optimum, σ, κ and the
//! per-parameter factors are estimated there ([`estimate_noise`], the same formulas at the
//! same optimum as above, only from a start already near it), and the finishing solve runs
//! on the re-weighed prior from there, after one more probe at the estimated σ on the
//! probes' frames (the finishing solve then begins near its optimum, as from a probe). The
//! estimate is the one above up to where on the σ₀-optimum's basin it is taken: 0.1 instead
//! of 0.01 SE (a point that close moves σ² by `d²/dof` and κ by the 0.3 % bound above). Only
//! the preliminary fit from the given start is saved; the result moves within statistical
//! resolution (`notebook/performance_fit.md`: on ten opencap, gait2392 and Hamner fits σ within
//! 0.031 % and the parameters within 0.0021 SE of the preliminary fit's; σ within 0.3 % on
//! every row of the prior gait table). Without the global phase (`probes` 0,
//! several full starts, the swarm) the preliminary fit runs as above.

use super::{FitSettings, NoObserver, WorkflowError};
use crate::calibrate::joint::{solve_joint_to, JointOptions};
use crate::calibrate::uncertainty::analyze;
use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::{Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// How close (standard errors) the preliminary fit gets to its optimum (module docs).
pub(crate) const PRELIMINARY_RESOLUTION_SE: f64 = 0.01;

/// How close (standard errors) the global phase's best start gets to the σ₀-optimum before σ
/// is estimated there (module docs).
pub(crate) const SIGMA_POINT_RESOLUTION_SE: f64 = 0.1;

/// What the σ estimate computed on the way that the fit which follows reuses: the seeded
/// inner solutions at the start, and the inner solutions and marker term there.
pub(crate) struct Preliminary {
    /// [`Problem::initial_coords`] at the start.
    pub q_seed: Vec<Vec<f64>>,
    /// One more inner pass from `q_seed` ([`Problem::inner`]).
    pub q_inner: Vec<Vec<f64>>,
    /// The marker term there (m², without the prior).
    pub data_cost: f64,
    /// σ is still to be estimated ([`map_problem_with`]'s `defer`): the problem's prior is
    /// weighed by the starting σ₀, and the global phase calls [`estimate_noise`] at its
    /// σ₀-optimum ([`super::global::run`]).
    pub pending: bool,
}

/// The problem of `free` on `trials` from `start`, with the model's priors when
/// `settings.priors` is set and the model has any, weighed by `noise` (m) when given, else by
/// the σ estimated as the module docs say. Returns the problem, the σ used (`None`: no
/// prior, the paper's unregularized fit) and what the σ estimate computed ([`Preliminary`];
/// `None` when σ was given or there is no prior). With `defer` the preliminary fit is not
/// run: the problem's prior is weighed by the starting σ₀ and the caller finishes the
/// estimate with [`estimate_noise`] at the σ₀-optimum it reaches anyway (the global phase,
/// module docs); the σ returned is then σ₀.
/// What a fit knows before it starts: the marker noise σ (m) that weighs its prior (`None`:
/// estimated), and its starting inner solutions ([`Problem::initial_coords`] at the start)
/// when they were solved already for the same model, start and trials.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Known<'a> {
    pub noise: Option<f64>,
    pub coords: Option<&'a [Vec<f64>]>,
}

pub(crate) fn map_problem_with<'m>(
    model: &'m Model,
    start: &[f64],
    trials: &[&'m Trial],
    free: &[ParamId],
    settings: &FitSettings,
    known: Known,
    defer: bool,
) -> Result<(Problem<'m>, Option<f64>, Option<Preliminary>), WorkflowError> {
    let Known { noise, coords } = known;
    let prob = Problem::new(model, start.to_vec(), free, trials)?;
    let has_prior = free
        .iter()
        .any(|id| model.parameters()[id.0].prior_sd.is_some());
    if !settings.priors || !has_prior {
        return Ok((prob, None, None));
    }
    if let Some(sigma) = noise {
        let prob = prob.with_model_prior(sigma);
        let used = prob.prior.as_ref().map(|p| p.noise);
        return Ok((prob, used, None));
    }
    let q0 = match coords {
        Some(q) => q.to_vec(),
        None => prob.initial_coords(start),
    };
    let mut q = q0.clone();
    let mut ws = IkWorkspace::new(model);
    let data = prob.inner(start, &mut q, &mut ws);
    let observations = crate::calibrate::joint::observations(&prob).max(1);
    let mut prob = prob.with_model_prior((data / observations as f64).sqrt());
    let mut preliminary = None;
    if prob.prior.is_some() {
        if !defer {
            let s0 = prob.to_scaled(start);
            let pre = solve_joint_to(
                &prob,
                &s0,
                q0.clone(),
                &JointOptions::default(),
                PRELIMINARY_RESOLUTION_SE,
                &mut NoObserver,
            );
            estimate_noise(&mut prob, &pre);
        }
        preliminary = Some(Preliminary {
            q_seed: q0,
            q_inner: q,
            data_cost: data,
            pending: defer,
        });
    }
    let used = prob.prior.as_ref().map(|p| p.noise);
    Ok((prob, used, preliminary))
}

/// Re-weighs the prior of `prob` (weighed by σ₀) by the σ and per-parameter factors
/// estimated at `fit`, the σ₀-optimum of `prob` to [`PRELIMINARY_RESOLUTION_SE`] or
/// [`SIGMA_POINT_RESOLUTION_SE`] (module docs); nothing when the estimate is not a positive finite number.
pub(crate) fn estimate_noise(prob: &mut Problem<'_>, fit: &Fit) {
    // The unregularized problem on the same frames (the prior changes only `S`, not the
    // residuals or their degrees of freedom, so its σ² is the posterior's).
    let mut plain = prob.clone();
    plain.prior = None;
    let u = analyze(&plain, fit, &UncertaintyOptions::default());
    let kappa = crate::calibrate::uncertainty::correlation_inflation(&u);
    let sigma2 = match u.dof {
        0 => f64::INFINITY,
        dof => (fit.cost - prob.prior_cost(&fit.p)) / dof as f64,
    };
    let sigma = (sigma2 * kappa).sqrt();
    if sigma.is_finite() && sigma > 0.0 {
        let model = prob.model;
        let names: Vec<&str> = prob
            .free
            .iter()
            .map(|&i| model.parameters()[i].name.as_str())
            .collect();
        if let Some(pr) = prob.prior.as_mut() {
            pr.noise = sigma;
            pr.inflation = crate::calibrate::uncertainty::parameter_inflation(&u, &names, kappa);
        }
    }
}

/// Multiplies the prior weight of each named free parameter of `prob` by its factor (the
/// per-parameter factors of an earlier fit of the same trials, [`inflation_of`]); nothing
/// without a prior or with no factors.
pub(crate) fn set_inflation(prob: &mut Problem<'_>, factors: &[(String, f64)]) {
    let model = prob.model;
    let free = prob.free.clone();
    let Some(pr) = prob.prior.as_mut() else {
        return;
    };
    for (k, &i) in free.iter().enumerate() {
        let name = &model.parameters()[i].name;
        if let Some((_, f)) = factors.iter().find(|(n, _)| n == name) {
            pr.inflation[k] = *f;
        }
    }
}

/// The free parameters of `prob` whose prior weight carries a factor above 1, with it.
pub(crate) fn inflation_of(prob: &Problem<'_>) -> Vec<(String, f64)> {
    let Some(pr) = &prob.prior else {
        return Vec::new();
    };
    prob.free
        .iter()
        .zip(&pr.inflation)
        .filter(|(_, &f)| f > 1.0)
        .map(|(&i, &f)| (prob.model.parameters()[i].name.clone(), f))
        .collect()
}
