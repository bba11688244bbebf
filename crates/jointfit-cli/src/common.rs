//! Shared pieces of the subcommands: reading trials, units, per-marker summaries.

use std::path::Path;

use anyhow::{Context, Result};
use clap::ValueEnum;
use jointfit::signal::{filter_trial, LowPass};
use jointfit::trial::{up_axis_rotation, Trial, UpAxis};

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

/// Reads a motion file, rotates it to Y-up and low-pass filters it when asked; warns on
/// stderr when filtering moves a marker by more than 2 cm.
pub fn load_trial(path: &Path, up: Up, filter_hz: Option<f64>) -> Result<Trial> {
    let mut trial = jointfit_io::trial_file::read_trial(path)?;
    crate::validate::check_trial(path, &trial)?;
    trial.rotate(&up_axis_rotation(up.into()));
    if let Some(hz) = filter_hz {
        let lp = LowPass {
            cutoff_hz: hz,
            ..LowPass::default()
        };
        let (filtered, report) = filter_trial(&trial, &lp)
            .with_context(|| format!("{}: --filter {hz} Hz", path.display()))?;
        for m in report.moved_more_than(0.02) {
            eprintln!(
                "jointfit: warning: {}: filtering moved marker {} by {:.1} mm",
                path.display(),
                m.label,
                m.max_displacement_m * 1e3
            );
        }
        trial = filtered;
    }
    Ok(trial)
}

pub const MM: f64 = 1e3;
