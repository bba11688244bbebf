//! Monte Carlo check of the uncertainty intervals.
//!
//! For each seed: true parameters = nominal moved by up to 40 % of each half-range, a
//! synthetic trial of the chosen motion with skin-artifact noise (`A sin(ωt + φ)`, A up to
//! `--noise-mm`, ω up to 25 rad/s, Chèze et al. 1995), a joint fit of all 27 parameters from
//! the nominal model, and the uncertainty analysis, all through [`jointfit::workflow::calibrate`]
//! with its default settings (global phase included). Prints, per parameter group, how often
//! each estimator's 95 % interval contains the truth, the mean reported half-width against
//! the RMS error, and whether the flagged parameters are those with large errors.
//!
//! ```text
//! cargo run --release -p jointfit-experiments --example coverage -- \
//!     --seeds 50 --frames 100 --motion all --noise-mm 10 --replicates 0
//! ```
//!
//! Options: `--seeds`, `--first-seed`, `--frames`, `--motion hip|knee|ankle|all`,
//! `--noise-mm`, `--replicates` (block bootstrap; ~0.3 s per replicate at 100 frames),
//! `--blocks` (jackknife blocks), `--bandwidth` (HAC, frames), `--joints hip|knee|ankle|all`
//! (the free parameters), `--perturb MM,DEG` (truth = nominal moved by up to MM / DEG, as
//! `jointfit synth --perturb-mm --perturb-deg`, instead of 40 % of each half-range), `--dump
//! FILE.csv` (one row per seed and parameter: error, each estimator's standard error, the
//! critical values, bandwidth, label, the status half-width and correlation factor the label is
//! judged by, and the objective of the fit and at the truth, for offline checks of other
//! estimators and labels), `--prior` (the landmark priors of
//! `personalize` on every parameter, the truth drawn from them: `N(nominal, sd²)` clipped to
//! the bounds, and the default maximum a posteriori fit; coverage is then also tallied per
//! information label: determined by the trial / partly / held by the prior), `--default` (the
//! command's default entry point: the landmark priors in the model as `personalize` writes
//! them, and `workflow::refine::calibrate_refined` with the default settings, marker policy
//! and anatomical envelope included; the truth as without it; prints what the policy and the
//! envelope did), `--misplace-mm MM` (one thigh or shank marker, seeded, moved MM since the
//! static trial: the trial is synthesized with it moved), `--no-policy`, `--no-envelope`, `--no-conflict` (with `--default`), `--method joint|varpro|pso`, `--compare-none` (each trial also
//! fitted with `--prior none`; prints both fits' RMS parameter errors per joint),
//! `--landmark-error` (with `--default` or `--prior`: every fit starts from the subject's
//! landmark model, whose prior means are the truth moved by the landmark method's published
//! error, `N(truth, sd²)` seeded and clipped, as `personalize` would write it for this subject;
//! without it the prior mean and the start are the nominal model). Figures:
//! `docs/global.md` (coverage) and `docs/identifiability.md`.

mod args;
mod policy;

use std::io::Write;
use std::time::Instant;

use args::{misplaced, parse};
use policy::{Errors, Policy, GROUPS};

use jointfit::calibrate::prior::Source;
use jointfit::calibrate::uncertainty::{Identifiability, UncertaintyOptions};
use jointfit::calibrate::{params_for_groups, Problem};
use jointfit::ik::IkWorkspace;
use jointfit::landmarks::priors::fill_landmark_priors;
use jointfit::landmarks::HipCentreMethod;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::{Model, Unit};
use jointfit::workflow::refine::calibrate_refined;
use jointfit::workflow::{calibrate, perturb, FitSettings, NoObserver};
use jointfit_experiments::subject::landmark_model;
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, SkinNoise};

#[derive(Default, Clone)]
struct Tally {
    n: usize,
    white: usize,
    hac: usize,
    boot: usize,
    jack: usize,
    reported: usize,
    undetermined: usize,
    interior: usize,
    interior_hit: usize,
    determined: usize,
    determined_hit: usize,
    /// Per information label (determined by the trial, partly, held by the prior): (n, covered).
    source: [(usize, usize); 3],
    half_width: f64,
    sq_err: f64,
}

fn main() {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("coverage: {e}");
            std::process::exit(2);
        }
    };
    let mut spec = lower_limb(Side::Right);
    if args.prior || args.default {
        fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    }
    let model = Model::compile(&spec).expect("built-in model compiles");
    let coords = coordinates(&model, args.motion, args.frames).expect("built-in motion");
    let free =
        params_for_groups(&model, &[args.joints.as_str()]).expect("--joints hip|knee|ankle|all");
    let every: Vec<usize> = (0..model.n_p()).collect();
    let groups = GROUPS;
    let (mut err_fit, mut err_none, mut policy) =
        (Errors::default(), Errors::default(), Policy::default());
    let mut by_group = vec![Tally::default(); groups.len()];
    let (mut flagged_err, mut flagged_n, mut ok_err, mut ok_n) = (0.0, 0usize, 0.0, 0usize);
    let (mut big_err, mut big_flagged) = (0usize, 0usize);
    let mut per_param = vec![(0usize, 0usize, 0usize); free.len()];
    let clock = Instant::now();
    let mut bw_sum = 0.0;
    let mut global_warnings = 0usize;
    let mut conflicts = policy::Conflicts::default();
    let mut dump = args.dump.as_ref().map(|path| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("--dump file"));
        writeln!(
            f,
            "seed,name,group,unit,err,se_white,se_hac,se_jack,se_boot,z,t_jack,half_width,method,status,at_bound,bandwidth,frames,n_free,cost_fit,cost_truth,threshold,z_hac,data_share,source,status_half_width,correlation_factor"
        )
        .expect("write");
        f
    });
    for seed in args.first_seed..args.first_seed + args.seeds {
        let truth = match (args.prior, args.perturb) {
            (true, _) => model.sample_priors(seed),
            (false, Some((mm, deg))) => {
                perturb(&model, &model.nominal_params(), &every, mm, deg, seed)
            }
            (false, None) => perturbed_params(&model, 0.4, seed),
        };
        let noise = SkinNoise {
            max_amplitude: args.noise_mm / 1e3,
            seed: 10_000 + seed,
            ..SkinNoise::default()
        };
        let (true_spec, moved) = misplaced(&spec, args.misplace_mm, seed);
        let true_model = Model::compile(&true_spec).expect("built-in model compiles");
        let (trial, _) = markers(&true_model, &truth, &coords, 50.0, Some(&noise));
        // The fitted joints start at nominal (or, with `--landmark-error`, at the subject's
        // landmark model, which is also the prior mean); the others are held at the truth.
        let landmark = args.landmark_error.then(|| {
            let (s, means) = landmark_model(&spec, &truth, seed);
            (Model::compile(&s).expect("landmark model compiles"), means)
        });
        let fit_model = landmark.as_ref().map_or(&model, |(m, _)| m);
        let mut start = truth.clone();
        for id in &free {
            start[id.0] = match &landmark {
                Some((_, means)) => means[id.0],
                None => model.parameters()[id.0].nominal,
            };
        }
        let opts = UncertaintyOptions {
            bootstrap_replicates: args.replicates,
            seed,
            hac_bandwidth: args.bandwidth,
            jackknife_blocks: args.blocks,
            ..UncertaintyOptions::default()
        };
        let settings = FitSettings {
            method: args.method,
            seed,
            uncertainty: Some(opts),
            marker_policy: !args.no_policy,
            anatomical_envelope: !args.no_envelope,
            prior_conflict: !args.no_conflict,
            ..FitSettings::default()
        };
        let cal = if args.default {
            let r = calibrate_refined(
                fit_model,
                &start,
                &[&trial],
                &free,
                &settings,
                &mut NoObserver,
            )
            .expect("calibration");
            let truth_mm = |name: &str| {
                model
                    .param_id(name)
                    .map_or(f64::NAN, |id| truth[id.0] * 1e3)
            };
            policy.add(
                seed,
                &r.marker_decisions,
                &r.envelope,
                moved.as_deref(),
                truth_mm,
            );
            conflicts.add(seed, &r.conflict);
            r.calibration
        } else {
            calibrate(
                fit_model,
                &start,
                &[&trial],
                &free,
                &settings,
                &mut NoObserver,
            )
            .expect("calibration")
        };
        err_fit.add(&model, &free, &cal.fit.p, &truth);
        if args.compare_none {
            let none = FitSettings {
                method: args.method,
                seed,
                priors: false,
                ..FitSettings::default()
            };
            let fit = calibrate(fit_model, &start, &[&trial], &free, &none, &mut NoObserver)
                .expect("calibration");
            err_none.add(&model, &free, &fit.fit.p, &truth);
        }
        let u = cal.uncertainty.expect("analysed");
        // The objective at the truth (inner problem solved there): a fit above it ended in
        // another minimum.
        let cost_truth = {
            let prob = Problem::new(fit_model, start.clone(), &free, &[&trial]).expect("problem");
            let mut q = prob.initial_coords(&truth);
            prob.inner(&truth, &mut q, &mut IkWorkspace::new(&model))
        };
        global_warnings += cal.global_warning.is_some() as usize;
        bw_sum += u.hac_bandwidth.unwrap_or(0.0);
        // With refined markers their parameters follow the joints' (group `markers`).
        for (k, p) in u.params.iter().enumerate().take(free.len()) {
            let i = free[k].0;
            let f = model.parameters()[i].unit.display_scale();
            let threshold = match model.parameters()[i].unit {
                Unit::Metre => u.threshold_mm,
                Unit::Radian => u.threshold_deg,
            };
            let err = p.value - truth[i] * f;
            let g = groups.iter().position(|g| *g == p.group).expect("group");
            let t = &mut by_group[g];
            t.n += 1;
            t.sq_err += err * err;
            let within = |se: Option<f64>, c: f64| se.is_some_and(|s| err.abs() <= c * s) as usize;
            t.white += within(p.se_white, u.z);
            t.hac += within(p.se_hac, u.z_hac.unwrap_or(f64::NAN));
            t.boot += within(p.se_bootstrap, u.z);
            t.jack += within(p.se_jackknife, u.t_jackknife.unwrap_or(f64::NAN));
            let covers = p.half_width.is_some_and(|h| err.abs() <= h) as usize;
            t.reported += covers;
            if !p.at_bound {
                t.interior += 1;
                t.interior_hit += covers;
            }
            t.undetermined += p.se.is_none() as usize;
            if p.status == Identifiability::Determined {
                t.determined += 1;
                t.determined_hit += covers;
            }
            let row = &cal.parameters[k];
            if let Some(src) = row.source {
                let c = match src {
                    Source::DeterminedByTrial => 0,
                    Source::Partly => 1,
                    Source::HeldByPrior | Source::HeldAtLimit => 2,
                };
                t.source[c].0 += 1;
                t.source[c].1 += covers;
            }
            t.half_width += p.half_width.unwrap_or(0.0);
            if let Some(f) = dump.as_mut() {
                let o = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
                writeln!(
                    f,
                    "{seed},{},{},{},{err:.6e},{},{},{},{},{},{},{},{:?},{:?},{},{},{},{},{:.9e},{:.9e},{threshold},{},{},{},{},{:.6e}",
                    p.name,
                    p.group,
                    p.unit,
                    o(p.se_white),
                    o(p.se_hac),
                    o(p.se_jackknife),
                    o(p.se_bootstrap),
                    u.z,
                    o(u.t_jackknife),
                    o(p.half_width),
                    p.method,
                    p.status,
                    p.at_bound,
                    o(u.hac_bandwidth),
                    u.frames,
                    free.len(),
                    cal.cost_after,
                    cost_truth,
                    o(u.z_hac),
                    o(row.data_share),
                    row.source.map_or("", |s| s.words()),
                    o(p.status_half_width),
                    u.correlation_factor
                )
                .expect("write");
            }
            per_param[k].0 += 1;
            per_param[k].1 += covers;
            per_param[k].2 += p.at_bound as usize;
            let rel = err.abs() / threshold;
            if p.status == Identifiability::Determined {
                ok_err += rel;
                ok_n += 1;
            } else {
                flagged_err += rel;
                flagged_n += 1;
            }
            if rel > 1.0 {
                big_err += 1;
                big_flagged += (p.status != Identifiability::Determined) as usize;
            }
        }
    }
    println!(
        "{} seeds, motion {:?}, {} frames at 50 Hz, skin noise up to {} mm (ω ≤ 25 rad/s), free: {} ({} parameters), {} bootstrap replicates; {:.0} s",
        args.seeds,
        args.motion,
        args.frames,
        args.noise_mm,
        args.joints,
        free.len(),
        args.replicates,
        clock.elapsed().as_secs_f64()
    );
    println!(
        "{:<6} {:>6} {:>7} {:>7} {:>7} {:>7} {:>9} {:>15} {:>15} {:>8} {:>12} {:>10}",
        "group",
        "n",
        "white",
        "HAC",
        "boot",
        "jack",
        "reported",
        "interior (n)",
        "determ. (n)",
        "undet.",
        "mean ±95%",
        "RMS err"
    );
    for (g, t) in groups.iter().zip(&by_group) {
        let pct = |h: usize| 100.0 * h as f64 / t.n.max(1) as f64;
        let det = (t.n - t.undetermined).max(1) as f64;
        println!(
            "{:<6} {:>6} {:>6.1}% {:>6.1}% {:>7} {:>6.1}% {:>8.1}% {:>15} {:>15} {:>8} {:>12.2} {:>10.2}",
            g,
            t.n,
            pct(t.white),
            pct(t.hac),
            if args.replicates > 1 {
                format!("{:.1}%", pct(t.boot))
            } else {
                "-".to_string()
            },
            pct(t.jack),
            pct(t.reported),
            format!(
                "{:.1}% ({})",
                100.0 * t.interior_hit as f64 / t.interior.max(1) as f64,
                t.interior
            ),
            format!(
                "{:.1}% ({})",
                100.0 * t.determined_hit as f64 / t.determined.max(1) as f64,
                t.determined
            ),
            t.undetermined,
            t.half_width / det,
            (t.sq_err / t.n.max(1) as f64).sqrt()
        );
    }
    if args.prior || args.default {
        println!(
            "(with a prior the white/HAC/jack columns apply each estimator's own critical value to \
             the total variance; only `reported` uses the Welch–Satterthwaite value)"
        );
        println!("reported coverage per information label, % (n):");
        println!(
            "{:<6} {:>24} {:>24} {:>24}",
            "group", "determined by the trial", "partly", "held by the prior"
        );
        for (g, t) in groups.iter().zip(&by_group) {
            let cell = |(n, h): (usize, usize)| {
                format!("{:.1}% ({n})", 100.0 * h as f64 / n.max(1) as f64)
            };
            println!(
                "{:<6} {:>24} {:>24} {:>24}",
                g,
                cell(t.source[0]),
                cell(t.source[1]),
                cell(t.source[2])
            );
        }
    }
    println!("(white/boot: z·se; HAC: fixed-b cv·se; jack: t(K−1)·se; reported: the widest; interior: reported, estimates not at a bound;");
    println!(" mean ±95% and RMS err mix mm and deg within a group, as the parameters do)");
    println!(
        "flagged parameters: {flagged_n}, mean |error|/threshold {:.2}; determined: {ok_n}, mean |error|/threshold {:.2}",
        flagged_err / flagged_n.max(1) as f64,
        ok_err / ok_n.max(1) as f64
    );
    let low: Vec<String> = per_param
        .iter()
        .enumerate()
        .filter(|(_, c)| (c.1 as f64) < 0.85 * c.0 as f64)
        .map(|(k, c)| {
            format!(
                "{} {}/{} (at bound {})",
                model.parameters()[free[k].0].name,
                c.1,
                c.0,
                c.2
            )
        })
        .collect();
    println!(
        "parameters covered in < 85 % of seeds: {}",
        if low.is_empty() {
            "none".to_string()
        } else {
            low.join(", ")
        }
    );
    println!(
        "mean HAC bandwidth {:.1} frames",
        bw_sum / args.seeds as f64
    );
    println!("errors above the threshold: {big_err}, of which flagged: {big_flagged}");
    println!("fits warned not known to be the global optimum: {global_warnings}");
    println!("RMS parameter error per joint (mm / deg):");
    for (g, name) in groups.iter().enumerate() {
        let none = match args.compare_none {
            true => format!("; --prior none {}", err_none.cell(g)),
            false => String::new(),
        };
        println!("  {name:<6} this fit {}{none}", err_fit.cell(g));
    }
    if args.default {
        policy.print();
        conflicts.print();
    }
}
