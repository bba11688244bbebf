//! SARA: the symmetrical axis of rotation approach (Ehrig et al. 2007). See the parent module
//! for the objective.

use nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector3, Vector6};

use super::score::spread;
use super::{
    block_resample, check_pairs, frame_normals, pose_pairs, rng, sum_normals, Cluster,
    FunctionalError, FunctionalOptions, PosePairs,
};
use jointfit::trial::Trial;

/// A functional hinge axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisFit {
    /// Unit direction at the static pose (reference frame), signed to agree with the hint.
    pub axis: Vector3<f64>,
    /// The point of the axis nearest the given reference point (reference frame, m).
    pub point: Vector3<f64>,
    /// RMS over frames of the distance between the two segment-side copies of `point` in the
    /// lab (m).
    pub rms_gap: f64,
    /// Bootstrap RMS angle between replicate axes and `axis` (rad; NaN without replicates).
    pub angle_rms: f64,
    /// Bootstrap SD of `point` per axis of the reference frame (m).
    pub point_sd: Vector3<f64>,
    pub point_covariance: Matrix3<f64>,
    /// Ratio of the smallest to the second-smallest eigenvalue of `AᵀA` (≪ 1 for a clear
    /// hinge; near 1 when the motion does not single out one axis).
    pub eigen_ratio: f64,
    pub frames: usize,
    /// Largest rotation of cluster b relative to a over the trial (rad).
    pub range_of_motion: f64,
}

/// Axis (signed toward `hint`) and the point nearest `near`; `None` if degenerate.
fn solve(
    n: &Matrix6<f64>,
    h: &Vector6<f64>,
    near: &Vector3<f64>,
    hint: &Vector3<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>, f64)> {
    let eig = SymmetricEigen::new(*n);
    let mut order: Vec<usize> = (0..6).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let (k0, k1) = (order[0], order[1]);
    if eig.eigenvalues[k1] <= 0.0 {
        return None;
    }
    let v = eig.eigenvectors.column(k0);
    let da: Vector3<f64> = v.fixed_rows::<3>(0).into();
    let db: Vector3<f64> = v.fixed_rows::<3>(3).into();
    let mut axis = (da + db).try_normalize(1e-12)?;
    if axis.dot(hint) < 0.0 {
        axis = -axis;
    }
    let mut x = Vector6::zeros();
    for &k in &order[1..] {
        let vk = eig.eigenvectors.column(k);
        x += vk * (vk.dot(h) / eig.eigenvalues[k]);
    }
    let pa: Vector3<f64> = x.fixed_rows::<3>(0).into();
    let pb: Vector3<f64> = x.fixed_rows::<3>(3).into();
    let mid = 0.5 * (pa + pb);
    let point = mid + axis * axis.dot(&(near - mid));
    Some((
        axis,
        point,
        eig.eigenvalues[k0].max(0.0) / eig.eigenvalues[k1],
    ))
}

/// The SARA axis between clusters `a` and `b` (e.g. thigh and shank in a knee
/// flexion-extension trial). `near`: the returned point is the axis point nearest it (e.g.
/// the landmark knee centre); `hint`: the axis is signed to point the same way (e.g. the
/// landmark axis, pointing right).
pub(crate) fn sara(
    trial: &Trial,
    a: &Cluster,
    b: &Cluster,
    near: &Vector3<f64>,
    hint: &Vector3<f64>,
    opts: &FunctionalOptions,
) -> Result<AxisFit, FunctionalError> {
    let pairs = pose_pairs(trial, a, b)?;
    let motion = "flexion-extension of the joint";
    check_pairs(&pairs, a, b, opts, motion)?;
    sara_pairs(&pairs, near, hint, opts).ok_or_else(|| FunctionalError::TooLittleMotion {
        a: a.segment.clone(),
        b: b.segment.clone(),
        degrees: super::relative_rotation_range(&pairs).to_degrees(),
        min_degrees: opts.min_rotation.to_degrees(),
        motion,
    })
}

/// SARA on given pose pairs; `None` when degenerate.
pub(crate) fn sara_pairs(
    pairs: &PosePairs,
    near: &Vector3<f64>,
    hint: &Vector3<f64>,
    opts: &FunctionalOptions,
) -> Option<AxisFit> {
    let normals = frame_normals(pairs);
    let n = normals.len();
    let (nn, h) = sum_normals(&normals, 0..n);
    let (axis, point, eigen_ratio) = solve(&nn, &h, near, hint)?;
    let gap2: f64 = pairs
        .a
        .iter()
        .zip(&pairs.b)
        .map(|(pa, pb)| (pa.transform_point(&point) - pb.transform_point(&point)).norm_squared())
        .sum();
    let mut r = rng(opts.seed);
    let mut points = Vec::with_capacity(opts.replicates);
    let mut ang2 = 0.0;
    for _ in 0..opts.replicates {
        let idx = block_resample(n, opts.block_frames, &mut r);
        let (bn, bh) = sum_normals(&normals, idx.into_iter());
        if let Some((ax, pt, _)) = solve(&bn, &bh, near, &axis) {
            ang2 += ax.angle(&axis).powi(2);
            points.push(pt);
        }
    }
    let (point_sd, point_covariance) = spread(&points, &point);
    let angle_rms = if points.len() >= 2 {
        (ang2 / points.len() as f64).sqrt()
    } else {
        f64::NAN
    };
    Some(AxisFit {
        axis,
        point,
        rms_gap: (gap2 / n as f64).sqrt(),
        angle_rms,
        point_sd,
        point_covariance,
        eigen_ratio,
        frames: n,
        range_of_motion: super::relative_rotation_range(pairs),
    })
}

#[cfg(test)]
mod tests {
    use super::super::synthetic;
    use super::*;
    use nalgebra::{Rotation3, Unit};

    fn hinge(axis: Vector3<f64>) -> impl Fn(f64) -> Rotation3<f64> {
        // Flexion 0–100°, about 4 cycles over 4 s.
        move |t| {
            let w = std::f64::consts::TAU;
            Rotation3::from_axis_angle(&Unit::new_normalize(axis), 0.87 * (1.0 - (w * t).cos()))
        }
    }

    #[test]
    fn noiseless_axis_is_exact() {
        let c = Vector3::new(0.01, -0.4, 0.02);
        let dir = Vector3::new(0.05, -0.1, 1.0).normalize();
        let (trial, a, b) = synthetic::trial(c, hinge(dir), 200, 0.0, 5);
        let near = c + Vector3::new(0.0, 0.0, 0.03) + 0.01 * Vector3::x();
        let fit = sara(&trial, &a, &b, &near, &Vector3::z(), &Default::default()).unwrap();
        assert!(fit.axis.angle(&dir) < 1e-8, "{}", fit.axis.angle(&dir));
        // The point is on the true axis and nearest `near`.
        let expect = c + dir * dir.dot(&(near - c));
        assert!(
            (fit.point - expect).norm() < 1e-8,
            "{:?}",
            fit.point - expect
        );
        assert!(fit.rms_gap < 1e-9 && fit.eigen_ratio < 1e-12);
    }

    #[test]
    fn skin_noise_axis_error_matches_the_bootstrap() {
        let c = Vector3::new(0.01, -0.4, 0.02);
        let dir = Vector3::new(0.05, -0.1, 1.0).normalize();
        let (mut ang2, mut pred2, mut pt2, mut ptpred2) = (0.0, 0.0, 0.0, 0.0);
        for seed in 1..=20 {
            let (trial, a, b) = synthetic::trial(c, hinge(dir), 200, 0.01, seed);
            let opts = FunctionalOptions {
                seed,
                ..Default::default()
            };
            let fit = sara(&trial, &a, &b, &c, &Vector3::z(), &opts).unwrap();
            let ang = fit.axis.angle(&dir);
            assert!(
                ang < 8f64.to_radians(),
                "seed {seed}: {:.1}°",
                ang.to_degrees()
            );
            ang2 += ang * ang;
            pred2 += fit.angle_rms.powi(2);
            let e = fit.point - c;
            // Only the component across the axis is defined.
            let e = e - dir * dir.dot(&e);
            pt2 += e.norm_squared();
            ptpred2 += fit.point_sd.norm_squared();
        }
        let (r_ang, r_pt) = ((ang2 / pred2).sqrt(), (pt2 / ptpred2).sqrt());
        assert!((0.33..3.0).contains(&r_ang), "angle error/SD {r_ang}");
        assert!((0.33..3.0).contains(&r_pt), "point error/SD {r_pt}");
    }
}
