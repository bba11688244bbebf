//! Monte Carlo check of the uncertainty intervals.
//!
//! For each seed: true parameters = nominal moved by up to 40 % of each half-range, a
//! synthetic trial of the chosen motion with skin-artifact noise (`A sin(ωt + φ)`, A up to
//! `--noise-mm`, ω up to 25 rad/s, Chèze et al. 1995), a joint fit of all 27 parameters from
//! the nominal model, and the uncertainty analysis, all through [`jointfit::workflow::calibration::calibrate`]
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

use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::prior::Source;
use jointfit::calibrate::uncertainty::Identifiability;
use jointfit::calibrate::uncertainty::ParamUncertainty;
use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::population::{fill_landmark_priors, HipCentreMethod};
use jointfit::model::spec::ModelSpec;
use jointfit::model::spec::Unit;
use jointfit::model::{Model, ParamId};
use jointfit::solver::NoObserver;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::refine::calibrate_refined;
use jointfit::workflow::{perturb, FitSettings};
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
    let run = Run::new(args);
    let mut totals = Totals::new(&run);
    let clock = Instant::now();
    for seed in run.args.first_seed..run.args.first_seed + run.args.seeds {
        let sample = run.sample(seed);
        let cal = run.fit(&sample, seed, &mut totals);
        totals.add(&run, &sample, &cal, seed);
    }
    totals.print(&run, clock.elapsed().as_secs_f64());
}

/// What every seed shares: the options, the model (with landmark priors for `--prior` and
/// `--default`), the motion and the free parameters.
struct Run {
    args: args::Args,
    spec: ModelSpec,
    model: Model,
    coords: Vec<Vec<f64>>,
    free: Vec<ParamId>,
    every: Vec<usize>,
}

/// One seed's synthetic subject: the true parameters, the noisy trial (with the misplaced
/// marker, if any), the model the fit starts from and its start.
struct Sample {
    truth: Vec<f64>,
    trial: Trial,
    moved: Option<String>,
    /// The subject's landmark model and its prior means (`--landmark-error`).
    landmark: Option<(Model, Vec<f64>)>,
    start: Vec<f64>,
}

impl Sample {
    fn fit_model<'a>(&'a self, run: &'a Run) -> &'a Model {
        self.landmark.as_ref().map_or(&run.model, |(m, _)| m)
    }
}

impl Run {
    fn new(args: args::Args) -> Run {
        let mut spec = lower_limb(Side::Right);
        if args.prior || args.default {
            fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
        }
        let model = Model::compile(&spec).expect("built-in model compiles");
        let coords = coordinates(&model, args.motion, args.frames).expect("built-in motion");
        let free = params_for_groups(&model, &[args.joints.as_str()])
            .expect("--joints hip|knee|ankle|all");
        let every: Vec<usize> = (0..model.parameters().len()).collect();
        Run {
            args,
            spec,
            model,
            coords,
            free,
            every,
        }
    }

    /// The synthetic subject of `seed`.
    fn sample(&self, seed: u64) -> Sample {
        let (args, model) = (&self.args, &self.model);
        let truth = match (args.prior, args.perturb) {
            (true, _) => model.sample_priors(seed),
            (false, Some((mm, deg))) => {
                perturb(model, &model.nominal_params(), &self.every, mm, deg, seed)
            }
            (false, None) => perturbed_params(model, 0.4, seed),
        };
        let noise = SkinNoise {
            max_amplitude: args.noise_mm / 1e3,
            seed: 10_000 + seed,
            ..SkinNoise::default()
        };
        let (true_spec, moved) = misplaced(&self.spec, args.misplace_mm, seed);
        let true_model = Model::compile(&true_spec).expect("built-in model compiles");
        let (trial, _) = markers(&true_model, &truth, &self.coords, 50.0, Some(&noise));
        // The fitted joints start at nominal (or, with `--landmark-error`, at the subject's
        // landmark model, which is also the prior mean); the others are held at the truth.
        let landmark = args.landmark_error.then(|| {
            let (s, means) = landmark_model(&self.spec, &truth, seed);
            (Model::compile(&s).expect("landmark model compiles"), means)
        });
        let mut start = truth.clone();
        for id in &self.free {
            start[id.0] = match &landmark {
                Some((_, means)) => means[id.0],
                None => model.parameters()[id.0].nominal,
            };
        }
        Sample {
            truth,
            trial,
            moved,
            landmark,
            start,
        }
    }

    /// The fit of one sample with its uncertainty: `calibrate_refined` with `--default`
    /// (what the policy and envelope did goes to `totals`), else `calibrate`; with
    /// `--compare-none` also a fit without priors, whose errors go to `totals`.
    fn fit(&self, sample: &Sample, seed: u64, totals: &mut Totals) -> Calibration {
        let args = &self.args;
        let (fit_model, start, free) = (sample.fit_model(self), &sample.start, &self.free);
        let trials = [&sample.trial];
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
            let r = calibrate_refined(fit_model, start, &trials, free, &settings, &mut NoObserver)
                .expect("calibration");
            let truth_mm = |name: &str| {
                self.model
                    .param_id(name)
                    .map_or(f64::NAN, |id| sample.truth[id.0] * 1e3)
            };
            totals.policy.add(
                seed,
                &r.marker_decisions,
                &r.envelope,
                sample.moved.as_deref(),
                truth_mm,
            );
            totals.conflicts.add(seed, &r.conflict);
            r.calibration
        } else {
            calibrate(fit_model, start, &trials, free, &settings, &mut NoObserver)
                .expect("calibration")
        };
        if args.compare_none {
            let none = FitSettings {
                method: args.method,
                seed,
                priors: false,
                ..FitSettings::default()
            };
            let fit = calibrate(fit_model, start, &trials, free, &none, &mut NoObserver)
                .expect("calibration");
            totals
                .err_none
                .add(&self.model, free, &fit.fit.p, &sample.truth);
        }
        cal
    }

    /// The objective at the truth (inner problem solved there): a fit above it ended in
    /// another minimum.
    fn cost_at_truth(&self, sample: &Sample) -> f64 {
        let fit_model = sample.fit_model(self);
        jointfit::workflow::marker_rms::marker_rms(fit_model, &sample.truth, &[&sample.trial])
            .expect("problem")
            .cost
    }
}

/// What the seeds add up to.
struct Totals {
    err_fit: Errors,
    err_none: Errors,
    policy: Policy,
    conflicts: policy::Conflicts,
    by_group: Vec<Tally>,
    /// Per free parameter: (seeds, covered, at a bound).
    per_param: Vec<(usize, usize, usize)>,
    /// Sum of |error|/threshold and count, for flagged and for determined parameters.
    flagged: (f64, usize),
    determined: (f64, usize),
    /// Errors above the threshold, and of those the flagged ones.
    big_err: usize,
    big_flagged: usize,
    bw_sum: f64,
    global_warnings: usize,
    dump: Option<std::io::BufWriter<std::fs::File>>,
}

impl Totals {
    fn new(run: &Run) -> Totals {
        let args = &run.args;
        let dump = args.dump.as_ref().map(|path| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("--dump file"));
        writeln!(
            f,
            "seed,name,group,unit,err,se_white,se_hac,se_jack,se_boot,z,t_jack,half_width,method,status,at_bound,bandwidth,frames,n_free,cost_fit,cost_truth,threshold,z_hac,data_share,source,status_half_width,correlation_factor"
        )
        .expect("write");
        f
    });
        Totals {
            err_fit: Errors::default(),
            err_none: Errors::default(),
            policy: Policy::default(),
            conflicts: policy::Conflicts::default(),
            by_group: vec![Tally::default(); GROUPS.len()],
            per_param: vec![(0, 0, 0); run.free.len()],
            flagged: (0.0, 0),
            determined: (0.0, 0),
            big_err: 0,
            big_flagged: 0,
            bw_sum: 0.0,
            global_warnings: 0,
            dump,
        }
    }

    /// One seed's fit: its errors, and per free parameter whether each estimator's interval
    /// covers the truth (a row of `--dump` each).
    fn add(&mut self, run: &Run, sample: &Sample, cal: &Calibration, seed: u64) {
        self.err_fit
            .add(&run.model, &run.free, &cal.fit.p, &sample.truth);
        let u = cal.uncertainty.as_ref().expect("analysed");
        let cost_truth = run.cost_at_truth(sample);
        self.global_warnings += cal.global_warning.is_some() as usize;
        self.bw_sum += u.hac_bandwidth.unwrap_or(0.0);
        // With refined markers their parameters follow the joints' (group `markers`).
        for (k, p) in u.params.iter().enumerate().take(run.free.len()) {
            self.add_param(run, sample, cal, k, p, seed, cost_truth);
        }
    }

    /// One free parameter of one seed.
    #[allow(clippy::too_many_arguments)]
    fn add_param(
        &mut self,
        run: &Run,
        sample: &Sample,
        cal: &Calibration,
        k: usize,
        p: &ParamUncertainty,
        seed: u64,
        cost_truth: f64,
    ) {
        let (model, free, truth) = (&run.model, &run.free, &sample.truth);
        let u = cal.uncertainty.as_ref().expect("analysed");
        let (by_group, dump) = (&mut self.by_group, &mut self.dump);
        let i = free[k].0;
        let f = jointfit_experiments::units::scale(model.parameters()[i].unit);
        let threshold = match model.parameters()[i].unit {
            Unit::Metre => u.threshold_m * 1e3,
            Unit::Radian => u.threshold_rad.to_degrees(),
        };
        let err = p.value - truth[i] * f;
        let g = GROUPS.iter().position(|g| *g == p.group).expect("group");
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
            row.source.map_or(String::new(), |s| s.to_string()),
            o(p.status_half_width),
            u.correlation_factor
        )
        .expect("write");
        }
        self.per_param[k].0 += 1;
        self.per_param[k].1 += covers;
        self.per_param[k].2 += p.at_bound as usize;
        let rel = err.abs() / threshold;
        if p.status == Identifiability::Determined {
            self.determined.0 += rel;
            self.determined.1 += 1;
        } else {
            self.flagged.0 += rel;
            self.flagged.1 += 1;
        }
        if rel > 1.0 {
            self.big_err += 1;
            self.big_flagged += (p.status != Identifiability::Determined) as usize;
        }
    }

    /// The coverage table per group, per information label with a prior, and the summary
    /// lines.
    fn print(&self, run: &Run, seconds: f64) {
        self.print_table(run, seconds);
        if run.args.prior || run.args.default {
            self.print_by_label();
        }
        self.print_findings(run);
    }

    /// Coverage per group and estimator.
    fn print_table(&self, run: &Run, seconds: f64) {
        let (args, free, groups, by_group) =
            (&run.args, &run.free, GROUPS, self.by_group.as_slice());
        println!(
        "{} seeds, motion {:?}, {} frames at 50 Hz, skin noise up to {} mm (ω ≤ 25 rad/s), free: {} ({} parameters), {} bootstrap replicates; {:.0} s",
        args.seeds,
        args.motion,
        args.frames,
        args.noise_mm,
        args.joints,
        free.len(),
        args.replicates,
        seconds
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
        for (g, t) in groups.iter().zip(by_group) {
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
    }

    /// Reported coverage per information label (determined by the trial, partly, held by the
    /// prior).
    fn print_by_label(&self) {
        let (groups, by_group) = (GROUPS, self.by_group.as_slice());
        println!(
            "(with a prior the white/HAC/jack columns apply each estimator's own critical value to \
             the total variance; only `reported` uses the Welch–Satterthwaite value)"
        );
        println!("reported coverage per information label, % (n):");
        println!(
            "{:<6} {:>24} {:>24} {:>24}",
            "group", "determined by the trial", "partly", "held by the prior"
        );
        for (g, t) in groups.iter().zip(by_group) {
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

    /// What the flags say, the parameters rarely covered, and the errors per joint.
    fn print_findings(&self, run: &Run) {
        let (args, model, free, groups) = (&run.args, &run.model, &run.free, GROUPS);
        let (flagged_n, flagged_err) = (self.flagged.1, self.flagged.0);
        let (ok_n, ok_err) = (self.determined.1, self.determined.0);
        let (big_err, big_flagged) = (self.big_err, self.big_flagged);
        let (per_param, bw_sum) = (&self.per_param, self.bw_sum);
        let global_warnings = self.global_warnings;
        let (err_fit, err_none, policy, conflicts) =
            (&self.err_fit, &self.err_none, &self.policy, &self.conflicts);
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
}
