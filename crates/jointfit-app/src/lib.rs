//! The one calibration pipeline every front end of jointfit calls: the command line's
//! `calibrate` (a jointfit model or an `.osim`), `batch` and `demo`, and the Python package's
//! `calibrate` and batches.
//!
//! ```text
//! Request { model: ModelSource, trials: [TrialSource], read: ReadOptions, fit: FitOptions }
//!   │ read::load_subject      model file, built-in name, description, or .osim (+ selection)
//!   │ read::read_trials       C3D/TRC files or trials in memory → Y-up, low-pass filtered
//!   │ pipeline::fit           FitOptions::settings → workflow::refine::calibrate_refined
//!   │                         (.osim: osim::personalize → jointfit::workflow::redundant::calibrate_holding_redundant)
//!   │ pipeline::gate          the verdict: `reject` is an error unless accept_rejected
//!   ▼ fit::summarize_*        Calibration: SI (m, rad), one row per free parameter, warnings
//! ```
//!
//! [`run`] runs every stage; a front end with more to do between stages (the command line
//! edits priors, reads trials with repairs and data checks, prints the core's whole result)
//! calls the stages itself, in the same order. [`FitOptions::settings`] is the one mapping
//! from the options of a calibration to the core's [`jointfit::workflow::FitSettings`], so
//! every front end fits the same way from the same options. Inside, everything is SI; the
//! presentation (mm and degrees, sentences) is the front ends' ([`Calibration`] carries SI
//! values only).
//!
//! [`batch`] runs many requests on a thread pool, resumable, and writes the results table.

pub mod batch;
pub mod fit;
pub mod osim;
mod pipeline;
pub mod present;
pub mod read;
pub mod scale;
mod trial_checks;

use jointfit::model::ModelError;
use jointfit_io::model_file::ModelFileError;
use jointfit_io::osim_read::OsimReadError;
use jointfit_io::trial_file::TrialFileError;
use jointfit_signal::SignalError;
use thiserror::Error;

pub use fit::{Calibration, FitOptions, Method, ParamRow};
pub use pipeline::{fit, gate, name_trial, run, run_observed, Detail, Fitted, Request};
pub use read::{
    check_plausible, load_subject, prepare_trial, read_trial, read_trials, ModelSource,
    ReadOptions, Subject, TrialSource,
};
pub use trial_checks::{check_markers, check_motion};

/// Why a request failed. The display is the command line's message for the same failure.
#[derive(Debug, Error)]
pub enum Error {
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    #[error(transparent)]
    OsimFile(#[from] OsimReadError),
    #[error("{name}: invalid model: {source}")]
    Model { name: String, source: ModelError },
    /// A selection of offset scalars given for a model that is not an `.osim`.
    #[error("{0}: selecting offset frames needs an .osim model")]
    ParamsNeedOsim(String),
    #[error(transparent)]
    Selection(#[from] jointfit_io::osim_read::personalize::SelectionError),
    #[error(transparent)]
    Osim(#[from] osim::OsimFitError),
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
    /// Trial data no measurement can give (a rate, a coordinate, the units): the cause.
    #[error("{0}")]
    Implausible(String),
    #[error("no trials to fit")]
    NoTrials,
    /// The verdict of the fit (or of its inputs) is `reject`: the cause.
    #[error("rejected: {0}")]
    Rejected(String),
}

/// The one-line message of an error and its causes, as the command line prints it after
/// `jointfit: error: ` ([`jointfit_io::message::of_error`]).
pub fn message(e: &(dyn std::error::Error + 'static)) -> String {
    jointfit_io::message::of_error(e)
}
