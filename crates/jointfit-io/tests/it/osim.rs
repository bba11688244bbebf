//! The `.osim` export ([`jointfit_io::osim`]): the XML structure (no Python needed), the
//! errors, and OpenSim 4.6 itself as the oracle of the kinematics (`crates/jointfit-cli/assets/osim_check.py`):
//! marker positions in ground for random coordinates and parameters must equal jointfit's
//! forward kinematics to 1e-6 m, for the built-in legs, a subject personalized from the real
//! OpenCap static trial, and a model with every joint kind.

use std::collections::HashMap;

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{builtin, Side};
use jointfit::model::{CoordKind, JointKind, Model};
use jointfit_io::osim::{to_osim, write_osim};
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{personalize, PersonalizeOptions};
use jointfit_testkit::models::all_kinds;
use jointfit_testkit::script::osim_check;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

/// Largest marker-position difference accepted between OpenSim and jointfit (m).
const FK_TOL: f64 = 1e-6;

/// Runs `osim_check.py MODE` with `request` on stdin; `None` (skipped) without Python.
fn check(mode: &str, request: &Value) -> Option<Value> {
    let python = jointfit_testkit::python()?;
    Some(osim_check(&python, mode, request, None))
}

fn personalized_subject() -> Option<Model> {
    let path = jointfit_testkit::data_file("opencap_expert1/static1.trc")?;
    let trial = jointfit_io::trc::read_trc(&path).unwrap();
    let set = MarkerSet::preset("opencap").unwrap();
    let opts = PersonalizeOptions {
        name: "expert1-right".into(),
        ..PersonalizeOptions::default()
    };
    let out = personalize(&trial, &set, Side::Right, &opts).unwrap();
    Some(Model::compile(&out.spec).unwrap())
}

pub(crate) fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Random parameters inside their bounds (the nominal vector first).
fn param_sets(model: &Model, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let mut sets = vec![model.nominal_params()];
    if !model.parameters().is_empty() {
        sets.push(
            model
                .parameters()
                .iter()
                .map(|p| rng.gen_range(p.lower..p.upper))
                .collect(),
        );
    }
    sets
}

/// Random coordinates: angles in ±π (beyond the ranges too: the export does not clamp),
/// translations in ±0.5 m.
fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model
        .coordinates()
        .iter()
        .map(|c| match c.kind {
            CoordKind::Rotational => rng.gen_range(-3.1..3.1),
            CoordKind::Translational => rng.gen_range(-0.5..0.5),
        })
        .collect()
}

/// Exports `model` with each parameter set, asks OpenSim for the marker positions at random
/// coordinates and compares with jointfit's forward kinematics; returns the largest
/// difference (m), or `None` when skipped.
fn compare_fk(model: &Model, seed: u64) -> Option<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let dir = tempdir();
    let names: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    let mut worst = 0.0f64;
    for (k, p) in param_sets(model, &mut rng).into_iter().enumerate() {
        let path = dir.path().join(format!("m{k}.osim"));
        write_osim(&path, model, &p).unwrap();
        let mut poses = vec![model.default_coords(), vec![0.0; model.coordinates().len()]];
        poses.extend((0..20).map(|_| random_q(model, &mut rng)));
        let answer = check(
            "fk",
            &json!({"model": path, "coordinates": names, "poses": poses}),
        )?;
        check_summary(model, &answer);
        let mut data = KinData::new(model);
        let osim_markers: Vec<&str> = answer["markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["name"].as_str().unwrap())
            .collect();
        for (pose, got) in poses.iter().zip(answer["positions"].as_array().unwrap()) {
            forward_kinematics(model, &p, pose, Want::Positions, &mut data);
            for (j, m) in model.markers().iter().enumerate() {
                let o = osim_markers.iter().position(|n| *n == m.name).unwrap();
                let xyz = &got[o];
                for a in 0..3 {
                    let d = (xyz[a].as_f64().unwrap() - data.markers[j][a]).abs();
                    worst = worst.max(d);
                    assert!(
                        d <= FK_TOL,
                        "{}: marker {} axis {a} differs by {d} m at q = {pose:?}, p = {p:?}",
                        model.spec().name,
                        m.name
                    );
                }
            }
        }
    }
    eprintln!(
        "osim fk {}: max |OpenSim − jointfit| marker difference {worst:.3e} m",
        model.spec().name
    );
    Some(worst)
}

/// What OpenSim loaded: same bodies, joints (parents, children, coordinates), coordinate
/// kinds, ranges and defaults (not clamped), marker parents and locations.
fn check_summary(model: &Model, a: &Value) {
    let bodies: Vec<&str> = a["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_str().unwrap())
        .collect();
    let segs: Vec<&str> = model.segments().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(bodies, segs);
    let joints: HashMap<&str, &Value> = a["joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| (j["name"].as_str().unwrap(), j))
        .collect();
    assert_eq!(joints.len(), model.joints().len());
    for j in model.joints() {
        let o = joints[j.name.as_str()];
        let parent = j
            .parent
            .map_or("ground", |s| model.segments()[s.0].name.as_str());
        assert_eq!(o["parent"], parent, "joint {}", j.name);
        assert_eq!(
            o["child"],
            model.segments()[j.child.0].name,
            "joint {}",
            j.name
        );
        let expected_type = match j.kind {
            JointKind::Weld => "WeldJoint",
            _ => "CustomJoint",
        };
        assert_eq!(o["type"], expected_type, "joint {}", j.name);
        let mut theirs: Vec<&str> = o["coordinates"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_str().unwrap())
            .collect();
        let mut ours: Vec<&str> = model.coordinates()[j.coords.clone()]
            .iter()
            .map(|c| c.name.as_str())
            .collect();
        theirs.sort_unstable();
        ours.sort_unstable();
        assert_eq!(theirs, ours, "coordinates of joint {}", j.name);
    }
    let coords = a["coordinates"].as_array().unwrap();
    assert_eq!(coords.len(), model.coordinates().len());
    for c in coords {
        let ours = &model.coordinates()[model.coord_id(c["name"].as_str().unwrap()).unwrap()];
        let kind = match ours.kind {
            CoordKind::Rotational => "rotational",
            CoordKind::Translational => "translational",
        };
        assert_eq!(c["motion_type"], kind, "coordinate {}", ours.name);
        assert_eq!(c["joint"], model.joints()[ours.joint].name);
        assert_eq!(c["range"][0].as_f64().unwrap(), ours.range[0]);
        assert_eq!(c["range"][1].as_f64().unwrap(), ours.range[1]);
        assert_eq!(c["default"].as_f64().unwrap(), ours.default);
        assert_eq!(c["clamped"], false);
        assert_eq!(c["locked"], false);
    }
    let markers = a["markers"].as_array().unwrap();
    assert_eq!(markers.len(), model.markers().len());
    for (m, o) in model.markers().iter().zip(markers) {
        assert_eq!(o["name"], m.name);
        assert_eq!(o["parent"], model.segments()[m.segment.0].name);
        // OpenSim's number parser may land one ulp away from the shortest decimal form.
        for k in 0..3 {
            let d = (o["location"][k].as_f64().unwrap() - m.local[k]).abs();
            assert!(d <= 1e-15 * (1.0 + m.local[k].abs()), "{} axis {k}", m.name);
        }
    }
}

#[test]
fn osim_fk_builtin_legs_match_opensim() {
    for name in ["lower-limb-right", "lower-limb-left"] {
        let model = Model::compile(&builtin(name).unwrap()).unwrap();
        let Some(worst) = compare_fk(&model, 11) else {
            return;
        };
        assert!(worst <= FK_TOL);
    }
}

#[test]
fn osim_fk_personalized_subject_matches_opensim() {
    let Some(model) = personalized_subject() else {
        return;
    };
    compare_fk(&model, 12);
}

#[test]
fn osim_fk_every_joint_kind_matches_opensim() {
    let model = Model::compile(&all_kinds()).unwrap();
    compare_fk(&model, 13);
}

/// Text of the child element `tag` of `node`.
fn child_text<'a>(node: roxmltree::Node<'a, 'a>, tag: &str) -> &'a str {
    node.children()
        .find(|n| n.has_tag_name(tag))
        .unwrap_or_else(|| panic!("<{}> lacks <{tag}>", node.tag_name().name()))
        .text()
        .unwrap_or("")
}

fn numbers(s: &str) -> Vec<f64> {
    s.split_whitespace().map(|v| v.parse().unwrap()).collect()
}

/// Well-formed XML with OpenSim's layout, checked by an independent XML parser; the offsets
/// hold the parameter values (with their scales), every coordinate and marker is there.
#[test]
fn osim_xml_structure() {
    let spec = all_kinds();
    let model = Model::compile(&spec).unwrap();
    let p = vec![-0.03, 0.25, 0.2];
    let text = to_osim(&model, &p).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let root = doc.root_element();
    assert!(root.has_tag_name("OpenSimDocument"));
    assert_eq!(root.attribute("Version"), Some("40000"));
    let comment = doc
        .descendants()
        .find(|n| n.is_comment())
        .unwrap()
        .text()
        .unwrap();
    assert!(comment.contains("PLACEHOLDERS"), "{comment}");
    assert!(comment.contains("sh_y = 0.25"), "{comment}");
    assert!(comment.contains("t1 2.5"), "marker weight noted: {comment}");
    let m = root.children().find(|n| n.has_tag_name("Model")).unwrap();
    assert_eq!(m.attribute("name"), Some("all-kinds"));

    let set = |tag: &str| -> Vec<roxmltree::Node> {
        m.children()
            .find(|n| n.has_tag_name(tag))
            .unwrap()
            .children()
            .find(|n| n.has_tag_name("objects"))
            .unwrap()
            .children()
            .filter(|n| n.is_element())
            .collect()
    };
    let bodies = set("BodySet");
    let body_names: Vec<&str> = bodies
        .iter()
        .map(|b| b.attribute("name").unwrap())
        .collect();
    let segs: Vec<&str> = model.segments().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(body_names, segs, "the model's topological order");
    assert_eq!(segs, ["base", "arm", "cap", "hand", "finger", "tip"]);
    for b in &bodies {
        assert_eq!(numbers(child_text(*b, "mass")), [1.0]);
        assert_eq!(numbers(child_text(*b, "inertia")).len(), 6);
    }

    let joints = set("JointSet");
    let kinds: Vec<(&str, &str)> = joints
        .iter()
        .map(|j| (j.tag_name().name(), j.attribute("name").unwrap()))
        .collect();
    assert_eq!(
        kinds,
        [
            ("CustomJoint", "root"),
            ("CustomJoint", "shoulder"),
            ("WeldJoint", "glue"),
            ("CustomJoint", "elbow"),
            ("CustomJoint", "wrist"),
            ("CustomJoint", "slide"),
        ]
    );
    let mut coords = Vec::new();
    for j in &joints {
        for c in j.descendants().filter(|n| n.has_tag_name("Coordinate")) {
            coords.push(c.attribute("name").unwrap());
            assert_eq!(child_text(c, "clamped"), "false");
            assert_eq!(numbers(child_text(c, "range")).len(), 2);
        }
        check_joint_frames_and_axes(*j);
    }
    let expected: Vec<&str> = model
        .coordinates()
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    assert_eq!(coords, expected);

    check_offsets(&joints);

    let markers = set("MarkerSet");
    assert_eq!(markers.len(), model.markers().len());
    for (x, m) in markers.iter().zip(model.markers()) {
        assert_eq!(x.attribute("name"), Some(m.name.as_str()));
        assert_eq!(
            child_text(*x, "socket_parent_frame"),
            format!("/bodyset/{}", model.segments()[m.segment.0].name)
        );
        assert_eq!(numbers(child_text(*x, "location")), m.local.as_slice());
    }
}

/// A joint has its two offset frames, named by its sockets, and a spatial transform (when it
/// has one) of six unit axes in OpenSim's order.
fn check_joint_frames_and_axes(j: roxmltree::Node) {
    let frames: Vec<_> = j
        .descendants()
        .filter(|n| n.has_tag_name("PhysicalOffsetFrame"))
        .collect();
    assert_eq!(frames.len(), 2);
    // The sockets name the joint's own offset frames.
    for (socket, frame) in ["socket_parent_frame", "socket_child_frame"]
        .iter()
        .zip(&frames)
    {
        assert_eq!(child_text(j, socket), frame.attribute("name").unwrap());
    }
    if let Some(st) = j.children().find(|n| n.has_tag_name("SpatialTransform")) {
        let axes: Vec<&str> = st
            .children()
            .filter(|n| n.has_tag_name("TransformAxis"))
            .map(|n| n.attribute("name").unwrap())
            .collect();
        assert_eq!(
            axes,
            [
                "rotation1",
                "rotation2",
                "rotation3",
                "translation1",
                "translation2",
                "translation3"
            ]
        );
        for ax in st.children().filter(|n| n.has_tag_name("TransformAxis")) {
            let a = numbers(child_text(ax, "axis"));
            let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            assert!((n - 1.0).abs() < 1e-12, "unit axes");
        }
    }
}

/// The offset frames of the shoulder (parent: tx = sh_x, ty = −sh_y, rx = sh_rx, rz = 0.3;
/// child: tz = 0.05, ry = 0.5·sh_rx) and the root's parent (the ground).
fn check_offsets(joints: &[roxmltree::Node]) {
    let shoulder = joints[1];
    let frame = |name: &str| {
        shoulder
            .descendants()
            .find(|n| n.has_tag_name("PhysicalOffsetFrame") && n.attribute("name") == Some(name))
            .unwrap()
    };
    let base = frame("base_offset");
    assert_eq!(child_text(base, "socket_parent"), "/bodyset/base");
    assert_eq!(
        numbers(child_text(base, "translation")),
        [-0.03, -0.25, 0.0]
    );
    assert_eq!(numbers(child_text(base, "orientation")), [0.2, 0.0, 0.3]);
    let arm = frame("arm_offset");
    assert_eq!(numbers(child_text(arm, "translation")), [0.0, 0.0, 0.05]);
    assert_eq!(numbers(child_text(arm, "orientation")), [0.0, 0.1, 0.0]);
    let root_frame = joints[0]
        .descendants()
        .find(|n| n.attribute("name") == Some("ground_offset"))
        .unwrap();
    assert_eq!(child_text(root_frame, "socket_parent"), "/ground");
}
