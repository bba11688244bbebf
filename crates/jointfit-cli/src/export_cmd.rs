//! `jointfit export osim <MODEL> -o <OUT.osim>`: the model as an OpenSim 4 model
//! ([`jointfit_io::osim`]), its joint offsets evaluated at the parameters' nominal values (a
//! personalized or calibrated model file stores its subject's values there).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};

#[derive(Subcommand)]
pub enum ExportCommand {
    /// Write an OpenSim 4 model (.osim): bodies, CustomJoints, coordinates, markers.
    /// Masses and inertias are placeholders (kinematics only).
    Osim(OsimArgs),
}

#[derive(Args)]
pub struct OsimArgs {
    /// Subject model (TOML file or built-in name: lower-limb, lower-limb-right, lower-limb-left).
    pub model: String,
    /// Output .osim file, written atomically.
    #[arg(short, long, value_name = "OUT.osim")]
    pub output: PathBuf,
}

pub fn run(cmd: ExportCommand) -> Result<()> {
    match cmd {
        ExportCommand::Osim(args) => osim(args),
    }
}

fn osim(args: OsimArgs) -> Result<()> {
    crate::output::Files::new()
        .model("model", &args.model)
        .output("output", &args.output)
        .check()?;
    let model = jointfit_io::model_file::load_model(&args.model)?;
    jointfit_io::osim::write_osim(&args.output, &model, &model.nominal_params())
        .with_context(|| format!("{}: cannot export to OpenSim", args.model))?;
    println!(
        "wrote {} ({} bodies, {} joints, {} coordinates, {} markers; masses and inertias are \
         placeholders)",
        args.output.display(),
        model.segments().len(),
        model.joints().len(),
        model.coordinates().len(),
        model.markers().len()
    );
    Ok(())
}
