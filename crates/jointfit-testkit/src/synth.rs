//! The synthetic-trial generator of the tests: model markers at known parameters along a known
//! motion, plus seeded noise, so that every solver can be checked against the truth.
//!
//! Frame `f` (time `t = f / rate`) has coordinates `coords(f)` and markers
//! `x_j(p, coords(f)) + n_j(t)` with one of:
//!
//! * [`Noise::Skin`]: the skin-movement artifact of Chèze et al. 1995 as used by Lu &
//!   O'Connor 1999 and Reinbolt et al. 2005: for every marker and axis,
//!   `n(t) = A sin(ωt + φ)` with `A ~ U[0, amplitude]`, `ω ~ U[0, 25] rad/s`, `φ ~ U[0, 2π)`
//!   drawn once;
//! * [`Noise::White`]: independent Gaussian samples of standard deviation `sd` (Box–Muller);
//! * [`Noise::None`]: exact markers.
//!
//! The random stream (ChaCha8 seeded with `seed`) draws the three sinusoid terms of every
//! marker axis first, in marker then axis order, and then, for white noise, two uniforms per
//! sample in frame, marker, axis order. The application's own generator, with the paper's
//! motions, is `jointfit_experiments::synth`.

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::Model;
use jointfit::trial::Trial;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Measurement noise added to the exact markers (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Noise {
    /// Exact markers.
    None,
    /// A sinusoid per marker axis, amplitude at most `amplitude` (m).
    Skin { amplitude: f64 },
    /// White Gaussian noise of standard deviation `sd` (m).
    White { sd: f64 },
}

/// A synthetic trial and the coordinates that produced it.
#[derive(Debug, Clone)]
pub struct SynthTrial {
    /// The markers, labelled with the model's marker names, in metres.
    pub trial: Trial,
    /// `coords[f]`: the true coordinate vector of frame `f`.
    pub coords: Vec<Vec<f64>>,
}

/// Markers of `model` at parameters `p` along `coords(f)` for `frames` frames at `rate_hz`,
/// with `noise` drawn from `seed`.
///
/// # Panics
/// When `coords` returns a vector of the wrong length (the test is wrong).
pub fn synthetic_trial(
    model: &Model,
    p: &[f64],
    frames: usize,
    rate_hz: f64,
    mut coords: impl FnMut(usize) -> Vec<f64>,
    noise: Noise,
    seed: u64,
) -> SynthTrial {
    let mut kin = KinData::new(model);
    let mut positions = Vec::with_capacity(frames * model.markers().len());
    let mut truth = Vec::with_capacity(frames);
    for f in 0..frames {
        let q = coords(f);
        assert_eq!(
            q.len(),
            model.coordinates().len(),
            "frame {f}: coordinate vector length"
        );
        forward_kinematics(model, p, &q, Want::Positions, &mut kin);
        positions.extend_from_slice(&kin.markers);
        truth.push(q);
    }
    add_noise(&mut positions, model.markers().len(), rate_hz, noise, seed);
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, rate_hz, 1, positions).expect("a valid synthetic trial");
    SynthTrial {
        trial,
        coords: truth,
    }
}

/// Adds `noise` drawn from `seed` to exact marker positions, `n_markers` per frame in frame
/// order, frames at `rate_hz`: the noise of [`synthetic_trial`], for a caller that computes
/// the exact markers itself (the core crate's own unit tests).
pub fn add_noise(
    positions: &mut [Vector3<f64>],
    n_markers: usize,
    rate_hz: f64,
    noise: Noise,
    seed: u64,
) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let amplitude = match noise {
        Noise::None => return,
        Noise::Skin { amplitude } => amplitude,
        Noise::White { sd } => sd,
    };
    let terms: Vec<(f64, f64, f64)> = (0..3 * n_markers)
        .map(|_| {
            (
                rng.gen_range(0.0..=amplitude),
                rng.gen_range(0.0..=25.0),
                rng.gen_range(0.0..std::f64::consts::TAU),
            )
        })
        .collect();
    let mut gauss = || {
        let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
        let u2: f64 = rng.gen();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    for (i, x) in positions.iter_mut().enumerate() {
        let (f, j) = (i / n_markers, i % n_markers);
        let t = f as f64 / rate_hz;
        for k in 0..3 {
            x[k] += match noise {
                Noise::None => 0.0,
                Noise::Skin { .. } => {
                    let (a, w, phi) = terms[3 * j + k];
                    a * (w * t + phi).sin()
                }
                Noise::White { sd } => sd * gauss(),
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::two_link;

    fn setup() -> (Model, Vec<f64>) {
        let m = Model::compile(&two_link()).unwrap();
        let p = m.nominal_params();
        (m, p)
    }

    fn wave(f: usize) -> Vec<f64> {
        vec![0.1 * f as f64, 0.5 + 0.01 * f as f64]
    }

    #[test]
    fn exact_markers_are_forward_kinematics() {
        let (m, p) = setup();
        let s = synthetic_trial(&m, &p, 7, 100.0, wave, Noise::None, 0);
        assert_eq!(s.trial.n_frames(), 7);
        assert_eq!(s.coords[3], wave(3));
        let mut kin = KinData::new(&m);
        forward_kinematics(&m, &p, &wave(3), Want::Positions, &mut kin);
        for j in 0..m.markers().len() {
            assert_eq!(s.trial.get(3, j), Some(kin.markers[j]));
        }
    }

    #[test]
    fn skin_noise_is_bounded_seeded_and_smooth() {
        let (m, p) = setup();
        let a = 0.01;
        let exact = synthetic_trial(&m, &p, 50, 50.0, wave, Noise::None, 0);
        let noisy = synthetic_trial(&m, &p, 50, 50.0, wave, Noise::Skin { amplitude: a }, 3);
        let again = synthetic_trial(&m, &p, 50, 50.0, wave, Noise::Skin { amplitude: a }, 3);
        let other = synthetic_trial(&m, &p, 50, 50.0, wave, Noise::Skin { amplitude: a }, 4);
        let mut largest: f64 = 0.0;
        for f in 0..50 {
            for j in 0..m.markers().len() {
                let d = noisy.trial.get(f, j).unwrap() - exact.trial.get(f, j).unwrap();
                assert!(d.amax() <= a, "frame {f} marker {j}: {d}");
                largest = largest.max(d.amax());
                assert_eq!(noisy.trial.get(f, j), again.trial.get(f, j));
            }
        }
        assert!(largest > 0.2 * a, "noise too small: {largest}");
        assert_ne!(noisy.trial.get(10, 0), other.trial.get(10, 0));
    }

    #[test]
    fn white_noise_has_the_requested_spread() {
        let (m, p) = setup();
        let sd = 0.002;
        let exact = synthetic_trial(&m, &p, 2000, 100.0, wave, Noise::None, 0);
        let noisy = synthetic_trial(&m, &p, 2000, 100.0, wave, Noise::White { sd }, 11);
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        let mut n = 0.0;
        for f in 0..2000 {
            for j in 0..m.markers().len() {
                let d = noisy.trial.get(f, j).unwrap() - exact.trial.get(f, j).unwrap();
                for k in 0..3 {
                    sum += d[k];
                    sum2 += d[k] * d[k];
                    n += 1.0;
                }
            }
        }
        let mean = sum / n;
        let var = sum2 / n - mean * mean;
        // 18 000 samples: the mean within 4 standard errors, the sd within 3 %.
        assert!(mean.abs() < 4.0 * sd / n.sqrt(), "mean {mean}");
        assert!((var.sqrt() / sd - 1.0).abs() < 0.03, "sd {}", var.sqrt());
    }
}
