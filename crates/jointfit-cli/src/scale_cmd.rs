//! `jointfit scale GENERIC.osim STATIC [TRIALS...] [--markerset MARKERS.xml] -o SUBJECT.osim
//! [--mass KG] [--height M] [--json] [--setup scale_setup.xml]`: a generic OpenSim model
//! scaled to the subject with its markers registered
//! ([`jointfit_app::scale::scale_subject`]), written as OpenSim's own scaling
//! writes it.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use jointfit_app::scale::{scale_subject, ScaleOutcome, ScaleRequest};
use jointfit_io::osim_scale::record::{read_record, write_record, ScaleRecord};
use jointfit_io::osim_scale::setup::read_scale_setup;
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ScalePrior {
    /// Segment proportions of the generic model with a 5 % spread (and the stature when given).
    Anthropometric,
    /// No prior on the factors (marker offsets keep theirs).
    None,
}

#[derive(Args, Debug)]
pub struct ScaleArgs {
    /// GENERIC.osim STATIC [TRIALS...] (with --setup: the setup names the model and static).
    #[arg(value_name = "FILES")]
    pub files: Vec<PathBuf>,
    /// OpenSim MarkerSet XML (OpenSim 3 or 4) attached to the generic model.
    #[arg(long, value_name = "MARKERS.xml")]
    pub markerset: Option<PathBuf>,
    /// OpenSim ScaleTool setup: model, marker set, static trial, time range, mass, height,
    /// the measurements' body groups, manual scales (held, not fitted), the marker placer's
    /// marker weights, preserve_mass_distribution.
    #[arg(long, value_name = "scale_setup.xml")]
    pub setup: Option<PathBuf>,
    /// The subject model to write.
    #[arg(short = 'o', long = "output", value_name = "SUBJECT.osim")]
    pub output: Option<PathBuf>,
    /// Total mass of the subject model (kg); default: the setup's, else the generic's.
    #[arg(long, value_name = "KG", value_parser = crate::validate::positive)]
    pub mass: Option<f64>,
    /// Subject stature (m), for the anthropometric prior.
    #[arg(long, value_name = "M", value_parser = crate::validate::positive)]
    pub height: Option<f64>,
    /// Static trial time range (s).
    #[arg(long, num_args = 2, value_names = ["START", "END"])]
    pub time_range: Option<Vec<f64>>,
    #[arg(long, value_enum, default_value = "anthropometric")]
    pub prior: ScalePrior,
    /// Three factors per body (x, y, z) instead of one.
    #[arg(long)]
    pub per_axis: bool,
    /// A body and its mirror (`_r`/`_l`) share factors.
    #[arg(long)]
    pub symmetric: bool,
    /// Prior SD of a marker's offset from its scaled generic place (mm).
    #[arg(long, default_value_t = 10.0, value_name = "MM", value_parser = crate::validate::positive)]
    pub marker_sd: f64,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct JsonMarker<'a> {
    name: &'a str,
    body: &'a str,
    /// Location in the scaled body (m).
    location: [f64; 3],
    /// Offset from the scaled generic place (mm).
    moved_mm: [f64; 3],
    rms_mm: Option<f64>,
}

#[derive(Serialize)]
struct JsonReport<'a> {
    output: String,
    scale_factors: std::collections::BTreeMap<&'a str, [f64; 3]>,
    groups: &'a [jointfit_scale::fit::GroupFit],
    markers: Vec<JsonMarker<'a>>,
    rms_mm: f64,
    frames: usize,
    absent_markers: &'a [String],
    flags: &'a [String],
    generic_mass: f64,
    total_mass: f64,
    iterations: usize,
    seconds: f64,
}

fn request(args: &ScaleArgs) -> Result<(ScaleRequest, PathBuf)> {
    let setup = match &args.setup {
        Some(p) => Some(read_scale_setup(p)?),
        None => None,
    };
    let mut files = args.files.iter();
    let generic = files
        .next()
        .cloned()
        .or_else(|| setup.as_ref().and_then(|s| s.model.clone()))
        .context("no generic model: give GENERIC.osim or --setup with a <model_file>")?;
    let static_trial = files
        .next()
        .cloned()
        .or_else(|| setup.as_ref().and_then(|s| s.static_trial.clone()))
        .context("no static trial: give STATIC or --setup with a <marker_file>")?;
    let output = args
        .output
        .clone()
        .or_else(|| setup.as_ref().and_then(|s| s.output_model.clone()))
        .context("no output: give -o SUBJECT.osim")?;
    let mut req = ScaleRequest::new(generic, static_trial);
    req.trials = files.cloned().collect();
    req.marker_set = args
        .markerset
        .clone()
        .or_else(|| setup.as_ref().and_then(|s| s.marker_set.clone()));
    req.mass = args.mass.or(setup.as_ref().and_then(|s| s.mass));
    req.height = args.height.or(setup.as_ref().and_then(|s| s.height));
    req.time_range = match &args.time_range {
        Some(v) => Some([v[0], v[1]]),
        None => setup.as_ref().and_then(|s| s.time_range),
    };
    req.groups = setup
        .as_ref()
        .map(|s| s.groups.clone())
        .filter(|g| !g.is_empty());
    if let Some(s) = &setup {
        req.manual_scales = s.manual_scales.clone();
        req.marker_weights = s.marker_weights.clone();
        req.scale_masses = !s.preserve_mass_distribution;
    }
    req.prior = args.prior == ScalePrior::Anthropometric;
    req.per_axis = args.per_axis;
    req.symmetric = args.symmetric;
    req.marker_sd = args.marker_sd / 1000.0;
    Ok((req, output))
}

fn print_text(out: &ScaleOutcome, path: &Path) {
    println!("scale factors (± SD):");
    for g in &out.fit.groups {
        let f = g.factors;
        let s = g.sd;
        if f[0] == f[1] && f[1] == f[2] {
            println!(
                "  {:<14} {:.4} ± {:.4}   {}",
                g.name,
                f[0],
                s[0],
                g.bodies.join(", ")
            );
        } else {
            println!(
                "  {:<14} {:.4} {:.4} {:.4} ± {:.4} {:.4} {:.4}   {}",
                g.name,
                f[0],
                f[1],
                f[2],
                s[0],
                s[1],
                s[2],
                g.bodies.join(", ")
            );
        }
    }
    let mut moved: Vec<_> = out
        .fit
        .markers
        .iter()
        .map(|m| {
            (
                m,
                (m.moved[0].powi(2) + m.moved[1].powi(2) + m.moved[2].powi(2)).sqrt(),
            )
        })
        .collect();
    moved.sort_by(|a, b| b.1.total_cmp(&a.1));
    println!("markers moved most from their scaled generic place:");
    for (m, d) in moved.iter().take(5) {
        println!("  {:<14} {:5.1} mm ({})", m.name, d * 1000.0, m.body);
    }
    if !out.absent.is_empty() {
        println!(
            "not in the static trial (placed by scaling only): {}",
            out.absent.join(", ")
        );
    }
    for f in &out.flags {
        println!("implausible: {f}");
    }
    println!(
        "marker RMS {:.1} mm over {} frame(s); mass {:.2} kg (generic {:.2}); {} iterations, {:.3} s",
        out.fit.rms * 1000.0,
        out.frames,
        out.total_mass,
        out.generic_mass,
        out.fit.iterations,
        out.seconds
    );
    println!("wrote {}", path.display());
}

/// The scaling record beside an `.osim` model (what `scale` wrote), for its report.
pub fn scaling_beside(model: &Path) -> Result<Option<ScaleRecord>> {
    if !jointfit_io::model_file::is_osim(model) {
        return Ok(None);
    }
    read_record(model).map_err(anyhow::Error::msg)
}

/// [`scaling_beside`] the report inputs' "subject model".
pub fn scaling_of(inputs: &[(String, String)]) -> Result<Option<ScaleRecord>> {
    match inputs.iter().find(|(k, _)| k == "subject model") {
        Some((_, model)) => scaling_beside(Path::new(model)),
        None => Ok(None),
    }
}

pub fn run(args: ScaleArgs) -> Result<()> {
    let (req, output) = request(&args)?;
    if output.extension().and_then(|e| e.to_str()) != Some("osim") {
        bail!("{}: the output must be an .osim file", output.display());
    }
    let out = scale_subject(&req).map_err(anyhow::Error::msg)?;
    jointfit_io::atomic::write_atomic(&output, out.text.as_bytes())
        .with_context(|| format!("{}: cannot write", output.display()))?;
    write_record(&output, &jointfit_app::scale::record(&req, &out)).map_err(anyhow::Error::msg)?;
    if args.json {
        let report = JsonReport {
            output: output.display().to_string(),
            scale_factors: out
                .fit
                .factors
                .iter()
                .map(|(k, v)| (k.as_str(), *v))
                .collect(),
            groups: &out.fit.groups,
            markers: out
                .fit
                .markers
                .iter()
                .map(|m| JsonMarker {
                    name: &m.name,
                    body: &m.body,
                    location: m.position,
                    moved_mm: m.moved.map(|d| d * 1000.0),
                    rms_mm: m.rms.is_finite().then_some(m.rms * 1000.0),
                })
                .collect(),
            rms_mm: out.fit.rms * 1000.0,
            frames: out.frames,
            absent_markers: &out.absent,
            flags: &out.flags,
            generic_mass: out.generic_mass,
            total_mass: out.total_mass,
            iterations: out.fit.iterations,
            seconds: out.seconds,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&out, &output);
    }
    Ok(())
}
