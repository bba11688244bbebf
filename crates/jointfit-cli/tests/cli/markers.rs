//! `jointfit markers suggest`: on the static trial of every lab in the shared data, the
//! proposed marker set is accepted by `personalize` for both legs, and names the landmarks
//! the lab's own preset names.

use jointfit_testkit::{data_file, scratch};

use super::jointfit;

#[test]
fn suggested_sets_personalize_on_every_lab() {
    // (static trial, expected right-leg epicondyles and malleoli: lateral, medial)
    let labs = [
        (
            "opencap_expert1/static1.trc",
            ["r_knee", "r_mknee", "r_ankle", "r_mankle"],
        ),
        (
            "opensim_gait2392_subject01/subject01_static.trc",
            ["R.Knee.Lat", "R.Knee.Med", "R.Ankle.Lat", "R.Ankle.Med"],
        ),
        (
            "opensim_hamner_subject02/subject02_static.trc",
            ["R.Knee.Lat", "R.Knee.Med", "R.Ankle.Lat", "R.Ankle.Med"],
        ),
        (
            "opensim_jam_healthy/static1.trc",
            ["R.Knee", "R.Mkn", "R.Ankle", "R.Man"],
        ),
        (
            "biobuddy_functional_vicon/anatomical_posture.c3d",
            ["RKNE", "RKNEM", "RANK", "RANKM"],
        ),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            ["RKNE", "RKNEM", "RANK", "RANKM"],
        ),
        (
            "c3d_reader/ezc3d/Qualisys.c3d",
            ["R_FLE", "R_FME", "R_FAL", "R_TAM"],
        ),
    ];
    for (rel, [lat_knee, med_knee, lat_ank, med_ank]) in labs {
        let Some(stat) = data_file(rel) else {
            println!("skipped: no data");
            return;
        };
        let dir = scratch("markers-suggest");
        let set = dir.join("set.toml");
        let (ok, _, err) = jointfit(&[
            "markers",
            "suggest",
            stat.to_str().unwrap(),
            "-o",
            set.to_str().unwrap(),
        ]);
        assert!(ok, "{rel}: {err}");
        assert!(!err.contains("fails"), "{rel}: {err}");
        let text = std::fs::read_to_string(&set).unwrap();
        for (role, label) in [
            ("lateral_epicondyle", lat_knee),
            ("medial_epicondyle", med_knee),
            ("lateral_malleolus", lat_ank),
            ("medial_malleolus", med_ank),
        ] {
            assert!(
                text.contains(&format!("{role} = \"{label}\"")),
                "{rel}: {role}\n{text}"
            );
        }
        for side in ["right", "left"] {
            let (ok, _, err) = jointfit(&[
                "personalize",
                "--static",
                stat.to_str().unwrap(),
                "--markers",
                set.to_str().unwrap(),
                "--side",
                side,
                "-o",
                dir.join(format!("{side}.toml")).to_str().unwrap(),
            ]);
            assert!(ok, "{rel} {side}: {err}\n{text}");
        }
    }
}

#[test]
fn a_trial_without_pelvis_labels_is_one_line() {
    let Some(trial) = data_file("c3d_reader/ezc3d/Vicon.c3d") else {
        println!("skipped: no data");
        return;
    };
    let (ok, _, err) = jointfit(&["markers", "suggest", trial.to_str().unwrap()]);
    assert!(!ok);
    assert!(err.contains("cannot suggest a marker set"), "{err}");
    assert_eq!(
        err.lines().filter(|l| l.contains("error")).count(),
        1,
        "{err}"
    );
}

/// A lab that sends only a Plug-in Gait walk (BTK's Gait.c3d: Z up, every marker missing in
/// 60 % of the frames, a sacral marker instead of PSIS, two tracking markers per thigh and
/// shank): `markers suggest` reads the frames where the markers are, proposes a set that
/// names the lab's epicondyles and malleoli, `personalize` accepts it for both legs from the
/// walk's stillest stretch, and `check` reports no label swap (the pelvis has only the two
/// ASIS and the sacrum: a mirror-symmetric pair that no distance tells from its swap) and
/// the markers' shared gaps in one finding, not one per marker.
#[test]
fn a_walk_without_a_static_trial_gets_a_marker_set_and_no_false_swaps() {
    let Some(walk) = data_file("c3d_reader/btk/Gait.c3d") else {
        println!("skipped: no data");
        return;
    };
    let walk = walk.to_str().unwrap();
    let dir = scratch("markers-walk");
    let set = dir.join("set.toml");
    let (ok, _, err) = jointfit(&["markers", "suggest", walk, "-o", set.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(err.contains("up axis detected: z"), "{err}");
    let text = std::fs::read_to_string(&set).unwrap();
    for line in [
        "right_asis = \"RASI\"",
        "sacrum = \"VSAC\"",
        "lateral_epicondyle = \"RKNE\"",
        "lateral_malleolus = \"LANK\"",
        "heel = \"RHEE\"",
    ] {
        assert!(text.contains(line), "{line}\n{text}");
    }
    let subject = dir.join("subject.toml");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        walk,
        "--markers",
        set.to_str().unwrap(),
        "--window",
        "0.02",
        "-o",
        subject.to_str().unwrap(),
    ]);
    assert!(ok, "{err}\n{text}");
    let (ok, out, err) = jointfit(&["check", subject.to_str().unwrap(), walk, "--json"]);
    assert!(ok, "{err}");
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let text = report.to_string();
    assert!(!text.contains("swapped"), "{text}");
    // The markers leave the capture volume together: one gaps finding names them all.
    let gaps: Vec<&str> = report["read"]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["kind"] == "gaps")
        .map(|c| c["message"].as_str().unwrap())
        .collect();
    assert!(!gaps.is_empty() && gaps.len() <= 3, "{gaps:?}");
    assert!(
        gaps.iter()
            .any(|g| g.contains("RASI, LASI, VSAC") && g.contains("are each missing")),
        "{gaps:?}"
    );
}
