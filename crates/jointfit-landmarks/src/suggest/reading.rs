//! The static trial read once: the frames with the most markers present and each labelled
//! marker's median position over them (stage 1 of the parent module's docs).

use nalgebra::Vector3;

use super::labels::{automatic_label, has, normalize, IGNORE, IGNORE_EXACT};
use jointfit::trial::Trial;

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

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A raw marker: label, normalized label, the side its label names, median position.
pub(super) type Raw = (String, String, Option<f64>, Vector3<f64>);

/// Every labelled marker present in most of the frames read, at its median position; the
/// others are said in `notes` (stage 1 of the module docs). Also the labels missing in most
/// frames.
pub(super) fn read_markers(trial: &Trial, notes: &mut Vec<String>) -> (Vec<Raw>, Vec<String>) {
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
