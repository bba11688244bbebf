//! Every OpenSim joint type and coordinate function the `.osim` reader supports, against
//! OpenSim 4.6 on a model this test writes itself (no shared model has most of them): a
//! chain with a FreeJoint, BallJoint, GimbalJoint, UniversalJoint, PinJoint, SliderJoint,
//! PlanarJoint and WeldJoint, and CustomJoints whose TransformAxis functions are Constant,
//! LinearFunction, SimmSpline, NaturalCubicSpline, GCVSpline (degree 3 and 5),
//! PiecewiseLinearFunction, PolynomialFunction and MultiplierFunction around splines, on
//! oblique and non-unit axes; every joint hangs between offset frames that translate and
//! rotate; one coordinate is driven by a CoordinateCouplerConstraint, one is locked, one is
//! clamped; every body carries markers (one through a loose offset frame).
//!
//! At 20 seeded random poses every marker position equals OpenSim's to 1e-9 m, per joint
//! type (each body's markers measure the joints above it), and ∂x/∂q equals central finite
//! differences. Unsupported components are one-line errors naming the component.

use std::path::Path;

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::custom::CoordRule;
use jointfit::model::Model;
use jointfit_io::osim_read::{parse_osim, read_osim};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use jointfit_testkit::script::osim_check;

use super::osim_joint_model::{linear, model_text, BODIES};

/// Free coordinates, then the coupled ones (what OpenSim is told), and the full pose.
fn pose_names(model: &Model) -> Vec<String> {
    let mut names: Vec<String> = model.coordinates().iter().map(|c| c.name.clone()).collect();
    for d in model.dependents() {
        if matches!(d.rule, CoordRule::Coupled { .. }) {
            names.push(d.name.clone());
        }
    }
    names
}

fn full_pose(model: &Model, q: &[f64]) -> Vec<f64> {
    let mut full = q.to_vec();
    for d in model.dependents() {
        if matches!(d.rule, CoordRule::Coupled { .. }) {
            full.push(d.value(q));
        }
    }
    full
}

fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model
        .coordinates()
        .iter()
        .map(|c| rng.gen_range(c.range[0]..c.range[1]))
        .collect()
}

fn load(dir: &Path) -> (std::path::PathBuf, Model) {
    let path = dir.join("all_joint_types.osim");
    std::fs::write(&path, model_text()).unwrap();
    let osim = read_osim(&path).unwrap_or_else(|e| panic!("{e}"));
    let model = Model::compile(&osim.spec).unwrap_or_else(|e| panic!("{e}"));
    (path, model)
}

#[test]
fn osim_every_joint_type_and_function_matches_opensim_fk() {
    let dir = jointfit_testkit::scratch("osim-joint-types");
    let (path, model) = load(dir.path());
    // 6 + 3 + 3 + 2 + 1 + 1 + 3 + 3 + 1 + clamp + c4 free; c3_dep coupled, c3_lock locked.
    assert_eq!(model.coordinates().len(), 25, "{:?}", pose_names(&model));
    assert_eq!(model.dependents().len(), 2);
    let Some(python) = jointfit_testkit::python() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI needs $JOINTFIT_PYTHON"
        );
        eprintln!("skipped: no OpenSim");
        return;
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2214);
    let mut kin = KinData::new(&model);
    let mut ours = Vec::new();
    let mut poses = Vec::new();
    for _ in 0..20 {
        let q = random_q(&model, &mut rng);
        forward_kinematics(&model, &[], &q, Want::Positions, &mut kin);
        ours.push(kin.markers.clone());
        poses.push(full_pose(&model, &q));
    }
    let answer = osim_check(
        &python,
        "fk",
        &json!({"model": path, "coordinates": pose_names(&model), "poses": poses, "bodies": true}),
        Some(dir.path()),
    );
    let names: Vec<&str> = answer["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    let mut worst_all = 0.0f64;
    for (body, what) in BODIES {
        let mut worst = 0.0f64;
        for (m, marker) in model.markers().iter().enumerate() {
            if !marker.name.starts_with(&format!("{body}_")) {
                continue;
            }
            let j = names.iter().position(|n| *n == marker.name).unwrap();
            for (k, x) in ours.iter().enumerate() {
                assert!(
                    answer["qerr"][k].as_f64().unwrap() < 1e-12,
                    "pose {k}: constraint"
                );
                let t = &answer["positions"][k][j];
                for a in 0..3 {
                    worst = worst.max((x[m][a] - t[a].as_f64().unwrap()).abs());
                }
            }
        }
        eprintln!("| {body} | {what} | {worst:.1e} m |");
        worst_all = worst_all.max(worst);
        assert!(
            worst <= 1e-9,
            "{body} ({what}): FK differs from OpenSim by {worst:e} m"
        );
    }
    assert_eq!(names.len(), model.markers().len());
    eprintln!("all markers at 20 poses: worst |Δ| {worst_all:.1e} m");
}

/// ∂x/∂q of the generated model equals central differences (every function's derivative,
/// the coupler's chain rule, the oblique axes).
#[test]
fn osim_every_joint_type_jacobian_matches_finite_differences() {
    let dir = jointfit_testkit::scratch("osim-joint-types-fd");
    let (_, model) = load(dir.path());
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut kin = KinData::new(&model);
    let mut plus = KinData::new(&model);
    let mut minus = KinData::new(&model);
    let h = 1e-6;
    let mut worst = 0.0f64;
    for _ in 0..20 {
        let q = random_q(&model, &mut rng);
        forward_kinematics(&model, &[], &q, Want::Dq, &mut kin);
        for i in 0..model.coordinates().len() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[i] += h;
            qm[i] -= h;
            forward_kinematics(&model, &[], &qp, Want::Positions, &mut plus);
            forward_kinematics(&model, &[], &qm, Want::Positions, &mut minus);
            for m in 0..model.markers().len() {
                let fd = (plus.markers[m] - minus.markers[m]) / (2.0 * h);
                for a in 0..3 {
                    let d = (kin.jq[(3 * m + a, i)] - fd[a]).abs();
                    worst = worst.max(d);
                    assert!(
                        d < 1e-7,
                        "∂ {} / ∂ {}: {} vs {}",
                        model.markers()[m].name,
                        model.coordinates()[i].name,
                        kin.jq[(3 * m + a, i)],
                        fd[a]
                    );
                }
            }
        }
    }
    eprintln!("∂x/∂q vs central differences: worst |Δ| {worst:.1e}");
}

/// What the reader cannot represent is refused in one line naming the component.
#[test]
fn osim_unsupported_components_are_one_line_errors_naming_them() {
    let text = model_text();
    let cases = [
        (
            text.replacen("<PinJoint name=\"pin\"", "<EllipsoidJoint name=\"pin\"", 1)
                .replacen("</PinJoint>", "</EllipsoidJoint>", 1),
            "EllipsoidJoint \"pin\"",
        ),
        (
            text.replacen(
                &linear(0.05, 0.01),
                "<StepFunction><start_time>0</start_time><end_time>1</end_time>\
                 <start_value>0</start_value><end_value>1</end_value></StepFunction>",
                1,
            ),
            "StepFunction",
        ),
        (
            text.replacen(
                "<CoordinateCouplerConstraint name=\"couple_dep\">",
                "<WeldConstraint name=\"w\"><isEnforced>true</isEnforced></WeldConstraint>\
                 <CoordinateCouplerConstraint name=\"couple_dep\">",
                1,
            ),
            "WeldConstraint \"w\"",
        ),
        (
            text.replacen(
                "<Coordinate name=\"s_d\">",
                "<Coordinate name=\"s_d\"><prescribed>true</prescribed>",
                1,
            ),
            "\"s_d\"",
        ),
    ];
    for (bad, needle) in cases {
        let e = parse_osim(bad, Path::new("gen.osim"))
            .unwrap_err()
            .to_string();
        eprintln!("{e}");
        assert!(e.starts_with("gen.osim: line "), "{e}");
        assert!(!e.contains('\n'), "one line: {e}");
        assert!(e.contains(needle), "names {needle}: {e}");
    }
}
