//! What `jointfit personalize` prints: per leg, in mm and degrees (text or JSON).

use std::collections::BTreeMap;
use std::path::Path;

use jointfit::model::lower_limb::Side;
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit_landmarks::bilateral::BothLegs;
use jointfit_landmarks::functional::apply::FunctionalReport;
use jointfit_landmarks::Personalized;
use serde::Serialize;

use crate::personalize_subject::JcComparison;

/// Another hip-centre estimate minus ours, in our pelvis frame (anterior, superior, lateral).
#[derive(Serialize)]
pub(crate) struct HjcComparison {
    pub(crate) marker: String,
    pub(crate) distance_mm: f64,
    pub(crate) delta_mm: [f64; 3],
}

#[derive(Serialize)]
struct SegmentRow {
    segment: String,
    markers: Vec<String>,
    rms_mm: f64,
    max_mm: f64,
}

/// Hip, knee and ankle centres (`hip_r`, …) in the file's own lab frame (mm), averaged over
/// the static window, and the stored joint centres asked for against them: the closing part of
/// a one-leg or a both-legs summary.
#[derive(Serialize, Default)]
pub(crate) struct LabCentres {
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    joint_centres_lab_mm: BTreeMap<String, [f64; 3]>,
    /// `--compare-jc`: stored joint centres against ours.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    joint_centre_comparison: Vec<JcComparison>,
}

impl LabCentres {
    pub(crate) fn new(centres: BTreeMap<String, [f64; 3]>, compare: Vec<JcComparison>) -> Self {
        LabCentres {
            joint_centres_lab_mm: centres,
            joint_centre_comparison: compare,
        }
    }

    /// The closing lines of a summary: the joint-centre comparisons, then `reproduced` and
    /// where the model of `parameters` parameters was written.
    fn closing(&self, reproduced: &str, parameters: usize, output: &str) -> String {
        let mut out = crate::personalize_subject::render(&self.joint_centre_comparison);
        out +=
            &format!("{reproduced}; all {parameters} parameters: jointfit model show {output}\n");
        out += &format!("wrote {output}\n");
        out
    }
}

/// Everything printed, in mm and degrees.
#[derive(Serialize)]
pub(crate) struct Summary {
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
    /// Joint centres in the lab frame (top level only).
    #[serde(flatten)]
    centres: LabCentres,
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
    pub(crate) fn of(
        r: &Personalized,
        set_name: &str,
        side: Side,
        static_trial: &str,
        output: &Path,
        hjc_comparison: Vec<HjcComparison>,
    ) -> Summary {
        let rep = &r.report;
        let w = &rep.window;
        let parameters = parameters(&r.spec);
        let static_pose = static_pose(&r.spec, &r.static_q);
        Summary {
            static_trial: static_trial.into(),
            output: output.display().to_string(),
            marker_set: set_name.to_string(),
            side: if side == Side::Right { "right" } else { "left" },
            window_first_frame: w.first,
            window_frames: w.len,
            window_seconds: w.seconds(),
            complete_frames: w.complete_frames,
            total_frames: w.total_frames,
            window_motion_rms_mm: w.motion_rms * 1e3,
            hip_method: if rep.hip_from_keypoint {
                "the hip keypoint"
            } else {
                rep.hip_method.citation()
            },
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
                    p.prior_sd.map(|sd| {
                        (
                            p.name.clone(),
                            sd * jointfit_app::present::unit_scale(p.unit),
                        )
                    })
                })
                .collect(),
            centres: LabCentres::default(),
        }
    }

    /// The summary with the lab-frame joint centres (a one-leg summary's top level).
    pub(crate) fn with_centres(self, centres: LabCentres) -> Summary {
        Summary { centres, ..self }
    }

    fn param(&self, name: &str) -> f64 {
        self.parameters
            .iter()
            .find(|(n, _)| n == name)
            .map_or(f64::NAN, |p| p.1)
    }

    pub(crate) fn render(&self) -> String {
        let reproduced = format!(
            "static pose reproduced to {:.1e} mm",
            self.static_fk_error_mm
        );
        self.render_leg()
            + &self
                .centres
                .closing(&reproduced, self.parameters.len(), &self.output)
    }

    /// Everything but the closing lines (one leg of a bilateral model too).
    pub(crate) fn render_leg(&self) -> String {
        let mut out = self.render_window_and_sizes();
        out += &self.render_axes();
        out += &self.render_residuals();
        if let Some(f) = &self.functional {
            out += &f.render();
        }
        out
    }

    /// The leg, the static window and the segment sizes.
    fn render_window_and_sizes(&self) -> String {
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
        out
    }

    /// The personalized joint centres and axes.
    fn render_axes(&self) -> String {
        let p = |n: &str| self.param(n);
        let mut out = format!(
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
        out
    }

    /// The rigid-fit residual per segment and the other hip-centre estimates.
    fn render_residuals(&self) -> String {
        let seg: Vec<String> = self
            .segments
            .iter()
            .map(|s| format!("{} {:.2}/{:.2}", s.segment, s.rms_mm, s.max_mm))
            .collect();
        let mut out = format!(
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
        out
    }
}

impl FunctionalSummary {
    /// The functional hip centre and knee axis against the landmark estimates.
    fn render(&self) -> String {
        let mut out = String::new();
        if let (Some(d), Some(s), Some(sd)) = (
            self.hip_minus_landmark_mm,
            self.hip_shift_mm,
            self.hip_sd_mm,
        ) {
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
                self.hip_rms_gap_mm.unwrap_or(f64::NAN),
                self.hip_range_deg.unwrap_or(f64::NAN)
            );
        }
        if let Some(a) = self.knee_axis_angle_deg {
            out += &format!(
                "functional knee axis (SARA): {a:.1} deg from the epicondylar axis \
                 (bootstrap {:.1} deg), point {:.1} mm from mid-epicondyles; gap RMS {:.1} \
                 mm over {:.0} deg of motion\n",
                self.knee_axis_sd_deg.unwrap_or(f64::NAN),
                self.knee_point_shift_mm.unwrap_or(f64::NAN),
                self.knee_rms_gap_mm.unwrap_or(f64::NAN),
                self.knee_range_deg.unwrap_or(f64::NAN)
            );
        }
        out
    }
}

/// Nominal parameters in the model's order (mm or deg).
fn parameters(spec: &ModelSpec) -> Vec<(String, f64)> {
    spec.parameters
        .iter()
        .map(|p| {
            (
                p.name.clone(),
                jointfit_app::present::shown_value(p.nominal, p.unit),
            )
        })
        .collect()
}

/// Coordinates of the static pose, in the compiled model's order (deg, or m for pelvis
/// translations).
fn static_pose(spec: &ModelSpec, q: &[f64]) -> Vec<(String, f64)> {
    let names: Vec<String> = Model::compile(spec).map_or(Vec::new(), |m| {
        m.coordinates().iter().map(|c| c.name.clone()).collect()
    });
    names
        .into_iter()
        .zip(q)
        .map(|(n, &q)| {
            let is_translation = n.starts_with("pelvis_t");
            (n, if is_translation { q } else { q.to_degrees() })
        })
        .collect()
}

/// The summary of a bilateral personalization: the joined model and each leg's summary.
#[derive(Serialize)]
pub(crate) struct BothSummary {
    static_trial: String,
    output: String,
    marker_set: String,
    side: &'static str,
    /// Largest distance of a pelvis marker between the two legs' static windows (0: both
    /// legs share one window, the usual case).
    pelvis_gap_mm: f64,
    /// Nominal parameters of the bilateral model (names suffixed _r/_l), mm or deg.
    parameters: Vec<(String, f64)>,
    /// Coordinates of the static pose in the bilateral model's order.
    static_pose: Vec<(String, f64)>,
    /// Each leg's one-sided summary (its parameters unsuffixed), right first.
    legs: Vec<Summary>,
    /// Joint centres of both legs (`hip_r`, …, `ankle_l`) in the lab frame.
    #[serde(flatten)]
    centres: LabCentres,
}

impl BothSummary {
    pub(crate) fn of(
        b: &BothLegs,
        static_trial: &str,
        output: &Path,
        legs: Vec<Summary>,
        centres: LabCentres,
    ) -> Self {
        BothSummary {
            static_trial: static_trial.into(),
            output: output.display().to_string(),
            marker_set: legs.first().map_or(String::new(), |l| l.marker_set.clone()),
            side: "both",
            pelvis_gap_mm: b.pelvis_gap * 1e3,
            parameters: parameters(&b.spec),
            static_pose: static_pose(&b.spec, &b.static_q),
            legs,
            centres,
        }
    }

    pub(crate) fn render(&self) -> String {
        let mut out = format!(
            "personalized both legs and the pelvis from {} (marker set {})\n",
            self.static_trial, self.marker_set
        );
        for leg in &self.legs {
            out += &format!("-- {} leg --\n", leg.side);
            out += &leg.render_leg();
        }
        let fk = self
            .legs
            .iter()
            .map(|l| l.static_fk_error_mm)
            .fold(0.0, f64::max);
        let pelvis = if self.pelvis_gap_mm == 0.0 {
            "both legs share one pelvis (one static window)".to_string()
        } else {
            format!(
                "no frame holds every marker of both legs: each leg used its own window, and \
                 pelvis markers moved {:.2} mm between them",
                self.pelvis_gap_mm
            )
        };
        let reproduced = format!("{pelvis}; static poses reproduced to {fk:.1e} mm");
        out + &self
            .centres
            .closing(&reproduced, self.parameters.len(), &self.output)
    }
}
