//! The `.osim` reader ([`jointfit_io::osim_read`]) against OpenSim 4.6: every shared OpenSim
//! model loads, and at random poses every body's pose and every marker position from
//! jointfit's forward kinematics equal OpenSim's to 1e-9 m (rotation entries to 1e-9), with
//! the coupled coordinates jointfit computes satisfying OpenSim's constraints.

use std::path::{Path, PathBuf};

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::custom::MotionType;
use jointfit::model::{CoordKind, Model};
use jointfit_io::osim_read::read_osim;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use jointfit_testkit::script::osim_check;

/// Runs `osim_check.py MODE` with `request` on stdin; `None` (skipped) without Python.
fn check(mode: &str, request: &Value) -> Option<Value> {
    let python = jointfit_testkit::python()?;
    Some(osim_check(&python, mode, request, None))
}

/// Largest accepted difference of a position (m) or a rotation-matrix entry.
const TOL: f64 = 1e-9;

/// Every `.osim` under the data directory (`None`: no data, skipped).
pub(super) fn shared_models() -> Option<Vec<PathBuf>> {
    jointfit_testkit::data_files(&["osim"])
}

/// A random pose: each free coordinate within its range and within ±0.6 (rad or m·0.1)
/// of its default.
pub(super) fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model
        .coordinates()
        .iter()
        .map(|c| {
            let w = match c.kind {
                CoordKind::Rotational => 0.6,
                CoordKind::Translational => 0.06,
            };
            let lo = c.range[0].max(c.default - w);
            let hi = c.range[1].min(c.default + w);
            if lo < hi {
                rng.gen_range(lo..hi)
            } else {
                c.default
            }
        })
        .collect()
}

#[test]
fn osim_every_shared_model_loads_and_matches_opensim_fk() {
    let Some(models) = shared_models() else {
        assert!(std::env::var_os("CI").is_none(), "CI needs $JOINTFIT_DATA");
        eprintln!("skipped: no data");
        return;
    };
    assert!(
        models.len() >= 6,
        "expected the six shared models: {models:?}"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    for path in &models {
        let osim = read_osim(path).unwrap_or_else(|e| panic!("{e}"));
        let model =
            Model::compile(&osim.spec).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut names: Vec<String> = model.coordinates().iter().map(|c| c.name.clone()).collect();
        let coupled: Vec<usize> = (0..model.dependents().len())
            .filter(|&i| {
                !matches!(
                    model.dependents()[i].rule,
                    jointfit::model::custom::CoordRule::Locked(_)
                )
            })
            .collect();
        names.extend(coupled.iter().map(|&i| model.dependents()[i].name.clone()));
        let mut kin = KinData::new(&model);
        let mut poses = Vec::new();
        let mut ours = Vec::new();
        for _ in 0..5 {
            let q = random_q(&model, &mut rng);
            let mut full = q.clone();
            full.extend(coupled.iter().map(|&i| model.dependents()[i].value(&q)));
            forward_kinematics(&model, &[], &q, Want::Positions, &mut kin);
            ours.push(kin.clone());
            poses.push(full);
        }
        let req = json!({"model": path, "coordinates": names, "poses": poses, "bodies": true});
        let Some(answer) = check("fk", &req) else {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI needs $JOINTFIT_PYTHON"
            );
            eprintln!("skipped: no OpenSim");
            return;
        };
        // Coordinate motion types as OpenSim reports them (decides .mot degrees).
        same_motion_types(&model, &answer, path);
        let worst = worst_fk_difference(&model, &ours, &answer, path);
        eprintln!(
            "{}: {} bodies, {} markers, {} free + {} dependent coordinates: worst |Δ| {worst:.2e}",
            path.display(),
            model.segments().len(),
            model.markers().len(),
            model.coordinates().len(),
            model.dependents().len()
        );
        assert!(
            worst <= TOL,
            "{}: FK differs from OpenSim by {worst:e}",
            path.display()
        );
    }
}

/// Each coordinate's motion type (rotational, translational, coupled) is OpenSim's.
fn same_motion_types(model: &Model, answer: &Value, path: &Path) {
    for c in answer["coordinates"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let ours = model
            .coordinates()
            .iter()
            .map(|x| (&x.name, x.motion))
            .chain(model.dependents().iter().map(|d| (&d.name, d.motion)))
            .find(|(n, _)| *n == name)
            .unwrap_or_else(|| panic!("{}: OpenSim coordinate {name} missing", path.display()))
            .1;
        let theirs = c["motion_type"].as_str().unwrap();
        let want = match ours {
            MotionType::Rotational => "rotational",
            MotionType::Translational => "translational",
            MotionType::Coupled => "coupled",
        };
        assert_eq!(theirs, want, "{}: motion type of {name}", path.display());
    }
}

/// The largest difference between our body poses and marker positions and OpenSim's over
/// the poses (each pose's constraint error must vanish).
fn worst_fk_difference(model: &Model, ours: &[KinData], answer: &Value, path: &Path) -> f64 {
    let mut worst = 0.0f64;
    for (k, kin) in ours.iter().enumerate() {
        let qerr = answer["qerr"][k].as_f64().unwrap();
        assert!(qerr < 1e-12, "{}: constraint error {qerr}", path.display());
        for (s, seg) in model.segments().iter().enumerate() {
            let v: Vec<f64> = answer["body_poses"][k][&seg.name]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let pose = &kin.segment_poses[s];
            let mut here = 0.0f64;
            for a in 0..3 {
                here = here.max((pose.trans[a] - v[a]).abs());
                for b in 0..3 {
                    here = here.max((pose.rot[(a, b)] - v[3 + 3 * a + b]).abs());
                }
            }
            if here > TOL && k == 0 {
                eprintln!("  body {}: |Δ| {here:.2e}", seg.name);
            }
            worst = worst.max(here);
        }
        let theirs: &Vec<Value> = answer["positions"][k].as_array().unwrap();
        let their_names: Vec<&str> = answer["markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["name"].as_str().unwrap())
            .collect();
        for (m, marker) in model.markers().iter().enumerate() {
            let j = their_names.iter().position(|n| *n == marker.name).unwrap();
            for (a, t) in theirs[j].as_array().unwrap().iter().enumerate() {
                worst = worst.max((kin.markers[m][a] - t.as_f64().unwrap()).abs());
            }
        }
    }
    worst
}

/// jointfit's functions equal OpenSim's (value and first derivative) inside, at and beyond
/// the knots: the FMM SimmSpline, natural GCV splines of degree 1, 3 and 5 and the
/// piecewise linear function (whose derivative at a kink is not compared).
#[test]
fn osim_functions_match_opensim() {
    use jointfit::model::functions::{Function, FunctionSpec};
    let x = vec![-1.2, 0.0, 0.4, 1.1, 2.5, 3.0, 4.2, 5.0, 6.1];
    let y = vec![0.3, 0.0, 0.5, -0.2, -1.0, 2.0, 1.0, 0.3, 0.9];
    let at: Vec<f64> = (0..=90)
        .map(|i| -2.5 + 0.1 * i as f64)
        .chain(x.clone())
        .collect();
    let mut ours = Vec::new();
    let mut req = Vec::new();
    for (kind, degree) in [
        ("SimmSpline", 0),
        ("GCVSpline", 1),
        ("GCVSpline", 3),
        ("GCVSpline", 5),
        ("PiecewiseLinearFunction", 0),
    ] {
        req.push(json!({"type": kind, "degree": degree, "x": &x, "y": &y}));
        let (x, y) = (x.clone(), y.clone());
        let spec = match kind {
            "SimmSpline" => FunctionSpec::SimmSpline { x, y },
            "GCVSpline" => FunctionSpec::GcvSpline { degree, x, y },
            _ => FunctionSpec::PiecewiseLinear { x, y },
        };
        ours.push((kind, degree, Function::try_from(&spec).unwrap()));
    }
    let Some(answer) = check("functions", &json!({"functions": req, "at": at})) else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI needs $JOINTFIT_PYTHON"
        );
        eprintln!("skipped: no OpenSim");
        return;
    };
    for (i, (kind, degree, f)) in ours.iter().enumerate() {
        let mut worst = [0.0f64; 2];
        for (k, &t) in at.iter().enumerate() {
            let (v, d) = f.eval(t);
            let theirs = &answer["values"][i][k];
            worst[0] = worst[0].max((v - theirs[0].as_f64().unwrap()).abs());
            // A piecewise linear function has no derivative at a kink; OpenSim's one-sided
            // choice there depends on its interval search, so only values are compared.
            if !(*kind == "PiecewiseLinearFunction" && x.contains(&t)) {
                worst[1] = worst[1].max((d - theirs[1].as_f64().unwrap()).abs());
            }
        }
        eprintln!(
            "{kind} {degree}: |Δf| {:.1e}, |Δf′| {:.1e}",
            worst[0], worst[1]
        );
        assert!(
            worst[0] < 1e-10 && worst[1] < 1e-9,
            "{kind} {degree}: {worst:?}"
        );
    }
}

/// Personalizing hip_r and walker_knee_r of the OpenCap hand-scaled model: the written file
/// differs from the input only in those joints' `<translation>`/`<orientation>` lines, reads
/// back to the same kinematics as the parameterized model at the fitted values, and OpenSim
/// 4.6 loads it and puts every marker where jointfit does (1e-9 m).
#[test]
fn osim_write_back_changes_only_the_personalized_frames() {
    use jointfit_io::osim_read::parse_osim;
    use jointfit_io::osim_read::personalize::{fitted_text, parameterize};
    let Some(path) = jointfit_testkit::data_file("opencap_expert1/hand_scaled.osim") else {
        assert!(std::env::var_os("CI").is_none(), "CI needs $JOINTFIT_DATA");
        eprintln!("skipped: no data");
        return;
    };
    let osim = read_osim(&path).unwrap();
    let spec = parameterize(&osim, &["hip_r", "walker_knee_r"]).unwrap();
    assert_eq!(spec.parameters.len(), 24);
    let model = Model::compile(&spec).unwrap();
    // A "fitted" vector: every parameter moved inside its bounds.
    let p: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(i, par)| par.nominal + (par.upper - par.nominal) * (0.1 + 0.05 * (i % 7) as f64))
        .collect();
    let text = fitted_text(&osim, &spec, &p).unwrap();
    // Only the offsets of the two joints changed: 4 frames × (translation, orientation).
    let joints = ["hip_r", "walker_knee_r"];
    let changed = jointfit_testkit::osim_text::changed_offset_lines(&osim.text, &text, &joints);
    assert_eq!(changed.len(), 8, "{changed:?}");
    // Read back: the same kinematics without parameters.
    let back = parse_osim(text.clone(), &path).unwrap();
    let back_model = Model::compile(&back.spec).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let q = random_q(&model, &mut rng);
    let mut a = KinData::new(&model);
    let mut b = KinData::new(&back_model);
    forward_kinematics(&model, &p, &q, Want::Positions, &mut a);
    forward_kinematics(&back_model, &[], &q, Want::Positions, &mut b);
    for (x, y) in a.markers.iter().zip(&b.markers) {
        assert!((x - y).norm() < 1e-12, "{x} vs {y}");
    }
    // OpenSim loads the written file and agrees.
    let dir = jointfit_testkit::scratch("osim-write-back");
    let out = dir.path().join("personalized.osim");
    std::fs::write(&out, &text).unwrap();
    let names: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let mut full = q.clone();
    let mut all = names.clone();
    for d in model.dependents() {
        if matches!(d.rule, jointfit::model::custom::CoordRule::Coupled { .. }) {
            all.push(&d.name);
            full.push(d.value(&q));
        }
    }
    let Some(answer) = check(
        "fk",
        &json!({"model": out, "coordinates": all, "poses": [full]}),
    ) else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI needs $JOINTFIT_PYTHON"
        );
        eprintln!("skipped: no OpenSim");
        return;
    };
    let theirs = answer["positions"][0].as_array().unwrap();
    let mut worst = 0.0f64;
    for (m, marker) in model.markers().iter().enumerate() {
        let j = answer["markers"]
            .as_array()
            .unwrap()
            .iter()
            .position(|x| x["name"] == marker.name.as_str())
            .unwrap();
        for (k, t) in theirs[j].as_array().unwrap().iter().enumerate() {
            worst = worst.max((a.markers[m][k] - t.as_f64().unwrap()).abs());
        }
    }
    eprintln!("written model: OpenSim vs jointfit markers |Δ| {worst:.1e}");
    assert!(worst < 1e-9, "{worst}");
}
