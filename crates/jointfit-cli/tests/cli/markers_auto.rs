//! `personalize` without `--markers` (`--markers auto`): on every shared laboratory's static
//! trial the preset of that laboratory is chosen and said in one line; labels no preset
//! knows fall back to the set `markers suggest` proposes.

use std::path::Path;

use jointfit_testkit::{data_file, scratch};

use super::jointfit;

fn auto(stat: &Path, out: &Path) -> (bool, String) {
    let (ok, _, err) = jointfit(&[
        "personalize",
        stat.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    (ok, err)
}

/// A TRC copy of `rel` with labels renamed in its label row (`(from, to)` pairs).
fn renamed(rel: &str, dir: &Path, pairs: &[(&str, &str)]) -> Option<std::path::PathBuf> {
    let text = std::fs::read_to_string(data_file(rel)?).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut labels: Vec<String> = lines[3].split('\t').map(str::to_string).collect();
    for (from, to) in pairs {
        let k = labels.iter().position(|l| l == from).unwrap();
        labels[k] = to.to_string();
    }
    lines[3] = labels.join("\t");
    let path = dir.join(rel.replace('/', "_"));
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    Some(path)
}

#[test]
fn each_lab_gets_its_preset() {
    let dir = scratch("auto");
    let out = dir.join("s.toml");
    let mut ran = 0;
    for (rel, preset) in [
        ("opencap_expert1/static1.trc", "opencap"),
        ("opencap_video_subject0/neutral.trc", "opencap-video"),
        (
            "opensim_gait2392_subject01/subject01_static.trc",
            "gait2392",
        ),
        ("opensim_hamner_subject02/subject02_static.trc", "gait2392"),
        ("opensim_jam_healthy/static1.trc", "jam"),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-medial",
        ),
        ("pig_pycgm/Static_trial.c3d", "plugin-gait"),
    ] {
        let Some(stat) = data_file(rel) else { continue };
        let (ok, err) = auto(&stat, &out);
        assert!(ok, "{rel}: {err}");
        let said = format!("markers auto: preset {preset} (the trial has all ");
        assert!(err.contains(&said), "{rel}: {err}");
        ran += 1;
    }
    // OpenSim's full-body (Rajagopal) pipeline labels: the JAM static, whose markers sit
    // where that pipeline puts them, with its medial and toe labels renamed.
    let renames = [
        ("R.Mkn", "R.MKnee"),
        ("L.Mkn", "L.MKnee"),
        ("R.Man", "R.MAnkle"),
        ("L.Man", "L.MAnkle"),
        ("R.MT0", "R.Toe"),
        ("L.MT0", "L.Toe"),
    ];
    if let Some(stat) = renamed("opensim_jam_healthy/static1.trc", &dir, &renames) {
        let (ok, err) = auto(&stat, &out);
        assert!(ok, "{err}");
        assert!(err.contains("markers auto: preset rajagopal ("), "{err}");
    }
    // Labels no preset knows: the suggestion, said as such.
    let calc = [("R.Heel", "R.Calc"), ("L.Heel", "L.Calc")];
    if let Some(stat) = renamed(
        "opensim_gait2392_subject01/subject01_static.trc",
        &dir,
        &calc,
    ) {
        let (ok, err) = auto(&stat, &out);
        assert!(ok, "{err}");
        assert!(
            err.contains(
                "markers auto: the set `markers suggest` proposes (no preset fits; closest \
                 gait2392 lacks R.Heel, L.Heel): check it"
            ),
            "{err}"
        );
        let toml = std::fs::read_to_string(&out).unwrap();
        assert!(
            toml.contains("R.Calc"),
            "the suggested set's heel tracks the foot"
        );
    }
    if ran == 0 {
        println!("skipped: no data");
    }
}

/// Video keypoints alone (OpenCap's OpenPose keypoints of `neutral.trc`, without the
/// augmented markers): `--markers auto` takes them as joint centres, and the model's hip,
/// knee and ankle centres are the keypoints averaged over the static window.
#[test]
fn keypoints_alone_are_joint_centres() {
    let Some(stat) = data_file("opencap_video_subject0/neutral.trc") else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("keypoints");
    let only = dir.join("keypoints.trc");
    let keep = "Neck,RShoulder,LShoulder,RHip,RKnee,RAnkle,LHip,LKnee,LAnkle,LBigToe,LSmallToe,\
                LHeel,RBigToe,RSmallToe,RHeel";
    let (ok, _, err) = jointfit(&[
        "convert",
        stat.to_str().unwrap(),
        only.to_str().unwrap(),
        "--markers",
        keep,
    ]);
    assert!(ok, "{err}");
    let out = dir.join("kp.toml");
    let (ok, json, err) = jointfit(&[
        "personalize",
        only.to_str().unwrap(),
        "--compare-jc",
        "hip=RHip,knee=RKnee,ankle=RAnkle",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("markers auto: keypoint set keypoints (no marker preset fits"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let rows = v["joint_centre_comparison"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for r in rows {
        let d = r["distance_mm"].as_f64().unwrap();
        assert!(d < 1e-6, "{r}");
    }
    // The model tracks the keypoints: the trunk point with a lower weight.
    let toml = std::fs::read_to_string(&out).unwrap();
    assert!(toml.contains("name = \"Neck\""), "{toml}");
    assert!(toml.contains("weight = 0.25"), "{toml}");
    // The same with the shoulders as the trunk point, asked for by name.
    let (ok, _, err) = jointfit(&[
        "personalize",
        stat.to_str().unwrap(),
        "--markers",
        "keypoints-shoulders",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
}
