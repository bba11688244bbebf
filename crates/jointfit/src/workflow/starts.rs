//! Several starts: seeded start points ([`restart_point`], [`perturb`]), every start run to
//! convergence ([`full_starts`], `FitSettings::starts` > 1) and the summary of the optima
//! they reached ([`multi_start_summary`]).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::calibration::{ConvergenceStage, MultiStart, StartRun};
use super::{FitSettings, Method, Observer, Termination};
use crate::calibrate::joint::{solve_joint, JointOptions};
use crate::calibrate::pso::{solve_pso, PsoOptions};
use crate::calibrate::varpro::{solve_varpro, VarProOptions};
use crate::calibrate::{Fit, Problem};
use crate::ik::lm::IkWorkspace;
use crate::model::spec::Unit;
use crate::model::Model;

/// Every start of `settings` run to convergence, in order (`starts` ≥ 1: the given start,
/// then [`restart_point`]s); with the given start's inner solutions and objective.
pub(super) fn full_starts(
    prob: &Problem,
    start: &[f64],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> (Vec<Fit>, Vec<StartRun>, Vec<Vec<f64>>, f64) {
    let model = prob.model;
    let mut ws = IkWorkspace::new(model);
    let mut q_before = Vec::new();
    let mut cost_before = f64::NAN;
    let starts = settings.effective_starts();
    let mut fits = Vec::with_capacity(starts);
    let mut runs = Vec::with_capacity(starts);
    for k in 0..starts {
        observer.progress(k, starts);
        let p0 = if k == 0 {
            start.to_vec()
        } else {
            restart_point(
                model,
                start,
                &prob.free,
                settings.restart_m,
                settings.restart_rad,
                settings.seed,
                k,
            )
        };
        // The solver starts from the seeded inner solutions; the objective there is one
        // more inner pass (which only polishes them; it includes the prior term).
        let q0 = prob.initial_coords(&p0);
        let mut q = q0.clone();
        let cost0 = prob.inner(&p0, &mut q, &mut ws);
        if k == 0 {
            (q_before, cost_before) = (q, cost0);
        }
        let label = |stage: &str| {
            if starts == 1 {
                stage.to_string()
            } else {
                format!("start {} of {starts}: {stage}", k + 1)
            }
        };
        let mut rec = Recorder {
            inner: &mut *observer,
            stages: Vec::new(),
        };
        let fit = run_start(prob, &p0, q0, cost0, settings, &label, &mut rec);
        runs.push(StartRun {
            start: k,
            objective: fit.cost,
            iterations: fit.iterations,
            evaluations: fit.evaluations,
            termination: fit.termination,
            convergence: rec.stages,
        });
        fits.push(fit);
    }
    observer.progress(starts, starts);
    (fits, runs, q_before, cost_before)
}

/// The optima of several starts: objectives, how many reached the best, spread per parameter.
pub(super) fn multi_start_summary(prob: &Problem, fits: &[Fit], best: usize) -> MultiStart {
    let best_cost = fits[best].cost;
    let spread = prob
        .free
        .iter()
        .map(|&i| {
            let par = &prob.model.parameters()[i];
            let (lo, hi) = fits
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
                    (lo.min(f.p[i]), hi.max(f.p[i]))
                });
            (par.name.clone(), hi - lo)
        })
        .collect();
    MultiStart {
        starts: fits.len(),
        objective: fits.iter().map(|f| f.cost).collect(),
        reached_best: fits
            .iter()
            .filter(|f| f.cost - best_cost <= 1e-9 * best_cost)
            .count(),
        spread,
    }
}

/// Start `k` (≥ 1) of a multi-start fit: [`perturb`] of `start` with a seed derived from the
/// run's `seed` and `k`, so every start of every run is reproducible and distinct.
/// The moves reach `span_m` metres for positions and `span_rad` radians for orientations.
pub(crate) fn restart_point(
    model: &Model,
    start: &[f64],
    free: &[usize],
    span_m: f64,
    span_rad: f64,
    seed: u64,
    k: usize,
) -> Vec<f64> {
    let k_seed = seed.wrapping_mul(1_000_003).wrapping_add(k as u64);
    perturb_by(model, start, free, (span_m, span_rad), k_seed)
}

/// Parameters `base` with the `free` ones (indices) moved by independent uniform amounts,
/// up to `mm` millimetres for positions and `deg` degrees for orientations, clamped into the
/// bounds; seeded (ChaCha8). The paper's "perturbed start".
pub fn perturb(
    model: &Model,
    base: &[f64],
    free: &[usize],
    mm: f64,
    deg: f64,
    seed: u64,
) -> Vec<f64> {
    let spans = (mm * crate::model::spec::M_PER_MM, deg.to_radians());
    perturb_by(model, base, free, spans, seed)
}

/// [`perturb`] by up to `span_m` metres and `span_rad` radians.
fn perturb_by(
    model: &Model,
    base: &[f64],
    free: &[usize],
    (span_m, span_rad): (f64, f64),
    seed: u64,
) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = base.to_vec();
    for &i in free {
        let par = &model.parameters()[i];
        let span = match par.unit {
            Unit::Metre => span_m,
            Unit::Radian => span_rad,
        };
        let d = if span > 0.0 {
            rng.gen_range(-span..=span)
        } else {
            0.0
        };
        p[i] = (p[i] + d).clamp(par.lower, par.upper);
    }
    p
}

/// Forwards to the caller's observer and records the objective per stage.
pub(super) struct Recorder<'o> {
    pub(super) inner: &'o mut dyn Observer,
    pub(super) stages: Vec<ConvergenceStage>,
}

impl Recorder<'_> {
    /// Starts stage `stage` (shown to the observer as `label`); `first` is its starting
    /// objective when known (recorded as iteration 0).
    fn begin(&mut self, stage: &str, label: &str, budget: Option<usize>, first: Option<f64>) {
        self.inner.stage_started(label, budget);
        self.stages.push(ConvergenceStage {
            stage: stage.to_string(),
            objective: Vec::new(),
        });
        if let Some(c) = first {
            self.iteration(0, c);
        }
    }
}

impl Observer for Recorder<'_> {
    fn iteration(&mut self, iteration: usize, objective: f64) {
        if let Some(s) = self.stages.last_mut() {
            s.objective.push(objective);
        }
        self.inner.iteration(iteration, objective);
    }
    fn stage_ended(&mut self, termination: Termination) {
        self.inner.stage_ended(termination);
    }
}

/// One start: the method's solver(s) from parameters `p0` and coordinates `q0`, where the
/// objective is `cost0`.
pub(super) fn run_start(
    prob: &Problem,
    p0: &[f64],
    q0: Vec<Vec<f64>>,
    cost0: f64,
    settings: &FitSettings,
    label: &dyn Fn(&str) -> String,
    rec: &mut Recorder,
) -> Fit {
    let s0 = prob.to_scaled(p0);
    let cost0 = Some(cost0);
    let joint = JointOptions {
        max_iterations: settings
            .max_iterations
            .unwrap_or(JointOptions::default().max_iterations),
        ..JointOptions::default()
    };
    let varpro = VarProOptions {
        max_iterations: settings
            .max_iterations
            .unwrap_or(VarProOptions::default().max_iterations),
        ..VarProOptions::default()
    };
    let fit = match settings.method {
        Method::Joint => {
            let stage = "joint Levenberg-Marquardt";
            rec.begin(stage, &label(stage), None, cost0);
            solve_joint(prob, &s0, q0, &joint, rec)
        }
        Method::Gradient => {
            let stage = "two-level Gauss-Newton";
            rec.begin(stage, &label(stage), None, cost0);
            solve_varpro(prob, &s0, q0, &varpro, rec)
        }
        Method::Pso => {
            let opts = PsoOptions {
                seed: settings.seed,
                ..PsoOptions::default()
            };
            // The swarm usually runs to its budget.
            let stage = "particle swarm";
            rec.begin(stage, &label(stage), Some(opts.max_iterations), None);
            let swarm = solve_pso(prob, &q0, &opts, rec);
            rec.stage_ended(swarm.termination);
            let stage = "joint Levenberg-Marquardt polish";
            rec.begin(stage, &label(stage), None, Some(swarm.cost));
            let mut polished = solve_joint(prob, &swarm.s, swarm.coords.clone(), &joint, rec);
            polished.iterations += swarm.iterations;
            polished.evaluations += swarm.evaluations;
            polished
        }
    };
    rec.stage_ended(fit.termination);
    fit
}
