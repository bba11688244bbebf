//! Both legs and the pelvis in one model: `personalize --side both` (the default) on the
//! shared static trials against the one-sided personalizations, the one-leg fallback, and a
//! seeded synthetic both-leg trial whose perturbed parameters `calibrate` recovers.

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::Side;
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_landmarks::bilateral::common_window;
use jointfit_landmarks::bilateral::personalize_sides;
use jointfit_landmarks::bilateral::PersonalizedModel;
use jointfit_landmarks::bilateral::Sides;
use jointfit_landmarks::functional::apply::FunctionalTrials;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{
    personalize, personalize_in, LandmarkError, PersonalizeOptions, Personalized,
};
use jointfit_testkit::data_file;

use super::jointfit;

/// A shared static trial, Y-up (the Vicon C3D is −Z up).
fn read(rel: &str) -> Option<Trial> {
    let path = data_file(rel)?;
    if rel.ends_with(".c3d") {
        let mut t = jointfit_io::c3d::read_c3d(&path)
            .unwrap()
            .to_trial()
            .unwrap();
        t.rotate(&jointfit::spatial::up_axis_rotation(
            jointfit::spatial::UpAxis::NegZ,
        ));
        return Some(t);
    }
    Some(jointfit_io::trc::read_trc(&path).unwrap())
}

fn both(trial: &Trial, set: &MarkerSet) -> Result<PersonalizedModel, LandmarkError> {
    let out = personalize_sides(
        trial,
        set,
        Sides::Both,
        &PersonalizeOptions::default(),
        &FunctionalTrials::default(),
    )?;
    assert!(out.warning.is_none(), "{:?}", out.warning);
    Ok(out.model)
}

/// Both legs share one pelvis: each leg of the bilateral model is that leg's personalization
/// over the common static window (the stillest window of all markers of both legs), bit for
/// bit (parameters: nominal, bounds, prior; markers at the joined static pose), so the two
/// legs' pelvis frames are identical. Against the one-sided personalizations (each over its
/// own window) a leg differs only by the subject's sway between the windows: every marker at
/// the static pose within 1 mm, or 6 mm on the Vicon static with the basic plug-in gait set
/// (its right leg's own window is frames 62–, the common one 85–: the pelvis markers moved
/// 5.6 mm), and every nominal parameter within 0.5 mm or 0.01 rad.
#[test]
fn both_legs_share_one_pelvis_and_match_the_one_sided_personalizations() {
    for (rel, preset, sway) in [
        ("opencap_expert1/static1.trc", "opencap", 1e-3),
        (
            "opensim_hamner_subject02/subject02_static.trc",
            "gait2392",
            1e-3,
        ),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-medial",
            1e-3,
        ),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-basic",
            6e-3,
        ),
    ] {
        let Some(trial) = read(rel) else { return };
        let set = MarkerSet::preset(preset).unwrap();
        let PersonalizedModel::Both(b) = both(&trial, &set).unwrap() else {
            panic!("{rel}: not bilateral")
        };
        assert_eq!(b.spec.parameters.len(), 54, "{rel}");
        let opts = PersonalizeOptions::default();
        let common = common_window(&trial, &set, &opts).unwrap().unwrap();
        assert_eq!(b.right.report.window.first, common.first, "{rel}");
        assert_eq!(b.left.report.window.first, common.first, "{rel}");
        assert_eq!(b.pelvis_gap, 0.0, "{rel}: one pelvis");
        assert_eq!(
            b.right.frames.pelvis.rot, b.left.frames.pelvis.rot,
            "{rel}: one pelvis"
        );
        assert_eq!(b.right.frames.pelvis.trans, b.left.frames.pelvis.trans);
        let model = Model::compile(&b.spec).unwrap();
        assert_eq!(model.coordinates().len(), 18);
        let mut kin = KinData::new(&model);
        let nominal = model.nominal_params();
        forward_kinematics(&model, &nominal, &b.static_q, Want::Positions, &mut kin);
        // Before: each leg over its own window; the pelvis markers moved between them.
        let own: Vec<_> = [Side::Right, Side::Left]
            .map(|side| personalize(&trial, &set, side, &opts).unwrap())
            .into_iter()
            .collect();
        let old_gap = pelvis_marker_gap(&own[0], &own[1]);
        eprintln!(
            "{rel}: windows right {} left {} common {}; pelvis markers moved {:.3} mm between \
             the legs' own windows",
            own[0].report.window.first,
            own[1].report.window.first,
            common.first,
            old_gap * 1e3
        );
        // The bilateral model's suffixes of the right and left leg's names.
        for (side, s) in [(Side::Right, "_r"), (Side::Left, "_l")] {
            let func = FunctionalTrials::default();
            let exact = personalize_in(&trial, &set, side, &opts, &func, Some(&common)).unwrap();
            let own = personalize(&trial, &set, side, &opts).unwrap();
            let mut worst = [0.0f64; 2];
            for (p, o) in exact.spec.parameters.iter().zip(&own.spec.parameters) {
                let q = b
                    .spec
                    .parameters
                    .iter()
                    .find(|q| q.name == format!("{}{s}", p.name))
                    .unwrap();
                assert_eq!(q.nominal, p.nominal, "{rel} {}", q.name);
                assert_eq!((q.lower, q.upper), (p.lower, p.upper), "{rel} {}", q.name);
                assert_eq!(q.prior_sd, p.prior_sd, "{rel} {}", q.name);
                assert_eq!(q.group, format!("{}{s}", p.group));
                let d = (q.nominal - o.nominal).abs();
                let k = usize::from(matches!(p.unit, jointfit::model::spec::Unit::Radian));
                worst[k] = worst[k].max(d);
            }
            for (exact_or_own, tol, what) in [(&exact, 1e-12, "common"), (&own, sway, "own")] {
                let far = static_marker_distance(&model, &kin, exact_or_own);
                eprintln!(
                    "{rel} {side:?}: markers at the static pose within {:.3} mm of the \
                     one-sided model over the {what} window; nominals within {:.3} mm / {:.4} \
                     rad of the one-sided model",
                    far * 1e3,
                    worst[0] * 1e3,
                    worst[1]
                );
                assert!(far < tol, "{rel} {side:?}: {far:e} m");
            }
            assert!(
                worst[0] < 6e-3 && worst[1] < 0.06,
                "{rel} {side:?}: {worst:?}"
            );
        }
    }
}

/// A static trial with one leg's markers only gives that leg's one-sided model and a warning;
/// a leg missing only some markers is an error naming them.
#[test]
fn one_leg_trial_falls_back_with_a_warning() {
    let Some(trial) = read("opencap_expert1/static1.trc") else {
        return;
    };
    let set = MarkerSet::preset("opencap").unwrap();
    let right_only: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| !l.starts_with("L_"))
        .collect();
    let t = trial.select(&right_only).unwrap();
    let opts = PersonalizeOptions::default();
    let out =
        personalize_sides(&t, &set, Sides::Both, &opts, &FunctionalTrials::default()).unwrap();
    let w = out.warning.unwrap();
    assert!(
        w.starts_with("the static trial has none of the left leg's markers (L_knee, L_mknee"),
        "{w}"
    );
    assert!(w.ends_with("personalized the right leg only"), "{w}");
    let PersonalizedModel::One(Side::Right, p) = out.model else {
        panic!("not the right leg")
    };
    let one = personalize(&trial, &set, Side::Right, &opts).unwrap();
    assert_eq!(p.spec.parameters, one.spec.parameters);

    let no_toe: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| *l != "L_toe")
        .collect();
    let e = both(&trial.select(&no_toe).unwrap(), &set).unwrap_err();
    assert!(
        matches!(&e, LandmarkError::MissingMarkers { side: "left", missing, .. }
            if missing.iter().all(|m| m.contains("\"L_toe\""))),
        "{e}"
    );
}

#[test]
fn cli_default_is_both_legs_and_warns_on_one_leg() {
    let Some(trial) = read("opencap_expert1/static1.trc") else {
        return;
    };
    let path = data_file("opencap_expert1/static1.trc").unwrap();
    let dir = jointfit_testkit::scratch("bilateral");
    let out = dir.join("both.toml");
    let (ok, stdout, stderr) = jointfit(&[
        "personalize",
        "--static",
        path.to_str().unwrap(),
        "--markers",
        "opencap",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["side"], "both");
    assert_eq!(v["parameters"].as_array().unwrap().len(), 54);
    assert_eq!(v["legs"].as_array().unwrap().len(), 2);
    let (ok, shown, _) = jointfit(&["model", "show", out.to_str().unwrap(), "--json"]);
    assert!(ok);
    let m: serde_json::Value = serde_json::from_str(&shown).unwrap();
    assert_eq!(m["coordinates"].as_array().unwrap().len(), 18);

    // The right leg's markers only: the right leg's model and one warning line.
    let right_only: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| !l.starts_with("L_"))
        .collect();
    let trc = dir.join("right_only.trc");
    jointfit_io::trc::write_trc(
        &trc,
        &trial.select(&right_only).unwrap(),
        &Default::default(),
    )
    .unwrap();
    let one = dir.join("one.toml");
    let (ok, stdout, stderr) = jointfit(&[
        "personalize",
        "--static",
        trc.to_str().unwrap(),
        "--markers",
        "opencap",
        "-o",
        one.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("warning: "), "{stderr}");
    assert!(
        stderr.contains("personalized the right leg only"),
        "{stderr}"
    );
    assert!(stdout.contains("personalized right leg from"), "{stdout}");
}

/// `synth lower-limb` moves both legs; `calibrate` recovers all 54 perturbed parameters from
/// the noiseless trial, and `--joints hip` frees both hips (12 parameters), `hip_l` one.
#[test]
fn calibrate_recovers_both_legs_from_a_synthetic_trial() {
    let dir = jointfit_testkit::scratch("bilateral-synth");
    let (trc, truth, fitted) = (
        dir.join("both.trc"),
        dir.join("truth.toml"),
        dir.join("fitted.toml"),
    );
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let (ok, _, stderr) = jointfit(&[
        "synth",
        "lower-limb",
        "--motion",
        "all",
        "--frames",
        "60",
        "--perturb-mm",
        "10",
        "--perturb-deg",
        "5",
        "--seed",
        "11",
        "-o",
        &s(&trc),
        "--truth",
        &s(&truth),
    ]);
    assert!(ok, "{stderr}");
    let (ok, stdout, stderr) = jointfit(&[
        "calibrate",
        "lower-limb",
        &s(&trc),
        "--json",
        "-o",
        &s(&fitted),
    ]);
    assert!(ok, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["free_parameters"], 54);
    let load = |p: &std::path::Path| {
        let text = std::fs::read_to_string(p).unwrap();
        jointfit::model::spec::ModelSpec::from_toml(&text).unwrap()
    };
    let (t, f) = (load(&truth), load(&fitted));
    let nominal = jointfit::model::lower_limb::builtin("lower-limb").unwrap();
    let mut moved = 0;
    for ((pt, pf), pn) in t
        .parameters
        .iter()
        .zip(&f.parameters)
        .zip(&nominal.parameters)
    {
        assert_eq!(pt.name, pf.name);
        if (pt.nominal - pn.nominal).abs() > 1e-4 {
            moved += 1;
        }
        assert!(
            (pt.nominal - pf.nominal).abs() < 1e-6,
            "{}: truth {} fitted {}",
            pt.name,
            pt.nominal,
            pf.nominal
        );
    }
    assert!(moved > 40, "only {moved} parameters were perturbed");

    for (joints, free) in [("hip", 12), ("hip_l", 6), ("knee_r,ankle", 33)] {
        let (ok, stdout, stderr) = jointfit(&[
            "calibrate",
            "lower-limb",
            &s(&trc),
            "--joints",
            joints,
            "--json",
            "-o",
            &s(&dir.join("part.toml")),
        ]);
        assert!(ok, "{joints}: {stderr}");
        let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(v["free_parameters"], free, "{joints}");
        let names: Vec<&str> = v["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["name"].as_str().unwrap())
            .collect();
        if joints == "hip_l" {
            assert!(names
                .iter()
                .all(|n| n.starts_with("hip_") && n.ends_with("_l")));
        }
    }
}

/// A shared trial, a preset, the trial's up axis and label renames.
type Case<'a> = (
    &'a str,
    &'a str,
    jointfit::spatial::UpAxis,
    &'a [(&'a str, &'a str)],
);

/// Every preset personalizes both legs of a real shared static trial. Where no shared trial
/// carries a preset's exact labels, a trial with the same placement is read with its labels
/// renamed (stated per case).
#[test]
fn every_preset_personalizes_both_legs_of_a_shared_trial() {
    use jointfit::spatial::UpAxis;
    let jam_as_rajagopal: &[(&str, &str)] = &[
        ("R.Mkn", "R.MKnee"),
        ("L.Mkn", "L.MKnee"),
        ("R.Man", "R.MAnkle"),
        ("L.Man", "L.MAnkle"),
        ("R.MT0", "R.Toe"),
        ("L.MT0", "L.Toe"),
    ];
    let cases: [Case; 10] = [
        ("opencap_expert1/static1.trc", "opencap", UpAxis::Y, &[]),
        (
            "opencap_video_subject0/neutral.trc",
            "opencap-video",
            UpAxis::Y,
            &[],
        ),
        (
            "opensim_gait2392_subject01/subject01_static.trc",
            "gait2392",
            UpAxis::Y,
            &[],
        ),
        (
            "opensim_hamner_subject02/subject02_static.trc",
            "gait2392",
            UpAxis::Y,
            &[],
        ),
        ("opensim_jam_healthy/static1.trc", "jam", UpAxis::Y, &[]),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-medial",
            UpAxis::NegZ,
            &[],
        ),
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-basic",
            UpAxis::NegZ,
            &[],
        ),
        // Its medial markers stand in for the chord function (which tests/cli/plugin_gait.rs
        // checks against Vicon with the subject measurements).
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait",
            UpAxis::NegZ,
            &[],
        ),
        // Renamed: no shared trial has a SACR marker together with medial knee markers.
        (
            "biobuddy_functional_vicon/Test_func_anat.c3d",
            "plugin-gait-sacr",
            UpAxis::NegZ,
            &[("S1", "SACR")],
        ),
        // Renamed: the JAM static trial is the Rajagopal placement with other medial labels.
        (
            "opensim_jam_healthy/static1.trc",
            "rajagopal",
            UpAxis::Y,
            jam_as_rajagopal,
        ),
    ];
    let mut covered: Vec<&str> = Vec::new();
    for (rel, preset, up, renames) in cases {
        let Some(path) = data_file(rel) else { return };
        let t = read_renamed(&path, up, renames);
        let set = MarkerSet::preset(preset).unwrap();
        let model = both(&t, &set).unwrap_or_else(|e| panic!("{rel} {preset}: {e}"));
        let PersonalizedModel::Both(b) = model else {
            panic!("{rel} {preset}: one leg")
        };
        assert_eq!(b.spec.parameters.len(), 54, "{rel} {preset}");
        for (_, leg) in [(Side::Right, &b.right), (Side::Left, &b.left)] {
            assert!(leg.report.static_fk_error < 1e-9, "{rel} {preset}");
            let pw = leg.report.pelvis_width;
            assert!((0.15..0.40).contains(&pw), "{rel} {preset}: PW {pw}");
        }
        covered.push(preset);
    }
    for name in jointfit_landmarks::markerset::PRESET_NAMES {
        assert!(
            covered.contains(&name),
            "preset {name} has no shared-trial check"
        );
    }
}

/// The largest distance between the lab positions of a pelvis marker in two one-sided
/// personalizations (each over its own static window).
fn pelvis_marker_gap(a: &Personalized, b: &Personalized) -> f64 {
    a.spec
        .markers
        .iter()
        .filter(|m| m.segment == "pelvis")
        .map(|m| {
            let x = nalgebra::Vector3::from(m.position);
            let y = b.spec.markers.iter().find(|n| n.name == m.name).unwrap();
            let y = nalgebra::Vector3::from(y.position);
            (a.frames.pelvis.transform_point(&x) - b.frames.pelvis.transform_point(&y)).norm()
        })
        .fold(0.0, f64::max)
}

/// The largest distance between a marker of `leg` at its static pose and the same marker of
/// the bilateral `model` at its static pose (`kin`).
fn static_marker_distance(model: &Model, kin: &KinData, leg: &Personalized) -> f64 {
    let m1 = Model::compile(&leg.spec).unwrap();
    let mut k1 = KinData::new(&m1);
    let p1 = m1.nominal_params();
    forward_kinematics(&m1, &p1, &leg.static_q, Want::Positions, &mut k1);
    let mut far = 0.0f64;
    for (m, x) in m1.markers().iter().zip(&k1.markers) {
        let j = model
            .markers()
            .iter()
            .position(|n| n.name == m.name)
            .unwrap();
        far = far.max((kin.markers[j] - x).norm());
    }
    far
}

/// The trial at `path` turned to Y up, its labels renamed (`from`, `to`).
fn read_renamed(
    path: &std::path::Path,
    up: jointfit::spatial::UpAxis,
    renames: &[(&str, &str)],
) -> Trial {
    let mut t = super::personalize::read(path, up);
    if !renames.is_empty() {
        let labels = t
            .labels()
            .iter()
            .map(|l| {
                renames
                    .iter()
                    .find(|(from, _)| from == l)
                    .map_or(l.clone(), |(_, to)| to.to_string())
            })
            .collect();
        t = Trial::new(labels, t.rate(), t.first_frame(), t.positions().to_vec()).unwrap();
    }
    t
}
