//! The calibration `jointfit bench` times: what `jointfit calibrate SUBJECT TRIAL -o OUT`
//! runs with no options ([`workflow::refine::calibrate_refined`] with
//! `jointfit_app::FitOptions::default().settings()`), and where its time goes (`--fit-only`).

use std::time::Instant;

use anyhow::Result;
use jointfit::calibrate::params_for_groups;
use jointfit::model::{Model, ParamId};
use jointfit::solver::Observer;
use jointfit::solver::Termination;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::UNCERTAINTY_STAGE;
use jointfit::workflow::refine::{calibrate_refined, RefinedCalibration};
use jointfit::workflow::{marker_policy, FitSettings, Method};

/// The command's default calibration of `free` (with `method`: `calibrate --method M`).
pub fn command_fit(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    free: &[ParamId],
    method: Method,
    observer: &mut dyn Observer,
) -> Result<RefinedCalibration> {
    let settings = FitSettings {
        method,
        ..jointfit_app::FitOptions::default().settings()
    };
    Ok(calibrate_refined(
        model,
        p,
        &[trial],
        free,
        &settings,
        observer,
    )?)
}

/// What ended, seconds since the start of the calibration, in order.
type Marks = Vec<(&'static str, f64)>;

/// Marks the phases of one calibration from the workflow's observer hooks: the global
/// phase's `progress(0, n + 1)`, `progress(n, n + 1)` (probes done) and
/// `progress(n + 1, n + 1)` (finishing solves done), and the uncertainty stage.
struct PhaseClock {
    t0: Instant,
    /// (what ended, seconds since `t0`), in order.
    marks: Marks,
    in_uncertainty: bool,
}

impl PhaseClock {
    fn mark(&mut self, what: &'static str) {
        self.marks.push((what, self.t0.elapsed().as_secs_f64()));
    }
}

impl Observer for PhaseClock {
    fn progress(&mut self, done: usize, total: usize) {
        let rounds = self
            .marks
            .iter()
            .filter(|m| m.0.starts_with("policy"))
            .count();
        match (done, rounds) {
            (0, 0) => self.mark("policy IK, start's inner solutions, starting σ₀"),
            (0, _) => self.mark("fit, table, envelope check (→ bounded refit: σ estimate)"),
            (d, _) if d + 1 == total => self.mark("global phase: probes"),
            (d, _) if d == total => {
                self.mark("global phase: finishing solve(s) (σ₀-optimum, σ estimate, final)")
            }
            _ => {}
        }
    }
    fn stage_started(&mut self, stage: &str, _budget: Option<usize>) {
        if stage.starts_with(UNCERTAINTY_STAGE) {
            self.mark("marker RMS, table, reduced system, conflict test, envelope check");
            self.in_uncertainty = true;
        }
    }
    fn stage_ended(&mut self, _termination: Termination) {
        if self.in_uncertainty {
            self.mark("uncertainty analysis");
            self.in_uncertainty = false;
        }
    }
}

/// `--fit-only N`: the command's default calibration of all parameters of the workload `n`
/// times, each wall time, where the time of the fastest went, and the fastest.
pub fn fit_only(model: &Model, p: &[f64], trial: &Trial, source: &str, n: usize) -> Result<()> {
    let all = params_for_groups(model, &["all"])?;
    println!("workload: {source} ({} frames)", trial.n_frames());
    println!(
        "timed: workflow::refine::calibrate_refined, jointfit_app::FitOptions::default().settings() \
         (= jointfit calibrate SUBJECT TRIAL -o OUT)"
    );
    // (total s, the phase marks, the policy's IK alone s) of the fastest run.
    let mut best: Option<(f64, Marks, f64)> = None;
    for _ in 0..n {
        // The marker policy's own IK, timed alone (it runs first inside the calibration).
        let t = Instant::now();
        let decisions = marker_policy::decide(model, p, &[trial], &[]);
        let policy = t.elapsed().as_secs_f64();
        std::hint::black_box(decisions);
        let mut clock = PhaseClock {
            t0: Instant::now(),
            marks: Vec::new(),
            in_uncertainty: false,
        };
        let cal = command_fit(model, p, trial, &all, Method::Joint, &mut clock)?;
        let total = clock.t0.elapsed().as_secs_f64();
        clock.mark("marker trade-offs, verdict, fitted model");
        let c = &cal.calibration;
        println!(
            "calibrate 27, joint (command default): {:.1} ms ({} iterations, all starts {}, \
             cost {:.6} mm², {} marker decisions, envelope {})",
            total * 1e3,
            c.iterations,
            c.start_runs.iter().map(|r| r.iterations).sum::<usize>(),
            c.cost_after * 1e6,
            cal.marker_decisions.len(),
            match cal.envelope.iter().any(|b| b.unbounded_fit.is_some()) {
                true => "refit",
                false => "inside",
            }
        );
        if best.as_ref().is_none_or(|b| total < b.0) {
            best = Some((total, clock.marks, policy));
        }
    }
    let Some((total, marks, policy)) = best else {
        return Ok(());
    };
    println!(
        "fastest of {n}: {:.1} ms; where its time went:",
        total * 1e3
    );
    let mut last = 0.0;
    for (what, t) in marks {
        println!("  {:7.2} ms  {what}", (t - last) * 1e3);
        last = t;
    }
    println!(
        "  (the marker policy's IK alone, timed before that run: {:.2} ms)",
        policy * 1e3
    );
    Ok(())
}
