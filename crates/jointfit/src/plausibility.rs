//! Anatomical plausibility of fitted joint parameters of the lower-limb template.
//!
//! After a fit, each joint is compared with an envelope around where the landmark (or
//! functional) method puts it. The envelopes are the 95 % regions of the priors
//! (`model::population`, `docs/priors.md`), so a violation says "the fit moved this joint
//! further than the method that placed it is ever this wrong in 95 % of people":
//!
//! * **hip centre lateral offset** `≤ 0.9 × PW/2` (PW: inter-ASIS distance, read off the
//!   model's ASIS markers, which sit at `(0, 0, ±PW/2)` in the pelvis frame of a personalized
//!   model): the hip centre lies medial to the ASIS (Bell et al. 1990 put it at 0.36·PW from
//!   the midline; Harrington et al. 2007 at 0.33·PW + 7 mm);
//! * **hip centre distance** from the prior mean in the pelvis `≤ 2.80 σ` (the 95 % radius
//!   of an isotropic 3-D normal with the prior's per-axis σ; 34 mm for Bell's 12 mm);
//! * **axis angles** (knee axis in thigh and in shank, talocrural axis in shank, subtalar
//!   axis in foot) from the prior mean's direction `≤ 2.45 σ` (the 95 % radius of a 2-D
//!   normal of the two orientation angles; 12° for the epicondylar axis' 5°).
//!
//! Without priors in the model the envelopes use the landmark table's SDs.

use nalgebra::Vector3;

use crate::model::population::{landmark_prior, HipCentreMethod, PriorEntry};
use crate::model::refine::marker_home;
use crate::model::Model;

/// One fitted joint measure against its anatomical envelope.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Plausibility {
    /// What is checked, e.g. `hip centre lateral offset`.
    pub check: String,
    /// The parameters involved.
    pub parameters: Vec<String>,
    /// Measured value and the limit, in `unit` (`mm` or `deg`).
    pub value: f64,
    pub limit: f64,
    pub unit: &'static str,
    /// False when outside the envelope.
    pub ok: bool,
}

impl Plausibility {
    #[cfg(test)]
    /// How far outside the envelope (0 when inside).
    pub(crate) fn excess(&self) -> f64 {
        (self.value - self.limit).max(0.0)
    }
}

/// 95 % radius of an isotropic 3-D normal, in σ (√χ²₃(0.95)).
pub(crate) const RADIUS_95_3D: f64 = 2.795;
/// 95 % radius of an isotropic 2-D normal, in σ (√χ²₂(0.95)).
pub(crate) const RADIUS_95_2D: f64 = 2.448;
/// Largest accepted hip-centre lateral offset as a fraction of half the inter-ASIS width.
pub(crate) const HIP_LATERAL_FRACTION: f64 = 0.9;

fn sd_of(model: &Model, i: usize) -> f64 {
    let p = &model.parameters()[i];
    // A bilateral model's names carry the leg's suffix; the published accuracies do not.
    let base = ["_r", "_l"]
        .iter()
        .find_map(|s| p.name.strip_suffix(s))
        .unwrap_or(&p.name);
    p.prior_sd.unwrap_or_else(|| {
        landmark_prior(&p.name, HipCentreMethod::Bell)
            .or_else(|| landmark_prior(base, HipCentreMethod::Bell))
            .map_or(f64::NAN, |e: PriorEntry| e.sd)
    })
}

/// Half the inter-ASIS distance (m) from the pelvis markers on the pelvis z axis, if any
/// (at their static-trial positions when the markers are refined, [`marker_home`]).
pub(crate) fn half_pelvis_width(model: &Model) -> Option<f64> {
    let pelvis = model.segments().iter().position(|s| s.name == "pelvis")?;
    let zs: Vec<f64> = (0..model.markers().len())
        .map(|j| marker_home(model, j))
        .filter(|(seg, x)| seg.0 == pelvis && x.x.abs() < 1e-6 && x.y.abs() < 1e-6)
        .map(|(_, x)| x.z.abs())
        .collect();
    (zs.len() == 2).then(|| 0.5 * (zs[0] + zs[1]))
}

/// Unit axis of a pin about z tilted by (rx, ry): `(sin ry, −sin rx cos ry, cos rx cos ry)`.
fn pin_axis(rx: f64, ry: f64) -> Vector3<f64> {
    Vector3::new(ry.sin(), -rx.sin() * ry.cos(), rx.cos() * ry.cos())
}

/// Runs every check that the model's parameters allow on the parameter vector `p`: for a
/// one-sided model on its parameters, for the bilateral model on each leg's (names suffixed
/// `_r` and `_l`; the check says which leg).
pub fn assess(model: &Model, p: &[f64]) -> Vec<Plausibility> {
    let mut out = Vec::new();
    for (suffix, leg) in [("", ""), ("_r", " (right)"), ("_l", " (left)")] {
        out.extend(assess_leg(model, p, suffix, leg));
    }
    out
}

/// The checks of one leg: parameter names end in `suffix`, check names in `leg`.
fn assess_leg(model: &Model, p: &[f64], suffix: &str, leg: &str) -> Vec<Plausibility> {
    let id = |n: &str| model.param_id(&format!("{n}{suffix}")).map(|x| x.0);
    let mean = |i: usize| model.parameters()[i].prior_mean;
    let mut out = Vec::new();
    let hip: Option<Vec<usize>> = [
        "hip_pelvis_anterior",
        "hip_pelvis_superior",
        "hip_pelvis_lateral",
    ]
    .iter()
    .map(|n| id(n))
    .collect();
    if let Some(h) = hip {
        let names: Vec<String> = h
            .iter()
            .map(|&i| model.parameters()[i].name.clone())
            .collect();
        if let Some(half) = half_pelvis_width(model) {
            let limit = HIP_LATERAL_FRACTION * half;
            out.push(Plausibility {
                check: format!(
                    "hip centre lateral offset (≤ 0.9 × half the inter-ASIS width){leg}"
                ),
                parameters: vec![names[2].clone()],
                value: p[h[2]] * 1e3,
                limit: limit * 1e3,
                unit: "mm",
                ok: p[h[2]] <= limit,
            });
        }
        let d = h
            .iter()
            .map(|&i| (p[i] - mean(i)).powi(2))
            .sum::<f64>()
            .sqrt();
        let sd = h.iter().map(|&i| sd_of(model, i)).fold(0.0, f64::max);
        let limit = RADIUS_95_3D * sd;
        out.push(Plausibility {
            check: format!("hip centre distance from the landmark/functional estimate{leg}"),
            parameters: names,
            value: d * 1e3,
            limit: limit * 1e3,
            unit: "mm",
            ok: d <= limit,
        });
    }
    let axes: [(&str, &str, &str); 4] = [
        (
            "knee axis in thigh",
            "knee_thigh_frontal",
            "knee_thigh_transverse",
        ),
        (
            "knee axis in shank",
            "knee_shank_frontal",
            "knee_shank_transverse",
        ),
        (
            "talocrural axis in shank",
            "talocrural_shank_frontal",
            "talocrural_shank_transverse",
        ),
        (
            "subtalar axis in foot",
            "subtalar_foot_sagittal",
            "subtalar_foot_transverse",
        ),
    ];
    for (what, a, b) in axes {
        let (Some(ia), Some(ib)) = (id(a), id(b)) else {
            continue;
        };
        // The subtalar foot axis is x turned by (ry = transverse, rz = sagittal); the others
        // are z turned by (rx = frontal, ry = transverse).
        let dir = |va: f64, vb: f64| {
            if a == "subtalar_foot_sagittal" {
                Vector3::new(vb.cos() * va.cos(), va.sin(), -vb.sin() * va.cos())
            } else {
                pin_axis(va, vb)
            }
        };
        let angle = dir(p[ia], p[ib]).angle(&dir(mean(ia), mean(ib)));
        let sd = sd_of(model, ia).max(sd_of(model, ib));
        let limit = RADIUS_95_2D * sd;
        out.push(Plausibility {
            check: format!("{what}{leg}: angle from the landmark/functional axis"),
            parameters: vec![format!("{a}{suffix}"), format!("{b}{suffix}")],
            value: angle.to_degrees(),
            limit: limit.to_degrees(),
            unit: "deg",
            ok: angle <= limit,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::model::population::fill_landmark_priors;

    fn model() -> Model {
        // The template's ASIS markers sit at (0, 0, ±120 mm): PW/2 = 120 mm.
        let mut spec = lower_limb(Side::Left);
        fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
        Model::compile(&spec).unwrap()
    }

    #[test]
    fn nominal_passes_and_moves_are_measured() {
        let m = model();
        let p0 = m.nominal_params();
        let checks = assess(&m, &p0);
        assert_eq!(checks.len(), 6);
        for c in &checks {
            assert!(c.ok, "{c:?}");
        }
        // Hip lateral to 120 mm (> 0.9 × 120 mm), 34 mm from the mean (> 2.8 × 12 mm).
        let mut p = p0.clone();
        let lat = m.param_id("hip_pelvis_lateral").unwrap().0;
        p[lat] = 0.120;
        let shift = 0.120 - p0[lat];
        let c = assess(&m, &p);
        assert!(
            !c[0].ok && (c[0].excess() - 12.0).abs() < 1e-6,
            "{:?}",
            c[0]
        );
        assert!((c[1].value - shift * 1e3).abs() < 1e-6);
        assert!(!c[1].ok, "33.7 mm > 2.8 × 12 mm: {:?}", c[1]);
        // Knee axis turned 15° in the frontal plane of the thigh: 15° > 12.2°.
        let mut p = p0.clone();
        let f = m.param_id("knee_thigh_frontal").unwrap().0;
        p[f] += 15f64.to_radians();
        let c = assess(&m, &p);
        let knee = c
            .iter()
            .find(|c| c.check.starts_with("knee axis in thigh"))
            .unwrap();
        assert!(!knee.ok && (knee.value - 15.0).abs() < 1e-6, "{knee:?}");
    }

    #[test]
    fn bilateral_model_is_checked_per_leg() {
        let spec = crate::model::lower_limb::builtin("lower-limb").unwrap();
        let m = Model::compile(&spec).unwrap();
        let one = assess(&model(), &model().nominal_params()).len();
        let both = assess(&m, &m.nominal_params());
        // Every one-sided check, once per leg, each naming its leg and suffixed parameters.
        assert_eq!(both.len(), 2 * one, "{both:?}");
        assert!(both.iter().all(|c| c.ok));
        for (leg, suffix) in [("(right)", "_r"), ("(left)", "_l")] {
            let mine: Vec<&Plausibility> = both.iter().filter(|c| c.check.contains(leg)).collect();
            assert_eq!(mine.len(), one);
            assert!(mine
                .iter()
                .all(|c| c.parameters.iter().all(|n| n.ends_with(suffix))));
        }
        // Moving one leg's knee axis fails that leg's check only.
        let f = m.param_id("knee_thigh_frontal_l").unwrap().0;
        let mut p = m.nominal_params();
        p[f] += 0.5;
        let failed: Vec<String> = assess(&m, &p)
            .into_iter()
            .filter(|c| !c.ok)
            .map(|c| c.check)
            .collect();
        assert_eq!(failed.len(), 1, "{failed:?}");
        assert!(
            failed[0].contains("knee axis in thigh (left)"),
            "{failed:?}"
        );
    }
}

/// One body measurement of a subject model against the range people have.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Measure {
    /// What is measured, e.g. `thigh length (right)`.
    pub what: String,
    /// The model's value (mm, or a plain ratio when `unit` is empty).
    pub value: f64,
    /// The plausible range, same unit.
    pub range: [f64; 2],
    pub unit: &'static str,
}

impl Measure {
    /// Whether the value lies inside the plausible range.
    pub fn ok(&self) -> bool {
        (self.range[0]..=self.range[1]).contains(&self.value)
    }
}

/// Thigh length range (mm): hip centre to knee axis. Winter (2009, Biomechanics and Motor
/// Control of Human Movement, 4th ed., Table 4.1) gives 0.245 × stature, 343–515 mm for
/// statures 1.40–2.10 m; widened by 10 % for where the landmark method puts the centres.
pub(crate) const THIGH_MM: [f64; 2] = [300.0, 570.0];
/// Shank length range (mm): knee axis to talocrural axis, 0.246 × stature (same source).
pub(crate) const SHANK_MM: [f64; 2] = [300.0, 570.0];
/// Inter-ASIS width range (mm): 190–300 mm in adults (Bell et al. 1990, J Biomech
/// 23:617–621: 20 adults 205–288 mm), widened for marker radius and obesity.
pub(crate) const PELVIS_MM: [f64; 2] = [150.0, 380.0];
/// Thigh-to-shank length ratio range: 1.0 ± 0.1 in Winter's proportions, widened for where
/// the landmark method puts the centres.
pub(crate) const THIGH_SHANK_RATIO: [f64; 2] = [0.7, 1.45];

/// The subject model's thigh and shank lengths, their ratio and the pelvis width at
/// parameters `p`, for every leg of the lower-limb template the model has (parameter names
/// of [`crate::model::lower_limb`]); empty for other models.
pub fn anthropometry(model: &Model, p: &[f64]) -> Vec<Measure> {
    let mut out = Vec::new();
    if let Some(half) = half_pelvis_width(model) {
        out.push(Measure {
            what: "inter-ASIS width".into(),
            value: 2.0 * half * 1e3,
            range: PELVIS_MM,
            unit: "mm",
        });
    }
    for (suffix, leg) in [("", ""), ("_r", " (right)"), ("_l", " (left)")] {
        let point = |names: [&str; 3]| -> Option<Vector3<f64>> {
            let ids: Vec<Option<usize>> = names
                .iter()
                .map(|n| model.param_id(&format!("{n}{suffix}")).map(|x| x.0))
                .collect();
            ids.iter()
                .any(Option::is_some)
                .then(|| Vector3::from_iterator(ids.iter().map(|i| i.map_or(0.0, |i| p[i]))))
        };
        let hip = point([
            "hip_thigh_anterior",
            "hip_thigh_superior",
            "hip_thigh_lateral",
        ]);
        let knee_thigh = point([
            "knee_thigh_anterior",
            "knee_thigh_superior",
            "knee_thigh_lateral",
        ]);
        let knee_shank = point([
            "knee_shank_anterior",
            "knee_shank_superior",
            "knee_shank_lateral",
        ]);
        let ankle = point([
            "talocrural_shank_anterior",
            "talocrural_shank_superior",
            "talocrural_shank_lateral",
        ]);
        let (Some(h), Some(kt), Some(ks), Some(a)) = (hip, knee_thigh, knee_shank, ankle) else {
            continue;
        };
        let (thigh, shank) = ((kt - h).norm() * 1e3, (a - ks).norm() * 1e3);
        out.push(Measure {
            what: format!("thigh length{leg}"),
            value: thigh,
            range: THIGH_MM,
            unit: "mm",
        });
        out.push(Measure {
            what: format!("shank length{leg}"),
            value: shank,
            range: SHANK_MM,
            unit: "mm",
        });
        out.push(Measure {
            what: format!("thigh-to-shank length ratio{leg}"),
            value: thigh / shank,
            range: THIGH_SHANK_RATIO,
            unit: "",
        });
    }
    out
}
