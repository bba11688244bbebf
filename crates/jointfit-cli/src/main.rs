//! The `jointfit` command-line tool: thin clap front end, one module per subcommand.
//!
//! Exit status: 0 success; 1 error (one line on stderr, no file written); 2 bad command line;
//! 3 a fit did not converge (nothing written unless `--accept-unconverged`); 4 some batch jobs
//! failed; 5 rejected by the verdict (nothing written unless `--accept-rejected`). See
//! [`output`].

// First: its never-panicking print macros replace std's in every module declared below.
#[macro_use]
mod output;
mod validate;

mod batch_cmd;
mod bench_cmd;
mod bench_perf;
mod bench_profile;
mod bench_stream;
mod bench_workload;
mod calibrate_cmd;
mod calibrate_text;
mod check_cmd;
mod common;
mod data_cmd;
mod demo_cmd;
mod export_cmd;
mod ik_cmd;
mod ik_setup;
mod markers_cmd;
mod model_cmd;
mod osim_calibrate;
mod personalize_cmd;
mod personalize_subject;
mod personalize_summary;
mod prior_args;
mod progress;
mod report_cmd;
mod reproduce_cmd;
mod scale_cmd;
mod stream_cmd;
mod synth_cmd;
mod table;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Patient-specific joint parameters of leg models from motion capture
/// (two-level optimization, Reinbolt et al. 2005).
#[derive(Parser)]
#[command(name = "jointfit", version, long_about = None, after_help = WORKFLOW)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The usual order of the commands, shown under `jointfit --help`.
const WORKFLOW: &str = "\
A subject, from a static trial and motion trials (.c3d or .trc):
  jointfit inspect static.c3d                             labels, rate, units, gaps
  jointfit markers suggest static.c3d -o lab.toml         or a preset: --markers plugin-gait
  jointfit personalize static.c3d --markers lab.toml -o subject.toml
  jointfit check subject.toml walk.c3d                    which parameters the trial determines
  jointfit calibrate subject.toml walk.c3d -o fitted.toml --report report
  jointfit ik fitted.toml walk.c3d -o walk.mot            joint angles for OpenSim
  jointfit export osim fitted.toml -o fitted.osim
Without any data: jointfit demo. Each command's options: jointfit COMMAND --help.
Exit status: 0 success, 1 error, 2 bad command line, 3 calibrate did not converge,
4 some batch jobs failed, 5 rejected (inputs that do not belong together, an implausible
result; nothing written).";

/// Subcommands, listed by `--help` in this order (the order of a workflow).
#[derive(Subcommand)]
enum Command {
    /// Synthesize a noisy trial from the built-in leg, calibrate it, show what was recovered.
    Demo(demo_cmd::DemoArgs),
    /// Summarize a motion file: format, rate, frames, units, markers with gaps.
    Inspect(data_cmd::InspectArgs),
    /// Convert a motion file (C3D or TRC) to a Y-up TRC, optionally low-pass filtered.
    Convert(data_cmd::ConvertArgs),
    /// Marker sets: propose one from a static trial (`markers suggest`).
    Markers {
        #[command(subcommand)]
        command: markers_cmd::MarkersCommand,
    },
    /// Scale a generic OpenSim model to a subject and register its markers (static trial).
    Scale(scale_cmd::ScaleArgs),
    /// Build a subject's leg model from a static trial (anatomical-landmark method).
    Personalize(personalize_cmd::PersonalizeArgs),
    /// Before a fit: each joint's range of motion and which parameters the trial can determine.
    Check(check_cmd::CheckArgs),
    /// Fit joint parameters to one or more trials (two-level optimization).
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Inverse kinematics of a trial with a subject model (the inner level).
    Ik(ik_cmd::IkArgs),
    /// Inverse kinematics of a live marker feed: labels then one frame per line on stdin (mm),
    /// coordinates per line on stdout (degrees, metres), flushed per frame.
    Stream(stream_cmd::StreamArgs),
    /// Write an HTML report (figures, parameter table) of a fitted model on trials.
    Report(report_cmd::ReportArgs),
    /// Export a model to other programs' formats (OpenSim .osim).
    Export {
        #[command(subcommand)]
        command: export_cmd::ExportCommand,
    },
    /// Many calibrations from a manifest on all cores; resumable; results table CSV + JSON.
    Batch(batch_cmd::BatchArgs),
    /// Synthetic markers from a subject model along a motion, with noise, and the true model.
    Synth(synth_cmd::SynthArgs),
    /// Reproduce the paper's Table 1 or Table 2 (Markdown, JSON and CSV into a directory).
    Reproduce(reproduce_cmd::ReproduceArgs),
    /// Inspect kinematic models (`model show`: segments, joints, parameters, markers).
    Model {
        #[command(subcommand)]
        command: model_cmd::ModelCommand,
    },
    /// Time the core (FK, IK on a real gait trial, calibration) on this machine.
    Bench(bench_cmd::BenchArgs),
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
    output::start_threads();
    // Every file of the command lands together, or none does (see `output`).
    let batch = jointfit_io::staging::Batch::begin().ok();
    let result = match cli.command {
        Command::Model { command } => model_cmd::run(command),
        Command::Markers { command } => markers_cmd::run(command),
        Command::Inspect(args) => data_cmd::inspect(args),
        Command::Convert(args) => data_cmd::convert(args),
        Command::Ik(args) => ik_cmd::run(args),
        Command::Stream(args) => stream_cmd::run(args),
        Command::Calibrate(args) => calibrate_cmd::run(args),
        Command::Batch(args) => batch_cmd::run(args),
        Command::Check(args) => check_cmd::run(args),
        Command::Demo(args) => demo_cmd::run(args),
        Command::Personalize(args) => personalize_cmd::run(args),
        Command::Scale(args) => scale_cmd::run(args),
        Command::Report(args) => report_cmd::run(args),
        Command::Bench(args) => bench_cmd::run(args),
        Command::Export { command } => export_cmd::run(command),
        Command::Synth(args) => synth_cmd::run(args),
        Command::Reproduce(args) => reproduce_cmd::run(args),
    };
    output::finish(result, batch)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every command line of the workflow shown under `--help` parses (a renamed option would
    /// otherwise leave the help teaching a command that fails).
    #[test]
    fn the_help_workflow_commands_parse() {
        let lines: Vec<&str> = WORKFLOW
            .lines()
            .filter_map(|l| l.strip_prefix("  "))
            .map(|l| l.split("   ").next().unwrap_or(l).trim())
            .collect();
        assert_eq!(lines.len(), 7);
        for line in lines {
            let words: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(words[0], "jointfit");
            if let Err(e) = Cli::try_parse_from(&words) {
                panic!("{line}: {e}");
            }
        }
    }

    /// Every `jointfit …` command line of the README (indented code, `\` continuations
    /// joined, `# comments` and `[optional]` parts dropped) parses with today's options.
    #[test]
    fn the_readme_commands_parse() {
        let readme = include_str!("../../../README.md");
        let mut commands: Vec<String> = Vec::new();
        let mut pending = String::new();
        for line in readme.lines() {
            let Some(code) = line.strip_prefix("    ") else {
                continue;
            };
            let code = code.split(" # ").next().unwrap_or(code).trim();
            if pending.is_empty() && !code.starts_with("jointfit ") {
                continue;
            }
            match code.strip_suffix('\\') {
                Some(head) => pending.push_str(head),
                None => {
                    pending.push_str(code);
                    commands.push(std::mem::take(&mut pending));
                }
            }
        }
        assert!(commands.len() >= 15, "{commands:?}");
        for command in &commands {
            let mut words = Vec::new();
            let mut optional = 0;
            for w in command.split_whitespace() {
                optional += w.matches('[').count();
                if optional == 0 {
                    words.push(w);
                }
                optional -= w.matches(']').count();
            }
            if let Err(e) = Cli::try_parse_from(&words) {
                panic!("README: {command}: {e}");
            }
        }
    }
}
