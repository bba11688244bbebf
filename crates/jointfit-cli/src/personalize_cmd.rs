//! `jointfit personalize`: a static trial + a marker set → a subject model TOML
//! (the anatomical-landmark method, [`jointfit::landmarks`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use jointfit::landmarks::functional::{FunctionalReport, FunctionalTrials};
use jointfit::landmarks::{
    personalize_with, HipCentreMethod, MarkerSet, PersonalizeOptions, Personalized, PRESET_NAMES,
};
use jointfit::model::lower_limb::Side;
use serde::Serialize;

use crate::common::{load_trial, Up};

#[derive(Args)]
pub struct PersonalizeArgs {
    /// Static standing trial (.trc or .c3d).
    #[arg(long = "static", value_name = "FILE")]
    static_trial: PathBuf,
    /// Marker set: a TOML file or a preset (gait2392, opencap, jam, plugin-gait).
    #[arg(long, value_name = "MAP.toml|PRESET")]
    markers: String,
    /// Which leg to model.
    #[arg(long, value_enum)]
    side: SideArg,
    /// The laboratory's vertical axis; the trial is rotated to the model's Y-up frame.
    /// Default: detected from the static trial's marker layout (head and pelvis above the
    /// feet), else y. Recorded in the model as `lab_up` for every later command.
    #[arg(long, value_enum)]
    up: Option<Up>,
    /// Hip-centre regression.
    #[arg(long, value_enum, default_value = "bell")]
    hip: HipArg,
    /// Length of the averaged static window (s).
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS", allow_negative_numbers = true, value_parser = crate::validate::positive)]
    window: f64,
    /// Model name written into the file (default: the output file's stem).
    #[arg(long)]
    name: Option<String>,
    /// A marker of the trial holding another hip-centre estimate (e.g. OpenCap's R_HJC):
    /// prints its distance from ours, averaged over the same window. Repeatable.
    #[arg(long = "compare-hjc", value_name = "LABEL")]
    compare_hjc: Vec<String>,
    /// Functional hip trial (circumduction / star arcs): the hip centre by SCoRE
    /// (Ehrig et al. 2006) replaces the regression as nominal value and prior mean.
    #[arg(long, value_name = "FILE")]
    functional_hip: Option<PathBuf>,
    /// Functional knee trial (flexion-extension): the knee axis by SARA (Ehrig et al. 2007)
    /// replaces the epicondylar axis as nominal value and prior mean.
    #[arg(long, value_name = "FILE")]
    functional_knee: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Output model file (TOML), written atomically.
    #[arg(short = 'o', long = "output", value_name = "SUBJECT.toml")]
    output: PathBuf,
}

#[derive(Clone, Copy, ValueEnum)]
enum SideArg {
    Right,
    Left,
}

#[derive(Clone, Copy, ValueEnum)]
enum HipArg {
    Bell,
    Harrington,
}

fn load_marker_set(arg: &str) -> Result<MarkerSet> {
    let path = Path::new(arg);
    if path.exists() {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        return Ok(MarkerSet::from_toml(&text, &path.display().to_string())?);
    }
    if PRESET_NAMES.contains(&arg) {
        return Ok(MarkerSet::preset(arg)?);
    }
    bail!(
        "{arg:?} is neither a marker-set file nor a preset ({})",
        PRESET_NAMES.join(", ")
    )
}

/// `--up`, else the vertical detected from the static trial's marker layout
/// ([`jointfit::vertical::detect_up`], said on stderr), else y (with a warning).
fn static_up(args: &PersonalizeArgs) -> Result<Up> {
    if let Some(up) = args.up {
        return Ok(up);
    }
    let (raw, _) = jointfit_io::trial_file::read_trial_noted(&args.static_trial)?;
    let path = args.static_trial.display();
    Ok(match jointfit::vertical::detect_up(&raw) {
        // Recorded in the model as `lab_up`; said in the error context if personalize fails.
        Some(d) => Up::from(d.up),
        None => {
            eprintln!(
                "jointfit: warning: {path}: cannot tell the up axis from the marker labels; \
                 assuming y (pass --up)"
            );
            Up::Y
        }
    })
}

pub fn run(args: PersonalizeArgs) -> Result<()> {
    crate::output::Files::new()
        .input("static trial", &args.static_trial)
        .model("marker set", &args.markers)
        .output("output", &args.output)
        .check()?;
    let set = load_marker_set(&args.markers)?;
    let up = static_up(&args)?;
    let trial = load_trial(&args.static_trial, up, None)?;
    let scale: Vec<_> = jointfit::checks::check_scale(&trial).into_iter().collect();
    crate::common::report_findings(&scale, &args.static_trial)?;
    let side = match args.side {
        SideArg::Right => Side::Right,
        SideArg::Left => Side::Left,
    };
    let name = args.name.clone().unwrap_or_else(|| {
        args.output
            .file_stem()
            .map_or("subject".into(), |s| s.to_string_lossy().into_owned())
    });
    let opts = PersonalizeOptions {
        hip_centre: match args.hip {
            HipArg::Bell => HipCentreMethod::Bell,
            HipArg::Harrington => HipCentreMethod::Harrington,
        },
        window_seconds: args.window,
        name,
        ..PersonalizeOptions::default()
    };
    let static_name = args.static_trial.display().to_string();
    let load = |p: &Option<PathBuf>| p.as_ref().map(|p| load_trial(p, up, None)).transpose();
    let (hip_trial, knee_trial) = (load(&args.functional_hip)?, load(&args.functional_knee)?);
    let func = FunctionalTrials {
        hip: hip_trial.as_ref(),
        knee: knee_trial.as_ref(),
        ..FunctionalTrials::default()
    };
    let mut result = personalize_with(&trial, &set, side, &opts, &func).with_context(|| {
        let up = up
            .to_possible_value()
            .map_or("?".into(), |v| v.get_name().to_string());
        let functional: Vec<String> = [&args.functional_hip, &args.functional_knee]
            .into_iter()
            .flatten()
            .map(|p| p.display().to_string())
            .collect();
        let with = if functional.is_empty() {
            String::new()
        } else {
            format!(" with functional trial(s) {}", functional.join(", "))
        };
        format!("{static_name} (read with --up={up}){with}: cannot personalize")
    })?;
    result.spec.description = format!("{}; from {static_name}", result.spec.description);
    result.spec.lab_up = Some(up.into());

    let mut compare = Vec::new();
    for label in &args.compare_hjc {
        let c = trial
            .index_of(label)
            .with_context(|| format!("{static_name}: --compare-hjc"))?;
        let w = &result.report.window;
        let pts: Vec<_> = (w.first..w.end()).filter_map(|f| trial.get(f, c)).collect();
        if pts.is_empty() {
            bail!("{static_name}: marker {label:?} is missing throughout the static window");
        }
        let mean = pts.iter().sum::<nalgebra::Vector3<f64>>() / pts.len() as f64;
        let d = result.frames.pelvis.rot.transpose() * (mean - result.report.hip_centre);
        let lateral = if side == Side::Right { d.z } else { -d.z };
        compare.push(HjcComparison {
            marker: label.clone(),
            distance_mm: d.norm() * 1e3,
            delta_mm: [d.x * 1e3, d.y * 1e3, lateral * 1e3],
        });
    }

    jointfit_io::atomic::write_atomic(&args.output, result.spec.to_toml().as_bytes())
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    let summary = Summary::of(&result, &set, side, &static_name, &args.output, compare);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", summary.render());
    }
    Ok(())
}

/// Another hip-centre estimate minus ours, in our pelvis frame (anterior, superior, lateral).
#[derive(Serialize)]
struct HjcComparison {
    marker: String,
    distance_mm: f64,
    delta_mm: [f64; 3],
}

#[derive(Serialize)]
struct SegmentRow {
    segment: String,
    markers: Vec<String>,
    rms_mm: f64,
    max_mm: f64,
}

/// Everything printed, in mm and degrees.
#[derive(Serialize)]
struct Summary {
    static_trial: String,
    output: String,
    marker_set: String,
    side: &'static str,
    window_first_frame: usize,
    window_frames: usize,
    window_seconds: f64,
    complete_frames: usize,
    total_frames: usize,
    window_motion_rms_mm: f64,
    hip_method: &'static str,
    pelvis_width_mm: f64,
    pelvis_depth_mm: f64,
    knee_width_mm: f64,
    ankle_width_mm: f64,
    thigh_length_mm: f64,
    shank_length_mm: f64,
    /// Nominal parameters, in the model's order (mm or deg).
    parameters: Vec<(String, f64)>,
    /// Coordinates of the static pose (deg, or m for pelvis translations).
    static_pose: Vec<(String, f64)>,
    segments: Vec<SegmentRow>,
    static_fk_error_mm: f64,
    hjc_comparison: Vec<HjcComparison>,
    /// Functional hip centre / knee axis against the landmark estimates.
    functional: Option<FunctionalSummary>,
    /// Prior SD per parameter (mm or deg), in the model's order.
    prior_sd: Vec<(String, f64)>,
}

/// Functional methods' results (mm, deg), in the static trial's frame.
#[derive(Serialize)]
struct FunctionalSummary {
    /// SCoRE hip centre minus the regression's (pelvis frame: anterior, superior, lateral).
    hip_minus_landmark_mm: Option<[f64; 3]>,
    hip_shift_mm: Option<f64>,
    /// Bootstrap SD of the hip centre per static-frame axis.
    hip_sd_mm: Option<[f64; 3]>,
    hip_rms_gap_mm: Option<f64>,
    hip_range_deg: Option<f64>,
    /// Angle between the SARA axis and the epicondylar axis.
    knee_axis_angle_deg: Option<f64>,
    knee_axis_sd_deg: Option<f64>,
    knee_point_shift_mm: Option<f64>,
    knee_rms_gap_mm: Option<f64>,
    knee_range_deg: Option<f64>,
}

impl FunctionalSummary {
    fn of(f: &FunctionalReport, r: &Personalized, side: Side) -> Self {
        let lat = if side == Side::Right { 1.0 } else { -1.0 };
        let h = f.hip.as_ref();
        let k = f.knee.as_ref();
        FunctionalSummary {
            hip_minus_landmark_mm: h.map(|h| {
                let d = r.frames.pelvis.rot.transpose() * (h.centre - f.landmark_hip_centre);
                [d.x * 1e3, d.y * 1e3, lat * d.z * 1e3]
            }),
            hip_shift_mm: f.hip_shift().map(|d| d * 1e3),
            hip_sd_mm: h.map(|h| [h.sd.x * 1e3, h.sd.y * 1e3, h.sd.z * 1e3]),
            hip_rms_gap_mm: h.map(|h| h.rms_gap * 1e3),
            hip_range_deg: h.map(|h| h.range_of_motion.to_degrees()),
            knee_axis_angle_deg: f.knee_angle().map(f64::to_degrees),
            knee_axis_sd_deg: k.map(|k| k.angle_rms.to_degrees()),
            knee_point_shift_mm: k.map(|k| (k.point - f.landmark_knee_centre).norm() * 1e3),
            knee_rms_gap_mm: k.map(|k| k.rms_gap * 1e3),
            knee_range_deg: k.map(|k| k.range_of_motion.to_degrees()),
        }
    }
}

impl Summary {
    fn of(
        r: &Personalized,
        set: &MarkerSet,
        side: Side,
        static_trial: &str,
        output: &Path,
        hjc_comparison: Vec<HjcComparison>,
    ) -> Summary {
        let rep = &r.report;
        let w = &rep.window;
        let parameters = r
            .spec
            .parameters
            .iter()
            .map(|p| (p.name.clone(), p.unit.to_display(p.nominal)))
            .collect();
        let static_pose = r
            .spec
            .joints
            .iter()
            .flat_map(|j| j.coordinates.iter().map(|c| c.name().to_string()))
            .zip(&r.static_q)
            .map(|(n, &q)| {
                let is_translation = n.starts_with("pelvis_t");
                (n, if is_translation { q } else { q.to_degrees() })
            })
            .collect();
        Summary {
            static_trial: static_trial.into(),
            output: output.display().to_string(),
            marker_set: set.name.clone(),
            side: if side == Side::Right { "right" } else { "left" },
            window_first_frame: w.first,
            window_frames: w.len,
            window_seconds: w.seconds(),
            complete_frames: w.complete_frames,
            total_frames: w.total_frames,
            window_motion_rms_mm: w.motion_rms * 1e3,
            hip_method: rep.hip_method.citation(),
            pelvis_width_mm: rep.pelvis_width * 1e3,
            pelvis_depth_mm: rep.pelvis_depth * 1e3,
            knee_width_mm: rep.knee_width * 1e3,
            ankle_width_mm: rep.ankle_width * 1e3,
            thigh_length_mm: rep.thigh_length * 1e3,
            shank_length_mm: rep.shank_length * 1e3,
            parameters,
            static_pose,
            segments: rep
                .segments
                .iter()
                .map(|s| SegmentRow {
                    segment: s.segment.clone(),
                    markers: s.markers.clone(),
                    rms_mm: s.rms * 1e3,
                    max_mm: s.max * 1e3,
                })
                .collect(),
            static_fk_error_mm: rep.static_fk_error * 1e3,
            hjc_comparison,
            functional: rep
                .functional
                .as_ref()
                .map(|f| FunctionalSummary::of(f, r, side)),
            prior_sd: r
                .spec
                .parameters
                .iter()
                .filter_map(|p| {
                    p.prior_sd
                        .map(|sd| (p.name.clone(), sd * p.unit.display_scale()))
                })
                .collect(),
        }
    }

    fn param(&self, name: &str) -> f64 {
        self.parameters
            .iter()
            .find(|(n, _)| n == name)
            .map_or(f64::NAN, |p| p.1)
    }

    fn render(&self) -> String {
        let p = |n: &str| self.param(n);
        let mut out = format!(
            "personalized {} leg from {} (marker set {})\n",
            self.side, self.static_trial, self.marker_set
        );
        out += &format!(
            "window: frames {}-{} of {} ({:.2} s, {} complete), marker motion RMS {:.2} mm\n",
            self.window_first_frame,
            self.window_first_frame + self.window_frames - 1,
            self.total_frames,
            self.window_seconds,
            self.complete_frames,
            self.window_motion_rms_mm
        );
        out += &format!(
            "pelvis width {:.1} mm, depth {:.1} mm; knee width {:.1} mm; ankle width {:.1} mm; \
             thigh {:.1} mm; shank {:.1} mm\n",
            self.pelvis_width_mm,
            self.pelvis_depth_mm,
            self.knee_width_mm,
            self.ankle_width_mm,
            self.thigh_length_mm,
            self.shank_length_mm
        );
        out += &format!(
            "hip centre ({}) in pelvis: anterior {:.1}, superior {:.1}, lateral {:.1} mm\n",
            self.hip_method,
            p("hip_pelvis_anterior"),
            p("hip_pelvis_superior"),
            p("hip_pelvis_lateral")
        );
        out += &format!(
            "knee axis: thigh frontal {:.1} deg, superior {:.1} mm; shank frontal {:.1}, \
             transverse {:.1} deg\n",
            p("knee_thigh_frontal"),
            p("knee_thigh_superior"),
            p("knee_shank_frontal"),
            p("knee_shank_transverse")
        );
        out += &format!(
            "talocrural axis: shank frontal {:.1} deg, superior {:.1} mm\n",
            p("talocrural_shank_frontal"),
            p("talocrural_shank_superior")
        );
        out += &format!(
            "subtalar axis: talus transverse {:.1} deg, offset {:.1} mm; in foot {:.1}/{:.1} \
             deg at ({:.1}, {:.1}, {:.1}) mm\n",
            p("subtalar_talus_transverse"),
            p("subtalar_talus_superior"),
            p("subtalar_foot_transverse"),
            p("subtalar_foot_sagittal"),
            p("subtalar_foot_anterior"),
            p("subtalar_foot_superior"),
            p("subtalar_foot_lateral")
        );
        let seg: Vec<String> = self
            .segments
            .iter()
            .map(|s| format!("{} {:.2}/{:.2}", s.segment, s.rms_mm, s.max_mm))
            .collect();
        out += &format!(
            "rigid-fit residual over the window (RMS/max mm): {}\n",
            seg.join(", ")
        );
        for c in &self.hjc_comparison {
            out += &format!(
                "{} is {:.1} mm from our hip centre (anterior {:+.1}, superior {:+.1}, lateral \
                 {:+.1} mm)\n",
                c.marker, c.distance_mm, c.delta_mm[0], c.delta_mm[1], c.delta_mm[2]
            );
        }
        if let Some(f) = &self.functional {
            if let (Some(d), Some(s), Some(sd)) =
                (f.hip_minus_landmark_mm, f.hip_shift_mm, f.hip_sd_mm)
            {
                out += &format!(
                    "functional hip centre (SCoRE): {s:.1} mm from the regression (anterior \
                     {:+.1}, superior {:+.1}, lateral {:+.1} mm); bootstrap SD {:.1}/{:.1}/{:.1} \
                     mm; centre gap RMS {:.1} mm over {:.0} deg of motion\n",
                    d[0],
                    d[1],
                    d[2],
                    sd[0],
                    sd[1],
                    sd[2],
                    f.hip_rms_gap_mm.unwrap_or(f64::NAN),
                    f.hip_range_deg.unwrap_or(f64::NAN)
                );
            }
            if let Some(a) = f.knee_axis_angle_deg {
                out += &format!(
                    "functional knee axis (SARA): {a:.1} deg from the epicondylar axis \
                     (bootstrap {:.1} deg), point {:.1} mm from mid-epicondyles; gap RMS {:.1} \
                     mm over {:.0} deg of motion\n",
                    f.knee_axis_sd_deg.unwrap_or(f64::NAN),
                    f.knee_point_shift_mm.unwrap_or(f64::NAN),
                    f.knee_rms_gap_mm.unwrap_or(f64::NAN),
                    f.knee_range_deg.unwrap_or(f64::NAN)
                );
            }
        }
        out += &format!(
            "static pose reproduced to {:.1e} mm; all 27 parameters: jointfit model show {}\n",
            self.static_fk_error_mm, self.output
        );
        out += &format!("wrote {}\n", self.output);
        out
    }
}
