//! Trials a calibration can learn nothing from, refused before the fit with their cause
//! (every front end: the command line's `calibrate`, batches and Python).

use jointfit::model::Model;
use jointfit::trial::Trial;

/// A trial a calibration can learn nothing from is refused with its cause: fewer than two
/// frames, or no marker moving (every marker within `STILL_M` of its first present sample in
/// every frame, e.g. two identical frames or a copy of one frame).
pub fn check_motion(name: &str, trial: &Trial) -> Result<(), String> {
    const STILL_M: f64 = 1e-6;
    let shown = name;
    let n = trial.n_frames();
    if n < 2 {
        return Err(format!(
            "{shown}: {n} frame{}: a calibration needs a motion, at least two frames (and \
             many more for a useful fit)",
            if n == 1 { "" } else { "s" }
        ));
    }
    // Each marker against its own first present sample (a walk may start with gaps).
    let mut first: Vec<Option<nalgebra::Vector3<f64>>> = vec![None; trial.labels().len()];
    let moves = (0..n).any(|f| {
        trial.frame(f).iter().zip(first.iter_mut()).any(|(p, q)| {
            if p.x.is_nan() {
                return false;
            }
            match q {
                None => {
                    *q = Some(*p);
                    false
                }
                Some(q) => (p - *q).norm() > STILL_M,
            }
        })
    });
    if !moves {
        return Err(format!(
            "{shown}: no marker moves more than {} mm in its {n} frames: a still trial says \
             nothing about the joints (use a motion trial; a static trial is for personalize)",
            STILL_M * 1e3
        ));
    }
    Ok(())
}

/// Why no frame of `trial` can be fitted by `model`, when the cause is plain from the labels
/// and samples alone, as one error naming markers: no model marker among the trial's labels
/// (with the labels that differ only in case or by a `prefix:` or `prefix_` named), or every
/// model marker the trial holds missing in every frame.
pub fn check_markers(name: &str, trial: &Trial, model: &Model) -> Result<(), String> {
    let shown = name;
    let names: Vec<&str> = model.markers().iter().map(|m| m.name.as_str()).collect();
    let labels = trial.labels();
    let present: Vec<usize> = labels
        .iter()
        .enumerate()
        .filter(|(_, l)| names.contains(&l.as_str()))
        .map(|(i, _)| i)
        .collect();
    if present.is_empty() {
        let near: Vec<String> = labels
            .iter()
            .filter_map(|l| near_name(l, &names).map(|n| format!("{l} ({n}?)")))
            .take(6)
            .collect();
        if !near.is_empty() {
            return Err(format!(
                "{shown}: none of the model's {} markers is labelled as the model names it; \
                 labels that differ only in case or by a prefix: {}",
                names.len(),
                near.join(", ")
            ));
        }
        return Err(format!(
            "{shown}: none of the model's {} markers ({}) is in the trial, whose labels are {}",
            names.len(),
            list(&names),
            list(&labels.iter().map(String::as_str).collect::<Vec<_>>())
        ));
    }
    let sampled = present
        .iter()
        .any(|&m| (0..trial.n_frames()).any(|f| !trial.frame(f)[m].x.is_nan()));
    if !sampled {
        let held: Vec<&str> = present.iter().map(|&m| labels[m].as_str()).collect();
        return Err(format!(
            "{shown}: the model's markers in the trial ({}) are missing in all {} frames",
            list(&held),
            trial.n_frames()
        ));
    }
    Ok(())
}

/// The model marker `label` names up to letter case or a `prefix:` / `prefix_`.
fn near_name<'a>(label: &str, names: &[&'a str]) -> Option<&'a str> {
    let stripped = label.rsplit([':', '_']).next().unwrap_or(label);
    names.iter().copied().find(|n| {
        n.eq_ignore_ascii_case(label)
            || n.eq_ignore_ascii_case(stripped)
            || label
                .to_ascii_lowercase()
                .ends_with(&n.to_ascii_lowercase())
    })
}

/// The first names of a list, with how many more.
fn list(names: &[&str]) -> String {
    const SHOWN: usize = 8;
    if names.len() <= SHOWN {
        return names.join(", ");
    }
    format!("{}, … ({} in all)", names[..SHOWN].join(", "), names.len())
}
