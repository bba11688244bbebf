//! Subject measurements taken in the laboratory (anthropometry): what Plug-in Gait's hip,
//! knee and ankle centres need besides the markers.
//!
//! Values are in metres. Each measurement has a canonical name ([`MEASUREMENT_NAMES`]):
//! `leg_length_r`/`_l` (ASIS to medial malleolus), `knee_width_r`/`_l` and
//! `ankle_width_r`/`_l` (across the epicondyles / malleoli), `inter_asis` (ASIS to ASIS),
//! `asis_trochanter_r`/`_l` (ASIS to greater trochanter, perpendicular to the leg) and
//! `marker_diameter`. A missing value is `None`; Vicon's files write 0 for "not measured",
//! which the readers turn into `None`.

use jointfit::model::lower_limb::Side;

/// Canonical names of the measurements, in the order of the fields.
pub const MEASUREMENT_NAMES: [&str; 10] = [
    "leg_length_r",
    "leg_length_l",
    "knee_width_r",
    "knee_width_l",
    "ankle_width_r",
    "ankle_width_l",
    "inter_asis",
    "asis_trochanter_r",
    "asis_trochanter_l",
    "marker_diameter",
];

/// Plug-in Gait's default marker diameter (m) when none is given.
pub(crate) const DEFAULT_MARKER_DIAMETER: f64 = 0.014;

/// A subject's measurements (m); `None` when not measured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SubjectMeasurements {
    pub leg_length_r: Option<f64>,
    pub leg_length_l: Option<f64>,
    pub knee_width_r: Option<f64>,
    pub knee_width_l: Option<f64>,
    pub ankle_width_r: Option<f64>,
    pub ankle_width_l: Option<f64>,
    pub inter_asis: Option<f64>,
    pub asis_trochanter_r: Option<f64>,
    pub asis_trochanter_l: Option<f64>,
    pub marker_diameter: Option<f64>,
}

impl SubjectMeasurements {
    fn slots(&mut self) -> [&mut Option<f64>; 10] {
        [
            &mut self.leg_length_r,
            &mut self.leg_length_l,
            &mut self.knee_width_r,
            &mut self.knee_width_l,
            &mut self.ankle_width_r,
            &mut self.ankle_width_l,
            &mut self.inter_asis,
            &mut self.asis_trochanter_r,
            &mut self.asis_trochanter_l,
            &mut self.marker_diameter,
        ]
    }

    #[cfg(test)]
    /// The values by canonical name, in [`MEASUREMENT_NAMES`] order.
    pub(crate) fn values(&self) -> [(&'static str, Option<f64>); 10] {
        let mut copy = self.clone();
        let vals = copy.slots().map(|v| *v);
        let mut out = [("", None); 10];
        for (k, (n, v)) in MEASUREMENT_NAMES.iter().zip(vals).enumerate() {
            out[k] = (*n, v);
        }
        out
    }

    /// Sets one measurement by canonical name (m). A value that is not a finite positive
    /// length is refused; the error names the measurement.
    pub fn set(&mut self, name: &str, metres: f64) -> Result<(), String> {
        let k = MEASUREMENT_NAMES
            .iter()
            .position(|n| *n == name)
            .ok_or_else(|| {
                format!(
                    "unknown subject measurement {name:?}; known: {}",
                    MEASUREMENT_NAMES.join(", ")
                )
            })?;
        if !(metres.is_finite() && metres > 0.0 && metres < 3.0) {
            return Err(format!(
                "subject measurement {name} = {} mm is not a plausible length",
                metres * 1e3
            ));
        }
        *self.slots()[k] = Some(metres);
        Ok(())
    }

    /// Every value `other` has replaces this one's (a later source overrides an earlier).
    pub fn update(&mut self, other: &SubjectMeasurements) {
        let theirs = other.clone().slots().map(|v| *v);
        for (mine, v) in self.slots().into_iter().zip(theirs) {
            if v.is_some() {
                *mine = v;
            }
        }
    }

    #[cfg(test)]
    /// Whether no value is given.
    pub(crate) fn is_empty(&self) -> bool {
        self.values().iter().all(|(_, v)| v.is_none())
    }

    pub(crate) fn leg_length(&self, side: Side) -> Option<f64> {
        match side {
            Side::Right => self.leg_length_r,
            Side::Left => self.leg_length_l,
        }
    }

    /// Mean of the legs' lengths that are given (Plug-in Gait's `MeanLegLength`).
    pub fn mean_leg_length(&self) -> Option<f64> {
        match (self.leg_length_r, self.leg_length_l) {
            (Some(r), Some(l)) => Some(0.5 * (r + l)),
            (r, l) => r.or(l),
        }
    }

    pub(crate) fn knee_width(&self, side: Side) -> Option<f64> {
        match side {
            Side::Right => self.knee_width_r,
            Side::Left => self.knee_width_l,
        }
    }

    pub(crate) fn ankle_width(&self, side: Side) -> Option<f64> {
        match side {
            Side::Right => self.ankle_width_r,
            Side::Left => self.ankle_width_l,
        }
    }

    pub(crate) fn asis_trochanter(&self, side: Side) -> Option<f64> {
        match side {
            Side::Right => self.asis_trochanter_r,
            Side::Left => self.asis_trochanter_l,
        }
    }

    /// The marker diameter, Plug-in Gait's 14 mm when not given.
    pub(crate) fn marker_diameter_or_default(&self) -> f64 {
        self.marker_diameter.unwrap_or(DEFAULT_MARKER_DIAMETER)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_update_and_look_up() {
        let mut m = SubjectMeasurements::default();
        assert!(m.is_empty());
        m.set("knee_width_r", 0.105).unwrap();
        m.set("leg_length_l", 0.9).unwrap();
        assert_eq!(m.knee_width(Side::Right), Some(0.105));
        assert_eq!(m.mean_leg_length(), Some(0.9));
        let mut later = SubjectMeasurements::default();
        later.set("knee_width_r", 0.11).unwrap();
        later.set("leg_length_r", 0.8).unwrap();
        m.update(&later);
        assert_eq!(m.knee_width_r, Some(0.11));
        assert!((m.mean_leg_length().unwrap() - 0.85).abs() < 1e-15);
        assert_eq!(m.marker_diameter_or_default(), 0.014);
        let e = m.set("knee", 0.1).unwrap_err();
        assert!(e.starts_with("unknown subject measurement \"knee\""), "{e}");
        let e = m.set("inter_asis", -0.2).unwrap_err();
        assert_eq!(
            e,
            "subject measurement inter_asis = -200 mm is not a plausible length"
        );
        assert_eq!(m.values()[2], ("knee_width_r", Some(0.11)));
    }
}
