//! The moved-cluster check (`jointfit::checks::offsets`) on synthetic trials with skin-artifact
//! noise: the truth is the marker displacement seeded into the data.

use jointfit::checks::offsets::{check_offsets, marker_offsets};
use jointfit::checks::{check_trial, CheckKind};
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_testkit::synth::{self, Noise};

use super::ik::motion;

/// The right-leg model, and a 150-frame trial with skin noise (≤ 8 mm per axis, seed 11) of
/// the same model with the markers named in `moved` shifted by `by` (m, thigh frame).
fn trial_with(moved: &[&str], by: [f64; 3]) -> (Model, Trial) {
    trial_of(moved, by, 150)
}

/// [`trial_with`] with `frames` frames.
fn trial_of(moved: &[&str], by: [f64; 3], frames: usize) -> (Model, Trial) {
    let spec = lower_limb(Side::Right);
    let model = Model::compile(&spec).unwrap();
    let mut shifted = spec.clone();
    for m in &mut shifted.markers {
        if moved.contains(&m.name.as_str()) {
            for (x, d) in m.position.iter_mut().zip(by) {
                *x += d;
            }
        }
    }
    let truth = Model::compile(&shifted).unwrap();
    let p = truth.nominal_params();
    let s = synth::synthetic_trial(
        &truth,
        &p,
        frames,
        100.0,
        |f| motion(&truth, f, 0.3),
        Noise::Skin { amplitude: 0.008 },
        11,
    );
    (model, s.trial)
}

fn offsets_found(model: &Model, trial: &Trial) -> Vec<String> {
    let map = MarkerMap::by_name(model, trial.labels()).unwrap();
    check_trial(model, trial, &map)
        .into_iter()
        .filter(|f| f.kind == CheckKind::Offset)
        .map(|f| f.message)
        .collect()
}

#[test]
fn a_clean_noisy_trial_has_no_offsets() {
    let (model, trial) = trial_with(&[], [0.0; 3]);
    assert!(offsets_found(&model, &trial).is_empty());
    // The statistic itself: every marker's mean residual well below the threshold.
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let p = model.nominal_params();
    for o in marker_offsets(&model, &p, &trial, &map, &IkOptions::default(), None) {
        assert!(o.mean.norm() < 0.01, "{o:?}");
        assert_eq!(o.frames, 150);
    }
}

/// The three thigh cluster markers moved 80 mm forward and 40 mm down the thigh: one finding
/// naming the thigh cluster, its size within the IK's absorption of the true 89 mm.
#[test]
fn a_moved_thigh_cluster_is_named() {
    let (model, trial) = trial_with(&["RTHI", "RTHA", "RTHP"], [0.08, -0.04, 0.0]);
    let found = offsets_found(&model, &trial);
    // The IK pulls the pelvis towards the moved cluster: a pelvis marker may be named too,
    // never the shank or the foot.
    assert!(
        found
            .iter()
            .all(|m| !m.contains("shank") && !m.contains("foot")),
        "{found:?}"
    );
    let msg = found
        .iter()
        .find(|m| m.starts_with("the thigh cluster ("))
        .unwrap_or_else(|| panic!("{found:?}"));
    for name in ["RTHI", "RTHA", "RTHP"] {
        assert!(msg.contains(name), "{msg}");
    }
    assert!(msg.contains("the subject model (static trial)"), "{msg}");
    let mm: f64 = msg
        .split(" sits ")
        .nth(1)
        .and_then(|s| s.split(" mm").next())
        .unwrap()
        .parse()
        .unwrap();
    assert!((30.0..=100.0).contains(&mm), "{msg}");
}

/// One marker moved 50 mm: a finding for that marker alone, no other marker flagged.
#[test]
fn one_moved_marker_is_named_alone() {
    let (model, trial) = trial_with(&["RTHA"], [0.0, 0.0, 0.05]);
    let found = offsets_found(&model, &trial);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("thigh: RTHA sits "), "{}", found[0]);
}

/// The reference is named after the file for a model read from an OpenSim file.
#[test]
fn an_osim_model_is_the_reference() {
    let mut spec = lower_limb(Side::Right);
    spec.description = format!(
        "{}/data/gait2392.osim",
        jointfit::checks::offsets::OSIM_DESCRIPTION
    );
    let model = Model::compile(&spec).unwrap();
    let (plain, trial) = trial_with(&["RTHI", "RTHA", "RTHP"], [0.08, -0.04, 0.0]);
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let f = check_offsets(&model, &trial, &map, None);
    assert!(
        f[0].message.contains("in the model (gait2392.osim)"),
        "{f:?}"
    );
    let f = check_offsets(&plain, &trial, &map, None);
    assert!(
        f[0].message.contains("in the subject model (static trial)"),
        "{f:?}"
    );
}
