//! Batches of calibrations: many subjects × trials, one result per job, in job order.
//!
//! A [`Job`] is a [`Request`] (the model, its trials, how to read them and how to fit) with
//! a name; each runs through the pipeline ([`crate::run`]). [`run_batch`] runs many on a rayon pool of a given size and, with an output directory,
//! keeps each finished job's result in `DIR/jobs/<id>.json` so that a rerun skips it
//! (resumable), then writes the results table (`results.csv`, `results.json`, see
//! [`table`]) and each fitted model (`DIR/models/<id>.toml`).
//!
//! Every job is independent and every solver is deterministic, so the results do not depend
//! on the number of threads or on the order the jobs finish in. A failing job yields its error message (the command line's one-line text)
//! and the others go on.

pub mod table;

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::{message, Calibration, ModelSource, Request, TrialSource};

/// One calibration of a batch: a request and the name of its results.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// Unique name of the job (file names of its results).
    pub id: String,
    pub request: Request,
}

/// What became of one job of a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    pub id: String,
    /// The calibration, or the one-line error message.
    pub result: Result<Calibration, String>,
    /// Taken from an earlier run's saved result instead of being fitted again.
    pub resumed: bool,
}

/// Errors of the batch itself (not of its jobs).
#[derive(Debug, Error)]
pub enum BatchError {
    #[error("job id {0:?} appears twice")]
    DuplicateId(String),
    #[error(
        "job id {0:?} cannot name a file (at most 100 characters: letters, digits, '-', '_', '.')"
    )]
    BadId(String),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot start {threads} worker threads: {message}")]
    Pool { threads: usize, message: String },
}

/// A job's saved result: the job it answers (to tell a changed job from a finished one) and
/// the calibration.
#[derive(Serialize, Deserialize)]
struct Saved {
    job: String,
    calibration: Calibration,
}

/// A description of the job that changes whenever its inputs or settings change.
fn fingerprint(job: &Job) -> String {
    let request = &job.request;
    let model = match &request.model {
        ModelSource::Named(n) if Path::new(n).is_file() => {
            jointfit_io::content_hash::hash_files_and(&[Path::new(n)], "")
                .unwrap_or_else(|e| format!("unreadable: {e}"))
        }
        ModelSource::Named(n) => n.clone(),
        ModelSource::Spec(s) => s.to_toml(),
        ModelSource::Osim(o) => o.text.clone(),
    };
    let trials: Vec<String> = request
        .trials
        .iter()
        .map(|t| match t {
            // By content (jointfit_io::content_hash), not path and time: an edited trial with the
            // same modification time is a changed job.
            TrialSource::Path(p) => jointfit_io::content_hash::hash_files_and(&[p.as_path()], "")
                .unwrap_or_else(|e| format!("unreadable: {e}")),
            TrialSource::Data { name, trial } => {
                format!("{name} ({} frames in memory)", trial.n_frames())
            }
        })
        .collect();
    serde_json::json!({
        "model": model,
        "trials": trials,
        "up": format!("{:?}", request.read.up),
        "filter_hz": request.read.filter_hz,
        "fit": request.fit,
    })
    .to_string()
}

/// Longest job id (characters `[A-Za-z0-9._-]`).
pub const MAX_ID_CHARS: usize = 100;

fn check_ids(jobs: &[Job]) -> Result<(), BatchError> {
    let mut seen = std::collections::HashSet::new();
    for j in jobs {
        // At most MAX_ID_CHARS: the id names the job's result files (`jobs/<id>.json`), which
        // must fit a file name (255 bytes) with room for the extension and a temporary prefix.
        let ok = !j.id.is_empty()
            && j.id.len() <= MAX_ID_CHARS
            && !j.id.starts_with('.')
            && j.id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
        if !ok {
            return Err(BatchError::BadId(j.id.clone()));
        }
        if !seen.insert(j.id.as_str()) {
            return Err(BatchError::DuplicateId(j.id.clone()));
        }
    }
    Ok(())
}

fn saved_result(dir: &Path, job: &Job) -> Option<Calibration> {
    let text = std::fs::read_to_string(dir.join("jobs").join(format!("{}.json", job.id))).ok()?;
    let saved: Saved = serde_json::from_str(&text).ok()?;
    (saved.job == fingerprint(job)).then_some(saved.calibration)
}

fn save_result(dir: &Path, job: &Job, cal: &Calibration) -> Result<(), BatchError> {
    let io = |path: PathBuf| move |source| BatchError::Io { path, source };
    let saved = Saved {
        job: fingerprint(job),
        calibration: cal.clone(),
    };
    let text = serde_json::to_string_pretty(&saved).expect("serializable");
    let path = dir.join("jobs").join(format!("{}.json", job.id));
    jointfit_io::atomic::write_atomic(&path, text.as_bytes()).map_err(io(path.clone()))?;
    let model = dir.join("models").join(format!("{}.toml", job.id));
    jointfit_io::model_file::save_spec(&model, &cal.model).map_err(io(model.clone()))
}

/// Runs `jobs` on `threads` worker threads (0: one per core). With `dir`, finished jobs
/// found there from an earlier run are skipped, and every result is saved as it finishes
/// and the results table is written at the end. `on_done(index, outcome)` is called as each
/// job finishes (from the worker threads, in completion order). Outcomes are in job order.
pub fn run_batch(
    jobs: &[Job],
    dir: Option<&Path>,
    threads: usize,
    on_done: impl Fn(usize, &Outcome) + Sync,
) -> Result<Vec<Outcome>, BatchError> {
    check_ids(jobs)?;
    if let Some(dir) = dir {
        for sub in ["jobs", "models"] {
            let path = dir.join(sub);
            std::fs::create_dir_all(&path).map_err(|source| BatchError::Io { path, source })?;
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| BatchError::Pool {
            threads,
            message: e.to_string(),
        })?;
    let outcomes: Vec<Result<Outcome, BatchError>> = pool.install(|| {
        jobs.par_iter()
            .enumerate()
            .map(|(k, job)| {
                let outcome = match dir.and_then(|d| saved_result(d, job)) {
                    Some(cal) => Outcome {
                        id: job.id.clone(),
                        result: Ok(cal),
                        resumed: true,
                    },
                    None => {
                        let result = crate::run(&job.request).map_err(|e| message(&e));
                        if let (Some(d), Ok(cal)) = (dir, &result) {
                            save_result(d, job, cal)?;
                        }
                        Outcome {
                            id: job.id.clone(),
                            result,
                            resumed: false,
                        }
                    }
                };
                on_done(k, &outcome);
                Ok(outcome)
            })
            .collect()
    });
    let outcomes = outcomes.into_iter().collect::<Result<Vec<_>, _>>()?;
    if let Some(dir) = dir {
        table::write_tables(dir, &outcomes)?;
    }
    Ok(outcomes)
}

#[cfg(test)]
mod tests;
