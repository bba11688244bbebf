//! Vicon subject files (`.vsk`, XML): the subject measurements of a Plug-in Gait model.
//!
//! A `.vsk` holds `<StaticParameter NAME="RightKneeWidth" VALUE="105" …/>` elements (and
//! `<Parameter …/>` for values the model computed); lengths in millimetres. A parameter
//! without a VALUE, or with 0, is not measured. The names read (case-insensitive; the
//! C3D's PROCESSING group spells the sides `R`/`L`, the `.vsk` `Right`/`Left`):
//! `InterAsisDistance`, `{R,L,Right,Left}LegLength`, `…KneeWidth`, `…AnkleWidth`,
//! `…AsisTrocanterDistance`, `MarkerDiameter`.

use std::path::Path;

use jointfit_landmarks::subject::SubjectMeasurements;
use thiserror::Error;

/// Why a `.vsk` could not be read.
#[derive(Debug, Error)]
pub enum VskError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a Vicon subject file: {detail}")]
    Syntax { path: String, detail: String },
    #[error("{path} line {line}: parameter {name}: VALUE {value:?} is not a number")]
    Value {
        path: String,
        line: u32,
        name: String,
        value: String,
    },
}

/// The canonical measurement a Vicon parameter name stands for.
fn canonical(name: &str) -> Option<&'static str> {
    let n = name.to_ascii_lowercase();
    let (side, rest) = if let Some(r) = n.strip_prefix("right") {
        ("_r", r)
    } else if let Some(r) = n.strip_prefix("left") {
        ("_l", r)
    } else if let Some(r) = n.strip_prefix('r').filter(|r| !r.is_empty()) {
        ("_r", r)
    } else if let Some(r) = n.strip_prefix('l').filter(|r| !r.is_empty()) {
        ("_l", r)
    } else {
        ("", n.as_str())
    };
    let base = match n.as_str() {
        "interasisdistance" => return Some("inter_asis"),
        "markerdiameter" => return Some("marker_diameter"),
        _ => match rest {
            "leglength" => "leg_length",
            "kneewidth" => "knee_width",
            "anklewidth" => "ankle_width",
            "asistrocanterdistance" => "asis_trochanter",
            _ => return None,
        },
    };
    jointfit_landmarks::subject::MEASUREMENT_NAMES
        .into_iter()
        .find(|m| m.strip_suffix(side) == Some(base))
}

/// Subject measurements from Vicon-named values in millimetres; 0 (not measured) and names
/// that are not measurements are skipped.
pub fn vicon_measurements<'a>(
    values: impl IntoIterator<Item = (&'a str, f64)>,
) -> SubjectMeasurements {
    let mut m = SubjectMeasurements::default();
    for (name, mm) in values {
        if let Some(c) = canonical(name) {
            if mm != 0.0 {
                // An implausible value is left out here; the model then reports it missing.
                let _ = m.set(c, mm * 1e-3);
            }
        }
    }
    m
}

/// Reads the subject measurements of a `.vsk` text; `path` names it in errors.
pub fn parse_vsk(text: &str, path: &str) -> Result<SubjectMeasurements, VskError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| VskError::Syntax {
        path: path.into(),
        detail: e.to_string(),
    })?;
    if doc.root_element().tag_name().name() != "KinematicModel" {
        return Err(VskError::Syntax {
            path: path.into(),
            detail: format!(
                "its root element is <{}>, not <KinematicModel>",
                doc.root_element().tag_name().name()
            ),
        });
    }
    let mut values = Vec::new();
    for node in doc.descendants().filter(|n| {
        n.is_element() && matches!(n.tag_name().name(), "StaticParameter" | "Parameter")
    }) {
        let (Some(name), Some(value)) = (node.attribute("NAME"), node.attribute("VALUE")) else {
            continue;
        };
        if canonical(name).is_none() {
            continue;
        }
        let v: f64 = value.trim().parse().map_err(|_| VskError::Value {
            path: path.into(),
            line: doc.text_pos_at(node.range().start).row,
            name: name.into(),
            value: value.into(),
        })?;
        values.push((name.to_string(), v));
    }
    Ok(vicon_measurements(
        values.iter().map(|(n, v)| (n.as_str(), *v)),
    ))
}

/// Reads a `.vsk` file's subject measurements.
pub fn read_vsk(path: &Path) -> Result<SubjectMeasurements, VskError> {
    let shown = path.display().to_string();
    let text = crate::limits::read_text(path, crate::limits::DOCUMENT_BYTES, "subject").map_err(
        |source| VskError::Io {
            path: shown.clone(),
            source,
        },
    )?;
    parse_vsk(&text, &shown)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_map_to_measurements() {
        assert_eq!(canonical("RightKneeWidth"), Some("knee_width_r"));
        assert_eq!(canonical("LKneeWidth"), Some("knee_width_l"));
        assert_eq!(canonical("LLegLength"), Some("leg_length_l"));
        assert_eq!(
            canonical("LeftAsisTrocanterDistance"),
            Some("asis_trochanter_l")
        );
        assert_eq!(canonical("InterAsisDistance"), Some("inter_asis"));
        assert_eq!(canonical("MarkerDiameter"), Some("marker_diameter"));
        assert_eq!(canonical("RightTibialTorsion"), None);
        assert_eq!(canonical("Bodymass"), None);
    }

    #[test]
    fn parses_static_parameters() {
        let text = r#"<?xml version="1.0"?>
<KinematicModel MODEL="PlugInGait">
  <Parameters>
    <StaticParameter NAME="RightKneeWidth" VALUE="105" />
    <StaticParameter NAME="LeftLegLength" VALUE="880.5" />
    <StaticParameter NAME="RightTibialTorsion" />
    <StaticParameter NAME="InterAsisDistance" VALUE="0" />
  </Parameters>
</KinematicModel>"#;
        let m = parse_vsk(text, "s.vsk").unwrap();
        assert_eq!(m.knee_width_r, Some(0.105));
        assert!((m.leg_length_l.unwrap() - 0.8805).abs() < 1e-15);
        assert_eq!(m.inter_asis, None);
        let bad = text.replace("\"880.5\"", "\"88o\"");
        let e = parse_vsk(&bad, "s.vsk").unwrap_err().to_string();
        assert_eq!(
            e,
            "s.vsk line 5: parameter LeftLegLength: VALUE \"88o\" is not a number"
        );
        let e = parse_vsk("<Model/>", "s.vsk").unwrap_err().to_string();
        assert!(e.contains("not <KinematicModel>"), "{e}");
    }
}
