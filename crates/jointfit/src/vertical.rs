//! The laboratory's vertical from the marker layout ([`detect_up`]).
//!
//! Gravity is not recorded by a motion-capture system, but the body shows it: whatever the
//! lab's axes, head and shoulder markers sit above the pelvis, the pelvis above the knees and
//! the knees above the feet. Each marker whose label names a landmark with a known height is
//! given that height as a fraction of stature (`h`, Winter 2009, *Biomechanics and Motor
//! Control of Human Movement*, 4th ed., Fig. 4.1 segment proportions: head top 1.0, C7/shoulder
//! 0.82, sternum 0.72, anterior iliac spine 0.55, knee 0.285, ankle 0.04, foot 0.02). With
//! `p_i` the median position of marker `i` over the frames in which it is present, the
//! direction of increasing height is the least-squares slope of position on height,
//!
//! `d = Σ_i (h_i − h̄)(p_i − p̄)`,  normalised,
//!
//! and the lab's up axis is the signed coordinate axis nearest `d`. The answer is trusted only
//! when at least two height levels and three markers take part and `d` lies within 35° of that
//! axis (`|d_k| ≥ cos 35°`); otherwise [`detect_up`] returns `None` and callers keep their
//! default. Labels are matched after dropping a `Subject:` prefix, digits and a left/right
//! letter at either end (`RASI`, `L_IAS`, `Daphnee:ASISr`, `r.ASIS`, `A22:RKNE`); model
//! outputs stored as points (`LKneeAngles`, `RHipMoment`, ...) are ignored.

use nalgebra::Vector3;

use crate::spatial::UpAxis;
use crate::trial::Trial;

/// `d` must lie within this angle of a coordinate axis (rad) for the answer to be trusted.
pub(crate) const MAX_TILT: f64 = 35.0 * std::f64::consts::PI / 180.0;

/// Short codes matched exactly (after the normalisation of the module docs) and the height
/// they stand for (fraction of stature).
const EXACT: &[(&str, f64)] = &[
    ("fhd", 0.97),
    ("bhd", 0.97),
    ("hdf", 0.97),
    ("hdb", 0.97),
    ("c7", 0.82),
    ("cv", 0.82),
    ("sho", 0.82),
    ("saj", 0.82),
    ("acr", 0.82),
    ("clav", 0.8),
    ("ij", 0.8),
    ("snj", 0.8),
    ("strn", 0.72),
    ("ster", 0.72),
    ("sxs", 0.7),
    ("px", 0.7),
    ("xiph", 0.7),
    ("tv", 0.72),
    ("asi", 0.55),
    ("psi", 0.55),
    ("ias", 0.55),
    ("ips", 0.55),
    ("sacr", 0.55),
    ("vsac", 0.55),
    ("hjc", 0.5),
    ("gtr", 0.5),
    ("ftc", 0.5),
    ("kne", 0.285),
    ("mkn", 0.285),
    ("lfc", 0.285),
    ("mfc", 0.285),
    ("fle", 0.285),
    ("fme", 0.285),
    ("kjc", 0.285),
    ("ank", 0.04),
    ("man", 0.04),
    ("mal", 0.04),
    ("mmal", 0.04),
    ("lmal", 0.04),
    ("fal", 0.04),
    ("tam", 0.04),
    ("ajc", 0.04),
    ("hee", 0.02),
    ("cal", 0.02),
    ("fcc", 0.02),
    ("mt", 0.02),
    ("fm", 0.02),
    ("nav", 0.02),
    ("toe", 0.02),
];

/// Longer words matched anywhere in a label token.
const CONTAINS: &[(&str, f64)] = &[
    ("head", 0.97),
    ("shoulder", 0.82),
    ("acrom", 0.82),
    ("clavic", 0.8),
    ("sternum", 0.72),
    ("asis", 0.55),
    ("psis", 0.55),
    ("sacral", 0.55),
    ("sacrum", 0.55),
    ("knee", 0.285),
    ("epicond", 0.285),
    ("ankle", 0.04),
    ("malleol", 0.04),
    ("heel", 0.02),
    ("calc", 0.02),
    ("meta", 0.02),
    ("toe", 0.02),
];

/// The height (fraction of stature) a marker label stands for, if it names a known landmark.
pub(crate) fn label_height(label: &str) -> Option<f64> {
    let label = label
        .rsplit(':')
        .next()
        .unwrap_or(label)
        .to_ascii_lowercase();
    // Model outputs stored as points (Plug-in Gait's LKneeAngles, RHipMoment, ...).
    if ["angle", "moment", "power", "force"]
        .iter()
        .any(|w| label.contains(w))
    {
        return None;
    }
    // Thoracic vertebrae: T1–T12 (not a bare "t").
    for token in label.split(|c: char| !c.is_ascii_alphanumeric()) {
        if token.len() >= 2
            && token.starts_with('t')
            && token[1..].chars().all(|c| c.is_ascii_digit())
        {
            return Some(0.72);
        }
        let letters: String = token.chars().filter(|c| c.is_ascii_alphabetic()).collect();
        if letters.is_empty() {
            continue;
        }
        let mut candidates = vec![token, letters.as_str()];
        for (prefix, suffix) in [("r", ""), ("l", ""), ("", "r"), ("", "l")] {
            let s = letters.strip_prefix(prefix).unwrap_or("");
            let s = if suffix.is_empty() {
                s
            } else {
                letters.strip_suffix(suffix).unwrap_or("")
            };
            if !s.is_empty() {
                candidates.push(s);
            }
        }
        for c in &candidates {
            if let Some((_, h)) = EXACT.iter().find(|(k, _)| k == c) {
                return Some(*h);
            }
        }
        if let Some((_, h)) = CONTAINS.iter().find(|(k, _)| letters.contains(k)) {
            return Some(*h);
        }
    }
    None
}

/// What [`detect_up`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct UpDetection {
    /// The lab's axis nearest to the head-above-feet direction.
    pub up: UpAxis,
    /// That direction (unit, lab frame).
    pub direction: Vector3<f64>,
    /// Angle between the direction and the axis (rad).
    pub tilt: f64,
    /// How many markers took part.
    pub markers: usize,
}

/// One phrase for messages: `z (from 12 labelled markers, 4° off the axis)`.
impl std::fmt::Display for UpDetection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} (from {} labelled markers, {:.0}° off the axis)",
            self.up,
            self.markers,
            self.tilt.to_degrees()
        )
    }
}

/// The lab's vertical from the marker layout of `trial` (module docs); `None` when the labels
/// name too few landmarks of known height or the direction is not near a coordinate axis.
pub fn detect_up(trial: &Trial) -> Option<UpDetection> {
    let n = trial.n_frames();
    let step = n.div_ceil(200).max(1);
    let mut points: Vec<(f64, Vector3<f64>)> = Vec::new();
    for (j, label) in trial.labels().iter().enumerate() {
        let Some(h) = label_height(label) else {
            continue;
        };
        let present: Vec<Vector3<f64>> = (0..n)
            .step_by(step)
            .filter_map(|f| trial.get(f, j))
            .collect();
        if present.is_empty() {
            continue;
        }
        let median = |k: usize| {
            let mut v: Vec<f64> = present.iter().map(|p| p[k]).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        points.push((h, Vector3::new(median(0), median(1), median(2))));
    }
    let levels = {
        let mut hs: Vec<f64> = points.iter().map(|(h, _)| *h).collect();
        hs.sort_by(f64::total_cmp);
        hs.dedup();
        hs.len()
    };
    if points.len() < 3 || levels < 2 {
        return None;
    }
    let count = points.len() as f64;
    let h_mean = points.iter().map(|(h, _)| h).sum::<f64>() / count;
    let p_mean = points.iter().map(|(_, p)| p).sum::<Vector3<f64>>() / count;
    let d: Vector3<f64> = points
        .iter()
        .map(|(h, p)| (h - h_mean) * (p - p_mean))
        .sum();
    let norm = d.norm();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    let d = d / norm;
    let up = UpAxis::ALL
        .into_iter()
        .max_by(|a, b| a.direction().dot(&d).total_cmp(&b.direction().dot(&d)))
        .expect("six axes");
    let tilt = up.direction().dot(&d).clamp(-1.0, 1.0).acos();
    (tilt <= MAX_TILT).then_some(UpDetection {
        up,
        direction: d,
        tilt,
        markers: points.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::up_axis_rotation;

    #[test]
    fn labels_of_several_labs() {
        for (label, h) in [
            ("RASI", 0.55),
            ("L_IAS", 0.55),
            ("Daphnee:ASISr", 0.55),
            ("r.ASIS", 0.55),
            ("A22:RKNE", 0.285),
            ("r_mknee", 0.285),
            ("LFHD", 0.97),
            ("C7", 0.82),
            ("T10", 0.72),
            ("r_calc", 0.02),
            ("r_5meta", 0.02),
            ("RTOE5", 0.02),
            ("L.Heel", 0.02),
            ("V.Sacral", 0.55),
            ("RMMAL", 0.04),
            ("R.Ankle.Lat", 0.04),
        ] {
            assert_eq!(label_height(label), Some(h), "{label}");
        }
        for label in [
            "r_thigh1",
            "RTHI",
            "boite:gauche_ext",
            "R_WAND1",
            "RTH1",
            "A22:LKneeAngles",
        ] {
            assert_eq!(label_height(label), None, "{label}");
        }
    }

    /// A standing figure in the model frame, rotated into each lab frame, gives that lab's
    /// axis back; a figure with no known labels gives nothing.
    #[test]
    fn every_axis_is_found() {
        let labels = ["RFHD", "C7", "RASI", "LASI", "RKNE", "RANK", "RHEE", "RTOE"];
        let heights = [1.7, 1.45, 0.95, 0.96, 0.5, 0.08, 0.04, 0.03];
        let model: Vec<Vector3<f64>> = heights
            .iter()
            .enumerate()
            .map(|(i, &y)| Vector3::new(0.05 * i as f64 - 0.1, y, 0.03 * (i % 3) as f64))
            .collect();
        for up in UpAxis::ALL {
            let lab_from_model = up_axis_rotation(up).transpose();
            let positions: Vec<Vector3<f64>> = model.iter().map(|p| lab_from_model * p).collect();
            let trial = Trial::new(
                labels.iter().map(|s| s.to_string()).collect(),
                100.0,
                1,
                positions,
            )
            .unwrap();
            let d = detect_up(&trial).expect("detected");
            assert_eq!(d.up, up);
            assert!(d.tilt < 0.2, "{d}");
        }
        let anonymous = Trial::new(
            (0..8).map(|i| format!("M{i}")).collect(),
            100.0,
            1,
            model.clone(),
        )
        .unwrap();
        assert!(detect_up(&anonymous).is_none());
    }
}
