//! Identifiability explained: ranges of motion, the reason a parameter is poorly
//! determined, and weak directions named after the parameters they combine.

use super::super::Problem;
use super::estimators::{conservative, Covariances};
use super::{
    display, CoordRange, DirectionComponent, UncertaintyOptions, WeakDirection, NULL_RATIO,
};
use crate::model::spec::Unit;
use crate::model::{CoordKind, Model};

/// Ranges of motion of every coordinate over the frames `qs` (display units).
pub(crate) fn coordinate_ranges(model: &Model, qs: &[Vec<f64>]) -> Vec<CoordRange> {
    model
        .coordinates()
        .iter()
        .enumerate()
        .map(|(c, coord)| {
            let (k, unit) = match coord.kind {
                CoordKind::Rotational => (180.0 / std::f64::consts::PI, "deg"),
                CoordKind::Translational => (1e3, "mm"),
            };
            let vals = qs.iter().map(|q| q[c]).filter(|v| v.is_finite());
            let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
            CoordRange {
                name: coord.name.clone(),
                joint: model.joints()[coord.joint].name.clone(),
                unit: unit.to_string(),
                min: lo * k,
                max: hi * k,
                range: (hi - lo) * k,
            }
        })
        .collect()
}

/// Rotations below this range (deg) are "barely moved" in reasons.
pub(super) const SMALL_RANGE_DEG: f64 = 15.0;

/// The trial that exercises a coordinate, for the reason text.
pub(super) fn suggestion(coord: &str) -> String {
    let c = coord.to_ascii_lowercase();
    if c.contains("hip") && (c.contains("adduction") || c.contains("abduction")) {
        "a hip circumduction trial (flexion-extension combined with ab-adduction) would determine it".into()
    } else if c.contains("hip") && c.contains("rotation") {
        "a trial with hip internal-external rotation would determine it".into()
    } else if c.contains("hip") {
        "a hip flexion-extension or circumduction trial would determine it".into()
    } else if c.contains("knee") {
        "a knee flexion-extension trial through at least 60° would determine it".into()
    } else if c.contains("ankle")
        || c.contains("talocrural")
        || c.contains("subtalar")
        || c.contains("inversion")
    {
        "an ankle toe-tip circumduction trial (plantar/dorsiflexion with inversion/eversion) would determine it".into()
    } else {
        format!("a trial moving {coord} through a larger range would determine it")
    }
}

/// Residual SD (mm) above which a wide interval is blamed on the residuals: optical
/// marker measurement alone leaves well under 1 mm (Chiari et al. 2005, Gait Posture
/// 21:197–211); more is soft-tissue artefact, misplacement or model error.
const NOISY_SIGMA_MM: f64 = 1.0;

/// Reason text for flagged free parameter `k` (model index `i`); `sigma_mm` is the marker
/// residual SD.
pub(super) fn reason(
    model: &Model,
    i: usize,
    at_bound: bool,
    ranges: &[CoordRange],
    partner: Option<(&str, f64)>,
    sigma_mm: f64,
) -> String {
    let par = &model.parameters()[i];
    let mut parts = Vec::new();
    let joint = par.uses.first().map(|u| u.joint);
    if let Some(j) = joint {
        let jname = &model.joints()[j].name;
        let coords: Vec<&CoordRange> = ranges
            .iter()
            .zip(model.coordinates())
            .filter(|(_, c)| c.joint == j && c.kind == CoordKind::Rotational)
            .map(|(r, _)| r)
            .collect();
        // The barely moved axis to name: the smallest range, but an axial rotation only when
        // no other axis is also barely moved (circumduction excites a joint centre best).
        let small: Vec<&&CoordRange> = coords
            .iter()
            .filter(|r| r.range < SMALL_RANGE_DEG)
            .collect();
        let not_axial: Vec<&&CoordRange> = small
            .iter()
            .copied()
            .filter(|r| !r.name.contains("rotation"))
            .collect();
        let pool = if not_axial.is_empty() {
            small
        } else {
            not_axial
        };
        if let Some(small) = pool.iter().min_by(|a, b| a.range.total_cmp(&b.range)) {
            let moved: Vec<String> = coords
                .iter()
                .map(|r| format!("{} {:.0}°", r.name, r.range))
                .collect();
            parts.push(format!(
                "{jname} range of motion: {} ({} only {:.0}°); {}",
                moved.join(", "),
                small.name,
                small.range,
                suggestion(&small.name)
            ));
        } else if !coords.is_empty() {
            let moved: Vec<String> = coords
                .iter()
                .map(|r| format!("{} {:.0}°", r.name, r.range))
                .collect();
            // Say which of the two causes of a wide interval applies: residuals above what
            // optical measurement alone leaves (≈ 1 mm), or a motion that shows the
            // parameter only in combination with others (true also on noiseless data).
            let why = if sigma_mm > NOISY_SIGMA_MM {
                format!(
                    "the marker residuals (σ = {sigma_mm:.1} mm) are large for what this \
                     trial shows of it"
                )
            } else {
                "this motion shows it only together with other parameters (see the weak \
                 combinations)"
                    .to_string()
            };
            parts.push(format!(
                "{jname} moved enough ({}), but {why}; a longer trial or more trials of this \
                 joint would help",
                moved.join(", ")
            ));
        }
    }
    if let Some((name, r)) = partner {
        parts.push(format!(
            "traded off against {name} (correlation {r:+.2}); fixing one would determine the other"
        ));
    }
    if at_bound {
        parts.push("the fit stopped at its bound, so the interval is only indicative".into());
    }
    parts.join("; ")
}

/// The weakest eigen-directions of `S` (at most 5) with some component over its threshold.
pub(super) fn weak_directions(
    prob: &Problem,
    cov: &Covariances,
    scale: &[f64],
    crit: (f64, f64),
    opts: &UncertaintyOptions,
) -> Vec<WeakDirection> {
    let model = prob.model;
    let nf = prob.n_free();
    let max = cov
        .eig
        .eigenvalues
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let mut order: Vec<usize> = (0..nf).collect();
    order.sort_by(|&a, &b| cov.eig.eigenvalues[a].total_cmp(&cov.eig.eigenvalues[b]));
    let mut out = Vec::new();
    for j in order {
        let lam = cov.eig.eigenvalues[j];
        let v = cov.eig.eigenvectors.column(j).into_owned();
        let null = !(lam > NULL_RATIO * max && lam > 0.0);
        // Half-width along the direction: the most conservative estimator.
        let hw = if null {
            f64::INFINITY
        } else {
            conservative(cov, crit, |c| (v.transpose() * c * &v)[(0, 0)])
                .1
                .map_or(f64::INFINITY, |b| b.1)
        };
        let mut comps: Vec<usize> = (0..nf).filter(|&k| v[k] * v[k] >= 0.1).collect();
        comps.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
        let over = (0..nf).any(|k| {
            let par = &model.parameters()[prob.free[k]];
            let t = par.unit.to_display(opts.threshold(par.unit));
            hw * v[k].abs() * scale[k] > t
        });
        if !over {
            continue;
        }
        let components: Vec<DirectionComponent> = comps
            .iter()
            .map(|&k| {
                let par = &model.parameters()[prob.free[k]];
                DirectionComponent {
                    name: par.name.clone(),
                    coefficient: v[k],
                    half_width: hw.is_finite().then(|| hw * v[k].abs() * scale[k]),
                    unit: display(par.unit).1.to_string(),
                }
            })
            .collect();
        let description = direction_words(prob, &v, &comps, hw, scale, null);
        out.push(WeakDirection {
            eigenvalue: lam,
            components,
            description,
        });
        if out.len() == 5 {
            break;
        }
    }
    out
}

/// A weak direction `v` in words: its components `comps` (largest first) with their signs
/// and half-widths (`hw` along the direction, `scale` per parameter), not determined at all
/// (`null`) or poorly.
fn direction_words(
    prob: &Problem,
    v: &nalgebra::DVector<f64>,
    comps: &[usize],
    hw: f64,
    scale: &[f64],
    null: bool,
) -> String {
    let model = prob.model;
    let words: Vec<String> = comps
        .iter()
        .map(|&k| {
            let par = &model.parameters()[prob.free[k]];
            let sign = if v[k] * v[comps[0]] >= 0.0 {
                "+"
            } else {
                "−"
            };
            let d = if par.description.is_empty() {
                &par.name
            } else {
                &par.description
            };
            let hw_k = if hw.is_finite() {
                format!("±{:.1} {}", hw * v[k].abs() * scale[k], display(par.unit).1)
            } else {
                "unbounded".to_string()
            };
            format!("{sign}[{d}] {hw_k}")
        })
        .collect();
    let lead = if null {
        "not determined at all"
    } else {
        "poorly determined"
    };
    let ids: Vec<usize> = comps.iter().map(|&k| prob.free[k]).collect();
    let head = headline(model, &ids);
    if words.is_empty() {
        format!("{lead}: a combination spread over many parameters")
    } else if words.len() == 1 {
        format!("{head} {lead}: {}", words[0])
    } else {
        format!(
            "{head} {lead} (components moving together as signed): {}",
            words.join(", ")
        )
    }
}

/// A short name for a combination of parameters (model indices `ids`), e.g. "hip centre,
/// superior-inferior," or "knee axis position along the axis," (directions in the joint's
/// nominal offset frames; a pin axis tilted by the fitted angles is treated as untilted).
pub(super) fn headline(model: &Model, ids: &[usize]) -> String {
    use crate::model::JointKind;
    let mut joints: Vec<usize> = ids
        .iter()
        .filter_map(|&i| model.parameters()[i].uses.first().map(|u| u.joint))
        .collect();
    joints.sort();
    joints.dedup();
    if joints.len() != 1 {
        let names: Vec<&str> = joints
            .iter()
            .map(|&j| model.joints()[j].name.as_str())
            .collect();
        return format!("{} parameters together,", names.join(" and "));
    }
    let joint = &model.joints()[joints[0]];
    let point = match joint.kind {
        JointKind::Pin { .. } | JointKind::Slider { .. } => "axis position",
        _ => "centre",
    };
    let mut scalars: Vec<&str> = ids
        .iter()
        .filter_map(|&i| model.parameters()[i].uses.first().map(|u| u.scalar))
        .collect();
    scalars.sort();
    scalars.dedup();
    let all_lengths = ids
        .iter()
        .all(|&i| model.parameters()[i].unit == Unit::Metre);
    let all_angles = ids
        .iter()
        .all(|&i| model.parameters()[i].unit == Unit::Radian);
    let name = &joint.name;
    if all_lengths && scalars.len() == 1 {
        let axis = match scalars[0] {
            "tx" => nalgebra::Vector3::x(),
            "ty" => nalgebra::Vector3::y(),
            _ => nalgebra::Vector3::z(),
        };
        if let JointKind::Pin { axis: pin } = &joint.kind {
            if pin.cross(&axis).norm() < 1e-9 {
                return format!("{name} axis position along the axis,");
            }
        }
        let dir = match scalars[0] {
            "tx" => "anterior-posterior",
            "ty" => "superior-inferior",
            _ => "medio-lateral",
        };
        format!("{name} {point}, {dir},")
    } else if all_lengths {
        format!("{name} {point},")
    } else if all_angles && scalars.len() == 1 {
        let plane = match scalars[0] {
            "rx" => "frontal",
            "ry" => "transverse",
            _ => "sagittal",
        };
        format!("{name} axis orientation in the {plane} plane,")
    } else if all_angles {
        format!("{name} axis orientation,")
    } else {
        format!("{name} axis position and orientation,")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};

    #[test]
    fn headlines_name_joint_quantity_and_direction() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let id = |n: &str| model.param_id(n).unwrap().0;
        assert_eq!(
            headline(
                &model,
                &[id("hip_pelvis_superior"), id("hip_thigh_superior")]
            ),
            "hip centre, superior-inferior,"
        );
        assert_eq!(
            headline(&model, &[id("knee_shank_lateral")]),
            "knee axis position along the axis,"
        );
        assert_eq!(
            headline(
                &model,
                &[
                    id("subtalar_talus_transverse"),
                    id("subtalar_foot_transverse")
                ]
            ),
            "subtalar axis orientation in the transverse plane,"
        );
        assert_eq!(
            headline(
                &model,
                &[id("talocrural_shank_lateral"), id("subtalar_foot_lateral")]
            ),
            "talocrural and subtalar parameters together,"
        );
    }
}
