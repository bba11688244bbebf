//! The default calibration reaches the global optimum on the hard synthetic cases
//! (`jointfit synth lower-limb-right --motion all|ankle --noise skin --perturb-mm 30
//! --perturb-deg 15 --seed S`), with the objective at the true parameters as the oracle:
//! the global optimum of a noisy trial lies at or below it.

use jointfit::calibrate::params_for_groups;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::marker_rms::marker_rms;
use jointfit::workflow::{perturb, FitSettings};
use jointfit_experiments::synth::{coordinates_scaled, synthesize, Motion, Noise};

/// The synthetic case of `seed` and the objective at its true parameters.
fn case(model: &Model, motion: Motion, seed: u64) -> (Trial, f64) {
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let nominal = model.nominal_params();
    let truth = perturb(model, &nominal, &all, 30.0, 15.0, seed);
    let coords = coordinates_scaled(model, motion, 50, 1.0).unwrap();
    let (trial, _) = synthesize(model, &truth, &coords, 10.0, &Noise::skin(seed));
    let at_truth = marker_rms(model, &truth, &[&trial]).unwrap().cost;
    (trial, at_truth)
}

fn fit(model: &Model, trial: &Trial, settings: &FitSettings) -> Calibration {
    let free = params_for_groups(model, &["all"]).unwrap();
    calibrate(
        model,
        &model.nominal_params(),
        &[trial],
        &free,
        settings,
        &mut NoObserver,
    )
    .unwrap()
}

#[test]
fn default_reaches_the_objective_at_the_truth() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let local = FitSettings {
        probes: 0,
        ..FitSettings::default()
    };
    for (motion, seed) in [
        (Motion::All, 7401),
        (Motion::All, 7420),
        (Motion::All, 7425),
        (Motion::Ankle, 7401),
    ] {
        let (trial, at_truth) = case(&model, motion, seed);
        let cal = fit(&model, &trial, &FitSettings::default());
        assert!(
            cal.cost_after <= 1.005 * at_truth,
            "{motion:?} {seed}: {} above the truth's {at_truth}",
            cal.cost_after
        );
        let g = cal.global.as_ref().expect("the default probes");
        assert_eq!(g.starts, FitSettings::default().probes + 1);
        assert_eq!(cal.global_warning.is_some(), !g.agree);
        // The paper's single local fit is the baseline the global phase must not lose to.
        let one = fit(&model, &trial, &local);
        assert!(one.global.is_none());
        assert!(cal.cost_after <= one.cost_after * (1.0 + 1e-9));
        if motion == Motion::All && seed != 7425 {
            // The cases where one start stops in a local minimum (3–5 % above the truth).
            assert!(
                one.cost_after > 1.02 * at_truth,
                "{seed}: {}",
                one.cost_after
            );
        }
    }
}

#[test]
fn global_phase_is_deterministic_whatever_the_threads() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let (trial, _) = case(&model, Motion::All, 7420);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| fit(&model, &trial, &FitSettings::default()))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.fit.p, b.fit.p);
    assert_eq!(a.cost_after, b.cost_after);
    assert_eq!(a.global, b.global);
    let other = fit(
        &model,
        &trial,
        &FitSettings {
            seed: 2,
            ..FitSettings::default()
        },
    );
    assert_ne!(
        other.global.unwrap().probe_objective,
        a.global.unwrap().probe_objective,
        "the seed draws the starts"
    );
}

/// The swarm on the noiseless ankle case, as run with the CLI
/// (`jointfit synth lower-limb-right --motion ankle --noise none --perturb-mm 30
/// --perturb-deg 15 --seed 7316`, the true model with its ankle reset to nominal as the start,
/// `calibrate --method pso --seed 7316 --joints J`), reaches the objective at the truth (0, the
/// oracle, evaluated by the inner problem) with the ankle at the truth and no free parameter at
/// a bound. `J` = the fitted groups; returns the swarm's own iterations.
fn swarm_on_the_noiseless_ankle(groups: &str) -> usize {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let nominal = model.nominal_params();
    let seed = 7316;
    let truth = perturb(&model, &nominal, &all, 30.0, 15.0, seed);
    let coords = coordinates_scaled(&model, Motion::Ankle, 50, 1.0).unwrap();
    let (trial, _) = synthesize(&model, &truth, &coords, 10.0, &Noise::none());
    let free = params_for_groups(&model, &[groups]).unwrap();
    let ankle = params_for_groups(&model, &["ankle"]).unwrap();
    let mut start = truth.clone();
    for id in &ankle {
        start[id.0] = nominal[id.0];
    }
    let at_truth = marker_rms(&model, &truth, &[&trial]).unwrap().cost;
    assert!(at_truth < 1e-20, "noiseless: {at_truth:e}");
    let settings = FitSettings {
        method: jointfit::workflow::Method::Pso,
        seed,
        ..FitSettings::default()
    };
    let cal = calibrate(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap();
    assert!(cal.converged);
    assert!(cal.cost_after <= at_truth + 1e-14, "{:e}", cal.cost_after);
    assert!(cal.rms_after < 1e-7, "{} m", cal.rms_after);
    for id in &free {
        let par = &model.parameters()[id.0];
        let v = cal.fit.p[id.0];
        let margin = 1e-3 * (par.upper - par.lower);
        assert!(
            v > par.lower + margin && v < par.upper - margin,
            "{} at a bound",
            par.name
        );
    }
    for id in &ankle {
        let v = cal.fit.p[id.0];
        let name = &model.parameters()[id.0].name;
        assert!((v - truth[id.0]).abs() < 1e-6, "{name}");
    }
    assert_eq!(cal.convergence[0].stage, "particle swarm");
    cal.convergence[0].objective.len() - 1
}

#[test]
fn swarm_finds_the_noiseless_ankle() {
    swarm_on_the_noiseless_ankle("ankle");
}

/// The same case with the CLI's default `--joints all` (27 free, of which an ankle motion
/// determines only the ankle's twelve): the swarm's own best stays far above 0 (the
/// undetermined hip and knee directions keep its particles spread, so it runs to its limit),
/// and its polished minimum is the truth's objective, none at a bound (`docs/global.md`,
/// "The stuck at bounds swarm").
#[test]
fn swarm_finds_the_noiseless_ankle_with_every_parameter_free() {
    let iterations = swarm_on_the_noiseless_ankle("all");
    assert!(iterations >= 100, "{iterations}");
}

/// The swarm on the noisy hip (`--motion hip --noise skin`, 50 frames,
/// seed 7317, the hip reset to nominal) stops on its basin test long before its iteration
/// limit, gives the same numbers on one and two threads, and ends in the minimum that the
/// joint solver reaches from the true parameters (the oracle: the trial's optimum near the
/// truth), with no parameter at a bound.
#[test]
fn swarm_on_the_noisy_hip_stops_in_the_minimum_near_the_truth_whatever_the_threads() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let nominal = model.nominal_params();
    let seed = 7317;
    let truth = perturb(&model, &nominal, &all, 30.0, 15.0, seed);
    let coords = coordinates_scaled(&model, Motion::Hip, 50, 1.0).unwrap();
    let (trial, _) = synthesize(&model, &truth, &coords, 10.0, &Noise::skin(seed));
    let free = params_for_groups(&model, &["hip"]).unwrap();
    let mut start = truth.clone();
    for id in &free {
        start[id.0] = nominal[id.0];
    }
    let settings = |method| FitSettings {
        method,
        seed,
        uncertainty: None,
        ..FitSettings::default()
    };
    let run = |threads: usize| {
        let mut budget = SwarmBudget(None);
        let cal = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                calibrate(
                    &model,
                    &start,
                    &[&trial],
                    &free,
                    &settings(jointfit::workflow::Method::Pso),
                    &mut budget,
                )
                .unwrap()
            });
        (cal, budget.0)
    };
    let ((a, limit), (b, _)) = (run(1), run(2));
    assert_eq!(a.fit.p, b.fit.p);
    assert_eq!(a.cost_after, b.cost_after);
    let swarm = &a.convergence[0];
    assert_eq!(swarm.stage, "particle swarm");
    let limit = limit.expect("the swarm announces its iteration budget");
    assert!(
        swarm.objective.len() < limit / 2,
        "swarm iterations {}",
        swarm.objective.len()
    );
    let from_truth = calibrate(
        &model,
        &truth,
        &[&trial],
        &free,
        &FitSettings {
            probes: 0,
            ..settings(jointfit::workflow::Method::Joint)
        },
        &mut NoObserver,
    )
    .unwrap();
    let excess = a.cost_after / from_truth.cost_after - 1.0;
    assert!(excess < 1e-9, "swarm minimum above the truth's: {excess:e}");
    for id in &free {
        let par = &model.parameters()[id.0];
        let v = a.fit.p[id.0];
        let margin = 1e-3 * (par.upper - par.lower);
        assert!(
            v > par.lower + margin && v < par.upper - margin,
            "{}",
            par.name
        );
    }
}

/// The iteration budget the particle swarm announces to the observer.
struct SwarmBudget(Option<usize>);

impl jointfit::solver::Observer for SwarmBudget {
    fn stage_started(&mut self, stage: &str, budget: Option<usize>) {
        if stage.contains("particle swarm") {
            self.0 = budget;
        }
    }
}
