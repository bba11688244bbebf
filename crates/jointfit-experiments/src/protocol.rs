//! The paper's protocol, run on trials in memory (no files, no printing).
//!
//! * [`fit`]: the outer level on a chosen parameter subset, from one or several starts
//!   ([`jointfit::workflow::calibration::calibrate`]); the best (lowest `e_inner`) wins. Reinbolt et al. 2005 used a particle swarm for the single
//!   joints and a gradient method for the full leg, ~41 h per noisy single-joint problem; we
//!   default to the joint sparse Levenberg–Marquardt (`jointfit::workflow::Method::Joint`), which
//!   shares the two-level formulation's optima and takes well under a second.
//! * [`synthetic_case`]: one synthetic experiment. The true parameters are the subject's
//!   nominal values; markers are generated along a motion and noise is added; the fit starts
//!   from the truth perturbed (seeded) on the free parameters only; the others stay at the
//!   truth. Errors are RMS over the free parameters: orientations in degrees, positions in
//!   mm; the marker error is the RMS distance between the fitted model's markers and the
//!   (noisy) synthetic markers, as in the paper's Table 1.
//! * [`experimental`]: the anatomical-landmark model (inner level only) against the fitted
//!   model on a real trial.

use std::time::Instant;

use jointfit::calibrate::params_for_groups;
use jointfit::model::spec::Unit;
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::trial::Trial;
use jointfit::workflow::{self, FitSettings, WorkflowError};
use serde::Serialize;

use crate::synth::{synthesize, Noise, NoiseStats};

/// The outcome of [`fit`]. SI units.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    pub p: Vec<f64>,
    pub coords: Vec<Vec<f64>>,
    /// `e_inner` at the fitted parameters (m²).
    pub cost: f64,
    /// RMS marker distance of the fit (m).
    pub marker_rms: f64,
    pub frames: usize,
    pub converged: bool,
    pub iterations: usize,
    pub seconds: f64,
}

/// Fits the parameters of `groups` to `trials` from `start` with [`jointfit::workflow::calibration::calibrate`]
/// (no uncertainty analysis), the random choices seeded by `seed`.
pub fn fit(
    model: &Model,
    start: &[f64],
    groups: &[&str],
    trials: &[&Trial],
    settings: &FitSettings,
    seed: u64,
) -> Result<FitOutcome, WorkflowError> {
    let clock = Instant::now();
    let free = params_for_groups(model, groups)?;
    let settings = FitSettings {
        seed,
        uncertainty: None,
        fix_unidentifiable: false,
        ..settings.clone()
    };
    let cal = jointfit::workflow::calibration::calibrate(
        model,
        start,
        trials,
        &free,
        &settings,
        &mut NoObserver,
    )?;
    Ok(FitOutcome {
        marker_rms: cal.rms_after,
        frames: cal.frames,
        converged: cal.converged,
        iterations: cal.start_runs.iter().map(|r| r.iterations).sum(),
        cost: cal.fit.cost,
        p: cal.fit.p,
        coords: cal.fit.coords,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// `e_inner(p)` and the RMS marker distance (m) of the inner level alone at fixed `p`
/// ([`jointfit::workflow::marker_rms::marker_rms`]).
pub fn inner_only(
    model: &Model,
    p: &[f64],
    trials: &[&Trial],
) -> Result<(f64, f64), WorkflowError> {
    let r = jointfit::workflow::marker_rms::marker_rms(model, p, trials)?;
    Ok((r.cost, r.rms))
}

/// RMS over the `free` parameters of `a − b`: (orientations in deg, positions in mm); `None`
/// when the subset has no parameter of that kind.
pub fn param_errors(
    model: &Model,
    free: &[usize],
    a: &[f64],
    b: &[f64],
) -> (Option<f64>, Option<f64>) {
    let (mut ori, mut pos) = (Vec::new(), Vec::new());
    for &i in free {
        let d = a[i] - b[i];
        match model.parameters()[i].unit {
            Unit::Radian => ori.push(d.to_degrees()),
            Unit::Metre => pos.push(d * crate::units::MM_PER_M),
        }
    }
    let rms = |v: &[f64]| {
        (!v.is_empty()).then(|| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt())
    };
    (rms(&ori), rms(&pos))
}

/// One synthetic experiment (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticSetup<'a> {
    /// Parameter groups fitted (`hip`, `knee`, `ankle`, `all`).
    pub groups: &'a [&'a str],
    /// Coordinates per frame (model order).
    pub coords: &'a [Vec<f64>],
    /// Sampling rate (Hz); sets the time axis of the skin noise.
    pub rate: f64,
    /// Perturbation of the start from the truth: up to this many mm / degrees per parameter.
    pub perturb_mm: f64,
    pub perturb_deg: f64,
}

/// What one synthetic experiment gave (mm, deg).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SyntheticResult {
    pub seed: u64,
    pub marker_rms_mm: f64,
    pub orientation_rms_deg: Option<f64>,
    pub position_rms_mm: Option<f64>,
    /// The same errors at the perturbed start.
    pub start_orientation_rms_deg: Option<f64>,
    pub start_position_rms_mm: Option<f64>,
    /// `e_inner` at the fitted and at the true parameters (m²).
    pub cost_fit: f64,
    pub cost_truth: f64,
    pub noise_rms_axis_mm: [f64; 3],
    pub noise_rms_3d_mm: f64,
    pub converged: bool,
    pub seconds: f64,
}

/// Runs one synthetic experiment on `model` whose true parameters are `truth`.
pub fn synthetic_case(
    model: &Model,
    truth: &[f64],
    setup: &SyntheticSetup,
    noise: &Noise,
    settings: &FitSettings,
    seed: u64,
) -> Result<SyntheticResult, WorkflowError> {
    let (trial, stats): (Trial, NoiseStats) =
        synthesize(model, truth, setup.coords, setup.rate, noise);
    let free: Vec<usize> = params_for_groups(model, setup.groups)?
        .iter()
        .map(|id| id.0)
        .collect();
    let start = workflow::perturb(
        model,
        truth,
        &free,
        setup.perturb_mm,
        setup.perturb_deg,
        seed.wrapping_add(0x9e37_79b9),
    );
    let out = fit(model, &start, setup.groups, &[&trial], settings, seed)?;
    let (cost_truth, _) = inner_only(model, truth, &[&trial])?;
    let (ori, pos) = param_errors(model, &free, &out.p, truth);
    let (ori0, pos0) = param_errors(model, &free, &start, truth);
    Ok(SyntheticResult {
        seed,
        marker_rms_mm: out.marker_rms * 1e3,
        orientation_rms_deg: ori,
        position_rms_mm: pos,
        start_orientation_rms_deg: ori0,
        start_position_rms_mm: pos0,
        cost_fit: out.cost,
        cost_truth,
        noise_rms_axis_mm: stats.rms_axis.map(|v| v * 1e3),
        noise_rms_3d_mm: stats.rms_3d * 1e3,
        converged: out.converged,
        seconds: out.seconds,
    })
}

/// Landmark model against fitted model on real trials (mm, SI parameters).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExperimentalResult {
    pub groups: Vec<String>,
    pub frames: usize,
    pub landmark_rms_mm: f64,
    pub fitted_rms_mm: f64,
    /// `100 (1 − fitted / landmark)`.
    pub reduction_percent: f64,
    pub cost_landmark: f64,
    pub cost_fit: f64,
    /// Fitted full parameter vector (SI).
    pub fitted: Vec<f64>,
    pub converged: bool,
    pub seconds: f64,
}

/// Fits `groups` of `model` to `trials` from `start`, and evaluates the landmark model
/// (`model`'s nominal parameters, inner level only) on the same trials.
pub fn experimental(
    model: &Model,
    start: &[f64],
    groups: &[&str],
    trials: &[&Trial],
    settings: &FitSettings,
    seed: u64,
) -> Result<ExperimentalResult, WorkflowError> {
    let (cost_landmark, landmark) = inner_only(model, &model.nominal_params(), trials)?;
    let out = fit(model, start, groups, trials, settings, seed)?;
    Ok(ExperimentalResult {
        groups: groups.iter().map(|g| g.to_string()).collect(),
        frames: out.frames,
        landmark_rms_mm: landmark * 1e3,
        fitted_rms_mm: out.marker_rms * 1e3,
        reduction_percent: 100.0 * (1.0 - out.marker_rms / landmark),
        cost_landmark,
        cost_fit: out.cost,
        fitted: out.p,
        converged: out.converged,
        seconds: out.seconds,
    })
}
