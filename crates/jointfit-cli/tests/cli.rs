//! The `jointfit` binary end to end: exit codes, one-line errors, JSON that parses.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "cli/batch.rs"]
mod batch;
#[path = "cli/bench.rs"]
mod bench;
#[path = "cli/bilateral.rs"]
mod bilateral;
#[path = "cli/conflict.rs"]
mod conflict;
#[path = "cli/data.rs"]
mod data;
#[path = "cli/functional.rs"]
mod functional;
#[path = "cli/fuzz.rs"]
mod fuzz;
#[path = "cli/held_out.rs"]
mod held_out;
#[path = "cli/held_out_hip.rs"]
mod held_out_hip;
#[path = "cli/ident.rs"]
mod ident;
#[path = "cli/ik.rs"]
mod ik;
#[path = "cli/ik_branch.rs"]
mod ik_branch;
#[path = "cli/ik_chunks.rs"]
mod ik_chunks;
#[path = "cli/limits.rs"]
mod limits;
#[path = "cli/markers.rs"]
mod markers;
#[path = "cli/markers_auto.rs"]
mod markers_auto;
#[path = "cli/markers_trust.rs"]
mod markers_trust;
#[path = "cli/offsets.rs"]
mod offsets;
#[path = "cli/osim.rs"]
mod osim;
#[path = "cli/osim_clamped.rs"]
mod osim_clamped;
#[path = "cli/osim_commands.rs"]
mod osim_commands;
#[path = "cli/osim_ik.rs"]
mod osim_ik;
#[path = "cli/osim_ik_setup.rs"]
mod osim_ik_setup;
#[path = "cli/osim_personalize.rs"]
mod osim_personalize;
#[path = "cli/personalize.rs"]
mod personalize;
#[path = "cli/plugin_gait.rs"]
mod plugin_gait;
#[path = "cli/priors.rs"]
mod priors;
#[path = "cli/refusals.rs"]
mod refusals;
#[path = "cli/reliability.rs"]
mod reliability;
#[path = "cli/repair.rs"]
mod repair;
#[path = "cli/report.rs"]
mod report;
#[path = "cli/rms.rs"]
mod rms;
#[path = "cli/safety.rs"]
mod safety;
#[path = "cli/scale.rs"]
mod scale;
#[path = "cli/stream.rs"]
mod stream;
#[path = "cli/synth.rs"]
mod synth;
#[path = "cli/trial_refusals.rs"]
mod trial_refusals;
#[path = "cli/up.rs"]
mod up;
#[path = "cli/verdict.rs"]
mod verdict;
#[path = "cli/weights.rs"]
mod weights;

/// `jointfit personalize --static STAT --markers PRESET --side right -o OUT`, which must
/// succeed.
fn personalize(stat: &Path, preset: &str, out: &Path) {
    personalize_side(stat, preset, "right", out);
}

/// `jointfit personalize --static STAT --markers PRESET --side SIDE -o OUT`, which must
/// succeed.
fn personalize_side(stat: &Path, preset: &str, side: &str, out: &Path) {
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        stat.to_str().unwrap(),
        "--markers",
        preset,
        "--side",
        side,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{} {side}: {err}", stat.display());
}

/// OpenCap's expert subject, the shared setup of the tests on real gait: `dir/name`
/// personalized (opencap preset, right leg) from `static1.trc`, and the path of
/// `walking1.trc`; `None` (the test is skipped) without the data.
fn opencap_subject(dir: &Path, name: &str) -> Option<(PathBuf, PathBuf)> {
    let stat = jointfit_testkit::data_file("opencap_expert1/static1.trc")?;
    let walk = jointfit_testkit::data_file("opencap_expert1/walking1.trc")?;
    let subject = dir.join(name);
    personalize(&stat, "opencap", &subject);
    Some((subject, walk))
}

fn jointfit(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(args)
        .output()
        .expect("jointfit runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn model_show_builtin() {
    let (ok, out, _) = jointfit(&["model", "show", "lower-limb-right"]);
    assert!(ok);
    assert!(
        out.contains("parameters (27): hip 6, knee 9, ankle 12"),
        "{out}"
    );
    assert!(out.contains("coordinates (12)"), "{out}");
    assert!(out.contains("knee_thigh_superior"), "{out}");
}

#[test]
fn model_show_json() {
    let (ok, out, _) = jointfit(&["model", "show", "lower-limb-left", "--json"]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert_eq!(v["parameters"].as_array().unwrap().len(), 27);
    assert_eq!(v["coordinates"].as_array().unwrap().len(), 12);
    let lateral = v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "hip_pelvis_lateral")
        .unwrap();
    assert_eq!(lateral["unit"], "mm");
    assert_eq!(lateral["nominal"], 86.28);
    assert_eq!(lateral["segment"], "pelvis");
}

#[test]
fn model_show_file_round_trip() {
    let dir = jointfit_testkit::scratch("cli");
    let path = dir.join("leg.toml");
    let spec = jointfit::model::lower_limb::builtin("lower-limb-right").unwrap();
    std::fs::write(&path, spec.to_toml()).unwrap();
    let (ok, from_file, _) = jointfit(&["model", "show", path.to_str().unwrap(), "--json"]);
    assert!(ok);
    let (_, builtin, _) = jointfit(&["model", "show", "lower-limb-right", "--json"]);
    assert_eq!(from_file, builtin);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_model_is_a_one_line_error() {
    let (ok, out, err) = jointfit(&["model", "show", "lower-limb-middle"]);
    assert!(!ok);
    assert!(out.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("jointfit: error: \"lower-limb-middle\" is neither"),
        "{err}"
    );
}

/// Without the shared data `bench` times a synthetic gait and says so; every figure is a
/// finite positive number and the IK it times converges in a handful of iterations.
#[test]
fn bench_runs_without_data() {
    let (ok, out, err) = jointfit(&[
        "bench",
        "--data",
        "/nonexistent-jointfit-data",
        "--json",
        "--long-frames",
        "200",
        "--rss-frames",
        "200",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert!(
        v["source"].as_str().unwrap().starts_with("synthetic"),
        "{out}"
    );
    for key in [
        "fk_us",
        "fk_dq_us",
        "ik_trial_us_per_frame",
        "ik_warm_us_per_frame",
        "joint_27_ms",
        "gradient_27_ms",
        "peak_rss_mb",
    ] {
        let x = v[key].as_f64().unwrap();
        assert!(x.is_finite() && x > 0.0, "{key} = {x}");
    }
    let iterations = v["ik_iterations_per_frame"].as_f64().unwrap();
    assert!((1.0..=12.0).contains(&iterations), "{iterations}");
    // The long-fit figures are there (their values are timings, not asserted).
    let long = &v["long_fit"];
    assert_eq!(long["frames"].as_u64(), Some(200), "{out}");
    assert!(long["two_over_one"].as_f64().unwrap().is_finite(), "{out}");
}

/// With the shared data and OpenSim, `bench` times OpenSim's IK solver on the exported
/// landmark model and exits 0 (the exported model is a scratch file for the subprocess, not a
/// staged output that would appear only after OpenSim needed it).
#[test]
fn bench_times_opensim_on_the_shared_trial() {
    let (Some(data), Some(_python)) = (jointfit_testkit::data_dir(), jointfit_testkit::python())
    else {
        return;
    };
    let data = data.to_str().unwrap().to_string();
    let (ok, out, err) = jointfit(&[
        "bench",
        "--data",
        &data,
        "--json",
        "--long-frames",
        "0",
        "--rss-frames",
        "0",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    let ratio = v["opensim_ik_over_jointfit_ik"].as_f64();
    assert!(
        ratio.is_some_and(|r| r.is_finite() && r > 0.0),
        "no OpenSim figure: {out}\n{err}"
    );
}

/// `--starts 3`: three optima reported, and the fit kept is the best of them.
#[test]
fn calibrate_multi_start_keeps_the_best() {
    let dir = jointfit_testkit::scratch("starts");
    let trc = dir.join("hip.trc");
    let truth = dir.join("truth.toml");
    let fitted = dir.join("fitted.toml");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let (ok, _, err) = jointfit(&[
        "synth",
        "lower-limb-right",
        "--motion",
        "hip",
        "--noise",
        "skin",
        "--seed",
        "2",
        "-o",
        &s(&trc),
        "--truth",
        &s(&truth),
    ]);
    assert!(ok, "{err}");
    let (ok, out, err) = jointfit(&[
        "calibrate",
        "lower-limb-right",
        &s(&trc),
        "--joints",
        "hip",
        "--starts",
        "3",
        "-o",
        &s(&fitted),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    let ms = &v["multistart"];
    assert_eq!(ms["starts"], 3);
    let objectives: Vec<f64> = ms["objective_mm2"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(objectives.len(), 3);
    let best = objectives.iter().copied().fold(f64::INFINITY, f64::min);
    let kept = v["cost_after"].as_f64().unwrap() * 1e6;
    assert!(
        (kept - best).abs() <= 1e-9 * best,
        "kept {kept}, best {best}"
    );
    assert!(ms["reached_best"].as_u64().unwrap() >= 1);
    assert_eq!(ms["spread"].as_array().unwrap().len(), 6);
    let (ok, _, err) = jointfit(&[
        "calibrate",
        "lower-limb-right",
        &s(&trc),
        "--starts",
        "0",
        "-o",
        &s(&fitted),
    ]);
    assert!(!ok && err.contains("--starts"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
