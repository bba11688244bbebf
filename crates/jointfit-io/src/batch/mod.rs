//! Batches of calibrations: many subjects × trials, one result per job, in job order.
//!
//! A [`Job`] names a model (file or built-in, or a description in memory), its trials (files
//! or trials in memory), how to read them and how to fit. [`run_job`] reads and fits one job;
//! [`run_batch`] runs many on a rayon pool of a given size and, with an output directory,
//! keeps each finished job's result in `DIR/jobs/<id>.json` so that a rerun skips it
//! (resumable), then writes the results table (`results.csv`, `results.json`, see
//! [`table`]) and each fitted model (`DIR/models/<id>.toml`).
//!
//! Every job is independent and every solver is deterministic, so the results do not depend
//! on the number of threads or on the order the jobs finish in. Both the command line
//! (`jointfit batch`) and the Python package (`jointfit.batch`) run jobs through
//! [`run_job`]. A failing job yields its error message (the command line's one-line text)
//! and the others go on.

pub mod fit;
pub mod table;

use std::path::{Path, PathBuf};

use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError};
use jointfit::signal::{filter_trial, LowPass, SignalError};
use jointfit::trial::{up_axis_rotation, Trial, UpAxis};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;

pub use fit::{calibrate, Calibration, FitOptions, Method, ParamRow};

use crate::model_file::ModelFileError;
use crate::trial_file::TrialFileError;

/// The model of a job.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelInput {
    /// A TOML file path or a built-in name, as on the command line.
    Named(String),
    /// A description in memory (e.g. sent by value to a cluster worker).
    Spec(Box<ModelSpec>),
}

/// A trial of a job.
#[derive(Debug, Clone, PartialEq)]
pub enum TrialInput {
    /// A motion file (.c3d, .trc), read with the job's [`ReadOptions`].
    Path(PathBuf),
    /// A trial in memory, already Y-up; only the low-pass filter applies.
    Data { name: String, trial: Box<Trial> },
}

/// How trial files are read.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReadOptions {
    /// The laboratory's vertical axis; `None`: the subject model's `lab_up` when a job reads
    /// its trials ([`run_job`]), else `Y` (no rotation).
    pub up: Option<UpAxis>,
    /// Low-pass cutoff (Hz) of the zero-phase Butterworth filter; `None`: unfiltered.
    pub filter_hz: Option<f64>,
}

/// One calibration to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// Unique name of the job (file names of its results).
    pub id: String,
    pub model: ModelInput,
    pub trials: Vec<TrialInput>,
    pub read: ReadOptions,
    pub fit: FitOptions,
}

/// Why a job failed. The display is the command line's message for the same failure.
#[derive(Debug, Error)]
pub enum JobError {
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    #[error("{name}: invalid model: {source}")]
    Model { name: String, source: ModelError },
    #[error(transparent)]
    TrialFile(#[from] TrialFileError),
    #[error("{name}: filtering at {hz} Hz: {source}")]
    Filter {
        name: String,
        hz: f64,
        source: SignalError,
    },
    #[error(transparent)]
    Calibrate(#[from] jointfit::workflow::WorkflowError),
    #[error("job has no trials")]
    NoTrials,
    /// The verdict of the fit (or of its inputs) is `reject`: the cause.
    #[error("rejected: {0}")]
    Rejected(String),
}

/// The one-line message of an error and its causes, as the command line prints it after
/// `jointfit: error: ` ([`crate::message::of_error`]).
pub fn message(e: &(dyn std::error::Error + 'static)) -> String {
    crate::message::of_error(e)
}

/// Filtering that moves a marker further than this is reported (m).
const FILTER_WARNING_M: f64 = 0.02;

/// Rotates `trial` to Y-up and low-pass filters it; returns the warnings (markers moved by
/// more than 2 cm by the filter).
pub fn prepare_trial(
    mut trial: Trial,
    name: &str,
    up: Option<UpAxis>,
    filter_hz: Option<f64>,
) -> Result<(Trial, Vec<String>), JobError> {
    if let Some(up) = up {
        trial.rotate(&up_axis_rotation(up));
    }
    let mut warnings = Vec::new();
    if let Some(hz) = filter_hz {
        let lp = LowPass {
            cutoff_hz: hz,
            ..LowPass::default()
        };
        let (filtered, report) = filter_trial(&trial, &lp).map_err(|source| JobError::Filter {
            name: name.to_string(),
            hz,
            source,
        })?;
        for m in report.moved_more_than(FILTER_WARNING_M) {
            warnings.push(format!(
                "{name}: filtering moved marker {} by {:.1} mm",
                m.label,
                m.max_displacement_m * 1e3
            ));
        }
        trial = filtered;
    }
    Ok((trial, warnings))
}

/// Reads a motion file (rotated to Y-up, filtered as asked) and its warnings.
pub fn read_trial(path: &Path, read: &ReadOptions) -> Result<(Trial, Vec<String>), JobError> {
    let trial = crate::trial_file::read_trial(path)?;
    let name = path.display().to_string();
    let up = read.up.unwrap_or(UpAxis::Y);
    let rotated = jointfit::vertical::rotation_warning(&trial, up, &format!("up {up}"));
    let (trial, mut warnings) = prepare_trial(trial, &name, Some(up), read.filter_hz)?;
    warnings.extend(rotated.map(|w| format!("{name}: {w}")));
    Ok((trial, warnings))
}

fn load_model(input: &ModelInput) -> Result<Model, JobError> {
    match input {
        ModelInput::Named(name) => Ok(crate::model_file::load_model(name)?),
        ModelInput::Spec(spec) => Model::compile(spec).map_err(|source| JobError::Model {
            name: spec.name.clone(),
            source,
        }),
    }
}

/// Reads and fits one job, starting from the model's nominal parameters.
pub fn run_job(job: &Job) -> Result<Calibration, JobError> {
    run_job_observed(job, &mut jointfit::workflow::NoObserver)
}

/// [`run_job`] reporting the fit's progress to `observer`.
pub fn run_job_observed(
    job: &Job,
    observer: &mut dyn jointfit::workflow::Observer,
) -> Result<Calibration, JobError> {
    let model = load_model(&job.model)?;
    if job.trials.is_empty() {
        return Err(JobError::NoTrials);
    }
    let mut warnings = Vec::new();
    let mut trials = Vec::with_capacity(job.trials.len());
    // The vertical: the job's, else the subject model's (`lab_up`, from personalize).
    let read = ReadOptions {
        up: job.read.up.or(model.spec().lab_up),
        ..job.read
    };
    for t in &job.trials {
        let (trial, w) = match t {
            TrialInput::Path(p) => read_trial(p, &read)?,
            TrialInput::Data { name, trial } => {
                prepare_trial((**trial).clone(), name, None, job.read.filter_hz)?
            }
        };
        warnings.extend(w);
        trials.push(trial);
    }
    let refs: Vec<&Trial> = trials.iter().collect();
    let mut cal =
        match fit::calibrate_observed(&model, model.nominal_params(), &refs, &job.fit, observer) {
            Err(jointfit::workflow::WorkflowError::Mismatch { trial, cause }) => {
                let name = match &job.trials[trial] {
                    TrialInput::Path(p) => p.display().to_string(),
                    TrialInput::Data { name, .. } => name.clone(),
                };
                return Err(JobError::Rejected(format!("{name}: {cause}")));
            }
            r => r?,
        };
    if cal.verdict.level == jointfit::workflow::Level::Reject && !job.fit.accept_rejected {
        return Err(JobError::Rejected(
            cal.verdict.reasons.first().cloned().unwrap_or_default(),
        ));
    }
    warnings.append(&mut cal.warnings);
    cal.warnings = warnings;
    Ok(cal)
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
    let model = match &job.model {
        ModelInput::Named(n) if Path::new(n).is_file() => {
            crate::content_hash::hash_files_and(&[Path::new(n)], "")
                .unwrap_or_else(|e| format!("unreadable: {e}"))
        }
        ModelInput::Named(n) => n.clone(),
        ModelInput::Spec(s) => s.to_toml(),
    };
    let trials: Vec<String> = job
        .trials
        .iter()
        .map(|t| match t {
            // By content (crate::content_hash), not path and time: an edited trial with the
            // same modification time is a changed job.
            TrialInput::Path(p) => crate::content_hash::hash_files_and(&[p.as_path()], "")
                .unwrap_or_else(|e| format!("unreadable: {e}")),
            TrialInput::Data { name, trial } => {
                format!("{name} ({} frames in memory)", trial.n_frames())
            }
        })
        .collect();
    serde_json::json!({
        "model": model,
        "trials": trials,
        "up": format!("{:?}", job.read.up),
        "filter_hz": job.read.filter_hz,
        "fit": job.fit,
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
    crate::atomic::write_atomic(&path, text.as_bytes()).map_err(io(path.clone()))?;
    let model = dir.join("models").join(format!("{}.toml", job.id));
    crate::model_file::save_spec(&model, &cal.model).map_err(io(model.clone()))
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
                        let result = run_job(job).map_err(|e| message(&e));
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
