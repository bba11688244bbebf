//! The up axis once: `personalize` detects the lab's vertical from the static trial and
//! records it in the subject model (`lab_up`); later commands apply it without `--up`.

use std::path::Path;

use jointfit_testkit::{data_file, scratch};

use super::jointfit;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// personalize without `--up`: the model records the detected axis.
fn personalize(stat: &Path, preset: &str, out: &Path) -> String {
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        s(stat),
        "--markers",
        preset,
        "--side",
        "right",
        "-o",
        s(out),
    ]);
    assert!(ok, "{err}");
    std::fs::read_to_string(out).unwrap()
}

#[test]
fn negative_z_lab_needs_up_only_once() {
    let (Some(stat), Some(trial)) = (
        data_file("biobuddy_functional_vicon/Test_func_anat.c3d"),
        data_file("biobuddy_functional_vicon/Test_func_rknee.c3d"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let dir = scratch("up_once");
    let subject = dir.join("subject.toml");
    let toml = personalize(&stat, "plugin-gait-medial", &subject);
    assert!(toml.contains("lab_up = \"-z\""), "{toml}");
    let (given, forgot, wrong) = (
        dir.join("given.mot"),
        dir.join("forgot.mot"),
        dir.join("y.mot"),
    );
    let run_on = |input: &Path, mot: &Path, extra: &[&str]| {
        let mut args = vec!["ik", s(&subject), s(input), "-o", s(mot)];
        args.extend_from_slice(extra);
        let (ok, _, err) = jointfit(&args);
        assert!(ok, "{err}");
        err
    };
    let run = |mot: &Path, extra: &[&str]| run_on(&trial, mot, extra);
    let err_given = run(&given, &["--up=-z"]);
    let err_forgot = run(&forgot, &[]);
    assert_eq!(
        std::fs::read(&given).unwrap(),
        std::fs::read(&forgot).unwrap(),
        "forgetting --up gives the same .mot as giving it"
    );
    assert!(!err_given.contains("looks rotated"), "{err_given}");
    assert!(!err_forgot.contains("looks rotated"), "{err_forgot}");
    // synth replays the trial's IK read the same way: without --up it takes the model's
    // lab_up, as ik does (it took y before, and replayed a rotated motion).
    let synth = |out: &Path, extra: &[&str]| {
        let motion = format!("gait:{}", s(&trial));
        let truth = out.with_extension("toml");
        let mut args = vec!["synth", s(&subject), "--motion", &motion, "-o", s(out)];
        args.extend_from_slice(&["--truth", s(&truth)]);
        args.extend_from_slice(extra);
        let (ok, _, err) = jointfit(&args);
        assert!(ok, "{err}");
        // Past the first line, which names the file.
        let text = std::fs::read_to_string(out).unwrap();
        text.split_once('\n').unwrap().1.to_string()
    };
    let (sg, sf, sy) = (dir.join("sg.trc"), dir.join("sf.trc"), dir.join("sy.trc"));
    assert_eq!(synth(&sg, &["--up=-z"]), synth(&sf, &[]));
    assert_ne!(synth(&sy, &["--up", "y"]), synth(&sf, &[]));
    // `convert` rotates to Y up (OpenSim's convention), so the converted TRC is no longer
    // in the frame the subject's lab_up describes: convert says so, and ik on it without
    // --up says exactly what to pass; with --up y it reads it as the C3D.
    let trc = dir.join("rknee.trc");
    let (ok, out, err) = jointfit(&["convert", s(&trial), s(&trc)]);
    assert!(ok, "{err}");
    assert!(
        out.contains("rotated from -z up to Y up") && out.contains("--up y"),
        "{out}"
    );
    let mot = dir.join("trc.mot");
    let err = run_on(&trc, &mot, &[]);
    assert!(
        err.contains("looks rotated")
            && err.contains("written by `jointfit convert` is already Y-up"),
        "{err}"
    );
    let err = run_on(&trc, &mot, &["--up", "y"]);
    assert!(!err.contains("looks rotated"), "{err}");
    // Overriding with the wrong axis is still possible, and said.
    let err_wrong = run(&wrong, &["--up", "y"]);
    assert!(
        err_wrong.contains("looks rotated relative to the subject")
            && err_wrong.contains("pass --up -z"),
        "{err_wrong}"
    );
}

#[test]
fn y_up_labs_record_y() {
    for (rel, preset) in [
        ("opencap_expert1/static1.trc", "opencap"),
        (
            "opensim_gait2392_subject01/subject01_static.trc",
            "gait2392",
        ),
        ("opensim_jam_healthy/static1.trc", "jam"),
    ] {
        let Some(stat) = data_file(rel) else {
            println!("skipped: no data");
            return;
        };
        let dir = scratch("up_y");
        let out = dir.join("subject.toml");
        let toml = personalize(&stat, preset, &out);
        assert!(toml.contains("lab_up = \"y\""), "{rel}: {toml}");
    }
}
