//! The units the experiments' tables show: millimetres for lengths, degrees for angles (the
//! paper's Tables 1 and 2); the models and fits are SI (m, rad).

use jointfit::model::spec::Unit;

/// Millimetres per metre.
pub const MM_PER_M: f64 = 1e3;

/// Shown units per SI unit of `unit`: 1000 mm per m, 180/π degrees per radian.
pub fn scale(unit: Unit) -> f64 {
    match unit {
        Unit::Metre => MM_PER_M,
        Unit::Radian => 180.0 / std::f64::consts::PI,
    }
}

/// The shown unit of `unit`: `mm` or `deg`.
pub fn suffix(unit: Unit) -> &'static str {
    match unit {
        Unit::Metre => "mm",
        Unit::Radian => "deg",
    }
}

/// An SI value of `unit` (m or rad) in its shown unit (mm or deg).
pub fn shown(si: f64, unit: Unit) -> f64 {
    si * scale(unit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_in_mm_and_angles_in_degrees() {
        assert_eq!(shown(0.012, Unit::Metre), 12.0);
        assert!((shown(std::f64::consts::FRAC_PI_2, Unit::Radian) - 90.0).abs() < 1e-12);
        assert_eq!((suffix(Unit::Metre), suffix(Unit::Radian)), ("mm", "deg"));
    }
}
