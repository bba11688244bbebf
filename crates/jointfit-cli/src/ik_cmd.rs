//! `jointfit ik <SUBJECT.toml> <TRIAL> -o <OUT.mot> [--errors <ERR.csv>] [--filter HZ] [--json]`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::ik::{FrameStatus, IkOptions, TrialFit};
use jointfit::model::{Model, MM_PER_M};
use jointfit::trial::Trial;
use jointfit::workflow::{self, WorkflowError};
use jointfit_io::sto::{coordinates_table, write_sto};
use serde::Serialize;

use crate::common::{load_trial, Up};

#[derive(Args)]
pub struct IkArgs {
    /// Subject model (TOML file or built-in name).
    pub model: String,
    /// Motion file (.trc or .c3d).
    pub trial: PathBuf,
    /// Joint angles as an OpenSim .mot (degrees, metres).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Per-frame and per-marker distance errors (mm) as CSV.
    #[arg(long)]
    pub errors: Option<PathBuf>,
    /// Low-pass filter cutoff in Hz (zero-phase Butterworth, effective order 4).
    #[arg(long, allow_negative_numbers = true, value_parser = crate::validate::cutoff_hz)]
    pub filter: Option<f64>,
    /// Which axis of the file points up.
    #[arg(long, value_enum, default_value = "y")]
    pub up: Up,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Summary {
    frames: usize,
    solved_frames: usize,
    unsolved: Vec<String>,
    mean_frame_rms_mm: f64,
    max_frame_rms_mm: f64,
    marker_rms_mm: Vec<(String, f64)>,
    solve_seconds: f64,
    frames_per_second: f64,
}

pub fn run(args: IkArgs) -> Result<()> {
    let mut files = crate::output::Files::new()
        .model("model", &args.model)
        .input("trial", &args.trial)
        .output("output", &args.output);
    if let Some(e) = &args.errors {
        files = files.output("--errors", e);
    }
    files.check()?;
    let model = jointfit_io::model_file::load_model(&args.model)?;
    let trial = load_trial(&args.trial, args.up, args.filter)?;
    let start = Instant::now();
    let run = match workflow::ik_trial(
        &model,
        &model.nominal_params(),
        &trial,
        &IkOptions::default(),
    ) {
        Ok(run) => run,
        Err(e @ WorkflowError::NoFrameSolved { .. }) => {
            bail!("{}: {e}; nothing written", args.trial.display())
        }
        Err(e) => return Err(e).with_context(|| args.trial.display().to_string()),
    };
    let seconds = start.elapsed().as_secs_f64();
    if !run.absent.is_empty() {
        eprintln!(
            "jointfit: warning: {}: lacks model markers {}; they count as missing in every frame",
            args.trial.display(),
            run.absent.join(", ")
        );
    }
    let fit = run.fit;
    write_sto(
        &args.output,
        &coordinates_table(&model, &trial, &fit.coords),
    )
    .with_context(|| format!("writing {}", args.output.display()))?;
    if let Some(path) = &args.errors {
        jointfit_io::atomic::write_atomic(path, errors_csv(&model, &trial, &fit).as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let summary = summarize(&model, &trial, &fit, seconds);
    if !(summary.mean_frame_rms_mm.is_finite() && summary.max_frame_rms_mm.is_finite()) {
        bail!(
            "{}: inverse kinematics gave non-finite marker errors; nothing written",
            args.trial.display()
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{} frames ({} solved) in {:.3} s ({:.0} frames/s)",
            summary.frames, summary.solved_frames, seconds, summary.frames_per_second
        );
        println!(
            "RMS marker error per frame: mean {:.2} mm, max {:.2} mm",
            summary.mean_frame_rms_mm, summary.max_frame_rms_mm
        );
        for u in &summary.unsolved {
            println!("not solved: {u}");
        }
        let mut t = crate::table::Table::new(&["marker", "RMS mm"]);
        for (name, v) in &summary.marker_rms_mm {
            t.row(vec![name.clone(), format!("{v:.2}")]);
        }
        print!("{}", t.render());
        println!("wrote {}", args.output.display());
    }
    Ok(())
}

fn summarize(model: &Model, trial: &Trial, fit: &TrialFit, seconds: f64) -> Summary {
    let rms: Vec<f64> = (0..fit.frames.len())
        .map(|f| fit.frame_rms(f))
        .filter(|v| !v.is_nan())
        .collect();
    let unsolved = fit
        .frames
        .iter()
        .enumerate()
        .filter_map(|(f, fr)| match &fr.status {
            FrameStatus::TooFewMarkers { segment, present } => Some(format!(
                "frame {} (file frame {}): segment {segment} has {present} markers",
                f,
                trial.first_frame() + f as i64
            )),
            _ => None,
        })
        .collect();
    Summary {
        frames: fit.frames.len(),
        solved_frames: rms.len(),
        unsolved,
        mean_frame_rms_mm: rms.iter().sum::<f64>() / rms.len().max(1) as f64 * MM_PER_M,
        max_frame_rms_mm: rms.iter().cloned().fold(0.0, f64::max) * MM_PER_M,
        marker_rms_mm: model
            .markers()
            .iter()
            .enumerate()
            .map(|(j, m)| (m.name.clone(), fit.marker_rms(j) * MM_PER_M))
            .collect(),
        solve_seconds: seconds,
        frames_per_second: fit.frames.len() as f64 / seconds.max(1e-12),
    }
}

fn errors_csv(model: &Model, trial: &Trial, fit: &TrialFit) -> String {
    let mut out = String::from("frame,time,rms_mm");
    for m in model.markers() {
        out.push(',');
        out.push_str(&jointfit_io::csv::field(&format!("{}_mm", m.name)));
    }
    out.push('\n');
    let cell = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{:.4}", v * MM_PER_M)
        }
    };
    for f in 0..fit.frames.len() {
        out.push_str(&format!(
            "{},{:.6},{}",
            trial.first_frame() + f as i64,
            trial.time(f),
            cell(fit.frame_rms(f))
        ));
        for e in &fit.errors[f] {
            out.push(',');
            out.push_str(&cell(*e));
        }
        out.push('\n');
    }
    out
}
