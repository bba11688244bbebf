//! Marker placement of a model against a trial ([`jointfit::placement`]): a trial made from
//! the model itself matches; a trial of another build (marker positions scaled on two
//! segments), labels exchanged between segments, another unit, and a marker moved far are
//! each told apart, with the known size of the change.

use jointfit::ik::MarkerMap;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::placement::{compare, Mismatch, Placement};
use jointfit::trial::Trial;
use nalgebra::Vector3;

use super::ik::synthetic_trial;

fn leg() -> Model {
    Model::compile(&lower_limb(Side::Right)).unwrap()
}

/// The trial of `model_made` at its nominal parameters, compared with `model`.
fn placement_of(model: &Model, trial: &Trial) -> Placement {
    let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
    compare(model, trial, &map)
}

fn trial_of(model: &Model) -> Trial {
    synthetic_trial(model, &model.nominal_params(), 80, 0.3).0
}

#[test]
fn the_models_own_trial_matches_exactly() {
    let model = leg();
    let p = placement_of(&model, &trial_of(&model));
    assert!((p.ratio - 1.0).abs() < 1e-9, "{}", p.ratio);
    for s in &p.segments {
        assert!((s.ratio - 1.0).abs() < 1e-9 || s.ratio.is_nan(), "{s:?}");
        assert!(s.change.abs() < 1e-9 || s.change.is_nan(), "{s:?}");
    }
    assert!(p.markers.iter().all(|m| m.change < 1e-9));
    assert_eq!(p.mismatch(), None);
}

/// Another person: the thigh's and shank's markers 15 % further apart (local positions
/// scaled about the segment origin, which scales every distance within the segment by
/// exactly 1.15).
#[test]
fn another_build_is_named_with_its_segment_and_size() {
    let model = leg();
    let mut spec = model.spec().clone();
    for m in spec.markers.iter_mut() {
        if m.segment == "thigh" || m.segment == "shank" {
            m.position = m.position.map(|x| 1.15 * x);
        }
    }
    let other = Model::compile(&spec).unwrap();
    let p = placement_of(&model, &trial_of(&other));
    for s in p
        .segments
        .iter()
        .filter(|s| s.segment == "thigh" || s.segment == "shank")
    {
        assert!((s.ratio - 1.15).abs() < 1e-9, "{s:?}");
    }
    match p.mismatch() {
        Some(Mismatch::Build { segments }) => {
            let names: Vec<&str> = segments.iter().map(|s| s.0.as_str()).collect();
            assert!(
                names.contains(&"thigh") && names.contains(&"shank"),
                "{names:?}"
            );
        }
        other => panic!("expected another build, got {other:?}"),
    }
    // The same change on one segment only, small enough to be soft tissue (2 %): accepted.
    let mut spec = model.spec().clone();
    for m in spec.markers.iter_mut().filter(|m| m.segment == "thigh") {
        m.position = m.position.map(|x| 1.02 * x);
    }
    let close = Model::compile(&spec).unwrap();
    assert_eq!(placement_of(&model, &trial_of(&close)).mismatch(), None);
}

/// A thigh and a shank marker with each other's labels: both named, the gross one first.
#[test]
fn labels_exchanged_between_segments_are_a_marker_mismatch() {
    let model = leg();
    let trial = trial_of(&model);
    let mut labels = trial.labels().to_vec();
    let a = labels.iter().position(|l| l == "RTHI").unwrap();
    let b = labels.iter().position(|l| l == "RTIB").unwrap();
    labels.swap(a, b);
    let swapped = Trial::new(labels, trial.rate(), 1, trial.positions().to_vec()).unwrap();
    match placement_of(&model, &swapped).mismatch() {
        Some(Mismatch::Markers { markers }) => {
            let names: Vec<&str> = markers.iter().map(|m| m.0.as_str()).collect();
            assert!(
                names.contains(&"RTHI") && names.contains(&"RTIB"),
                "{names:?}"
            );
            assert!(markers[0].1 > jointfit::placement::GROSS);
        }
        other => panic!("expected a marker mismatch, got {other:?}"),
    }
}

/// Centimetres read as millimetres: every distance ×0.1, named as units.
#[test]
fn another_unit_is_a_units_mismatch_with_its_factor() {
    let model = leg();
    let trial = trial_of(&model);
    let scaled: Vec<Vector3<f64>> = trial.positions().iter().map(|p| p * 0.1).collect();
    let cm = Trial::new(trial.labels().to_vec(), trial.rate(), 1, scaled).unwrap();
    match placement_of(&model, &cm).mismatch() {
        Some(Mismatch::Units { ratio }) => assert!((ratio - 0.1).abs() < 1e-9, "{ratio}"),
        other => panic!("expected units, got {other:?}"),
    }
}

/// One marker re-attached 20 mm away is ordinary (the calibration's marker policy handles
/// it); moved 150 mm, its label names another place. The marker moves in its segment, away
/// from the centroid of the segment's other markers.
#[test]
fn one_marker_moved_far_is_a_mismatch_and_a_re_attached_one_is_not() {
    let model = leg();
    let moved = |by: f64| {
        let mut spec = model.spec().clone();
        let k = spec.markers.iter().position(|m| m.name == "RTHA").unwrap();
        let others: Vec<Vector3<f64>> = spec
            .markers
            .iter()
            .filter(|m| m.segment == "thigh" && m.name != "RTHA")
            .map(|m| Vector3::from(m.position))
            .collect();
        let centroid = others.iter().sum::<Vector3<f64>>() / others.len() as f64;
        let at = Vector3::from(spec.markers[k].position);
        let to = at + by * (at - centroid).normalize();
        spec.markers[k].position = [to.x, to.y, to.z];
        trial_of(&Model::compile(&spec).unwrap())
    };
    assert_eq!(placement_of(&model, &moved(0.02)).mismatch(), None);
    match placement_of(&model, &moved(0.15)).mismatch() {
        Some(Mismatch::Markers { markers }) => assert_eq!(markers[0].0, "RTHA"),
        other => panic!("expected a marker mismatch, got {other:?}"),
    }
}
