//! The stages after reading: fit ([`fit`]), verdict ([`gate`]) and the whole pipeline
//! ([`run`]).

use jointfit::calibrate::params_for_groups;
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::solver::Observer;
use jointfit::trial::Trial;
use jointfit::workflow::refine::{calibrate_refined, RefinedCalibration};
use jointfit::workflow::verdict::Level;
use jointfit::workflow::verdict::Verdict;
use jointfit::workflow::{self, WorkflowError};

use crate::fit::{Calibration, FitOptions};
use crate::osim::OsimFit;
use crate::read::{load_subject, read_trials, ModelSource, ReadOptions, Subject, TrialSource};
use crate::trial_checks::{check_markers, check_motion};
use crate::Error;

/// One calibration to run: the model, its trials, how to read them and how to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    pub model: ModelSource,
    pub trials: Vec<TrialSource>,
    pub read: ReadOptions,
    pub fit: FitOptions,
}

/// What the fit stage found: the core's whole result (for the command line's detailed text,
/// JSON and report) and its SI summary.
#[derive(Debug, Clone)]
pub struct Fitted {
    pub detail: Detail,
    /// The result in SI units, with its warnings (the one result every front end returns).
    pub summary: Calibration,
}

/// The core's result of a fit, by kind of model.
#[derive(Debug, Clone)]
pub enum Detail {
    /// A jointfit model: the calibration with the marker policy, the anatomical envelope and
    /// the prior–data conflict step ([`workflow::refine::calibrate_refined`]).
    Native(Box<RefinedCalibration>),
    /// An OpenSim model's offsets, the redundant ones held ([`crate::osim::personalize`]).
    Osim(Box<OsimFit>),
}

impl Fitted {
    /// The core's calibration (display units, every detail).
    pub fn calibration(&self) -> &jointfit::workflow::calibration::Calibration {
        match &self.detail {
            Detail::Native(r) => &r.calibration,
            Detail::Osim(o) => &o.result.calibration,
        }
    }

    /// The model that was fitted (with marker parameters after the input's, when the fit
    /// refined markers; an OpenSim model without the markers the trials lack).
    pub fn model(&self) -> &Model {
        match &self.detail {
            Detail::Native(r) => &r.model,
            Detail::Osim(o) => &o.model,
        }
    }

    /// Each joint's prior–data conflict ([`workflow::conflict`]).
    pub fn conflict(&self) -> &[workflow::conflict::JointConflict] {
        match &self.detail {
            Detail::Native(r) => &r.conflict,
            Detail::Osim(o) => &o.result.prior_conflict,
        }
    }
}

/// The fit stage: the `opts.joints` parameters of a native model (every parameter of an
/// OpenSim selection) fitted to `trials` from `start` (`None`: the model's values), and the
/// SI summary of the result.
pub fn fit(
    subject: &Subject,
    start: Option<Vec<f64>>,
    trials: &[&Trial],
    opts: &FitOptions,
    observer: &mut dyn Observer,
) -> Result<Fitted, Error> {
    let settings = opts.settings();
    if subject.osim.is_some() {
        let done =
            crate::osim::personalize(subject.model.spec(), start, trials, &settings, observer)
                .map_err(|e| match e {
                    crate::osim::OsimFitError::Workflow(w) => Error::Calibrate(w),
                    e => Error::Osim(e),
                })?;
        let summary = crate::fit::summarize_osim(&done, opts.method);
        return Ok(Fitted {
            detail: Detail::Osim(Box::new(done)),
            summary,
        });
    }
    let model = &subject.model;
    let start = start.unwrap_or_else(|| model.nominal_params());
    let groups: Vec<&str> = opts.joints.iter().map(String::as_str).collect();
    let free = params_for_groups(model, &groups).map_err(WorkflowError::from)?;
    let refined = calibrate_refined(model, &start, trials, &free, &settings, observer)?;
    let summary = crate::fit::summarize_refined(model, &start, &refined, opts.method);
    Ok(Fitted {
        detail: Detail::Native(Box::new(refined)),
        summary,
    })
}

/// The verdict stage: a `reject` verdict is an error (its first reason) unless `accept`.
pub fn gate(verdict: &Verdict, accept: bool) -> Result<(), Error> {
    if verdict.level == Level::Reject && !accept {
        return Err(Error::Rejected(
            verdict.reasons.first().cloned().unwrap_or_default(),
        ));
    }
    Ok(())
}

/// A refusal of the inputs ([`WorkflowError::Mismatch`]) as a rejection naming the trial.
pub fn name_trial(e: Error, names: &[String]) -> Error {
    match e {
        Error::Calibrate(WorkflowError::Mismatch { trial, cause }) => {
            let name = names
                .get(trial)
                .cloned()
                .unwrap_or_else(|| format!("trial {}", trial + 1));
            Error::Rejected(format!("{name}: {cause}"))
        }
        e => e,
    }
}

/// The whole pipeline: read the model and the trials, prepare them, fit, judge, summarize.
/// An unconverged fit is kept (with a warning); a rejected one is an error unless
/// `fit.accept_rejected`.
pub fn run(request: &Request) -> Result<Calibration, Error> {
    run_observed(request, &mut NoObserver)
}

/// [`run`] reporting the fit's progress to `observer`.
pub fn run_observed(request: &Request, observer: &mut dyn Observer) -> Result<Calibration, Error> {
    let subject = load_subject(&request.model, &request.fit)?;
    let (trials, mut warnings) = read_trials(&request.trials, &request.read, subject.lab_up())?;
    let refs: Vec<&Trial> = trials.iter().collect();
    let names: Vec<String> = request.trials.iter().map(TrialSource::name).collect();
    for (name, trial) in names.iter().zip(&refs) {
        check_markers(name, trial, &subject.model).map_err(Error::Implausible)?;
        check_motion(name, trial).map_err(Error::Implausible)?;
    }
    let fitted =
        fit(&subject, None, &refs, &request.fit, observer).map_err(|e| name_trial(e, &names))?;
    let mut cal = fitted.summary;
    gate(&cal.verdict, request.fit.accept_rejected)?;
    warnings.append(&mut cal.warnings);
    cal.warnings = warnings;
    Ok(cal)
}
