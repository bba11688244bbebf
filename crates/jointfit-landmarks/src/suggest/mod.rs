//! A marker set proposed from a static trial's labels and positions ([`suggest`]), for the
//! user to check before `personalize --markers`.
//!
//! The trial must be Y-up (rotate it first, e.g. with the vertical of
//! [`jointfit::vertical::detect_up`]). It is read in the frames where the most markers are
//! present (of at most 400 evenly spaced ones); each marker's position is its median over
//! those of them in which it is present. Then:
//!
//! 1. **Ignored**: trajectories no one labelled ([`labels::automatic_label`]: Vicon's `*118`,
//!    `Unlabeled 12`, numbered auto-labels such as `M003`, `Marker12`, `New 0004`, bare
//!    numbers), points that are not markers (floor projections such as `*Ground`, Plug-in
//!    Gait's joint-centre and segment-axis outputs `RFEP`, `RFEO`, `RTIO`, …, centres of mass),
//!    virtual joint centres (`HJC`, `KJC`, `AJC`) and upper-body labels (head,
//!    trunk, arms), markers more than 0.35 m from the pelvis centre sideways or above 0.9 of
//!    the ASIS height (unless named as thigh markers, e.g. a trochanter), and markers missing
//!    in more than half of the frames read.
//! 2. **Pelvis**: ASIS (`ASIS`, `ASI`, `IAS`), PSIS (`PSIS`, `PSI`, `IPS`) and, without PSIS,
//!    a sacral marker (`SACR`, `V.Sacral`, `S2`). Forward is from the PSIS (or sacrum) to the
//!    ASIS, up is +y, right = forward × up (the model's z).
//! 3. **Side** of every other marker: from the label (`R`/`L` prefix or suffix, `Right`,
//!    `Left`), else the sign of its offset along the right axis from the pelvis centre.
//! 4. **Height**: `u = (y − floor) / (y_ASIS − floor)`, floor the lowest marker. Label hints
//!    place a marker on a segment (thigh: `THI`, `TH`, `FEM`, `GTR`; shank: `TIB`, `SH`,
//!    `SHANK`; foot: `HEE`, `HEEL`, `CALC`, `TOE`, `MT`, `META`, `NAV`); without one the height
//!    band decides (thigh 0.55–1, shank 0.12–0.55, foot below 0.12; Winter 2009 segment
//!    proportions put the knee near 0.52 and the ankle near 0.07 of the ASIS height).
//! 5. **Epicondyles and malleoli**: per side, among the markers whose labels name the knee
//!    (`KNE`, `KNEE`, `MKN`, `FLE`, `FME`, `LFC`, `MFC`, `EPI`) — or, if fewer than two do, all
//!    markers at 0.4–0.65 of the ASIS height — the pair 40–180 mm apart sideways at most
//!    60 mm apart in height that is widest; the one farther from the body's midline is
//!    lateral. The malleoli likewise (`ANK`, `ANKLE`, `MAL`, `MAN`, `FAL`, `TAM`; band
//!    0–0.2, 30–140 mm apart). Medial landmarks do not track (they are usually removed for
//!    motion trials); lateral ones track their segment (thigh, shank).
//! 6. **Heel and forefoot**: the heel-named marker (else the foot's most posterior one); the
//!    toe-named markers (else metatarsal heads, else the most anterior foot marker).
//!
//! 7. **Confidence per role** ([`Role`]): whether the label names the role, where the
//!    marker sits against the height band the role expects and, with a motion trial of the
//!    same session ([`coherence`]), whether it moves with its segment (its distances to the
//!    segment's other markers vary by less than [`INCOHERENT_M`]): `high` when the label and
//!    the place agree, `low` for a marker that does not move with its segment or that
//!    neither supports, `medium` otherwise.
//!
//! Upper-limb and trunk labels are ignored as parts (`ELB`, `WR`, `SHO`, …) or, for the short
//! ISB names (`RUS`, `REL`, `IJ`, …), whole.
//!
//! Everything decided is also said in [`Suggestion::notes`].
//!
//! The stages live by concept: what a label says (`labels`), the trial read once (`reading`),
//! the body's frame from the pelvis (`body`), one leg's roles (`leg`); the suggestion and how
//! sure each role is stay here.

mod body;
mod labels;
mod leg;
mod reading;

use body::{pelvic_roles, Body};
use labels::{has, THIGH};
use leg::leg;
use reading::{median, read_markers};

use super::markerset::MarkerSet;
use super::LandmarkError;
use jointfit::trial::Trial;

/// A proposed marker set and what the user should check.
#[derive(Debug, Clone)]
pub struct Suggestion {
    pub set: MarkerSet,
    /// One sentence per decision or doubt (ignored labels, geometric choices, legs left out).
    pub notes: Vec<String>,
    /// Every role given and what it is based on, pelvis first.
    pub roles: Vec<Role>,
}

/// Proposes a marker set for `trial` (Y-up, static) named `name` (module docs).
pub fn suggest(trial: &Trial, name: &str) -> Result<Suggestion, LandmarkError> {
    let fail = |detail: String| LandmarkError::InvalidMarkerSet {
        set: name.to_string(),
        detail,
    };
    let mut notes = Vec::new();
    let (raw, missing) = read_markers(trial, &mut notes);
    let body = Body::locate(&raw, &missing).map_err(fail)?;
    let markers = body.markers(&raw);
    let (pelvis, pelvic) = body.pelvis(&markers);
    let mut roles: Vec<Role> = pelvic_roles(&pelvis);
    let mut legs = [None, None];
    for (k, sign) in [(0usize, 1.0), (1, -1.0)] {
        let side_name = if sign > 0.0 { "right" } else { "left" };
        let mine: Vec<usize> = (0..markers.len())
            .filter(|&i| {
                let m = &markers[i];
                m.side == sign
                    && !pelvic.contains(&m.label)
                    && (m.u < 0.9 || has(&m.norm, THIGH))
                    && m.u < 1.05
                    && m.lateral.abs() < 0.35
            })
            .collect();
        match leg(&markers, &mine, sign) {
            Ok((leg, mut said, mut given)) => {
                notes.append(&mut said);
                for r in given.iter_mut() {
                    r.role = format!("{side_name} {}", r.role);
                }
                roles.append(&mut given);
                legs[k] = Some(leg);
            }
            Err(why) => notes.push(format!("no [{side_name}] leg: {why}")),
        }
    }
    let [right_leg, left_leg] = legs;
    if right_leg.is_none() && left_leg.is_none() {
        // Why the legs failed first; the ignored labels only counted (they can be many).
        let (legs, others): (Vec<&String>, Vec<&String>) =
            notes.iter().partition(|n| n.starts_with("no ["));
        let legs: Vec<&str> = legs.iter().map(|n| n.as_str()).collect();
        return Err(fail(format!(
            "{}{}",
            legs.join("; "),
            match others.len() {
                0 => String::new(),
                n => format!(" ({n} labels ignored: unlabelled, computed or missing)"),
            }
        )));
    }
    let set = MarkerSet {
        name: name.to_string(),
        description: "suggested by `jointfit markers suggest`: check every role".into(),
        pelvis,
        right: right_leg,
        left: left_leg,
    };
    Ok(Suggestion { set, notes, roles })
}

/// How sure a suggested role is ([`Role::confidence`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Confidence {
    Low,
    Medium,
    High,
}

impl Confidence {
    pub fn name(self) -> &'static str {
        match self {
            Confidence::Low => "low",
            Confidence::Medium => "medium",
            Confidence::High => "high",
        }
    }
}

/// A marker's distances to the other markers of its segment varying more than this (SD, m)
/// through a motion trial: it does not move with the segment. Skin markers of one segment
/// keep their distances within a few millimetres in gait (the shared trials: 1–3 mm between
/// static and motion trials); a marker of another segment (a wrist beside the thigh) changes
/// them by centimetres.
const INCOHERENT_M: f64 = 0.010;

/// What one suggested role is based on.
#[derive(Debug, Clone, PartialEq)]
pub struct Role {
    /// e.g. `right lateral epicondyle`, `left thigh tracking`, `pelvis right ASIS`.
    pub role: String,
    pub marker: String,
    /// The label names the role (`KNE`, `FLE`, `THI`, `HEE`, …).
    pub label_match: bool,
    /// Where the marker sits against where the role expects it, and whether it is inside.
    pub place: String,
    pub place_ok: bool,
    /// Motion coherence with its segment: the median SD (m) through a motion trial of the
    /// marker's distances to the other markers of its segment ([`coherence`]); `None`
    /// without a motion trial or for a landmark that tracks nothing.
    pub coherence: Option<f64>,
}

impl Role {
    fn new(role: &str, marker: &str, label_match: bool, place: String, place_ok: bool) -> Role {
        Role {
            role: role.to_string(),
            marker: marker.to_string(),
            label_match,
            place,
            place_ok,
            coherence: None,
        }
    }

    /// `low` for a marker that does not move with its segment ([`INCOHERENT_M`]) or that
    /// neither its label nor its place supports; `high` when its label names the role and it
    /// sits where the role expects it; `medium` otherwise.
    pub fn confidence(&self) -> Confidence {
        if self.coherence.is_some_and(|sd| sd > INCOHERENT_M) {
            return Confidence::Low;
        }
        match (self.label_match, self.place_ok) {
            (true, true) => Confidence::High,
            (false, false) => Confidence::Low,
            _ => Confidence::Medium,
        }
    }

    /// What the confidence is based on, in words.
    pub fn basis(&self) -> String {
        let mut out = vec![match self.label_match {
            true => "label matches".to_string(),
            false => "chosen by position".to_string(),
        }];
        out.push(self.place.clone());
        if let Some(sd) = self.coherence {
            out.push(match sd > INCOHERENT_M {
                true => format!(
                    "does NOT move with its segment (distance SD {:.1} mm)",
                    sd * 1e3
                ),
                false => format!("moves with its segment (distance SD {:.1} mm)", sd * 1e3),
            });
        }
        out.join("; ")
    }
}

/// Each role's motion coherence from a motion trial of the same session (its labels as in
/// the static trial): for a marker that tracks a segment of `set`, the median over the
/// segment's other tracking markers of the SD of their distance through the frames where
/// both are present (at least 10 such frames).
pub fn coherence(motion: &Trial, set: &MarkerSet, roles: &mut [Role]) {
    let mut groups: Vec<&[String]> = vec![&set.pelvis.tracking];
    for leg in [&set.right, &set.left].into_iter().flatten() {
        groups.extend([&leg.thigh[..], &leg.shank[..], &leg.foot[..]]);
    }
    let column = |l: &str| motion.labels().iter().position(|x| x == l);
    let sd_of = |a: usize, b: usize| -> Option<f64> {
        let d: Vec<f64> = (0..motion.n_frames())
            .filter_map(|f| Some((motion.get(f, a)? - motion.get(f, b)?).norm()))
            .collect();
        (d.len() >= 10).then(|| {
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
        })
    };
    for r in roles.iter_mut() {
        let Some(group) = groups.iter().find(|g| g.contains(&r.marker)) else {
            continue;
        };
        let Some(a) = column(&r.marker) else { continue };
        let sds: Vec<f64> = group
            .iter()
            .filter(|o| **o != r.marker)
            .filter_map(|o| sd_of(a, column(o)?))
            .collect();
        if !sds.is_empty() {
            r.coherence = Some(median(sds));
        }
    }
}
