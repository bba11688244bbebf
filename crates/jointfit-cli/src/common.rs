//! Shared pieces of the subcommands: the up-axis option and reading trials with warnings.

use std::path::Path;

use anyhow::Result;
use clap::ValueEnum;
use jointfit::trial::{Trial, UpAxis};
use jointfit_io::trial_file::LoadOptions;

/// Which lab axis points up in the input file.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Up {
    Y,
    Z,
    #[value(name = "-z")]
    NegZ,
}

impl From<Up> for UpAxis {
    fn from(u: Up) -> UpAxis {
        match u {
            Up::Y => UpAxis::Y,
            Up::Z => UpAxis::Z,
            Up::NegZ => UpAxis::NegZ,
        }
    }
}

/// Reads a motion file ([`jointfit_io::trial_file::load_trial`]), printing its warnings on
/// stderr.
pub fn load_trial(path: &Path, up: Up, filter_hz: Option<f64>) -> Result<Trial> {
    let options = LoadOptions {
        up: up.into(),
        filter_hz,
    };
    let (trial, warnings) = jointfit_io::trial_file::load_trial(path, &options)?;
    for w in warnings {
        eprintln!("jointfit: warning: {w}");
    }
    Ok(trial)
}
