//! Plug-in Gait's (Conventional Gait Model 1) joint centres from lateral markers and the
//! subject's measurements.
//!
//! ## Hip centre (Davis et al. 1991, Hum Mov Sci 10:575–587)
//! In the pelvis frame (origin mid-ASIS; x anterior, y superior, z to the right), with the
//! mean leg length `L`, the side's ASIS-to-trochanter distance `X_dis` (when not measured,
//! `0.1288·L_side − 48.56 mm`, Vicon's regression), half the inter-ASIS distance `a`, the
//! marker radius `r`, and `C = 0.115·L − 15.3 mm`:
//!
//! ```text
//! anterior  = (−X_dis − r)·cos β + C·cos θ·sin β
//! superior  = (−X_dis − r)·sin β − C·cos θ·cos β
//! lateral   = ±(a − C·sin θ)            (+ right, − left)
//! ```
//!
//! Davis et al. give θ = 28.4° and β = 18°; Vicon's Plug-in Gait uses θ = 0.5 rad (28.65°)
//! and β = 0.314 rad (17.99°) (the values pyCGM, the open reimplementation, reproduces Vicon
//! with), and so does this module, to reproduce Vicon's hip centres.
//!
//! ## Knee and ankle centres: the chord function
//! The joint centre `J` lies in the plane of three points: the wand marker `a` (thigh or
//! tibia wand), the proximal joint centre `b` (hip or knee centre) and the lateral marker `c`
//! (knee or ankle marker); it lies at the distance `δ = width/2 + r` from `c`, and the line
//! from `J` to `c` is perpendicular to the line from `J` to `b`. `J` is therefore on the
//! circle of diameter `bc` (Thales), at the inscribed angle `φ = acos(δ/|b − c|)` from `cb`:
//! with `m = (b + c)/2`, `u = (b − c)/|b − c|` and `n` the unit normal `(a − c) × (b − c)`,
//!
//! ```text
//! J = m + |b − c|/2 · (cos 2φ · u + sin 2φ · n × u)
//! ```
//!
//! (Vicon Plug-in Gait Reference Guide, "chord function"; Davis et al. 1991.) The knee
//! flexion axis of Plug-in Gait's femur then points from `J` toward the knee marker, which
//! is perpendicular to the femur's long axis by construction; the same holds at the ankle.

use nalgebra::Vector3;

use super::subject::SubjectMeasurements;
use jointfit::model::lower_limb::Side;

/// Vicon's θ (rad) in Davis's hip regression.
pub(crate) const DAVIS_THETA: f64 = 0.5;
/// Vicon's β (rad) in Davis's hip regression.
pub(crate) const DAVIS_BETA: f64 = 0.314;

/// What a Plug-in Gait joint centre needs and did not get: the measurement's description.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Missing(pub String);

/// The hip centre in the pelvis frame (m; x anterior, y superior, z right) by Davis et al.
/// 1991 as Plug-in Gait applies it (module docs). `pelvis_width` is the inter-ASIS distance
/// of the markers, used when no `inter_asis` measurement is given.
pub(crate) fn davis_hip(
    m: &SubjectMeasurements,
    side: Side,
    pelvis_width: f64,
) -> Result<Vector3<f64>, Missing> {
    let mean = m
        .mean_leg_length()
        .ok_or_else(|| Missing("the leg length (right and/or left)".into()))?;
    let own = m.leg_length(side).unwrap_or(mean);
    let x_dis = m.asis_trochanter(side).unwrap_or(0.1288 * own - 0.04856);
    let r = 0.5 * m.marker_diameter_or_default();
    let a = 0.5 * m.inter_asis.unwrap_or(pelvis_width);
    let c = 0.115 * mean - 0.0153;
    let (st, ct) = DAVIS_THETA.sin_cos();
    let (sb, cb) = DAVIS_BETA.sin_cos();
    Ok(Vector3::new(
        (-x_dis - r) * cb + c * ct * sb,
        (-x_dis - r) * sb - c * ct * cb,
        side.sign() * (a - c * st),
    ))
}

/// The chord function (module docs): the joint centre in the plane of `wand`, `proximal` and
/// `lateral`, `delta` from `lateral`, seen from `proximal` at a right angle. `None` when the
/// three points are collinear or `delta` is not shorter than `|proximal − lateral|`.
pub(crate) fn chord(
    wand: &Vector3<f64>,
    proximal: &Vector3<f64>,
    lateral: &Vector3<f64>,
    delta: f64,
) -> Option<Vector3<f64>> {
    let bc = proximal - lateral;
    let len = bc.norm();
    let n = (wand - lateral).cross(&bc);
    if !(len > 0.0 && delta >= 0.0 && delta < len) || n.norm() < 1e-9 * len * len {
        return None;
    }
    let (u, n) = (bc / len, n.normalize());
    let phi = (delta / len).acos();
    let (s2, c2) = (2.0 * phi).sin_cos();
    Some(0.5 * (proximal + lateral) + 0.5 * len * (c2 * u + s2 * n.cross(&u)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pyCGM's documented example of its chord function (mm): an independent number.
    #[test]
    fn chord_matches_the_published_example() {
        let a = Vector3::new(468.14532471, 325.09780884, 673.12591553);
        let b = Vector3::new(355.90861996, 365.38260964, 940.6974861);
        let c = Vector3::new(452.35180664, 329.0609436, 524.77893066);
        let j = chord(&a, &b, &c, 59.5).unwrap();
        let want = Vector3::new(396.25286248, 347.91367254, 518.63620527);
        assert!((j - want).norm() < 1e-6, "{j:?}");
        // The defining properties: δ from c, a right angle at J, in the plane of a, b, c.
        assert!(((j - c).norm() - 59.5).abs() < 1e-9);
        assert!((j - c).dot(&(j - b)).abs() < 1e-6);
        assert!((j - c).dot(&(a - c).cross(&(b - c)).normalize()).abs() < 1e-9);
        assert!(chord(&a, &b, &c, 1e4).is_none());
        assert!(chord(&b, &b, &c, 10.0).is_none());
    }

    /// The published example of pyCGM's hip centre (its test subject, pelvis axes given).
    #[test]
    fn davis_hip_matches_the_published_example() {
        // Pelvis rows x (anterior), y (left), z (up) and origin, mm.
        let (x, y, z) = (
            Vector3::new(0.14, 0.98, -0.11),
            Vector3::new(-0.99, 0.13, -0.02),
            Vector3::new(0.0, 0.1, 0.99),
        );
        let origin = Vector3::new(251.60, 391.74, 1032.89);
        let m = SubjectMeasurements {
            leg_length_r: Some(0.940),
            leg_length_l: Some(0.940),
            asis_trochanter_r: Some(0.07251),
            asis_trochanter_l: Some(0.07251),
            inter_asis: Some(0.21590),
            ..SubjectMeasurements::default()
        };
        for (side, want) in [
            (Side::Right, Vector3::new(307.36, 323.83, 938.72)),
            (Side::Left, Vector3::new(181.71, 340.33, 936.18)),
        ] {
            let h = davis_hip(&m, side, 0.2).unwrap() * 1e3;
            // Our z (right) is Vicon's −y.
            let world = origin + h.x * x + h.y * z - h.z * y;
            assert!((world - want).abs().max() < 0.01, "{side:?}: {world:?}");
        }
        let e = davis_hip(&SubjectMeasurements::default(), Side::Right, 0.2).unwrap_err();
        assert_eq!(e.0, "the leg length (right and/or left)");
    }
}
