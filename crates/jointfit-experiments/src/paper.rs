//! The published numbers the reproduction is compared with.
//!
//! Source: Reinbolt J.A., Schutte J.F., Fregly B.J., Koh B.I., Haftka R.T., George A.D.,
//! Mitchell K.H. (2005). *Determination of patient-specific multi-joint kinematic models
//! through two-level optimization.* Journal of Biomechanics 38(3):621–626,
//! doi:10.1016/j.jbiomech.2004.03.031 — Table 1 (RMS errors) and Table 2 (joint parameters),
//! transcribed from the paper's text (`shared/paper/reinbolt2005-two-level-optimization.txt`).
//! Units as published: mm and degrees. `None` is the paper's "n/a" (the hip has no
//! orientation parameters).

/// Columns of Table 1, in order.
pub const TABLE1_COLUMNS: [&str; 4] = ["Hip only", "Knee only", "Ankle only", "Full leg"];

/// One row of Table 1: a value per column.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    pub data: &'static str,
    pub quantity: &'static str,
    pub values: [Option<f64>; 4],
}

/// Reinbolt et al. 2005, Table 1: RMS joint-parameter and marker-distance errors.
pub const TABLE1: [PaperRow; 8] = [
    PaperRow {
        data: "synthetic without noise",
        quantity: "marker distances (mm)",
        values: [
            Some(3.89e-03),
            Some(1.79e-02),
            Some(3.58e-03),
            Some(9.80e-05),
        ],
    },
    PaperRow {
        data: "synthetic without noise",
        quantity: "orientation parameters (deg)",
        values: [None, Some(4.63e-02), Some(1.85e-02), Some(8.83e-02)],
    },
    PaperRow {
        data: "synthetic without noise",
        quantity: "position parameters (mm)",
        values: [
            Some(7.78e-05),
            Some(9.49e-02),
            Some(4.95e-03),
            Some(6.05e-03),
        ],
    },
    PaperRow {
        data: "synthetic with noise",
        quantity: "marker distances (mm)",
        values: [Some(5.20), Some(4.23), Some(5.68), Some(5.65)],
    },
    PaperRow {
        data: "synthetic with noise",
        quantity: "orientation parameters (deg)",
        values: [None, Some(2.51), Some(5.04), Some(10.37)],
    },
    PaperRow {
        data: "synthetic with noise",
        quantity: "position parameters (mm)",
        values: [Some(1.66), Some(3.46), Some(10.04), Some(8.16)],
    },
    PaperRow {
        data: "experimental, two-level optimization",
        quantity: "marker distances (mm)",
        values: [Some(3.92), Some(7.10), Some(3.94), Some(7.80)],
    },
    PaperRow {
        data: "experimental, anatomical landmarks",
        quantity: "marker distances (mm)",
        values: [Some(5.47), Some(14.23), Some(10.29), Some(13.66)],
    },
];

/// The reductions of RMS marker distance error the paper's text reports (§3, %), per column.
pub const TABLE1_REDUCTION_PERCENT: [f64; 4] = [28.0, 50.0, 62.0, 43.0];

/// One row of Table 2: (our parameter name, paper's joint, paper's description, segment,
/// anatomical landmarks, single-joint optimizations, full-leg optimization), mm or deg.
pub type PaperParamRow = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    f64,
    f64,
    f64,
);

/// Reinbolt et al. 2005, Table 2, in the paper's order (the same as the model's parameters).
pub const TABLE2: [PaperParamRow; 27] = [
    (
        "hip_pelvis_anterior",
        "Hip",
        "Anterior position",
        "Pelvis",
        -59.31,
        -75.19,
        -67.81,
    ),
    (
        "hip_pelvis_superior",
        "Hip",
        "Superior position",
        "Pelvis",
        -91.67,
        -92.69,
        -84.13,
    ),
    (
        "hip_pelvis_lateral",
        "Hip",
        "Lateral position",
        "Pelvis",
        86.28,
        88.58,
        134.64,
    ),
    (
        "hip_thigh_anterior",
        "Hip",
        "Anterior position",
        "Thigh",
        0.00,
        -21.23,
        8.88,
    ),
    (
        "hip_thigh_superior",
        "Hip",
        "Superior position",
        "Thigh",
        0.00,
        8.14,
        13.12,
    ),
    (
        "hip_thigh_lateral",
        "Hip",
        "Lateral position",
        "Thigh",
        0.00,
        14.38,
        67.08,
    ),
    (
        "knee_thigh_frontal",
        "Knee",
        "Frontal plane orientation",
        "Thigh",
        0.00,
        -0.59,
        17.40,
    ),
    (
        "knee_thigh_transverse",
        "Knee",
        "Transverse plane orientation",
        "Thigh",
        0.00,
        14.85,
        12.19,
    ),
    (
        "knee_shank_frontal",
        "Knee",
        "Frontal plane orientation",
        "Shank",
        -4.07,
        -2.72,
        6.19,
    ),
    (
        "knee_shank_transverse",
        "Knee",
        "Transverse plane orientation",
        "Shank",
        1.54,
        2.40,
        13.89,
    ),
    (
        "knee_thigh_anterior",
        "Knee",
        "Anterior position",
        "Thigh",
        0.00,
        -14.22,
        -22.17,
    ),
    (
        "knee_thigh_superior",
        "Knee",
        "Superior position",
        "Thigh",
        -392.11,
        -396.12,
        -390.54,
    ),
    (
        "knee_shank_anterior",
        "Knee",
        "Anterior position",
        "Shank",
        0.00,
        -2.50,
        -14.79,
    ),
    (
        "knee_shank_superior",
        "Knee",
        "Superior position",
        "Shank",
        0.00,
        -4.57,
        -4.99,
    ),
    (
        "knee_shank_lateral",
        "Knee",
        "Lateral position",
        "Shank",
        0.00,
        14.72,
        14.10,
    ),
    (
        "talocrural_shank_frontal",
        "Ankle (talocrural)",
        "Frontal plane orientation",
        "Shank",
        8.81,
        16.64,
        -5.07,
    ),
    (
        "talocrural_shank_transverse",
        "Ankle (talocrural)",
        "Transverse plane orientation",
        "Shank",
        0.00,
        9.54,
        10.37,
    ),
    (
        "talocrural_shank_anterior",
        "Ankle (talocrural)",
        "Anterior position",
        "Shank",
        0.00,
        16.51,
        23.56,
    ),
    (
        "talocrural_shank_superior",
        "Ankle (talocrural)",
        "Superior position",
        "Shank",
        -411.32,
        -411.86,
        -418.79,
    ),
    (
        "talocrural_shank_lateral",
        "Ankle (talocrural)",
        "Lateral position",
        "Shank",
        0.00,
        -15.10,
        -16.33,
    ),
    (
        "subtalar_talus_transverse",
        "Ankle (subtalar)",
        "Transverse plane orientation",
        "Talus",
        26.89,
        27.36,
        10.24,
    ),
    (
        "subtalar_foot_transverse",
        "Ankle (subtalar)",
        "Transverse plane orientation",
        "Foot",
        23.00,
        13.20,
        14.74,
    ),
    (
        "subtalar_foot_sagittal",
        "Ankle (subtalar)",
        "Sagittal plane orientation",
        "Foot",
        42.00,
        45.26,
        37.39,
    ),
    (
        "subtalar_talus_superior",
        "Ankle (subtalar)",
        "Superior position",
        "Talus",
        -12.40,
        -21.42,
        -9.49,
    ),
    (
        "subtalar_foot_anterior",
        "Ankle (subtalar)",
        "Anterior position",
        "Foot",
        91.14,
        112.44,
        115.80,
    ),
    (
        "subtalar_foot_superior",
        "Ankle (subtalar)",
        "Superior position",
        "Foot",
        39.01,
        38.51,
        29.38,
    ),
    (
        "subtalar_foot_lateral",
        "Ankle (subtalar)",
        "Lateral position",
        "Foot",
        11.17,
        2.83,
        -14.31,
    ),
];

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::{lower_limb, Side};
    use jointfit::model::Model;

    /// The built-in model's nominal values are the paper's anatomical-landmark column, and
    /// Table 2's rows name the model's parameters in the model's order.
    #[test]
    fn table2_matches_the_builtin_model() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        assert_eq!(model.parameters().len(), TABLE2.len());
        for (par, row) in model.parameters().iter().zip(TABLE2) {
            assert_eq!(par.name, row.0);
            let k = crate::units::scale(par.unit);
            assert!((par.nominal * k - row.4).abs() < 0.006, "{}", row.0);
        }
    }

    /// The reductions quoted in the text follow from the table's rows.
    #[test]
    fn reductions_follow_from_table1() {
        for (c, reduction) in TABLE1_REDUCTION_PERCENT.iter().enumerate() {
            let fit = TABLE1[6].values[c].unwrap();
            let lm = TABLE1[7].values[c].unwrap();
            let r = 100.0 * (1.0 - fit / lm);
            assert!((r - reduction).abs() < 1.0, "column {c}: {r}");
        }
    }
}
