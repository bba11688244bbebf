//! A marker set proposed from a static trial's labels and positions ([`suggest`]), for the
//! user to check before `personalize --markers`.
//!
//! The trial must be Y-up (rotate it first, e.g. with the vertical of
//! [`crate::vertical::detect_up`]). It is read in the frames where the most markers are
//! present (of at most 400 evenly spaced ones); each marker's position is its median over
//! those of them in which it is present. Then:
//!
//! 1. **Ignored**: trajectories no one labelled ([`automatic_label`]: Vicon's `*118`,
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
//! Everything decided is also said in [`Suggestion::notes`].

use nalgebra::Vector3;

use super::markerset::{LegMarkers, MarkerSet, PelvisMarkers};
use super::LandmarkError;
use crate::trial::Trial;

/// A proposed marker set and what the user should check.
#[derive(Debug, Clone)]
pub struct Suggestion {
    pub set: MarkerSet,
    /// One sentence per decision or doubt (ignored labels, geometric choices, legs left out).
    pub notes: Vec<String>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seg {
    Thigh,
    Shank,
    Foot,
}

struct Marker {
    label: String,
    /// Lower-case label without a subject prefix or side letter.
    norm: String,
    pos: Vector3<f64>,
    /// +1 right, −1 left.
    side: f64,
    /// Offset from the pelvis centre along the right axis (m).
    lateral: f64,
    /// Height as a fraction of the ASIS height above the floor.
    u: f64,
}

const IGNORE: &[&str] = &[
    "hjc", "kjc", "ajc", "elb", "wr", "hand", "fin", "frm", "forearm", "hum", "radius", "ulna",
    "bicep", "upa", "uarm", "sho", "acro", "clav", "head", "hd", "c7", "t10", "strn", "ster",
    "chest", "back", "bak", "temple", "scap", "melb", "neck", "hm", "uhe", "rsp", "hle", "hme",
];
const KNEE: &[&str] = &["kne", "mkn", "fle", "fme", "lfc", "mfc", "epi"];
const ANKLE: &[&str] = &["ank", "mal", "man", "fal", "tam"];
const HEEL: &[&str] = &["hee", "calc", "cal", "fcc"];
const TOE: &[&str] = &["toe"];
const META: &[&str] = &["mt", "meta", "fm"];
const THIGH: &[&str] = &["thi", "th", "fem", "gtr", "troch"];
const SHANK: &[&str] = &["tib", "sh", "shank", "fib"];
const FOOT: &[&str] = &[
    "nav", "foot", "mid", "cun", "toe", "hee", "calc", "mt", "meta",
];

/// Computed points as normalized labels: Plug-in Gait's segment origins (pelvis, femur,
/// tibia, foot, toe: the joint centres) and proximal femur point (the hip centre), joint
/// centres and centres of mass. (Its axis points `TIA`, `TIP`, … share their names with
/// tibia markers of other sets and are not listed.)
const COMPUTED: &[&str] = &[
    "peo",
    "feo",
    "fep",
    "tio",
    "foo",
    "too",
    "hjc",
    "kjc",
    "ajc",
    "com",
    "centreofmass",
    "centerofmass",
    "cog",
];

/// Why `label` (normalized `norm`) is not a marker anyone placed, if it is not: an
/// unlabelled trajectory (`*118`, `Unlabeled 12`, `M003`, `Marker12`, `New 0004`, `C_12`,
/// bare numbers), a floor projection (`*Ground`, `…floor`, `…proj`) or a computed point.
pub(crate) fn automatic_label(label: &str, norm: &str) -> Option<&'static str> {
    let l = label.rsplit(':').next().unwrap_or(label).trim();
    let lower = l.to_ascii_lowercase();
    if lower.starts_with('*') {
        return Some("an unlabelled or virtual trajectory (a '*' label)");
    }
    if lower.contains("unlabel") || lower.contains("unnamed") {
        return Some("an unlabelled trajectory");
    }
    // A word of letters (or none) followed by a number and nothing else.
    let stem = lower.trim_end_matches(|c: char| c.is_ascii_digit());
    let digits = lower.len() - stem.len();
    let stem = stem.trim_end_matches([' ', '_', '-', '.', '#']);
    if digits > 0
        && [
            "",
            "m",
            "marker",
            "mk",
            "new",
            "traj",
            "trajectory",
            "point",
            "pt",
        ]
        .contains(&stem)
    {
        return Some("a numbered automatic label, not a named marker");
    }
    if ["ground", "floor", "proj"]
        .iter()
        .any(|k| lower.contains(k))
    {
        return Some("a floor projection, not a marker");
    }
    if COMPUTED.contains(&norm) {
        return Some("a computed point (joint centre, segment axis or centre of mass)");
    }
    None
}

fn has(norm: &str, keys: &[&str]) -> bool {
    keys.iter().any(|k| norm.contains(k))
}

/// Lower-cased label without a `Subject:` prefix and without its side mark, and the side
/// the label names (+1 right, −1 left).
fn normalize(label: &str) -> (String, Option<f64>) {
    let l = label.rsplit(':').next().unwrap_or(label);
    let lower = l.to_ascii_lowercase();
    let chars: Vec<char> = l.chars().collect();
    let side_of = |c: char| match c.to_ascii_lowercase() {
        'r' => Some(1.0),
        'l' => Some(-1.0),
        _ => None,
    };
    for (word, s) in [("right", 1.0), ("left", -1.0)] {
        if let Some(rest) = lower.strip_prefix(word) {
            return (
                rest.trim_start_matches(['_', '.', ' ', '-']).to_string(),
                Some(s),
            );
        }
    }
    if chars.len() >= 2 {
        let (c0, c1) = (chars[0], chars[1]);
        // r_knee, R.ASIS, L ASI; RASI, LTHI (capital side letter, then capitals).
        if side_of(c0).is_some()
            && (matches!(c1, '_' | '.' | ' ' | '-') || (c0.is_uppercase() && c1.is_uppercase()))
        {
            let rest = lower[1..]
                .trim_start_matches(['_', '.', ' ', '-'])
                .to_string();
            return (rest, side_of(c0));
        }
        let (n, m) = (chars[chars.len() - 1], chars[chars.len() - 2]);
        // knee_r, ASIS.l; ASISr (lower-case side letter after capitals).
        if side_of(n).is_some()
            && (matches!(m, '_' | '.' | ' ' | '-') || (n.is_lowercase() && m.is_uppercase()))
        {
            let rest = lower[..lower.len() - 1]
                .trim_end_matches(['_', '.', ' ', '-'])
                .to_string();
            return (rest, side_of(n));
        }
    }
    (lower, None)
}

/// The frames the suggestion reads: of at most 400 evenly spaced frames, those in which the
/// most markers are present. A static trial usually has every marker in every frame; a trial
/// whose markers are all visible in only part of it (a walk through the capture volume) is
/// read where they are, instead of losing every marker that is missing in half of it.
fn fullest_frames(trial: &Trial) -> Vec<usize> {
    let n = trial.n_frames();
    let step = n.div_ceil(400).max(1);
    let count = |f: usize| {
        (0..trial.labels().len())
            .filter(|&j| trial.get(f, j).is_some())
            .count()
    };
    let counts: Vec<(usize, usize)> = (0..n).step_by(step).map(|f| (f, count(f))).collect();
    let most = counts.iter().map(|c| c.1).max().unwrap_or(0);
    counts
        .into_iter()
        .filter(|c| c.1 == most)
        .map(|c| c.0)
        .collect()
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Proposes a marker set for `trial` (Y-up, static) named `name` (module docs).
pub fn suggest(trial: &Trial, name: &str) -> Result<Suggestion, LandmarkError> {
    let fail = |detail: String| LandmarkError::InvalidMarkerSet {
        set: name.to_string(),
        detail,
    };
    let mut notes = Vec::new();
    let frames = fullest_frames(trial);
    let mut raw: Vec<(String, String, Option<f64>, Vector3<f64>)> = Vec::new();
    let mut missing = Vec::new();
    for (j, label) in trial.labels().iter().enumerate() {
        let present: Vec<Vector3<f64>> = frames.iter().filter_map(|&f| trial.get(f, j)).collect();
        let (norm, side) = normalize(label);
        if present.len() * 2 < frames.len() || present.is_empty() {
            notes.push(format!("ignored {label}: missing in most frames"));
            missing.push(label.as_str());
            continue;
        }
        if has(&norm, IGNORE) {
            continue;
        }
        if let Some(why) = automatic_label(label, &norm) {
            notes.push(format!("ignored {label}: {why}"));
            continue;
        }
        let pos = Vector3::new(
            median(present.iter().map(|p| p.x).collect()),
            median(present.iter().map(|p| p.y).collect()),
            median(present.iter().map(|p| p.z).collect()),
        );
        raw.push((label.clone(), norm, side, pos));
    }
    let find = |keys: &[&str]| -> Vec<usize> {
        (0..raw.len())
            .filter(|&i| {
                keys.iter()
                    .any(|k| raw[i].1 == *k || raw[i].1.starts_with(k))
            })
            .collect()
    };
    let asis = find(&["asis", "asi", "ias"]);
    let psis = find(&["psis", "psi", "ips"]);
    let sacrum = find(&["sacr", "vsac", "v.sacral", "sacral", "s2"]);
    if asis.len() != 2 {
        return Err(fail(format!(
            "found {} ASIS markers{} (labels like RASI, R.ASIS, L_IAS), need 2{}",
            asis.len(),
            if asis.is_empty() {
                String::new()
            } else {
                let labels: Vec<&str> = asis.iter().map(|&i| raw[i].0.as_str()).collect();
                format!(" ({})", labels.join(", "))
            },
            ignored_note(&missing)
        )));
    }
    let centre = (raw[asis[0]].3 + raw[asis[1]].3) / 2.0;
    let back = if psis.len() == 2 {
        (raw[psis[0]].3 + raw[psis[1]].3) / 2.0
    } else if let Some(&s) = sacrum.first() {
        raw[s].3
    } else {
        return Err(fail(format!(
            "found neither two PSIS (RPSI, R.PSIS, L_IPS) nor a sacral marker (SACR, V.Sacral){}",
            ignored_note(&missing)
        )));
    };
    let mut forward = centre - back;
    forward.y = 0.0;
    let right = forward.cross(&Vector3::y()).normalize();
    let floor = raw.iter().map(|r| r.3.y).fold(f64::INFINITY, f64::min);
    let height = centre.y - floor;
    if height.is_nan() || height <= 0.3 {
        return Err(fail(format!(
            "the ASIS sit {:.0} mm above the lowest marker: is the trial Y-up?",
            height * 1e3
        )));
    }
    let markers: Vec<Marker> = raw
        .iter()
        .map(|(label, norm, side, pos)| {
            let lateral = (pos - centre).dot(&right);
            Marker {
                label: label.clone(),
                norm: norm.clone(),
                pos: *pos,
                side: side.unwrap_or(lateral.signum()),
                lateral,
                u: (pos.y - floor) / height,
            }
        })
        .collect();
    let side_of = |i: usize| markers[i].side;
    let (ra, la) = if side_of(asis[0]) > 0.0 {
        (asis[0], asis[1])
    } else {
        (asis[1], asis[0])
    };
    let mut pelvis = PelvisMarkers {
        right_asis: markers[ra].label.clone(),
        left_asis: markers[la].label.clone(),
        right_psis: None,
        left_psis: None,
        sacrum: None,
        tracking: vec![markers[ra].label.clone(), markers[la].label.clone()],
    };
    if psis.len() == 2 {
        let (rp, lp) = if side_of(psis[0]) > 0.0 {
            (psis[0], psis[1])
        } else {
            (psis[1], psis[0])
        };
        pelvis.right_psis = Some(markers[rp].label.clone());
        pelvis.left_psis = Some(markers[lp].label.clone());
        pelvis
            .tracking
            .extend([markers[rp].label.clone(), markers[lp].label.clone()]);
    } else {
        let s = markers[sacrum[0]].label.clone();
        pelvis.sacrum = Some(s.clone());
        pelvis.tracking.push(s);
    }
    let mut pelvic: Vec<&String> = pelvis.tracking.iter().collect();
    pelvic.extend(sacrum.iter().map(|&i| &markers[i].label));
    let mut legs = [None, None];
    for (k, sign) in [(0usize, 1.0), (1, -1.0)] {
        let side_name = if sign > 0.0 { "right" } else { "left" };
        let mine: Vec<usize> = (0..markers.len())
            .filter(|&i| {
                markers[i].side == sign
                    && !pelvic.contains(&&markers[i].label)
                    && (markers[i].u < 0.9 || has(&markers[i].norm, THIGH))
                    && markers[i].u < 1.05
                    && markers[i].lateral.abs() < 0.35
            })
            .collect();
        match leg(&markers, &mine, sign) {
            Ok((leg, mut said)) => {
                notes.append(&mut said);
                legs[k] = Some(leg);
            }
            Err(why) => notes.push(format!("no [{side_name}] leg: {why}")),
        }
    }
    let [right_leg, left_leg] = legs;
    if right_leg.is_none() && left_leg.is_none() {
        return Err(fail(notes.join("; ")));
    }
    let set = MarkerSet {
        name: name.to_string(),
        description: "suggested by `jointfit markers suggest`: check every role".into(),
        pelvis,
        right: right_leg,
        left: left_leg,
    };
    Ok(Suggestion { set, notes })
}

/// The pair of markers among `cands` `sep` apart sideways (m, inclusive range) and at most
/// `dy` apart in height, widest first: (lateral, medial) for the leg on side `sign`.
fn pair(
    m: &[Marker],
    cands: &[usize],
    sep: (f64, f64),
    dy: f64,
    sign: f64,
) -> Option<(usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for (x, &a) in cands.iter().enumerate() {
        for &b in &cands[x + 1..] {
            let d = (m[a].lateral - m[b].lateral).abs();
            if d < sep.0 || d > sep.1 || (m[a].pos.y - m[b].pos.y).abs() > dy {
                continue;
            }
            if best.is_none_or(|(w, _, _)| d > w) {
                let (lat, med) = if m[a].lateral * sign > m[b].lateral * sign {
                    (a, b)
                } else {
                    (b, a)
                };
                best = Some((d, lat, med));
            }
        }
    }
    best.map(|(_, l, md)| (l, md))
}

/// One leg's roles from its markers `mine` (indices into `m`).
fn leg(m: &[Marker], mine: &[usize], sign: f64) -> Result<(LegMarkers, Vec<String>), String> {
    let mut notes = Vec::new();
    let named = |keys: &[&str]| -> Vec<usize> {
        mine.iter()
            .copied()
            .filter(|&i| has(&m[i].norm, keys))
            .collect()
    };
    let band = |lo: f64, hi: f64| -> Vec<usize> {
        mine.iter()
            .copied()
            .filter(|&i| m[i].u >= lo && m[i].u < hi)
            .collect()
    };
    let landmarks =
        |keys: &[&str], lo: f64, hi: f64, sep: (f64, f64), what: &str, notes: &mut Vec<String>| {
            let by_name = named(keys);
            if let Some(p) = pair(m, &by_name, sep, 0.06, sign) {
                return Ok(p);
            }
            let p = pair(m, &band(lo, hi), sep, 0.06, sign)
                .ok_or_else(|| format!("no pair of {what} markers found"))?;
            notes.push(format!(
                "{what}: chose {} (lateral) and {} (medial) by position; check them",
                m[p.0].label, m[p.1].label
            ));
            Ok::<_, String>(p)
        };
    let (lat_knee, med_knee) = landmarks(KNEE, 0.4, 0.65, (0.04, 0.18), "knee", &mut notes)?;
    let (lat_ank, med_ank) = landmarks(ANKLE, 0.0, 0.2, (0.03, 0.14), "ankle", &mut notes)?;
    let medial = [med_knee, med_ank];
    let ankle_y = (m[lat_ank].pos.y + m[med_ank].pos.y) / 2.0;
    let segment = |i: usize| -> Option<Seg> {
        if medial.contains(&i) {
            return None;
        }
        if i == lat_knee {
            return Some(Seg::Thigh);
        }
        if i == lat_ank {
            return Some(Seg::Shank);
        }
        let n = &m[i].norm;
        if has(n, FOOT) || has(n, HEEL) {
            Some(Seg::Foot)
        } else if has(n, SHANK) {
            Some(Seg::Shank)
        } else if has(n, THIGH) {
            Some(Seg::Thigh)
        } else if has(n, KNEE) || has(n, ANKLE) {
            None
        } else if m[i].u >= 0.55 {
            Some(Seg::Thigh)
        } else if m[i].u >= 0.12 {
            Some(Seg::Shank)
        } else {
            Some(Seg::Foot)
        }
    };
    let list = |s: Seg| -> Vec<String> {
        mine.iter()
            .copied()
            .filter(|&i| segment(i) == Some(s))
            .map(|i| m[i].label.clone())
            .collect()
    };
    let foot: Vec<usize> = mine
        .iter()
        .copied()
        .filter(|&i| segment(i) == Some(Seg::Foot))
        .collect();
    if foot.is_empty() {
        return Err("no foot markers".into());
    }
    let heel = named(HEEL)
        .into_iter()
        .filter(|i| foot.contains(i))
        .min_by(|&a, &b| m[a].pos.y.total_cmp(&m[b].pos.y))
        .unwrap_or_else(|| {
            let i = foot
                .iter()
                .copied()
                .min_by(|&a, &b| m[a].pos.x.total_cmp(&m[b].pos.x))
                .expect("non-empty");
            notes.push(format!(
                "heel: chose {} as the most posterior foot marker",
                m[i].label
            ));
            i
        });
    let forward = |keys: &[&str]| -> Vec<usize> {
        named(keys)
            .into_iter()
            .filter(|&i| foot.contains(&i) && i != heel && m[i].pos.y < ankle_y)
            .collect()
    };
    let mut forefoot = forward(TOE);
    if forefoot.is_empty() {
        forefoot = forward(META);
    }
    if forefoot.is_empty() {
        let i = foot
            .iter()
            .copied()
            .filter(|&i| i != heel)
            .max_by(|&a, &b| m[a].pos.x.total_cmp(&m[b].pos.x))
            .ok_or("no forefoot marker")?;
        notes.push(format!(
            "forefoot: chose {} as the most anterior foot marker",
            m[i].label
        ));
        forefoot.push(i);
    }
    let leg = LegMarkers {
        lateral_epicondyle: m[lat_knee].label.clone(),
        medial_epicondyle: m[med_knee].label.clone(),
        lateral_malleolus: m[lat_ank].label.clone(),
        medial_malleolus: m[med_ank].label.clone(),
        heel: m[heel].label.clone(),
        forefoot: forefoot.iter().map(|&i| m[i].label.clone()).collect(),
        thigh: list(Seg::Thigh),
        shank: list(Seg::Shank),
        foot: list(Seg::Foot),
    };
    for (seg, l) in [
        ("thigh", &leg.thigh),
        ("shank", &leg.shank),
        ("foot", &leg.foot),
    ] {
        let least = super::markerset::min_tracking(seg);
        if l.len() < least {
            return Err(format!(
                "{seg} has {} tracking markers ({}), needs {least}",
                l.len(),
                l.join(", ")
            ));
        }
    }
    Ok((leg, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn automatic_and_computed_labels_are_told_from_markers() {
        for label in [
            "*118",
            "Subject:*12",
            "Unlabeled 12",
            "unlabelled_3",
            "M003",
            "Marker12",
            "New 0004",
            "traj_7",
            "42",
            "*Ground",
            "RFloorProj",
            "RFEP",
            "LFEO",
            "RTIO",
            "LHJC",
            "CentreOfMass",
        ] {
            let (norm, _) = normalize(label);
            assert!(automatic_label(label, &norm).is_some(), "{label}");
        }
        for label in [
            "RASI",
            "L.PSIS",
            "r_knee",
            "RTIB",
            "RTIA",
            "RTIP",
            "RTHI",
            "LANK",
            "RHEE",
            "RMT5",
            "R.Toe.Tip",
            "r_sh2",
            "r_thigh1",
            "RKNM",
            "V.Sacral",
            "SACR",
            "RFM1",
            "LMT2",
        ] {
            let (norm, _) = normalize(label);
            assert_eq!(automatic_label(label, &norm), None, "{label}");
        }
    }
}
