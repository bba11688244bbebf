//! Synthetic motions and skin-movement-artifact noise.
//!
//! Motions follow the paper's synthetic trials (ARCHITECTURE.md §2): hip circumduction
//! (~3.5 cycles of flexion-extension with ab-adduction), knee flexion-extension (~4 cycles),
//! ankle toe-tip circumduction (~2.75 cycles of plantar/dorsiflexion with inversion/eversion),
//! and `all`, which runs the three together. Noise is the continuous model of Chèze et al. 1995
//! as used by Lu & O'Connor 1999: for every marker and axis `n(t) = A sin(ωt + φ)` with `A`,
//! `ω`, `φ` drawn once, uniformly from `[0, A_max]`, `[0, ω_max]`, `[0, 2π)`.

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::Model;
use jointfit::trial::Trial;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum SynthError {
    #[error("unknown motion {0:?}; choose hip, knee, ankle or all")]
    UnknownMotion(String),
    #[error("the model has no coordinate {0:?}, which the {1} motion drives")]
    MissingCoordinate(String, &'static str),
}

/// Which joint the synthetic motion exercises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    Hip,
    Knee,
    Ankle,
    All,
}

impl std::str::FromStr for Motion {
    type Err = SynthError;
    fn from_str(s: &str) -> Result<Self, SynthError> {
        match s {
            "hip" => Ok(Motion::Hip),
            "knee" => Ok(Motion::Knee),
            "ankle" => Ok(Motion::Ankle),
            "all" => Ok(Motion::All),
            other => Err(SynthError::UnknownMotion(other.to_string())),
        }
    }
}

/// Coordinates of the motion at phase `t ∈ [0, 1)` over the trial (rad, m), by name.
fn pose(motion: Motion, t: f64) -> Vec<(&'static str, f64)> {
    let w = std::f64::consts::TAU;
    let hip = [
        ("hip_flexion", 0.35 + 0.5 * (3.5 * w * t).sin()),
        ("hip_adduction", 0.25 * (3.5 * w * t).cos()),
        ("hip_rotation", 0.15 * (1.75 * w * t).sin()),
    ];
    let knee = [("knee_flexion", 0.85 + 0.75 * (4.0 * w * t - 1.5).sin())];
    let ankle = [
        ("ankle_dorsiflexion", -0.1 + 0.3 * (2.75 * w * t).sin()),
        ("subtalar_inversion", 0.25 * (2.75 * w * t).cos()),
    ];
    let mut out = vec![
        ("pelvis_ty", 0.95),
        ("pelvis_tilt", 0.03 * (w * t).sin()),
        ("pelvis_rotation", 0.05 * (w * t).cos()),
    ];
    match motion {
        Motion::Hip => out.extend(hip),
        Motion::Knee => {
            out.push(("hip_flexion", 0.6));
            out.extend(knee)
        }
        Motion::Ankle => {
            out.push(("knee_flexion", 0.5));
            out.extend(ankle)
        }
        Motion::All => {
            out.extend(hip);
            out.extend(knee);
            out.extend(ankle);
        }
    }
    out
}

/// The coordinate trajectory of a motion: `frames` rows of `n_q` values.
pub fn coordinates(
    model: &Model,
    motion: Motion,
    frames: usize,
) -> Result<Vec<Vec<f64>>, SynthError> {
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        let mut q = model.default_coords();
        for (name, v) in pose(motion, f as f64 / frames as f64) {
            let id = model
                .coord_id(name)
                .ok_or_else(|| SynthError::MissingCoordinate(name.to_string(), "synthetic"))?;
            q[id.0] = v;
        }
        out.push(q);
    }
    Ok(out)
}

/// Skin-artifact noise parameters: maximum amplitude (m) and maximum angular frequency (rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinNoise {
    pub max_amplitude: f64,
    pub max_omega: f64,
    pub seed: u64,
}

impl Default for SkinNoise {
    /// Chèze et al. 1995 magnitudes as the paper used them: up to 1 cm, up to 25 rad/s.
    fn default() -> Self {
        SkinNoise {
            max_amplitude: 0.01,
            max_omega: 25.0,
            seed: 1,
        }
    }
}

/// Marker trajectories of `model` with parameters `p` along `coords` at `rate` Hz, with
/// optional skin noise. Returns the trial and the injected noise's 3-D RMS (m).
pub fn markers(
    model: &Model,
    p: &[f64],
    coords: &[Vec<f64>],
    rate: f64,
    noise: Option<&SkinNoise>,
) -> (Trial, f64) {
    let terms: Vec<(f64, f64, f64)> = match noise {
        Some(n) => {
            let mut rng = ChaCha8Rng::seed_from_u64(n.seed);
            (0..3 * model.n_markers())
                .map(|_| {
                    (
                        rng.gen_range(0.0..=n.max_amplitude),
                        rng.gen_range(0.0..=n.max_omega),
                        rng.gen_range(0.0..std::f64::consts::TAU),
                    )
                })
                .collect()
        }
        None => Vec::new(),
    };
    let mut kin = KinData::new(model);
    let mut positions = Vec::with_capacity(coords.len() * model.n_markers());
    let (mut sum, mut count) = (0.0, 0usize);
    for (f, q) in coords.iter().enumerate() {
        forward_kinematics(model, p, q, Want::POSITIONS, &mut kin);
        let t = f as f64 / rate;
        for (j, x) in kin.markers.iter().enumerate() {
            let mut n = Vector3::zeros();
            if !terms.is_empty() {
                for k in 0..3 {
                    let (a, w, phi) = terms[3 * j + k];
                    n[k] = a * (w * t + phi).sin();
                }
            }
            sum += n.norm_squared();
            count += 1;
            positions.push(x + n);
        }
    }
    let labels = model.markers.iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, rate, 1, positions).expect("synthetic trial is well formed");
    (trial, (sum / count.max(1) as f64).sqrt())
}

/// Parameters moved from nominal by up to `fraction` of each half-range, seeded.
pub fn perturbed_params(model: &Model, fraction: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    model
        .parameters
        .iter()
        .map(|p| {
            let half = 0.5 * (p.upper - p.lower);
            (p.nominal + rng.gen_range(-fraction..=fraction) * half).clamp(p.lower, p.upper)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::model::lower_limb::{lower_limb, Side};

    #[test]
    fn noise_is_bounded_seeded_and_reported() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let p = model.nominal_params();
        let q = coordinates(&model, Motion::Hip, 50).unwrap();
        let (clean, zero) = markers(&model, &p, &q, 50.0, None);
        assert_eq!(zero, 0.0);
        let noise = SkinNoise::default();
        let (noisy, rms) = markers(&model, &p, &q, 50.0, Some(&noise));
        let (again, _) = markers(&model, &p, &q, 50.0, Some(&noise));
        assert_eq!(noisy, again);
        let mut max_axis = 0.0f64;
        let (mut sum, mut n) = (0.0, 0);
        for (a, b) in noisy.positions().iter().zip(clean.positions()) {
            let d = a - b;
            max_axis = max_axis.max(d.amax());
            sum += d.norm_squared();
            n += 1;
        }
        assert!(max_axis <= 0.01 + 1e-15);
        assert!((rms - (sum / n as f64).sqrt()).abs() < 1e-15);
        assert!(rms > 0.002 && rms < 0.01, "rms {rms}");
    }

    #[test]
    fn motions_move_their_joint() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let range = |m: Motion, name: &str| {
            let i = model.coord_id(name).unwrap().0;
            let q = coordinates(&model, m, 50).unwrap();
            let v: Vec<f64> = q.iter().map(|r| r[i]).collect();
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        assert!(range(Motion::Hip, "hip_adduction") > 0.4);
        assert_eq!(range(Motion::Hip, "knee_flexion"), 0.0);
        assert!(range(Motion::Knee, "knee_flexion") > 1.4);
        assert!(range(Motion::Ankle, "subtalar_inversion") > 0.4);
        assert!("elbow".parse::<Motion>().is_err());
    }
}
