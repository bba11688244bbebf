//! The anatomical-landmark method against a synthetic subject whose joints are known: the
//! template leg with its hip centre at Bell's position, epicondyle markers on its knee axis and
//! malleolus markers on its talocrural axis, posed by forward kinematics.

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::spec::{MarkerSpec, ModelSpec};
use jointfit::model::Model;
use jointfit::spatial::up_axis_rotation;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_landmarks::markerset::LegMarkers;
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::markerset::PelvisMarkers;
use jointfit_landmarks::{personalize, LandmarkError, PersonalizeOptions, Personalized};
use jointfit_testkit::synth::{synthetic_trial, Noise};
use nalgebra::{Matrix3, Rotation3, Vector3};

const PW: f64 = 0.24;
const KNEE_HALF: f64 = 0.05;
const ANKLE_HALF: f64 = 0.035;

/// The built-in markers' name prefix.
fn prefix(side: Side) -> &'static str {
    match side {
        Side::Right => "R",
        Side::Left => "L",
    }
}

/// The synthetic subject: the template with Bell's hip centre and landmark markers.
fn truth_spec(side: Side) -> ModelSpec {
    let s = side.sign();
    let r = prefix(side);
    let mut spec = lower_limb(side);
    let set = |spec: &mut ModelSpec, name: &str, v: f64| {
        spec.parameters
            .iter_mut()
            .find(|p| p.name == name)
            .unwrap()
            .nominal = v;
    };
    set(&mut spec, "hip_pelvis_anterior", -0.19 * PW);
    set(&mut spec, "hip_pelvis_superior", -0.30 * PW);
    set(&mut spec, "hip_pelvis_lateral", 0.36 * PW);
    let nominal = |name: &str| {
        spec.parameters
            .iter()
            .find(|p| p.name == name)
            .unwrap()
            .nominal
    };
    // PSIS level with the ASIS, so that the landmark pelvis frame is the template's.
    for m in spec.markers.iter_mut().filter(|m| m.name.ends_with("PSI")) {
        m.position[1] = 0.0;
    }
    let knee_y = nominal("knee_thigh_superior");
    let ankle_y = nominal("talocrural_shank_superior");
    let rx = s * nominal("talocrural_shank_frontal");
    // Rightward talocrural axis in the shank (ry = 0): (0, −sin rx, cos rx).
    let d = Vector3::new(0.0, -rx.sin(), rx.cos());
    let c = Vector3::new(0.0, ankle_y, 0.0);
    let lat = c + s * ANKLE_HALF * d;
    let med = c - s * ANKLE_HALF * d;
    let mk = |name: String, segment: &str, p: [f64; 3]| MarkerSpec {
        name,
        segment: segment.into(),
        position: p,
        weight: 1.0,
    };
    spec.markers.extend([
        mk(format!("{r}KNL"), "thigh", [0.0, knee_y, s * KNEE_HALF]),
        mk(format!("{r}KNM"), "thigh", [0.0, knee_y, -s * KNEE_HALF]),
        mk(format!("{r}ANL"), "shank", lat.into()),
        mk(format!("{r}ANM"), "shank", med.into()),
    ]);
    spec
}

fn marker_set(side: Side) -> MarkerSet {
    let r = prefix(side);
    let l = |n: &str| format!("{r}{n}");
    let leg = LegMarkers {
        lateral_epicondyle: l("KNL"),
        medial_epicondyle: l("KNM"),
        lateral_malleolus: l("ANL"),
        medial_malleolus: l("ANM"),
        heel: l("HEE"),
        forefoot: vec![l("TOE")],
        thigh: vec![l("THI"), l("THA"), l("THP"), l("KNE")],
        shank: vec![l("TIB"), l("TIA"), l("TIP"), l("ANK")],
        foot: vec![l("HEE"), l("TOE"), l("MT5")],
    };
    let (right, left) = match side {
        Side::Right => (Some(leg), None),
        Side::Left => (None, Some(leg)),
    };
    MarkerSet {
        name: "synthetic".into(),
        description: String::new(),
        pelvis: PelvisMarkers {
            right_asis: "RASI".into(),
            left_asis: "LASI".into(),
            right_psis: Some("RPSI".into()),
            left_psis: Some("LPSI".into()),
            sacrum: None,
            tracking: vec!["RASI".into(), "LASI".into(), "RPSI".into(), "LPSI".into()],
        },
        right,
        left,
    }
}

/// Standing pose of the synthetic subject (model coordinate order).
fn static_pose(model: &Model) -> Vec<f64> {
    let mut q = model.default_coords();
    for (name, v) in [
        ("pelvis_tx", 0.3),
        ("pelvis_ty", 0.93),
        ("pelvis_tilt", 0.05),
        ("hip_flexion", 0.1),
        ("hip_adduction", 0.03),
        ("hip_rotation", 0.05),
        ("knee_flexion", 0.08),
        ("ankle_dorsiflexion", 0.05),
        ("subtalar_inversion", 0.02),
    ] {
        q[model.coord_id(name).unwrap()] = v;
    }
    q
}

/// Markers of `model` at `q`, repeated over `frames` frames at 100 Hz.
fn trial_at(model: &Model, q: &[f64], frames: usize) -> Trial {
    let p = model.nominal_params();
    synthetic_trial(model, &p, frames, 100.0, |_| q.to_vec(), Noise::None, 0).trial
}

fn synthetic(side: Side) -> (Model, Vec<f64>, Trial) {
    let model = Model::compile(&truth_spec(side)).unwrap();
    let q = static_pose(&model);
    let trial = trial_at(&model, &q, 5);
    (model, q, trial)
}

fn run(trial: &Trial, side: Side) -> Result<Personalized, LandmarkError> {
    personalize(
        trial,
        &marker_set(side),
        side,
        &PersonalizeOptions::default(),
    )
}

fn params(p: &Personalized) -> Vec<f64> {
    p.spec.parameters.iter().map(|p| p.nominal).collect()
}

/// World position of marker `name` of `model` at (p, q).
fn markers_at(model: &Model, p: &[f64], q: &[f64]) -> Vec<(String, Vector3<f64>)> {
    let mut kin = KinData::new(model);
    forward_kinematics(model, p, q, Want::Positions, &mut kin);
    model
        .markers()
        .iter()
        .map(|m| m.name.clone())
        .zip(kin.markers)
        .collect()
}

#[test]
fn static_pose_is_reproduced_and_joints_recovered() {
    for side in [Side::Right, Side::Left] {
        let (truth, q_truth, trial) = synthetic(side);
        let out = run(&trial, side).unwrap();
        let rep = &out.report;
        assert!(rep.static_fk_error < 1e-12, "{}", rep.static_fk_error);
        assert_eq!((rep.window.first, rep.window.len), (0, 5));
        assert!((rep.pelvis_width - PW).abs() < 1e-12);
        assert!((rep.knee_width - 2.0 * KNEE_HALF).abs() < 1e-12);
        assert!((rep.ankle_width - 2.0 * ANKLE_HALF).abs() < 1e-12);
        for seg in &rep.segments {
            assert!(seg.max < 1e-12, "{}: {}", seg.segment, seg.max);
        }
        // Hip centre: the truth thigh's origin.
        let mut kin = KinData::new(&truth);
        forward_kinematics(
            &truth,
            &truth.nominal_params(),
            &q_truth,
            Want::Positions,
            &mut kin,
        );
        let thigh_index = truth.segments().iter().position(|s| s.name == "thigh");
        let thigh = kin.segment_poses[thigh_index.unwrap()];
        assert!((rep.hip_centre - thigh.trans).norm() < 1e-12);
        // Hip centre in the pelvis: Bell's fractions, mirrored by the template.
        let model = Model::compile(&out.spec).unwrap();
        let p = params(&out);
        let get = |n: &str| p[model.param_id(n).unwrap().0];
        assert!((get("hip_pelvis_anterior") + 0.19 * PW).abs() < 1e-12);
        assert!((get("hip_pelvis_superior") + 0.30 * PW).abs() < 1e-12);
        assert!((get("hip_pelvis_lateral") - 0.36 * PW).abs() < 1e-12);
        assert!((get("subtalar_talus_superior") + 0.0124).abs() < 1e-12);
        assert!((get("subtalar_foot_transverse") - 23f64.to_radians()).abs() < 1e-12);
        assert!((get("subtalar_foot_sagittal") - 42f64.to_radians()).abs() < 1e-12);
        // The truth's pelvis, thigh and shank frames are landmark frames too (its knee axis
        // is the thigh's z, its malleolus line lies in the shank's y-z plane), so the knee and
        // talocrural parameters and the pose down to the knee come back exactly.
        for name in [
            "knee_thigh_frontal",
            "knee_thigh_transverse",
            "knee_shank_frontal",
            "knee_shank_transverse",
            "knee_thigh_anterior",
            "knee_thigh_superior",
            "knee_shank_anterior",
            "knee_shank_superior",
            "knee_shank_lateral",
            "talocrural_shank_frontal",
            "talocrural_shank_transverse",
            "talocrural_shank_anterior",
            "talocrural_shank_superior",
            "talocrural_shank_lateral",
        ] {
            let t = truth.parameters()[truth.param_id(name).unwrap().0].nominal;
            assert!(
                (get(name) - t).abs() < 1e-12,
                "{side:?} {name}: {} vs {t}",
                get(name)
            );
        }
        for ((got, want), c) in out
            .static_q
            .iter()
            .zip(&q_truth)
            .zip(model.coordinates())
            .take(10)
        {
            assert!((got - want).abs() < 1e-12, "{side:?} {}", c.name);
        }
        // The same physical knee and talocrural axes with the same sign: a change of knee or
        // ankle angle in the truth is the same change in the personalized model.
        for (coord, delta) in [("knee_flexion", 0.9), ("ankle_dorsiflexion", -0.4)] {
            let mut qt = q_truth.clone();
            qt[truth.coord_id(coord).unwrap()] += delta;
            let mut qp = out.static_q.clone();
            qp[model.coord_id(coord).unwrap()] += delta;
            let want = markers_at(&truth, &truth.nominal_params(), &qt);
            for (name, x) in markers_at(&model, &p, &qp) {
                let t = want.iter().find(|(n, _)| *n == name).unwrap().1;
                assert!((x - t).norm() < 1e-12, "{side:?} {coord}: {name}");
            }
        }
    }
}

#[test]
fn the_written_model_reproduces_the_static_trial() {
    let (_, _, trial) = synthetic(Side::Right);
    let out = run(&trial, Side::Right).unwrap();
    let again = ModelSpec::from_toml(&out.spec.to_toml()).unwrap();
    assert_eq!(again, out.spec);
    let model = Model::compile(&again).unwrap();
    for (name, x) in markers_at(&model, &model.nominal_params(), &out.static_q) {
        let t = trial.get(0, trial.index_of(&name).unwrap()).unwrap();
        assert!((x - t).norm() < 1e-12, "{name}");
    }
    // Bounds: Reinbolt's cubes and cones around the nominal values.
    for p in &again.parameters {
        let half = 0.5 * (p.upper - p.lower);
        let want = if p.unit == jointfit::model::spec::Unit::Radian {
            30f64.to_radians()
        } else if p.group == "hip" {
            0.375 * PW
        } else if p.group == "knee" {
            KNEE_HALF
        } else {
            ANKLE_HALF
        };
        assert!((half - want).abs() < 1e-12, "{}", p.name);
        assert!((0.5 * (p.upper + p.lower) - p.nominal).abs() < 1e-12);
    }
}

#[test]
fn heading_and_position_in_the_lab_do_not_matter() {
    let (_, _, trial) = synthetic(Side::Right);
    let base = run(&trial, Side::Right).unwrap();
    for heading in [90.0f64, 180.0, -135.0] {
        let mut moved = trial.clone();
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), heading.to_radians());
        for m in 0..trial.labels().len() {
            let placed: Vec<_> = (trial.trajectory(m).iter())
                .map(|x| r * *x + Vector3::new(3.0, 0.2, -7.0))
                .collect();
            moved.set_trajectory(m, &placed);
        }
        let out = run(&moved, Side::Right).unwrap();
        for (a, b) in params(&base).iter().zip(params(&out)) {
            assert!((a - b).abs() < 1e-9, "heading {heading}");
        }
        for (a, b) in base.spec.markers.iter().zip(&out.spec.markers) {
            let d = Vector3::from(a.position) - Vector3::from(b.position);
            assert!(d.norm() < 1e-9, "heading {heading}: {}", a.name);
        }
        assert!(out.report.static_fk_error < 1e-9);
    }
}

#[test]
fn left_leg_of_the_mirror_image_has_the_right_legs_parameters() {
    let (_, _, right) = synthetic(Side::Right);
    let (_, _, left) = synthetic(Side::Left);
    let a = run(&right, Side::Right).unwrap();
    let b = run(&left, Side::Left).unwrap();
    for (pa, pb) in a.spec.parameters.iter().zip(&b.spec.parameters) {
        assert!((pa.nominal - pb.nominal).abs() < 1e-12, "{}", pa.name);
    }
    let levelling = |p: &Personalized| {
        let j = p
            .spec
            .joints
            .iter()
            .find(|j| j.name == "talocrural")
            .unwrap();
        match j.child_offset.rz {
            jointfit::model::spec::ScalarSpec::Fixed(v) => v,
            _ => panic!("levelling angle is fixed"),
        }
    };
    assert!((levelling(&a) - levelling(&b)).abs() < 1e-12);
}

#[test]
fn gaps_steer_the_window() {
    let (model, q, _) = synthetic(Side::Right);
    let mut trial = trial_at(&model, &q, 300);
    let c = trial.index_of("RKNM").unwrap();
    let mut traj = trial.trajectory(c);
    for x in traj.iter_mut().take(150) {
        *x = Vector3::repeat(f64::NAN);
    }
    trial.set_trajectory(c, &traj);
    let out = run(&trial, Side::Right).unwrap();
    let w = &out.report.window;
    assert_eq!((w.first, w.len, w.complete_frames), (150, 100, 150));
    // A needed marker never present: named.
    trial.set_trajectory(c, &vec![Vector3::repeat(f64::NAN); 300]);
    let e = run(&trial, Side::Right).unwrap_err().to_string();
    assert!(e.contains("never present: [\"RKNM\"]"), "{e}");
}

#[test]
fn missing_labels_are_listed_with_their_roles() {
    let (_, _, trial) = synthetic(Side::Right);
    let keep: Vec<&str> = trial
        .labels()
        .iter()
        .map(String::as_str)
        .filter(|l| !matches!(*l, "RKNM" | "RANK"))
        .collect();
    let cut = trial.select(&keep).unwrap();
    let e = run(&cut, Side::Right).unwrap_err();
    let LandmarkError::MissingMarkers { missing, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(
        missing,
        &["medial epicondyle \"RKNM\"", "shank tracking \"RANK\""]
    );
    let msg = e.to_string();
    assert!(
        msg.starts_with(
            "the static trial lacks 2 marker(s) that marker set \"synthetic\" expects for the \
             right leg: medial epicondyle \"RKNM\", shank tracking \"RANK\"; the trial has: RASI, \
             LASI"
        ),
        "{msg}"
    );
}

#[test]
fn collinear_tracking_markers_are_refused() {
    let (_, _, mut trial) = synthetic(Side::Right);
    // Put the shank markers on one line.
    let ids: Vec<usize> = ["RTIB", "RTIA", "RTIP", "RANK"]
        .iter()
        .map(|n| trial.index_of(n).unwrap())
        .collect();
    let a = trial.get(0, ids[0]).unwrap();
    let b = trial.get(0, ids[2]).unwrap();
    for (k, &c) in ids.iter().enumerate() {
        let x = a + (b - a) * (k as f64 / 3.0);
        trial.set_trajectory(c, &vec![x; trial.n_frames()]);
    }
    let e = run(&trial, Side::Right).unwrap_err();
    assert!(
        matches!(&e, LandmarkError::Collinear { segment, .. } if segment == "shank"),
        "{e}"
    );
    assert!(e.to_string().starts_with(
        "shank tracking markers [\"RTIB\", \"RTIA\", \"RTIP\", \"RANK\"] lie within 0.0 mm of \
         one line"
    ));
}

#[test]
fn swapped_labels_and_wrong_up_axis_are_explained() {
    let (_, _, trial) = synthetic(Side::Right);
    let mut set = marker_set(Side::Right);
    let leg = set.right.as_mut().unwrap();
    std::mem::swap(&mut leg.lateral_epicondyle, &mut leg.medial_epicondyle);
    let e = personalize(&trial, &set, Side::Right, &PersonalizeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("lateral epicondyle lies medial"), "{e}");

    let mut set = marker_set(Side::Right);
    let leg = set.right.as_mut().unwrap();
    leg.forefoot = vec![leg.heel.clone()];
    leg.heel = "RTOE".into();
    let e = personalize(&trial, &set, Side::Right, &PersonalizeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("forefoot markers lie behind the heel"), "{e}");

    // A Z-up recording read as Y-up.
    let mut zup = trial.clone();
    let to_z: Matrix3<f64> = up_axis_rotation(UpAxis::Z).transpose();
    zup.rotate(&to_z);
    let e = run(&zup, Side::Right).unwrap_err().to_string();
    assert!(e.contains("the trial is not Y-up"), "{e}");
    // … and read correctly.
    let mut back = zup;
    back.rotate(&up_axis_rotation(UpAxis::Z));
    run(&back, Side::Right).unwrap();

    // The other leg's data under this leg's name: the knee is across the midline.
    let (_, _, left) = synthetic(Side::Left);
    let mut set = marker_set(Side::Left);
    set.right = set.left.take();
    let e = personalize(&left, &set, Side::Right, &PersonalizeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("lies medial of the medial one"), "{e}");
}

#[test]
fn options_are_checked() {
    let (_, _, trial) = synthetic(Side::Right);
    let opts = PersonalizeOptions {
        window_seconds: 0.0,
        ..PersonalizeOptions::default()
    };
    let e = personalize(&trial, &marker_set(Side::Right), Side::Right, &opts).unwrap_err();
    assert_eq!(e.to_string(), "invalid option: window_seconds = 0");
}
