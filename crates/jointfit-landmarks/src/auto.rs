//! Which marker set a static trial carries (`--markers auto`): the built-in preset whose
//! labels the trial has, else the set [`super::suggest`] proposes from its labels and
//! positions.
//!
//! Each preset is first resolved against the trial's labels (a medial landmark with
//! alternatives, such as Plug-in Gait's `RKNEM|chord:RTHI`, becomes the alternative the trial
//! carries; [`MarkerSet::resolve`]). For each leg, its *coverage* is the share of the distinct
//! labels its roles need (pelvis, landmarks, tracking) that the trial has. A preset *fits* a
//! leg when the coverage is 1. The chosen preset fits the most legs; among those, the one
//! that uses the most of the trial's labels (the more specific set: Plug-in Gait with extra
//! thigh markers over plain Plug-in Gait), then the first in [`PRESET_NAMES`] order. When no
//! preset fits both legs and the suggestion covers both, or no preset fits any leg, the
//! suggestion is returned, with the closest preset's missing labels in the reason; but when
//! no marker preset fits any leg and the trial has every keypoint of a keypoint preset
//! ([`super::keypoints`]), that keypoint set is chosen.

use super::keypoints::{fitting_preset, KeypointSet};
use super::markerset::{MarkerSet, PRESET_NAMES};
use super::suggest::suggest;
use super::LandmarkError;
use jointfit::model::lower_limb::Side;
use jointfit::trial::Trial;

/// How well one preset fits a trial's labels.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetFit {
    pub name: &'static str,
    /// Legs (right, left) whose every needed label the trial has.
    pub legs_fitted: usize,
    /// Distinct labels of both legs' roles the trial has, and how many the preset needs.
    pub present: usize,
    pub needed: usize,
    /// Needed labels the trial lacks (both legs), in role order.
    pub missing: Vec<String>,
}

/// A marker set or a keypoint set.
#[derive(Debug, Clone)]
pub enum ChosenSet {
    Markers(Box<MarkerSet>),
    Keypoints(Box<KeypointSet>),
}

/// The marker set chosen for a trial and why.
#[derive(Debug, Clone)]
pub struct AutoChoice {
    /// The preset's name, or `None` when the set was suggested.
    pub preset: Option<&'static str>,
    /// The set (a preset as written, or the suggestion).
    pub set: ChosenSet,
    /// One line: what was chosen and why.
    pub reason: String,
    /// The suggestion's notes when the set was suggested.
    pub notes: Vec<String>,
}

/// How every preset fits `labels`, best first (module docs).
pub fn rank_presets(labels: &[String]) -> Vec<PresetFit> {
    let mut fits: Vec<(usize, PresetFit)> = PRESET_NAMES
        .iter()
        .enumerate()
        .filter_map(|(k, &name)| {
            let set = MarkerSet::preset(name).ok()?.resolve(labels);
            let mut needed: Vec<String> = Vec::new();
            let mut legs_fitted = 0;
            for side in [Side::Right, Side::Left] {
                let Ok(roles) = set.roles(side) else { continue };
                if roles.iter().all(|(_, l)| labels.contains(l)) {
                    legs_fitted += 1;
                }
                for (_, l) in roles {
                    if !needed.contains(&l) {
                        needed.push(l);
                    }
                }
            }
            let (have, missing): (Vec<String>, Vec<String>) =
                needed.iter().cloned().partition(|l| labels.contains(l));
            Some((
                k,
                PresetFit {
                    name,
                    legs_fitted,
                    present: have.len(),
                    needed: needed.len(),
                    missing,
                },
            ))
        })
        .collect();
    fits.sort_by(|(ka, a), (kb, b)| {
        b.legs_fitted
            .cmp(&a.legs_fitted)
            .then(b.present.cmp(&a.present))
            .then(ka.cmp(kb))
    });
    fits.into_iter().map(|(_, f)| f).collect()
}

/// Chooses the marker set for a static trial (Y-up, metres); `name` names a suggested set.
pub fn choose(trial: &Trial, name: &str) -> Result<AutoChoice, LandmarkError> {
    let ranked = rank_presets(trial.labels());
    let best = ranked.first().cloned();
    // A preset that fits one leg only gives way to a suggestion covering both legs.
    let suggestion = match best.as_ref() {
        Some(b) if b.legs_fitted == 2 => None,
        _ => suggest(trial, name)
            .ok()
            .filter(|s| s.set.right.is_some() && s.set.left.is_some()),
    };
    if let Some(b) = best
        .as_ref()
        .filter(|b| b.legs_fitted > 0 && suggestion.is_none())
    {
        let runner = ranked
            .iter()
            .skip(1)
            .find(|f| f.name != b.name && f.present > 0)
            .map(|f| {
                format!(
                    "; next {} with {} of {} labels",
                    f.name, f.present, f.needed
                )
            })
            .unwrap_or_default();
        let legs = if b.legs_fitted == 2 {
            "both legs"
        } else {
            "one leg"
        };
        return Ok(AutoChoice {
            preset: Some(b.name),
            set: ChosenSet::Markers(Box::new(MarkerSet::preset(b.name)?)),
            reason: format!(
                "markers auto: preset {} (the trial has all {} labels it needs for {legs}{runner})",
                b.name, b.present
            ),
            notes: Vec::new(),
        });
    }
    // Video keypoints alone: the hip, knee and ankle keypoints as joint centres.
    if best.as_ref().is_none_or(|b| b.legs_fitted == 0) {
        if let Some(k) = fitting_preset(trial.labels()) {
            return Ok(AutoChoice {
                preset: Some(k),
                set: ChosenSet::Keypoints(Box::new(KeypointSet::preset(k)?)),
                reason: format!(
                    "markers auto: keypoint set {k} (no marker preset fits; the trial has \
                     every keypoint it needs, taken as joint centres)"
                ),
                notes: Vec::new(),
            });
        }
    }
    let s = match suggestion {
        Some(s) => s,
        None => suggest(trial, name)?,
    };
    let why = match best {
        Some(b) => {
            let shown: Vec<&str> = b.missing.iter().take(4).map(String::as_str).collect();
            format!(
                "no preset fits; closest {} lacks {}{}",
                b.name,
                shown.join(", "),
                if b.missing.len() > 4 { ", …" } else { "" }
            )
        }
        None => "no preset fits".into(),
    };
    Ok(AutoChoice {
        preset: None,
        set: ChosenSet::Markers(Box::new(s.set)),
        reason: format!("markers auto: the set `markers suggest` proposes ({why}): check it"),
        notes: s.notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(set: &str) -> Vec<String> {
        let s = MarkerSet::preset(set).unwrap();
        let mut out = Vec::new();
        for side in [Side::Right, Side::Left] {
            for (_, l) in s.roles(side).unwrap() {
                if !out.contains(&l) {
                    out.push(l);
                }
            }
        }
        out
    }

    #[test]
    fn every_preset_is_found_from_its_own_labels() {
        for name in PRESET_NAMES {
            let mut l = labels(name);
            l.push("C7".into());
            let best = &rank_presets(&l)[0];
            assert_eq!(best.legs_fitted, 2, "{name}");
            // A preset whose labels another one's include may lose to the richer one only if
            // that one fits as well: never to one that lacks labels.
            assert!(best.missing.is_empty(), "{name}: {best:?}");
            if !["plugin-gait-basic"].contains(&name) {
                assert_eq!(best.name, name, "{name}: {best:?}");
            }
        }
    }

    #[test]
    fn plain_plug_in_gait_needs_no_medial_markers() {
        let plain: Vec<String> = [
            "RASI", "LASI", "RPSI", "LPSI", "RTHI", "RKNE", "RTIB", "RANK", "RHEE", "RTOE", "LTHI",
            "LKNE", "LTIB", "LANK", "LHEE", "LTOE",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let best = &rank_presets(&plain)[0];
        assert_eq!((best.name, best.legs_fitted), ("plugin-gait", 2));
        let mut one_leg = plain.clone();
        one_leg.retain(|l| !l.starts_with('L') || l == "LASI" || l == "LPSI");
        let best = &rank_presets(&one_leg)[0];
        assert_eq!((best.name, best.legs_fitted), ("plugin-gait", 1));
        assert!(best.missing.contains(&"LTHI".to_string()), "{best:?}");
    }
}
