//! Synthetic motions and measurement noise (Reinbolt et al. 2005, J Biomech 38:621–626,
//! doi:10.1016/j.jbiomech.2004.03.031, §2 "synthetic movement data").
//!
//! ## Motions
//! Motions follow the paper's synthetic trials (`docs/architecture.md` §6; Reinbolt's thesis:
//! 50 frames each). With `t = f / frames` the phase of frame `f` and `a` the amplitude factor
//! (default 1):
//!
//! * **hip**: circumduction, ~3.5 cycles: flexion `20° + a·28.6° sin(3.5·2πt)`, adduction
//!   `a·14.3° cos(3.5·2πt)` (together a cone), internal rotation `a·8.6° sin(1.75·2πt)`;
//!   knee and ankle at 0.
//! * **knee**: flexion-extension, 4 cycles: `48.7° + a·43° sin(4·2πt − 1.5)` (5.7°–91.7°),
//!   hip flexed 34°.
//! * **ankle**: toe-tip circumduction, ~2.75 cycles: dorsiflexion `−5.7° + a·17.2°
//!   sin(2.75·2πt)`, inversion `a·14.3° cos(2.75·2πt)`, knee flexed 29°.
//! * **all**: the three together.
//! * **gait**: the coordinates of a real trial found by inverse kinematics
//!   ([`gait_coordinates`]), replayed through any subject model.
//!
//! The pelvis sways slightly (tilt ±1.7°, rotation ±2.9°, once over the trial) at 0.95 m.
//! On a bilateral model (coordinates suffixed `_r`/`_l`) the right leg follows the motion at
//! phase `t` and the left leg the same motion half a trial later, at `(t + 0.5) mod 1`.
//!
//! ## Noise ([`Noise`], applied by [`synthesize`])
//! * **none**.
//! * **skin**: the continuous skin-movement-artifact model of Chèze et al. 1995 as used by Lu &
//!   O'Connor 1999 and by the paper: for every marker `j` and axis `k`,
//!   `n_jk(t) = A_jk sin(ω_jk t + φ_jk)` with `A ~ U[0, A_max]` (A_max = 1 cm), `ω ~ U[0,
//!   ω_max]` (ω_max = 25 rad/s), `φ ~ U[0, 2π)`, drawn once per marker-axis from a seeded
//!   ChaCha8 stream; `t = f / rate` is the frame's time. The sampled noise of one marker-axis
//!   has RMS ≈ A/√2, so the expected per-axis RMS over markers is A_max/√6 ≈ 4.1 mm and the
//!   3-D RMS ≈ 7.1 mm (reported exactly by [`NoiseStats`]).
//! * **white**: independent Gaussian `N(0, σ²)` on every sample and axis (Box–Muller on the
//!   same seeded stream), e.g. camera noise of σ = 1 mm.
//!
//! Both can be combined ([`Noise::skin_and_white`]).

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

/// Coordinates of the motion at phase `t ∈ [0, 1)` over the trial (rad, m), by name. The
/// joint excursions (not the mean postures) are multiplied by `amplitude`.
fn pose(motion: Motion, t: f64, amplitude: f64) -> Vec<(&'static str, f64)> {
    let w = std::f64::consts::TAU;
    let a = amplitude;
    let hip = [
        ("hip_flexion", 0.35 + a * 0.5 * (3.5 * w * t).sin()),
        ("hip_adduction", a * 0.25 * (3.5 * w * t).cos()),
        ("hip_rotation", a * 0.15 * (1.75 * w * t).sin()),
    ];
    let knee = [("knee_flexion", 0.85 + a * 0.75 * (4.0 * w * t - 1.5).sin())];
    let ankle = [
        ("ankle_dorsiflexion", -0.1 + a * 0.3 * (2.75 * w * t).sin()),
        ("subtalar_inversion", a * 0.25 * (2.75 * w * t).cos()),
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
    coordinates_scaled(model, motion, frames, 1.0)
}

/// [`coordinates`] with the joint excursions multiplied by `amplitude` (1: the ranges listed
/// in the module docs).
pub fn coordinates_scaled(
    model: &Model,
    motion: Motion,
    frames: usize,
    amplitude: f64,
) -> Result<Vec<Vec<f64>>, SynthError> {
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        let mut q = model.default_coords();
        let t = f as f64 / frames as f64;
        let left = pose(motion, (t + 0.5).fract(), amplitude);
        for ((name, v), (_, v_left)) in pose(motion, t, amplitude).into_iter().zip(left) {
            if let Some(id) = model.coord_id(name) {
                q[id] = v;
                continue;
            }
            // A bilateral model: the right leg at phase t, the left half a trial later.
            let sided = [("_r", v), ("_l", v_left)]
                .map(|(s, v)| model.coord_id(&format!("{name}{s}")).map(|id| (id, v)));
            if sided.iter().all(Option::is_none) {
                return Err(SynthError::MissingCoordinate(name.to_string(), "synthetic"));
            }
            for (id, v) in sided.into_iter().flatten() {
                q[id] = v;
            }
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
    let noise = Noise {
        skin: noise.copied(),
        white: None,
    };
    let (trial, stats) = synthesize(model, p, coords, rate, &noise);
    (trial, stats.rms_3d)
}

/// White (Gaussian, independent) noise: standard deviation per axis (m) and seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WhiteNoise {
    pub sigma: f64,
    pub seed: u64,
}

/// The noise added to synthetic markers: skin artifact, white noise, both or none.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Noise {
    pub skin: Option<SkinNoise>,
    pub white: Option<WhiteNoise>,
}

impl Noise {
    pub fn none() -> Noise {
        Noise::default()
    }
    /// The paper's skin-artifact model with its magnitudes (1 cm, 25 rad/s), seeded.
    pub fn skin(seed: u64) -> Noise {
        Noise {
            skin: Some(SkinNoise {
                seed,
                ..SkinNoise::default()
            }),
            white: None,
        }
    }
    pub fn white(sigma: f64, seed: u64) -> Noise {
        Noise {
            skin: None,
            white: Some(WhiteNoise { sigma, seed }),
        }
    }
    pub fn skin_and_white(skin: SkinNoise, white: WhiteNoise) -> Noise {
        Noise {
            skin: Some(skin),
            white: Some(white),
        }
    }
    pub fn is_none(&self) -> bool {
        self.skin.is_none() && self.white.is_none()
    }
}

/// What was actually injected, over every marker sample of the trial (m).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NoiseStats {
    /// RMS of the noise per lab axis (x, y, z).
    pub rms_axis: [f64; 3],
    /// RMS of the noise vector's length: `sqrt(Σ_k rms_axis[k]²)`.
    pub rms_3d: f64,
    /// Largest absolute noise on one axis.
    pub max_axis: f64,
}

/// One standard normal deviate by Box–Muller.
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>(); // (0, 1]
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Marker trajectories of `model` with parameters `p` along `coords` (one row per frame) at
/// `rate` Hz, plus `noise` (see the module docs). Returns the trial and what was injected.
pub fn synthesize(
    model: &Model,
    p: &[f64],
    coords: &[Vec<f64>],
    rate: f64,
    noise: &Noise,
) -> (Trial, NoiseStats) {
    let terms: Vec<(f64, f64, f64)> = match &noise.skin {
        Some(n) => {
            let mut rng = ChaCha8Rng::seed_from_u64(n.seed);
            (0..3 * model.markers().len())
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
    // A separate stream, so adding white noise leaves the skin terms of a seed unchanged.
    let mut white = noise.white.map(|w| {
        (
            w.sigma,
            ChaCha8Rng::seed_from_u64(w.seed ^ 0x005e_ed0f_face),
        )
    });
    let mut kin = KinData::new(model);
    let mut positions = Vec::with_capacity(coords.len() * model.markers().len());
    let mut sums = [0.0; 3];
    let mut max_axis = 0.0f64;
    let mut count = 0usize;
    for (f, q) in coords.iter().enumerate() {
        forward_kinematics(model, p, q, Want::Positions, &mut kin);
        let t = f as f64 / rate;
        for (j, x) in kin.markers.iter().enumerate() {
            let mut n = Vector3::<f64>::zeros();
            for k in 0..3 {
                if !terms.is_empty() {
                    let (a, w, phi) = terms[3 * j + k];
                    n[k] += a * (w * t + phi).sin();
                }
                if let Some((sigma, rng)) = white.as_mut() {
                    n[k] += *sigma * normal(rng);
                }
                sums[k] += n[k] * n[k];
                max_axis = max_axis.max(n[k].abs());
            }
            count += 1;
            positions.push(x + n);
        }
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, rate, 1, positions).expect("synthetic trial is well formed");
    let c = count.max(1) as f64;
    let rms_axis = sums.map(|s| (s / c).sqrt());
    let stats = NoiseStats {
        rms_axis,
        rms_3d: (sums.iter().sum::<f64>() / c).sqrt(),
        max_axis,
    };
    (trial, stats)
}

/// The coordinates of a real trial by inverse kinematics with `model` at parameters `p`
/// (frames that could not be solved are dropped; their indices are returned). This is the
/// paper's "gait" motion: replaying it through another model or other parameters gives a
/// synthetic gait trial.
pub fn gait_coordinates(
    model: &Model,
    p: &[f64],
    trial: &Trial,
) -> Result<(Vec<Vec<f64>>, Vec<usize>), jointfit::workflow::WorkflowError> {
    use jointfit::workflow::ik::ik_trial;
    use jointfit::workflow::WorkflowError;
    // Every marker of the model must be in the trial (the replay needs all of them).
    jointfit::ik::MarkerMap::by_name(model, trial.labels())?;
    let fit = match ik_trial(model, p, trial, &jointfit::ik::IkOptions::default()) {
        Ok(run) => run.fit,
        Err(WorkflowError::NoFrameSolved { .. }) => {
            return Ok((Vec::new(), (0..trial.n_frames()).collect()))
        }
        Err(e) => return Err(e),
    };
    let mut coords = Vec::with_capacity(fit.coords.len());
    let mut dropped = Vec::new();
    for (f, (q, frame)) in fit.coords.into_iter().zip(&fit.frames).enumerate() {
        if frame.solved() {
            coords.push(q);
        } else {
            dropped.push(f);
        }
    }
    Ok((coords, dropped))
}

/// Parameters moved from nominal by up to `fraction` of each half-range, seeded.
pub fn perturbed_params(model: &Model, fraction: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    model
        .parameters()
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
            let i = model.coord_id(name).unwrap();
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
