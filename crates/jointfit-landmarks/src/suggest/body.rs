//! The body's frame from the pelvis markers: the ASIS, PSIS or sacrum, the right axis, the
//! floor and the ASIS height, and every marker's side, lateral offset and height in it
//! (stages 2–4 of the parent module's docs).

use nalgebra::Vector3;

use super::reading::Raw;
use super::Role;
use crate::markerset::PelvisMarkers;

pub(super) struct Marker {
    pub(super) label: String,
    /// Lower-case label without a subject prefix or side letter.
    pub(super) norm: String,
    pub(super) pos: Vector3<f64>,
    /// +1 right, −1 left.
    pub(super) side: f64,
    /// Offset from the pelvis centre along the right axis (m).
    pub(super) lateral: f64,
    /// Height as a fraction of the ASIS height above the floor.
    pub(super) u: f64,
}

/// ", ignored as missing in most frames: A, B" when any marker was, else "".
fn ignored_note(missing: &[&str]) -> String {
    if missing.is_empty() {
        String::new()
    } else {
        format!(
            "; ignored as missing in most frames: {}",
            missing.join(", ")
        )
    }
}

/// The pelvis markers and the body's axes and scale (stage 2 of the module docs).
pub(super) struct Body {
    asis: Vec<usize>,
    psis: Vec<usize>,
    sacrum: Vec<usize>,
    /// Mid-ASIS (m) and the right axis (unit, horizontal).
    centre: Vector3<f64>,
    right: Vector3<f64>,
    /// Height of the lowest marker, and of the ASIS above it (m).
    floor: f64,
    height: f64,
}

impl Body {
    pub(super) fn locate(raw: &[Raw], missing: &[String]) -> Result<Body, String> {
        let find = |keys: &[&str]| -> Vec<usize> {
            (0..raw.len())
                .filter(|&i| {
                    keys.iter()
                        .any(|k| raw[i].1 == *k || raw[i].1.starts_with(k))
                })
                .collect()
        };
        let missing: Vec<&str> = missing.iter().map(String::as_str).collect();
        let asis = find(&["asis", "asi", "ias"]);
        let psis = find(&["psis", "psi", "ips"]);
        let sacrum = find(&["sacr", "vsac", "v.sacral", "sacral", "s2"]);
        if asis.len() != 2 {
            let labels: Vec<&str> = asis.iter().map(|&i| raw[i].0.as_str()).collect();
            return Err(format!(
                "found {} ASIS markers{} (labels like RASI, R.ASIS, L_IAS), need 2{}",
                asis.len(),
                match labels.is_empty() {
                    true => String::new(),
                    false => format!(" ({})", labels.join(", ")),
                },
                ignored_note(&missing)
            ));
        }
        let centre = (raw[asis[0]].3 + raw[asis[1]].3) / 2.0;
        let back = if psis.len() == 2 {
            (raw[psis[0]].3 + raw[psis[1]].3) / 2.0
        } else if let Some(&s) = sacrum.first() {
            raw[s].3
        } else {
            return Err(format!(
                "found neither two PSIS (RPSI, R.PSIS, L_IPS) nor a sacral marker (SACR, \
                 V.Sacral){}",
                ignored_note(&missing)
            ));
        };
        let mut forward = centre - back;
        forward.y = 0.0;
        let right = forward.cross(&Vector3::y()).normalize();
        let floor = raw.iter().map(|r| r.3.y).fold(f64::INFINITY, f64::min);
        let height = centre.y - floor;
        if height.is_nan() || height <= 0.3 {
            return Err(format!(
                "the ASIS sit {:.0} mm above the lowest marker: is the trial Y-up?",
                height * 1e3
            ));
        }
        Ok(Body {
            asis,
            psis,
            sacrum,
            centre,
            right,
            floor,
            height,
        })
    }

    /// Every marker with its side, lateral offset and height (stages 3 and 4).
    pub(super) fn markers(&self, raw: &[Raw]) -> Vec<Marker> {
        raw.iter()
            .map(|(label, norm, side, pos)| {
                let lateral = (pos - self.centre).dot(&self.right);
                Marker {
                    label: label.clone(),
                    norm: norm.clone(),
                    pos: *pos,
                    side: side.unwrap_or(lateral.signum()),
                    lateral,
                    u: (pos.y - self.floor) / self.height,
                }
            })
            .collect()
    }

    /// The pelvis roles, and every label that belongs to the pelvis (its tracking markers
    /// and any sacral marker).
    pub(super) fn pelvis(&self, markers: &[Marker]) -> (PelvisMarkers, Vec<String>) {
        let by_side = |pair: &[usize]| match markers[pair[0]].side > 0.0 {
            true => (pair[0], pair[1]),
            false => (pair[1], pair[0]),
        };
        let (ra, la) = by_side(&self.asis);
        let label = |i: usize| markers[i].label.clone();
        let mut pelvis = PelvisMarkers {
            right_asis: label(ra),
            left_asis: label(la),
            right_psis: None,
            left_psis: None,
            sacrum: None,
            tracking: vec![label(ra), label(la)],
        };
        if self.psis.len() == 2 {
            let (rp, lp) = by_side(&self.psis);
            pelvis.right_psis = Some(label(rp));
            pelvis.left_psis = Some(label(lp));
            pelvis.tracking.extend([label(rp), label(lp)]);
        } else {
            let s = label(self.sacrum[0]);
            pelvis.sacrum = Some(s.clone());
            pelvis.tracking.push(s);
        }
        let mut pelvic = pelvis.tracking.clone();
        pelvic.extend(self.sacrum.iter().map(|&i| label(i)));
        (pelvis, pelvic)
    }
}

/// The pelvis roles: found by their labels only (stage 2), so always a label match.
pub(super) fn pelvic_roles(p: &PelvisMarkers) -> Vec<Role> {
    let mut out = vec![
        ("pelvis right ASIS", &p.right_asis),
        ("pelvis left ASIS", &p.left_asis),
    ];
    if let (Some(r), Some(l)) = (&p.right_psis, &p.left_psis) {
        out.extend([("pelvis right PSIS", r), ("pelvis left PSIS", l)]);
    }
    if let Some(s) = &p.sacrum {
        out.push(("pelvis sacrum", s));
    }
    out.into_iter()
        .map(|(role, marker)| Role::new(role, marker, true, "defines the pelvis".into(), true))
        .collect()
}
