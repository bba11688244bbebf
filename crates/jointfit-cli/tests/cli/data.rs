//! `jointfit inspect` and `jointfit convert` on real files.

use jointfit::spatial::up_axis_rotation;
use jointfit::spatial::UpAxis;
use jointfit_io::trial_file::read_trial;
use jointfit_testkit::{data_file, scratch};

use super::jointfit;

/// `inspect --json` reports what the readers see, and counts gaps like an independent scan.
#[test]
fn inspect_reports_rate_frames_and_gaps() {
    let Some(path) = data_file("opencap_expert1/walking1.trc") else {
        return;
    };
    let (ok, out, err) = jointfit(&["inspect", path.to_str().unwrap(), "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let trial = read_trial(&path).unwrap();
    assert_eq!(v["format"], "TRC");
    assert_eq!(v["frames"].as_u64().unwrap() as usize, trial.n_frames());
    assert_eq!(v["rate_hz"].as_f64().unwrap(), trial.rate());
    let markers = v["markers"].as_array().unwrap();
    assert_eq!(markers.len(), trial.labels().len());
    for (m, entry) in markers.iter().enumerate() {
        assert_eq!(entry["label"], trial.labels()[m].as_str());
        let missing = (0..trial.n_frames())
            .filter(|&f| trial.frame(f)[m].x.is_nan())
            .count();
        let pct = entry["missing_percent"].as_f64().unwrap();
        assert!((pct - 100.0 * missing as f64 / trial.n_frames() as f64).abs() < 1e-9);
    }
}

/// C3D (Z-up) → TRC (Y-up): every sample is the rotated input, to the written precision,
/// and gaps stay gaps.
#[test]
fn convert_c3d_to_y_up_trc() {
    let Some(path) = data_file("biobuddy_functional_vicon/Test_func_rknee.c3d") else {
        return;
    };
    let dir = scratch("data-cli");
    let out = dir.join("rknee.trc");
    let (ok, _, err) = jointfit(&[
        "convert",
        path.to_str().unwrap(),
        out.to_str().unwrap(),
        "--up",
        "z",
        "--decimals",
        "6",
    ]);
    assert!(ok, "{err}");
    let input = read_trial(&path).unwrap();
    let output = read_trial(&out).unwrap();
    assert_eq!(input.labels(), output.labels());
    assert_eq!(input.n_frames(), output.n_frames());
    let r = up_axis_rotation(UpAxis::Z);
    for f in 0..input.n_frames() {
        for m in 0..input.labels().len() {
            match (input.get(f, m), output.get(f, m)) {
                (Some(a), Some(b)) => assert!((r * a - b).amax() <= 0.6e-9, "frame {f} marker {m}"),
                (None, None) => {}
                other => panic!("frame {f} marker {m}: gap mismatch {other:?}"),
            }
        }
    }
    // Without --up the vertical is detected from the marker layout, and said: this lab's is
    // -z (the ASIS have a lower z than the heels).
    let convert = |name: &str, up: &[&str]| {
        let file = dir.join(name);
        let mut args = vec![
            "convert",
            path.to_str().unwrap(),
            file.to_str().unwrap(),
            "--decimals",
            "6",
        ];
        args.extend_from_slice(up);
        let (ok, out, err) = jointfit(&args);
        assert!(ok, "{err}");
        (std::fs::read_to_string(&file).unwrap(), out)
    };
    let (a, _) = convert("rknee-minus-z.trc", &["--up=-z"]);
    let (b, out) = convert("rknee-detected.trc", &[]);
    // "wrote" on stdout, like every other command's.
    assert!(
        out.contains("wrote ") && out.contains("up axis detected: -z"),
        "{out}"
    );
    assert!(out.contains("read this file with --up y"), "{out}");
    assert_eq!(
        a.lines().skip(1).collect::<Vec<_>>(),
        b.lines().skip(1).collect::<Vec<_>>()
    );
}

/// Bad input: a non-zero exit and a one-line error naming the file or the marker.
#[test]
fn convert_errors_name_the_problem() {
    let (ok, _, err) = jointfit(&["convert", "/nonexistent/walk.trc", "/tmp/x.trc"]);
    assert!(!ok);
    assert!(err.contains("/nonexistent/walk.trc"), "{err}");
    let (ok, _, err) = jointfit(&["inspect", "notes.txt"]);
    assert!(!ok);
    assert!(err.contains("unknown motion file type"), "{err}");
    let Some(path) = data_file("opencap_expert1/walking1.trc") else {
        return;
    };
    let dir = scratch("data-cli");
    let out = dir.join("never.trc");
    let (ok, _, err) = jointfit(&[
        "convert",
        path.to_str().unwrap(),
        out.to_str().unwrap(),
        "--markers",
        "r.ASIS,NoSuchMarker",
    ]);
    assert!(!ok);
    assert!(err.contains("NoSuchMarker"), "{err}");
    assert!(!out.exists());
}

/// A trial that lacks a model marker altogether: IK treats it as missing in every frame
/// (with a warning) while the present markers determine the coordinates, and refuses with
/// the undetermined coordinate named when they cannot.
#[test]
fn ik_on_a_trial_lacking_model_markers() {
    let dir = scratch("data-cli");
    let Some((subject, walk)) = super::opencap_subject(&dir, "absent-subject.toml") else {
        return;
    };
    let model = jointfit_io::model_file::load_model(subject.to_str().unwrap()).unwrap();
    let keep = |drop: &[&str]| -> String {
        model
            .markers()
            .iter()
            .map(|m| m.name.as_str())
            .filter(|n| !drop.contains(n))
            .collect::<Vec<_>>()
            .join(",")
    };
    let ik = |drop: &[&str], name: &str| {
        let trc = dir.join(format!("{name}.trc"));
        let mot = dir.join(format!("{name}.mot"));
        let (ok, _, err) = jointfit(&[
            "convert",
            walk.to_str().unwrap(),
            trc.to_str().unwrap(),
            "--markers",
            &keep(drop),
        ]);
        assert!(ok, "{err}");
        let out = jointfit(&[
            "ik",
            subject.to_str().unwrap(),
            trc.to_str().unwrap(),
            "-o",
            mot.to_str().unwrap(),
            "--json",
        ]);
        (out, mot)
    };
    let ((ok, out, err), mot) = ik(&["r_thigh5"], "no-thigh5");
    assert!(ok, "{err}");
    assert!(err.contains("lacks model markers r_thigh5"), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["solved_frames"], v["frames"]);
    assert!(v["mean_frame_rms_mm"].as_f64().unwrap() < 10.0, "{out}");
    assert!(mot.exists());
    let ((ok, _, err), mot) = ik(&["r_calc", "r_5meta", "r_toe"], "no-foot");
    assert!(!ok);
    assert!(
        err.contains("no frame could be solved")
            && (err.contains("ankle_dorsiflexion undetermined")
                || err.contains("subtalar_inversion undetermined")),
        "{err}"
    );
    assert!(!mot.exists());
}

/// Field files (notebook/field_check.md): a Vicon file that repeats 2760 parameters prints one
/// warning per group, not one per parameter, and still converts with every frame; a C3D
/// without POINT:UNITS says which units it was read in instead of "units ,".
#[test]
fn field_c3d_quirks_are_said_briefly() {
    let Some(big) = data_file("c3d_reader/c3dorg/sample_33/bigparlove.c3d") else {
        return;
    };
    let dir = scratch("data-field");
    let out = dir.join("big.trc");
    let (ok, _, err) = jointfit(&["convert", big.to_str().unwrap(), out.to_str().unwrap()]);
    assert!(ok, "{err}");
    let repeats: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("repeated param"))
        .collect();
    assert!(!repeats.is_empty(), "{err}");
    assert!(!err.contains("appears twice"), "{err}");
    assert!(
        err.lines().count() < 20,
        "{} lines: {err}",
        err.lines().count()
    );
    let written = read_trial(&out).unwrap();
    assert_eq!(written.n_frames(), read_trial(&big).unwrap().n_frames());
    let Some(ps) = data_file("c3d_reader/c3dorg/sample_20/phasespace_sample.c3d") else {
        return;
    };
    let (ok, text, err) = jointfit(&["inspect", ps.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(text.contains("units mm (assumed"), "{text}");
    assert!(!text.contains("units ,"), "{text}");
}

/// Plug-in Gait's computed outputs (angles, forces, moments, powers), which the file lists in
/// POINT:ANGLES/FORCES/MOMENTS/POWERS, are not markers: the trial leaves them out, as BTK and
/// OpenSim's BTK-based reader do, and says so. Oracle: ezc3d reads 77 points in
/// gait-pig.c3d, 10 + 6 + 6 + 6 of them named in those four lists (notebook/field_check.md).
#[test]
fn c3d_model_outputs_are_not_markers() {
    let Some(pig) = data_file("c3d_reader/c3dorg/sample_03/gait-pig.c3d") else {
        return;
    };
    let c3d = jointfit_io::c3d::read_c3d(&pig).unwrap();
    assert_eq!(c3d.points.n_points(), 77);
    let trial = read_trial(&pig).unwrap();
    assert_eq!(trial.labels().len(), 77 - 28);
    let labels = trial.labels();
    for gone in ["LHipAngles", "RHipPower", "LKneeMoment", "RAnkleForce"] {
        assert!(!labels.iter().any(|l| l == gone), "{gone} is an output");
    }
    for kept in ["RKNE", "RASI", "SACR", "PELO"] {
        assert!(labels.iter().any(|l| l == kept), "{kept} is a point");
    }
    // The kept points keep their samples (gaps included): RKNE in every frame, bit for bit.
    let k = c3d
        .points
        .labels
        .iter()
        .position(|l| l == "A22:RKNE")
        .unwrap();
    let j = labels.iter().position(|l| l == "RKNE").unwrap();
    let n = c3d.points.n_points();
    for f in 0..trial.n_frames() {
        let (a, b) = (trial.frame(f)[j], c3d.points.positions[f * n + k]);
        let same = (0..3).all(|i| a[i].to_bits() == b[i].to_bits());
        assert!(same, "frame {f}: {a:?} vs {b:?}");
    }
    let (ok, text, err) = jointfit(&["inspect", pig.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(text.contains("left out 28 points"), "{text}");
    assert!(
        !text.lines().any(|l| l.starts_with("LHipAngles")),
        "not in the marker table: {text}"
    );
}
