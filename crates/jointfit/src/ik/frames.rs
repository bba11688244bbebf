//! Starting coordinates for many frames at once (the calibration's initial inverse
//! kinematics), in the same fixed parallel chunks as [`super::solve_trial`].

use nalgebra::Vector3;
use rayon::prelude::*;

use super::{chunk_ranges, seed_frame, solve_frame, IkOptions, IkWorkspace};
use crate::model::Model;

/// Solves every frame of `frames` (one target per model marker, NaN when missing) at
/// parameters `p` and returns the coordinates each solve ends at, whatever its status.
///
/// Frame `f` starts from the solution of frame `f − 1` unless `new_sequence(f)` (the first
/// frame of a trial) or it is the first frame of a chunk ([`chunk_ranges`]): those are
/// seeded ([`seed_frame`]). The chunks depend only on `frames.len()`, each is solved on one
/// thread the same way whatever thread that is, so the result is bit for bit the same on any
/// number of threads. This is the loop of `calibrate::Problem::initial_coords` (seed at each
/// trial, warm start from the previous frame) cut into chunks.
pub(crate) fn warm_started_coords(
    model: &Model,
    p: &[f64],
    frames: &[Vec<Vector3<f64>>],
    new_sequence: impl Fn(usize) -> bool + Sync,
    opts: &IkOptions,
) -> Vec<Vec<f64>> {
    let pieces: Vec<Vec<Vec<f64>>> = chunk_ranges(frames.len(), false)
        .into_par_iter()
        .map(|range| {
            let mut ws = IkWorkspace::new(model);
            let mut out: Vec<Vec<f64>> = Vec::with_capacity(range.len());
            let first = range.start;
            for f in range {
                let mut q = match out.last() {
                    Some(prev) if f > first && !new_sequence(f) => prev.clone(),
                    _ => seed_frame(model, p, &frames[f], opts, &mut ws),
                };
                solve_frame(model, p, &frames[f], &mut q, opts, &mut ws);
                out.push(q);
            }
            out
        })
        .collect();
    pieces.into_iter().flatten().collect()
}
