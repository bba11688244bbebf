//! The `jointfit` command-line tool: thin clap front end, one module per subcommand.
//!
//! Exit status: 0 success; 1 error (one line on stderr, no file written); 2 bad command line;
//! 3 a fit did not converge (nothing written unless `--accept-unconverged`). See [`output`].

// First: its never-panicking print macros replace std's in every module declared below.
#[macro_use]
mod output;
mod validate;

mod batch_cmd;
mod bench_cmd;
mod bench_perf;
mod bench_profile;
mod calibrate_cmd;
mod calibrate_text;
mod check_cmd;
mod common;
mod data_cmd;
mod demo_cmd;
mod export_cmd;
mod ik_cmd;
mod markers_cmd;
mod model_cmd;
mod osim_calibrate;
mod personalize_cmd;
mod personalize_summary;
mod prior_args;
mod progress;
mod report_cmd;
mod reproduce_cmd;
mod synth_cmd;
mod table;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Patient-specific joint parameters of leg models from motion capture
/// (two-level optimization, Reinbolt et al. 2005).
#[derive(Parser)]
#[command(name = "jointfit", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Inspect kinematic models.
    Model {
        #[command(subcommand)]
        command: model_cmd::ModelCommand,
    },
    /// Marker sets: propose one from a static trial (`markers suggest`).
    Markers {
        #[command(subcommand)]
        command: markers_cmd::MarkersCommand,
    },
    /// Summarize a motion file: format, rate, frames, units, markers with gaps.
    Inspect(data_cmd::InspectArgs),
    /// Convert a motion file (C3D or TRC) to a Y-up TRC, optionally low-pass filtered.
    Convert(data_cmd::ConvertArgs),
    /// Inverse kinematics of a trial with a subject model (the inner level).
    Ik(ik_cmd::IkArgs),
    /// Fit joint parameters to one or more trials (two-level optimization).
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Many calibrations from a manifest on all cores; resumable; results table CSV + JSON.
    Batch(batch_cmd::BatchArgs),
    /// Before a fit: each joint's range of motion and which parameters the trial can determine.
    Check(check_cmd::CheckArgs),
    /// Synthesize a noisy trial from the built-in leg, calibrate it, show what was recovered.
    Demo(demo_cmd::DemoArgs),
    /// Build a subject's leg model from a static trial (anatomical-landmark method).
    Personalize(personalize_cmd::PersonalizeArgs),
    /// Write an HTML report (figures, parameter table) of a fitted model on trials.
    Report(report_cmd::ReportArgs),
    /// Time the core (FK, IK on a real gait trial, calibration) on this machine.
    Bench(bench_cmd::BenchArgs),
    /// Export a model to other programs' formats (OpenSim .osim).
    Export {
        #[command(subcommand)]
        command: export_cmd::ExportCommand,
    },
    /// Synthetic markers from a subject model along a motion, with noise, and the true model.
    Synth(synth_cmd::SynthArgs),
    /// Reproduce the paper's Table 1 or Table 2 (Markdown, JSON and CSV into a directory).
    Reproduce(reproduce_cmd::ReproduceArgs),
}

fn main() -> ExitCode {
    // A closed pipe (`jointfit … | head`) ends the program quietly, as for any Unix filter,
    // instead of a panic in println!.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    output::install_signal_handlers();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return output::clap_error(e),
    };
    // Every file of the command lands together, or none does (see `output`).
    let batch = jointfit_io::staging::Batch::begin().ok();
    let result = match cli.command {
        Command::Model { command } => model_cmd::run(command),
        Command::Markers { command } => markers_cmd::run(command),
        Command::Inspect(args) => data_cmd::inspect(args),
        Command::Convert(args) => data_cmd::convert(args),
        Command::Ik(args) => ik_cmd::run(args),
        Command::Calibrate(args) => calibrate_cmd::run(args),
        Command::Batch(args) => batch_cmd::run(args),
        Command::Check(args) => check_cmd::run(args),
        Command::Demo(args) => demo_cmd::run(args),
        Command::Personalize(args) => personalize_cmd::run(args),
        Command::Report(args) => report_cmd::run(args),
        Command::Bench(args) => bench_cmd::run(args),
        Command::Export { command } => export_cmd::run(command),
        Command::Synth(args) => synth_cmd::run(args),
        Command::Reproduce(args) => reproduce_cmd::run(args),
    };
    output::finish(result, batch)
}
