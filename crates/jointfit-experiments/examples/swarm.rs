//! The particle swarm on the hard noiseless and noisy cases (see `docs/global.md`).
//!
//! * **ankle, noiseless**: `jointfit synth lower-limb-right --motion ankle --noise
//!   none --perturb-mm 30 --perturb-deg 15 --seed S`, the true model with its ankle reset to
//!   nominal as the start, `calibrate --joints ankle --method pso --seed S`. The global
//!   optimum is the truth (objective 0).
//! * **hip, noisy**: the same with `--motion hip --noise skin`, `--joints hip`.
//!
//! Prints the swarm's and the polished objective, how many fitted parameters ended at a
//! bound, the largest error against the truth, the iterations and the time.
//!
//! ```text
//! cargo run --release -p jointfit-experiments --example swarm -- [--seeds 7316,7317] \
//!     [--case ankle|hip]
//! ```

use std::time::Instant;

use jointfit::calibrate::params_for_groups;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::spec::Unit;
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::{perturb, FitSettings, Method};
use jointfit_experiments::synth::{coordinates_scaled, synthesize, Motion, Noise};

fn main() {
    let mut seeds = vec![7316u64];
    let mut cases = vec!["ankle".to_string(), "hip".to_string()];
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().unwrap_or_default();
        match flag.as_str() {
            "--seeds" => {
                seeds = v
                    .split(',')
                    .map(|s| s.parse().expect("--seeds N,N"))
                    .collect()
            }
            "--case" => cases = v.split(',').map(str::to_string).collect(),
            _ => {
                eprintln!("swarm: unknown option {flag}");
                std::process::exit(2);
            }
        }
    }
    let model = Model::compile(&lower_limb(Side::Right)).expect("built-in model compiles");
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let nominal = model.nominal_params();
    println!(
        "{:<6} {:>5} {:>12} {:>12} {:>9} {:>10} {:>7} {:>8}",
        "case", "seed", "swarm mm²", "polish mm²", "at bound", "max error", "iters", "ms"
    );
    for case in &cases {
        let (motion, noise_on) = match case.as_str() {
            "ankle" | "ankle-all" => (Motion::Ankle, false),
            "hip" => (Motion::Hip, true),
            _ => panic!("--case ankle|hip"),
        };
        let groups = if case == "ankle-all" {
            "all"
        } else {
            case.as_str()
        };
        let free = params_for_groups(&model, &[groups]).expect("group");
        // The joint fitted starts at nominal (ankle-all: the ankle; the rest at the truth).
        let reset = params_for_groups(&model, &[if case == "hip" { "hip" } else { "ankle" }])
            .expect("group");
        for &seed in &seeds {
            let truth = perturb(&model, &nominal, &all, 30.0, 15.0, seed);
            let coords = coordinates_scaled(&model, motion, 50, 1.0).expect("motion");
            let noise = if noise_on {
                Noise::skin(seed)
            } else {
                Noise::none()
            };
            let (trial, _) = synthesize(&model, &truth, &coords, 10.0, &noise);
            let mut start = truth.clone();
            for id in &reset {
                start[id.0] = nominal[id.0];
            }
            let settings = FitSettings {
                method: Method::Pso,
                seed,
                ..FitSettings::default()
            };
            let clock = Instant::now();
            let cal = calibrate(&model, &start, &[&trial], &free, &settings, &mut NoObserver)
                .expect("calibration");
            let ms = clock.elapsed().as_secs_f64() * 1e3;
            let swarm = cal.convergence[0]
                .objective
                .last()
                .map_or(f64::NAN, |c| c * 1e6);
            let mut at_bound = 0;
            let mut max_err: f64 = 0.0;
            for id in &free {
                let par = &model.parameters()[id.0];
                let v = cal.fit.p[id.0];
                let tol = 1e-6 * (par.upper - par.lower);
                at_bound += (v - par.lower < tol || par.upper - v < tol) as usize;
                let e = (v - truth[id.0]).abs() * jointfit_experiments::units::scale(par.unit);
                max_err = max_err.max(match par.unit {
                    Unit::Metre => e,
                    Unit::Radian => e,
                });
            }
            println!(
                "{:<6} {:>5} {:>12.4} {:>12.6} {:>9} {:>10.3} {:>7} {:>8.0}",
                case,
                seed,
                swarm,
                cal.cost_after * 1e6,
                at_bound,
                max_err,
                cal.iterations,
                ms
            );
        }
    }
}
