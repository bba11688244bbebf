//! `jointfit personalize`'s subject measurements (C3D PROCESSING group, `.vsk`, `--subject
//! NAME=MM`) and its joint centres in the file's own lab frame (`joint_centres_lab_mm`,
//! `--compare-jc`).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use jointfit::model::lower_limb::Side;
use jointfit::spatial::up_axis_rotation;
use jointfit::trial::Trial;
use jointfit_landmarks::bilateral::PersonalizedModel;
use jointfit_landmarks::subject::SubjectMeasurements;
use jointfit_landmarks::subject::MEASUREMENT_NAMES;
use nalgebra::Vector3;
use serde::Serialize;

use crate::common::Up;

/// Said after a missing-measurement error: how to give one.
pub(crate) const HINT: &str = " (give it with --subject NAME=MM, e.g. --subject \
     knee_width_r=105, or --subject FILE.vsk; a Vicon C3D's PROCESSING group is read \
     automatically)";

/// The subject's measurements: the static C3D's PROCESSING group, then each `--subject`
/// (a `.vsk` or NAME=MM pairs) in order, later values overriding earlier ones.
pub(crate) fn measurements(static_trial: &Path, args: &[String]) -> Result<SubjectMeasurements> {
    let mut m = SubjectMeasurements::default();
    let is_c3d = static_trial
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("c3d"));
    if is_c3d {
        let c3d = jointfit_io::c3d::read_c3d(static_trial)?;
        m.update(&jointfit_io::c3d::processing::processing_measurements(
            &c3d.parameters,
        ));
    }
    for arg in args {
        let path = Path::new(arg);
        if !arg.contains('=') {
            if !path.exists() {
                bail!("--subject {arg:?}: no such file, and not NAME=MM pairs");
            }
            m.update(&jointfit_io::vsk::read_vsk(path)?);
            continue;
        }
        for pair in arg.split(',').filter(|p| !p.trim().is_empty()) {
            let (name, value) = pair
                .split_once('=')
                .with_context(|| format!("--subject {pair:?}: expected NAME=MM"))?;
            let name = name.trim();
            let mm: f64 = value.trim().parse().with_context(|| {
                format!("--subject {name}: {:?} is not a number (mm)", value.trim())
            })?;
            m.set(name, mm * 1e-3).map_err(|e| {
                anyhow::anyhow!("--subject: {e} (names: {})", MEASUREMENT_NAMES.join(", "))
            })?;
        }
    }
    Ok(m)
}

/// The key of a joint of one leg: `hip_r`, `knee_l`, …
fn key(joint: &str, side: Side) -> String {
    format!("{joint}_{}", if side == Side::Right { "r" } else { "l" })
}

/// A Y-up trial point back in the file's lab frame (mm).
fn to_lab(p: &Vector3<f64>, up: Up) -> [f64; 3] {
    let lab = up_axis_rotation(up.into()).transpose() * p;
    [lab.x * 1e3, lab.y * 1e3, lab.z * 1e3]
}

/// Hip, knee and ankle centres of every leg in the lab frame of the file (mm), averaged over
/// the static window.
pub(crate) fn centres_lab(model: &PersonalizedModel, up: Up) -> BTreeMap<String, [f64; 3]> {
    let mut out = BTreeMap::new();
    for (side, r) in model.legs() {
        let rep = &r.report;
        for (joint, p) in [
            ("hip", rep.hip_centre),
            ("knee", rep.knee_centre),
            ("ankle", rep.ankle_centre),
        ] {
            out.insert(key(joint, side), to_lab(&p, up));
        }
    }
    out
}

/// A stored joint centre against ours.
#[derive(Serialize)]
pub(crate) struct JcComparison {
    /// `hip_r`, `knee_l`, …
    pub(crate) joint: String,
    pub(crate) marker: String,
    pub(crate) distance_mm: f64,
    /// The stored point minus ours, in the file's lab frame (mm).
    pub(crate) delta_lab_mm: [f64; 3],
}

/// The right leg's label for the left: the leading R/r swapped for L/l.
fn mirror(label: &str) -> String {
    let mut c = label.chars();
    match c.next() {
        Some('R') => format!("L{}", c.as_str()),
        Some('r') => format!("l{}", c.as_str()),
        _ => label.to_string(),
    }
}

/// `--compare-jc hip=RFEP,knee=RFEO,ankle=RTIO`: per leg and joint, the stored point averaged
/// over the leg's static window against our centre.
pub(crate) fn compare_jc(
    model: &PersonalizedModel,
    trial: &Trial,
    up: Up,
    spec: &str,
) -> Result<Vec<JcComparison>> {
    let mut out = Vec::new();
    for pair in spec.split(',').filter(|p| !p.trim().is_empty()) {
        let (joint, label) = pair
            .split_once('=')
            .with_context(|| format!("{pair:?}: expected JOINT=LABEL"))?;
        let joint = joint.trim();
        if !["hip", "knee", "ankle"].contains(&joint) {
            bail!("{pair:?}: the joint must be hip, knee or ankle");
        }
        for (side, r) in model.legs() {
            let label = match side {
                Side::Right => label.trim().to_string(),
                Side::Left => mirror(label.trim()),
            };
            let c = trial.index_of(&label)?;
            let w = &r.report.window;
            let pts: Vec<_> = (w.first..w.end()).filter_map(|f| trial.get(f, c)).collect();
            if pts.is_empty() {
                bail!("marker {label:?} is missing throughout the static window");
            }
            let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
            let ours = match joint {
                "hip" => r.report.hip_centre,
                "knee" => r.report.knee_centre,
                _ => r.report.ankle_centre,
            };
            let d = mean - ours;
            out.push(JcComparison {
                joint: key(joint, side),
                marker: label,
                distance_mm: d.norm() * 1e3,
                delta_lab_mm: to_lab(&d, up),
            });
        }
    }
    Ok(out)
}

/// Text lines of the comparisons.
pub(crate) fn render(rows: &[JcComparison]) -> String {
    rows.iter()
        .map(|c| {
            format!(
                "{} {}: {:.1} mm from ours (lab {:+.1}, {:+.1}, {:+.1} mm)\n",
                c.joint,
                c.marker,
                c.distance_mm,
                c.delta_lab_mm[0],
                c.delta_lab_mm[1],
                c.delta_lab_mm[2]
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirrored_labels() {
        assert_eq!(mirror("RFEP"), "LFEP");
        assert_eq!(mirror("r_knee_study"), "l_knee_study");
        assert_eq!(mirror("HJC"), "HJC");
    }
}
