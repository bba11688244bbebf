//! A marker set's tracking lists cut to the markers a motion trial has.
//!
//! A static trial often carries markers that are taken off before the motion trials (the
//! lateral epicondyle and malleolus of Plug-in Gait-like protocols, medial ones always). The
//! static trial alone cannot tell which: [`super::suggest::suggest`] lets the lateral
//! landmarks track their segment. Given a motion trial, [`keep_tracked_in`] leaves out of each
//! tracking list the labels the motion trial lacks (absent, or missing in every frame), so
//! that later commands do not warn about them in every trial. A label stays in its landmark
//! role (it is still read from the static trial). A list is never cut below
//! [`super::markerset::min_tracking`]; such a label is kept and said.

use super::markerset::{min_tracking, side_name, MarkerSet, TRACKED_SEGMENTS};
use jointfit::model::lower_limb::Side;
use jointfit::trial::Trial;

/// Whether `label` has at least one sample in `trial`.
pub fn has_samples(trial: &Trial, label: &str) -> bool {
    trial
        .index_of(label)
        .map(|j| trial.gap_stats(j).0 < 1.0)
        .unwrap_or(false)
}

/// Leaves out of `set`'s tracking lists every label `present` rejects (keeping each list at
/// its minimum length); returns one sentence per list changed or kept short of it.
pub fn keep_tracked_in(set: &mut MarkerSet, present: &dyn Fn(&str) -> bool) -> Vec<String> {
    let mut notes = Vec::new();
    let mut cut = |list: &mut Vec<String>, what: String, need: usize| {
        let (kept, absent): (Vec<String>, Vec<String>) =
            list.iter().cloned().partition(|l| present(l));
        if absent.is_empty() {
            return;
        }
        if kept.len() >= need {
            notes.push(format!(
                "left out of the {what} tracking list (not in the motion trial): {}",
                absent.join(", ")
            ));
            *list = kept;
        } else {
            notes.push(format!(
                "the {what} keeps {} although the motion trial lacks it: a {what} needs at \
                 least {need} tracking markers",
                absent.join(", ")
            ));
        }
    };
    cut(
        &mut set.pelvis.tracking,
        "pelvis".into(),
        min_tracking("pelvis"),
    );
    for side in [Side::Right, Side::Left] {
        let leg = match side {
            Side::Right => set.right.as_mut(),
            Side::Left => set.left.as_mut(),
        };
        let Some(leg) = leg else { continue };
        let sn = side_name(side);
        for seg in &TRACKED_SEGMENTS[1..] {
            let list = match *seg {
                "thigh" => &mut leg.thigh,
                "shank" => &mut leg.shank,
                _ => &mut leg.foot,
            };
            cut(list, format!("{sn} {seg}"), min_tracking(seg));
        }
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Plug-in Gait without its lateral knee and ankle markers in the motion trial: they leave
    /// the thigh and shank lists (which keep 2 markers each) and stay landmarks; a list that
    /// would fall below its minimum keeps the label and says so; the result still validates.
    #[test]
    fn absent_markers_leave_the_tracking_lists() {
        let mut set = MarkerSet::preset("plugin-gait-medial").unwrap();
        let r = set.right.clone().unwrap();
        let gone = [r.lateral_epicondyle.clone(), r.lateral_malleolus.clone()];
        let before = (r.thigh.len(), r.shank.len());
        let notes = keep_tracked_in(&mut set, &|l| !gone.iter().any(|g| g == l));
        let after = set.right.clone().unwrap();
        for g in &gone {
            assert!(!after.thigh.contains(g) && !after.shank.contains(g), "{g}");
        }
        assert_eq!(after.lateral_epicondyle, r.lateral_epicondyle);
        assert_eq!(after.lateral_malleolus, r.lateral_malleolus);
        let removed = (before.0 - after.thigh.len()) + (before.1 - after.shank.len());
        let listed = gone
            .iter()
            .filter(|g| r.thigh.contains(g) || r.shank.contains(g))
            .count();
        assert_eq!(removed, listed, "{notes:?}");
        assert_eq!(notes.len(), listed.min(2), "{notes:?}");
        assert!(notes.iter().all(|n| n.contains("right")), "{notes:?}");
        MarkerSet::from_toml(&set.to_toml(), "cut.toml").unwrap();
        // Nothing present: every list keeps its markers, and each says why.
        let mut all_gone = MarkerSet::preset("plugin-gait-medial").unwrap();
        let notes = keep_tracked_in(&mut all_gone, &|_| false);
        assert_eq!(
            all_gone.to_toml(),
            MarkerSet::preset("plugin-gait-medial").unwrap().to_toml()
        );
        assert_eq!(notes.len(), 7, "{notes:?}");
        assert!(notes[0].starts_with("the pelvis keeps"), "{notes:?}");
    }
}
