//! Functional joint methods: a joint's centre or axis from how two segments move relative to
//! each other, instead of from palpated landmarks.
//!
//! Both methods start from the poses of two marker clusters, one per segment. Each cluster has
//! *reference coordinates* (the markers' positions in one frame of reference, e.g. the
//! averaged static trial); per frame i a least-squares rigid fit (Kabsch) gives the pose
//! `x ↦ R_i x + t_i` that carries the reference coordinates onto the measured markers.
//!
//! * [`score`]: the SCoRE hip centre (Ehrig et al. 2006, J Biomech 39:2798–2809,
//!   doi:10.1016/j.jbiomech.2005.10.002). A point `c_a` fixed in cluster a and a point `c_b`
//!   fixed in cluster b that stay together: `min Σ_i ‖R_a,i c_a + t_a,i − R_b,i c_b − t_b,i‖²`,
//!   a linear least-squares problem in the six unknowns `(c_a, c_b)`.
//! * [`sara`]: the SARA knee axis (Ehrig et al. 2007, J Biomech 40:2150–2157,
//!   doi:10.1016/j.jbiomech.2006.10.026). The same stacked system `A x = b` with
//!   `A_i = [R_a,i  −R_b,i]`, `b_i = t_b,i − t_a,i`; for a hinge every point pair on the axis
//!   solves it, so `AᵀA` has one (near-)null direction `(d_a, d_b)`: the axis direction in
//!   each cluster. The point is the least-squares solution with that direction left out
//!   (the pseudo-inverse of the other five).
//!
//! Because the cluster reference coordinates are the static trial's positions, the results
//! are points and directions *in the static trial's frame at the static pose*; the two
//! segment-side estimates are averaged there.
//!
//! ## Uncertainty
//! Skin artefact is correlated in time, so a white-noise covariance `σ²(AᵀA)⁻¹` understates
//! the scatter. Each result carries a moving-block bootstrap over frames (seeded,
//! [`FunctionalOptions::replicates`] replicates of contiguous blocks of
//! [`FunctionalOptions::block_frames`] frames): the per-frame normal equations
//! `A_iᵀA_i`, `A_iᵀb_i` are summed over the resampled frames and the estimate recomputed.
//! The reported standard deviations are the bootstrap standard deviations of the static-pose
//! centre (per axis of the static frame) and, for an axis, the RMS angle between replicate
//! axes and the estimate.

pub mod apply;
mod sara;
mod score;

use nalgebra::{Matrix6, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

pub(crate) use sara::sara;
pub use sara::AxisFit;
pub(crate) use score::score;
pub use score::CentreFit;

use jointfit::spatial::rigid_fit;
use jointfit::spatial::Pose;
use jointfit::trial::Trial;

/// Why a functional method could not give a result.
#[derive(Debug, Error, PartialEq)]
pub enum FunctionalError {
    #[error("functional trial lacks {segment} marker {label:?}; the trial has: {available}")]
    MissingMarker {
        segment: String,
        label: String,
        available: String,
    },
    #[error(
        "functional trial: only {usable} frames have at least 3 markers on both the {a} and \
         the {b} cluster (at least {needed} needed)"
    )]
    TooFewFrames {
        a: String,
        b: String,
        usable: usize,
        needed: usize,
    },
    #[error(
        "functional trial: the {b} barely moves relative to the {a} (largest relative \
         rotation {degrees:.1}°, at least {min_degrees:.0}° needed): record a {motion}"
    )]
    TooLittleMotion {
        a: String,
        b: String,
        degrees: f64,
        min_degrees: f64,
        motion: &'static str,
    },
}

/// A marker cluster: labels and their reference coordinates (m).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Cluster {
    /// Segment name, for messages.
    pub segment: String,
    pub labels: Vec<String>,
    /// Reference coordinates of each label (same order), e.g. static-trial positions.
    pub reference: Vec<Vector3<f64>>,
}

/// Settings of the functional methods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FunctionalOptions {
    /// Bootstrap replicates (0: no uncertainty, the SDs are NaN).
    pub replicates: usize,
    /// Length of a bootstrap block (frames); clamped to the number of frames.
    pub block_frames: usize,
    pub seed: u64,
    /// Smallest largest relative rotation between the clusters accepted (rad).
    pub min_rotation: f64,
}

impl Default for FunctionalOptions {
    fn default() -> Self {
        FunctionalOptions {
            replicates: 200,
            block_frames: 10,
            seed: 1,
            min_rotation: 15f64.to_radians(),
        }
    }
}

/// Per-frame poses of two clusters, on the frames where both have ≥ 3 markers.
#[derive(Debug, Clone)]
pub(crate) struct PosePairs {
    pub a: Vec<Pose>,
    pub b: Vec<Pose>,
    /// Trial frame index of each pair.
    pub frames: Vec<usize>,
}

/// Rigidly fits both clusters to every frame of `trial` where each has at least 3 markers.
pub(crate) fn pose_pairs(
    trial: &Trial,
    a: &Cluster,
    b: &Cluster,
) -> Result<PosePairs, FunctionalError> {
    let cols = |c: &Cluster| -> Result<Vec<usize>, FunctionalError> {
        c.labels
            .iter()
            .map(|l| {
                trial.labels().iter().position(|x| x == l).ok_or_else(|| {
                    FunctionalError::MissingMarker {
                        segment: c.segment.clone(),
                        label: l.clone(),
                        available: trial.labels().join(", "),
                    }
                })
            })
            .collect()
    };
    let (ca, cb) = (cols(a)?, cols(b)?);
    let fit = |c: &Cluster, cols: &[usize], f: usize| -> Option<Pose> {
        let (mut local, mut world) = (Vec::new(), Vec::new());
        for (k, &col) in cols.iter().enumerate() {
            if let Some(x) = trial.get(f, col) {
                local.push(c.reference[k]);
                world.push(x);
            }
        }
        (local.len() >= 3).then(|| rigid_fit(&local, &world))
    };
    let mut out = PosePairs {
        a: Vec::new(),
        b: Vec::new(),
        frames: Vec::new(),
    };
    for f in 0..trial.n_frames() {
        if let (Some(pa), Some(pb)) = (fit(a, &ca, f), fit(b, &cb, f)) {
            out.a.push(pa);
            out.b.push(pb);
            out.frames.push(f);
        }
    }
    Ok(out)
}

/// Largest rotation angle of `R_a,iᵀ R_b,i` relative to its first frame's (rad).
pub(crate) fn relative_rotation_range(pairs: &PosePairs) -> f64 {
    let rel = |i: usize| pairs.a[i].rot.transpose() * pairs.b[i].rot;
    let r0 = rel(0);
    (0..pairs.a.len())
        .map(|i| {
            let m = r0.transpose() * rel(i);
            ((m.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
        })
        .fold(0.0, f64::max)
}

/// Per-frame normal equations `A_iᵀA_i`, `A_iᵀb_i` of the stacked system.
pub(crate) fn frame_normals(pairs: &PosePairs) -> Vec<(Matrix6<f64>, Vector6<f64>)> {
    pairs
        .a
        .iter()
        .zip(&pairs.b)
        .map(|(pa, pb)| {
            let mut a = nalgebra::Matrix3x6::zeros();
            a.fixed_view_mut::<3, 3>(0, 0).copy_from(&pa.rot);
            a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-pb.rot));
            let b = pb.trans - pa.trans;
            (a.transpose() * a, a.transpose() * b)
        })
        .collect()
}

/// Sum of per-frame normals over `idx`.
pub(crate) fn sum_normals(
    normals: &[(Matrix6<f64>, Vector6<f64>)],
    idx: impl Iterator<Item = usize>,
) -> (Matrix6<f64>, Vector6<f64>) {
    idx.fold((Matrix6::zeros(), Vector6::zeros()), |(n, h), i| {
        (n + normals[i].0, h + normals[i].1)
    })
}

/// Frame indices of one moving-block bootstrap replicate over `n` frames.
pub(crate) fn block_resample(n: usize, block: usize, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let block = block.clamp(1, n);
    let mut idx = Vec::with_capacity(n);
    while idx.len() < n {
        let start = rng.gen_range(0..=n - block);
        idx.extend((start..start + block).take(n - idx.len()));
    }
    idx
}

pub(crate) fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Checks frame count and range of motion.
pub(crate) fn check_pairs(
    pairs: &PosePairs,
    a: &Cluster,
    b: &Cluster,
    opts: &FunctionalOptions,
    motion: &'static str,
) -> Result<(), FunctionalError> {
    const NEEDED: usize = 10;
    if pairs.a.len() < NEEDED {
        return Err(FunctionalError::TooFewFrames {
            a: a.segment.clone(),
            b: b.segment.clone(),
            usable: pairs.a.len(),
            needed: NEEDED,
        });
    }
    let range = relative_rotation_range(pairs);
    if range < opts.min_rotation {
        return Err(FunctionalError::TooLittleMotion {
            a: a.segment.clone(),
            b: b.segment.clone(),
            degrees: range.to_degrees(),
            min_degrees: opts.min_rotation.to_degrees(),
            motion,
        });
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod synthetic {
    //! Synthetic functional trials with known truth and sinusoidal skin artefact.
    use super::*;
    use nalgebra::{Rotation3, Unit};
    use rand::Rng;

    /// Trial with clusters "a" (a1..a4) and "b" (b1..b4); b rotates relative to a about
    /// `centre` (in the static frame) by `rel(t)`; the pair also moves rigidly in the lab.
    /// Returns the trial and both clusters' reference (static) coordinates.
    pub(crate) fn trial(
        centre: Vector3<f64>,
        rel: impl Fn(f64) -> Rotation3<f64>,
        frames: usize,
        noise: f64,
        seed: u64,
    ) -> (Trial, Cluster, Cluster) {
        let ref_a = vec![
            Vector3::new(0.10, 0.10, 0.05),
            Vector3::new(-0.05, 0.12, 0.10),
            Vector3::new(0.0, 0.05, -0.10),
            Vector3::new(-0.10, 0.15, -0.02),
        ];
        let ref_b = vec![
            Vector3::new(0.05, -0.15, 0.06),
            Vector3::new(-0.04, -0.25, 0.05),
            Vector3::new(0.02, -0.30, -0.04),
            Vector3::new(0.06, -0.35, 0.02),
        ];
        let mut r = rng(seed);
        // Per marker-axis artefact A sin(ωt + φ) (Chèze et al. 1995 style).
        let mut waves = Vec::new();
        for _ in 0..8 * 3 {
            waves.push((
                r.gen_range(0.0..noise.max(1e-300)),
                r.gen_range(1.0..25.0),
                r.gen_range(0.0..std::f64::consts::TAU),
            ));
        }
        let rate = 50.0;
        let mut labels = Vec::new();
        for k in 1..=4 {
            labels.push(format!("a{k}"));
        }
        for k in 1..=4 {
            labels.push(format!("b{k}"));
        }
        let mut pos = Vec::with_capacity(frames * 8);
        for f in 0..frames {
            let t = f as f64 / rate;
            let lab_rot = Rotation3::from_axis_angle(
                &Unit::new_normalize(Vector3::new(0.2, 1.0, 0.1)),
                0.2 * (0.7 * t).sin(),
            );
            let lab_t = Vector3::new(0.3 * t, 0.9 + 0.02 * (2.0 * t).sin(), 0.01 * t);
            let rel_rot = rel(t);
            for (k, x) in ref_a.iter().enumerate() {
                let w = lab_rot * x + lab_t;
                pos.push(w + artefact(&waves[3 * k..3 * k + 3], t));
            }
            for (k, x) in ref_b.iter().enumerate() {
                let w = lab_rot * (centre + rel_rot * (x - centre)) + lab_t;
                pos.push(w + artefact(&waves[3 * (k + 4)..3 * (k + 4) + 3], t));
            }
        }
        let trial = Trial::new(labels, rate, 0, pos).expect("valid trial");
        let ca = Cluster {
            segment: "a".into(),
            labels: (1..=4).map(|k| format!("a{k}")).collect(),
            reference: ref_a,
        };
        let cb = Cluster {
            segment: "b".into(),
            labels: (1..=4).map(|k| format!("b{k}")).collect(),
            reference: ref_b,
        };
        (trial, ca, cb)
    }

    fn artefact(w: &[(f64, f64, f64)], t: f64) -> Vector3<f64> {
        Vector3::from_iterator(w.iter().map(|&(a, om, ph)| a * (om * t + ph).sin()))
    }
}
