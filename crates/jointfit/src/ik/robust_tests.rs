//! Solvability from the chain, holding undetermined coordinates, and gross-error rejection,
//! against synthetic truth and the explicit marker Jacobian.

use crate::ik::trial_fit::solve_trial;
use crate::ik::{FrameStatus, IkOptions, MarkerMap};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::trial::Trial;
use nalgebra::{DMatrix, Vector3};

use super::tests::synthetic_trial;

fn right_leg() -> (Model, Vec<f64>) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    (model, p)
}

/// Sets the named markers missing in frames `frames`.
fn drop_markers(trial: &mut Trial, names: &[&str], frames: std::ops::Range<usize>) {
    let n = trial.labels().len();
    let cols: Vec<usize> = names.iter().map(|l| trial.index_of(l).unwrap()).collect();
    let pos = trial.positions_mut();
    for f in frames {
        for &c in &cols {
            pos[f * n + c] = Vector3::repeat(f64::NAN);
        }
    }
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
}

/// Smallest singular value of the column-normalised marker Jacobian at `q` over the present
/// markers (rows of `present`) and the coordinates in `cols`: an oracle built from the
/// explicit Jacobian, independent of the solver's moment form and generic configuration.
fn min_singular(model: &Model, p: &[f64], q: &[f64], present: &[bool], cols: &[usize]) -> f64 {
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::Dq, &mut kin);
    let jq = kin.jq;
    let rows: Vec<usize> = (0..model.markers().len())
        .filter(|&j| present[j])
        .flat_map(|j| 3 * j..3 * j + 3)
        .collect();
    let mut j = DMatrix::from_fn(rows.len(), cols.len(), |r, c| jq[(rows[r], cols[c])]);
    for mut c in j.column_iter_mut() {
        let norm = c.norm();
        if norm > 0.0 {
            c /= norm;
        }
    }
    j.singular_values().min()
}

/// A sparse case: pelvis 2, thigh 2, shank 1, foot 2 markers in every frame.
/// The joints carry the rest, so every frame is solved, exactly (noiseless data).
#[test]
fn sparse_segments_are_solved_through_the_chain() {
    let (model, p) = right_leg();
    let (mut trial, truth) = synthetic_trial(&model, &p, 30, 0.3);
    let gone = [
        "RPSI", "LPSI", "RTHP", "RKNE", "RTIA", "RTIP", "RANK", "RMT5",
    ];
    drop_markers(&mut trial, &gone, 0..30);
    // Oracle: the explicit Jacobian of the present markers has full rank at the truth.
    let present: Vec<bool> = model
        .markers()
        .iter()
        .map(|m| !gone.contains(&m.name.as_str()))
        .collect();
    let all: Vec<usize> = (0..model.coordinates().len()).collect();
    assert!(min_singular(&model, &p, &truth[7], &present, &all) > 1e-3);
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    for (f, fr) in fit.frames.iter().enumerate() {
        assert_eq!(fr.status, FrameStatus::Converged, "frame {f}");
        assert!(close(&fit.coords[f], &truth[f], 1e-7), "frame {f}");
    }
    assert!(fit.unsolved_ranges().is_empty());
}

/// A pelvis with one marker: rotation about the line from that marker to the hip centre is
/// free. The named coordinate is one the explicit Jacobian cannot determine (rank
/// deficient), and holding it fixed leaves a full-rank problem. Unsolved frames come back as
/// one range.
#[test]
fn undetermined_coordinate_is_named_and_ranged() {
    let (model, p) = right_leg();
    let (mut trial, truth) = synthetic_trial(&model, &p, 20, 0.0);
    let gone = ["LASI", "RPSI", "LPSI"];
    drop_markers(&mut trial, &gone, 5..9);
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    let ranges = fit.unsolved_ranges();
    assert_eq!(ranges.len(), 1, "{ranges:?}");
    assert_eq!((ranges[0].first, ranges[0].last), (5, 8));
    let FrameStatus::Undetermined { coordinate } = &fit.frames[6].status else {
        panic!("{:?}", fit.frames[6].status);
    };
    assert_eq!(ranges[0].reason, format!("{coordinate} undetermined"));
    assert!(fit.coords[6].iter().all(|v| v.is_nan()));
    let named = model.coord_id(coordinate).unwrap();
    let present: Vec<bool> = model
        .markers()
        .iter()
        .map(|m| !gone.contains(&m.name.as_str()))
        .collect();
    let all: Vec<usize> = (0..model.coordinates().len()).collect();
    let rest: Vec<usize> = all.iter().copied().filter(|&c| c != named).collect();
    assert!(min_singular(&model, &p, &truth[6], &present, &all) < 1e-8);
    assert!(min_singular(&model, &p, &truth[6], &present, &rest) > 1e-3);
    // The frames around the gap are solved exactly.
    assert!(close(&fit.coords[4], &truth[4], 1e-7));
    assert!(close(&fit.coords[9], &truth[9], 1e-7));
}

/// With the hold option, frames without foot markers are solved: the foot's coordinates
/// stay exactly at the last solved frame's values, every other coordinate is exact.
#[test]
fn holding_undetermined_coordinates_at_the_previous_frame() {
    let (model, p) = right_leg();
    let (mut trial, truth) = synthetic_trial(&model, &p, 20, 0.0);
    drop_markers(&mut trial, &["RHEE", "RTOE", "RMT5"], 10..15);
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let skip = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    assert_eq!(skip.frames.iter().filter(|f| !f.solved()).count(), 5);
    let opts = IkOptions {
        hold_undetermined: true,
        ..IkOptions::default()
    };
    let fit = solve_trial(&model, &p, &trial, &map, &opts).unwrap();
    let foot = [
        model.coord_id("ankle_dorsiflexion").unwrap(),
        model.coord_id("subtalar_inversion").unwrap(),
    ];
    for f in 10..15 {
        assert!(fit.frames[f].solved(), "frame {f}");
        let mut held = fit.frames[f].held.clone();
        held.sort();
        assert_eq!(held, foot, "frame {f}");
        for (c, got) in fit.coords[f].iter().enumerate() {
            let want = if foot.contains(&c) {
                truth[9][c]
            } else {
                truth[f][c]
            };
            assert!((got - want).abs() < 1e-7, "frame {f} coord {c}");
        }
    }
    assert!(fit.frames[15].held.is_empty());
    assert!(close(&fit.coords[16], &truth[16], 1e-7));
}

/// Gross errors: a 1e18 m sample, an infinite one and a marker 0.5 m off. Each is rejected
/// and reported; every frame is still solved exactly, and so are the frames after.
#[test]
fn gross_samples_are_rejected_and_reported() {
    let (model, p) = right_leg();
    let (mut trial, truth) = synthetic_trial(&model, &p, 40, 0.0);
    let n = trial.labels().len();
    let (thi, tib, hee) = (
        trial.index_of("RTHI").unwrap(),
        trial.index_of("RTIB").unwrap(),
        trial.index_of("RHEE").unwrap(),
    );
    let pos = trial.positions_mut();
    pos[10 * n + thi].x = 1e18;
    pos[20 * n + tib] += Vector3::new(0.5, 0.0, 0.0);
    pos[25 * n + hee].y = f64::INFINITY;
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    let index = |name: &str| model.markers().iter().position(|m| m.name == name).unwrap();
    assert_eq!(fit.frames[10].rejected, vec![index("RTHI")]);
    assert_eq!(fit.frames[20].rejected, vec![index("RTIB")]);
    assert_eq!(fit.frames[25].rejected, vec![index("RHEE")]);
    for (f, q) in truth.iter().enumerate() {
        assert!(fit.frames[f].solved(), "frame {f}");
        assert!(close(&fit.coords[f], q, 1e-7), "frame {f}");
        assert!(
            crate::ik::trial_fit::rms(fit.errors[f].iter().copied()) < 1e-9,
            "frame {f}"
        );
        if ![10, 20, 25].contains(&f) {
            assert!(fit.frames[f].rejected.is_empty(), "frame {f}");
        }
    }
    assert!(fit.errors[20][index("RTIB")].is_nan());
    // Without rejection (infinite outlier distance), the 0.5 m marker drags the frame far
    // beyond the others (exact, RMS 0): no start does better, so it is not reported solved.
    let plain = IkOptions {
        outlier_distance: f64::INFINITY,
        ..IkOptions::default()
    };
    let dragged = solve_trial(&model, &p, &trial, &map, &plain).unwrap();
    let FrameStatus::Implausible { rms, median } = dragged.frames[20].status else {
        panic!("{:?}", dragged.frames[20].status);
    };
    assert!(rms > 0.05 && median < 1e-9, "{rms} {median}");
    assert!(dragged.coords[20].iter().all(|v| v.is_nan()));
    let ranges = dragged.unsolved_ranges();
    assert_eq!(ranges.len(), 1, "{ranges:?}");
    assert_eq!((ranges[0].first, ranges[0].last), (20, 20));
    for f in (0..40).filter(|&f| f != 20) {
        assert!(close(&dragged.coords[f], &truth[f], 1e-7), "frame {f}");
    }
}
