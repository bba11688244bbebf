//! Starting points for frames with no previous solution.

use nalgebra::Vector3;

use super::lm::{frame_weights, lm};
use super::{IkOptions, IkWorkspace};
use crate::model::{CoordKind, Model};

/// A starting point for a frame with no previous solution: defaults everywhere, then the
/// coordinates of the joints of root segments fitted to those segments' markers alone from
/// several starting orientations (every rotational root coordinate at 0, ±90° or 180°).
/// A root with fewer than three markers present is fitted to every present marker instead
/// (the other coordinates at their defaults): the chain below it fixes what its own markers
/// cannot.
pub fn seed_frame(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> Vec<f64> {
    let mut q = model.default_coords();
    let roots: Vec<usize> = (0..model.segments().len())
        .filter(|&s| model.segments()[s].parent.is_none())
        .collect();
    let full_weights = {
        let mut rejected = Vec::new();
        frame_weights(model, targets, &mut ws.weights, &mut rejected);
        ws.weights.clone()
    };
    for &root in &roots {
        let joint = &model.joints()[model.segments()[root].joint.0];
        let active: Vec<usize> =
            (joint.first_coord..joint.first_coord + joint.kind.dof()).collect();
        if active.is_empty() {
            continue;
        }
        // Only this root's markers count.
        for (j, m) in model.markers().iter().enumerate() {
            ws.weights[j] = if m.segment.0 == root {
                full_weights[j]
            } else {
                0.0
            };
        }
        if ws.weights.iter().filter(|&&w| w > 0.0).count() < 3 {
            ws.weights.copy_from_slice(&full_weights);
            if ws.weights.iter().filter(|&&w| w > 0.0).count() < 3 {
                continue;
            }
        }
        // Translations start at their default values (the cost is quadratic in them, so the
        // first iterations carry them to the markers, however far); rotations from a grid.
        let rot: Vec<usize> = active
            .iter()
            .copied()
            .filter(|&c| model.coordinates()[c].kind == CoordKind::Rotational)
            .collect();
        let grid = [
            0.0,
            std::f64::consts::FRAC_PI_2,
            std::f64::consts::PI,
            -std::f64::consts::FRAC_PI_2,
        ];
        // Every start gets a few iterations; the most promising few are then converged
        // (the correct basin is clear long before convergence, and most starts are far).
        let starts = grid.len().pow(rot.len() as u32);
        let mut candidates: Vec<(f64, Vec<f64>)> = (0..starts)
            .map(|s| {
                let mut qs = q.clone();
                let mut k = s;
                for &c in &rot {
                    qs[c] = grid[k % grid.len()];
                    k /= grid.len();
                }
                let scout = IkOptions {
                    max_iterations: SEED_SCOUT_ITERATIONS,
                    ..*opts
                };
                let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &scout, ws);
                (cost, qs)
            })
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        candidates.truncate(SEED_FINALISTS);
        let mut best: Option<(f64, Vec<f64>)> = None;
        let seed_opts = IkOptions {
            max_iterations: 15,
            ..*opts
        };
        for (_, mut qs) in candidates {
            let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &seed_opts, ws);
            for &c in &rot {
                qs[c] = wrap_angle(qs[c]);
            }
            // Equal fits (e.g. the two Euler-angle solutions of one orientation): prefer the
            // one with the smaller angles, so results do not depend on the start order.
            let size: f64 = rot.iter().map(|&c| qs[c].abs()).sum();
            let better = match &best {
                None => true,
                Some((b, bq)) => {
                    let bsize: f64 = rot.iter().map(|&c| bq[c].abs()).sum();
                    let tie = (cost - b).abs() <= 1e-9 * b.max(1e-12);
                    if tie {
                        size < bsize - 1e-9
                    } else {
                        cost < *b
                    }
                }
            };
            if better {
                best = Some((cost, qs));
            }
        }
        if let Some((_, qs)) = best {
            for &c in &active {
                q[c] = qs[c];
            }
        }
    }
    ws.weights.copy_from_slice(&full_weights);
    q
}

/// Iterations every seeding start gets before the finalists are chosen.
const SEED_SCOUT_ITERATIONS: usize = 3;
/// Starts converged fully when seeding.
const SEED_FINALISTS: usize = 8;

/// The angle in (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}
