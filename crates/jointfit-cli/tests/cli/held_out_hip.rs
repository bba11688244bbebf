//! Held-out check on a shared trial that carries the lab's own hip centre:
//! default `personalize` + `calibrate` must leave the hip centre
//! (a) medial to the ASIS: lateral offset ≤ 0.9 × half the inter-ASIS distance;
//! (b) no further from the lab's hip centre than the landmark model's was, + 5 mm;
//! (c) with a marker RMS at least 15 % below the landmark model's.
//!
//! The lab's estimate is OpenCap Expert1's `R_HJC`/`L_HJC`: a functional (pelvis–thigh
//! common point) centre from the lab's own hip calibration trials, written into every trial as
//! a virtual marker that moves with the four pelvis markers (`notebook/gait_table.md`). The `opencap`
//! preset does not use it, so the landmark model is independent of it. Per frame it is put in
//! the pelvis markers' frame (origin mid-ASIS, z from left to right ASIS, y normal to the
//! ASIS–mid-PSIS plane) and carried into the model's pelvis frame by the same construction
//! on the model's own pelvis marker positions; the mean over frames is the lab's centre.
//! Every number is computed here from the written models, the JSON and the trial, none is
//! hard-coded.

use std::path::Path;

use jointfit::model::spec::ModelSpec;
use jointfit::trial::Trial;
use jointfit_io::model_file::load_spec;
use jointfit_io::trial_file::read_trial;
use jointfit_testkit::script::script_path;
use jointfit_testkit::{data_file, scratch};
use nalgebra::{Matrix3, Vector3};

use super::jointfit;

/// Right ASIS, left ASIS, right PSIS, left PSIS of OpenCap and of OpenSim's Vicon walks.
const OPENCAP_PELVIS: [&str; 4] = ["r.ASIS", "L.ASIS", "r.PSIS", "L.PSIS"];
const VICON_PELVIS: [&str; 4] = ["RASI", "LASI", "RPSI", "LPSI"];

/// Origin and axes (columns: anterior, superior, right) of the pelvis markers' frame.
fn pelvis_frame(p: [Vector3<f64>; 4]) -> (Vector3<f64>, Matrix3<f64>) {
    let origin = (p[0] + p[1]) / 2.0;
    let z = (p[0] - p[1]).normalize();
    let y = z.cross(&(origin - (p[2] + p[3]) / 2.0)).normalize();
    (origin, Matrix3::from_columns(&[y.cross(&z), y, z]))
}

fn marker(spec: &ModelSpec, name: &str) -> Vector3<f64> {
    let m = spec.markers.iter().find(|m| m.name == name).unwrap();
    assert_eq!(m.segment, "pelvis", "{name}");
    Vector3::from(m.position)
}

fn nominal(spec: &ModelSpec, name: &str) -> f64 {
    spec.parameters
        .iter()
        .find(|p| p.name == name)
        .unwrap()
        .nominal
}

/// The model's hip centre in its pelvis frame, (anterior, superior, lateral) in m.
fn hip_centre(spec: &ModelSpec) -> Vector3<f64> {
    Vector3::new(
        nominal(spec, "hip_pelvis_anterior"),
        nominal(spec, "hip_pelvis_superior"),
        nominal(spec, "hip_pelvis_lateral"),
    )
}

/// Mean of the trial's `label` in the model's pelvis frame, (anterior, superior, lateral).
fn lab_centre(
    spec: &ModelSpec,
    trial: &Trial,
    pelvis: [&str; 4],
    label: &str,
    lateral: f64,
) -> Vector3<f64> {
    let (om, rm) = pelvis_frame(pelvis.map(|n| marker(spec, n)));
    let cols = pelvis.map(|n| trial.index_of(n).unwrap());
    let h = trial.index_of(label).unwrap();
    let mut sum = Vector3::zeros();
    let mut n = 0;
    for f in 0..trial.n_frames() {
        let (Some(hjc), [Some(a), Some(b), Some(c), Some(d)]) =
            (trial.get(f, h), cols.map(|k| trial.get(f, k)))
        else {
            continue;
        };
        let (ot, rt) = pelvis_frame([a, b, c, d]);
        sum += om + rm * (rt.transpose() * (hjc - ot));
        n += 1;
    }
    assert!(n >= 100, "{label}: present in {n} frames");
    let mean = sum / n as f64;
    Vector3::new(mean.x, mean.y, lateral * mean.z)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Personalizes `side` (extra `personalize` arguments `how`), calibrates `walk` with the
/// defaults and returns (fit → lab distance, landmark → lab distance, fitted lateral offset,
/// its limit 0.9 × half the inter-ASIS distance, lab centre's lateral offset, RMS before,
/// RMS after), lengths in m, RMS in mm.
fn held_out(
    dir: &Path,
    walk: &Path,
    how: &[&str],
    side: &str,
    pelvis: [&str; 4],
    label: &str,
) -> [f64; 7] {
    let stem = walk.file_stem().unwrap().to_string_lossy();
    let landmark = dir.join(format!("{stem}-{side}.toml"));
    let fitted = dir.join(format!("{stem}-{side}-fit.toml"));
    let mut args = vec!["personalize", "--side", side, "-o", s(&landmark)];
    args.extend_from_slice(how);
    let (ok, _, err) = jointfit(&args);
    assert!(ok, "{stem} {side}: {err}");
    let (ok, out, err) = jointfit(&[
        "calibrate",
        s(&landmark),
        s(walk),
        "--filter",
        "6",
        "--json",
        "-o",
        s(&fitted),
    ]);
    assert!(ok, "{stem} {side}: {err}");
    let rep: serde_json::Value = serde_json::from_str(&out).unwrap();
    let start = load_spec(s(&landmark)).unwrap();
    let fit = load_spec(s(&fitted)).unwrap();
    let trial = read_trial(walk).unwrap();
    let lateral = if side == "right" { 1.0 } else { -1.0 };
    let lab = lab_centre(&fit, &trial, pelvis, label, lateral);
    let d0 = (hip_centre(&start) - lab_centre(&start, &trial, pelvis, label, lateral)).norm();
    let d1 = (hip_centre(&fit) - lab).norm();
    let half_width = (marker(&fit, pelvis[0]) - marker(&fit, pelvis[1])).norm() / 2.0;
    println!(
        "{stem} {side}: landmark → {label} {:.1} mm, fit → {label} {:.1} mm",
        d0 * 1e3,
        d1 * 1e3
    );
    [
        d1,
        d0,
        hip_centre(&fit).z,
        0.9 * half_width,
        lab.z,
        rep["rms_before_mm"].as_f64().unwrap(),
        rep["rms_after_mm"].as_f64().unwrap(),
    ]
}

fn assert_b_c(what: &str, r: [f64; 7]) {
    let [d1, d0, _, _, _, before, after] = r;
    // (b) no further from the lab's centre than the landmark model's, + 5 mm.
    assert!(
        d1 <= d0 + 0.005,
        "{what} (b): fit {:.1} mm from the lab's centre, landmark model {:.1} mm",
        d1 * 1e3,
        d0 * 1e3
    );
    // (c) the markers fit at least 15 % better than with the landmark model.
    assert!(
        after <= 0.85 * before,
        "{what} (c): RMS {before:.2} → {after:.2} mm"
    );
}

fn assert_a(what: &str, r: [f64; 7]) {
    let [_, _, lat, limit, ..] = r;
    assert!(
        lat <= limit,
        "{what} (a): hip centre {:.1} mm lateral, limit {:.1} mm",
        lat * 1e3,
        limit * 1e3
    );
}

#[test]
fn default_calibration_passes_the_held_out_hip_check_on_opencap_walking2() {
    let (Some(stat), Some(walk)) = (
        data_file("opencap_expert1/static1.trc"),
        data_file("opencap_expert1/walking2.trc"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("held-out-hip");
    let how = ["--static", s(&stat), "--markers", "opencap"];
    for (side, label) in [("right", "R_HJC"), ("left", "L_HJC")] {
        let r = held_out(&dir, &walk, &how, side, OPENCAP_PELVIS, label);
        assert_a(side, r);
        assert_b_c(side, r);
    }
}

/// Sit-to-stand: the correlated thigh artefact of deep flexion concentrates on the hip
/// centre (its robust-to-white variance ratio ≈ 4 × the trial's), which a single trial-wide
/// correlation factor let the fit move 23 mm lateral, to the limit of (a); the per-parameter
/// inflation of the prior weight (`calibrate::uncertainty::parameter_inflation`) holds it.
#[test]
fn default_calibration_passes_the_held_out_hip_check_on_opencap_sit_to_stand() {
    let (Some(stat), Some(walk)) = (
        data_file("opencap_expert1/static1.trc"),
        data_file("opencap_expert1/STS1.trc"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("held-out-hip-sts");
    let how = ["--static", s(&stat), "--markers", "opencap"];
    let r = held_out(&dir, &walk, &how, "right", OPENCAP_PELVIS, "R_HJC");
    assert_a("STS1 right", r);
    assert_b_c("STS1 right", r);
}

/// OpenSim's Vicon walk (no static trial: the model comes from the walk's own stillest
/// 0.02 s, `notebook/frames_solved.md`). Its `RHJC` (a computed marker, present in the last
/// third, rigid with the pelvis markers) lies ≈ 50 mm from the landmark estimate and at the
/// ASIS's own lateral offset (inter-ASIS 198 mm), so (a)'s envelope, built from the same
/// ASIS markers, does not hold for the lab's own centre: the test asserts that fact and
/// (a), (b), (c) for the fit. Without the anatomical envelope the default fit went to
/// 91.1 mm against the limit 88.5 mm; with it (`workflow::envelope`), and the check
/// measuring the width on the fitted model's ASIS markers, (a) holds.
#[test]
fn default_calibration_moves_toward_the_lab_hip_centre_on_opensim_walking2() {
    let Some(walk) = data_file("c3d_reader/opensim/walking2.c3d") else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("held-out-hip-c3d");
    let set = script_path("markersets/opensim_test_walks.toml");
    let how = [
        "--static",
        s(&walk),
        "--markers",
        s(&set),
        "--window",
        "0.02",
    ];
    let r = held_out(&dir, &walk, &how, "right", VICON_PELVIS, "RHJC");
    let [_, _, _, limit, lab, ..] = r;
    assert!(
        lab > 0.95 * limit,
        "the lab's RHJC is {:.1} mm lateral, (a) limit {:.1} mm",
        lab * 1e3,
        limit * 1e3
    );
    assert_a("walking2.c3d right", r);
    assert_b_c("walking2.c3d right", r);
}

/// The trials where one marker or a cluster sits differently than in the static trial
/// (walkingTO1 right: r_thigh3/r_thigh5 re-attached; walking1 left: the thigh cluster moved
/// about 110 mm): without the marker policy (c) failed (3 % and 1 %); the policy refines those
/// markers only (`workflow::marker_policy`), and (a), (b), (c) hold.
#[test]
fn default_calibration_passes_the_held_out_hip_check_with_a_moved_marker() {
    let (Some(stat), Some(to1), Some(w1)) = (
        data_file("opencap_expert1/static1.trc"),
        data_file("opencap_expert1/walkingTO1.trc"),
        data_file("opencap_expert1/walking1.trc"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("held-out-hip-moved");
    let how = ["--static", s(&stat), "--markers", "opencap"];
    for (walk, side, label) in [(&to1, "right", "R_HJC"), (&w1, "left", "L_HJC")] {
        let r = held_out(&dir, walk, &how, side, OPENCAP_PELVIS, label);
        assert_a(side, r);
        assert_b_c(side, r);
    }
}
