//! The population prior of the lower-limb template's parameters: how far the anatomical-landmark
//! (or functional) estimate of each parameter typically is from the truth, across people.
//!
//! A maximum a posteriori fit (`calibrate::prior`) pulls each parameter toward its nominal
//! value with weight `1/sd²`, so these numbers decide how much a trial must show before a
//! joint moves; the plausibility envelopes (`plausibility`) are their 95 % regions. Each entry
//! names its source; where the literature gives a 3-D error or a 95 % radius for an isotropic
//! error, the per-axis SD follows from the χ₃ distribution (mean distance 1.596 σ, 95 % radius
//! 2.796 σ). The hip centre's SD depends on the regression that placed it
//! ([`HipCentreMethod`]). The table with the derivations is in `docs/priors.md`.

use super::spec::ModelSpec;

/// Which regression places the hip centre in the pelvis frame (PW: the inter-ASIS width).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HipCentreMethod {
    /// Bell et al. 1990: (−0.19, −0.30, ±0.36)·PW.
    #[default]
    Bell,
    /// Harrington et al. 2007: pelvic depth and width, with constant terms.
    Harrington,
    /// Davis et al. 1991 as Vicon's Plug-in Gait applies it: leg length, ASIS-to-trochanter
    /// distance, inter-ASIS distance and marker radius; needs the subject's leg length.
    Davis,
}

impl HipCentreMethod {
    pub fn citation(self) -> &'static str {
        match self {
            HipCentreMethod::Bell => "Bell et al. 1990",
            HipCentreMethod::Harrington => "Harrington et al. 2007",
            HipCentreMethod::Davis => "Davis et al. 1991 (Plug-in Gait)",
        }
    }
}

/// One prior: standard deviation (m or rad) and where it comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PriorEntry {
    pub sd: f64,
    pub source: &'static str,
}

const MM: f64 = 1e-3;
const DEG: f64 = std::f64::consts::PI / 180.0;

/// Per-axis SD of a regression hip centre (m).
fn hip_regression_sd(method: HipCentreMethod) -> PriorEntry {
    match method {
        HipCentreMethod::Bell => PriorEntry {
            sd: 12.0 * MM,
            source: "Bell et al. 1989/1990: 95 % of adult hip centres within 26 mm (9.3 mm \
                     per axis), widened for skin-marker ASIS palpation (Della Croce et al. 2005)",
        },
        HipCentreMethod::Davis => PriorEntry {
            sd: 15.0 * MM,
            source: "Davis et al. 1991 regression (Plug-in Gait), judged wider than Bell's: \
                     the least accurate of the regressions Harrington et al. 2007 compared \
                     with MRI, and it adds the errors of the measured leg length and \
                     ASIS-to-trochanter distance",
        },
        HipCentreMethod::Harrington => PriorEntry {
            sd: 10.0 * MM,
            source: "Harrington et al. 2007 regression vs CT, 12.3 ± 5.9 mm 3-D (Mantovani \
                     et al. 2016; 7.7 mm per axis), widened for skin-marker palpation",
        },
    }
}

/// Medio-lateral SD of a regression hip centre in the pelvis frame (m).
///
/// The lateral coordinate is the best-predicted one: pelvic width alone predicts it (Bell et
/// al. 1989: 14 % of the inter-ASIS distance medial to the ASIS; Harrington et al. 2007:
/// pelvic width is its main predictor); regressions refitted on CT of ≈ 158 pelvises predict
/// each coordinate to 3.6–4.8 mm RMS at bone level (a CT regression report, studylib.net
/// doc 10720131; Hara et al. 2016, Sci Rep 6:37707, and Bakke et al. 2023, J Biomech
/// 147:111418, report refitted regressions below 1 cm 3-D on 157–159 CT pelvises). Skin-marker ASIS add the error of the marker midline
/// (≈ 3.5 mm for 5 mm per ASIS) and 0.36 × the width error (≈ 2.5 mm): √(4.7² + 3.5² + 2.5²)
/// ≈ 6.4 mm, rounded up to 7 mm. Anterior and superior keep the larger regression SD, where
/// the skin over the ASIS (9.7 ± 7.0 mm, Mantovani et al. 2016) and pelvic depth add error.
fn hip_lateral_sd() -> PriorEntry {
    PriorEntry {
        sd: 7.0 * MM,
        source: "hip centre medio-lateral position: predicted by pelvic width to 3.6–4.8 mm \
                 RMS per axis at bone level (CT regressions, ≈ 158 pelvises), plus the ASIS markers' \
                 midline and width error ⇒ √(4.7² + 3.5² + 2.5²) ≈ 7 mm",
    }
}

/// The prior SD of a lower-limb template parameter estimated by the landmark method.
pub(crate) fn landmark_prior(name: &str, hip: HipCentreMethod) -> Option<PriorEntry> {
    let e = |sd: f64, source: &'static str| Some(PriorEntry { sd, source });
    match name {
        "hip_pelvis_lateral" => Some(hip_lateral_sd()),
        n if n.starts_with("hip_") => Some(hip_regression_sd(hip)),
        "knee_thigh_frontal"
        | "knee_thigh_transverse"
        | "knee_shank_frontal"
        | "knee_shank_transverse" => e(
            5.0 * DEG,
            "epicondyle palpation ≈ 6 mm per landmark over a ≈ 100 mm knee width \
             (Della Croce et al. 1999) ⇒ ≈ 5°; transepicondylar ≈ optimal flexion axis \
             (Churchill et al. 1998, 2.9° representation error)",
        ),
        "knee_thigh_anterior"
        | "knee_thigh_superior"
        | "knee_shank_anterior"
        | "knee_shank_superior"
        | "knee_shank_lateral" => e(
            8.0 * MM,
            "mid-epicondyle point vs flexion axis: palpation (Della Croce et al. 1999) and \
             axis offset (Churchill et al. 1998, 3.4 mm)",
        ),
        "talocrural_shank_frontal" => e(
            4.0 * DEG,
            "talocrural axis vs tibia 80° ± 4° across 46 specimens (Isman & Inman 1969; \
             Inman 1976)",
        ),
        "talocrural_shank_transverse" => e(
            6.0 * DEG,
            "talocrural axis vs transmalleolar line in the transverse plane (Inman 1976; \
             Lundberg et al. 1989), judged ≈ 6°",
        ),
        "talocrural_shank_anterior" | "talocrural_shank_superior" | "talocrural_shank_lateral" => {
            e(
                6.0 * MM,
                "the axis passes a few mm distal to the malleolar tips (Inman 1976); \
                 malleolus palpation is precise (bony, thin tissue)",
            )
        }
        "subtalar_foot_sagittal" => e(
            9.0 * DEG,
            "subtalar elevation 42° ± 9° (range 20.5–68.5°) in 46 specimens (Isman & Inman \
             1969; Inman 1976)",
        ),
        "subtalar_foot_transverse" | "subtalar_talus_transverse" => e(
            11.0 * DEG,
            "subtalar medial deviation 23° ± 11° (range 4–47°) in 46 specimens (Isman & \
             Inman 1969; Inman 1976)",
        ),
        "subtalar_talus_superior" => e(
            5.0 * MM,
            "distance between the talocrural and subtalar axes (Reinbolt's 12.4 mm; \
             judged ± 5 mm from Isman & Inman 1969)",
        ),
        "subtalar_foot_anterior" | "subtalar_foot_superior" | "subtalar_foot_lateral" => e(
            10.0 * MM,
            "subtalar axis position in the foot follows from the population-mean angles \
             (Inman 1976): judged ± 10 mm",
        ),
        _ => None,
    }
}

/// Writes `prior_sd` into every template parameter that has a landmark prior (leaves
/// parameters that already have one alone). Names are those of a one-sided template
/// ([`lower_limb`](super::lower_limb::lower_limb)).
pub fn fill_landmark_priors(spec: &mut ModelSpec, hip: HipCentreMethod) {
    for p in &mut spec.parameters {
        if p.prior_sd.is_none() {
            p.prior_sd = landmark_prior(&p.name, hip).map(|e| e.sd);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};

    #[test]
    fn every_template_parameter_has_a_prior() {
        let mut spec = lower_limb(Side::Right);
        fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
        for p in &spec.parameters {
            let sd = p
                .prior_sd
                .unwrap_or_else(|| panic!("{} has no prior", p.name));
            // A prior is narrower than the search bounds (else it would add nothing).
            assert!(sd < 0.5 * (p.upper - p.lower), "{}: {sd}", p.name);
        }
    }
}
