//! Plug-in Gait (CGM 1) without medial markers on a Vicon Nexus session (`pig_pycgm`): the
//! hip, knee and ankle centres from the subject measurements against the ones Vicon's
//! Plug-in Gait stored in the same static trial (RFEP/LFEP hip, RFEO/LFEO knee, RTIO/LTIO
//! ankle centres), averaged over the static window.

use std::path::Path;

use jointfit_testkit::{data_file, scratch};
use serde_json::Value;

use super::jointfit;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Distances (mm) of `--compare-jc` by joint key, from the JSON summary.
fn distances(json: &str) -> Vec<(String, f64)> {
    let v: Value = serde_json::from_str(json).unwrap();
    v["joint_centre_comparison"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["joint"].as_str().unwrap().to_string(),
                c["distance_mm"].as_f64().unwrap(),
            )
        })
        .collect()
}

fn check_vicon_centres(rows: &[(String, f64)], what: &str) {
    assert_eq!(rows.len(), 6, "{what}: {rows:?}");
    for (joint, d) in rows {
        // Goal: 1.5 mm of Vicon's hip centres, 2.5 mm of its knee and ankle centres.
        let limit = if joint.starts_with("hip") { 1.5 } else { 2.5 };
        assert!(*d < limit, "{what}: {joint} {d:.3} mm from Vicon's");
    }
}

#[test]
fn plug_in_gait_matches_vicon_joint_centres() {
    let (Some(stat), Some(vsk)) = (
        data_file("pig_pycgm/Static_trial.c3d"),
        data_file("pig_pycgm/Test.vsk"),
    ) else {
        println!("skipped: no pig_pycgm data");
        return;
    };
    let dir = scratch("pig");
    let out = dir.join("pig.toml");
    let compare = "hip=RFEP,knee=RFEO,ankle=RTIO";
    // Measurements from the C3D's PROCESSING group; --markers auto picks plugin-gait.
    let (ok, json, err) = jointfit(&[
        "personalize",
        s(&stat),
        "--compare-jc",
        compare,
        "--json",
        "-o",
        s(&out),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("markers auto: preset plugin-gait (the trial has all 16 labels"),
        "{err}"
    );
    let rows = distances(&json);
    check_vicon_centres(&rows, "PROCESSING");
    let v: Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        v["legs"][0]["hip_method"],
        "Davis et al. 1991 (Plug-in Gait)"
    );
    // The centres in the file's own lab frame (Z up): the hips about 0.7 m up, the ankles
    // about 0.1 m, the right leg at smaller lab y than the left in this session.
    let c = &v["joint_centres_lab_mm"];
    for (k, z) in [("hip_r", 706.0), ("knee_r", 285.0), ("ankle_r", 101.0)] {
        let got = c[k][2].as_f64().unwrap().abs();
        assert!((got - z).abs() < 5.0, "{k}: {c}");
    }
    assert!(c["hip_r"][1].as_f64().unwrap() < c["hip_l"][1].as_f64().unwrap());

    // The same from a TRC copy (no PROCESSING group) with the .vsk.
    let trc = dir.join("static.trc");
    let (ok, _, err) = jointfit(&["convert", s(&stat), s(&trc), "--decimals", "6"]);
    assert!(ok, "{err}");
    let args = |extra: &[&str]| {
        let mut a = vec!["personalize", s(&trc), "--markers", "plugin-gait", "--json"];
        a.extend_from_slice(extra);
        a.extend_from_slice(&["-o", s(&out)]);
        a.iter().map(|x| x.to_string()).collect::<Vec<_>>()
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        jointfit(&a)
    };
    let (ok, json, err) = run(args(&["--subject", s(&vsk), "--compare-jc", compare]));
    assert!(ok, "{err}");
    check_vicon_centres(&distances(&json), ".vsk");

    // Without measurements: one line naming what is missing and how to give it.
    let (ok, _, err) = run(args(&[]));
    assert!(!ok);
    let line = err.lines().last().unwrap();
    assert!(
        line.contains(
            "the right knee centre by Plug-in Gait's chord function (marker set \
             \"plugin-gait\" has no medial knee marker) needs the subject's right knee width, \
             which was not given (give it with --subject NAME=MM"
        ),
        "{err}"
    );
    // Command-line values override the file's: a 20 mm wider right knee moves the right
    // knee centre 10 mm medially, away from Vicon's.
    let (ok, json, err) = run(args(&[
        "--subject",
        s(&vsk),
        "--subject",
        "knee_width_r=159",
        "--compare-jc",
        "knee=RFEO",
    ]));
    assert!(ok, "{err}");
    let rows = distances(&json);
    let right = rows.iter().find(|(j, _)| j == "knee_r").unwrap().1;
    assert!((right - 10.0).abs() < 1.0, "{rows:?}");
    let left = rows.iter().find(|(j, _)| j == "knee_l").unwrap().1;
    assert!(left < 2.5, "{rows:?}");
    let (ok, _, err) = run(args(&["--subject", "knee_width=100"]));
    assert!(!ok);
    assert!(
        err.contains("unknown subject measurement \"knee_width\""),
        "{err}"
    );
}
