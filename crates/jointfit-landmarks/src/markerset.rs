//! Marker sets: which of a laboratory's marker labels play which anatomical role.
//!
//! A marker set is a small TOML description (the built-in presets are written the same way):
//!
//! ```toml
//! name = "my-lab"
//!
//! [pelvis]
//! right_asis = "RASI"
//! left_asis = "LASI"
//! right_psis = "RPSI"        # both PSIS, or a single `sacrum` marker, or both
//! left_psis = "LPSI"
//! tracking = ["RASI", "LASI", "RPSI", "LPSI"]
//!
//! [right]                    # and/or [left]
//! lateral_epicondyle = "RKNE"
//! medial_epicondyle = "RKNEM"
//! lateral_malleolus = "RANK"
//! medial_malleolus = "RANKM"
//! heel = "RHEE"
//! forefoot = ["RTOE"]        # toe marker or metatarsal heads: their mean sets the foot's x
//! thigh = ["RTHI", "RTHIB", "RTHID", "RKNE"]   # tracking markers: pelvis ≥ 3, leg segments ≥ 2
//! shank = ["RTIB", "RTIBF", "RTIBD", "RANK"]
//! foot = ["RHEE", "RTOE", "RNAV", "RTOE5"]
//! ```
//!
//! Landmarks (ASIS, PSIS, sacrum, epicondyles, malleoli, heel, forefoot) are used only to
//! build the segment frames from the static trial; tracking markers become model markers and
//! must also be present in the movement trials. A landmark may also track (a lateral knee
//! marker often does). A label can track only one segment.
//!
//! ## Sets without medial markers (Plug-in Gait)
//! A medial landmark may be `"chord:WAND"` instead of a label: the joint centre is then found
//! by Plug-in Gait's chord function ([`super::plugin_gait`]) in the plane of the wand marker
//! `WAND` (thigh wand at the knee, tibia wand at the ankle), the lateral marker and the joint
//! centre above, from the subject's knee or ankle width and the marker diameter
//! ([`super::SubjectMeasurements`]). A medial landmark may also list alternatives separated
//! by `|`, e.g. `"RKNEM|chord:RTHI"`: the first one the static trial carries is used (a chord
//! alternative when its wand marker is there) — medial markers where the lab placed them,
//! the chord function otherwise.

use serde::{Deserialize, Serialize};

use super::LandmarkError;
use jointfit::model::lower_limb::Side;

/// Names of the built-in marker sets.
pub const PRESET_NAMES: [&str; 9] = [
    "gait2392",
    "opencap",
    "opencap-video",
    "jam",
    "plugin-gait",
    "plugin-gait-sacr",
    "plugin-gait-medial",
    "plugin-gait-basic",
    "rajagopal",
];

const PRESETS: [(&str, &str); 9] = [
    ("gait2392", include_str!("presets/gait2392.toml")),
    ("opencap", include_str!("presets/opencap.toml")),
    ("opencap-video", include_str!("presets/opencap-video.toml")),
    ("jam", include_str!("presets/jam.toml")),
    ("plugin-gait", include_str!("presets/plugin-gait.toml")),
    (
        "plugin-gait-sacr",
        include_str!("presets/plugin-gait-sacr.toml"),
    ),
    (
        "plugin-gait-medial",
        include_str!("presets/plugin-gait-medial.toml"),
    ),
    (
        "plugin-gait-basic",
        include_str!("presets/plugin-gait-basic.toml"),
    ),
    ("rajagopal", include_str!("presets/rajagopal.toml")),
];

/// One alternative of a medial landmark (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MedialLandmark<'a> {
    /// A marker label.
    Marker(&'a str),
    /// Plug-in Gait's chord function in the plane of this wand marker.
    Chord { wand: &'a str },
}

impl<'a> MedialLandmark<'a> {
    /// Reads one alternative: `chord:WAND` or a label.
    pub(crate) fn parse(text: &'a str) -> MedialLandmark<'a> {
        match text.strip_prefix("chord:") {
            Some(wand) => MedialLandmark::Chord { wand },
            None => MedialLandmark::Marker(text),
        }
    }

    /// The alternatives of a medial landmark field, in order.
    pub(crate) fn alternatives(field: &'a str) -> impl Iterator<Item = MedialLandmark<'a>> {
        field.split('|').map(MedialLandmark::parse)
    }

    /// The label the static trial must carry for this alternative.
    pub(crate) fn label(self) -> &'a str {
        match self {
            MedialLandmark::Marker(l) | MedialLandmark::Chord { wand: l } => l,
        }
    }
}

/// The first alternative of `field` whose label is in `labels`, else the first alternative.
fn resolve_medial(field: &str, labels: &[String]) -> String {
    let mut alts = field.split('|');
    let first = alts.next().unwrap_or(field);
    std::iter::once(first)
        .chain(alts)
        .find(|a| {
            let l = MedialLandmark::parse(a).label();
            labels.iter().any(|x| x == l)
        })
        .unwrap_or(first)
        .to_string()
}

/// A laboratory's marker labels mapped to anatomical roles (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerSet {
    pub name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    pub pelvis: PelvisMarkers,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right: Option<LegMarkers>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left: Option<LegMarkers>,
}

/// Pelvis landmarks and tracking markers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PelvisMarkers {
    pub right_asis: String,
    pub left_asis: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub right_psis: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left_psis: Option<String>,
    /// A single sacral marker; used for the pelvis frame only when there are no PSIS markers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sacrum: Option<String>,
    pub tracking: Vec<String>,
}

/// One leg's landmarks and tracking markers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegMarkers {
    pub lateral_epicondyle: String,
    pub medial_epicondyle: String,
    pub lateral_malleolus: String,
    pub medial_malleolus: String,
    pub heel: String,
    /// Toe marker or metatarsal-head markers; the foot's x axis points from the heel to their
    /// mean.
    pub forefoot: Vec<String>,
    pub thigh: Vec<String>,
    pub shank: Vec<String>,
    pub foot: Vec<String>,
}

/// The segments that carry tracking markers, in model order.
pub(crate) const TRACKED_SEGMENTS: [&str; 4] = ["pelvis", "thigh", "shank", "foot"];

impl MarkerSet {
    /// Parses and validates a marker-set TOML text; `name` (a file name) is used in errors.
    pub fn from_toml(text: &str, name: &str) -> Result<MarkerSet, LandmarkError> {
        let set: MarkerSet = toml::from_str(text).map_err(|e| LandmarkError::MarkerSetSyntax {
            source_name: name.to_string(),
            detail: e.to_string(),
        })?;
        set.validate()?;
        Ok(set)
    }

    /// A built-in marker set by name (see [`PRESET_NAMES`]).
    pub fn preset(name: &str) -> Result<MarkerSet, LandmarkError> {
        let (_, text) = PRESETS.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            LandmarkError::UnknownPreset {
                name: name.to_string(),
                available: PRESET_NAMES.join(", "),
            }
        })?;
        MarkerSet::from_toml(text, &format!("preset {name}"))
    }

    /// The set with each medial landmark's alternatives reduced to the first one the trial
    /// with these labels carries (module docs); a set without alternatives is unchanged.
    pub fn resolve(&self, labels: &[String]) -> MarkerSet {
        let mut out = self.clone();
        for leg in [out.right.as_mut(), out.left.as_mut()]
            .into_iter()
            .flatten()
        {
            leg.medial_epicondyle = resolve_medial(&leg.medial_epicondyle, labels);
            leg.medial_malleolus = resolve_medial(&leg.medial_malleolus, labels);
        }
        out
    }

    /// Whether any medial landmark may come from the chord function (module docs).
    pub fn uses_chord(&self) -> bool {
        [self.right.as_ref(), self.left.as_ref()]
            .into_iter()
            .flatten()
            .flat_map(|l| [&l.medial_epicondyle, &l.medial_malleolus])
            .any(|f| {
                MedialLandmark::alternatives(f).any(|a| matches!(a, MedialLandmark::Chord { .. }))
            })
    }

    /// Writes the set as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a marker set always serializes to TOML")
    }

    /// The markers of one leg.
    pub(crate) fn leg(&self, side: Side) -> Result<&LegMarkers, LandmarkError> {
        match side {
            Side::Right => self.right.as_ref(),
            Side::Left => self.left.as_ref(),
        }
        .ok_or_else(|| LandmarkError::NoSuchLeg {
            set: self.name.clone(),
            side: side_name(side),
        })
    }

    /// Tracking markers of `segment` (one of [`TRACKED_SEGMENTS`]) for `side`.
    pub(crate) fn tracking(&self, side: Side, segment: &str) -> Result<&[String], LandmarkError> {
        let leg = || self.leg(side);
        Ok(match segment {
            "pelvis" => &self.pelvis.tracking,
            "thigh" => &leg()?.thigh,
            "shank" => &leg()?.shank,
            "foot" => &leg()?.foot,
            _ => unreachable!("segment names come from TRACKED_SEGMENTS"),
        })
    }

    /// Every (role, label) the static trial must contain for `side`, landmarks first.
    pub fn roles(&self, side: Side) -> Result<Vec<(String, String)>, LandmarkError> {
        let leg = self.leg(side)?;
        let p = &self.pelvis;
        let mut out: Vec<(String, String)> = vec![
            ("right ASIS".into(), p.right_asis.clone()),
            ("left ASIS".into(), p.left_asis.clone()),
        ];
        let mut opt = |role: &str, label: &Option<String>| {
            if let Some(l) = label {
                out.push((role.to_string(), l.clone()));
            }
        };
        opt("right PSIS", &p.right_psis);
        opt("left PSIS", &p.left_psis);
        opt("sacrum", &p.sacrum);
        // A medial landmark with alternatives stands for its first one (see `resolve`).
        let medial = |field: &str, marker: &str, wand: &str| match MedialLandmark::alternatives(
            field,
        )
        .next()
        {
            Some(MedialLandmark::Chord { wand: w }) => (wand.to_string(), w.to_string()),
            Some(MedialLandmark::Marker(l)) => (marker.to_string(), l.to_string()),
            None => (marker.to_string(), field.to_string()),
        };
        out.push(("lateral epicondyle".into(), leg.lateral_epicondyle.clone()));
        out.push(medial(
            &leg.medial_epicondyle,
            "medial epicondyle",
            "thigh wand (knee centre by the chord function)",
        ));
        out.push(("lateral malleolus".into(), leg.lateral_malleolus.clone()));
        out.push(medial(
            &leg.medial_malleolus,
            "medial malleolus",
            "tibia wand (ankle centre by the chord function)",
        ));
        out.push(("heel".into(), leg.heel.clone()));
        for l in &leg.forefoot {
            out.push(("forefoot".into(), l.clone()));
        }
        for seg in TRACKED_SEGMENTS {
            for l in self.tracking(side, seg)? {
                out.push((format!("{seg} tracking"), l.clone()));
            }
        }
        Ok(out)
    }

    /// Checks the set's structure (not the labels of any trial).
    pub(crate) fn validate(&self) -> Result<(), LandmarkError> {
        self.validate_pelvis()?;
        if self.right.is_none() && self.left.is_none() {
            return Err(self.invalid("it has neither a [right] nor a [left] leg".into()));
        }
        // Which list holds each tracking label, over both legs (the pelvis list once): a
        // label in two lists would define one model marker twice.
        let mut owner: Vec<(String, &str)> = Vec::new();
        for side in [Side::Right, Side::Left] {
            let Ok(leg) = self.leg(side) else { continue };
            self.validate_landmarks(side, leg)?;
            self.validate_tracking(side, &mut owner)?;
        }
        self.validate_labels()
    }

    /// The error of a set whose structure is wrong.
    fn invalid(&self, detail: String) -> LandmarkError {
        LandmarkError::InvalidMarkerSet {
            set: self.name.clone(),
            detail,
        }
    }

    /// The pelvis: both PSIS or neither (then a sacrum marker), two distinct ASIS labels.
    fn validate_pelvis(&self) -> Result<(), LandmarkError> {
        let p = &self.pelvis;
        match (&p.right_psis, &p.left_psis, &p.sacrum) {
            (Some(_), None, _) | (None, Some(_), _) => {
                return Err(self.invalid(
                    "give both right_psis and left_psis, or neither (a sacrum marker alone \
                     is enough)"
                        .into(),
                ))
            }
            (None, None, None) => {
                return Err(self.invalid(
                    "the pelvis needs right_psis and left_psis, or a sacrum marker".into(),
                ))
            }
            _ => {}
        }
        if p.right_asis == p.left_asis {
            return Err(self.invalid(format!(
                "right_asis and left_asis are the same label {:?}",
                p.right_asis
            )));
        }
        Ok(())
    }

    /// A leg's landmarks: a forefoot marker, and medial landmarks other than the lateral
    /// ones, without empty or space-padded alternatives.
    fn validate_landmarks(&self, side: Side, leg: &LegMarkers) -> Result<(), LandmarkError> {
        let sn = side_name(side);
        if leg.forefoot.is_empty() {
            return Err(self.invalid(format!("{sn} forefoot lists no marker")));
        }
        for (lateral, medial) in [
            (&leg.lateral_epicondyle, &leg.medial_epicondyle),
            (&leg.lateral_malleolus, &leg.medial_malleolus),
        ] {
            for alt in MedialLandmark::alternatives(medial) {
                let l = alt.label();
                if l == lateral.as_str() {
                    return Err(self.invalid(format!(
                        "{sn} leg: the lateral and medial landmarks must be different \
                         markers"
                    )));
                }
                if l.trim().is_empty() || l.trim() != l {
                    return Err(self.invalid(format!(
                        "{sn} leg: medial landmark {medial:?} has an empty alternative or \
                         one with surrounding spaces"
                    )));
                }
            }
        }
        Ok(())
    }

    /// A leg's tracking lists: no label twice, enough markers per segment
    /// ([`min_tracking`]), and no label in two segments' lists (`owner`: the lists seen so
    /// far, the pelvis's once).
    fn validate_tracking<'s>(
        &'s self,
        side: Side,
        owner: &mut Vec<(String, &'s str)>,
    ) -> Result<(), LandmarkError> {
        let sn = side_name(side);
        for seg in TRACKED_SEGMENTS {
            if seg == "pelvis" && owner.iter().any(|(o, _)| o == "pelvis") {
                continue;
            }
            let list = self.tracking(side, seg)?;
            let mut distinct: Vec<&str> = list.iter().map(String::as_str).collect();
            distinct.sort_unstable();
            distinct.dedup();
            if distinct.len() != list.len() {
                return Err(self.invalid(format!("{sn} {seg} tracking lists a marker twice")));
            }
            let need = min_tracking(seg);
            if list.len() < need {
                let why = if seg == "pelvis" {
                    "the pelvis, the root of the chain, needs at least 3"
                } else {
                    "a leg segment needs at least 2 (the joint above fixes the rest)"
                };
                return Err(self.invalid(format!(
                    "{sn} {seg} has {} tracking marker(s) {:?}; {why}",
                    list.len(),
                    list
                )));
            }
            let here = if seg == "pelvis" {
                seg.to_string()
            } else {
                format!("{sn} {seg}")
            };
            for l in list {
                if let Some((other, _)) = owner.iter().find(|(_, m)| *m == l.as_str()) {
                    return Err(self.invalid(format!(
                        "marker {l:?} is in the tracking lists of both the {other} and the \
                         {here}; a marker can track one segment only"
                    )));
                }
                owner.push((here.clone(), l));
            }
        }
        Ok(())
    }

    /// Every role's label is non-empty and without surrounding spaces.
    fn validate_labels(&self) -> Result<(), LandmarkError> {
        let all_labels = self
            .roles(if self.right.is_some() {
                Side::Right
            } else {
                Side::Left
            })?
            .into_iter()
            .chain(if self.left.is_some() {
                self.roles(Side::Left)?
            } else {
                vec![]
            });
        for (role, label) in all_labels {
            if label.trim().is_empty() || label.trim() != label {
                return Err(self.invalid(format!(
                    "{role}: label {label:?} is empty or has surrounding spaces"
                )));
            }
        }
        Ok(())
    }
}

/// The fewest tracking markers a segment may list: 3 on the pelvis (the root, whose markers
/// alone seed its six coordinates), 2 on a leg segment (the joint to its parent fixes the
/// rotation about the line through two markers, as Plug-in Gait's thigh, shank and foot rely
/// on).
pub(crate) fn min_tracking(segment: &str) -> usize {
    if segment == "pelvis" {
        3
    } else {
        2
    }
}

pub(crate) fn side_name(side: Side) -> &'static str {
    match side {
        Side::Right => "right",
        Side::Left => "left",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_round_trip() {
        for name in PRESET_NAMES {
            let set = MarkerSet::preset(name).unwrap();
            assert_eq!(set.name, name);
            // Every preset covers both legs.
            for side in [Side::Right, Side::Left] {
                let roles = set.roles(side).unwrap();
                assert!(roles.len() >= 18, "{name} {side:?}: {}", roles.len());
            }
            let again = MarkerSet::from_toml(&set.to_toml(), "round trip").unwrap();
            assert_eq!(again, set);
        }
    }

    #[test]
    fn unknown_preset_lists_the_presets() {
        let e = MarkerSet::preset("vicon").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown marker-set preset \"vicon\"; presets: gait2392, opencap, opencap-video, jam, \
             plugin-gait, plugin-gait-sacr, plugin-gait-medial, plugin-gait-basic, rajagopal"
        );
    }

    fn edit(f: impl FnOnce(&mut MarkerSet)) -> String {
        let mut set = MarkerSet::preset("plugin-gait-medial").unwrap();
        f(&mut set);
        MarkerSet::from_toml(&set.to_toml(), "edited.toml")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn structural_errors_name_the_problem() {
        let e = edit(|s| s.right.as_mut().unwrap().thigh.truncate(1));
        assert!(e.contains("right thigh has 1 tracking marker(s)"), "{e}");
        assert!(e.contains("a leg segment needs at least 2"), "{e}");
        let e = edit(|s| s.pelvis.tracking.truncate(2));
        assert!(e.contains("pelvis has 2 tracking marker(s)"), "{e}");
        let e = edit(|s| s.pelvis.left_psis = None);
        assert!(e.contains("both right_psis and left_psis"), "{e}");
        let e = edit(|s| {
            s.pelvis.left_psis = None;
            s.pelvis.right_psis = None;
        });
        assert!(e.contains("or a sacrum marker"), "{e}");
        let e = edit(|s| s.left.as_mut().unwrap().foot.push("LANK".into()));
        assert!(
            e.contains(
                "marker \"LANK\" is in the tracking lists of both the left shank and the \
                 left foot"
            ),
            "{e}"
        );
        // One label in both legs' lists: refused when the set loads, naming both lists (it
        // was refused only at model build, as a marker defined twice).
        let e = edit(|s| {
            let r = s.right.as_ref().unwrap().thigh[0].clone();
            s.left.as_mut().unwrap().thigh.push(r);
        });
        assert!(
            e.contains("is in the tracking lists of both the right thigh and the left thigh"),
            "{e}"
        );
        let e = edit(|s| {
            let p = s.pelvis.tracking[0].clone();
            s.left.as_mut().unwrap().foot.push(p);
        });
        assert!(
            e.contains("is in the tracking lists of both the pelvis and the left foot"),
            "{e}"
        );
        let e = edit(|s| s.right.as_mut().unwrap().forefoot.clear());
        assert!(e.contains("right forefoot lists no marker"), "{e}");
        let e = edit(|s| s.right.as_mut().unwrap().heel = " RHEE".into());
        assert!(e.contains("heel: label \" RHEE\""), "{e}");
        let e = edit(|s| {
            s.right = None;
            s.left = None;
        });
        assert!(e.contains("neither a [right] nor a [left]"), "{e}");
    }

    #[test]
    fn syntax_errors_name_the_file_and_key() {
        let e = MarkerSet::from_toml("name = \"x\"\n[pelvis]\nright_asis = 3\n", "lab.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("marker set lab.toml: "), "{e}");
        assert!(e.contains("right_asis"), "{e}");
        let e = MarkerSet::from_toml(
            "name = \"x\"\n[pelvis]\nright_asis = \"a\"\nleft_asis = \"b\"\nsacrum = \"s\"\n\
             tracking = [\"a\", \"b\", \"s\"]\nknee = \"k\"\n",
            "lab.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("unknown field `knee`"), "{e}");
    }

    #[test]
    fn missing_leg_is_reported() {
        let mut set = MarkerSet::preset("jam").unwrap();
        set.left = None;
        let e = set.leg(Side::Left).unwrap_err().to_string();
        assert_eq!(e, "marker set \"jam\" has no [left] leg");
    }
}
