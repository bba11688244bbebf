//! SCoRE: the symmetrical centre of rotation estimation (Ehrig et al. 2006). See the parent
//! module for the objective.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::{
    block_resample, check_pairs, frame_normals, pose_pairs, rng, sum_normals, Cluster,
    FunctionalError, FunctionalOptions, PosePairs,
};
use jointfit::trial::Trial;

/// A functional joint centre.
#[derive(Debug, Clone, PartialEq)]
pub struct CentreFit {
    /// The centre at the static pose (reference frame of the clusters, m): the mean of the
    /// two segment-side points.
    pub centre: Vector3<f64>,
    /// The point fixed in cluster a and the one fixed in cluster b (reference frame, m).
    pub in_a: Vector3<f64>,
    pub in_b: Vector3<f64>,
    /// RMS over frames of the distance between the two points in the lab (m): how well one
    /// fixed centre explains the motion (skin artefact, a non-spherical joint).
    pub rms_gap: f64,
    /// Bootstrap standard deviation of `centre` per axis of the reference frame (m; NaN
    /// without replicates).
    pub sd: Vector3<f64>,
    /// Bootstrap covariance of `centre` (m²).
    pub covariance: Matrix3<f64>,
    /// Frames used.
    pub frames: usize,
    /// Largest rotation of cluster b relative to a over the trial (rad).
    pub range_of_motion: f64,
}

fn solve(n: &Matrix6<f64>, h: &Vector6<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let x = n.cholesky()?.solve(h);
    Some((x.fixed_rows::<3>(0).into(), x.fixed_rows::<3>(3).into()))
}

/// The SCoRE centre between clusters `a` (proximal) and `b` (distal) from a functional trial
/// (e.g. hip circumduction: pelvis and thigh).
pub(crate) fn score(
    trial: &Trial,
    a: &Cluster,
    b: &Cluster,
    opts: &FunctionalOptions,
) -> Result<CentreFit, FunctionalError> {
    let pairs = pose_pairs(trial, a, b)?;
    check_pairs(
        &pairs,
        a,
        b,
        opts,
        "circumduction (flexion-extension with ab-adduction) of the joint",
    )?;
    score_pairs(&pairs, opts).ok_or_else(|| FunctionalError::TooLittleMotion {
        a: a.segment.clone(),
        b: b.segment.clone(),
        degrees: super::relative_rotation_range(&pairs).to_degrees(),
        min_degrees: opts.min_rotation.to_degrees(),
        motion: "circumduction (flexion-extension with ab-adduction) of the joint",
    })
}

/// SCoRE on given pose pairs; `None` when the normal matrix is singular.
pub(crate) fn score_pairs(pairs: &PosePairs, opts: &FunctionalOptions) -> Option<CentreFit> {
    let normals = frame_normals(pairs);
    let n = normals.len();
    let (nn, h) = sum_normals(&normals, 0..n);
    let (in_a, in_b) = solve(&nn, &h)?;
    let centre = 0.5 * (in_a + in_b);
    let gap2: f64 = pairs
        .a
        .iter()
        .zip(&pairs.b)
        .map(|(pa, pb)| (pa.transform_point(&in_a) - pb.transform_point(&in_b)).norm_squared())
        .sum();
    let mut r = rng(opts.seed);
    let mut reps: Vec<Vector3<f64>> = Vec::with_capacity(opts.replicates);
    for _ in 0..opts.replicates {
        let idx = block_resample(n, opts.block_frames, &mut r);
        let (bn, bh) = sum_normals(&normals, idx.into_iter());
        if let Some((ca, cb)) = solve(&bn, &bh) {
            reps.push(0.5 * (ca + cb));
        }
    }
    let (sd, covariance) = spread(&reps, &centre);
    Some(CentreFit {
        centre,
        in_a,
        in_b,
        rms_gap: (gap2 / n as f64).sqrt(),
        sd,
        covariance,
        frames: n,
        range_of_motion: super::relative_rotation_range(pairs),
    })
}

/// Sample covariance of replicates around their mean, and per-axis SDs (NaN for < 2).
pub(crate) fn spread(reps: &[Vector3<f64>], _at: &Vector3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
    if reps.len() < 2 {
        return (Vector3::repeat(f64::NAN), Matrix3::repeat(f64::NAN));
    }
    let mean: Vector3<f64> = reps.iter().sum::<Vector3<f64>>() / reps.len() as f64;
    let cov = reps
        .iter()
        .map(|x| (x - mean) * (x - mean).transpose())
        .sum::<Matrix3<f64>>()
        / (reps.len() - 1) as f64;
    (cov.diagonal().map(f64::sqrt), cov)
}

#[cfg(test)]
mod tests {
    use super::super::synthetic;
    use super::*;
    use nalgebra::Rotation3;

    fn circumduction(t: f64) -> Rotation3<f64> {
        // Flexion ±30° with ab-adduction ±20°, ~3.5 cycles over 4 s.
        let w = std::f64::consts::TAU * 0.875;
        Rotation3::from_euler_angles(0.35 * (w * t).cos(), 0.0, 0.52 * (w * t).sin())
    }

    #[test]
    fn noiseless_centre_is_exact() {
        let c = Vector3::new(-0.02, -0.08, 0.09);
        let (trial, a, b) = synthetic::trial(c, circumduction, 200, 0.0, 3);
        let fit = score(&trial, &a, &b, &FunctionalOptions::default()).unwrap();
        assert!((fit.centre - c).norm() < 1e-9, "{:?}", fit.centre - c);
        assert!(fit.rms_gap < 1e-9);
        assert!(fit.sd.norm() < 1e-9);
    }

    #[test]
    fn skin_noise_error_is_within_the_bootstrap_spread() {
        // 20 seeds, artefact up to 10 mm: the bootstrap SD predicts the scatter of the
        // estimates over seeds within a factor of three, and the error stays small.
        let c = Vector3::new(-0.02, -0.08, 0.09);
        let mut sq_err = 0.0;
        let mut var_pred = 0.0;
        for seed in 1..=20 {
            let (trial, a, b) = synthetic::trial(c, circumduction, 200, 0.01, seed);
            let opts = FunctionalOptions {
                seed,
                ..Default::default()
            };
            let fit = score(&trial, &a, &b, &opts).unwrap();
            let e = fit.centre - c;
            assert!(
                e.norm() < 0.02,
                "seed {seed}: error {:.1} mm",
                e.norm() * 1e3
            );
            sq_err += e.norm_squared();
            var_pred += fit.sd.norm_squared();
        }
        let ratio = (sq_err / var_pred).sqrt();
        assert!((0.33..3.0).contains(&ratio), "error/SD ratio {ratio}");
    }

    #[test]
    fn no_motion_is_refused() {
        let c = Vector3::zeros();
        let (trial, a, b) = synthetic::trial(c, |_| Rotation3::identity(), 100, 0.0, 1);
        let err = score(&trial, &a, &b, &FunctionalOptions::default()).unwrap_err();
        assert!(
            matches!(err, FunctionalError::TooLittleMotion { .. }),
            "{err}"
        );
    }
}
