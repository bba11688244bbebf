//! The anatomical-landmark method on the real static trials of the shared data
//! (`$JOINTFIT_DATA`; skipped outside CI when absent), through the library and the binary.

use std::path::Path;

use jointfit::ik::lm::IkWorkspace;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::Side;
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit::spatial::up_axis_rotation;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{
    personalize, HipCentreMethod, LandmarkError, PersonalizeOptions, Personalized,
};
use jointfit_testkit::data_file;
use nalgebra::Vector3;

use super::jointfit;

/// A TRC or C3D trial turned so that `up` becomes y.
pub(super) fn read(path: &Path, up: UpAxis) -> Trial {
    let mut t = if path.extension().is_some_and(|e| e == "c3d") {
        jointfit_io::c3d::read_c3d(path)
            .unwrap()
            .to_trial()
            .unwrap()
    } else {
        jointfit_io::trc::read_trc(path).unwrap()
    };
    t.rotate(&up_axis_rotation(up));
    t
}

fn mean_over_window(trial: &Trial, out: &Personalized, label: &str) -> Vector3<f64> {
    let c = trial.index_of(label).unwrap();
    let w = &out.report.window;
    (w.first..w.end())
        .map(|f| trial.get(f, c).unwrap())
        .sum::<Vector3<f64>>()
        / w.len as f64
}

/// Personalizes and checks what must hold on any real static trial.
fn check(
    rel: &str,
    preset: &str,
    side: Side,
    up: UpAxis,
    hip: HipCentreMethod,
) -> Option<(Trial, Personalized)> {
    let path = data_file(rel)?;
    let trial = read(&path, up);
    let set = MarkerSet::preset(preset).unwrap();
    let opts = PersonalizeOptions {
        hip_centre: hip,
        ..PersonalizeOptions::default()
    };
    let out = personalize(&trial, &set, side, &opts).unwrap();
    let rep = &out.report;
    let tag = format!("{rel} {side:?}");

    // The written model, read back, reproduces every tracking marker of the averaged static
    // frame at the static pose.
    let spec = ModelSpec::from_toml(&out.spec.to_toml()).unwrap();
    let model = Model::compile(&spec).unwrap();
    let p = model.nominal_params();
    let mut kin = KinData::new(&model);
    forward_kinematics(&model, &p, &out.static_q, Want::Positions, &mut kin);
    let worst = model
        .markers()
        .iter()
        .zip(&kin.markers)
        .map(|(m, x)| (x - mean_over_window(&trial, &out, &m.name)).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "{tag}: static reconstruction {worst:e} m");
    assert!(rep.static_fk_error < 1e-9, "{tag}");

    // Plausibility (mm, deg).
    let get = |n: &str| {
        let q = &spec.parameters[model.param_id(n).unwrap().0];
        match q.unit {
            jointfit::model::spec::Unit::Metre => q.nominal * 1e3,
            jointfit::model::spec::Unit::Radian => q.nominal.to_degrees(),
        }
    };
    let within = |n: &str, lo: f64, hi: f64| {
        let v = get(n);
        assert!(
            lo <= v && v <= hi,
            "{tag}: {n} = {v:.2} outside [{lo}, {hi}]"
        );
    };
    within("hip_pelvis_anterior", -80.0, -20.0);
    within("hip_pelvis_superior", -110.0, -60.0);
    within("hip_pelvis_lateral", 70.0, 110.0);
    within("knee_thigh_superior", -500.0, -300.0);
    within("talocrural_shank_superior", -500.0, -300.0);
    within("knee_thigh_frontal", -15.0, 15.0);
    within("knee_shank_frontal", -15.0, 15.0);
    within("knee_shank_transverse", -25.0, 25.0);
    within("talocrural_shank_frontal", -20.0, 20.0);
    within("subtalar_talus_transverse", 10.0, 50.0);
    within("subtalar_foot_anterior", 40.0, 140.0);
    within("subtalar_foot_superior", 0.0, 80.0);
    let mm = |x: f64| x * 1e3;
    assert!((80.0..180.0).contains(&mm(rep.knee_width)), "{tag}");
    assert!((50.0..110.0).contains(&mm(rep.ankle_width)), "{tag}");
    assert!((200.0..300.0).contains(&mm(rep.pelvis_width)), "{tag}");
    assert!(mm(rep.window.motion_rms) < 1.0, "{tag}");
    for s in &rep.segments {
        assert!(
            mm(s.rms) < 1.0 && mm(s.max) < 2.0,
            "{tag}: {} rigid fit {:.2}/{:.2} mm",
            s.segment,
            mm(s.rms),
            mm(s.max)
        );
    }
    let q = |n: &str| out.static_q[model.coord_id(n).unwrap()].to_degrees();
    // JAM stands with the knees at −11° and −15° by these frames (its ASIS–PSIS plane is
    // tilted 18°, which moves the regression hip centre forward).
    assert!((-20.0..20.0).contains(&q("knee_flexion")), "{tag}");
    assert!((-25.0..25.0).contains(&q("ankle_dorsiflexion")), "{tag}");
    Some((trial, out))
}

#[test]
fn opencap_both_legs_and_its_virtual_hip_centres() {
    let rel = "opencap_expert1/static1.trc";
    let mut rows = Vec::new();
    for (side, r) in [(Side::Right, "R"), (Side::Left, "L")] {
        for hip in [HipCentreMethod::Bell, HipCentreMethod::Harrington] {
            let Some((trial, out)) = check(rel, "opencap", side, UpAxis::Y, hip) else {
                return;
            };
            for label in [format!("{r}_HJC"), format!("{r}_HJC_reg")] {
                let d = (mean_over_window(&trial, &out, &label) - out.report.hip_centre).norm();
                rows.push((side, hip, label, d));
            }
        }
    }
    for (side, hip, label, d) in &rows {
        eprintln!("{side:?} {hip:?} vs {label}: {:.1} mm", d * 1e3);
        assert!(*d < 0.030, "{side:?} {hip:?} {label}: {:.1} mm", d * 1e3);
    }
    // Harrington's regression lands closer to OpenCap's hip centres than Bell's.
    for pair in rows.chunks(4) {
        assert!(pair[2].3 < pair[0].3 && pair[3].3 < pair[1].3, "{pair:?}");
    }
}

#[test]
fn opensim_gait2392_and_hamner() {
    for rel in [
        "opensim_gait2392_subject01/subject01_static.trc",
        "opensim_hamner_subject02/subject02_static.trc",
    ] {
        for side in [Side::Right, Side::Left] {
            if check(rel, "gait2392", side, UpAxis::Y, HipCentreMethod::Bell).is_none() {
                return;
            }
        }
    }
}

#[test]
fn opensim_jam() {
    for side in [Side::Right, Side::Left] {
        let Some((_, out)) = check(
            "opensim_jam_healthy/static1.trc",
            "jam",
            side,
            UpAxis::Y,
            HipCentreMethod::Bell,
        ) else {
            return;
        };
        // 1204 frames at 200 Hz: a 1 s window inside the trial.
        assert_eq!(out.report.window.len, 200);
    }
}

#[test]
fn plugin_gait_c3d_with_negative_z_up() {
    let rel = "biobuddy_functional_vicon/Test_func_anat.c3d";
    for side in [Side::Right, Side::Left] {
        if check(
            rel,
            "plugin-gait-medial",
            side,
            UpAxis::NegZ,
            HipCentreMethod::Bell,
        )
        .is_none()
        {
            return;
        }
    }
    // Read as Y-up, the pelvis lies on its side: refused with the reason.
    let trial = read(&data_file(rel).unwrap(), UpAxis::Y);
    let set = MarkerSet::preset("plugin-gait-medial").unwrap();
    let e = personalize(&trial, &set, Side::Right, &PersonalizeOptions::default()).unwrap_err();
    assert!(
        matches!(&e, LandmarkError::Implausible(m) if m.contains("not Y-up")),
        "{e}"
    );
}

/// The inner-level IK, started from scratch, finds the static pose of the personalized model.
#[test]
fn ik_recovers_the_static_pose() {
    let Some((trial, out)) = check(
        "opensim_gait2392_subject01/subject01_static.trc",
        "gait2392",
        Side::Right,
        UpAxis::Y,
        HipCentreMethod::Bell,
    ) else {
        return;
    };
    let model = Model::compile(&out.spec).unwrap();
    let p = model.nominal_params();
    let targets: Vec<Vector3<f64>> = model
        .markers()
        .iter()
        .map(|m| mean_over_window(&trial, &out, &m.name))
        .collect();
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    assert_eq!(map.columns.len(), model.markers().len());
    let opts = IkOptions::default();
    let mut ws = IkWorkspace::new(&model);
    let mut q = ws.seed(&model, &p, &targets, &opts);
    let fit = ws.solve(&model, &p, &targets, &mut q, &opts);
    assert!(fit.cost < 1e-18, "{fit:?}");
    // The pelvis may come back as another Euler triple of the same orientation; the joint
    // angles below it are unique.
    for (a, b) in q.iter().zip(&out.static_q).skip(6) {
        assert!((a - b).abs() < 1e-6, "{q:?} vs {:?}", out.static_q);
    }
}

#[test]
fn cli_personalize_writes_a_model_that_loads() {
    let Some(path) = data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let dir = jointfit_testkit::scratch("pers");
    let out = dir.join("expert1-right.toml");
    let args = [
        "personalize",
        "--static",
        path.to_str().unwrap(),
        "--markers",
        "opencap",
        "--side",
        "right",
        "--compare-hjc",
        "R_HJC",
        "-o",
        out.to_str().unwrap(),
    ];
    let (ok, stdout, stderr) = jointfit(&args);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("personalized right leg from"), "{stdout}");
    assert!(stdout.contains("pelvis width 253.9 mm"), "{stdout}");
    assert!(stdout.contains("R_HJC is "), "{stdout}");
    let (ok, shown, stderr) = jointfit(&["model", "show", out.to_str().unwrap(), "--json"]);
    assert!(ok, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&shown).unwrap();
    assert_eq!(v["name"], "expert1-right");
    assert_eq!(v["parameters"].as_array().unwrap().len(), 27);
    assert_eq!(v["markers"].as_array().unwrap().len(), 4 + 6 + 5 + 3);

    let mut json_args = args.to_vec();
    json_args.push("--json");
    let (ok, stdout, stderr) = jointfit(&json_args);
    assert!(ok, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["parameters"].as_array().unwrap().len(), 27);
    assert!(v["static_fk_error_mm"].as_f64().unwrap() < 1e-6);
    assert!(v["hjc_comparison"][0]["distance_mm"].as_f64().unwrap() < 30.0);

    // The wrong marker set: one line naming the missing labels; nothing written.
    let bad = dir.join("bad.toml");
    let stderr = refused_left_leg(&path, "gait2392", &bad);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains(
            "cannot personalize (the trial's labels fit the preset opencap: --markers opencap): \
             the static trial lacks 18 marker(s) that marker set \
             \"gait2392\" expects for the left leg: right ASIS and pelvis tracking \"R.ASIS\""
        ),
        "{stderr}"
    );
    assert!(!bad.exists());

    // Unknown preset, marker-set file with an error.
    let stderr = refused_left_leg(&path, "vicon", &bad);
    assert!(
        stderr.contains(
            "\"vicon\" is neither a marker-set file nor a preset (gait2392, opencap, \
             opencap-video, jam, plugin-gait, plugin-gait-sacr, plugin-gait-medial, \
             plugin-gait-basic, rajagopal)"
        ),
        "{stderr}"
    );
    let map = dir.join("lab.toml");
    std::fs::write(&map, "name = \"lab\"\n[pelvis]\nright_asis = 1\n").unwrap();
    let stderr = refused_left_leg(&path, map.to_str().unwrap(), &bad);
    assert!(
        stderr.contains(&format!("marker set {}: ", map.display())),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `personalize` of the left leg of `static_trial` with `markers` into `out`, which must
/// fail; its stderr.
fn refused_left_leg(
    static_trial: &std::path::Path,
    markers: &str,
    out: &std::path::Path,
) -> String {
    let (ok, _, stderr) = jointfit(&[
        "personalize",
        "--static",
        static_trial.to_str().unwrap(),
        "--markers",
        markers,
        "--side",
        "left",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok, "{markers}: {stderr}");
    stderr
}

#[test]
fn cli_personalize_c3d() {
    let Some(path) = data_file("biobuddy_functional_vicon/Test_func_anat.c3d") else {
        return;
    };
    let dir = jointfit_testkit::scratch("pers-c3d");
    let out = dir.join("vicon-left.toml");
    let (ok, stdout, stderr) = jointfit(&[
        "personalize",
        "--static",
        path.to_str().unwrap(),
        "--markers",
        "plugin-gait-medial",
        "--side",
        "left",
        "--up=-z",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("window: frames"), "{stdout}");
    let (ok, _, stderr) = jointfit(&["model", "show", out.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The static trial may be given as the positional argument, like every other command's
/// trial, or as `--static`: the same model either way; both at once, or neither, is a
/// command-line error (exit 2) before anything is read.
#[test]
fn cli_personalize_takes_the_static_trial_as_positional_or_option() {
    let (ok, _, stderr) = jointfit(&[
        "personalize",
        "a.trc",
        "--static",
        "b.trc",
        "--markers",
        "opencap",
        "-o",
        "never.toml",
    ]);
    assert!(!ok);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("cannot be used with"), "{stderr}");
    let (ok, _, stderr) = jointfit(&["personalize", "--markers", "opencap", "-o", "never.toml"]);
    assert!(!ok);
    assert!(stderr.contains("<STATIC|--static <FILE>>"), "{stderr}");
    assert!(!Path::new("never.toml").exists());

    let Some(path) = data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let dir = jointfit_testkit::scratch("pers-positional");
    let written = |how: &str, args: &[&str]| {
        let out = dir.join(format!("{how}.toml"));
        let mut all = vec!["personalize"];
        all.extend_from_slice(args);
        all.extend([
            "--markers",
            "opencap",
            "--name",
            "s",
            "-o",
            out.to_str().unwrap(),
        ]);
        let (ok, stdout, stderr) = jointfit(&all);
        assert!(ok, "{how}: {stderr}");
        assert!(stdout.contains("wrote "), "{how}: {stdout}");
        std::fs::read(&out).unwrap()
    };
    let positional = written("positional", &[path.to_str().unwrap()]);
    let option = written("option", &["--static", path.to_str().unwrap()]);
    assert_eq!(positional, option);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A static trial without the chosen set's labels: the one-line error names the presets
/// whose every label the trial has (checked against the trial's own labels), else points to
/// `markers suggest`; nothing is written.
#[test]
fn cli_personalize_names_the_preset_that_fits() {
    let (Some(gait), Some(walk)) = (
        data_file("opensim_gait2392_subject01/subject01_static.trc"),
        data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("pers-hint");
    let out = dir.join("never.toml");
    let run = |trial: &Path, preset: &str| {
        let (ok, _, stderr) = jointfit(&[
            "personalize",
            trial.to_str().unwrap(),
            "--markers",
            preset,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!ok);
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(!out.exists());
        stderr
    };
    let err = run(&gait, "opencap");
    assert!(
        err.contains(
            "cannot personalize (the trial's labels fit the preset gait2392: --markers gait2392): \
             the static trial lacks 19 marker(s) that marker set \"opencap\""
        ),
        "{err}"
    );
    // The walk lacks the epicondyles and malleoli every preset needs.
    let err = run(&walk, "gait2392");
    assert!(
        err.contains("cannot personalize (no preset fits its labels; `jointfit markers suggest "),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
