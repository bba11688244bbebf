//! `jointfit calibrate MODEL.osim TRIAL --joints ... -o OUT.osim` end to end, OpenSim 4.6 as
//! the oracle (`crates/jointfit-cli/assets/osim_check.py`): on the OpenCap hand-scaled full-body model with
//! walking1 (hip_r, walker_knee_r) and on the gait2354 subject01 model with its walk (hip_r,
//! knee_r), the written file differs from the input only in `<translation>`/`<orientation>`
//! lines of the named joints and holds exactly the reported fitted values; OpenSim loads it
//! with every body, force and muscle and puts every marker where jointfit does (1e-9 m) at
//! random poses. A parameter pair reported redundant is shown redundant by OpenSim itself,
//! and unknown names are one-line errors listing the joints.

use std::path::{Path, PathBuf};

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::spec::{AxisMotion, AxisSpec, JointKindSpec};
use jointfit::model::Model;
use jointfit_io::osim_read::{read_osim, write_back, Side};
use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use super::jointfit;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The data files, or `None` (skipped) without data.
fn files(model: &str, trial: &str) -> Option<(PathBuf, PathBuf)> {
    let m = jointfit_testkit::data_file(model);
    let t = jointfit_testkit::data_file(trial);
    match (m, t) {
        (Some(m), Some(t)) => Some((m, t)),
        _ => {
            assert!(!jointfit_testkit::in_ci(), "CI needs $JOINTFIT_DATA");
            eprintln!("skipped: no data");
            None
        }
    }
}

/// OpenSim's `fk` answer for `model` at `poses` of the coordinates `names`.
fn opensim_fk(model: &Path, names: &[String], poses: &[Vec<f64>]) -> Option<Value> {
    let Some(python) = jointfit_testkit::python() else {
        assert!(!jointfit_testkit::in_ci(), "CI needs $JOINTFIT_PYTHON");
        eprintln!("skipped: no OpenSim");
        return None;
    };
    let req = json!({"model": model, "coordinates": names, "poses": poses});
    Some(jointfit_testkit::script::osim_check(
        &python, "fk", &req, None,
    ))
}

/// Random poses of a read model (free and coupled coordinates, in that order, with names)
/// and jointfit's marker positions there.
fn poses_and_markers(model: &Model, seed: u64) -> (Vec<String>, Vec<Vec<f64>>, Vec<KinData>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let coupled: Vec<usize> = (0..model.dependents().len())
        .filter(|&i| {
            matches!(
                model.dependents()[i].rule,
                jointfit::model::custom::CoordRule::Coupled { .. }
            )
        })
        .collect();
    let mut names: Vec<String> = model.coordinates().iter().map(|c| c.name.clone()).collect();
    names.extend(coupled.iter().map(|&i| model.dependents()[i].name.clone()));
    let mut poses = Vec::new();
    let mut kins = Vec::new();
    let mut kin = KinData::new(model);
    for _ in 0..3 {
        let q: Vec<f64> = model
            .coordinates()
            .iter()
            .map(|c| {
                let lo = c.range[0].max(c.default - 0.5);
                let hi = c.range[1].min(c.default + 0.5);
                if lo < hi {
                    rng.gen_range(lo..hi)
                } else {
                    c.default
                }
            })
            .collect();
        forward_kinematics(model, &[], &q, Want::Positions, &mut kin);
        kins.push(kin.clone());
        let mut full = q.clone();
        full.extend(coupled.iter().map(|&i| model.dependents()[i].value(&q)));
        poses.push(full);
    }
    (names, poses, kins)
}

/// Largest |OpenSim − jointfit| marker coordinate (m) over the poses.
fn worst_marker(model: &Model, kins: &[KinData], answer: &Value) -> f64 {
    let theirs: Vec<&str> = answer["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    let mut worst = 0.0f64;
    for (k, kin) in kins.iter().enumerate() {
        for (m, marker) in model.markers().iter().enumerate() {
            let j = theirs.iter().position(|n| *n == marker.name).unwrap();
            for a in 0..3 {
                let t = answer["positions"][k][j][a].as_f64().unwrap();
                worst = worst.max((kin.markers[m][a] - t).abs());
            }
        }
    }
    worst
}

/// One personalization: calibrate, then every check of the module docs.
fn personalize_and_check(model_file: &str, trial_file: &str, joints: &[&str]) {
    let Some((input, trial)) = files(model_file, trial_file) else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-personalize");
    let out = dir.path().join("personalized.osim");
    let list = joints.join(",");
    let (ok, stdout, err) = jointfit(&[
        "calibrate",
        s(&input),
        s(&trial),
        "--joints",
        &list,
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(ok, "{err}");
    let report: Value = serde_json::from_str(&stdout).expect("JSON");
    // Ball-joint (hip) offset orientations are absorbed by the hip's three coordinates.
    let held: Vec<&str> = report["held_redundant"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| h["parameter"].as_str().unwrap())
        .collect();
    for side in ["parent", "child"] {
        for r in ["rx", "ry", "rz"] {
            let name = format!("hip_r.{side}.{r}");
            assert!(held.contains(&name.as_str()), "{name} not held: {held:?}");
        }
    }
    eprintln!(
        "{model_file}: {} free, held {held:?}, RMS {:.2} → {:.2} mm, {:.3} s",
        report["free_parameters"],
        report["rms_before_mm"],
        report["rms_after_mm"],
        report["seconds"]
    );

    // Only translation/orientation lines of the named joints changed.
    only_offsets_of_changed(&input, &out, joints);

    // The file holds the reported fitted values; held parameters keep the input's.
    let before = read_osim(&input).unwrap();
    let after = read_osim(&out).unwrap();
    for row in report["parameters"].as_array().unwrap() {
        let name = row["name"].as_str().unwrap();
        let (joint, side, k) = offset_slot(name);
        let scale = if k < 3 {
            1e3
        } else {
            180.0 / std::f64::consts::PI
        };
        let written = after.site(joint, side).unwrap().value[k] * scale;
        let fitted = row["fitted"].as_f64().unwrap();
        assert!(
            (written - fitted).abs() < 1e-9 * fitted.abs().max(1.0),
            "{name}: {written} vs {fitted}"
        );
    }
    for h in &held {
        let (joint, side, k) = offset_slot(h);
        assert_eq!(
            after.site(joint, side).unwrap().value[k],
            before.site(joint, side).unwrap().value[k],
            "{h}"
        );
    }

    // OpenSim loads it, keeps every body, force and muscle, and agrees on the markers.
    let model = Model::compile(&after.spec).unwrap();
    let (names, poses, kins) = poses_and_markers(&model, 14);
    let Some(theirs) = opensim_fk(&out, &names, &poses) else {
        return;
    };
    let Some(original) = opensim_fk(&input, &names, &[]) else {
        return;
    };
    for key in ["bodies", "forces", "muscles"] {
        assert_eq!(theirs[key], original[key], "{key}");
    }
    assert!(theirs["muscles"].as_u64().unwrap() > 0);
    let worst = worst_marker(&model, &kins, &theirs);
    eprintln!(
        "OpenSim vs jointfit on the written model: {worst:.1e} m; {} muscles, {} forces kept",
        theirs["muscles"], theirs["forces"]
    );
    assert!(worst <= 1e-9, "{worst}");
}

/// `joint`, frame side and index (tx, ty, tz, rx, ry, rz) of an offset parameter named
/// `joint.parent.rx` or `joint.child.tx`.
fn offset_slot(name: &str) -> (&str, Side, usize) {
    let parts: Vec<&str> = name.split('.').collect();
    let side = if parts[1] == "parent" {
        Side::Parent
    } else {
        Side::Child
    };
    let k = ["tx", "ty", "tz", "rx", "ry", "rz"]
        .iter()
        .position(|x| *x == parts[2])
        .unwrap();
    (parts[0], side, k)
}

/// `out` differs from `input` only in `<translation>` and `<orientation>` lines of the
/// named joints, and in at least one.
fn only_offsets_of_changed(input: &Path, out: &Path, joints: &[&str]) {
    let old = std::fs::read_to_string(input).unwrap();
    let new = std::fs::read_to_string(out).unwrap();
    let changed = jointfit_testkit::osim_text::changed_offset_lines(&old, &new, joints);
    assert!(!changed.is_empty(), "nothing changed");
    eprintln!("{} lines changed", changed.len());
}

#[test]
fn osim_calibrate_opencap_hip_and_walker_knee() {
    personalize_and_check(
        "opencap_expert1/hand_scaled.osim",
        "opencap_expert1/walking1.trc",
        &["hip_r", "walker_knee_r"],
    );
}

#[test]
fn osim_calibrate_gait2354_subject01_hip_and_knee() {
    personalize_and_check(
        "opensim_gait2392_subject01/subject01_simbody.osim",
        "opensim_gait2392_subject01/subject01_walk1.trc",
        &["hip_r", "knee_r"],
    );
}

/// The pin ankle: jointfit holds the child translation as redundant with the parent's, and
/// OpenSim confirms the redundancy: moving both offsets by 10 mm along the pin axis (in
/// each body's frame) leaves every marker where it was at random poses (1e-9 m).
#[test]
fn osim_calibrate_holds_the_pin_axis_translation_pair() {
    let Some((input, trial)) = files(
        "opensim_gait2392_subject01/subject01_simbody.osim",
        "opensim_gait2392_subject01/subject01_walk1.trc",
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-redundant");
    let out = dir.path().join("ankle.osim");
    let (ok, stdout, err) = jointfit(&[
        "calibrate",
        s(&input),
        s(&trial),
        "--params",
        "ankle_r.parent.translation,ankle_r.child.translation",
        "--prior",
        "none",
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(ok, "{err}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    let held = report["held_redundant"].as_array().unwrap();
    assert_eq!(held.len(), 1, "{held:?}");
    assert_eq!(held[0]["parameter"], "ankle_r.child.tz");
    assert!(held[0]["with"]
        .as_array()
        .unwrap()
        .iter()
        .any(|w| w == "ankle_r.parent.tz"));
    assert_eq!(report["free_parameters"], 5);

    // The oracle: shift both offsets along the pin axis in the input file.
    let osim = read_osim(&input).unwrap();
    let joint = osim
        .spec
        .joints
        .iter()
        .find(|j| j.name == "ankle_r")
        .unwrap();
    let JointKindSpec::Custom { axes } = &joint.kind else {
        panic!("ankle_r is not a custom joint");
    };
    let moving: Vec<_> = axes
        .iter()
        .filter(|a| a.coordinate.is_some() && a.motion == AxisMotion::Rotation)
        .collect();
    assert_eq!(moving.len(), 1, "a pin");
    let AxisSpec::Vector(v) = moving[0].axis.clone() else {
        panic!("axis as a vector");
    };
    let axis = Vector3::from(v).normalize();
    let shifted = |side: Side| -> [f64; 6] {
        let o = osim.site("ankle_r", side).unwrap().value;
        // OpenSim's orientation: body-fixed X-Y-Z.
        let r = Rotation3::from_axis_angle(&Vector3::x_axis(), o[3])
            * Rotation3::from_axis_angle(&Vector3::y_axis(), o[4])
            * Rotation3::from_axis_angle(&Vector3::z_axis(), o[5]);
        let d = r * axis * 0.01;
        [o[0] + d.x, o[1] + d.y, o[2] + d.z, o[3], o[4], o[5]]
    };
    let text = write_back(
        &osim,
        &[
            ("ankle_r", Side::Parent, shifted(Side::Parent)),
            ("ankle_r", Side::Child, shifted(Side::Child)),
        ],
        &[],
    )
    .unwrap();
    let moved = dir.path().join("moved.osim");
    std::fs::write(&moved, text).unwrap();
    let model = Model::compile(&osim.spec).unwrap();
    let (names, poses, _) = poses_and_markers(&model, 3);
    let (Some(a), Some(b)) = (
        opensim_fk(&input, &names, &poses),
        opensim_fk(&moved, &names, &poses),
    ) else {
        return;
    };
    let mut worst = 0.0f64;
    for (pa, pb) in a["positions"]
        .as_array()
        .unwrap()
        .iter()
        .zip(b["positions"].as_array().unwrap())
    {
        for (ma, mb) in pa.as_array().unwrap().iter().zip(pb.as_array().unwrap()) {
            for k in 0..3 {
                worst = worst.max((ma[k].as_f64().unwrap() - mb[k].as_f64().unwrap()).abs());
            }
        }
    }
    eprintln!("OpenSim: markers moved by {worst:.1e} m when both ankle offsets slide 10 mm along the axis");
    assert!(worst <= 1e-9, "{worst}");
}

#[test]
fn osim_calibrate_bad_names_are_one_line_errors() {
    let Some((input, trial)) = files(
        "opensim_gait2392_subject01/subject01_simbody.osim",
        "opensim_gait2392_subject01/subject01_walk1.trc",
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-bad-names");
    let out = dir.path().join("x.osim");
    for (flag, value, needle) in [
        (
            "--joints",
            "hip_r,kne_r",
            "no joint \"kne_r\"; its joints: ground_pelvis, hip_r, knee_r",
        ),
        (
            "--params",
            "knee_r.middle",
            "\"middle\" is not parent or child",
        ),
        (
            "--params",
            "knee_r.child.translation.w",
            "\"w\" is not x, y or z",
        ),
        ("--joints", "all", "nothing selected"),
    ] {
        let (ok, stdout, err) = jointfit(&[
            "calibrate",
            s(&input),
            s(&trial),
            flag,
            value,
            "-o",
            s(&out),
        ]);
        assert!(!ok, "{flag} {value}");
        assert!(stdout.is_empty(), "{stdout}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{err}");
        assert!(!out.exists());
    }
}

/// `-o OUT.toml` writes the parameterized jointfit model at the fitted values.
#[test]
fn osim_calibrate_to_toml() {
    let Some((input, trial)) = files(
        "opensim_gait2392_subject01/subject01_simbody.osim",
        "opensim_gait2392_subject01/subject01_walk1.trc",
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-toml");
    let out = dir.path().join("fitted.toml");
    let (ok, stdout, err) = jointfit(&[
        "calibrate",
        s(&input),
        s(&trial),
        "--params",
        "knee_r.child.translation.y",
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(ok, "{err}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    let model = jointfit_io::model_file::load_model(s(&out)).unwrap();
    assert_eq!(model.parameters().len(), 1);
    let p = &model.parameters()[0];
    assert_eq!(p.name, "knee_r.child.ty");
    assert!((p.nominal * 1e3 - report["parameters"][0]["fitted"].as_f64().unwrap()).abs() < 1e-9);
    assert_eq!(
        p.prior_sd,
        Some(jointfit_io::osim_read::personalize::TRANSLATION_PRIOR_SD)
    );
}
