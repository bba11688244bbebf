//! Does the default calibration reach the global optimum?
//!
//! For each case of `jointfit synth lower-limb-right --motion M --noise skin --perturb-mm 30
//! --perturb-deg 15 --seed S` (50 frames at 10 Hz, skin artifact up to 1 cm), fits all 27
//! parameters from the nominal model with the default settings of [`FitSettings`] and prints
//! the final objective against the objective at the true parameters (`e_inner(truth)`, the
//! inner problem solved at the truth), the time, and whether the fit warned that it is not
//! known to be the global optimum.
//!
//! ```text
//! cargo run --release -p jointfit-experiments --example global_optimum -- \
//!     [--starts N] [--probes N] [--probe-iterations N] [--motion all,ankle] \
//!     [--seeds 7401,7420,7425]
//! ```

use std::time::Instant;

use jointfit::calibrate::params_for_groups;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::{perturb, FitSettings};
use jointfit_experiments::synth::{coordinates_scaled, synthesize, Motion, Noise, SkinNoise};

fn main() {
    let (settings, motions, seeds) = options();
    let model = Model::compile(&lower_limb(Side::Right)).expect("built-in model compiles");
    println!(
        "{:<6} {:>5} {:>14} {:>14} {:>9} {:>8} {:>7} {:>8}",
        "motion", "seed", "fit (mm²)", "truth (mm²)", "excess", "starts", "warn", "ms"
    );
    let mut worst: f64 = f64::NEG_INFINITY;
    for &motion in &motions {
        for &seed in &seeds {
            let cal = fit_case(&model, &settings, motion, seed, &mut worst);
            if std::env::var("TRACE").is_ok() {
                trace(&cal);
            }
        }
    }
    println!(
        "worst excess over the objective at the truth: {:.2} %",
        100.0 * worst
    );
}

/// The fit settings, motions and seeds of the command line (and `PROBE_FRAMES`).
fn options() -> (FitSettings, Vec<Motion>, Vec<u64>) {
    let mut starts = None;
    let mut probes = None;
    let mut probe_iterations = None;
    let mut motions = vec![Motion::All, Motion::Ankle];
    let mut seeds = vec![7401u64, 7420, 7425];
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().unwrap_or_default();
        match flag.as_str() {
            "--starts" => starts = Some(v.parse().expect("--starts N")),
            "--probes" => probes = Some(v.parse().expect("--probes N")),
            "--probe-iterations" => {
                probe_iterations = Some(v.parse().expect("--probe-iterations N"))
            }
            "--motion" => {
                motions = v
                    .split(',')
                    .map(|m| m.parse().expect("--motion hip|knee|ankle|all"))
                    .collect()
            }
            "--seeds" => {
                seeds = v
                    .split(',')
                    .map(|s| s.parse().expect("--seeds N,N"))
                    .collect()
            }
            _ => {
                eprintln!("global_optimum: unknown option {flag}");
                std::process::exit(2);
            }
        }
    }
    let mut settings = FitSettings::default();
    if let Some(s) = starts {
        settings.starts = s;
    }
    if let Some(n) = probes {
        settings.probes = n;
    }
    if let Ok(n) = std::env::var("PROBE_FRAMES") {
        settings.probe_frames = n.parse().expect("PROBE_FRAMES");
    }
    if let Some(n) = probe_iterations {
        settings.probe_iterations = n;
    }
    (settings, motions, seeds)
}

/// One case: the synthetic trial of `motion` and `seed`, the default fit from the nominal
/// model, and a row comparing its objective with the objective at the truth (the largest
/// relative excess so far in `worst`).
fn fit_case(
    model: &Model,
    settings: &FitSettings,
    motion: Motion,
    seed: u64,
    worst: &mut f64,
) -> Calibration {
    let free = params_for_groups(model, &["all"]).expect("all");
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let nominal = model.nominal_params();
    let truth = perturb(model, &nominal, &all, 30.0, 15.0, seed);
    let coords = coordinates_scaled(model, motion, 50, 1.0).expect("motion");
    let noise = Noise {
        skin: Some(SkinNoise {
            seed,
            ..SkinNoise::default()
        }),
        white: None,
    };
    let (trial, _) = synthesize(model, &truth, &coords, 10.0, &noise);
    let at_truth = jointfit::workflow::marker_rms::marker_rms(model, &truth, &[&trial])
        .expect("problem")
        .cost;
    let clock = Instant::now();
    let cal = calibrate(model, &nominal, &[&trial], &free, settings, &mut NoObserver)
        .expect("calibration");
    let ms = clock.elapsed().as_secs_f64() * 1e3;
    let excess = cal.cost_after / at_truth - 1.0;
    *worst = worst.max(excess);
    println!(
        "{:<6} {:>5} {:>14.3} {:>14.3} {:>8.2}% {:>8} {:>7} {:>8.1}",
        format!("{motion:?}").to_lowercase(),
        seed,
        cal.cost_after * 1e6,
        at_truth * 1e6,
        100.0 * excess,
        cal.start_runs.len(),
        cal.global_warning.is_some(),
        ms
    );
    cal
}

/// With `TRACE` set: the global phase's probes, or each start's convergence.
fn trace(cal: &Calibration) {
    if let Some(g) = &cal.global {
        println!(
            "   probes {:?}\n   finished {:?} {:?}",
            g.probe_objective
                .iter()
                .map(|c| (c * 1e6).round())
                .collect::<Vec<_>>(),
            g.finished,
            g.finished_objective
                .iter()
                .map(|c| c * 1e6)
                .collect::<Vec<_>>()
        );
    }
    if cal.global.is_none() {
        for r in &cal.start_runs {
            let h = &r.convergence[0].objective;
            let at = |i: usize| h.get(i).or(h.last()).map_or(f64::NAN, |c| c * 1e6);
            println!(
                "   start {:>2}: it {:>3} final {:>10.1}  @2 {:>10.1} @4 {:>10.1} @6 {:>10.1} @10 {:>10.1}",
                r.start, r.iterations, r.objective * 1e6, at(2), at(4), at(6), at(10)
            );
        }
    }
}
