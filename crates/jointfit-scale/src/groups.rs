//! Which bodies share a scale factor, the static pose the fit registers markers on, and the
//! plausibility checks of fitted factors.

use std::collections::BTreeMap;
use std::ops::Range;

use nalgebra::Vector3;

use crate::fit::{GroupFit, ScaleGroup};
use jointfit::model::spec::ModelSpec;
use jointfit::trial::Trial;

/// The other side's name of a bilateral body (`femur_r` ↔ `femur_l`), if it has one.
pub(crate) fn mirror_name(body: &str) -> Option<String> {
    if let Some(s) = body.strip_suffix("_r") {
        Some(format!("{s}_l"))
    } else {
        body.strip_suffix("_l").map(|s| format!("{s}_r"))
    }
}

/// Default groups: every body that carries a marker scales by its own factor; a body without
/// markers (patella, talus, toes, …) follows the nearest ancestor that has one, as OpenSim's
/// setups scale them with their parent's measurement; bodies with no marked ancestor keep
/// their size. `symmetric`: a body and its mirror (`_r`/`_l`) share one group.
pub fn default_groups(spec: &ModelSpec, per_axis: bool, symmetric: bool) -> Vec<ScaleGroup> {
    let marked = |b: &str| spec.markers.iter().any(|m| m.segment == b);
    let parent = |b: &str| {
        spec.joints
            .iter()
            .find(|j| j.child == b)
            .map(|j| j.parent.clone())
    };
    let mut owner: BTreeMap<String, String> = BTreeMap::new();
    for s in &spec.segments {
        let mut b = s.name.clone();
        let mut hops = 0;
        while !marked(&b) && hops < 64 {
            match parent(&b) {
                Some(p) => b = p,
                None => break,
            }
            hops += 1;
        }
        if marked(&b) {
            owner.insert(s.name.clone(), b);
        }
    }
    let mut groups: Vec<ScaleGroup> = Vec::new();
    for s in &spec.segments {
        let Some(o) = owner.get(&s.name) else {
            continue;
        };
        let key = match (symmetric, mirror_name(o)) {
            (true, Some(m)) if o.ends_with("_l") && owner.values().any(|v| *v == m) => m,
            _ => o.clone(),
        };
        let name = if symmetric && mirror_name(&key).is_some() {
            key.trim_end_matches("_r").to_string()
        } else {
            key.clone()
        };
        match groups.iter_mut().find(|g| g.name == name) {
            Some(g) => g.bodies.push(s.name.clone()),
            None => groups.push(ScaleGroup {
                name,
                bodies: vec![s.name.clone()],
                per_axis,
            }),
        }
    }
    groups
}

/// Per model marker: the mean position over `frames` of the trial's marker of that name
/// (NaN when absent or never present).
pub fn averaged_targets(
    spec: &ModelSpec,
    trial: &Trial,
    frames: Range<usize>,
) -> Vec<Vector3<f64>> {
    spec.markers
        .iter()
        .map(|m| {
            let Ok(c) = trial.index_of(&m.name) else {
                return Vector3::repeat(f64::NAN);
            };
            let (mut sum, mut n) = (Vector3::zeros(), 0usize);
            for f in frames.clone() {
                if let Some(p) = trial.get(f, c) {
                    sum += p;
                    n += 1;
                }
            }
            if n == 0 {
                Vector3::repeat(f64::NAN)
            } else {
                sum / n as f64
            }
        })
        .collect()
}

/// Plausibility of fitted factors, as sentences with the numbers: left and right groups
/// whose factors differ by more than `asymmetry` (relative), and factors farther than
/// `spread` (log units) from the median factor (segment proportions far from the generic
/// model's, i.e. from the population the model was built on).
pub fn plausibility(groups: &[GroupFit], asymmetry: f64, spread: f64) -> Vec<String> {
    let mut out = Vec::new();
    let mut all: Vec<f64> = groups.iter().flat_map(|g| g.factors).collect();
    all.sort_by(f64::total_cmp);
    let median = all.get(all.len() / 2).copied().unwrap_or(1.0);
    for g in groups {
        if let Some(m) = mirror_name(&g.name) {
            if g.name.ends_with("_r") {
                if let Some(h) = groups.iter().find(|h| h.name == m) {
                    for k in 0..3 {
                        let d = g.factors[k] / h.factors[k] - 1.0;
                        if d.abs() > asymmetry {
                            out.push(format!(
                                "asymmetric: {} {:.3} vs {} {:.3} ({}{:.1} %, axis {})",
                                g.name,
                                g.factors[k],
                                h.name,
                                h.factors[k],
                                if d > 0.0 { "+" } else { "" },
                                100.0 * d,
                                ["x", "y", "z"][k]
                            ));
                        }
                        if !g.per_axis_like() && !h.per_axis_like() {
                            break;
                        }
                    }
                }
            }
        }
        for k in 0..3 {
            let d = (g.factors[k] / median).ln();
            if d.abs() > spread {
                out.push(format!(
                    "out of proportion: {} factor {:.3} is {:.0} % from the median factor {:.3} (axis {})",
                    g.name,
                    g.factors[k],
                    100.0 * (g.factors[k] / median - 1.0),
                    median,
                    ["x", "y", "z"][k]
                ));
            }
            if !g.per_axis_like() {
                break;
            }
        }
    }
    out
}

impl GroupFit {
    fn per_axis_like(&self) -> bool {
        self.factors[0] != self.factors[1] || self.factors[1] != self.factors[2]
    }
}
