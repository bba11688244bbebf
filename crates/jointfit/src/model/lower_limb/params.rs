//! The 27 joint parameters of one leg (Reinbolt et al. 2005, Table 2): names, groups, nominal
//! values, bounds and how each mirrors onto the left leg.

use super::Side;
use crate::model::spec::{ParameterSpec, ScalarSpec, Unit, M_PER_MM};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// How a parameter enters its offset scalar.
#[derive(Clone, Copy)]
pub(super) enum Mirror {
    /// Same on both sides (anterior, superior, sagittal angles).
    Keep,
    /// Negated on the left (lateral positions, frontal and transverse angles).
    Flip,
}

/// (name, group, value in mm or deg, half-width of the bounds in mm or deg, mirror, doc)
pub(super) type ParamRow = (&'static str, &'static str, f64, f64, Mirror, &'static str);

/// The 27 parameters in the paper's Table 2 order (positions in mm, angles in deg).
/// Half-widths follow Reinbolt's bounds: hip centre in a cube of side 0.75·PW (PW ≈ 240 mm),
/// knee positions in a cube of side ≈ knee width, ankle positions in a cube of side ≈
/// inter-malleolar distance, every axis within ±30°.
pub(super) const PARAMS: [ParamRow; 27] = [
    (
        "hip_pelvis_anterior",
        "hip",
        -59.31,
        90.0,
        Mirror::Keep,
        "hip centre in pelvis, anterior",
    ),
    (
        "hip_pelvis_superior",
        "hip",
        -91.67,
        90.0,
        Mirror::Keep,
        "hip centre in pelvis, superior",
    ),
    (
        "hip_pelvis_lateral",
        "hip",
        86.28,
        90.0,
        Mirror::Flip,
        "hip centre in pelvis, lateral",
    ),
    (
        "hip_thigh_anterior",
        "hip",
        0.0,
        90.0,
        Mirror::Keep,
        "hip centre in thigh, anterior",
    ),
    (
        "hip_thigh_superior",
        "hip",
        0.0,
        90.0,
        Mirror::Keep,
        "hip centre in thigh, superior",
    ),
    (
        "hip_thigh_lateral",
        "hip",
        0.0,
        90.0,
        Mirror::Flip,
        "hip centre in thigh, lateral",
    ),
    (
        "knee_thigh_frontal",
        "knee",
        0.0,
        30.0,
        Mirror::Flip,
        "knee axis in thigh, frontal-plane angle",
    ),
    (
        "knee_thigh_transverse",
        "knee",
        0.0,
        30.0,
        Mirror::Flip,
        "knee axis in thigh, transverse-plane angle",
    ),
    (
        "knee_shank_frontal",
        "knee",
        -4.07,
        30.0,
        Mirror::Flip,
        "knee axis in shank, frontal-plane angle",
    ),
    (
        "knee_shank_transverse",
        "knee",
        1.54,
        30.0,
        Mirror::Flip,
        "knee axis in shank, transverse-plane angle",
    ),
    (
        "knee_thigh_anterior",
        "knee",
        0.0,
        50.0,
        Mirror::Keep,
        "knee axis point in thigh, anterior",
    ),
    (
        "knee_thigh_superior",
        "knee",
        -392.11,
        50.0,
        Mirror::Keep,
        "knee axis point in thigh, superior",
    ),
    (
        "knee_shank_anterior",
        "knee",
        0.0,
        50.0,
        Mirror::Keep,
        "knee axis point in shank, anterior",
    ),
    (
        "knee_shank_superior",
        "knee",
        0.0,
        50.0,
        Mirror::Keep,
        "knee axis point in shank, superior",
    ),
    (
        "knee_shank_lateral",
        "knee",
        0.0,
        50.0,
        Mirror::Flip,
        "knee axis point in shank, lateral",
    ),
    (
        "talocrural_shank_frontal",
        "ankle",
        8.81,
        30.0,
        Mirror::Flip,
        "talocrural axis in shank, frontal-plane angle",
    ),
    (
        "talocrural_shank_transverse",
        "ankle",
        0.0,
        30.0,
        Mirror::Flip,
        "talocrural axis in shank, transverse-plane angle",
    ),
    (
        "talocrural_shank_anterior",
        "ankle",
        0.0,
        35.0,
        Mirror::Keep,
        "talocrural axis point in shank, anterior",
    ),
    (
        "talocrural_shank_superior",
        "ankle",
        -411.32,
        35.0,
        Mirror::Keep,
        "talocrural axis point in shank, superior",
    ),
    (
        "talocrural_shank_lateral",
        "ankle",
        0.0,
        35.0,
        Mirror::Flip,
        "talocrural axis point in shank, lateral",
    ),
    (
        "subtalar_talus_transverse",
        "ankle",
        26.89,
        30.0,
        Mirror::Flip,
        "subtalar axis in talus, medial angle (transverse plane)",
    ),
    (
        "subtalar_foot_transverse",
        "ankle",
        23.0,
        30.0,
        Mirror::Flip,
        "subtalar axis in foot, medial deviation (transverse plane)",
    ),
    (
        "subtalar_foot_sagittal",
        "ankle",
        42.0,
        30.0,
        Mirror::Keep,
        "subtalar axis in foot, elevation (sagittal plane)",
    ),
    (
        "subtalar_talus_superior",
        "ankle",
        -12.4,
        35.0,
        Mirror::Keep,
        "subtalar axis offset from the talocrural axis along their common perpendicular",
    ),
    (
        "subtalar_foot_anterior",
        "ankle",
        91.14,
        35.0,
        Mirror::Keep,
        "subtalar axis point in foot, anterior",
    ),
    (
        "subtalar_foot_superior",
        "ankle",
        39.01,
        35.0,
        Mirror::Keep,
        "subtalar axis point in foot, superior",
    ),
    (
        "subtalar_foot_lateral",
        "ankle",
        11.17,
        35.0,
        Mirror::Flip,
        "subtalar axis point in foot, lateral",
    ),
];

pub(super) fn param_spec(row: &ParamRow) -> ParameterSpec {
    let (name, group, value, half, _, doc) = *row;
    let is_angle =
        name.ends_with("frontal") || name.ends_with("transverse") || name.ends_with("sagittal");
    let (unit, k) = if is_angle {
        (Unit::Radian, DEG)
    } else {
        (Unit::Metre, M_PER_MM)
    };
    ParameterSpec {
        name: name.to_string(),
        group: group.to_string(),
        unit,
        nominal: value * k,
        lower: (value - half) * k,
        upper: (value + half) * k,
        description: doc.to_string(),
        prior_sd: None,
        prior_mean: None,
    }
}

pub(super) fn nominal(name: &str) -> f64 {
    let row = PARAMS
        .iter()
        .find(|r| r.0 == name)
        .expect("known parameter");
    param_spec(row).nominal
}

/// The scalar that reads parameter `name` on `side`.
pub(super) fn par(name: &str, side: Side) -> ScalarSpec {
    let row = PARAMS
        .iter()
        .find(|r| r.0 == name)
        .expect("known parameter");
    let scale = match row.4 {
        Mirror::Keep => 1.0,
        Mirror::Flip => side.sign(),
    };
    ScalarSpec::param(name, scale)
}
