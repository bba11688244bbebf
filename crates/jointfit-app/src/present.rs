//! Presentation at the edge: the units a person reads (mm, degrees) and the hints that name a
//! front end's own options. The core and the pipeline work in SI and name settings, never a
//! command-line flag; the command line, the report and the Python package turn values and
//! errors into text here.

use jointfit::model::spec::Unit;
use jointfit::model::spec::MM_PER_M;
use jointfit::spatial::UpAxis;
use jointfit::workflow::WorkflowError;

/// Who reads the text: the command line (flags) or Python (keyword arguments; the batch
/// manifest's keys are the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Front {
    Cli,
    Python,
}

/// A value in SI (m or rad) in the unit a person reads (mm or deg), with that unit's name.
pub fn shown(value_si: f64, unit: Unit) -> (f64, &'static str) {
    match unit {
        Unit::Metre => (value_si * MM_PER_M, "mm"),
        Unit::Radian => (value_si.to_degrees(), "deg"),
    }
}

/// How to read a trial with `axis` up, as the pipeline's warnings say it (Python's keyword
/// and the batch manifest's key are both `up`).
pub fn read_with_up(axis: UpAxis) -> String {
    format!("read it with up=\"{axis}\"")
}

/// The option of `front` that resolves a workflow error, when one does.
pub fn hint(e: &WorkflowError, front: Front) -> Option<&'static str> {
    match (e, front) {
        (WorkflowError::RefineNeedsPriors, Front::Cli) => Some("drop --prior none"),
        (WorkflowError::RefineNeedsPriors, Front::Python) => Some("pass prior=\"model\""),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Display units against the definitions: 1 mm = 1e-3 m, 180° = π rad.
    #[test]
    fn shown_units() {
        let (mm, u) = shown(0.0125, Unit::Metre);
        assert!((mm - 12.5).abs() < 1e-12 && u == "mm");
        let (deg, u) = shown(std::f64::consts::PI / 4.0, Unit::Radian);
        assert!((deg - 45.0).abs() < 1e-12 && u == "deg");
    }

    #[test]
    fn hints_name_each_front_ends_own_option() {
        let e = WorkflowError::RefineNeedsPriors;
        assert!(!e.to_string().contains("--"), "{e}");
        assert_eq!(hint(&e, Front::Cli), Some("drop --prior none"));
        assert!(hint(&e, Front::Python).unwrap().contains("prior="));
        assert_eq!(read_with_up(UpAxis::NegZ), "read it with up=\"-z\"");
    }
}
