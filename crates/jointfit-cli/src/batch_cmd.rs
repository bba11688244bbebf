//! `jointfit batch MANIFEST -o DIR [--jobs N]`: many calibrations on one machine.
//!
//! This file only parses the manifest, reports progress and prints; every job is a request
//! of the calibration pipeline (`jointfit_app`) and the runner (a rayon pool, resumption,
//! the results table) is `jointfit_app::batch`.
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
use jointfit::spatial::UpAxis;
use jointfit_app::batch::{run_batch, Job, Outcome};
use jointfit_app::{FitOptions, ModelSource, ReadOptions, Request, TrialSource};
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
    match s.parse::<UpAxis>() {
        Ok(up) => Ok(Some(up)),
        Err(_) => bail!("up must be \"y\", \"-y\", \"z\", \"-z\", \"x\" or \"-x\", not {s:?}"),
    }
}

impl Settings {
    /// These settings, each missing one taken from `defaults`.
    fn or(&self, defaults: &Settings) -> Settings {
        let d = defaults.clone();
        let s = self.clone();
        Settings {
            up: s.up.or(d.up),
            joints: s.joints.or(d.joints),
            method: s.method.or(d.method),
            filter: s.filter.or(d.filter),
            seed: s.seed.or(d.seed),
            bootstrap: s.bootstrap.or(d.bootstrap),
            threshold_mm: s.threshold_mm.or(d.threshold_mm),
            threshold_deg: s.threshold_deg.or(d.threshold_deg),
            starts: s.starts.or(d.starts),
            fix_unidentifiable: s.fix_unidentifiable.or(d.fix_unidentifiable),
            prior: s.prior.or(d.prior),
            marker_noise_mm: s.marker_noise_mm.or(d.marker_noise_mm),
            max_iter: s.max_iter.or(d.max_iter),
            accept_rejected: s.accept_rejected.or(d.accept_rejected),
        }
    }

    /// How the job's trial files are read.
    fn read_options(&self) -> Result<ReadOptions> {
        Ok(ReadOptions {
            up: match &self.up {
                Some(u) => parse_up(u)?,
                None => None,
            },
            filter_hz: match self.filter {
                Some(hz) => Some(bounded(
                    "filter",
                    hz,
                    crate::validate::MIN_FILTER_HZ,
                    crate::validate::MAX_RATE_HZ,
                )?),
                None => None,
            },
        })
    }

    /// The fit options: the calibrate command's defaults where the manifest says nothing,
    /// checked against its limits.
    fn fit_options(&self) -> Result<FitOptions> {
        let d = FitOptions::default();
        let fit = FitOptions {
            joints: self.joints.clone().unwrap_or(d.joints),
            method: match &self.method {
                Some(m) => m.parse().map_err(anyhow::Error::msg)?,
                None => d.method,
            },
            seed: self.seed.unwrap_or(d.seed),
            bootstrap: self.bootstrap.unwrap_or(d.bootstrap),
            threshold_mm: self.threshold_mm.unwrap_or(d.threshold_mm),
            threshold_deg: self.threshold_deg.unwrap_or(d.threshold_deg),
            starts: self.starts.unwrap_or(d.starts),
            fix_unidentifiable: self.fix_unidentifiable.unwrap_or(d.fix_unidentifiable),
            priors: match self.prior.as_deref() {
                None | Some("model") => true,
                Some("none") => false,
                Some(other) => bail!("prior must be \"model\" or \"none\", not {other:?}"),
            },
            marker_noise_mm: self.marker_noise_mm,
            max_iterations: self.max_iter,
            accept_rejected: self.accept_rejected.unwrap_or(d.accept_rejected),
            ..d
        };
        fit.check().map_err(anyhow::Error::msg)?;
        Ok(fit)
    }
}

/// `path` of the manifest, relative to its folder `base` unless absolute.
fn relative_to(base: &Path, path: &str) -> PathBuf {
    let p = Path::new(path);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

fn to_job(entry: JobEntry, defaults: &Settings, base: &Path) -> Result<Job> {
    let settings = entry.settings.or(defaults);
    let builtin = jointfit::model::lower_limb::BUILTIN_NAMES.contains(&entry.model.as_str());
    let model = if builtin && !relative_to(base, &entry.model).exists() {
        entry.model.clone()
    } else {
        relative_to(base, &entry.model).display().to_string()
    };
    Ok(Job {
        id: entry.id,
        request: Request {
            model: ModelSource::Named(model),
            trials: entry
                .trials
                .iter()
                .map(|t| TrialSource::Path(relative_to(base, t)))
                .collect(),
            read: settings.read_options()?,
            fit: settings.fit_options()?,
        },
    })
}

/// Reads a manifest into jobs (paths resolved against its folder).
fn read_manifest(path: &Path) -> Result<Vec<Job>> {
    let text =
        jointfit_io::limits::read_text(path, jointfit_io::limits::DOCUMENT_BYTES, "manifest")
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
        if let ModelSource::Named(m) = &job.request.model {
            files = files.model(&format!("model of job {:?}", job.id), m);
        }
        for t in &job.request.trials {
            if let TrialSource::Path(p) = t {
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
        println!("{}", jointfit_app::batch::table::json(&outcomes));
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
