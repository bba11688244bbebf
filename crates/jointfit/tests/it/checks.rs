//! Data checks against synthetic trials with known defects (and a clean one with none).

use jointfit::checks::{check_scale, check_trial, CheckKind, Severity};
use jointfit::ik::MarkerMap;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::trial::Trial;
use nalgebra::Vector3;

use super::ik::synthetic_trial;

fn setup() -> (Model, Trial) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let (trial, _) = synthetic_trial(&model, &p, 60, 0.2);
    (model, trial)
}

fn kinds(model: &Model, trial: &Trial) -> Vec<(CheckKind, String)> {
    let map = MarkerMap::by_name(model, trial.labels()).unwrap();
    check_trial(model, trial, &map)
        .into_iter()
        .map(|f| (f.kind, f.message))
        .collect()
}

#[test]
fn a_clean_trial_has_no_findings() {
    let (model, trial) = setup();
    assert!(kinds(&model, &trial).is_empty());
    assert!(check_scale(&trial).is_none());
}

/// Millimetre numbers read as metres: an error naming the factor and the fix.
#[test]
fn millimetres_declared_as_metres_is_an_error() {
    let (_, trial) = setup();
    let scaled: Vec<Vector3<f64>> = trial.positions().iter().map(|p| p * 1e3).collect();
    let mm = Trial::new(trial.labels().to_vec(), trial.rate(), 1, scaled).unwrap();
    let f = check_scale(&mm).unwrap();
    assert_eq!(f.severity, Severity::Error);
    assert!(
        f.message
            .contains("millimetre data read as metres: declare the units as mm"),
        "{}",
        f.message
    );
}

/// `trial` with its samples replaced by `positions` (frame-major).
fn with_positions(trial: &Trial, positions: Vec<Vector3<f64>>) -> Trial {
    let labels = trial.labels().to_vec();
    Trial::new(labels, trial.rate(), trial.first_frame(), positions).unwrap()
}

/// Labels of two thigh markers exchanged from frame 41 (file numbering from 1) to the end.
#[test]
fn swapped_labels_are_found_with_their_frames() {
    let (model, trial) = setup();
    let (a, b) = (
        trial.index_of("RTHI").unwrap(),
        trial.index_of("RTHA").unwrap(),
    );
    let n = trial.labels().len();
    let mut pos = trial.positions().to_vec();
    for f in 40..60 {
        pos.swap(f * n + a, f * n + b);
    }
    let trial = with_positions(&trial, pos);
    let found = kinds(&model, &trial);
    let swaps: Vec<&String> = found
        .iter()
        .filter(|(k, _)| *k == CheckKind::Swap)
        .map(|(_, m)| m)
        .collect();
    assert_eq!(swaps.len(), 1, "{found:?}");
    assert!(
        swaps[0].starts_with("RTHI and RTHA look swapped in frames 41–60"),
        "{}",
        swaps[0]
    );
}

/// A thigh marker 20 mm from where the subject model has it in every frame (re-attached):
/// cluster findings name it, and only it.
#[test]
fn a_moved_cluster_marker_is_found() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let mut moved = lower_limb(Side::Right);
    let k = moved.markers.iter().position(|m| m.name == "RTHP").unwrap();
    moved.markers[k].position[1] += 0.02;
    let moved = Model::compile(&moved).unwrap();
    let (trial, _) = synthetic_trial(&moved, &moved.nominal_params(), 60, 0.2);
    let found = kinds(&model, &trial);
    let clusters: Vec<&String> = found
        .iter()
        .filter(|(k, _)| *k == CheckKind::Cluster)
        .map(|(_, m)| m)
        .collect();
    assert!(!clusters.is_empty(), "{found:?}");
    assert!(clusters.iter().all(|m| m.contains("RTHP")), "{clusters:?}");
    assert!(
        found.iter().all(|(k, _)| *k == CheckKind::Cluster),
        "{found:?}"
    );
}

/// A 0.5 m spike in one frame and a 5-frame gap.
#[test]
fn jumps_and_gaps_are_counted() {
    let (model, trial) = setup();
    let (tib, toe) = (
        trial.index_of("RTIB").unwrap(),
        trial.index_of("RTOE").unwrap(),
    );
    let n = trial.labels().len();
    let mut pos = trial.positions().to_vec();
    pos[20 * n + tib].x += 0.5;
    for f in 10..15 {
        pos[f * n + toe] = Vector3::repeat(f64::NAN);
    }
    let trial = with_positions(&trial, pos);
    let found = kinds(&model, &trial);
    let jump = found.iter().find(|(k, _)| *k == CheckKind::Jump).unwrap();
    assert_eq!(
        jump.1,
        "RTIB jumps faster than 30 m/s in 2 frames (first: frame 21)"
    );
    let gap = found.iter().find(|(k, _)| *k == CheckKind::Gaps).unwrap();
    assert_eq!(
        gap.1,
        "RTOE is missing in 5 of 60 frames (1 gaps; longest frames 11–15)"
    );
}
