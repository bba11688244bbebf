//! What a marker's label says: the side it names, the segment or landmark it hints at, and
//! whether it names a point no one placed (stages 1 and 3–6 of the parent module's docs).

pub(super) const IGNORE: &[&str] = &[
    "hjc", "kjc", "ajc", "elb", "wr", "hand", "fin", "frm", "forearm", "hum", "radius", "ulna",
    "bicep", "upa", "uarm", "sho", "acro", "clav", "head", "hd", "c7", "t10", "strn", "ster",
    "chest", "back", "bak", "temple", "scap", "melb", "neck", "hm", "uhe", "rsp", "hle", "hme",
];
/// Upper-limb and trunk landmarks of the ISB recommendations (Wu et al. 2005, J Biomech
/// 38:981–992) as normalized labels, matched whole: `RUS` (ulnar styloid), `REL` (lateral
/// humeral epicondyle), `IJ` (incisura jugularis), … Short enough to occur inside leg labels,
/// so not matched as parts.
pub(super) const IGNORE_EXACT: &[&str] = &[
    "us", "rs", "el", "em", "ac", "aa", "ai", "ts", "sc", "ij", "px", "t8", "gh",
];
pub(super) const KNEE: &[&str] = &["kne", "mkn", "fle", "fme", "lfc", "mfc", "epi"];
pub(super) const ANKLE: &[&str] = &["ank", "mal", "man", "fal", "tam"];
pub(super) const HEEL: &[&str] = &["hee", "calc", "cal", "fcc"];
pub(super) const TOE: &[&str] = &["toe"];
pub(super) const META: &[&str] = &["mt", "meta", "fm"];
pub(super) const THIGH: &[&str] = &["thi", "th", "fem", "gtr", "troch"];
pub(super) const SHANK: &[&str] = &["tib", "sh", "shank", "fib"];
pub(super) const FOOT: &[&str] = &[
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
pub(super) fn automatic_label(label: &str, norm: &str) -> Option<&'static str> {
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

pub(super) fn has(norm: &str, keys: &[&str]) -> bool {
    keys.iter().any(|k| norm.contains(k))
}

/// Lower-cased label without a `Subject:` prefix and without its side mark, and the side
/// the label names (+1 right, −1 left).
pub(super) fn normalize(label: &str) -> (String, Option<f64>) {
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
