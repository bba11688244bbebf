//! One calibration of a job, values in and values out: the free parameters by group, the
//! outer solve, the uncertainty of the optimum (`jointfit::calibrate::uncertainty`).
//!
//! The solvers are called in the order `jointfit calibrate` calls them (start = the model's
//! nominal parameters, inner coordinates seeded by IK at the start, one start, uncertainty
//! from the optimum), so the fitted parameters equal the command line's bit for bit. This is
//! the interim orchestration until `jointfit::workflow::calibrate` (issue 18) lands; then
//! [`calibrate`] becomes a call to it.

use jointfit::calibrate::joint::{solve_joint_observed, JointOptions};
use jointfit::calibrate::pso::{solve_pso, PsoOptions};
use jointfit::calibrate::uncertainty::{analyze, Identifiability, UncertaintyOptions};
use jointfit::calibrate::varpro::{solve_varpro_observed, VarProOptions};
use jointfit::calibrate::{params_for_groups, CalibError, Problem};
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, Unit};
use jointfit::trial::Trial;
use serde::{Deserialize, Serialize};

/// The outer optimizer (as `jointfit calibrate --method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Joint sparse Levenberg–Marquardt over all frames and parameters.
    Joint,
    /// Two-level Gauss–Newton on the reduced (variable-projection) Jacobian.
    Gradient,
    /// Particle swarm (global), then polished by the joint solver.
    Pso,
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "joint" => Ok(Method::Joint),
            "gradient" => Ok(Method::Gradient),
            "pso" => Ok(Method::Pso),
            _ => Err(format!(
                "unknown method {s:?} (expected joint, gradient or pso)"
            )),
        }
    }
}

/// Settings of one calibration (the command line's defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Parameter groups to fit (`hip`, `knee`, `ankle`, `all`).
    pub joints: Vec<String>,
    pub method: Method,
    /// Seed of the particle swarm and of the bootstrap.
    pub seed: u64,
    /// Length parameters whose 95 % half-width exceeds this are flagged (mm).
    pub threshold_mm: f64,
    /// Angle parameters whose 95 % half-width exceeds this are flagged (deg).
    pub threshold_deg: f64,
    /// Moving-block bootstrap replicates of the intervals (0: none).
    pub bootstrap: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            joints: vec!["all".into()],
            method: Method::Joint,
            seed: 1,
            threshold_mm: 5.0,
            threshold_deg: 5.0,
            bootstrap: 0,
        }
    }
}

/// One free parameter of a calibration, SI units (m or rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamRow {
    pub name: String,
    pub group: String,
    /// `m` or `rad`.
    pub unit: String,
    pub start: f64,
    pub fitted: f64,
    /// Standard error; `None` when the trials do not determine the parameter.
    pub se: Option<f64>,
    /// 95 % interval `[low, high]`.
    pub ci95: Option<[f64; 2]>,
    pub identifiability: Option<Identifiability>,
}

/// The result of [`calibrate`]: the fitted model and what a results table needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// The fitted model description (its nominal parameters are the fitted values).
    pub model: ModelSpec,
    pub method: Method,
    pub frames: usize,
    pub skipped_frames: usize,
    /// The free parameters, in model order.
    pub parameters: Vec<ParamRow>,
    /// RMS marker distance over all present samples at the start and at the optimum (m).
    pub rms_before: f64,
    pub rms_after: f64,
    /// Objective `e_inner` (m²) at the start and at the optimum.
    pub cost_before: f64,
    pub cost_after: f64,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    /// Reading and fitting warnings, one line each.
    pub warnings: Vec<String>,
}

/// Fits the `opts.joints` parameters of `model` to `trials`, starting from `start`.
pub fn calibrate(
    model: &Model,
    start: Vec<f64>,
    trials: &[&Trial],
    opts: &FitOptions,
) -> Result<Calibration, CalibError> {
    let groups: Vec<&str> = opts.joints.iter().map(String::as_str).collect();
    let free = params_for_groups(model, &groups)?;
    let prob = Problem::new(model, start.clone(), &free, trials)?;
    let q0 = prob.initial_coords(&start);
    let s0 = prob.to_scaled(&start);
    let mut ws = jointfit::ik::IkWorkspace::new(model);
    let mut q_before = q0.clone();
    let cost_before = prob.inner(&start, &mut q_before, &mut ws);
    let fit = match opts.method {
        Method::Joint => solve_joint_observed(&prob, &s0, q0, &JointOptions::default(), |_, _| {}),
        Method::Gradient => {
            solve_varpro_observed(&prob, &s0, q0, &VarProOptions::default(), |_, _| {})
        }
        Method::Pso => {
            let pso = PsoOptions {
                seed: opts.seed,
                ..PsoOptions::default()
            };
            let swarm = solve_pso(&prob, &q0, &pso, |_, _| {});
            let mut polished = solve_joint_observed(
                &prob,
                &swarm.s,
                swarm.coords.clone(),
                &JointOptions::default(),
                |_, _| {},
            );
            polished.iterations += swarm.iterations;
            polished.evaluations += swarm.evaluations;
            polished
        }
    };
    let uopts = UncertaintyOptions {
        threshold_m: opts.threshold_mm / 1e3,
        threshold_rad: opts.threshold_deg.to_radians(),
        bootstrap_replicates: opts.bootstrap,
        seed: opts.seed,
        ..UncertaintyOptions::default()
    };
    let u = analyze(&prob, &fit, &uopts);
    let mut warnings = Vec::new();
    for pu in u.flagged() {
        let hw = pu
            .half_width
            .map_or("unbounded".to_string(), |h| format!("±{h:.1} {}", pu.unit));
        warnings.push(format!(
            "{} {} by these trials ({hw}){}",
            pu.name,
            if pu.status == Identifiability::Undetermined {
                "not determined"
            } else {
                "poorly determined"
            },
            pu.reason
                .as_deref()
                .map_or(String::new(), |r| format!(": {r}"))
        ));
    }
    if !fit.converged {
        warnings.push("the outer solver stopped before converging".into());
    }
    let parameters = prob
        .free
        .iter()
        .zip(&u.params)
        .map(|(&i, pu)| {
            let par = &model.parameters()[i];
            // The uncertainty rows are in display units (mm, deg): back to SI.
            let (unit, to_si) = match par.unit {
                Unit::Metre => ("m", 1e-3),
                Unit::Radian => ("rad", std::f64::consts::PI / 180.0),
            };
            ParamRow {
                name: par.name.clone(),
                group: par.group.clone(),
                unit: unit.into(),
                start: start[i],
                fitted: fit.p[i],
                se: pu.se.map(|v| v * to_si),
                ci95: pu.ci.map(|[lo, hi]| [lo * to_si, hi * to_si]),
                identifiability: Some(pu.status),
            }
        })
        .collect();
    let mut fitted = model.spec_with_nominal(&fit.p);
    fitted.name = format!("{} (fitted)", model.spec().name);
    Ok(Calibration {
        model: fitted,
        method: opts.method,
        frames: prob.frames.len(),
        skipped_frames: prob.skipped.len(),
        parameters,
        rms_before: prob.marker_rms(&start, &q_before),
        rms_after: prob.marker_rms(&fit.p, &fit.coords),
        cost_before,
        cost_after: fit.cost,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        converged: fit.converged,
        warnings,
    })
}
