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
    /// Every role given and what it is based on, pelvis first.
    pub roles: Vec<Role>,
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
/// Upper-limb and trunk landmarks of the ISB recommendations (Wu et al. 2005, J Biomech
/// 38:981–992) as normalized labels, matched whole: `RUS` (ulnar styloid), `REL` (lateral
/// humeral epicondyle), `IJ` (incisura jugularis), … Short enough to occur inside leg labels,
/// so not matched as parts.
const IGNORE_EXACT: &[&str] = &[
    "us", "rs", "el", "em", "ac", "aa", "ai", "ts", "sc", "ij", "px", "t8", "gh",
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

/// A raw marker: label, normalized label, the side its label names, median position.
type Raw = (String, String, Option<f64>, Vector3<f64>);

/// Every labelled marker present in most of the frames read, at its median position; the
/// others are said in `notes` (stage 1 of the module docs). Also the labels missing in most
/// frames.
fn read_markers(trial: &Trial, notes: &mut Vec<String>) -> (Vec<Raw>, Vec<String>) {
    let frames = fullest_frames(trial);
    let mut raw = Vec::new();
    let mut missing = Vec::new();
    for (j, label) in trial.labels().iter().enumerate() {
        let present: Vec<Vector3<f64>> = frames.iter().filter_map(|&f| trial.get(f, j)).collect();
        let (norm, side) = normalize(label);
        if present.len() * 2 < frames.len() || present.is_empty() {
            notes.push(format!("ignored {label}: missing in most frames"));
            missing.push(label.clone());
            continue;
        }
        if has(&norm, IGNORE) || IGNORE_EXACT.contains(&norm.as_str()) {
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
    (raw, missing)
}

/// The pelvis markers and the body's axes and scale (stage 2 of the module docs).
struct Body {
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
    fn locate(raw: &[Raw], missing: &[String]) -> Result<Body, String> {
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
    fn markers(&self, raw: &[Raw]) -> Vec<Marker> {
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
    fn pelvis(&self, markers: &[Marker]) -> (PelvisMarkers, Vec<String>) {
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
fn pelvic_roles(p: &PelvisMarkers) -> Vec<Role> {
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

/// Height bands (fractions of the ASIS height) of the module docs, stage 4.
const THIGH_BAND: (f64, f64) = (0.55, 1.05);
const SHANK_BAND: (f64, f64) = (0.12, 0.55);
const FOOT_BAND: (f64, f64) = (-0.05, 0.12);
const KNEE_BAND: (f64, f64) = (0.4, 0.65);
const ANKLE_BAND: (f64, f64) = (0.0, 0.2);

/// Where marker `i` sits against the band its role expects, and whether it is inside.
fn place(m: &Marker, band: (f64, f64)) -> (String, bool) {
    (
        format!(
            "at {:.2} of the ASIS height (expected {:.2}–{:.2})",
            m.u, band.0, band.1
        ),
        m.u >= band.0 && m.u < band.1,
    )
}

/// One leg's markers `mine` (indices into `m`) and what the roles are based on.
struct Leg<'a> {
    m: &'a [Marker],
    mine: &'a [usize],
    sign: f64,
    notes: Vec<String>,
    roles: Vec<Role>,
}

impl Leg<'_> {
    fn named(&self, keys: &[&str]) -> Vec<usize> {
        self.mine
            .iter()
            .copied()
            .filter(|&i| has(&self.m[i].norm, keys))
            .collect()
    }

    fn role(&mut self, role: &str, i: usize, by_label: bool, band: (f64, f64)) {
        let (text, ok) = place(&self.m[i], band);
        self.roles
            .push(Role::new(role, &self.m[i].label, by_label, text, ok));
    }

    /// The (lateral, medial) landmark pair of a joint (stage 5): by name, else by position.
    fn landmarks(
        &mut self,
        keys: &[&str],
        band: (f64, f64),
        sep: (f64, f64),
        what: &str,
    ) -> Result<(usize, usize), String> {
        let (p, by_label) = match pair(self.m, &self.named(keys), sep, 0.06, self.sign) {
            Some(p) => (p, true),
            None => {
                let cands: Vec<usize> = self
                    .mine
                    .iter()
                    .copied()
                    .filter(|&i| self.m[i].u >= band.0 && self.m[i].u < band.1)
                    .collect();
                let p = pair(self.m, &cands, sep, 0.06, self.sign)
                    .ok_or_else(|| format!("no pair of {what} markers found"))?;
                self.notes.push(format!(
                    "{what}: chose {} (lateral) and {} (medial) by position; check them",
                    self.m[p.0].label, self.m[p.1].label
                ));
                (p, false)
            }
        };
        let (lat, med) = match what {
            "knee" => ("lateral epicondyle", "medial epicondyle"),
            _ => ("lateral malleolus", "medial malleolus"),
        };
        self.role(lat, p.0, by_label, band);
        self.role(med, p.1, by_label, band);
        Ok(p)
    }

    /// The segment a marker tracks (stage 4), and whether its label said so; `None` for a
    /// medial landmark or a landmark-named marker off its pair.
    fn segment(&self, i: usize, landmarks: [usize; 4]) -> Option<(Seg, bool)> {
        let [lat_knee, med_knee, lat_ank, med_ank] = landmarks;
        if i == med_knee || i == med_ank {
            return None;
        }
        if i == lat_knee {
            return Some((Seg::Thigh, true));
        }
        if i == lat_ank {
            return Some((Seg::Shank, true));
        }
        let (n, u) = (&self.m[i].norm, self.m[i].u);
        if has(n, FOOT) || has(n, HEEL) {
            Some((Seg::Foot, true))
        } else if has(n, SHANK) {
            Some((Seg::Shank, true))
        } else if has(n, THIGH) {
            Some((Seg::Thigh, true))
        } else if has(n, KNEE) || has(n, ANKLE) {
            None
        } else if u >= THIGH_BAND.0 {
            Some((Seg::Thigh, false))
        } else if u >= SHANK_BAND.0 {
            Some((Seg::Shank, false))
        } else {
            Some((Seg::Foot, false))
        }
    }

    /// The heel (stage 6): the heel-named foot marker, else the most posterior one.
    fn heel(&mut self, foot: &[usize]) -> usize {
        let named = self
            .named(HEEL)
            .into_iter()
            .filter(|i| foot.contains(i))
            .min_by(|&a, &b| self.m[a].pos.y.total_cmp(&self.m[b].pos.y));
        let i = named.unwrap_or_else(|| {
            let i = foot
                .iter()
                .copied()
                .min_by(|&a, &b| self.m[a].pos.x.total_cmp(&self.m[b].pos.x))
                .expect("non-empty");
            self.notes.push(format!(
                "heel: chose {} as the most posterior foot marker",
                self.m[i].label
            ));
            i
        });
        self.role("heel", i, named.is_some(), FOOT_BAND);
        i
    }

    /// The forefoot (stage 6): toe-named markers, else metatarsal heads, else the most
    /// anterior foot marker.
    fn forefoot(
        &mut self,
        foot: &[usize],
        heel: usize,
        ankle_y: f64,
    ) -> Result<Vec<usize>, String> {
        let forward = |keys: &[&str]| -> Vec<usize> {
            self.named(keys)
                .into_iter()
                .filter(|&i| foot.contains(&i) && i != heel && self.m[i].pos.y < ankle_y)
                .collect()
        };
        let mut chosen = forward(TOE);
        if chosen.is_empty() {
            chosen = forward(META);
        }
        let by_label = !chosen.is_empty();
        if chosen.is_empty() {
            let i = foot
                .iter()
                .copied()
                .filter(|&i| i != heel)
                .max_by(|&a, &b| self.m[a].pos.x.total_cmp(&self.m[b].pos.x))
                .ok_or("no forefoot marker")?;
            self.notes.push(format!(
                "forefoot: chose {} as the most anterior foot marker",
                self.m[i].label
            ));
            chosen.push(i);
        }
        for &i in &chosen {
            self.role("forefoot", i, by_label, FOOT_BAND);
        }
        Ok(chosen)
    }
}

/// One leg's roles from its markers `mine` (indices into `m`), the notes on how they were
/// chosen, and what each role is based on.
fn leg(
    m: &[Marker],
    mine: &[usize],
    sign: f64,
) -> Result<(LegMarkers, Vec<String>, Vec<Role>), String> {
    let mut l = Leg {
        m,
        mine,
        sign,
        notes: Vec::new(),
        roles: Vec::new(),
    };
    let (lat_knee, med_knee) = l.landmarks(KNEE, KNEE_BAND, (0.04, 0.18), "knee")?;
    let (lat_ank, med_ank) = l.landmarks(ANKLE, ANKLE_BAND, (0.03, 0.14), "ankle")?;
    let landmarks = [lat_knee, med_knee, lat_ank, med_ank];
    let segments: Vec<(usize, Seg, bool)> = mine
        .iter()
        .filter_map(|&i| l.segment(i, landmarks).map(|(s, named)| (i, s, named)))
        .collect();
    let list = |s: Seg| -> Vec<String> {
        segments
            .iter()
            .filter(|x| x.1 == s)
            .map(|x| m[x.0].label.clone())
            .collect()
    };
    let foot: Vec<usize> = segments
        .iter()
        .filter(|x| x.1 == Seg::Foot)
        .map(|x| x.0)
        .collect();
    if foot.is_empty() {
        return Err("no foot markers".into());
    }
    let heel = l.heel(&foot);
    let ankle_y = (m[lat_ank].pos.y + m[med_ank].pos.y) / 2.0;
    let forefoot = l.forefoot(&foot, heel, ankle_y)?;
    for &(i, s, named) in &segments {
        let (name, band) = match s {
            Seg::Thigh => ("thigh tracking", THIGH_BAND),
            Seg::Shank => ("shank tracking", SHANK_BAND),
            Seg::Foot => ("foot tracking", FOOT_BAND),
        };
        l.role(name, i, named, band);
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
    for (seg, tracked) in [
        ("thigh", &leg.thigh),
        ("shank", &leg.shank),
        ("foot", &leg.foot),
    ] {
        let least = super::markerset::min_tracking(seg);
        if tracked.len() < least {
            return Err(format!(
                "{seg} has {} tracking markers ({}), needs {least}",
                tracked.len(),
                tracked.join(", ")
            ));
        }
    }
    Ok((leg, l.notes, l.roles))
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
pub(crate) const INCOHERENT_M: f64 = 0.010;

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
