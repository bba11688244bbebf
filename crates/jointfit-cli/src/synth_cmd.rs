//! `jointfit synth <SUBJECT.toml|builtin> --motion M --noise N --seed S -o OUT.trc --truth T.toml`:
//! synthetic markers from a subject model along a motion, with the true model beside them.
//!
//! The true parameters are the subject's nominal values, or those moved by up to
//! `--perturb-mm` / `--perturb-deg` per parameter (seeded) when asked; the truth file is the
//! subject model with the true parameters as its nominal values, so `jointfit calibrate
//! SUBJECT OUT.trc` should recover the truth file's nominal values. Motions and noise are
//! documented in `jointfit_experiments::synth`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use jointfit::workflow::perturb;
use jointfit_experiments::synth::{
    coordinates_scaled, gait_coordinates, synthesize, Motion, Noise, SkinNoise, WhiteNoise,
};
use jointfit_io::trc::{write_trc, TrcUnits, TrcWriteOptions};

use crate::common::{load_trial, Up};

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum NoiseKind {
    /// No noise: every marker lies exactly where the true model puts it.
    None,
    /// Skin-movement artifact A·sin(ωt+φ) per marker-axis (Chèze et al. 1995).
    Skin,
    /// Independent Gaussian noise per sample and axis.
    White,
    /// Skin artifact plus white noise.
    SkinWhite,
}

#[derive(Args)]
pub struct SynthArgs {
    /// Subject model (TOML file or built-in name).
    pub model: String,
    /// hip, knee, ankle, all, or gait:<TRIAL> (the coordinates of a real trial by IK with
    /// the subject model at its nominal parameters).
    #[arg(long, default_value = "all")]
    pub motion: String,
    /// Noise added to the synthetic markers.
    #[arg(long, value_enum, default_value = "none")]
    pub noise: NoiseKind,
    /// Seed of the noise and of the perturbation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Frames of a synthetic motion (not gait).
    #[arg(long, default_value_t = 50, allow_negative_numbers = true, value_parser = crate::validate::frames)]
    pub frames: usize,
    /// Sampling rate of a synthetic motion (Hz); gait keeps its trial's rate.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = crate::validate::rate_hz)]
    pub rate: f64,
    /// Multiplies the joint excursions of a synthetic motion.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = crate::validate::amplitude)]
    pub amplitude: f64,
    /// Largest skin-artifact amplitude per marker-axis (mm).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = crate::validate::noise_mm_or_zero)]
    pub skin_mm: f64,
    /// Largest skin-artifact angular frequency (rad/s).
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true, value_parser = crate::validate::omega)]
    pub skin_omega: f64,
    /// Standard deviation of white noise per axis (mm).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = crate::validate::noise_mm_or_zero)]
    pub white_mm: f64,
    /// True positions = nominal moved by up to this many mm (uniform, seeded).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = crate::validate::perturb_mm)]
    pub perturb_mm: f64,
    /// True orientations = nominal moved by up to this many degrees (uniform, seeded).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = crate::validate::perturb_deg)]
    pub perturb_deg: f64,
    /// Vertical axis of the gait trial's file (default: the subject model's `lab_up`,
    /// recorded by `personalize`; else y), as for every command that reads a subject's trials.
    #[arg(long, value_enum)]
    pub up: Option<Up>,
    /// Low-pass cutoff (Hz) applied to the gait trial before IK.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    /// Output markers (TRC, mm, written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Output true model (TOML, written atomically).
    #[arg(long)]
    pub truth: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(serde::Serialize)]
struct Summary {
    model: String,
    motion: String,
    frames: usize,
    rate_hz: f64,
    markers: usize,
    noise: String,
    seed: u64,
    noise_rms_axis_mm: [f64; 3],
    noise_rms_3d_mm: f64,
    noise_max_axis_mm: f64,
    perturb_mm: f64,
    perturb_deg: f64,
    dropped_gait_frames: Vec<usize>,
    output: String,
    truth: String,
}

pub fn run(args: SynthArgs) -> Result<()> {
    let mut files = crate::output::Files::new().model("model", &args.model);
    if let Some(gait) = args.motion.strip_prefix("gait:") {
        files = files.input("gait trial", gait);
    }
    files
        .output("output", &args.output)
        .output("--truth", &args.truth)
        .check()?;
    let spec = jointfit_io::model_file::load_spec(&args.model)?;
    let model = jointfit_io::model_file::load_model(&args.model)?;
    if model.markers().is_empty() {
        bail!(
            "{}: the model has no markers, so there is nothing to synthesize",
            args.model
        );
    }
    check_numbers(&args)?;
    let all: Vec<usize> = (0..model.parameters().len()).collect();
    let truth = if args.perturb_mm > 0.0 || args.perturb_deg > 0.0 {
        perturb(
            &model,
            &model.nominal_params(),
            &all,
            args.perturb_mm,
            args.perturb_deg,
            args.seed,
        )
    } else {
        model.nominal_params()
    };
    let (coords, rate, dropped) = coordinates(&args, spec.lab_up.map(Up::from), &model)?;
    let noise = noise(&args);
    let (trial, stats) = synthesize(&model, &truth, &coords, rate, &noise);
    let opts = TrcWriteOptions {
        units: TrcUnits::Millimetres,
        // 1e-9 mm: noiseless data stay exact enough to recover parameters to ~1e-9.
        decimals: 9,
    };
    write_trc(&args.output, &trial, &opts)?;
    let mut true_spec = model.spec_with_nominal(&truth);
    true_spec.name = format!("{} (synthetic truth)", spec.name);
    true_spec.description = format!(
        "true parameters of {} (seed {}, perturbed by up to {} mm / {} deg)",
        args.output.display(),
        args.seed,
        args.perturb_mm,
        args.perturb_deg
    );
    jointfit_io::model_file::save_spec(&args.truth, &true_spec)
        .with_context(|| format!("{}: cannot write", args.truth.display()))?;
    let summary = Summary {
        model: args.model.clone(),
        motion: args.motion.clone(),
        frames: coords.len(),
        rate_hz: rate,
        markers: model.markers().len(),
        noise: format!("{:?}", args.noise).to_lowercase(),
        seed: args.seed,
        noise_rms_axis_mm: stats.rms_axis.map(|v| v * 1e3),
        noise_rms_3d_mm: stats.rms_3d * 1e3,
        noise_max_axis_mm: stats.max_axis * 1e3,
        perturb_mm: args.perturb_mm,
        perturb_deg: args.perturb_deg,
        dropped_gait_frames: dropped,
        output: args.output.display().to_string(),
        truth: args.truth.display().to_string(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", summary.render());
    }
    Ok(())
}

/// The numeric options are finite and in range.
fn check_numbers(args: &SynthArgs) -> Result<()> {
    let check = |ok: bool, what: &str, v: f64| -> Result<()> {
        if ok {
            Ok(())
        } else {
            bail!("{what} must be finite and positive (got {v})")
        }
    };
    check(
        args.rate.is_finite() && args.rate > 0.0,
        "--rate",
        args.rate,
    )?;
    check(
        args.amplitude.is_finite() && args.amplitude >= 0.0,
        "--amplitude",
        args.amplitude,
    )?;
    for (w, v) in [
        ("--skin-mm", args.skin_mm),
        ("--skin-omega", args.skin_omega),
        ("--white-mm", args.white_mm),
        ("--perturb-mm", args.perturb_mm),
        ("--perturb-deg", args.perturb_deg),
    ] {
        check(v.is_finite() && v >= 0.0, w, v)?;
    }
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    Ok(())
}

/// The coordinates to synthesize, their rate and the gait frames dropped: inverse
/// kinematics of a gait trial (`gait:<TRIAL>`, read with `--up`, else the model's lab up,
/// else y), or a built-in motion.
fn coordinates(
    args: &SynthArgs,
    lab_up: Option<Up>,
    model: &jointfit::model::Model,
) -> Result<(Vec<Vec<f64>>, f64, Vec<usize>)> {
    Ok(match args.motion.strip_prefix("gait:") {
        Some(path) => {
            let path = PathBuf::from(path);
            let up = args.up.or(lab_up).unwrap_or(Up::Y);
            let trial = load_trial(&path, up, args.filter)?;
            let (coords, dropped) = gait_coordinates(model, &model.nominal_params(), &trial)
                .with_context(|| format!("{}: inverse kinematics", path.display()))?;
            if coords.is_empty() {
                bail!(
                    "{}: no frame could be solved by inverse kinematics",
                    path.display()
                );
            }
            (coords, trial.rate(), dropped)
        }
        None => {
            let motion: Motion = args
                .motion
                .parse()
                .map_err(|e| anyhow::anyhow!("--motion: {e}, or gait:<TRIAL>"))?;
            let coords = coordinates_scaled(model, motion, args.frames, args.amplitude)
                .with_context(|| format!("{}: motion {}", args.model, args.motion))?;
            (coords, args.rate, Vec::new())
        }
    })
}

/// The marker noise `--noise` asks for.
fn noise(args: &SynthArgs) -> Noise {
    let skin = SkinNoise {
        max_amplitude: args.skin_mm * 1e-3,
        max_omega: args.skin_omega,
        seed: args.seed,
    };
    let white = WhiteNoise {
        sigma: args.white_mm * 1e-3,
        seed: args.seed,
    };
    match args.noise {
        NoiseKind::None => Noise::none(),
        NoiseKind::Skin => Noise {
            skin: Some(skin),
            white: None,
        },
        NoiseKind::White => Noise {
            skin: None,
            white: Some(white),
        },
        NoiseKind::SkinWhite => Noise::skin_and_white(skin, white),
    }
}

impl Summary {
    /// The text `synth` prints.
    fn render(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "synthetic {} motion: {} frames at {} Hz, {} markers of {}",
            self.motion, self.frames, self.rate_hz, self.markers, self.model
        );
        if !self.dropped_gait_frames.is_empty() {
            let _ = writeln!(
                out,
                "dropped {} gait frames that IK could not solve",
                self.dropped_gait_frames.len()
            );
        }
        let a = self.noise_rms_axis_mm;
        let _ = writeln!(
            out,
            "noise {} (seed {}): RMS x {:.3}, y {:.3}, z {:.3} mm; 3-D RMS {:.3} mm; max {:.3} mm",
            self.noise, self.seed, a[0], a[1], a[2], self.noise_rms_3d_mm, self.noise_max_axis_mm
        );
        let _ = writeln!(
            out,
            "true parameters: nominal moved by up to {} mm / {} deg",
            self.perturb_mm, self.perturb_deg
        );
        let _ = writeln!(out, "wrote {} and {}", self.output, self.truth);
        out
    }
}
