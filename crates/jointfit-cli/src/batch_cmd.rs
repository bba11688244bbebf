//! `jointfit batch MANIFEST -o DIR [--jobs N]`: many calibrations on one machine.
//!
//! This file only parses the manifest, reports progress and prints; the runner (a rayon
//! pool, resumption, the results table) is `jointfit_io::batch`, which the Python package
//! uses too.
//!
//! The manifest is TOML; paths are relative to the manifest's folder:
//!
//! ```toml
//! [defaults]                 # optional: any job setting below except id, model, trials
//! up = "z"
//! joints = ["knee", "ankle"]
//!
//! [[job]]
//! id = "S01"                 # names DIR/jobs/S01.json and DIR/models/S01.toml
//! model = "S01/subject.toml" # or a built-in model name
//! trials = ["S01/walk1.c3d", "S01/walk2.c3d"]
//! method = "joint"           # joint | gradient | pso
//! filter = 6.0               # Hz
//! starts = 3                 # and seed, bootstrap, threshold_mm, threshold_deg,
//! prior = "none"             # fix_unidentifiable, marker_noise_mm, max_iter: as the
//! ```                        # calibrate options of the same names, with their limits
//!
//! A job's fitted model equals `jointfit calibrate`'s with the same options (and
//! `--accept-unconverged`: the batch keeps an unconverged fit, with a warning).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::trial::UpAxis;
use jointfit_io::batch::{
    run_batch, FitOptions, Job, ModelInput, Outcome, ReadOptions, TrialInput,
};
use serde::Deserialize;

#[derive(Args)]
#[command(after_help = MANIFEST_HELP)]
pub struct BatchArgs {
    /// Manifest (TOML): one [[job]] table per calibration (keys below).
    pub manifest: PathBuf,
    /// Output folder: results.csv, results.json, jobs/<id>.json, models/<id>.toml.
    /// Jobs already finished there (same inputs and settings) are skipped.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Worker threads (0: one per core; at most 1024).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=1024))]
    pub jobs: u16,
    /// Print the results table as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The manifest's keys, shown after the options in `jointfit batch --help`.
const MANIFEST_HELP: &str =
    "Manifest keys (paths relative to the manifest's folder; [defaults] may give any \
but id, model and trials):
  [[job]] id = \"S01\", model = \"S01/subject.toml\" or a built-in name, trials = [\"a.c3d\", ...]
  up (\"y\", \"z\", \"-z\"), filter (Hz), joints, method, seed, starts, bootstrap, threshold_mm,
  threshold_deg, fix_unidentifiable, prior (\"model\", \"none\"), marker_noise_mm, max_iter,
  accept_rejected: as the calibrate options of the same names, with the same limits.
At most 100000 jobs. Exit status 4 when some jobs failed or were rejected by their verdict
(their errors are in results.csv; its verdict column says ok, caution or reject).";

/// Most jobs in one manifest.
pub const MAX_JOBS: usize = 100_000;

/// Settings a job may give and `[defaults]` may provide.
#[derive(Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
struct Settings {
    up: Option<String>,
    joints: Option<Vec<String>>,
    method: Option<String>,
    filter: Option<f64>,
    seed: Option<u64>,
    bootstrap: Option<usize>,
    threshold_mm: Option<f64>,
    threshold_deg: Option<f64>,
    starts: Option<usize>,
    fix_unidentifiable: Option<bool>,
    prior: Option<String>,
    marker_noise_mm: Option<f64>,
    max_iter: Option<usize>,
    accept_rejected: Option<bool>,
}

/// `value` of manifest key `key` within `lo..=hi` (the command line's limits).
fn bounded<T: PartialOrd + std::fmt::Display + Copy>(
    key: &str,
    value: T,
    lo: T,
    hi: T,
) -> Result<T> {
    if !(lo..=hi).contains(&value) {
        bail!("{key} must be from {lo} to {hi} (got {value})");
    }
    Ok(value)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JobEntry {
    id: String,
    model: String,
    trials: Vec<String>,
    #[serde(flatten)]
    settings: Settings,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    #[serde(default)]
    defaults: Settings,
    #[serde(default)]
    job: Vec<JobEntry>,
}

fn parse_up(s: &str) -> Result<Option<UpAxis>> {
    match UpAxis::parse(s) {
        Some(up) => Ok(Some(up)),
        None => bail!("up must be \"y\", \"-y\", \"z\", \"-z\", \"x\" or \"-x\", not {s:?}"),
    }
}

fn to_job(entry: JobEntry, defaults: &Settings, base: &Path) -> Result<Job> {
    let s = &entry.settings;
    let d = FitOptions::default();
    let rel = |p: &str| -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    };
    let builtin = jointfit::model::lower_limb::BUILTIN_NAMES.contains(&entry.model.as_str());
    let model = if builtin && !rel(&entry.model).exists() {
        entry.model.clone()
    } else {
        rel(&entry.model).display().to_string()
    };
    let method = s.method.clone().or(defaults.method.clone());
    let job = Job {
        id: entry.id.clone(),
        model: ModelInput::Named(model),
        trials: entry
            .trials
            .iter()
            .map(|t| TrialInput::Path(rel(t)))
            .collect(),
        read: ReadOptions {
            up: match s.up.as_ref().or(defaults.up.as_ref()) {
                Some(u) => parse_up(u)?,
                None => None,
            },
            filter_hz: match s.filter.or(defaults.filter) {
                Some(hz) => Some(bounded(
                    "filter",
                    hz,
                    crate::validate::MIN_FILTER_HZ,
                    crate::validate::MAX_RATE_HZ,
                )?),
                None => None,
            },
        },
        fit: FitOptions {
            joints: s
                .joints
                .clone()
                .or(defaults.joints.clone())
                .unwrap_or(d.joints),
            method: match method {
                Some(m) => m.parse().map_err(anyhow::Error::msg)?,
                None => d.method,
            },
            seed: s.seed.or(defaults.seed).unwrap_or(d.seed),
            bootstrap: s.bootstrap.or(defaults.bootstrap).unwrap_or(d.bootstrap),
            threshold_mm: s
                .threshold_mm
                .or(defaults.threshold_mm)
                .unwrap_or(d.threshold_mm),
            threshold_deg: s
                .threshold_deg
                .or(defaults.threshold_deg)
                .unwrap_or(d.threshold_deg),
            starts: s.starts.or(defaults.starts).unwrap_or(d.starts),
            fix_unidentifiable: s
                .fix_unidentifiable
                .or(defaults.fix_unidentifiable)
                .unwrap_or(d.fix_unidentifiable),
            priors: match s
                .prior
                .as_ref()
                .or(defaults.prior.as_ref())
                .map(String::as_str)
            {
                None | Some("model") => true,
                Some("none") => false,
                Some(other) => bail!("prior must be \"model\" or \"none\", not {other:?}"),
            },
            marker_noise_mm: s.marker_noise_mm.or(defaults.marker_noise_mm),
            max_iterations: s.max_iter.or(defaults.max_iter),
            accept_rejected: s
                .accept_rejected
                .or(defaults.accept_rejected)
                .unwrap_or(d.accept_rejected),
        },
    };
    job.fit.check().map_err(anyhow::Error::msg)?;
    Ok(job)
}

/// Reads a manifest into jobs (paths resolved against its folder).
fn read_manifest(path: &Path) -> Result<Vec<Job>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let manifest: Manifest = toml::from_str(&text).map_err(|e| {
        let line = e.span().map_or(String::new(), |s| {
            format!("line {}: ", text[..s.start].matches('\n').count() + 1)
        });
        anyhow::anyhow!("{}: {line}{}", path.display(), e.message())
    })?;
    if manifest.job.is_empty() {
        bail!("{}: no [[job]] tables", path.display());
    }
    if manifest.job.len() > MAX_JOBS {
        bail!(
            "{}: {} jobs; a manifest holds at most {MAX_JOBS} (split it)",
            path.display(),
            manifest.job.len()
        );
    }
    let base = path.parent().unwrap_or(Path::new("."));
    manifest
        .job
        .into_iter()
        .map(|entry| {
            let id = entry.id.clone();
            to_job(entry, &manifest.defaults, base)
                .with_context(|| format!("{}: job {id:?}", path.display()))
        })
        .collect()
}

/// Refuses a batch whose outputs (the results table, each job's saved result and fitted
/// model) would replace one of its inputs (the manifest, a model or trial file) or each other.
fn check_files(args: &BatchArgs, jobs: &[Job]) -> Result<()> {
    let mut files = crate::output::Files::new().input("manifest", &args.manifest);
    for job in jobs {
        if let ModelInput::Named(m) = &job.model {
            files = files.model(&format!("model of job {:?}", job.id), m);
        }
        for t in &job.trials {
            if let TrialInput::Path(p) = t {
                files = files.input(&format!("trial of job {:?}", job.id), p);
            }
        }
    }
    for name in ["results.csv", "results.json"] {
        files = files.output_in_dir(name, &args.output, name);
    }
    let (saved, models) = (args.output.join("jobs"), args.output.join("models"));
    for job in jobs {
        files = files
            .output_in_dir("saved result", &saved, &format!("{}.json", job.id))
            .output_in_dir("fitted model", &models, &format!("{}.toml", job.id));
    }
    files.check()
}

pub fn run(args: BatchArgs) -> Result<()> {
    let jobs = read_manifest(&args.manifest)?;
    check_files(&args, &jobs)?;
    let threads = if args.jobs == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        usize::from(args.jobs)
    };
    let clock = Instant::now();
    let done = AtomicUsize::new(0);
    let stderr = Mutex::new(());
    let outcomes = run_batch(&jobs, Some(&args.output), threads, |_, o: &Outcome| {
        let k = done.fetch_add(1, Ordering::SeqCst) + 1;
        let status = match (&o.result, o.resumed) {
            (Ok(_), true) => "done earlier, skipped".to_string(),
            (Ok(c), false) => format!(
                "ok, RMS {:.2} → {:.2} mm",
                c.rms_before * 1e3,
                c.rms_after * 1e3
            ),
            (Err(e), _) => format!("FAILED: {e}"),
        };
        let _guard = stderr.lock();
        eprintln!(
            "jointfit: batch [{k}/{}] {:.1} s: {}: {status}",
            jobs.len(),
            clock.elapsed().as_secs_f64(),
            o.id
        );
    })?;
    let seconds = clock.elapsed().as_secs_f64();
    let fitted = outcomes
        .iter()
        .filter(|o| o.result.is_ok() && !o.resumed)
        .count();
    let failed = outcomes.iter().filter(|o| o.result.is_err()).count();
    if args.json {
        println!("{}", jointfit_io::batch::table::json(&outcomes));
    } else {
        let mut t = crate::table::Table::new(&[
            "job",
            "status",
            "RMS before mm",
            "RMS after mm",
            "warnings",
        ]);
        for o in &outcomes {
            match &o.result {
                Ok(c) => t.row(vec![
                    o.id.clone(),
                    if o.resumed { "ok (earlier run)" } else { "ok" }.into(),
                    format!("{:.2}", c.rms_before * 1e3),
                    format!("{:.2}", c.rms_after * 1e3),
                    c.warnings.len().to_string(),
                ]),
                Err(e) => t.row(vec![
                    o.id.clone(),
                    format!("failed: {e}"),
                    "-".into(),
                    "-".into(),
                    "-".into(),
                ]),
            }
        }
        print!("{}", t.render());
        println!(
            "{} jobs ({fitted} fitted, {} from an earlier run, {failed} failed) in {seconds:.2} s on {threads} threads ({:.2} fitted jobs/s)",
            outcomes.len(),
            outcomes.iter().filter(|o| o.resumed).count(),
            fitted as f64 / seconds.max(1e-9)
        );
        println!(
            "wrote {} and {}",
            args.output.join("results.csv").display(),
            args.output.join("results.json").display()
        );
    }
    if failed > 0 {
        return Err(crate::output::PartialFailure(format!(
            "{failed} of {} jobs failed (their errors are in {})",
            outcomes.len(),
            args.output.join("results.csv").display()
        ))
        .into());
    }
    Ok(())
}
