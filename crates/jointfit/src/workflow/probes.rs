//! The starts of the global phase ([`super::global`]): where each start is drawn, the
//! probes' frames (every k-th frame, the prior reweighed to keep the posterior's balance), and
//! the intermediate frames the best probe is continued on before the σ stage.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::map::SIGMA_POINT_RESOLUTION_SE;
use super::starts::restart_point;
use super::{FitSettings, Observer};
use crate::calibrate::joint::{solve_joint_to, JointOptions};
use crate::calibrate::{Fit, Problem};

/// One start drawn for the global phase (`k` ≥ 1): from the prior where the problem has one,
/// else [`restart_point`] of `start`.
pub(crate) fn probe_point(
    prob: &Problem,
    start: &[f64],
    settings: &FitSettings,
    k: usize,
) -> Vec<f64> {
    let model = prob.model;
    let mut p = restart_point(
        model,
        start,
        &prob.free,
        settings.restart_m,
        settings.restart_rad,
        settings.seed,
        k,
    );
    if let Some(pr) = &prob.prior {
        let seed = settings.seed.wrapping_mul(2_000_003).wrapping_add(k as u64);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for (j, &i) in prob.free.iter().enumerate() {
            // Drawn for every parameter, so one parameter's prior does not shift the others.
            let u1: f64 = 1.0 - rng.gen::<f64>();
            let u2: f64 = rng.gen();
            let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            if pr.sd[j].is_finite() {
                let par = &model.parameters()[i];
                p[i] = (pr.mean[j] + z.clamp(-2.0, 2.0) * pr.sd[j]).clamp(par.lower, par.upper);
            }
        }
    }
    p
}

/// Every `stride`-th frame of `prob`, the prior reweighed so that the posterior keeps its
/// balance (the marker term shrinks by about `stride`, so σ² shrinks with it).
/// Only the kept frames are copied (never the whole problem's: on a long trial that copy
/// would be the largest allocation of the calibration).
pub(super) fn subsample<'m>(prob: &Problem<'m>, stride: usize) -> Problem<'m> {
    if stride <= 1 {
        return prob.clone();
    }
    let mut prior = prob.prior.clone();
    if let Some(pr) = prior.as_mut() {
        pr.noise /= (stride as f64).sqrt();
    }
    Problem {
        model: prob.model,
        free: prob.free.clone(),
        base: prob.base.clone(),
        frames: prob.frames.select((0..prob.frames.len()).step_by(stride)),
        origin: prob.origin.iter().step_by(stride).copied().collect(),
        skipped: prob.skipped.clone(),
        ik: prob.ik,
        prior,
    }
}

/// Coordinates `at` on every frame of `prob`, moved by the change a solve on every
/// `stride`-th frame ([`subsample`]) made to them: `moved[i]` is frame `i·stride`'s new
/// coordinates. Between two such frames of the same trial the change is interpolated
/// linearly; past a trial's last one (or before its first) the nearest one's is taken. The
/// coordinates follow the parameters smoothly along a trial, so this carries `at` to the
/// parameters of that solve to first order.
pub(super) fn carried(
    prob: &Problem,
    at: &[Vec<f64>],
    moved: &[Vec<f64>],
    stride: usize,
) -> Vec<Vec<f64>> {
    let change: Vec<Vec<f64>> = moved
        .iter()
        .enumerate()
        .map(|(i, m)| m.iter().zip(&at[i * stride]).map(|(a, b)| a - b).collect())
        .collect();
    let trial = |f: usize| prob.origin[f].0;
    let mut out = at.to_vec();
    for (f, q) in out.iter_mut().enumerate() {
        let i = f / stride;
        let w = (f - i * stride) as f64 / stride as f64;
        let this = (trial(i * stride) == trial(f)).then(|| &change[i]);
        let next = change
            .get(i + 1)
            .filter(|_| trial((i + 1) * stride) == trial(f));
        for (c, v) in q.iter_mut().enumerate() {
            *v += match (this, next) {
                (Some(a), Some(b)) => (1.0 - w) * a[c] + w * b[c],
                (Some(a), None) => a[c],
                (None, Some(b)) => b[c],
                (None, None) => 0.0,
            };
        }
    }
    out
}

/// Every start of the global phase (the given one first) and its seeded inner solutions on
/// the probes' frames: what the probes begin from.
pub(crate) type ProbeStarts = Vec<(Vec<f64>, Vec<Vec<f64>>)>;

/// The probes' frames: every `stride`-th of `prob`'s, `stride` the smallest that leaves at
/// most `settings.probe_frames`.
pub(super) fn probe_stride(prob: &Problem, settings: &FitSettings) -> usize {
    prob.frames.len().div_ceil(settings.probe_frames.max(1))
}

/// Start `k` of the global phase on `prob` (the given `start` for k = 0, else
/// [`probe_point`]) and its seeded inner solutions on the probes' frames `coarse`: what its
/// probe begins from. Neither depends on the marker noise σ that weighs the prior (only the
/// prior's means and SDs choose the starts), so a caller may form them from a problem whose
/// prior carries any σ.
pub(super) fn seeded_start(
    prob: &Problem,
    coarse: &Problem,
    start: &[f64],
    settings: &FitSettings,
    k: usize,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let p0 = if k == 0 {
        start.to_vec()
    } else {
        probe_point(prob, start, settings, k)
    };
    let q0 = coarse.initial_coords(&p0);
    (p0, q0)
}

/// The intermediate frames of the σ stage on a long trial ([`approach`]): every `m`-th frame,
/// `m = round(√stride)` (the geometric middle between the probes' `stride` and every frame),
/// when `m` is at least [`MIN_APPROACH_STRIDE`].
pub(super) fn approach_stride(stride: usize) -> Option<usize> {
    let m = (stride as f64).sqrt().round() as usize;
    (m >= MIN_APPROACH_STRIDE).then_some(m)
}

/// Below this intermediate stride the approach costs more than it saves (measured with
/// callgrind, one thread, default `calibrate`: opencap walking1, 143 frames, probes every
/// 6th frame, `m` = 2: +2.6 % instructions; gait2392 walk1, `m` = 3: −1.8 %; Hamner running,
/// 600 frames, `m` = 5: −28 %).
pub(super) const MIN_APPROACH_STRIDE: usize = 3;

/// A probe `fit` (on every `stride`-th frame) continued on every `m`-th frame
/// ([`approach_stride`]) to [`SIGMA_POINT_RESOLUTION_SE`] of that problem's optimum, from
/// inner solutions seeded at its parameters. The probes' optimum, on a `1/stride` sample of
/// the frames, lies of the order of `√stride` standard errors of the full problem from the
/// full optimum, and a probe stops short of it, so on a long trial most of the σ stage's
/// iterations on every frame moved the parameters across that distance (Hamner running: steps
/// of 0.1–0.16 of the parameters' half-ranges in its first six). On `m`-th frames they cost
/// `1/m` as much, and the stage on every frame starts of the order of `√m` SE away.
pub(super) fn approach(
    prob: &Problem,
    m: usize,
    fit: &Fit,
    opts: &JointOptions,
    observer: &mut dyn Observer,
) -> Fit {
    let medium = subsample(prob, m);
    let q0 = medium.initial_coords(&fit.p);
    solve_joint_to(
        &medium,
        &fit.s,
        q0,
        opts,
        SIGMA_POINT_RESOLUTION_SE,
        observer,
    )
}
