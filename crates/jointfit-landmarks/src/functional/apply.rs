//! Functional hip centre and knee axis as the nominal (prior-mean) values of a personalized
//! model, with prior SDs from their bootstrap spread.
//!
//! The clusters' reference coordinates are the static trial's averaged marker positions, so
//! SCoRE and SARA return the centre and axis in the static trial's frame at the static pose
//! (see the parent module). The hip joint then sits at the functional centre in both the
//! pelvis and the thigh (the thigh frame keeps its landmark origin, so `hip_thigh_*` become
//! non-zero); the knee axis is the functional axis through its point nearest the
//! mid-epicondyle point. The segment frames are unchanged.
//!
//! Prior SD of each affected parameter: `√(sd_boot² + floor²)`, the bootstrap SD turned into
//! the segment frame plus a floor for what the bootstrap cannot see (artefact common to the
//! whole trial, a joint that is not an ideal ball or hinge): [`HIP_FLOOR`], [`KNEE_ANGLE_FLOOR`],
//! [`KNEE_POINT_FLOOR`] (judgements; `docs/priors.md`).

use nalgebra::{Matrix3, Vector3};

use super::{sara, score, AxisFit, CentreFit, Cluster, FunctionalOptions};
use crate::frames::Anatomy;
use crate::LandmarkError;
use jointfit::spatial::Pose;
use jointfit::trial::Trial;

/// Floor of the functional hip centre's prior SD per axis (m).
pub(crate) const HIP_FLOOR: f64 = 0.005;
/// Floor of the functional knee axis' prior SD per orientation angle (rad).
pub(crate) const KNEE_ANGLE_FLOOR: f64 = 2.0 * std::f64::consts::PI / 180.0;
/// Floor of the functional knee axis point's prior SD per axis (m).
pub(crate) const KNEE_POINT_FLOOR: f64 = 0.003;

/// Functional trials to use in `personalize_with` (each in metres, Y-up, like the static).
#[derive(Debug, Clone, Copy, Default)]
pub struct FunctionalTrials<'a> {
    /// Hip circumduction / star-arc trial: SCoRE between pelvis and thigh.
    pub hip: Option<&'a Trial>,
    /// Knee flexion-extension trial: SARA between thigh and shank.
    pub knee: Option<&'a Trial>,
    pub options: FunctionalOptions,
}

/// What the functional methods found, next to the landmark estimates (static-trial frame).
#[derive(Debug, Clone, PartialEq)]
pub struct FunctionalReport {
    pub hip: Option<CentreFit>,
    /// Landmark (regression) hip centre (m).
    pub landmark_hip_centre: Vector3<f64>,
    pub knee: Option<AxisFit>,
    /// Epicondylar axis (unit) and mid-epicondyle point (m).
    pub landmark_knee_axis: Vector3<f64>,
    pub landmark_knee_centre: Vector3<f64>,
}

impl FunctionalReport {
    /// Distance from the landmark to the functional hip centre (m).
    pub fn hip_shift(&self) -> Option<f64> {
        self.hip
            .as_ref()
            .map(|h| (h.centre - self.landmark_hip_centre).norm())
    }
    /// Angle between the epicondylar and the functional knee axis (rad).
    pub fn knee_angle(&self) -> Option<f64> {
        self.knee
            .as_ref()
            .map(|k| k.axis.angle(&self.landmark_knee_axis))
    }
}

fn sd_in(frame: &Pose, cov: &Matrix3<f64>, floor: f64) -> Vector3<f64> {
    let c = frame.rot.transpose() * cov * frame.rot;
    c.diagonal().map(|v| (v.max(0.0) + floor * floor).sqrt())
}

/// Prior SDs of the parameters the functional methods set, by template parameter name.
pub(crate) type PriorSds = Vec<(&'static str, f64)>;

/// Applies the functional trials to `an`; returns the report and the prior SDs of the
/// parameters they set.
pub(crate) fn apply(
    an: &mut Anatomy,
    cluster: &dyn Fn(&str) -> Result<Cluster, LandmarkError>,
    trials: &FunctionalTrials,
) -> Result<(FunctionalReport, PriorSds), LandmarkError> {
    let mut report = FunctionalReport {
        hip: None,
        landmark_hip_centre: an.hip_centre,
        knee: None,
        landmark_knee_axis: an.knee_axis,
        landmark_knee_centre: an.knee_centre,
    };
    let mut sds = Vec::new();
    let f = an.frames.clone();
    let err = |joint: &'static str| move |e| LandmarkError::Functional { joint, error: e };
    if let Some(trial) = trials.hip {
        let fit = score(
            trial,
            &cluster("pelvis")?,
            &cluster("thigh")?,
            &trials.options,
        )
        .map_err(err("hip"))?;
        an.hip_in_pelvis = f.pelvis.inverse().transform_point(&fit.centre);
        an.hip_in_thigh = f.thigh.inverse().transform_point(&fit.centre);
        let sp = sd_in(&f.pelvis, &fit.covariance, HIP_FLOOR);
        let st = sd_in(&f.thigh, &fit.covariance, HIP_FLOOR);
        for (k, axis) in ["anterior", "superior", "lateral"].iter().enumerate() {
            sds.push((hip_name("pelvis", axis), sp[k]));
            sds.push((hip_name("thigh", axis), st[k]));
        }
        report.hip = Some(fit);
    }
    if let Some(trial) = trials.knee {
        let fit = sara(
            trial,
            &cluster("thigh")?,
            &cluster("shank")?,
            &an.knee_centre,
            &an.knee_axis,
            &trials.options,
        )
        .map_err(err("knee"))?;
        an.knee_axis = fit.axis;
        an.knee_centre = fit.point;
        let angle = (fit.angle_rms.powi(2) / 2.0 + KNEE_ANGLE_FLOOR.powi(2)).sqrt();
        for n in [
            "knee_thigh_frontal",
            "knee_thigh_transverse",
            "knee_shank_frontal",
            "knee_shank_transverse",
        ] {
            sds.push((n, angle));
        }
        let t = sd_in(&f.thigh, &fit.point_covariance, KNEE_POINT_FLOOR);
        let s = sd_in(&f.shank, &fit.point_covariance, KNEE_POINT_FLOOR);
        sds.extend([
            ("knee_thigh_anterior", t.x),
            ("knee_thigh_superior", t.y),
            ("knee_shank_anterior", s.x),
            ("knee_shank_superior", s.y),
            ("knee_shank_lateral", s.z),
        ]);
        report.knee = Some(fit);
    }
    Ok((report, sds))
}

fn hip_name(side: &str, axis: &str) -> &'static str {
    match (side, axis) {
        ("pelvis", "anterior") => "hip_pelvis_anterior",
        ("pelvis", "superior") => "hip_pelvis_superior",
        ("pelvis", _) => "hip_pelvis_lateral",
        (_, "anterior") => "hip_thigh_anterior",
        (_, "superior") => "hip_thigh_superior",
        _ => "hip_thigh_lateral",
    }
}
