//! Segment frames from averaged static landmarks (docs/architecture.md §6), the regression hip
//! centre, the joint axes, and the checks that catch swapped labels and degenerate markers.
//!
//! Every frame is built from the markers alone, so the laboratory heading does not matter:
//! only the vertical (+y) is used, to check that the pelvis is upright. "Right" below means
//! the model's +z: for a left leg the epicondyle and malleolus vectors run lateral → medial.

use nalgebra::{Matrix3, Vector3};

use super::{HipCentreMethod, LandmarkError, PersonalizeOptions};
use jointfit::model::lower_limb::Side;
use jointfit::spatial::Pose;

/// `world_from_segment` of every segment at the averaged static pose (trial frame, m).
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentFrames {
    pub pelvis: Pose,
    pub thigh: Pose,
    pub shank: Pose,
    /// Virtual segment: origin at the ankle centre, z along the talocrural axis, y along the
    /// common perpendicular of the talocrural and subtalar axes, pointing away from the
    /// subtalar axis (so the subtalar offset along y is negative, as in Reinbolt's Table 2).
    pub talus: Pose,
    pub foot: Pose,
}

/// Averaged landmark positions (trial frame, m).
#[derive(Debug, Clone)]
pub(crate) struct Landmarks {
    pub r_asis: Vector3<f64>,
    pub l_asis: Vector3<f64>,
    /// Mid-PSIS, or the sacrum marker.
    pub back: Vector3<f64>,
    pub lat_epicondyle: Vector3<f64>,
    /// The medial epicondyle marker, or how Plug-in Gait's chord function finds the knee
    /// centre without one.
    pub med_epicondyle: Medial,
    pub lat_malleolus: Vector3<f64>,
    pub med_malleolus: Medial,
    pub heel: Vector3<f64>,
    /// Mean of the forefoot markers.
    pub forefoot: Vector3<f64>,
    /// The hip centre itself (a video keypoint), used instead of a regression.
    pub hip_centre: Option<Vector3<f64>>,
}

/// A medial landmark: a marker, or Plug-in Gait's chord construction
/// ([`super::plugin_gait::chord`]) from a wand marker in the plane of the joint.
#[derive(Debug, Clone)]
pub(crate) enum Medial {
    Marker(Vector3<f64>),
    /// The wand marker and the distance δ = width/2 + marker radius from the lateral marker
    /// to the joint centre (m).
    Chord {
        wand: Vector3<f64>,
        delta: f64,
    },
}

/// The medial point that puts the joint centre at the chord function's centre: the lateral
/// marker mirrored through it. `proximal` is the joint centre above.
fn medial_point(
    medial: &Medial,
    lateral: &Vector3<f64>,
    proximal: &Vector3<f64>,
    joint: &str,
    segment: &str,
) -> Result<Vector3<f64>, LandmarkError> {
    match medial {
        Medial::Marker(m) => Ok(*m),
        Medial::Chord { wand, delta } => {
            let centre =
                super::plugin_gait::chord(wand, proximal, lateral, *delta).ok_or_else(|| {
                    LandmarkError::Degenerate {
                        segment: segment.into(),
                        detail: format!(
                            "the {joint} centre by the chord function: the wand marker, the \
                         lateral marker and the joint centre above are collinear, or the \
                         lateral marker is within {:.1} mm (half the width plus the marker \
                         radius) of the joint centre above",
                            delta * 1e3
                        ),
                    }
                })?;
            Ok(2.0 * centre - lateral)
        }
    }
}

/// Everything the landmark method derives from one static pose.
#[derive(Debug, Clone)]
pub(crate) struct Anatomy {
    pub frames: SegmentFrames,
    /// Hip centre in the pelvis frame (m).
    pub hip_in_pelvis: Vector3<f64>,
    /// Hip centre in the thigh frame (m): zero for the landmark method (the thigh origin),
    /// the functional centre's offset when a functional hip trial is used.
    pub hip_in_thigh: Vector3<f64>,
    pub hip_centre: Vector3<f64>,
    pub knee_centre: Vector3<f64>,
    pub ankle_centre: Vector3<f64>,
    /// Unit epicondyle direction toward +z of the model (world).
    pub knee_axis: Vector3<f64>,
    /// Unit malleolus direction toward +z of the model (world).
    pub ankle_axis: Vector3<f64>,
    /// Unit subtalar axis direction, pointing anterior (world).
    pub subtalar_axis: Vector3<f64>,
    /// The point of the subtalar axis on the common perpendicular (world).
    pub subtalar_point: Vector3<f64>,
    pub pelvis_width: f64,
    pub pelvis_depth: f64,
    pub knee_width: f64,
    pub ankle_width: f64,
}

/// The frame with origin `origin` and unit axes `x`, `y`, `z` (right-handed by construction).
fn frame(origin: Vector3<f64>, x: Vector3<f64>, y: Vector3<f64>, z: Vector3<f64>) -> Pose {
    Pose {
        rot: Matrix3::from_columns(&[x, y, z]),
        trans: origin,
    }
}

/// `v` with its component along the unit vector `along` removed, normalised; `None` when the
/// rest is shorter than `min` (nearly parallel).
fn orthonormal(v: Vector3<f64>, along: &Vector3<f64>, min: f64) -> Option<Vector3<f64>> {
    let r = v - along * along.dot(&v);
    let n = r.norm();
    (n > min).then(|| r / n)
}

fn unit(v: Vector3<f64>, what: &str, segment: &str) -> Result<Vector3<f64>, LandmarkError> {
    let n = v.norm();
    if n < 1e-3 || !n.is_finite() {
        return Err(LandmarkError::Degenerate {
            segment: segment.into(),
            detail: format!("{what} is {:.1} mm long", n * 1e3),
        });
    }
    Ok(v / n)
}

fn perpendicular(
    v: Vector3<f64>,
    along: &Vector3<f64>,
    what: &str,
    segment: &str,
) -> Result<Vector3<f64>, LandmarkError> {
    // 0.1 of the vector's length: the landmark line must be at least ~6° off the long axis.
    orthonormal(v, along, 0.1 * v.norm()).ok_or_else(|| LandmarkError::Degenerate {
        segment: segment.into(),
        detail: format!("{what} is nearly parallel to the segment's long axis"),
    })
}

/// The hip centre in the pelvis frame by the regression `opts` names.
fn regression_hip(
    opts: &PersonalizeOptions,
    side: Side,
    pelvis_width: f64,
    pelvis_depth: f64,
) -> Result<Vector3<f64>, LandmarkError> {
    let s = side.sign();
    Ok(match opts.hip_centre {
        HipCentreMethod::Bell => Vector3::new(
            -0.19 * pelvis_width,
            -0.30 * pelvis_width,
            s * 0.36 * pelvis_width,
        ),
        HipCentreMethod::Harrington => Vector3::new(
            -0.24 * pelvis_depth - 0.0099,
            -0.30 * pelvis_width - 0.0109,
            s * (0.33 * pelvis_width + 0.0073),
        ),
        HipCentreMethod::Davis => super::plugin_gait::davis_hip(&opts.subject, side, pelvis_width)
            .map_err(|m| LandmarkError::MissingMeasurement {
                what: m.0,
                why: "the hip centre by Davis et al. 1991 (Plug-in Gait)".into(),
            })?,
    })
}

/// Builds the frames, hip centre and axes (docs/architecture.md §6) and checks them.
pub(crate) fn anatomy(
    lm: &Landmarks,
    side: Side,
    opts: &PersonalizeOptions,
) -> Result<Anatomy, LandmarkError> {
    let s = side.sign();
    let PelvisFrame {
        pelvis,
        mid_asis,
        px,
        pz,
        pelvis_width,
        pelvis_depth,
    } = pelvis_frame(lm)?;
    let hip_in_pelvis = match lm.hip_centre {
        Some(h) => pelvis.inverse().transform_point(&h),
        None => regression_hip(opts, side, pelvis_width, pelvis_depth)?,
    };
    let hip_centre = pelvis.transform_point(&hip_in_pelvis);

    // Rightward (+z) landmark vectors of this leg; a chord-function joint centre is the
    // midpoint of the lateral marker and its mirror image through that centre.
    let med_epicondyle = medial_point(
        &lm.med_epicondyle,
        &lm.lat_epicondyle,
        &hip_centre,
        "knee",
        "thigh",
    )?;
    let knee_centre = 0.5 * (lm.lat_epicondyle + med_epicondyle);
    let med_malleolus = medial_point(
        &lm.med_malleolus,
        &lm.lat_malleolus,
        &knee_centre,
        "ankle",
        "shank",
    )?;
    let knee_vec = s * (lm.lat_epicondyle - med_epicondyle);
    let ankle_vec = s * (lm.lat_malleolus - med_malleolus);
    let ankle_centre = 0.5 * (lm.lat_malleolus + med_malleolus);
    let knee_axis = unit(knee_vec, "the epicondyle line", "thigh")?;
    let ankle_axis = unit(ankle_vec, "the malleolus line", "shank")?;

    // Thigh: origin hip centre, y knee centre → hip centre, z epicondyles made orthogonal.
    let ty = unit(hip_centre - knee_centre, "the hip-to-knee line", "thigh")?;
    let tz = perpendicular(knee_vec, &ty, "the epicondyle line", "thigh")?;
    let thigh = frame(hip_centre, ty.cross(&tz), ty, tz);
    // Shank: origin knee centre, y ankle centre → knee centre, z malleoli made orthogonal.
    let sy = unit(
        knee_centre - ankle_centre,
        "the knee-to-ankle line",
        "shank",
    )?;
    let sz = perpendicular(ankle_vec, &sy, "the malleolus line", "shank")?;
    let shank = frame(knee_centre, sy.cross(&sz), sy, sz);
    // Foot: origin heel, x heel → forefoot, z the shank's z made orthogonal.
    let fx = unit(lm.forefoot - lm.heel, "the heel-to-forefoot line", "foot")?;
    let fz = perpendicular(sz, &fx, "the shank's lateral axis", "foot")?;
    let foot = frame(lm.heel, fx, fz.cross(&fx), fz);

    let sn = super::markerset::side_name(side);
    let lateral = [("epicondyle", tz), ("malleolus", sz)];
    check_leg_sides(
        sn,
        lateral,
        fx,
        s * (knee_centre - mid_asis).dot(&pz),
        &px,
        &pz,
    )?;
    let (talus, subtalar_axis, subtalar_point) =
        talus_frame(opts, s, &foot, &ankle_axis, &ankle_centre)?;
    Ok(Anatomy {
        frames: SegmentFrames {
            pelvis,
            thigh,
            shank,
            talus,
            foot,
        },
        hip_in_pelvis,
        hip_in_thigh: Vector3::zeros(),
        hip_centre,
        knee_centre,
        ankle_centre,
        knee_axis,
        ankle_axis,
        subtalar_axis,
        subtalar_point,
        pelvis_width,
        pelvis_depth,
        knee_width: knee_vec.norm(),
        ankle_width: ankle_vec.norm(),
    })
}

/// The pelvis frame and measures of [`anatomy`].
struct PelvisFrame {
    pelvis: Pose,
    mid_asis: Vector3<f64>,
    /// The pelvis's anterior (x) and rightward (z) axes in the lab.
    px: Vector3<f64>,
    pz: Vector3<f64>,
    pelvis_width: f64,
    pelvis_depth: f64,
}

/// Pelvis: origin mid-ASIS, z left → right ASIS, x anterior in the ASIS/back plane; refused
/// when its superior axis is far from the trial's +Y.
fn pelvis_frame(lm: &Landmarks) -> Result<PelvisFrame, LandmarkError> {
    let mid_asis = 0.5 * (lm.r_asis + lm.l_asis);
    let pelvis_width = (lm.r_asis - lm.l_asis).norm();
    let pz = unit(lm.r_asis - lm.l_asis, "the inter-ASIS line", "pelvis")?;
    let px = perpendicular(
        mid_asis - lm.back,
        &pz,
        "the PSIS/sacrum-to-ASIS line",
        "pelvis",
    )?;
    let py = pz.cross(&px);
    let up = py.y.clamp(-1.0, 1.0).acos().to_degrees();
    if up > 45.0 {
        return Err(LandmarkError::Implausible(format!(
            "the pelvis superior axis (from the ASIS and PSIS/sacrum markers) is {up:.0}° from \
             the trial's +Y: the trial is not Y-up (choose the lab's up axis) or the right and \
             left ASIS labels are swapped"
        )));
    }
    let pelvis = frame(mid_asis, px, py, pz);
    let pelvis_depth = (mid_asis - lm.back).norm();

    Ok(PelvisFrame {
        pelvis,
        mid_asis,
        px,
        pz,
        pelvis_width,
        pelvis_depth,
    })
}

/// Refuses a leg (`sn`: its side's name) whose lateral landmarks (`lateral`: the thigh's and
/// shank's lateral axes) point medially, whose forefoot (`fx`: the foot's anterior axis)
/// lies behind the heel, or whose knee lies across the pelvis midline (`knee_side`: the
/// knee's signed lateral distance from it), as seen from the pelvis (`px`, `pz`).
fn check_leg_sides(
    sn: &str,
    lateral: [(&str, Vector3<f64>); 2],
    fx: Vector3<f64>,
    knee_side: f64,
    px: &Vector3<f64>,
    pz: &Vector3<f64>,
) -> Result<(), LandmarkError> {
    for (what, v) in lateral {
        if v.dot(pz) < 0.0 {
            return Err(LandmarkError::Implausible(format!(
                "the {sn} lateral {what} lies medial of the medial one (seen from the pelvis): \
                 are the lateral and medial labels swapped, or is this the other leg?"
            )));
        }
    }
    if fx.dot(px) < 0.0 {
        return Err(LandmarkError::Implausible(format!(
            "the {sn} forefoot markers lie behind the heel marker (seen from the pelvis): are \
             the heel and forefoot labels swapped?"
        )));
    }
    if knee_side < 0.0 {
        return Err(LandmarkError::Implausible(format!(
            "the {sn} knee lies on the other side of the pelvis midline: wrong leg, or right \
             and left ASIS labels swapped?"
        )));
    }
    Ok(())
}

/// The talus frame (origin at the ankle centre, z along the talocrural axis, y along the
/// common perpendicular to the subtalar axis), the subtalar axis and a point on it
/// (`s`: the side's sign).
fn talus_frame(
    opts: &PersonalizeOptions,
    s: f64,
    foot: &Pose,
    ankle_axis: &Vector3<f64>,
    ankle_centre: &Vector3<f64>,
) -> Result<(Pose, Vector3<f64>, Vector3<f64>), LandmarkError> {
    let (ankle_axis, ankle_centre) = (*ankle_axis, *ankle_centre);
    // Subtalar axis (Inman): elevation and medial deviation in the foot frame, anterior.
    let (elev, dev) = (opts.subtalar_elevation, s * opts.subtalar_deviation);
    let u_foot = Vector3::new(dev.cos() * elev.cos(), elev.sin(), -dev.sin() * elev.cos());
    let subtalar_axis = foot.rot * u_foot;
    // Common perpendicular of the talocrural axis a and the subtalar axis u: n = u × a points
    // inferior and anterior; the subtalar axis passes at `subtalar_offset` along it.
    let n = unit(
        subtalar_axis.cross(&ankle_axis),
        "the common perpendicular of the talocrural and subtalar axes",
        "talus",
    )?;
    let subtalar_point = ankle_centre + opts.subtalar_offset * n;
    let talus_y = -n;
    let talus = frame(
        ankle_centre,
        talus_y.cross(&ankle_axis),
        talus_y,
        ankle_axis,
    );

    Ok((talus, subtalar_axis, subtalar_point))
}

/// Refuses a segment whose tracking markers (averaged) lie within `min_spread` of one line:
/// their rigid fit could not determine the rotation about that line.
pub(crate) fn check_spread(
    segment: &str,
    names: &[String],
    points: &[Vector3<f64>],
    min_spread: f64,
) -> Result<(), LandmarkError> {
    let c: Vector3<f64> = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let mut cov = Matrix3::zeros();
    for p in points {
        cov += (p - c) * (p - c).transpose();
    }
    let eig = cov.symmetric_eigen();
    let k = eig.eigenvalues.imax();
    let dir = eig.eigenvectors.column(k).into_owned();
    let spread = points
        .iter()
        .map(|p| orthonormal_distance(p - c, &dir))
        .fold(0.0, f64::max);
    if spread < min_spread {
        return Err(LandmarkError::Collinear {
            segment: segment.into(),
            markers: names.to_vec(),
            spread_mm: spread * 1e3,
            min_mm: min_spread * 1e3,
        });
    }
    Ok(())
}

fn orthonormal_distance(v: Vector3<f64>, dir: &Vector3<f64>) -> f64 {
    (v - dir * dir.dot(&v)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_markers_are_refused() {
        let names: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let line = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.0, 0.1, 0.001),
            Vector3::new(0.0, 0.2, 0.0),
        ];
        let e = check_spread("thigh", &names, &line, 0.005)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "thigh tracking markers [\"a\", \"b\", \"c\"] lie within 0.7 mm of one line"
            ),
            "{e}"
        );
        let ok = [line[0], line[1], Vector3::new(0.03, 0.2, 0.0)];
        check_spread("thigh", &names, &ok, 0.005).unwrap();
    }
}
