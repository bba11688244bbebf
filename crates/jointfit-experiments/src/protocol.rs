//! The paper's protocol, run on trials in memory (no files, no printing).
//!
//! * [`fit`]: the outer level on a chosen parameter subset, from one or several starts; the
//!   best (lowest `e_inner`) wins. Reinbolt et al. 2005 used a particle swarm for the single
//!   joints and a gradient method for the full leg, ~41 h per noisy single-joint problem; we
//!   default to the joint sparse Levenberg–Marquardt ([`jointfit::calibrate::joint`]), which
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

use jointfit::calibrate::joint::{solve_joint, JointOptions};
use jointfit::calibrate::pso::{solve_pso, PsoOptions};
use jointfit::calibrate::varpro::{solve_varpro, VarProOptions};
use jointfit::calibrate::{params_for_groups, CalibError, Problem};
use jointfit::ik::IkWorkspace;
use jointfit::model::{Model, Unit};
use jointfit::trial::Trial;
use serde::Serialize;

use crate::synth::{perturb, restart_point, synthesize, Noise, NoiseStats};

/// The outer optimizer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum OuterMethod {
    /// Joint sparse Levenberg–Marquardt over every frame's coordinates and the parameters.
    Joint,
    /// Two-level Gauss-Newton with the envelope-theorem gradient (variable projection).
    Gradient,
    /// Particle swarm (Schutte et al. 2005), polished by the joint solver.
    Pso,
}

impl OuterMethod {
    pub fn name(self) -> &'static str {
        match self {
            OuterMethod::Joint => "joint",
            OuterMethod::Gradient => "gradient",
            OuterMethod::Pso => "pso",
        }
    }
}

/// How every fit of an experiment is run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitSettings {
    pub method: OuterMethod,
    /// Number of starts (≥ 1). Start 0 is the given start; the others perturb it by up to
    /// `restart_mm` / `restart_deg` (seeded). Ignored by the particle swarm.
    pub starts: usize,
    pub restart_mm: f64,
    pub restart_deg: f64,
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            method: OuterMethod::Joint,
            starts: 1,
            restart_mm: 20.0,
            restart_deg: 10.0,
        }
    }
}

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

/// Fits the parameters of `groups` to `trials` from `start` (see [`FitSettings`]).
pub fn fit(
    model: &Model,
    start: &[f64],
    groups: &[&str],
    trials: &[&Trial],
    settings: &FitSettings,
    seed: u64,
) -> Result<FitOutcome, CalibError> {
    let clock = Instant::now();
    let free = params_for_groups(model, groups)?;
    let prob = Problem::new(model, start.to_vec(), &free, trials)?;
    let starts = if settings.method == OuterMethod::Pso {
        1
    } else {
        settings.starts.max(1)
    };
    let mut best: Option<jointfit::calibrate::Fit> = None;
    let mut iterations = 0;
    for k in 0..starts {
        let p0 = if k == 0 {
            start.to_vec()
        } else {
            restart_point(
                model,
                start,
                &prob.free,
                settings.restart_mm,
                settings.restart_deg,
                seed,
                k,
            )
        };
        let q0 = prob.initial_coords(&p0);
        let s0 = prob.to_scaled(&p0);
        let f = match settings.method {
            OuterMethod::Joint => solve_joint(&prob, &s0, q0, &JointOptions::default()),
            OuterMethod::Gradient => solve_varpro(&prob, &s0, q0, &VarProOptions::default()),
            OuterMethod::Pso => {
                let opts = PsoOptions {
                    seed,
                    ..PsoOptions::default()
                };
                let swarm = solve_pso(&prob, &q0, &opts, |_, _| {});
                let mut polished = solve_joint(
                    &prob,
                    &swarm.s,
                    swarm.coords.clone(),
                    &JointOptions::default(),
                );
                polished.iterations += swarm.iterations;
                polished
            }
        };
        iterations += f.iterations;
        if best.as_ref().is_none_or(|b| f.cost < b.cost) {
            best = Some(f);
        }
    }
    let best = best.expect("at least one start");
    Ok(FitOutcome {
        marker_rms: prob.marker_rms(&best.p, &best.coords),
        frames: prob.frames.len(),
        converged: best.converged,
        iterations,
        cost: best.cost,
        p: best.p,
        coords: best.coords,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// `e_inner(p)` and the RMS marker distance (m) of the inner level alone at fixed `p`.
pub fn inner_only(model: &Model, p: &[f64], trials: &[&Trial]) -> Result<(f64, f64), CalibError> {
    let all = params_for_groups(model, &["all"])?;
    let prob = Problem::new(model, p.to_vec(), &all, trials)?;
    let mut qs = prob.initial_coords(p);
    let mut ws = IkWorkspace::new(model);
    let cost = prob.inner(p, &mut qs, &mut ws);
    Ok((cost, prob.marker_rms(p, &qs)))
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
            Unit::Metre => pos.push(d * 1e3),
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
) -> Result<SyntheticResult, CalibError> {
    let (trial, stats): (Trial, NoiseStats) =
        synthesize(model, truth, setup.coords, setup.rate, noise);
    let free: Vec<usize> = params_for_groups(model, setup.groups)?
        .iter()
        .map(|id| id.0)
        .collect();
    let start = perturb(
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
) -> Result<ExperimentalResult, CalibError> {
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
