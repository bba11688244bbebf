//! Forward kinematics and the analytic Jacobians against independent oracles.

use super::{fd, forward_kinematics, KinData, Want};
use crate::model::lower_limb::bilateral::bilateral;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::spec::ModelSpec;
use crate::model::{CoordKind, Model};
use nalgebra::{DMatrix, Matrix3, Vector3};
use proptest::prelude::*;

/// The sample models of `jointfit_testkit::models` (their TOML texts), read by this crate.
fn sample_model(text: &str) -> ModelSpec {
    ModelSpec::from_toml(text).unwrap()
}

fn two_link() -> ModelSpec {
    sample_model(include_str!(
        "../../../jointfit-testkit/models/two_link.toml"
    ))
}

fn kitchen_sink() -> ModelSpec {
    sample_model(include_str!(
        "../../../jointfit-testkit/models/kitchen_sink.toml"
    ))
}

fn custom_joints() -> ModelSpec {
    sample_model(include_str!(
        "../../../jointfit-testkit/models/custom_joints.toml"
    ))
}

/// Coordinates and parameters from unit-interval samples: rotations in [−π, π],
/// translations in [−1, 1] m, parameters inside their bounds.
fn sample(model: &Model, u: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let q = model
        .coordinates()
        .iter()
        .zip(u)
        .map(|(c, &t)| match c.kind {
            CoordKind::Rotational => (2.0 * t - 1.0) * std::f64::consts::PI,
            CoordKind::Translational => 2.0 * t - 1.0,
        })
        .collect();
    let p = model
        .parameters()
        .iter()
        .zip(&u[model.coordinates().len()..])
        .map(|(par, &t)| par.lower + t * (par.upper - par.lower))
        .collect();
    (p, q)
}

/// max |a − b| / max(1, max |b|).
fn rel_err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    let scale = b.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    (a - b).iter().fold(0.0f64, |m, v| m.max(v.abs())) / scale
}

fn check_jacobians(spec: &ModelSpec, u: &[f64]) -> Result<(), TestCaseError> {
    let model = Model::compile(spec).unwrap();
    let (p, q) = sample(&model, u);
    let mut data = KinData::new(&model);
    forward_kinematics(&model, &p, &q, Want::DqDp, &mut data);
    let h = 1e-6;
    let eq = rel_err(&data.jq, &fd::jacobian_q(&model, &p, &q, h));
    let ep = rel_err(&data.jp, &fd::jacobian_p(&model, &p, &q, h));
    prop_assert!(eq <= 1e-6, "{}: dq relative error {eq:e}", model.name());
    prop_assert!(ep <= 1e-6, "{}: dp relative error {ep:e}", model.name());
    // Asking for one Jacobian gives the same numbers as asking for both.
    let mut only_q = KinData::new(&model);
    forward_kinematics(&model, &p, &q, Want::Dq, &mut only_q);
    prop_assert_eq!(only_q.jq, data.jq);
    Ok(())
}

fn units(n: usize) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(0.0f64..1.0, n)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A reused workspace (cached parameter blocks, Jacobians written in place) gives exactly
    /// what a fresh one gives, whatever was evaluated before.
    #[test]
    fn reused_workspace_equals_fresh(u1 in units(15 + 4), u2 in units(15 + 4), same_p: bool) {
        let model = Model::compile(&kitchen_sink()).unwrap();
        let (p1, q1) = sample(&model, &u1);
        let (p2, q2) = sample(&model, &u2);
        let p2 = if same_p { p1.clone() } else { p2 };
        let mut reused = KinData::new(&model);
        forward_kinematics(&model, &p1, &q1, Want::DqDp, &mut reused);
        forward_kinematics(&model, &p2, &q2, Want::DqDp, &mut reused);
        let mut fresh = KinData::new(&model);
        forward_kinematics(&model, &p2, &q2, Want::DqDp, &mut fresh);
        prop_assert_eq!(&reused.markers, &fresh.markers);
        prop_assert_eq!(reused.jq, fresh.jq);
        prop_assert_eq!(reused.jp, fresh.jp);
    }

    /// Steps through functions (splines, polynomials, a coupled coordinate by the chain
    /// rule) next to parameterized offsets.
    #[test]
    fn custom_joint_jacobians_match_finite_differences(u in units(3 + 2)) {
        check_jacobians(&custom_joints(), &u)?;
    }

    #[test]
    fn two_link_jacobians_match_finite_differences(u in units(2 + 4)) {
        check_jacobians(&two_link(), &u)?;
    }

    #[test]
    fn kitchen_sink_jacobians_match_finite_differences(u in units(15 + 4)) {
        check_jacobians(&kitchen_sink(), &u)?;
    }

    #[test]
    fn right_leg_jacobians_match_finite_differences(u in units(12 + 27)) {
        check_jacobians(&lower_limb(Side::Right), &u)?;
    }

    #[test]
    fn left_leg_jacobians_match_finite_differences(u in units(12 + 27)) {
        check_jacobians(&lower_limb(Side::Left), &u)?;
    }

    /// Both legs and the shared pelvis (`lower-limb`, 18 coordinates, 54 parameters).
    #[test]
    fn bilateral_jacobians_match_finite_differences(u in units(18 + 54)) {
        check_jacobians(&bilateral(), &u)?;
    }

    /// A universal joint (x then y) moves markers exactly like two pins (x, then y) with a
    /// massless segment between them.
    #[test]
    fn universal_equals_two_pins(a in -3.0f64..3.0, b in -3.0f64..3.0, t in -0.5f64..0.5) {
        let universal = Model::compile(&ModelSpec::from_toml(r#"
name = "u"
segments = [{ name = "s" }]
[[joints]]
name = "j"
parent = "ground"
child = "s"
kind = { type = "universal", axes = ["x", "y"] }
coordinates = ["a", "b"]
parent_offset = { tx = 0.1, rz = "t" }
child_offset = { ty = 0.2, rx = 0.3 }
[[parameters]]
name = "t"
group = "g"
unit = "rad"
nominal = 0.0
lower = -1.0
upper = 1.0
[[markers]]
name = "m"
segment = "s"
position = [0.3, -0.2, 0.1]
"#).unwrap()).unwrap();
        let pins = Model::compile(&ModelSpec::from_toml(r#"
name = "pins"
segments = [{ name = "mid" }, { name = "s" }]
[[joints]]
name = "j1"
parent = "ground"
child = "mid"
kind = { type = "pin", axis = "x" }
coordinates = ["a"]
parent_offset = { tx = 0.1, rz = "t" }
[[joints]]
name = "j2"
parent = "mid"
child = "s"
kind = { type = "pin", axis = "y" }
coordinates = ["b"]
child_offset = { ty = 0.2, rx = 0.3 }
[[parameters]]
name = "t"
group = "g"
unit = "rad"
nominal = 0.0
lower = -1.0
upper = 1.0
[[markers]]
name = "m"
segment = "s"
position = [0.3, -0.2, 0.1]
"#).unwrap()).unwrap();
        let mut du = KinData::new(&universal);
        let mut dp = KinData::new(&pins);
        forward_kinematics(&universal, &[t], &[a, b], Want::DqDp, &mut du);
        forward_kinematics(&pins, &[t], &[a, b], Want::DqDp, &mut dp);
        prop_assert!((du.markers[0] - dp.markers[0]).norm() < 1e-14);
        prop_assert!((du.jq - dp.jq).abs().max() < 1e-14);
        prop_assert!((du.jp - dp.jp).abs().max() < 1e-14);
    }

    /// The left leg is the mirror image of the right one: with the pelvis coordinates that
    /// mirror (tz, list, rotation negated) every left marker is the mirror of its right twin.
    #[test]
    fn left_leg_mirrors_right_leg(u in units(12 + 27)) {
        let right = Model::compile(&lower_limb(Side::Right)).unwrap();
        let left = Model::compile(&lower_limb(Side::Left)).unwrap();
        let (p, q) = sample(&right, &u);
        let mut ql = q.clone();
        for name in ["pelvis_tz", "pelvis_list", "pelvis_rotation"] {
            let i = right.coord_id(name).unwrap();
            ql[i] = -ql[i];
        }
        let (mut dr, mut dl) = (KinData::new(&right), KinData::new(&left));
        forward_kinematics(&right, &p, &q, Want::Positions, &mut dr);
        forward_kinematics(&left, &p, &ql, Want::Positions, &mut dl);
        let mirror = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        for (i, m) in right.markers().iter().enumerate() {
            let twin = match m.name.as_str() {
                "RASI" => "LASI".to_string(),
                "LASI" => "RASI".to_string(),
                "RPSI" => "LPSI".to_string(),
                "LPSI" => "RPSI".to_string(),
                n => format!("L{}", &n[1..]),
            };
            let j = left.markers().iter().position(|n| n.name == twin).unwrap();
            prop_assert!((mirror * dr.markers[i] - dl.markers[j]).norm() < 1e-12, "marker {}", m.name);
        }
    }
}

/// FK of the two-link chain against a hand computation.
#[test]
fn two_link_by_hand() {
    let model = Model::compile(&two_link()).unwrap();
    let mut d = KinData::new(&model);
    let (shoulder, elbow) = (0.4, 0.7);
    // All parameters zero except the upper length.
    let p = [0.0, -0.3, 0.0, 0.0];
    forward_kinematics(&model, &p, &[shoulder, elbow], Want::Positions, &mut d);
    let rz = |a: f64| nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), a);
    let upper = rz(shoulder);
    let base = Vector3::new(0.0, 1.2, 0.0);
    let elbow_lat = base + upper * Vector3::new(0.0, -0.3, 0.04);
    assert!((d.markers[0] - elbow_lat).norm() < 1e-15);
    // Elbow: pin about −z, child offset rotation rz = 0.2 inverted.
    let elbow_origin = base + upper * Vector3::new(0.0, -0.3, 0.01);
    let lower = upper * rz(-elbow) * rz(-0.2);
    let wrist = elbow_origin + lower * Vector3::new(0.0, -0.25, 0.0);
    assert!(
        (d.markers[2] - wrist).norm() < 1e-15,
        "{} vs {}",
        d.markers[2],
        wrist
    );
}

/// With nominal parameters and q = 0 the generic leg stands upright: hip centre, knee and
/// ankle on a vertical line below the pelvis, the foot's long axis horizontal.
#[test]
fn nominal_leg_stands_upright() {
    for side in [Side::Right, Side::Left] {
        let model = Model::compile(&lower_limb(side)).unwrap();
        let mut d = KinData::new(&model);
        let q = vec![0.0; model.coordinates().len()];
        forward_kinematics(&model, &model.nominal_params(), &q, Want::Positions, &mut d);
        let pose = |name: &str| {
            let s = model.segments().iter().position(|s| s.name == name);
            d.segment_poses[s.unwrap()]
        };
        let foot = pose("foot");
        assert!(foot.rot.column(0).y.abs() < 1e-12, "foot x is horizontal");
        let thigh = pose("thigh");
        assert!((thigh.trans.y - (-0.09167)).abs() < 1e-12);
        assert!(
            (thigh.trans.z - side.sign() * 0.08628).abs() < 1e-12,
            "hip is lateral"
        );
        let shank = pose("shank");
        assert!((shank.trans.y - thigh.trans.y + 0.39211).abs() < 1e-12);
    }
}

/// Positive coordinates mean the clinical motion on both sides.
#[test]
fn clinical_signs() {
    for side in [Side::Right, Side::Left] {
        let model = Model::compile(&lower_limb(side)).unwrap();
        let p = model.nominal_params();
        let at = |name: &str, value: f64, marker: &str| {
            let mut q = vec![0.0; model.coordinates().len()];
            q[model.coord_id(name).unwrap()] = value;
            let mut d = KinData::new(&model);
            forward_kinematics(&model, &p, &q, Want::Positions, &mut d);
            let label = format!("{}{marker}", side.prefix());
            d.markers[model
                .markers()
                .iter()
                .position(|m| m.name == label)
                .unwrap()]
        };
        let lateral = side.sign();
        let a = 0.3;
        // Hip flexion brings the knee forward; adduction brings it medially.
        assert!(at("hip_flexion", a, "KNE").x > at("hip_flexion", 0.0, "KNE").x + 0.05);
        assert!(
            lateral * (at("hip_adduction", a, "KNE").z - at("hip_adduction", 0.0, "KNE").z) < -0.05
        );
        // Internal rotation turns the anterior thigh marker medially.
        assert!(
            lateral * (at("hip_rotation", a, "THA").z - at("hip_rotation", 0.0, "THA").z) < -0.01
        );
        // Knee flexion moves the ankle backwards; dorsiflexion lifts the toe.
        assert!(at("knee_flexion", a, "ANK").x < at("knee_flexion", 0.0, "ANK").x - 0.05);
        assert!(
            at("ankle_dorsiflexion", a, "TOE").y > at("ankle_dorsiflexion", 0.0, "TOE").y + 0.02
        );
        // Inversion turns the sole medially: the lateral forefoot drops.
        assert!(
            at("subtalar_inversion", a, "MT5").y < at("subtalar_inversion", 0.0, "MT5").y - 0.005
        );
    }
}
