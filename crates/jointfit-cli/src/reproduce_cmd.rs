//! `jointfit reproduce table1|table2 -o DIR`: the paper's protocol end to end, our numbers
//! next to Reinbolt et al. 2005's (J Biomech 38:621–626, doi:10.1016/j.jbiomech.2004.03.031).
//!
//! * **Table 1, synthetic** (no data needed): the subject model (default: the built-in right
//!   leg, whose nominal values are the paper's Table 2 landmark column) is the truth; markers
//!   along the hip, knee, ankle and all-joint motions (and gait, when the data are there) with
//!   no noise and with the skin-artifact model over several seeds; each fit starts from the
//!   truth perturbed on the fitted joint's parameters.
//! * **Table 1, experimental**: `biobuddy_functional_vicon` (static → personalize with the
//!   plugin-gait-medial preset → hip on the hip trial, knee on the knee trial, ankle on the ankle
//!   trial) and `opencap_expert1` (static → personalize with the opencap preset → all 27 on
//!   walking1, low-passed at 6 Hz); the landmark row is the inner level alone at the
//!   personalized (nominal) parameters.
//! * **Table 2**: landmark, single-joint and full-leg parameters of the biobuddy subject (the
//!   full leg fitted on its three functional trials together, started from the single-joint
//!   values, as the paper seeded its full leg from its single-joint fits) and landmark and
//!   full-leg (gait) parameters of the OpenCap subject.
//!
//! Results go to `DIR/table1.{md,json,csv}` (or `table2.*`), written atomically.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit::workflow::FitSettings;
use jointfit_experiments::protocol::experimental;
use jointfit_experiments::report::{
    run_synthetic_column_observed, ColumnSpec, ExperimentalColumn, Report, SyntheticColumn, Table2,
};
use jointfit_experiments::synth::{coordinates_scaled, gait_coordinates, Motion};
use jointfit_io::atomic::write_atomic;

use crate::calibrate_cmd::MethodArg;

mod subjects;
use subjects::{biobuddy, data_dir, needed_files, opencap, require, Subject, BIOBUDDY, OPENCAP};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Which {
    Table1,
    Table2,
}

#[derive(Args)]
pub struct ReproduceArgs {
    /// Which table.
    #[arg(value_enum)]
    pub table: Which,
    /// Output directory (created if needed).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The shared data directory (default: $JOINTFIT_DATA, else ../shared/data).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Table 1: only the synthetic experiments (no data needed).
    #[arg(long)]
    pub synthetic_only: bool,
    /// Outer optimizer. The paper used a particle swarm (single joints) and a gradient method
    /// (full leg); the joint solver reaches the same optima in a fraction of the time.
    #[arg(long, value_enum, default_value = "joint")]
    pub method: MethodArg,
    /// Starts per fit: the given start plus this many minus one starts moved from it by up to
    /// 20 mm / 10° (seeded); the lowest cost wins. Ignored by --method pso.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true, value_parser = crate::validate::runs)]
    pub starts: usize,
    /// Noisy synthetic runs per column (seeds first-seed, first-seed+1, ...).
    #[arg(long, default_value_t = 10, allow_negative_numbers = true, value_parser = crate::validate::runs)]
    pub seeds: usize,
    /// Seed of the first noisy run of each column; run k uses first-seed + k, so two
    /// invocations with the same seeds give the same tables.
    #[arg(long, default_value_t = 1)]
    pub first_seed: u64,
    /// Subject model of the synthetic experiments (TOML file or built-in name).
    #[arg(long, default_value = "lower-limb-right")]
    pub subject: String,
    /// Frames of each synthetic joint motion (the paper: 50).
    #[arg(long, default_value_t = 50, allow_negative_numbers = true, value_parser = crate::validate::frames)]
    pub frames: usize,
    /// Sampling rate of the synthetic joint motions (Hz): the time axis of the skin noise.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = crate::validate::rate_hz)]
    pub rate: f64,
    /// Multiplies the synthetic joint excursions.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = crate::validate::amplitude)]
    pub amplitude: f64,
    /// Start = truth moved by up to this many mm per fitted position parameter.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true, value_parser = crate::validate::perturb_mm)]
    pub perturb_mm: f64,
    /// Start = truth moved by up to this many degrees per fitted orientation parameter.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = crate::validate::perturb_deg)]
    pub perturb_deg: f64,
    /// Use every K-th frame of the experimental trials (after filtering); 1 uses them all.
    #[arg(long, default_value_t = 1, value_name = "K", allow_negative_numbers = true, value_parser = crate::validate::runs)]
    pub stride: usize,
    /// Trials of opencap_expert1 the full leg is fitted on (comma-separated; the first is
    /// also the synthetic gait motion), e.g. walking1.trc,squats1.trc.
    #[arg(long, default_value = "walking1.trc", value_delimiter = ',')]
    pub gait_trials: Vec<String>,
}

/// A note naming the parameters of `p` that ended on a bound of their search box.
fn bounds_note(model: &Model, method: &str, p: &[f64]) -> Option<String> {
    let at: Vec<String> = model
        .parameters()
        .iter()
        .zip(p)
        .filter(|(par, v)| {
            let tol = 1e-9 * (par.upper - par.lower);
            (**v - par.lower).abs() <= tol || (**v - par.upper).abs() <= tol
        })
        .map(|(par, _)| par.name.clone())
        .collect();
    (!at.is_empty()).then(|| {
        format!(
            "{method}: {} at a bound of the search box (Reinbolt's bounds: ±30° cones, \
             position cubes): {}",
            if at.len() == 1 {
                "1 parameter"
            } else {
                "parameters"
            },
            at.join(", ")
        )
    })
}

fn synthetic_columns(
    args: &ReproduceArgs,
    settings: &FitSettings,
    gait: Option<(&[Vec<f64>], f64, &str)>,
) -> Result<Vec<SyntheticColumn>> {
    let model = jointfit_io::model_file::load_model(&args.subject)?;
    let truth = model.nominal_params();
    let mut specs = Vec::new();
    for (label, col, group, motion) in [
        ("Hip only", 0, "hip", Motion::Hip),
        ("Knee only", 1, "knee", Motion::Knee),
        ("Ankle only", 2, "ankle", Motion::Ankle),
        ("Full leg (all-joint motion)", 3, "all", Motion::All),
    ] {
        specs.push(ColumnSpec {
            label: label.to_string(),
            paper_column: col,
            groups: vec![group.to_string()],
            motion: format!("{motion:?}").to_lowercase(),
            coords: coordinates_scaled(&model, motion, args.frames, args.amplitude)?,
            rate: args.rate,
        });
    }
    if let Some((coords, rate, name)) = gait {
        specs.push(ColumnSpec {
            label: "Full leg (gait)".to_string(),
            paper_column: 3,
            groups: vec!["all".to_string()],
            motion: format!("gait: IK of {name}"),
            coords: coords.to_vec(),
            rate,
        });
    }
    let mut out = Vec::new();
    // One step per fitted case: a bar with ETA on a terminal, log lines otherwise.
    let total = specs.len() * (1 + args.seeds);
    let mut bar = crate::progress::Progress::new("reproduce: synthetic fits", Some(total as u64))
        .unit("fits");
    for (c, spec) in specs.iter().enumerate() {
        let done_before = c * (1 + args.seeds);
        out.push(
            run_synthetic_column_observed(
                &model,
                &truth,
                spec,
                args.perturb_mm,
                args.perturb_deg,
                settings,
                args.first_seed,
                args.seeds,
                &mut |k| bar.set((done_before + k + 1) as u64, &spec.label),
            )
            .with_context(|| format!("synthetic {}", spec.label))?,
        );
    }
    bar.finish(&format!("{} columns", specs.len()));
    Ok(out)
}

/// The counts and the rate are usable.
fn check_args(args: &ReproduceArgs) -> Result<()> {
    if args.seeds == 0 || args.starts == 0 || args.frames == 0 || args.stride == 0 {
        bail!("--seeds, --starts, --frames and --stride must be at least 1");
    }
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate must be finite and positive (got {})", args.rate);
    }
    Ok(())
}

/// The shared data the run needs are there (the experimental part and table 2).
fn check_data(args: &ReproduceArgs, data: &std::path::Path) -> Result<()> {
    if args.gait_trials.is_empty() {
        bail!("--gait-trials needs at least one trial");
    }
    let files = needed_files(&args.gait_trials);
    let refs: Vec<&str> = files.iter().map(|s| s.as_str()).collect();
    let what = match args.table {
        Which::Table1 => "table 1 (experimental part)",
        Which::Table2 => "table 2",
    };
    require(data, &refs, what)
}

/// The first note: which outer optimizer ran, against the paper's.
fn optimizer_note(settings: &FitSettings) -> String {
    format!(
        "Outer optimizer: {} ({} start{} per fit). The paper used a particle swarm for single \
         joints and a gradient method for the full leg (~41 h per noisy single joint on a cluster); \
         the joint sparse Levenberg–Marquardt shares the two-level optima and each fit here takes \
         seconds (see each result's `seconds` in the JSON).",
        settings.method,
        settings.starts,
        if settings.starts == 1 { "" } else { "s" }
    )
}

/// Table 1's synthetic columns (with a gait column from the OpenCap subject's IK, when the
/// data are there) and their notes.
fn synthetic_part(
    args: &ReproduceArgs,
    settings: &FitSettings,
    opencap: Option<&Subject>,
    notes: &mut Vec<String>,
) -> Result<Vec<SyntheticColumn>> {
    let gait = match opencap {
        Some(s) => {
            let (coords, dropped) =
                gait_coordinates(&s.model, &s.model.nominal_params(), &s.trials[0].1)
                    .with_context(|| format!("{OPENCAP}/{}: inverse kinematics", s.trials[0].0))?;
            if !dropped.is_empty() {
                notes.push(format!("gait IK dropped {} frames", dropped.len()));
            }
            Some((coords, s.trials[0].1.rate()))
        }
        None => None,
    };
    let gait_name = opencap
        .map(|s| format!("{OPENCAP}/{} (6 Hz low-pass)", s.trials[0].0))
        .unwrap_or_default();
    let gait_ref = gait
        .as_ref()
        .map(|(c, r)| (c.as_slice(), *r, gait_name.as_str()));
    let synthetic = synthetic_columns(args, settings, gait_ref)?;
    notes.push(format!(
        "Synthetic: truth = nominal parameters of {}; {} frames per joint motion at {} Hz \
         (amplitude ×{}); start = truth moved by up to {} mm / {}° per fitted parameter \
         (uniform, seeded); noise = skin artifact A·sin(ωt+φ) per marker-axis, A ≤ 10 mm, \
         ω ≤ 25 rad/s, seeds {}–{}; the noiseless row uses seed {}.",
        args.subject,
        args.frames,
        args.rate,
        args.amplitude,
        args.perturb_mm,
        args.perturb_deg,
        args.first_seed,
        args.first_seed + args.seeds as u64 - 1,
        args.first_seed
    ));
    Ok(synthetic)
}

/// The experimental single-joint columns (hip, knee, ankle on the biobuddy subject's
/// functional trials) and the parameters with each joint at its single-joint fit.
fn single_joint_columns(
    bb: &Subject,
    settings: &FitSettings,
    seed: u64,
) -> Result<(Vec<ExperimentalColumn>, Vec<f64>)> {
    let nominal = bb.model.nominal_params();
    let mut single = nominal.clone();
    let mut columns = Vec::new();
    for (k, (label, group)) in [
        ("Hip only", "hip"),
        ("Knee only", "knee"),
        ("Ankle only", "ankle"),
    ]
    .iter()
    .enumerate()
    {
        let (name, trial) = &bb.trials[k];
        eprintln!("jointfit: experimental {label} on {BIOBUDDY}/{name}");
        let r = experimental(&bb.model, &nominal, &[group], &[trial], settings, seed)
            .with_context(|| format!("{BIOBUDDY}/{name}: fitting {group}"))?;
        for id in jointfit::calibrate::params_for_groups(&bb.model, &[group])? {
            single[id.0] = r.fitted[id.0];
        }
        columns.push(ExperimentalColumn {
            label: label.to_string(),
            paper_column: k,
            dataset: format!("{BIOBUDDY} (Plug-in Gait, 12 Hz, unfiltered)"),
            trials: vec![name.clone()],
            result: r,
        });
    }
    Ok((columns, single))
}

/// The experimental full-leg column: all 27 on the OpenCap subject's gait trials.
fn gait_column(oc: &Subject, settings: &FitSettings, seed: u64) -> Result<ExperimentalColumn> {
    let names: Vec<String> = oc.trials.iter().map(|(n, _)| n.clone()).collect();
    eprintln!(
        "jointfit: experimental full leg on {OPENCAP}/{}",
        names.join(" + ")
    );
    let gait_trials: Vec<&Trial> = oc.trials.iter().map(|(_, t)| t).collect();
    let gait_fit = experimental(
        &oc.model,
        &oc.model.nominal_params(),
        &["all"],
        &gait_trials,
        settings,
        seed,
    )
    .with_context(|| format!("{OPENCAP}/{}: fitting all", names.join(" + ")))?;
    Ok(ExperimentalColumn {
        label: "Full leg (gait)".to_string(),
        paper_column: 3,
        dataset: format!("{OPENCAP} (OpenCap markers, 100 Hz, 6 Hz low-pass)"),
        trials: names,
        result: gait_fit,
    })
}

/// Table 2 of the biobuddy subject: landmark, single-joint and full-leg parameters (the full
/// leg on its three functional trials, started from the single-joint values).
fn biobuddy_table2(
    bb: &Subject,
    single: &[f64],
    settings: &FitSettings,
    seed: u64,
) -> Result<Table2> {
    eprintln!("jointfit: full leg on the three {BIOBUDDY} functional trials");
    let nominal = bb.model.nominal_params();
    let all: Vec<&Trial> = bb.trials.iter().map(|(_, t)| t).collect();
    let full = experimental(&bb.model, single, &["all"], &all, settings, seed)
        .context("biobuddy functional trials: fitting all")?;
    let mut t = Table2::new(
        &format!(
            "{} (right leg; Test_func_anat.c3d, plugin-gait-medial preset)",
            bb.name
        ),
        &bb.model,
        &[
            ("anatomical landmarks", Some(&nominal)),
            ("single joint", Some(single)),
            ("full leg (3 functional trials)", Some(&full.fitted)),
        ],
    );
    t.notes
        .extend(bounds_note(&bb.model, "single joint", single));
    t.notes
        .extend(bounds_note(&bb.model, "full leg", &full.fitted));
    t.notes.push(format!(
        "single joint: hip on Test_func_rhip, knee on Test_func_rknee, ankle on \
         Test_func_rankle, each from the landmark values; full leg: all 27 on the three \
         trials together ({} frames), started from the single-joint values (this \
         subject has no gait trial); marker RMS {:.2} mm vs {:.2} mm for the landmark model",
        full.frames, full.fitted_rms_mm, full.landmark_rms_mm
    ));
    Ok(t)
}

/// Table 2 of the OpenCap subject: landmark and full-leg (gait) parameters.
fn opencap_table2(oc: &Subject, gait: &ExperimentalColumn) -> Table2 {
    let fitted = &gait.result.fitted;
    let mut t = Table2::new(
        &format!("{} (right leg; static1.trc, opencap preset)", oc.name),
        &oc.model,
        &[
            ("anatomical landmarks", Some(&oc.model.nominal_params())),
            ("single joint", None),
            ("full leg (gait)", Some(fitted)),
        ],
    );
    t.notes
        .extend(bounds_note(&oc.model, "full leg (gait)", fitted));
    t.notes.push(format!(
        "no single-joint functional trials exist for this subject; full leg: all 27 on \
         {} (6 Hz low-pass) from the landmark values",
        gait.trials.join(" + ")
    ));
    t
}

/// The experimental part: table 1's experimental columns, or table 2's tables.
fn experimental_part(
    args: &ReproduceArgs,
    settings: &FitSettings,
    bb: &Subject,
    oc: &Subject,
) -> Result<(Vec<ExperimentalColumn>, Vec<Table2>)> {
    let (mut columns, single) = single_joint_columns(bb, settings, args.first_seed)?;
    let gait = gait_column(oc, settings, args.first_seed)?;
    if args.table == Which::Table1 {
        columns.push(gait);
        return Ok((columns, Vec::new()));
    }
    let tables = vec![
        biobuddy_table2(bb, &single, settings, args.first_seed)?,
        opencap_table2(oc, &gait),
    ];
    Ok((Vec::new(), tables))
}

/// The run's settings as the report's JSON records them.
fn settings_json(
    args: &ReproduceArgs,
    settings: &FitSettings,
    data: Option<&std::path::Path>,
) -> serde_json::Value {
    serde_json::json!({
        "table": format!("{:?}", args.table).to_lowercase(),
        "data": data.map(|d| d.display().to_string()),
        "synthetic_only": args.synthetic_only,
        "fit": {
            "method": settings.method,
            "restart_deg": settings.restart_rad.to_degrees(),
            "restart_mm": jointfit_app::present::mm(settings.restart_m),
            "starts": settings.starts,
        },
        "seeds": args.seeds,
        "first_seed": args.first_seed,
        "subject": args.subject,
        "frames": args.frames,
        "rate_hz": args.rate,
        "amplitude": args.amplitude,
        "perturb_mm": args.perturb_mm,
        "perturb_deg": args.perturb_deg,
        "stride": args.stride,
        "skin_noise": {"max_amplitude_mm": 10.0, "max_omega_rad_s": 25.0},
    })
}

/// Writes `DIR/table1.{md,json,csv}` (or `table2.*`) and prints the Markdown.
fn write_report(args: &ReproduceArgs, report: &Report) -> Result<()> {
    let stem = match args.table {
        Which::Table1 => "table1",
        Which::Table2 => "table2",
    };
    jointfit_io::staging::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create", args.output.display()))?;
    let md = report.markdown();
    for (ext, text) in [
        ("md", md.clone()),
        ("json", serde_json::to_string_pretty(report)?),
        ("csv", report.csv()),
    ] {
        let path = args.output.join(format!("{stem}.{ext}"));
        write_atomic(&path, text.as_bytes())
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    print!("{md}");
    println!("wrote {}/{stem}.md, .json and .csv", args.output.display());
    Ok(())
}

pub fn run(args: ReproduceArgs) -> Result<()> {
    let clock = Instant::now();
    check_args(&args)?;
    let data = data_dir(&args.data);
    // The paper's protocol: local fits from the perturbed starts, no global phase.
    let settings = FitSettings {
        method: args.method.into(),
        starts: args.starts,
        probes: 0,
        ..FitSettings::default()
    };
    let needs_data = args.table == Which::Table2 || !args.synthetic_only;
    if needs_data {
        check_data(&args, &data)?;
    }
    let mut notes = vec![optimizer_note(&settings)];
    let (biobuddy_subject, opencap_subject) = match needs_data {
        true => (
            Some(biobuddy(&data, args.stride)?),
            Some(opencap(&data, args.stride, &args.gait_trials)?),
        ),
        false => (None, None),
    };
    let synthetic = match args.table {
        Which::Table1 => synthetic_part(&args, &settings, opencap_subject.as_ref(), &mut notes)?,
        Which::Table2 => Vec::new(),
    };
    let (experimental_cols, table2) = match (&biobuddy_subject, &opencap_subject) {
        (Some(bb), Some(oc)) => experimental_part(&args, &settings, bb, oc)?,
        _ => (Vec::new(), Vec::new()),
    };
    let command = std::iter::once("jointfit".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let mut report = Report {
        title: match args.table {
            Which::Table1 => "Table 1 — RMS marker-distance and joint-parameter errors".into(),
            Which::Table2 => "Table 2 — joint parameters by method".into(),
        },
        command,
        version: env!("CARGO_PKG_VERSION").to_string(),
        // `git describe` of the sources at build time (build.rs), if they were a checkout.
        git: option_env!("JOINTFIT_GIT_DESCRIBE").map(str::to_string),
        settings: settings_json(&args, &settings, needs_data.then_some(data.as_path())),
        synthetic,
        experimental: experimental_cols,
        table2,
        notes,
        seconds: 0.0,
    };
    report.seconds = clock.elapsed().as_secs_f64();
    write_report(&args, &report)
}
