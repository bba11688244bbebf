//! The read and prepare stages: the model of a request ([`ModelSource`] → [`Subject`]) and
//! its trials ([`TrialSource`] → [`Trial`], rotated to Y-up and low-pass filtered).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit::spatial::up_axis_rotation;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_io::osim_read::{read_osim, OsimModel};
use jointfit_signal::filter_trial;
use jointfit_signal::LowPass;

use crate::fit::FitOptions;
use crate::Error;

/// The model of a request.
#[derive(Debug, Clone)]
pub enum ModelSource {
    /// A model file path (TOML or `.osim`) or a built-in name, as on the command line.
    Named(String),
    /// A description in memory (e.g. sent by value to a cluster worker).
    Spec(Box<ModelSpec>),
    /// An OpenSim model already read: its selected offsets are personalized
    /// ([`crate::osim`]) and the fitted values written back into its text.
    Osim(Arc<OsimModel>),
}

impl ModelSource {
    /// `name` as the command line takes it: an `.osim` file is read now (so that a front end
    /// can keep it, to write the fitted offsets back), anything else stays a name.
    pub fn read(name: &str) -> Result<ModelSource, Error> {
        if jointfit_io::model_file::is_osim(Path::new(name)) {
            Ok(ModelSource::Osim(Arc::new(read_osim(Path::new(name))?)))
        } else {
            Ok(ModelSource::Named(name.to_string()))
        }
    }
}

impl PartialEq for ModelSource {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (ModelSource::Named(a), ModelSource::Named(b)) => a == b,
            (ModelSource::Spec(a), ModelSource::Spec(b)) => a == b,
            (ModelSource::Osim(a), ModelSource::Osim(b)) => a.text == b.text,
            _ => false,
        }
    }
}

/// A trial of a request.
#[derive(Debug, Clone, PartialEq)]
pub enum TrialSource {
    /// A motion file (.c3d, .trc), read with the request's [`ReadOptions`].
    Path(PathBuf),
    /// A trial in memory, already Y-up; only the low-pass filter applies.
    Data { name: String, trial: Box<Trial> },
}

impl TrialSource {
    /// The name messages give the trial: its path, or the name given with the data.
    pub fn name(&self) -> String {
        match self {
            TrialSource::Path(p) => p.display().to_string(),
            TrialSource::Data { name, .. } => name.clone(),
        }
    }
}

/// How trial files are read.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReadOptions {
    /// The laboratory's vertical axis; `None`: the subject model's `lab_up` ([`read_trials`]),
    /// else `Y` (no rotation).
    pub up: Option<UpAxis>,
    /// Low-pass cutoff (Hz) of the zero-phase Butterworth filter; `None`: unfiltered.
    pub filter_hz: Option<f64>,
}

/// The model a request fits, prepared: native models compiled as read; an OpenSim model's
/// selected offset scalars turned into parameters ([`crate::osim::selection_spec`]).
#[derive(Debug, Clone)]
pub struct Subject {
    /// The model to fit. A front end may edit its description (priors, marker weights) and
    /// recompile it with [`Subject::with_spec`].
    pub model: Model,
    /// The OpenSim model it came from, if any.
    pub osim: Option<Arc<OsimModel>>,
}

impl Subject {
    /// The same subject with an edited description (e.g. other priors or marker weights).
    pub fn with_spec(&self, spec: &ModelSpec) -> Result<Subject, Error> {
        Ok(Subject {
            model: compile(spec)?,
            osim: self.osim.clone(),
        })
    }

    /// The laboratory's vertical the subject's trials were recorded with (`lab_up`).
    pub fn lab_up(&self) -> Option<UpAxis> {
        self.model.spec().lab_up
    }
}

fn compile(spec: &ModelSpec) -> Result<Model, Error> {
    Model::compile(spec).map_err(|source| Error::Model {
        name: spec.name.clone(),
        source,
    })
}

/// Reads and prepares the model of a request: a native model is loaded and compiled; an
/// OpenSim model (read, or named by an `.osim` path) gets `fit.joints` (whole joints; the
/// default `all` names none) and `fit.params` (finer selections) as its parameters. A
/// native model refuses `fit.params`.
pub fn load_subject(source: &ModelSource, fit: &FitOptions) -> Result<Subject, Error> {
    let osim = match source {
        ModelSource::Osim(osim) => osim.clone(),
        ModelSource::Named(name) if jointfit_io::model_file::is_osim(Path::new(name)) => {
            Arc::new(read_osim(Path::new(name))?)
        }
        ModelSource::Named(name) => {
            refuse_params(name, fit)?;
            let model = jointfit_io::model_file::load_model(name)?;
            return Ok(Subject { model, osim: None });
        }
        ModelSource::Spec(spec) => {
            refuse_params(&spec.name, fit)?;
            return Ok(Subject {
                model: compile(spec)?,
                osim: None,
            });
        }
    };
    let joints: Vec<String> = fit.joints.iter().filter(|j| *j != "all").cloned().collect();
    let spec = crate::osim::selection_spec(&osim, &joints, &fit.params)?;
    Ok(Subject {
        model: compile(&spec)?,
        osim: Some(osim),
    })
}

fn refuse_params(model: &str, fit: &FitOptions) -> Result<(), Error> {
    if fit.params.is_empty() {
        Ok(())
    } else {
        Err(Error::ParamsNeedOsim(model.to_string()))
    }
}

/// Largest plausible sampling rate (Hz).
pub const MAX_RATE_HZ: f64 = 100_000.0;
/// Largest plausible marker coordinate (m).
pub const MAX_POSITION_M: f64 = 1_000.0;

/// The data of a trial are plausible: rate at most [`MAX_RATE_HZ`], every recorded coordinate
/// within ±[`MAX_POSITION_M`] m. The error names the trial (`name`), the frame (file
/// numbering) and the marker, or the units when the markers' span says they are wrong
/// ([`jointfit::checks::check_scale`]: millimetre data declared as metres). Missing samples
/// are fine here.
pub fn check_plausible(trial: &Trial, name: &str) -> Result<(), Error> {
    let implausible = |what: String| Err(Error::Implausible(format!("{name}: {what}")));
    if trial.rate() > MAX_RATE_HZ {
        return implausible(format!(
            "frame rate {:e} Hz is implausible (limit {MAX_RATE_HZ} Hz)",
            trial.rate()
        ));
    }
    for f in 0..trial.n_frames() {
        for (m, p) in trial.frame(f).iter().enumerate() {
            if p.x.is_nan() || p.iter().all(|v| v.abs() <= MAX_POSITION_M) {
                continue;
            }
            // Millimetre data declared as metres land here: say so when the whole trial's
            // scale points to the units rather than one wild sample.
            let too_wide = jointfit::checks::marker_span(trial)
                .is_some_and(|span| span > jointfit::checks::PLAUSIBLE_SPAN[1]);
            if let Some(units) = jointfit::checks::check_scale(trial).filter(|_| too_wide) {
                return implausible(units.message);
            }
            return implausible(format!(
                "frame {}, marker {}: position ({:e}, {:e}, {:e}) m is beyond \
                 ±{MAX_POSITION_M} m, not a plausible measurement",
                trial.first_frame() + f as i64,
                trial.labels()[m],
                p.x,
                p.y,
                p.z
            ));
        }
    }
    Ok(())
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
) -> Result<(Trial, Vec<String>), Error> {
    if let Some(up) = up {
        trial.rotate(&up_axis_rotation(up));
    }
    let mut warnings = Vec::new();
    if let Some(hz) = filter_hz {
        let lp = LowPass {
            cutoff_hz: hz,
            ..LowPass::default()
        };
        let (filtered, report) = filter_trial(&trial, &lp).map_err(|source| Error::Filter {
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

/// Reads a motion file (checked plausible, rotated to Y-up, filtered as asked) and its
/// warnings.
pub fn read_trial(path: &Path, read: &ReadOptions) -> Result<(Trial, Vec<String>), Error> {
    let trial = jointfit_io::trial_file::read_trial(path)?;
    let name = path.display().to_string();
    check_plausible(&trial, &name)?;
    let up = read.up.unwrap_or(UpAxis::Y);
    let rotated = crate::present::rotation_warning(&trial, up, &format!("up {up}"));
    let (trial, mut warnings) = prepare_trial(trial, &name, Some(up), read.filter_hz)?;
    warnings.extend(rotated.map(|(w, axis)| {
        format!(
            "{name}: {w}; {} if that is right",
            crate::present::read_with_up(axis)
        )
    }));
    Ok((trial, warnings))
}

/// Reads and prepares every trial, in order: files with `read` (the vertical: `read.up`,
/// else `lab_up`, the subject model's), trials in memory filtered only. Returns the trials
/// and the warnings of their reading.
pub fn read_trials(
    sources: &[TrialSource],
    read: &ReadOptions,
    lab_up: Option<UpAxis>,
) -> Result<(Vec<Trial>, Vec<String>), Error> {
    if sources.is_empty() {
        return Err(Error::NoTrials);
    }
    let files = ReadOptions {
        up: read.up.or(lab_up),
        ..*read
    };
    let mut warnings = Vec::new();
    let mut trials = Vec::with_capacity(sources.len());
    for t in sources {
        let (trial, w) = match t {
            TrialSource::Path(p) => read_trial(p, &files)?,
            TrialSource::Data { name, trial } => {
                prepare_trial((**trial).clone(), name, None, read.filter_hz)?
            }
        };
        warnings.extend(w);
        trials.push(trial);
    }
    Ok((trials, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn implausible_data_are_named_by_frame_and_marker() {
        let labels = vec!["A".to_string(), "B".to_string()];
        let mut pos = vec![Vector3::new(0.1, 0.2, 0.3); 6];
        let t = Trial::new(labels.clone(), 100.0, 1, pos.clone()).unwrap();
        check_plausible(&t, "t.trc").unwrap();
        pos[3] = Vector3::new(1e300, 0.0, 0.0);
        let t = Trial::new(labels.clone(), 100.0, 1, pos).unwrap();
        let e = check_plausible(&t, "t.trc").unwrap_err().to_string();
        assert!(e.starts_with("t.trc: frame 2, marker B: position"), "{e}");
        let t = Trial::new(labels.clone(), 1e300, 1, vec![Vector3::zeros(); 2]).unwrap();
        let e = check_plausible(&t, "t.trc").unwrap_err().to_string();
        assert!(e.contains("frame rate 1e300 Hz is implausible"), "{e}");
        let t = Trial::new(labels, 100.0, 1, vec![Vector3::repeat(f64::NAN); 4]).unwrap();
        check_plausible(&t, "t.trc").unwrap();
    }

    /// Millimetre data declared as metres (the pelvis 1000 m up): the error names the units.
    #[test]
    fn millimetres_declared_as_metres_are_named_as_units() {
        let labels: Vec<String> = ["RASI", "LASI", "RPSI", "LPSI", "RKNE", "RTOE"]
            .map(String::from)
            .to_vec();
        let frame = [
            Vector3::new(120.0, 1010.0, 30.0),
            Vector3::new(-130.0, 1005.0, 35.0),
            Vector3::new(50.0, 1060.0, -140.0),
            Vector3::new(-55.0, 1058.0, -138.0),
            Vector3::new(110.0, 520.0, 40.0),
            Vector3::new(100.0, 40.0, 180.0),
        ];
        let pos: Vec<Vector3<f64>> = (0..5).flat_map(|_| frame).collect();
        let t = Trial::new(labels, 100.0, 1, pos).unwrap();
        let e = check_plausible(&t, "w.trc").unwrap_err().to_string();
        assert!(e.starts_with("w.trc: the markers span"), "{e}");
        assert!(e.contains("millimetre data read as metres"), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }
}
