//! `jointfit bench` on any subject (`--static`/`--model` with `--trial`): the subject it
//! personalizes is the one `jointfit personalize` writes, a C3D trial is timed against
//! OpenSim on the same markers, an `.osim` model is timed as read, and bad inputs are one-line
//! errors naming the file. Timings are never asserted; the long synthetic parts are off
//! (`--long-frames 0 --rss-frames 0 --io-frames 0`) or the fit alone runs (`--fit-only 1`).

use std::path::Path;

use super::{jointfit, personalize};

const QUICK: [&str; 6] = [
    "--long-frames",
    "0",
    "--rss-frames",
    "0",
    "--io-frames",
    "0",
];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The "calibrate 27, joint (command default): … cost X mm², …" line of `bench --fit-only`, without its time.
fn fit_cost(out: &str) -> String {
    let line = out
        .lines()
        .find(|l| l.starts_with("calibrate 27, joint"))
        .unwrap_or_else(|| panic!("no fit line: {out}"));
    line.split_once(" ms ").unwrap().1.to_string()
}

/// `bench --static S --markers P` fits the subject `personalize --static S --markers P
/// --side right` writes: the same iterations and cost (to the printed digits) as
/// `bench --model` on that file.
#[test]
fn bench_static_personalizes_as_personalize_does() {
    let (Some(stat), Some(walk)) = (
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_static.trc"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("bench-static");
    let subject = dir.join("subject.toml");
    personalize(&stat, "gait2392", &subject);
    let (ok, from_static, err) = jointfit(&[
        "bench",
        "--static",
        s(&stat),
        "--markers",
        "gait2392",
        "--trial",
        s(&walk),
        "--fit-only",
        "1",
    ]);
    assert!(ok, "{err}");
    assert!(from_static.contains("(151 frames)"), "{from_static}");
    let (ok, from_model, err) = jointfit(&[
        "bench",
        "--model",
        s(&subject),
        "--trial",
        s(&walk),
        "--fit-only",
        "1",
    ]);
    assert!(ok, "{err}");
    assert_eq!(fit_cost(&from_static), fit_cost(&from_model));
    // The left leg is another subject model: another fit.
    let (ok, left, err) = jointfit(&[
        "bench",
        "--static",
        s(&stat),
        "--markers",
        "gait2392",
        "--side",
        "left",
        "--trial",
        s(&walk),
        "--fit-only",
        "1",
    ]);
    assert!(ok, "{err}");
    assert!(left.contains("the left leg"), "{left}");
    assert_ne!(fit_cost(&left), fit_cost(&from_static));
}

/// A C3D trial whose subject walks into and out of the capture volume (Z-up lab): the bench
/// times the frames jointfit's IK solves, says which, and OpenSim's IK runs on the same
/// markers (a temporary TRC, removed afterwards).
#[test]
fn bench_times_a_c3d_trial_against_opensim() {
    let Some(walk) = jointfit_testkit::data_file("c3d_reader/opensim/walking2.c3d") else {
        return;
    };
    let Some(_python) = jointfit_testkit::python() else {
        return;
    };
    let set = jointfit_testkit::script::script_path("markersets/opensim_test_walks.toml");
    let dir = jointfit_testkit::scratch("bench-c3d");
    let subject = dir.join("walk.toml");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        s(&walk),
        "--markers",
        s(&set),
        "--side",
        "right",
        "--window",
        "0.02",
        "-o",
        s(&subject),
    ]);
    assert!(ok, "{err}");
    // The bench's scratch files go to its TMPDIR, which must be empty afterwards.
    let tmp = dir.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args([
            "bench",
            "--model",
            s(&subject),
            "--trial",
            s(&walk),
            "--json",
        ])
        .args(QUICK)
        .env("TMPDIR", &tmp)
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr),
    );
    assert!(run.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    let frames = v["frames"].as_u64().unwrap();
    // The walk has 1249 frames; the subject is in view in the middle ones only.
    assert!((100..1249).contains(&frames), "{out}");
    let source = v["source"].as_str().unwrap();
    assert!(source.contains(" of 1249 "), "{source}");
    assert_eq!(v["markers"].as_u64(), Some(13), "{out}");
    let ratio = v["opensim_ik_over_jointfit_ik"].as_f64();
    assert!(
        ratio.is_some_and(|r| r.is_finite() && r > 0.0),
        "no OpenSim figure: {out}\n{err}"
    );
    assert!(v["fit_over_opensim_ik"].as_f64().unwrap() > 0.0, "{out}");
    assert_eq!(
        jointfit_testkit::scratch::entries(&tmp),
        Vec::<String>::new(),
        "the bench left scratch files"
    );
}

/// An `.osim` model: one leg's hip, knee and ankle offsets are the free parameters, the
/// markers the trial lacks and the coordinates none determines are left out as `calibrate`
/// does (and said).
#[test]
fn bench_fits_an_osim_model() {
    let (Some(model), Some(walk)) = (
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_simbody.osim"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        return;
    };
    let (ok, out, err) = jointfit(&[
        "bench",
        "--model",
        s(&model),
        "--trial",
        s(&walk),
        "--fit-only",
        "1",
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("offsets of hip_r, knee_r, ankle_r fitted"),
        "{out}"
    );
    assert!(err.contains("no marker determines mtp_angle_r"), "{err}");
    let (ok, out, err) = jointfit(&[
        "bench",
        "--model",
        s(&model),
        "--side",
        "left",
        "--trial",
        s(&walk),
        "--fit-only",
        "1",
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("offsets of hip_l, knee_l, ankle_l fitted"),
        "{out}"
    );
}

/// `args` fails with one line on stderr that contains `expect`.
fn refused(args: &[&str], expect: &str) {
    let (ok, out, err) = jointfit(args);
    assert!(!ok, "{args:?} succeeded: {out}");
    let line = err
        .lines()
        .filter(|l| !l.starts_with("jointfit: warning:"))
        .collect::<Vec<_>>();
    assert_eq!(line.len(), 1, "{err}");
    assert!(
        line[0].starts_with("jointfit: error: ") && line[0].contains(expect),
        "{args:?}: expected {expect:?} in {err}"
    );
}

/// Missing files, an unknown preset, a trial without the model's markers, options that do
/// not go together: one line each, naming the file or option.
#[test]
fn bench_bad_inputs_are_one_line_errors() {
    let dir = jointfit_testkit::scratch("bench-bad");
    let missing = dir.join("missing.trc");
    let also_missing = dir.join("walk.c3d");
    refused(
        &[
            "bench",
            "--static",
            s(&missing),
            "--markers",
            "opencap",
            "--trial",
            s(&also_missing),
        ],
        s(&missing),
    );
    refused(
        &[
            "bench",
            "--static",
            s(&missing),
            "--markers",
            "no-such-preset",
            "--trial",
            s(&also_missing),
        ],
        "\"no-such-preset\" is neither a marker-set file nor a preset",
    );
    let osim = dir.join("none.osim");
    refused(
        &["bench", "--model", s(&osim), "--trial", s(&missing)],
        s(&osim),
    );
    refused(&["bench", "--trial", s(&missing)], "--static");
    // The default workload is the right leg: --side alone is refused, not ignored.
    refused(&["bench", "--side", "left"], "--static");
    refused(
        &["bench", "--static", s(&missing), "--trial", s(&missing)],
        "--markers",
    );
    refused(
        &[
            "bench",
            "--model",
            "lower-limb-right",
            "--side",
            "left",
            "--trial",
            s(&missing),
        ],
        "--side",
    );
    let (Some(stat), Some(walk)) = (
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_static.trc"),
        jointfit_testkit::data_file("opencap_expert1/walking1.trc"),
    ) else {
        return;
    };
    refused(
        &[
            "bench",
            "--static",
            s(&stat),
            "--markers",
            "opencap",
            "--trial",
            s(&walk),
        ],
        &format!("{}: cannot personalize", stat.display()),
    );
    let gait = stat.with_file_name("subject01_walk1.trc");
    refused(
        &["bench", "--model", "lower-limb-right", "--trial", s(&gait)],
        &format!("{}: no marker of the trial is a marker of", gait.display()),
    );
    let subject = dir.join("subject.toml");
    personalize(&stat, "gait2392", &subject);
    refused(
        &["bench", "--model", s(&subject), "--trial", s(&missing)],
        s(&missing),
    );
}
