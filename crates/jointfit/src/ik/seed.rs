//! Starting points for frames with no previous solution.

use nalgebra::{Rotation3, Unit, Vector3};

use super::lm::{frame_weights, lm};
use super::{IkOptions, IkWorkspace};
use crate::kinematics::forward_kinematics_axes;
use crate::model::{CoordKind, Model, Source};

/// A starting point for a frame with no previous solution: defaults everywhere, then the
/// coordinates of the joints of root segments fitted to those segments' markers alone from
/// several starting orientations (every rotational root coordinate at 0, ±90° or 180°).
/// A root with fewer than three markers present is fitted to every present marker instead
/// (the other coordinates at their defaults): the chain below it fixes what its own markers
/// cannot.
///
/// Every start gets [`SEED_SCOUT_ITERATIONS`] iterations and the best [`SEED_FINALISTS`]
/// are converged. When the root's rotations are plain rotations by their coordinates, the
/// starts are first ranked by the root markers' misfit at each start's orientation in closed
/// form ([`rotation_scores`]) and only the best [`SEED_SCOUTED`] are scouted: on opencap
/// walking1 this cuts the seed from 3.15 to 1.26 M instructions (callgrind). The score
/// ranks orientations on the 90° grid without iterating, so it alone picks the wrong
/// basin too often to choose the finalists (commit 0dc932d converged only its best 4 and
/// changed OpenCap's generic.osim walking1 beyond OpenSim's fit); it only drops the starts
/// far from every good orientation, and the scouting iterations still choose.
///
/// Before scouting, the best-scored starts alone are converged, and their fit is taken
/// when it reaches the least misfit any rigid placement of the root's markers can have (the
/// orthogonal Procrustes minimum): a certificate that it is the global minimum the scouting
/// looks for ([`certified_root`]). On opencap walking1 that cuts a seed from 1.23 to
/// 0.21 M instructions.
pub(crate) fn seed_frame(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> Vec<f64> {
    // The seed fits the markers alone; the frame's coordinate tasks act in its solve.
    let goals = std::mem::take(&mut ws.goals);
    let q = seed(model, p, targets, opts, ws, true);
    ws.goals = goals;
    q
}

#[cfg(test)]
/// [`seed_frame`] without the certified shortcut ([`certified_root`]): every root scouted
/// on the grid. The oracle of the shortcut's tests.
#[doc(hidden)]
pub(crate) fn seed_frame_by_scouting(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
) -> Vec<f64> {
    seed(model, p, targets, opts, ws, false)
}

fn seed(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    opts: &IkOptions,
    ws: &mut IkWorkspace,
    certify: bool,
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
        let joint = &model.joints()[root];
        let active: Vec<usize> = joint.coords.clone().collect();
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
        let starts = grid.len().pow(rot.len() as u32);
        let start = |s: usize| {
            let mut qs = q.clone();
            let mut k = s;
            for &c in &rot {
                qs[c] = grid[k % grid.len()];
                k /= grid.len();
            }
            qs
        };
        let seed_opts = IkOptions {
            max_iterations: 15,
            ..*opts
        };
        // The starts worth scouting: all, or the best few by the closed-form score, in
        // start order (so that equal scouting costs sort as they would among all starts).
        let scouted: Vec<usize> = match rotation_scores(model, p, &q, root, &rot, targets, ws) {
            Some((score, floor)) if starts > SEED_SCOUTED => {
                let mut scored: Vec<(f64, usize)> =
                    (0..starts).map(|s| (score(&start(s)), s)).collect();
                scored.sort_by(|a, b| a.0.total_cmp(&b.0));
                let certified = certify
                    .then(|| {
                        certified_root(
                            model, p, targets, &active, &rot, &scored, floor, start, ws, opts,
                        )
                    })
                    .flatten();
                if let Some(qs) = certified {
                    for &c in &active {
                        q[c] = qs[c];
                    }
                    continue;
                }
                let mut best: Vec<usize> =
                    scored.iter().take(SEED_SCOUTED).map(|&(_, s)| s).collect();
                best.sort_unstable();
                best
            }
            _ => (0..starts).collect(),
        };
        // Every scouted start gets a few iterations; the most promising few are then
        // converged (the correct basin is clear long before convergence, and most starts
        // are far).
        let scout = IkOptions {
            max_iterations: SEED_SCOUT_ITERATIONS,
            ..*opts
        };
        let mut candidates: Vec<(f64, Vec<f64>)> = scouted
            .into_iter()
            .map(|s| {
                let mut qs = start(s);
                let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &scout, ws);
                (cost, qs)
            })
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        candidates.truncate(SEED_FINALISTS);
        let mut best: Option<(f64, Vec<f64>)> = None;
        for (_, mut qs) in candidates {
            let (cost, _, _) = lm(model, p, targets, &mut qs, &active, &seed_opts, ws);
            for &c in &rot {
                qs[c] = wrap_angle(qs[c]);
            }
            keep_better(&mut best, cost, qs, &rot);
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

/// Keeps in `best` the better of it and the fit `qs` of cost `cost`. Equal fits (e.g. the two
/// Euler-angle solutions of one orientation): the one with the smaller rotations `rot`, so
/// that results do not depend on the start order.
fn keep_better(best: &mut Option<(f64, Vec<f64>)>, cost: f64, qs: Vec<f64>, rot: &[usize]) {
    let size: f64 = rot.iter().map(|&c| qs[c].abs()).sum();
    let better = match best {
        None => true,
        Some((b, bq)) => {
            let bsize: f64 = rot.iter().map(|&c| bq[c].abs()).sum();
            let tie = (cost - *b).abs() <= 1e-9 * b.max(1e-12);
            if tie {
                size < bsize - 1e-9
            } else {
                cost < *b
            }
        }
    };
    if better {
        *best = Some((cost, qs));
    }
}

/// The root's coordinates fitted to its own markers from the best-scored starts alone, when
/// that fit is certified globally optimal; `None` (scout the grid instead) otherwise.
///
/// `scored` lists every start by its closed-form score ([`rotation_scores`]), best first;
/// `floor` is the least misfit any rigid placement of the root's markers can reach (the
/// weighted orthogonal Procrustes minimum, [`procrustes_floor`]). The starts whose score
/// ties the best (the grid holds each orientation twice, as both Euler-angle triples; at
/// most [`CERTIFIED_STARTS`], at least two) are converged. The root's coordinates cannot fit
/// its markers better than the floor, so a fit that reaches it (to
/// [`CERTIFIED_TOLERANCE`]) is a global minimum of the root's misfit, which is what the
/// scouting looks for; at least two starts must reach it, so that both Euler-angle triples
/// of the orientation are seen and the smaller is kept as [`seed_frame`] keeps it. On
/// opencap walking1 this cuts a seed from 1.23 to 0.21 M instructions (callgrind;
/// `notebook/ik_speed.md`).
#[allow(clippy::too_many_arguments)]
fn certified_root(
    model: &Model,
    p: &[f64],
    targets: &[Vector3<f64>],
    active: &[usize],
    rot: &[usize],
    scored: &[(f64, usize)],
    floor: Floor,
    start: impl Fn(usize) -> Vec<f64>,
    ws: &mut IkWorkspace,
    opts: &IkOptions,
) -> Option<Vec<f64>> {
    let Floor {
        misfit: floor,
        scale,
    } = floor;
    let tol = |x: f64| 1e-9 * x.abs() + 1e-12 * scale;
    let s0 = scored.first()?.0;
    let tied = scored
        .iter()
        .take(CERTIFIED_STARTS)
        .take_while(|(s, _)| *s <= s0 + tol(s0))
        .count()
        .max(2);
    let converge = IkOptions {
        max_iterations: SEED_SCOUT_ITERATIONS + 15,
        ..*opts
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut certified = 0;
    for &(_, s) in scored.iter().take(tied) {
        let mut qs = start(s);
        let (cost, _, _) = lm(model, p, targets, &mut qs, active, &converge, ws);
        if cost > floor + CERTIFIED_TOLERANCE * floor.max(0.0) + 1e-12 * scale {
            continue;
        }
        certified += 1;
        for &c in rot {
            qs[c] = wrap_angle(qs[c]);
        }
        keep_better(&mut best, cost, qs, rot);
    }
    if certified < 2 {
        return None;
    }
    #[cfg(test)]
    CERTIFIED.with(|n| n.set(n.get() + 1));
    best.map(|(_, qs)| qs)
}

#[cfg(test)]
thread_local! {
    /// Seeds of this thread that took the certified shortcut (for the tests).
    static CERTIFIED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Seeds of this thread that took the certified shortcut so far.
#[cfg(test)]
pub(super) fn certified_count() -> usize {
    CERTIFIED.with(|n| n.get())
}

/// Most starts [`certified_root`] converges.
const CERTIFIED_STARTS: usize = 4;
/// Relative excess over the Procrustes floor up to which a root fit counts as reaching it:
/// a converged fit is within rounding of its minimum, while another basin of the root's
/// misfit (a rotation tens of degrees off) lies orders of magnitude higher.
const CERTIFIED_TOLERANCE: f64 = 1e-6;

/// The least weighted misfit `min_{R ∈ SO(3), t} Σ_j w_j ‖m_j − (R x_j + t)‖²` of the point
/// pairs `(w_j, x_j − x̄, m_j − m̄)` (centred on their weighted centroids), with the scale
/// `Σ w (‖x − x̄‖² + ‖m − m̄‖²)` it is a difference within. The best translation matches
/// the centroids; with `C = Σ_j w_j (x_j − x̄)(m_j − m̄)ᵀ` and its singular values
/// `σ₁ ≥ σ₂ ≥ σ₃`, the best proper rotation gives `tr(R C) = σ₁ + σ₂ + sign(det C) σ₃`
/// (Kabsch 1976; Umeyama, IEEE TPAMI 13(4), 1991, for the reflection case), so the minimum
/// is `Σ w (‖x − x̄‖² + ‖m − m̄‖²) − 2 (σ₁ + σ₂ + sign(det C) σ₃)`.
pub(super) fn procrustes_floor(pairs: &[(f64, Vector3<f64>, Vector3<f64>)]) -> Floor {
    let mut c = nalgebra::Matrix3::zeros();
    let mut scale = 0.0;
    for (w, x, m) in pairs {
        c += *w * x * m.transpose();
        scale += w * (x.norm_squared() + m.norm_squared());
    }
    let mut sv = c.singular_values();
    sv.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    let sign = if c.determinant() < 0.0 { -1.0 } else { 1.0 };
    Floor {
        misfit: (scale - 2.0 * (sv[0] + sv[1] + sign * sv[2])).max(0.0),
        scale,
    }
}

/// The result of [`procrustes_floor`].
#[derive(Debug, Clone, Copy)]
pub(super) struct Floor {
    /// The least misfit.
    pub misfit: f64,
    /// `Σ w (‖x − x̄‖² + ‖m − m̄‖²)`, the sum the misfit is a difference within.
    pub scale: f64,
}

/// Iterations every seeding start gets before the finalists are chosen.
const SEED_SCOUT_ITERATIONS: usize = 3;
/// Starts converged fully when seeding.
const SEED_FINALISTS: usize = 8;
/// Starts scouted when the closed-form score ranks them first ([`rotation_scores`]): twice
/// [`SEED_FINALISTS`] (the grid holds every orientation twice, as both Euler-angle
/// triples), a quarter of the 64 starts of a three-rotation root.
const SEED_SCOUTED: usize = 16;

/// The misfit of the root segment's markers when the root's rotational coordinates `rot`
/// take other values, the translation chosen best, as a closed-form score of a start `qs`
/// (equal to `q` outside `rot`): `Σ_j w_j ‖(m_j − m̄) − ΔR (x_j − x̄)‖²` with `x_j` the model
/// markers at `q`, `m_j` their targets, bars the weighted centroids, and `ΔR` the rotation
/// the coordinate changes cause. By the product-of-exponentials formula of a serial chain
/// (Brockett 1984; Murray, Li & Sastry, *A Mathematical Introduction to Robotic
/// Manipulation*, 1994, §3.2), `ΔR = Π_k exp(θ_k [ω_k]×)` over the joint's rotation steps
/// in chain order, `ω_k` the world axis of step `k` at `q` and `θ_k = s_k (qs_c − q_c)` its
/// angle change (`s_k` the step's scale): no kinematics per start. The root's translation
/// moves its markers rigidly, so the best translation for a rotation is the one that
/// matches the centroids. `None` (score by iterations instead) when a step of `rot` is not a
/// rotation by a multiple of its coordinate (a function of it, or a translation), or the
/// root has fewer than three markers with weight (`ws.weights`).
fn rotation_scores<'a>(
    model: &Model,
    p: &[f64],
    q: &[f64],
    root: usize,
    rot: &'a [usize],
    targets: &[Vector3<f64>],
    ws: &mut IkWorkspace,
) -> Option<(impl Fn(&[f64]) -> f64 + 'a, Floor)> {
    let mut steps: Vec<(usize, f64, Unit<Vector3<f64>>)> = Vec::new();
    let markers: Vec<usize> = model.plan.markers_by_segment[root]
        .iter()
        .copied()
        .filter(|&j| ws.weights[j] > 0.0)
        .collect();
    if markers.len() < 3 {
        return None;
    }
    forward_kinematics_axes(model, p, q, &mut ws.cur);
    for c in &model.plan.cols_q[root] {
        if !rot.contains(&c.col) {
            continue;
        }
        if !c.rotation || !matches!(model.steps[c.step].source, Source::Coord { .. }) {
            return None;
        }
        let axis = Unit::try_new(ws.cur.step_frame(c.step).0, 1e-12)?;
        steps.push((c.col, c.scale, axis));
    }
    let w: Vec<f64> = markers.iter().map(|&j| ws.weights[j]).collect();
    let mass: f64 = w.iter().sum();
    let centroid = |x: &dyn Fn(usize) -> Vector3<f64>| {
        markers
            .iter()
            .zip(&w)
            .map(|(&j, &wj)| wj * x(j))
            .sum::<Vector3<f64>>()
            / mass
    };
    let (xc, mc) = (centroid(&|j| ws.cur.markers[j]), centroid(&|j| targets[j]));
    let pairs: Vec<(f64, Vector3<f64>, Vector3<f64>)> = markers
        .iter()
        .zip(&w)
        .map(|(&j, &wj)| (wj, ws.cur.markers[j] - xc, targets[j] - mc))
        .collect();
    let q0 = q.to_vec();
    let floor = procrustes_floor(&pairs);
    let score = move |qs: &[f64]| {
        let mut r = Rotation3::identity();
        for (c, scale, axis) in &steps {
            r *= Rotation3::from_axis_angle(axis, scale * (qs[*c] - q0[*c]));
        }
        pairs
            .iter()
            .map(|(wj, x, m)| wj * (m - r * x).norm_squared())
            .sum()
    };
    Some((score, floor))
}

/// The angle in (−π, π].
fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}
