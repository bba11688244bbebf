//! The shared data `reproduce` reads: where they are, which files each part needs, and the
//! personalized subjects (biobuddy's functional trials, OpenCap's gait) with their trials.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use jointfit::model::lower_limb::Side;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{personalize, PersonalizeOptions};

use crate::common::{load_trial, Up};

pub(super) const BIOBUDDY: &str = "biobuddy_functional_vicon";
pub(super) const OPENCAP: &str = "opencap_expert1";

pub(super) fn data_dir(arg: &Option<PathBuf>) -> PathBuf {
    match arg {
        Some(d) => d.clone(),
        None => match std::env::var_os("JOINTFIT_DATA") {
            Some(d) => PathBuf::from(d),
            None => PathBuf::from("../shared/data"),
        },
    }
}

/// Every file a data-driven part needs, checked up front so the error lists all that is missing.
pub(super) fn require(data: &Path, files: &[&str], what: &str) -> Result<()> {
    if !data.is_dir() {
        bail!(
            "data directory {} not found (use --data or JOINTFIT_DATA); {what} needs {}{}",
            data.display(),
            files.join(", "),
            if what.starts_with("table 1") {
                "; `jointfit reproduce table1 --synthetic-only` runs without data"
            } else {
                ""
            }
        );
    }
    let missing: Vec<String> = files
        .iter()
        .filter(|f| !data.join(f).is_file())
        .map(|f| data.join(f).display().to_string())
        .collect();
    if !missing.is_empty() {
        bail!(
            "{what} needs files that are missing: {}",
            missing.join(", ")
        );
    }
    Ok(())
}

pub(super) fn needed_files(gait_trials: &[String]) -> Vec<String> {
    let mut v: Vec<String> = [
        "Test_func_anat.c3d",
        "Test_func_rhip.c3d",
        "Test_func_rknee.c3d",
        "Test_func_rankle.c3d",
    ]
    .iter()
    .map(|f| format!("{BIOBUDDY}/{f}"))
    .collect();
    v.push(format!("{OPENCAP}/static1.trc"));
    v.extend(gait_trials.iter().map(|f| format!("{OPENCAP}/{f}")));
    v
}

/// A personalized subject and its trials, loaded from the shared data.
pub(super) struct Subject {
    pub name: String,
    pub model: Model,
    pub trials: Vec<(String, Trial)>,
}

/// Every `k`-th frame of `trial`, at `rate / k`.
pub(super) fn every_kth(trial: Trial, k: usize) -> Result<Trial> {
    if k <= 1 {
        return Ok(trial);
    }
    let positions = (0..trial.n_frames())
        .step_by(k)
        .flat_map(|f| trial.frame(f).to_vec())
        .collect();
    Ok(Trial::new(
        trial.labels().to_vec(),
        trial.rate() / k as f64,
        trial.first_frame(),
        positions,
    )?
    .with_times(
        trial
            .times()
            .map(|t| t.iter().step_by(k).copied().collect()),
    )?)
}

#[allow(clippy::too_many_arguments)]
fn subject(
    data: &Path,
    dataset: &str,
    static_file: &str,
    preset: &str,
    up: Up,
    trials: &[&str],
    filter: Option<f64>,
    stride: usize,
) -> Result<Subject> {
    let path = data.join(dataset).join(static_file);
    let trial = load_trial(&path, up, None)?;
    let set = MarkerSet::preset(preset)?;
    let opts = PersonalizeOptions {
        name: dataset.to_string(),
        ..PersonalizeOptions::default()
    };
    let p = personalize(&trial, &set, Side::Right, &opts)
        .with_context(|| format!("{}: cannot personalize", path.display()))?;
    let model = Model::compile(&p.spec)?;
    let trials = trials
        .iter()
        .map(|t| {
            let path = data.join(dataset).join(t);
            Ok((
                t.to_string(),
                every_kth(load_trial(&path, up, filter)?, stride)?,
            ))
        })
        .collect::<Result<_>>()?;
    Ok(Subject {
        name: dataset.to_string(),
        model,
        trials,
    })
}

pub(super) fn biobuddy(data: &Path, stride: usize) -> Result<Subject> {
    // 12 Hz recordings: a 6 Hz cutoff would sit at Nyquist, so they are used as recorded.
    subject(
        data,
        BIOBUDDY,
        "Test_func_anat.c3d",
        "plugin-gait-medial",
        Up::NegZ,
        &[
            "Test_func_rhip.c3d",
            "Test_func_rknee.c3d",
            "Test_func_rankle.c3d",
        ],
        None,
        stride,
    )
}

pub(super) fn opencap(data: &Path, stride: usize, trials: &[String]) -> Result<Subject> {
    let trials: Vec<&str> = trials.iter().map(|t| t.as_str()).collect();
    subject(
        data,
        OPENCAP,
        "static1.trc",
        "opencap",
        Up::Y,
        &trials,
        Some(6.0),
        stride,
    )
}
