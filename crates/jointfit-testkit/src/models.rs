//! Sample models for tests, in the manner of Pinocchio's `buildModels`: small descriptions
//! that between them exercise every joint kind, general and negative axes, parameters in
//! both offsets, shared and scaled parameters, and marker weights. The TOML texts are in
//! `crates/jointfit-testkit/models/`. The paper's leg is [`jointfit::model::lower_limb`].

use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;

/// A two-link chain (pin joints about z and −z) with parameters in both offsets and a
/// weighted marker.
pub fn two_link() -> ModelSpec {
    parse(include_str!("../models/two_link.toml"), "two_link")
}

/// Every joint kind, general axes, a parameter shared by two scalars and a scaled one.
pub fn kitchen_sink() -> ModelSpec {
    parse(include_str!("../models/kitchen_sink.toml"), "kitchen_sink")
}

/// Every joint kind the description allows, non-principal and negative axes, rotated and
/// translated offsets, parameters read with scales (including −1), a weld with a parameter;
/// every joint is one OpenSim can hold.
pub fn all_kinds() -> ModelSpec {
    parse(include_str!("../models/all_kinds.toml"), "all_kinds")
}

/// Custom joints through every function type: splines and polynomials of a coordinate, a
/// locked coordinate, a coordinate coupled to another joint's, an oblique axis, and
/// parameters on the offsets around them. Coordinates: q1, q2, q4 (q3 locked, qd coupled).
pub fn custom_joints() -> ModelSpec {
    parse(
        include_str!("../models/custom_joints.toml"),
        "custom_joints",
    )
}

/// Every sample model above, compiled, with its name.
pub fn all() -> Vec<(&'static str, Model)> {
    [
        ("two_link", two_link()),
        ("kitchen_sink", kitchen_sink()),
        ("all_kinds", all_kinds()),
        ("custom_joints", custom_joints()),
    ]
    .into_iter()
    .map(|(n, s)| {
        let m = Model::compile(&s).unwrap_or_else(|e| panic!("sample model {n}: {e}"));
        (n, m)
    })
    .collect()
}

fn parse(text: &str, name: &str) -> ModelSpec {
    ModelSpec::from_toml(text).unwrap_or_else(|e| panic!("sample model {name}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::JointKind;

    #[test]
    fn samples_compile_and_cover_every_joint_kind() {
        let mut kinds = std::collections::BTreeSet::new();
        for (_, m) in all() {
            assert!(!m.parameters().is_empty() && !m.markers().is_empty());
            kinds.extend(m.joints().iter().map(|j| j.kind.to_string()));
        }
        let every = [
            JointKind::Weld.to_string(),
            "free".into(),
            "gimbal".into(),
            "universal".into(),
            "pin".into(),
            "slider".into(),
        ];
        for k in every {
            assert!(kinds.contains(&k), "no sample model has a {k} joint");
        }
    }
}
