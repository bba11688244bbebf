//! Model descriptions: counts, TOML round trips, and errors that name the offending item.

use jointfit::model::lower_limb::{builtin, lower_limb, Side};
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError};

use jointfit_testkit::models::{kitchen_sink, two_link};

/// The parameters of one group.
fn group(model: &Model, name: &str) -> Vec<jointfit::model::ParamId> {
    jointfit::calibrate::params_for_groups(model, &[name]).unwrap()
}

#[test]
fn leg_model_has_the_papers_counts() {
    for side in [Side::Right, Side::Left] {
        let model = Model::compile(&lower_limb(side)).unwrap();
        assert_eq!(model.parameters().len(), 27);
        assert_eq!(model.coordinates().len(), 12);
        assert_eq!(group(&model, "hip").len(), 6);
        assert_eq!(group(&model, "knee").len(), 9);
        assert_eq!(group(&model, "ankle").len(), 12);
        let rot = |g: &str| {
            group(&model, g)
                .iter()
                .filter(|id| model.parameters()[id.0].unit == jointfit::model::spec::Unit::Radian)
                .count()
        };
        // Knee: 4 orientations, 5 positions; ankle: 5 orientations, 7 positions.
        assert_eq!((rot("hip"), rot("knee"), rot("ankle")), (0, 4, 5));
        let kinds: Vec<_> = model.joints().iter().map(|j| j.kind.to_string()).collect();
        assert_eq!(kinds, ["free", "gimbal", "pin", "pin", "pin"]);
    }
}

#[test]
fn builtins_by_name() {
    assert_eq!(builtin("lower-limb-left").unwrap().name, "lower-limb-left");
    let e = builtin("arm").unwrap_err();
    assert_eq!(
        e.to_string(),
        "unknown built-in model \"arm\"; built-in models: lower-limb, lower-limb-right, \
         lower-limb-left"
    );
}

#[test]
fn toml_round_trip_is_exact() {
    for spec in [
        two_link(),
        kitchen_sink(),
        lower_limb(Side::Right),
        lower_limb(Side::Left),
    ] {
        let text = spec.to_toml();
        let back = ModelSpec::from_toml(&text).unwrap();
        assert_eq!(back, spec, "round trip of {}", spec.name);
        Model::compile(&back).unwrap();
    }
}

fn compile_err(text: &str) -> ModelError {
    let spec = ModelSpec::from_toml(text).unwrap();
    Model::compile(&spec).unwrap_err()
}

fn two_link_with(from: &str, to: &str) -> String {
    let text = two_link().to_toml();
    assert!(text.contains(from), "fixture text contains {from:?}");
    text.replacen(from, to, 1)
}

#[test]
fn errors_name_the_offending_item() {
    let e = compile_err(&two_link_with("child = \"lower\"", "child = \"forearm\""));
    assert_eq!(
        e.to_string(),
        "joint \"elbow\" (child) refers to segment \"forearm\", which is not defined"
    );
    let e = compile_err(&two_link_with(
        "ty = \"upper_length\"",
        "ty = \"upper_len\"",
    ));
    assert_eq!(
        e.to_string(),
        "joint \"elbow\" parent_offset.ty refers to parameter \"upper_len\", which is not defined"
    );
    let e = compile_err(&two_link_with(
        "rx = \"shoulder_tilt\"",
        "tx = \"shoulder_tilt\"",
    ));
    assert!(e.to_string().contains("parameter \"shoulder_tilt\" is declared in Radian but joint \"shoulder\" parent_offset.tx needs Metre"), "{e}");
    let e = compile_err(&two_link_with("nominal = -0.3", "nominal = -0.5"));
    assert_eq!(
        e.to_string(),
        "parameter \"upper_length\": nominal -0.5 lies outside [-0.35, -0.25]"
    );
    let e = compile_err(&two_link_with("axis = \"-z\"", "axis = \"w\""));
    assert!(
        e.to_string()
            .starts_with("joint \"elbow\" axis 1: axis \"w\""),
        "{e}"
    );
    let e = compile_err(&two_link_with("segment = \"lower\"", "segment = \"hand\""));
    assert_eq!(
        e.to_string(),
        "marker \"forearm\" refers to segment \"hand\", which is not defined"
    );
    let e = compile_err(&two_link_with(
        "coordinates = [\"shoulder_angle\"]",
        "coordinates = [\"a\", \"b\"]",
    ));
    assert_eq!(
        e.to_string(),
        "joint \"shoulder\" is pin with 1 degrees of freedom but lists 2 coordinates"
    );
    let e = compile_err(&two_link_with("parent = \"upper\"", "parent = \"lower\""));
    assert!(
        e.to_string()
            .contains("connects segment \"lower\" to itself"),
        "{e}"
    );
    let e = compile_err(&two_link_with(
        "name = \"elbow_in_lower\"",
        "name = \"upper_length\"",
    ));
    assert_eq!(e.to_string(), "parameter \"upper_length\" is defined twice");
}

#[test]
fn loops_and_orphans_are_rejected() {
    let text = r#"
name = "loop"
segments = [{ name = "a" }, { name = "b" }]
[[joints]]
name = "j1"
parent = "b"
child = "a"
kind = { type = "weld" }
[[joints]]
name = "j2"
parent = "a"
child = "b"
kind = { type = "weld" }
"#;
    let e = compile_err(text);
    assert!(e.to_string().contains("not connected to ground"), "{e}");
    let orphan = "name = \"o\"\nsegments = [{ name = \"a\" }]\njoints = []\n";
    assert_eq!(
        compile_err(orphan).to_string(),
        "segment \"a\" is not the child of any joint"
    );
}

#[test]
fn unused_parameter_is_an_error() {
    let mut spec = two_link();
    let mut extra = spec.parameters[0].clone();
    extra.name = "spare".into();
    spec.parameters.push(extra);
    assert_eq!(
        Model::compile(&spec).unwrap_err().to_string(),
        "parameter \"spare\" is not used by any joint offset"
    );
}

#[test]
fn unknown_toml_keys_are_rejected_with_a_position() {
    let text = two_link().to_toml().replacen("group = ", "grup = ", 1);
    let e = ModelSpec::from_toml(&text).unwrap_err().to_string();
    assert!(e.contains("grup"), "{e}");
    assert!(e.contains("line"), "{e}");
}

#[test]
fn joints_may_be_listed_in_any_order() {
    let mut spec = two_link();
    spec.joints.reverse();
    let model = Model::compile(&spec).unwrap();
    assert_eq!(model.segments()[0].name, "upper");
    assert_eq!(model.coordinates()[0].name, "shoulder_angle");
}

/// A fitted value one rounding step past its bound (the solver's scaled variables mapped
/// back) is written at the bound, so the saved description compiles again.
#[test]
fn a_fitted_value_a_rounding_step_past_its_bound_is_saved_at_the_bound() {
    let model = Model::compile(&jointfit::model::lower_limb::lower_limb(
        jointfit::model::lower_limb::Side::Right,
    ))
    .unwrap();
    let mut p = model.nominal_params();
    let upper = model.spec().parameters[0].upper;
    p[0] = f64::from_bits(upper.to_bits() + 1);
    assert!(p[0] > upper);
    let spec = model.spec_with_nominal(&p);
    assert_eq!(spec.parameters[0].nominal, upper);
    Model::compile(&spec).unwrap();
}
