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
//! filter = 6.0               # Hz; seed, bootstrap, threshold_mm, threshold_deg as for calibrate
//! ```

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
pub struct BatchArgs {
    /// Manifest (TOML): one [[job]] table per calibration (see `jointfit batch --help`).
    pub manifest: PathBuf,
    /// Output folder: results.csv, results.json, jobs/<id>.json, models/<id>.toml.
    /// Jobs already finished there (same inputs and settings) are skipped.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
    /// Print the results table as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

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
    Ok(Job {
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
            filter_hz: s.filter.or(defaults.filter),
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
        },
    })
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

pub fn run(args: BatchArgs) -> Result<()> {
    let jobs = read_manifest(&args.manifest)?;
    let threads = if args.jobs == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        args.jobs
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
