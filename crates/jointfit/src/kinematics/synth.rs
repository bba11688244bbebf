//! Synthetic trials for the core's own unit tests: the markers of a model along a known
//! motion by [`super::forward_kinematics`], with the seeded noise of
//! `jointfit_testkit::synth` (the same random stream, so the same trials as the other
//! crates' tests build).

use super::{forward_kinematics, KinData, Want};
use crate::model::Model;
use crate::trial::Trial;

pub(crate) use jointfit_testkit::synth::Noise;

/// A synthetic trial and the coordinates that produced it.
#[derive(Debug, Clone)]
pub(crate) struct SynthTrial {
    /// The markers, labelled with the model's marker names, in metres.
    pub trial: Trial,
    /// `coords[f]`: the true coordinate vector of frame `f`.
    pub coords: Vec<Vec<f64>>,
}

/// Markers of `model` at parameters `p` along `coords(f)` for `frames` frames at `rate_hz`,
/// with `noise` drawn from `seed` (`jointfit_testkit::synth::synthetic_trial`).
pub(crate) fn synthetic_trial(
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
    jointfit_testkit::synth::add_noise(&mut positions, model.markers().len(), rate_hz, noise, seed);
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, rate_hz, 1, positions).expect("a valid synthetic trial");
    SynthTrial {
        trial,
        coords: truth,
    }
}
