//! The PROCESSING group of a Vicon Nexus C3D: the subject measurements Plug-in Gait used
//! (Bodymass, Height, InterAsisDistance, RLegLength, LKneeWidth, RAnkleWidth, …), stored as
//! named float parameters in millimetres (kilograms, radians for the few that are not
//! lengths).

use std::collections::BTreeMap;

use jointfit_landmarks::subject::SubjectMeasurements;

use super::Parameters;

/// Every numeric parameter of the PROCESSING group by its stored name (first value), in
/// the file's units; empty when the file has no such group.
pub fn processing_values(params: &Parameters) -> BTreeMap<String, f64> {
    let Some(group) = params.group("PROCESSING") else {
        return BTreeMap::new();
    };
    group
        .params
        .values()
        .filter_map(|p| Some((p.name.clone(), p.f64()?)))
        .filter(|(_, v)| v.is_finite())
        .collect()
}

/// The subject measurements of the PROCESSING group (see [`crate::vsk::vicon_measurements`]
/// for the names read).
pub fn processing_measurements(params: &Parameters) -> SubjectMeasurements {
    crate::vsk::vicon_measurements(
        processing_values(params)
            .iter()
            .map(|(k, v)| (k.as_str(), *v)),
    )
}

#[cfg(test)]
mod tests {
    use super::super::{Group, ParamData, Parameter};
    use super::*;

    fn param(name: &str, v: f32) -> Parameter {
        Parameter {
            name: name.to_ascii_uppercase(),
            description: String::new(),
            locked: false,
            dims: vec![],
            data: ParamData::Float(vec![v]),
        }
    }

    #[test]
    fn reads_named_floats_and_maps_vicon_names() {
        let mut group = Group {
            name: "PROCESSING".into(),
            ..Group::default()
        };
        for (n, v) in [
            ("RKneeWidth", 105.0),
            ("LLegLength", 880.0),
            ("RAsisTrocanterDistance", 0.0),
            ("Bodymass", 70.0),
        ] {
            group.params.insert(n.to_ascii_uppercase(), param(n, v));
        }
        let mut params = Parameters::default();
        params.groups.insert("PROCESSING".into(), group);
        let values = processing_values(&params);
        assert_eq!(values.get("BODYMASS"), Some(&70.0));
        let m = processing_measurements(&params);
        assert_eq!(m.knee_width_r, Some(0.105));
        assert_eq!(m.leg_length_l, Some(0.88));
        // Vicon's 0 means "not measured".
        assert_eq!(m.asis_trochanter_r, None);
        assert!(processing_values(&Parameters::default()).is_empty());
    }
}
