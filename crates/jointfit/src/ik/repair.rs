//! Frames whose fit is absurd against the rest of the trial, re-solved from other starts.
//!
//! Warm starts make IK fast, but on a model that matches the markers poorly (an unscaled
//! generic model, say) an extrapolated start can fall into a wrong local minimum: on OpenCap's
//! unscaled `generic.osim` with `walking1`, frame 20 ended at 683 mm RMS where its
//! neighbours sit at 96 mm and OpenSim's IK finds 98 mm. Such a frame is recognised by its
//! RMS marker distance `r_f` against the median `m` of the trial's solved frames:
//!
//! * *suspect* when `r_f > max(2 m, m + 5 mm)` (or the fit diverged): it is solved again from the
//!   solution of the nearest earlier frame that is not suspect, from that of the nearest later
//!   one, and from a fresh seed ([`super::seed_frame`]), and the best of these and the original
//!   is kept. "Best" is the smallest truncated quadratic loss `Σ_j w_j min(d_j², c²)` with
//!   `c` the outlier distance ([`IkOptions::outlier_distance`]): a marker rejected as a gross
//!   error counts `w_j c²`, so a start cannot win by rejecting good markers;
//! * *implausible* when, after that, still `r_f > max(5 m, m + 50 mm)`: the frame is not
//!   reported solved ([`FrameStatus::Implausible`]), its coordinates are NaN.
//!
//! A frame whose solution improved may have found a basin its neighbours missed (on
//! `generic.osim` the warm-start chain after frame 20 stayed up to 9 mm RMS above OpenSim's
//! minima for 50 frames): each neighbour is solved again from the improved solution and kept
//! when its loss drops (by more than a relative 1e-9, so equal minima never alternate), and
//! so on outwards. The first frame of each parallel chunk ([`super::trial_chunk_ranges`]) was
//! seeded rather than warm-started, so it is also tried from the frame before it, and that
//! frame from it, with the same propagation.
//!
//! The margins keep noiseless or very clean trials (median near 0) from flagging ordinary
//! frames. Suspects are handled in frame order, a repaired frame serving as the earlier
//! neighbour of the next, all on one thread: the result does not depend on the thread count.
//! On a trial without suspects the pass costs two frame solves per chunk boundary.

use super::trial_fit::marker_errors;
use super::{
    seed_frame, solve_frame, FrameFit, FrameStatus, IkOptions, IkWorkspace, MarkerMap, TrialFit,
};
use crate::model::Model;
use crate::trial::Trial;

/// A frame is suspect above `max(SUSPECT_RATIO · m, m + SUSPECT_MARGIN)` (m: the median).
pub(crate) const SUSPECT_RATIO: f64 = 2.0;
/// See [`SUSPECT_RATIO`] (m).
pub(crate) const SUSPECT_MARGIN: f64 = 0.005;
/// A frame is implausible above `max(IMPLAUSIBLE_RATIO · m, m + IMPLAUSIBLE_MARGIN)`.
pub(crate) const IMPLAUSIBLE_RATIO: f64 = 5.0;
/// See [`IMPLAUSIBLE_RATIO`] (m).
pub(crate) const IMPLAUSIBLE_MARGIN: f64 = 0.05;

/// The median of `v` (NaN when empty).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The truncated quadratic loss of a solved frame (see the module docs).
fn loss(model: &Model, fit: &FrameFit, opts: &IkOptions) -> f64 {
    let c2 = opts.outlier_distance * opts.outlier_distance;
    if !c2.is_finite() {
        // No rejection after the fit: only gross samples are rejected, by every start alike.
        return fit.cost;
    }
    fit.cost
        + fit
            .rejected
            .iter()
            .map(|&j| model.markers()[j].weight * c2)
            .sum::<f64>()
}

/// Scratch of one repair pass.
struct Repair<'a> {
    model: &'a Model,
    p: &'a [f64],
    trial: &'a Trial,
    map: &'a MarkerMap,
    opts: &'a IkOptions,
    ws: IkWorkspace,
    targets: Vec<nalgebra::Vector3<f64>>,
}

impl Repair<'_> {
    /// Solves frame `f` from `start`; keeps the result when its loss is lower than the
    /// current one by more than a relative 1e-9 (so equal minima never ping-pong).
    fn try_start(&mut self, fit: &mut TrialFit, f: usize, mut start: Vec<f64>) -> bool {
        if start.iter().any(|v| !v.is_finite()) {
            return false;
        }
        let current = if fit.frames[f].solved() {
            loss(self.model, &fit.frames[f], self.opts)
        } else {
            f64::INFINITY
        };
        self.map.targets(self.trial, f, &mut self.targets);
        self.ws.set_coordinate_goals(&self.map.coordinate_tasks, f);
        let mut attempt = solve_frame(
            self.model,
            self.p,
            &self.targets,
            &mut start,
            self.opts,
            &mut self.ws,
        );
        let l = loss(self.model, &attempt, self.opts);
        // NaN losses never win.
        let better = l < current * (1.0 - 1e-9);
        if !attempt.solved() || !better {
            return false;
        }
        attempt.iterations += fit.frames[f].iterations;
        fit.errors[f] = marker_errors(self.model, &self.targets, &attempt, &self.ws);
        fit.coords[f] = start;
        fit.frames[f] = attempt;
        true
    }
}

/// Re-solves the suspect frames of `fit`, carries every improvement to the neighbouring
/// frames, and marks the frames that stay implausible (see the module docs). `boundaries`
/// are the first frames of the chunks after the first: each is tried from the frame before
/// it and the other way round. `ws` is scratch space (any, e.g. a chunk's).
#[allow(clippy::too_many_arguments)]
pub(super) fn repair_absurd(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    fit: &mut TrialFit,
    boundaries: &[usize],
    ws: IkWorkspace,
) {
    let n = fit.frames.len();
    let solved_rms = |fit: &TrialFit, f: usize| {
        if fit.frames[f].solved() {
            super::trial_fit::rms(fit.errors[f].iter().copied())
        } else {
            f64::NAN
        }
    };
    let m = median(
        (0..n)
            .map(|f| solved_rms(fit, f))
            .filter(|r| r.is_finite())
            .collect(),
    );
    if !m.is_finite() {
        return;
    }
    let suspect_above = (SUSPECT_RATIO * m).max(m + SUSPECT_MARGIN);
    let implausible_above = (IMPLAUSIBLE_RATIO * m).max(m + IMPLAUSIBLE_MARGIN);
    let mut good: Vec<bool> = (0..n)
        .map(|f| solved_rms(fit, f) <= suspect_above)
        .collect();
    let suspects: Vec<usize> = (0..n)
        .filter(|&f| {
            (fit.frames[f].solved() && !good[f]) || fit.frames[f].status == FrameStatus::Diverged
        })
        .collect();
    let mut r = Repair {
        model,
        p,
        trial,
        map,
        opts,
        ws,
        targets: Vec::with_capacity(model.markers().len()),
    };
    let mut changed = std::collections::VecDeque::new();
    for &f in &suspects {
        let mut starts: Vec<Vec<f64>> = Vec::with_capacity(3);
        if let Some(g) = (0..f).rev().find(|&g| good[g]) {
            starts.push(fit.coords[g].clone());
        }
        if let Some(g) = (f + 1..n).find(|&g| good[g]) {
            starts.push(fit.coords[g].clone());
        }
        r.map.targets(trial, f, &mut r.targets);
        let targets = std::mem::take(&mut r.targets);
        starts.push(seed_frame(model, p, &targets, opts, &mut r.ws));
        r.targets = targets;
        let mut improved = false;
        for start in starts {
            improved |= r.try_start(fit, f, start);
        }
        if improved {
            changed.push_back(f);
        }
        good[f] = solved_rms(fit, f) <= suspect_above;
    }
    for &b in boundaries.iter().filter(|&&b| b > 0 && b < n) {
        for (f, from) in [(b, b - 1), (b - 1, b)] {
            if fit.frames[from].solved() && r.try_start(fit, f, fit.coords[from].clone()) {
                changed.push_back(f);
            }
        }
    }
    // An improved frame may have found a basin its neighbours missed: carry it on, in both
    // directions, as long as it improves them.
    while let Some(f) = changed.pop_front() {
        for g in [f.wrapping_sub(1), f + 1] {
            if g < n && fit.frames[g].solved() && r.try_start(fit, g, fit.coords[f].clone()) {
                changed.push_back(g);
            }
        }
    }
    for f in suspects {
        let rms = solved_rms(fit, f);
        // A NaN RMS (no marker left) is implausible too.
        let plausible = rms <= implausible_above;
        if fit.frames[f].solved() && !plausible {
            fit.frames[f].status = FrameStatus::Implausible { rms, median: m };
            fit.coords[f] = vec![f64::NAN; model.coordinates().len()];
            fit.errors[f] = vec![f64::NAN; model.markers().len()];
        }
    }
}
