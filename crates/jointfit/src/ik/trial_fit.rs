//! The trial loop: every frame in order, warm-started from the ones before, in chunks of
//! frames solved in parallel.

use std::ops::Range;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::lm::frame_weights;
use super::{
    seed_frame, solve_frame, FrameFit, FrameStatus, IkError, IkOptions, IkWorkspace, MarkerMap,
};
use crate::model::Model;
use crate::trial::Trial;

/// Inverse kinematics of a whole trial.
#[derive(Debug, Clone)]
pub struct TrialFit {
    /// Coordinates per frame (`n_q` each; NaN for frames not solved).
    pub coords: Vec<Vec<f64>>,
    pub frames: Vec<FrameFit>,
    /// Marker distance errors `‖m − x‖` per frame and model marker (m; NaN when missing).
    pub errors: Vec<Vec<f64>>,
}

/// Root mean square of the non-NaN values (NaN when there are none). The marker RMS of a
/// [`TrialFit`]: of one frame over its present markers, `rms(fit.errors[frame].iter().copied())`;
/// of one marker over the frames, `rms(fit.errors.iter().map(|e| e[marker]))`; of every
/// present sample, `rms(fit.errors.iter().flatten().copied())` (m).
pub fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for v in values.filter(|v| !v.is_nan()) {
        s += v * v;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// The start for the next frame: the last two solutions extrapolated linearly,
/// `q_i⁰ = 2 q_{i−1} − q_{i−2}`. At mocap rates the coordinates are smooth, so this starts
/// within `O(Δt²)` of the solution instead of `O(Δt)`, which saves about one Gauss-Newton
/// iteration per frame.
pub(crate) fn extrapolate(prev: &[f64], before: &[f64]) -> Vec<f64> {
    prev.iter().zip(before).map(|(a, b)| 2.0 * a - b).collect()
}

/// Frames are solved in chunks of consecutive frames, each chunk on its own thread (see
/// [`trial_chunk_ranges`]).
///
/// Solves every frame of `trial` with warm starts (see the module docs): the first frame of
/// each chunk (and the first after a frame that could not be solved) from [`seed_frame`],
/// the second from the first, later ones from the linear extrapolation of the two before.
/// Frames whose fit is absurd against the rest of the trial are then re-solved from their
/// neighbours ([`super::repair`]). Each frame's coordinates are reported as the equivalent
/// ones inside the model's coordinate ranges: the in-range branch of every Euler-angle
/// triple, whole turns removed ([`super::branch`]).
///
/// The chunks depend only on the number of frames (and on
/// [`IkOptions::hold_undetermined`]), never on the number of threads, and each chunk is
/// solved the same way on any thread, so the result is bit for bit the same on one thread
/// or many.
pub fn solve_trial(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
) -> Result<TrialFit, IkError> {
    let chunks = trial_chunk_ranges(trial.n_frames(), opts.hold_undetermined);
    solve_trial_in_chunks(model, p, trial, map, opts, &chunks)
}

/// [`solve_trial`] with other work, `also`, run alongside on the thread pool (the data checks
/// of `workflow::ik::ik_checked`). `also` is queued after the chunks, so that a free thread takes
/// a chunk first and `also` (with the parallel tasks it spawns) fills the time of whichever
/// thread finishes its chunk first, instead of delaying a chunk by its whole length. Neither
/// result depends on the order the pool runs them in.
pub(crate) fn solve_trial_alongside<R: Send>(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    also: impl FnOnce() -> R + Send,
) -> (Result<TrialFit, IkError>, R) {
    let chunks = trial_chunk_ranges(trial.n_frames(), opts.hold_undetermined);
    solve_chunks_alongside(model, p, trial, map, opts, &chunks, also)
}

/// [`solve_trial`] with the chunks given: `chunks` must cover `0..trial.n_frames()` in order
/// (a chunk per thread; the first frame of each seeded). For tests and measurements (the
/// trial solved as one chunk against the chunks [`solve_trial`] takes).
pub(crate) fn solve_trial_in_chunks(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    chunks: &[Range<usize>],
) -> Result<TrialFit, IkError> {
    solve_chunks_alongside(model, p, trial, map, opts, chunks, || ()).0
}

/// [`solve_trial_in_chunks`] with `also` alongside (see [`solve_trial_alongside`]).
fn solve_chunks_alongside<R: Send>(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    chunks: &[Range<usize>],
    also: impl FnOnce() -> R + Send,
) -> (Result<TrialFit, IkError>, R) {
    if p.len() != model.parameters().len() {
        let err = IkError::ParamLength {
            got: p.len(),
            expected: model.parameters().len(),
        };
        return (Err(err), also());
    }
    assert!(
        chunks.first().map_or(0, |c| c.start) == 0
            && chunks.last().map_or(0, |c| c.end) == trial.n_frames()
            && chunks.windows(2).all(|w| w[0].end == w[1].start),
        "chunks must cover the trial in order"
    );
    let boundaries: Vec<usize> = chunks.iter().skip(1).map(|c| c.start).collect();
    let solve = |range: &Range<usize>| solve_range(model, p, trial, map, opts, range.clone());
    // `rayon::join(a, b)` queues `b` and runs `a` here: the first chunk with `also` behind
    // it is queued first (a free thread takes it), the other chunks run here; the first
    // chunk's thread queues `also` before solving its chunk, for the first free thread.
    let (rest, (first, also)) = rayon::join(
        || {
            let rest = chunks.get(1..).unwrap_or(&[]);
            rest.par_iter().map(solve).collect::<Vec<_>>()
        },
        || rayon::join(|| chunks.first().map(solve), also),
    );
    let pieces = first.into_iter().chain(rest);
    let mut out = TrialFit {
        coords: Vec::with_capacity(trial.n_frames()),
        frames: Vec::with_capacity(trial.n_frames()),
        errors: Vec::with_capacity(trial.n_frames()),
    };
    // The repair pass reuses the first chunk's workspace (a fresh one costs as much as
    // two frames; nothing a frame's solve reads survives from the one before, so the result
    // is the same).
    let mut ws = None;
    for (piece, piece_ws) in pieces {
        out.coords.extend(piece.coords);
        out.frames.extend(piece.frames);
        out.errors.extend(piece.errors);
        ws.get_or_insert(piece_ws);
    }
    let ws = ws.unwrap_or_else(|| IkWorkspace::new(model));
    super::repair::repair_absurd(model, p, trial, map, opts, &mut out, &boundaries, ws);
    // Report every pose by its coordinates inside the model's ranges ([`super::branch`]).
    let branches = super::branch::Branches::new(model);
    for q in &mut out.coords {
        branches.canonicalize(q);
    }
    (Ok(out), also)
}

/// Fewest frames in a chunk of a long trial (in [`trial_chunk_ranges`] and `chunk_ranges`): from 1024 frames on a trial is cut into `⌊n / 512⌋` chunks, so that
/// the seeds cost under 5 % and, from 4096 frames on, there are enough chunks for work
/// stealing to balance the load on a shared machine.
pub(crate) const MIN_CHUNK_FRAMES: usize = 512;
/// Most chunks in a trial (enough to balance the load on a few cores).
pub(crate) const MAX_CHUNKS: usize = 32;
/// From this many frames on [`solve_trial`] cuts a trial into at least two chunks, so that a
/// short trial (a gait cycle or two) uses two cores. The second chunk's seed costs about as
/// much as 2 warm-started frames (`seed.rs`: 0.21 M instructions, 1.26 M before the
/// certified root fit, against ≈ 0.12 M a frame on walking1), and two idle cores solve it
/// in ≈ 0.55 of the one-chunk time (measurements in `notebook/ik_speed.md`).
pub(crate) const MIN_SPLIT_FRAMES: usize = 128;

/// The chunks of consecutive frames [`solve_trial`] solves independently: one below
/// [`MIN_SPLIT_FRAMES`] frames, else `k = clamp(⌊n / 512⌋, 2, 32)` chunks of nearly equal
/// length (chunk `i` is `i·n/k .. (i+1)·n/k`). With `hold` (holding undetermined coordinates
/// at the previous frame's values, which needs the previous frame) the trial is one chunk.
/// A function of the frame count alone, never of the thread count, so the result is the same
/// on any number of threads.
pub(crate) fn trial_chunk_ranges(n: usize, hold: bool) -> Vec<Range<usize>> {
    let k = if hold || n < MIN_SPLIT_FRAMES {
        1
    } else {
        (n / MIN_CHUNK_FRAMES).clamp(2, MAX_CHUNKS)
    };
    even_chunks(n, k)
}

/// The chunks of `super::warm_started_coords` (a test oracle): `k = clamp(⌊n / 512⌋, 1, 32)` chunks of
/// nearly equal length, one with `hold`. Short trials stay one chunk here. (The
/// calibration's `calibrate::Problem::initial_coords` cuts its frames with
/// [`trial_chunk_ranges`] instead, so a short trial's seeded IK uses two cores.)
#[cfg(test)]
pub(crate) fn chunk_ranges(n: usize, hold: bool) -> Vec<Range<usize>> {
    let k = if hold {
        1
    } else {
        (n / MIN_CHUNK_FRAMES).clamp(1, MAX_CHUNKS)
    };
    even_chunks(n, k)
}

/// `0..n` cut into `k` chunks of nearly equal length (chunk `i` is `i·n/k .. (i+1)·n/k`).
fn even_chunks(n: usize, k: usize) -> Vec<Range<usize>> {
    (0..k).map(|i| i * n / k..(i + 1) * n / k).collect()
}

/// Solves frames `range` of `trial` in order, warm-started, the first seeded; returns the
/// fit with the workspace it used.
fn solve_range(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    opts: &IkOptions,
    range: Range<usize>,
) -> (TrialFit, IkWorkspace) {
    let mut ws = IkWorkspace::new(model);
    let mut targets = Vec::with_capacity(model.markers().len());
    // The last two solutions when they belong to consecutive frames.
    let mut q: Option<Vec<f64>> = None;
    let mut q_before: Option<Vec<f64>> = None;
    let mut out = TrialFit {
        coords: Vec::with_capacity(range.len()),
        frames: Vec::with_capacity(range.len()),
        errors: Vec::with_capacity(range.len()),
    };
    let no_hold = IkOptions {
        hold_undetermined: false,
        ..*opts
    };
    for f in range {
        map.targets(trial, f, &mut targets);
        ws.set_coordinate_goals(&map.coordinate_tasks, f);
        let mut qf = match (&q, &q_before) {
            (Some(prev), Some(before)) => extrapolate(prev, before),
            (Some(prev), None) => prev.clone(),
            (None, _) => seed_frame(model, p, &targets, opts, &mut ws),
        };
        let frame_opts = match &q {
            Some(prev) if opts.hold_undetermined => {
                // Held coordinates stay exactly at the previous frame's values.
                let mut rejected = Vec::new();
                frame_weights(model, &targets, &mut ws.weights, &mut rejected);
                let held =
                    ws.solvability
                        .undetermined_at(model, p, &ws.weights, &ws.known, prev, opts);
                for c in held {
                    qf[c] = prev[c];
                }
                opts
            }
            // A seeded frame holds what its markers leave undetermined at the seed's values
            // (the defaults beyond the root), where OpenSim's IK starts and leaves them.
            None if opts.hold_undetermined => opts,
            _ => &no_hold,
        };
        let fit = solve_frame(model, p, &targets, &mut qf, frame_opts, &mut ws);
        if fit.solved() {
            out.errors.push(marker_errors(model, &targets, &fit, &ws));
            out.coords.push(qf.clone());
            q_before = q.replace(qf);
        } else {
            out.errors.push(vec![f64::NAN; model.markers().len()]);
            out.coords.push(vec![f64::NAN; model.coordinates().len()]);
            // Across a gap the velocity is unknown: restart from the last solution alone;
            // after a result that went wrong, from seeding.
            q_before = None;
            if fit.status == FrameStatus::Diverged {
                q = None;
            }
        }
        out.frames.push(fit);
    }
    (out, ws)
}

/// Distances `‖m − x‖` of the model markers from their targets at the last solution in
/// `ws` (NaN for missing and rejected markers).
pub(super) fn marker_errors(
    model: &Model,
    targets: &[Vector3<f64>],
    fit: &FrameFit,
    ws: &IkWorkspace,
) -> Vec<f64> {
    (0..model.markers().len())
        .map(|j| {
            if fit.rejected.contains(&j) {
                f64::NAN
            } else {
                (targets[j] - ws.kin().markers[j]).norm()
            }
        })
        .collect()
}

/// A run of consecutive frames not solved for the same reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnsolvedRange {
    /// First and last frame index (inclusive, from 0).
    pub first: usize,
    pub last: usize,
    /// Why, e.g. `hip_flexion undetermined` or `diverged`.
    pub reason: String,
}

impl TrialFit {
    /// The frames not solved, as runs of consecutive frames with one reason.
    pub fn unsolved_ranges(&self) -> Vec<UnsolvedRange> {
        let mut out: Vec<UnsolvedRange> = Vec::new();
        for (f, frame) in self.frames.iter().enumerate() {
            let reason = match &frame.status {
                FrameStatus::Converged | FrameStatus::MaxIterations | FrameStatus::Stalled => {
                    continue
                }
                FrameStatus::Undetermined { coordinate } => format!("{coordinate} undetermined"),
                FrameStatus::Diverged => "diverged".to_string(),
                FrameStatus::Implausible { .. } => {
                    "implausible fit: RMS far above the trial's median".to_string()
                }
            };
            match out.last_mut() {
                Some(r) if r.last + 1 == f && r.reason == reason => r.last = f,
                _ => out.push(UnsolvedRange {
                    first: f,
                    last: f,
                    reason,
                }),
            }
        }
        out
    }
}
