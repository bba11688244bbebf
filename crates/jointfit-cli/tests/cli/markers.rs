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

/// gait2392 subject01: the static trial has lateral knee and ankle markers the walk lacks.
/// Without `--motion` the suggested set tracks with them and its comments say so; with
/// `--motion WALK` they leave the tracking lists (staying landmarks), the subject
/// personalized from that set is fitted to the walk by `ik` with no warning about absent
/// markers, and "wrote" goes to stdout like every other command's.
#[test]
fn motion_trial_drops_static_only_tracking_markers() {
    let (Some(stat), Some(walk)) = (
        data_file("opensim_gait2392_subject01/subject01_static.trc"),
        data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let dir = scratch("markers-motion");
    let (plain, cut) = (dir.join("plain.toml"), dir.join("cut.toml"));
    let (ok, out, err) = jointfit(&["markers", "suggest", &s(&stat), "-o", &s(&plain)]);
    assert!(ok, "{err}");
    assert!(
        out.contains("wrote ") && !err.contains("wrote "),
        "{out}\n{err}"
    );
    let text = std::fs::read_to_string(&plain).unwrap();
    assert!(text.contains("pass --motion TRIAL"), "{text}");
    // Every label of the legs' thigh and shank tracking lists.
    let lists = |t: &str| -> String {
        let set = jointfit_landmarks::markerset::MarkerSet::from_toml(t, "suggested").unwrap();
        let mut all = Vec::new();
        for leg in [&set.right, &set.left].into_iter().flatten() {
            all.extend(leg.thigh.iter().chain(&leg.shank).cloned());
        }
        all.join(",")
    };
    assert!(lists(&text).contains("R.Knee.Lat"), "{text}");
    let (ok, _, err) = jointfit(&[
        "markers",
        "suggest",
        &s(&stat),
        "--motion",
        &s(&walk),
        "-o",
        &s(&cut),
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&cut).unwrap();
    for lat in ["R.Knee.Lat", "R.Ankle.Lat", "L.Knee.Lat", "L.Ankle.Lat"] {
        assert!(!lists(&text).contains(lat), "{lat}\n{text}");
    }
    assert!(
        text.contains("lateral_epicondyle = \"R.Knee.Lat\""),
        "{text}"
    );
    assert!(text.contains("not in the motion trial"), "{text}");
    let subject = dir.join("subject.toml");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        &s(&stat),
        "--markers",
        &s(&cut),
        "-o",
        &s(&subject),
    ]);
    assert!(ok, "{err}\n{text}");
    let (ok, _, err) = jointfit(&[
        "ik",
        &s(&subject),
        &s(&walk),
        "-o",
        &s(&dir.join("walk.mot")),
    ]);
    assert!(ok, "{err}");
    assert!(!err.contains(".Lat"), "{err}");
}

/// Plug-in Gait files carry computed outputs (angles, powers) and virtual segment axes
/// (`RFEO`, `RTIP`, …) as 3D points. Before, `markers suggest` on c3d.org's gait-pig.c3d
/// proposed `RHipPower` as the heel and `RFEO` as the medial epicondyle, and `personalize`
/// accepted the set. Now neither kind is a candidate: the file has no medial knee marker, so
/// the suggestion is refused in one line, naming the missing knee pair.
#[test]
fn plug_in_gait_outputs_are_never_landmarks() {
    let Some(pig) = data_file("c3d_reader/c3dorg/sample_03/gait-pig.c3d") else {
        return;
    };
    let dir = scratch("markers-pig");
    let out = dir.join("pig.toml");
    let (ok, _, err) = jointfit(&[
        "markers",
        "suggest",
        pig.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok, "{err}");
    assert!(!out.exists());
    let errors: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("jointfit: error:"))
        .collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(errors[0].contains("knee markers"), "{err}");
    assert!(err.contains("segment axes"), "{err}");
    for output in ["Power", "Angles", "RFEO", "RTIP"] {
        assert!(!err.contains(&format!("chose {output}")), "{err}");
    }
}
