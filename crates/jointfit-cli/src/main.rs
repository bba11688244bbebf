//! The `jointfit` command-line tool: thin clap front end, one module per subcommand.

mod calibrate_cmd;
mod check_cmd;
mod common;
mod demo_cmd;
mod ik_cmd;
mod model_cmd;
mod personalize_cmd;
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
    /// Inverse kinematics of a trial with a subject model (the inner level).
    Ik(ik_cmd::IkArgs),
    /// Fit joint parameters to one or more trials (two-level optimization).
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Before a fit: each joint's range of motion and which parameters the trial can determine.
    Check(check_cmd::CheckArgs),
    /// Synthesize a noisy trial from the built-in leg, calibrate it, show what was recovered.
    Demo(demo_cmd::DemoArgs),
    /// Build a subject's leg model from a static trial (anatomical-landmark method).
    Personalize(personalize_cmd::PersonalizeArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Model { command } => model_cmd::run(command),
        Command::Ik(args) => ik_cmd::run(args),
        Command::Calibrate(args) => calibrate_cmd::run(args),
        Command::Check(args) => check_cmd::run(args),
        Command::Demo(args) => demo_cmd::run(args),
        Command::Personalize(args) => personalize_cmd::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the chain of causes joined, as in "file: line 3: ...".
            let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            eprintln!("jointfit: error: {}", msg.join(": "));
            ExitCode::FAILURE
        }
    }
}
