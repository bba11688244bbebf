//! The `.osim` export's names and errors ([`jointfit_io::osim`]): names that XML or OpenSim
//! cannot take are escaped or refused, bad parameter vectors are one-line errors.

use jointfit::model::lower_limb::builtin;
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit_io::osim::{to_osim, write_osim, OsimError};
use jointfit_testkit::models::all_kinds;

use crate::osim::tempdir;

#[test]
fn osim_names_are_escaped_and_checked() {
    let mut spec = builtin("lower-limb-right").unwrap();
    spec.markers[0].name = "R&D<1>".into();
    spec.name = "my leg/2".into();
    spec.description = "a -- b".into();
    let model = Model::compile(&spec).unwrap();
    let text = to_osim(&model, &model.nominal_params()).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    assert!(doc
        .descendants()
        .any(|n| n.has_tag_name("Marker") && n.attribute("name") == Some("R&D<1>")));
    assert!(doc
        .descendants()
        .any(|n| n.has_tag_name("Model") && n.attribute("name") == Some("my_leg_2")));

    spec.markers[0].name = "R ASI".into();
    let model = Model::compile(&spec).unwrap();
    let e = to_osim(&model, &model.nominal_params()).unwrap_err();
    assert!(
        matches!(e, OsimError::BadName { kind: "marker", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("\"R ASI\""), "{e}");
    spec.markers[0].name = "RASI".into();
    spec.segments[1].name = "thigh/r".into();
    for j in &mut spec.joints {
        for s in [&mut j.parent, &mut j.child] {
            if s == "thigh" {
                *s = "thigh/r".into();
            }
        }
    }
    for m in &mut spec.markers {
        if m.segment == "thigh" {
            m.segment = "thigh/r".into();
        }
    }
    let model = Model::compile(&spec).unwrap();
    let e = to_osim(&model, &model.nominal_params()).unwrap_err();
    assert!(
        matches!(
            e,
            OsimError::BadName {
                kind: "segment",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn osim_errors() {
    let model = Model::compile(&builtin("lower-limb-right").unwrap()).unwrap();
    let e = to_osim(&model, &[0.0; 3]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "parameter vector has 3 values, the model has 27 parameters"
    );
    let mut p = model.nominal_params();
    p[4] = f64::NAN;
    let e = to_osim(&model, &p).unwrap_err();
    assert_eq!(
        e.to_string(),
        "parameter \"hip_thigh_superior\" = NaN is not finite"
    );

    // A z-x-z gimbal (proper Euler angles) repeats an axis: no CustomJoint can hold it.
    let mut spec = all_kinds();
    spec.joints[1].kind = ModelSpec::from_toml(
        "name = \"x\"\nsegments = []\n[[joints]]\nname = \"j\"\nparent = \"ground\"\n\
         child = \"s\"\nkind = { type = \"gimbal\", axes = [\"z\", \"x\", \"-z\"] }\n",
    )
    .unwrap()
    .joints[0]
        .kind
        .clone();
    let model = Model::compile(&spec).unwrap();
    let e = to_osim(&model, &model.nominal_params()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "joint \"shoulder\": rotation axes 1 and 3 are parallel; an OpenSim CustomJoint needs \
         independent axes, so this joint cannot be exported"
    );
    // A universal joint with parallel axes: refused when the model is loaded, before any
    // export (jointfit::model::fields).
    let mut spec = all_kinds();
    if let jointfit::model::spec::JointKindSpec::Universal { axes } = &mut spec.joints[2].kind {
        axes[1] = jointfit::model::spec::AxisSpec::Vector([0.0, 0.0, -2.0]);
    }
    let e = Model::compile(&spec).unwrap_err().to_string();
    assert!(
        e.starts_with("joint \"elbow\": rotation axes 1 and 2 are parallel"),
        "{e}"
    );
    // An unwritable destination names the file; nothing is left behind.
    let dir = tempdir();
    let model = Model::compile(&builtin("lower-limb-left").unwrap()).unwrap();
    let path = dir.path().join("no/such/dir/leg.osim");
    let e = write_osim(&path, &model, &model.nominal_params()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with(&format!("{}: cannot write", path.display())),
        "{e}"
    );
}
