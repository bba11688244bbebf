//! `jointfit ik --setup` on OpenSim's own IK setup of the gait2392 subject01 tutorial
//! (OpenSim 3 format: marker weights 0.1–10, coordinate tasks of weight 1000 on the subtalar
//! and toe angles, time range 0.5–2.5 s, relative paths), run by both programs. OpenSim 4.6's
//! InverseKinematicsTool runs the same setup file (`opensim_oracle.py ik-setup`) and then
//! evaluates its weighted objective, frame by frame, at both solutions
//! (`opensim_oracle.py objective`: OpenSim's kinematics, its reading of the task set and the
//! marker file, the goal as Simbody's Assembler sums it). No frame of jointfit's may be worse
//! than OpenSim's by more than a relative 1e-6. A second run of the same setup with a
//! `manual_value` task and a `from_file` task (OpenSim's own IK result of the trial as the
//! coordinate file) is judged the same way.

use std::path::{Path, PathBuf};

use jointfit_testkit::script::{result_lines, Script};
use serde_json::Value;

use super::jointfit;

const SETUP: &str = "subject01_Setup_IK.xml";

/// The pipeline's files copied into `dir` (the setup's relative paths then resolve there);
/// `None` without the data.
fn pipeline(dir: &Path) -> Option<()> {
    std::fs::create_dir_all(dir).unwrap();
    for name in [
        SETUP,
        "subject01_simbody.osim",
        "subject01_walk1.trc",
        "subject01_walk1_ik.mot",
    ] {
        let src = jointfit_testkit::data_file(&format!("opensim_gait2392_subject01/{name}"))?;
        std::fs::write(dir.join(name), std::fs::read(src).unwrap()).unwrap();
    }
    Some(())
}

/// Per motion file: the objective of every frame, `(time, value)`, as OpenSim evaluates it.
fn objectives(python: &Path, dir: &Path, mots: &[&str]) -> Vec<Vec<(f64, f64)>> {
    let mut args = vec!["objective", SETUP];
    args.extend(mots);
    let out = Script::new(python, "opensim_oracle.py")
        .args(&args)
        .current_dir(dir)
        .run();
    let mut files: Vec<Vec<(f64, f64)>> = Vec::new();
    for line in result_lines(&out) {
        let f: Vec<&str> = line.split('\t').collect();
        match f[0] {
            "FILE" => files.push(Vec::new()),
            "FRAME" => files
                .last_mut()
                .unwrap()
                .push((f[1].parse().unwrap(), f[2].parse().unwrap())),
            _ => {}
        }
    }
    assert_eq!(files.len(), mots.len(), "{out}");
    files
}

/// Runs both programs on `dir/SETUP` and compares their objectives frame by frame; returns
/// jointfit's JSON summary.
fn both(python: &Path, dir: &Path, label: &str) -> Value {
    let setup = dir.join(SETUP);
    // From the test's own working directory: the setup's paths resolve from its directory.
    let (ok, out, err) = jointfit(&["ik", "--setup", setup.to_str().unwrap(), "--json"]);
    assert!(ok, "{label}: {err}");
    let summary: Value = serde_json::from_str(&out).unwrap();
    let ours = dir.join("subject01_walk1_ik_jointfit.mot");
    assert!(
        ours.exists(),
        "{label}: output_motion_file written where the setup says"
    );
    Script::new(python, "opensim_oracle.py")
        .args(&["ik-setup", SETUP, "opensim.mot"])
        .current_dir(dir)
        .run();
    let obj = objectives(
        python,
        dir,
        &["opensim.mot", "subject01_walk1_ik_jointfit.mot"],
    );
    let (os, jf) = (&obj[0], &obj[1]);
    assert_eq!(os.len(), jf.len(), "{label}: the same frames");
    // 0.5–2.5 s at 60 Hz: the rows nearest to both ends, inclusive.
    assert_eq!(jf.len(), 121, "{label}");
    let mut worst = f64::NEG_INFINITY;
    for (f, ((t0, a), (t1, b))) in os.iter().zip(jf).enumerate() {
        assert!(
            (t0 - t1).abs() < 1e-3,
            "{label} frame {f}: times {t0} and {t1}"
        );
        let rel = b / a - 1.0;
        worst = worst.max(rel);
        assert!(
            rel <= 1e-6,
            "{label} frame {f} (t = {t1}): jointfit {b:e}, OpenSim {a:e}"
        );
    }
    let sum = |v: &[(f64, f64)]| v.iter().map(|x| x.1).sum::<f64>();
    eprintln!(
        "{label}: {} frames; objective summed over frames: jointfit {:.6e}, OpenSim {:.6e}; \
         worst frame jointfit/OpenSim − 1 = {worst:.2e}",
        jf.len(),
        sum(jf),
        sum(os)
    );
    summary
}

/// The setup with its output renamed (OpenSim's run writes to `opensim.mot` in any case).
fn write_setup(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let path = dir.join(SETUP);
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "<output_motion_file>subject01_walk1_ik.mot",
        "<output_motion_file>subject01_walk1_ik_jointfit.mot",
    );
    std::fs::write(&path, edit(text)).unwrap();
    path
}

#[test]
fn gait2392_setup_no_frame_worse_than_opensim() {
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let scratch = jointfit_testkit::scratch("osim-ik-setup");
    let dir = scratch.join("pipeline");
    if pipeline(&dir).is_none() {
        return;
    }
    write_setup(&dir, |t| t);
    let summary = both(&python, &dir, "gait2392 subject01 setup");
    assert_eq!(summary["solved_frames"], 121);
    // OpenSim's marker-error file, in results_directory (./), named after the tool.
    let errors = jointfit_io::sto::read_sto(&dir.join("subject01_ik_marker_errors.sto")).unwrap();
    assert_eq!(
        errors.columns,
        [
            "time",
            "total_squared_error",
            "marker_error_RMS",
            "marker_error_max"
        ]
    );
    assert_eq!(errors.rows.len(), 121);
    let mean_rms = errors.rows.iter().map(|r| r[2]).sum::<f64>() / errors.rows.len() as f64 * 1e3;
    let reported = summary["mean_frame_rms_mm"].as_f64().unwrap();
    assert!(
        (mean_rms - reported).abs() < 1e-6 * reported,
        "{mean_rms} vs {reported}"
    );
}

/// `from_file` (OpenSim's IK result of the trial, in degrees, as the coordinate file of the
/// subtalar task) and `manual_value` (a knee task far from the markers' answer).
#[test]
fn gait2392_setup_with_file_and_manual_tasks_no_frame_worse_than_opensim() {
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let scratch = jointfit_testkit::scratch("osim-ik-setup-tasks");
    let dir = scratch.join("pipeline");
    if pipeline(&dir).is_none() {
        return;
    }
    write_setup(&dir, |t| {
        let at = t.find("name=\"subtalar_angle_r\"").unwrap();
        let rel = t[at..].find("default_value").unwrap();
        let mut t = t.clone();
        t.replace_range(at + rel..at + rel + "default_value".len(), "from_file");
        t.replace(
            "<coordinate_file></coordinate_file>",
            "<coordinate_file>subject01_walk1_ik.mot</coordinate_file>",
        )
        .replace(
            "</objects>",
            "<IKCoordinateTask name=\"knee_angle_r\"><apply>true</apply><weight>0.001</weight>\
             <value_type>manual_value</value_type><value>-0.3</value></IKCoordinateTask>\
             </objects>",
        )
    });
    let summary = both(
        &python,
        &dir,
        "gait2392 subject01 setup, file and manual tasks",
    );
    assert_eq!(summary["solved_frames"], 121);
}

/// OpenCap's own IK setup of its Squats_0 trial (OpenSim 4 format, written on another machine:
/// absolute Windows paths, so the model, the trial and the output are given as arguments; 47
/// marker tasks of weights 5–30), against OpenCap's published OpenSim IK result of the same
/// setup (`Squats_0.mot`), both judged by OpenSim's objective of that setup frame by frame:
/// no frame worse by more than a relative 1e-6.
#[test]
fn opencap_squats_setup_no_frame_worse_than_opencaps_opensim_result() {
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let rel = |n: &str| jointfit_testkit::data_file(&format!("opencap_video_subject0/{n}"));
    let model_name = "LaiArnoldModified2017_poly_withArms_weldHand_scaled.osim";
    let (Some(setup), Some(model), Some(trial), Some(reference)) = (
        rel("Squats_0_setup_ik.xml"),
        rel(model_name),
        rel("Squats_0.trc"),
        rel("Squats_0.mot"),
    ) else {
        return;
    };
    let scratch = jointfit_testkit::scratch("osim-ik-setup-opencap");
    let dir = scratch.join("ik");
    std::fs::create_dir_all(&dir).unwrap();
    let ours = dir.join("jointfit.mot");
    let (ok, out, err) = jointfit(&[
        "ik",
        "--setup",
        setup.to_str().unwrap(),
        model.to_str().unwrap(),
        trial.to_str().unwrap(),
        "-o",
        ours.to_str().unwrap(),
        "--json",
    ]);
    assert!(ok, "{err}");
    assert!(err.contains("results_directory"), "{err}");
    let summary: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(summary["solved_frames"], summary["frames"]);
    // The oracle reads the setup's own paths: a copy naming the local files.
    let text = std::fs::read_to_string(&setup).unwrap();
    let element = |t: &str, tag: &str, value: &str| {
        let (open, close) = (format!("<{tag}>"), format!("</{tag}>"));
        let a = t.find(&open).unwrap() + open.len();
        let b = t.find(&close).unwrap();
        format!("{}{value}{}", &t[..a], &t[b..])
    };
    let text = element(&text, "model_file", model.to_str().unwrap());
    let text = match text.find("<marker_file>") {
        Some(_) => element(&text, "marker_file", trial.to_str().unwrap()),
        None => text.replace(
            "</InverseKinematicsTool>",
            &format!(
                "<marker_file>{}</marker_file></InverseKinematicsTool>",
                trial.display()
            ),
        ),
    };
    std::fs::write(dir.join(SETUP), text).unwrap();
    std::fs::write(dir.join("opencap.mot"), std::fs::read(&reference).unwrap()).unwrap();
    let obj = objectives(&python, &dir, &["opencap.mot", "jointfit.mot"]);
    let (os, jf) = (&obj[0], &obj[1]);
    assert_eq!(os.len(), jf.len());
    assert_eq!(jf.len() as u64, summary["frames"].as_u64().unwrap());
    let mut worst = f64::NEG_INFINITY;
    for (f, ((_, a), (t, b))) in os.iter().zip(jf).enumerate() {
        let rel = b / a - 1.0;
        worst = worst.max(rel);
        assert!(
            rel <= 1e-6,
            "frame {f} (t = {t}): jointfit {b:e}, OpenSim {a:e}"
        );
    }
    let sum = |v: &[(f64, f64)]| v.iter().map(|x| x.1).sum::<f64>();
    eprintln!(
        "OpenCap Squats_0 setup: {} frames; objective summed: jointfit {:.6e}, OpenCap's OpenSim \
         {:.6e}; worst frame jointfit/OpenSim − 1 = {worst:.2e}",
        jf.len(),
        sum(jf),
        sum(os)
    );
}
