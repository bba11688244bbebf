//! The block-arrow normal equations of the joint problem and their Schur-complement solve.
//!
//! Unknowns: every frame's coordinates `q_i` (n_q each) and the scaled free parameters `s`
//! (n_f). With `J_i = [J_q,i | J_s,i]` the weighted Jacobian of frame i and `r_i = m_i − x_i`:
//!
//! `U_i = J_qᵀWJ_q`, `W_i = J_qᵀWJ_s`, `V = Σ_i J_sᵀWJ_s`, `g_i = J_qᵀWr`, `g_s = Σ_i J_sᵀWr`.
//!
//! The damped step solves `[U* W; Wᵀ V*] [δq; δs] = [g; g_s]` (`*`: diagonal scaled by
//! `1 + λ`): `S = V* − Σ W_iᵀ U_i*⁻¹ W_i`, `S δs = g_s − Σ W_iᵀ U_i*⁻¹ g_i`, then
//! `δq_i = U_i*⁻¹ (g_i − W_i δs)`. Cost: O(frames · n_q² · n_f) instead of a dense solve.
//!
//! **Memory.** Only `U_i`, `W_i`, `g_i` are kept per frame (`n_q² + n_q·n_f + n_q` numbers),
//! and only for as many frames as fit in [`CACHE_BYTES`]; the blocks of the other frames are
//! recomputed from the kinematics when a pass needs them. The working set therefore does not
//! grow with the trial beyond the coordinates themselves. When every frame's blocks and its
//! damped factor `L_i` (`n_q²` more) fit in [`CACHE_BYTES`], [`solve`] also keeps the factors
//! for [`back_substitute`], which otherwise factors `U_i*` again.
//!
//! **Threads.** Every pass runs over fixed chunks of [`chunk_len`] frames in parallel (rayon);
//! each chunk sums its frames in order and the chunk sums are added in chunk order, so the
//! results are the same bit for bit whatever the number of threads.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::kernel::{frame_gradient, frame_gram, FrameScratch, ScratchPool};
use super::Problem;
use crate::kinematics::{forward_kinematics, Want};

/// Frames per parallel work item of a long trial (the length sets the order of every
/// floating-point sum, so it depends on the number of frames only, never on the threads).
pub(crate) const CHUNK: usize = 32;

/// Below this many chunks of [`CHUNK`] frames an odd count is made even ([`chunk_len`]).
const EVEN_BELOW: usize = 16;

/// Frames per parallel work item on a problem of `frames` frames: [`CHUNK`], except that a
/// short trial whose chunks of [`CHUNK`] would be odd in number gets one chunk more, of equal
/// lengths (two threads then split the passes evenly: 143 frames are 5 chunks of 32, which
/// two threads split 3 : 2, 0.56 of the pass on the slower one, but 6 chunks of 24, 3 : 3).
/// Long trials keep [`CHUNK`]: with many chunks the split is even anyway.
pub(crate) fn chunk_len(frames: usize) -> usize {
    let chunks = frames.div_ceil(CHUNK);
    if chunks % 2 == 1 && chunks < EVEN_BELOW {
        frames.div_ceil(chunks + 1).max(1)
    } else {
        CHUNK
    }
}

/// Memory for cached per-frame blocks (bytes); frames beyond it are recomputed.
pub(crate) const CACHE_BYTES: usize = 48 << 20;

pub(crate) struct Blocks {
    pub nq: usize,
    pub nf: usize,
    frames: usize,
    /// Frames per parallel work item ([`chunk_len`]).
    chunk: usize,
    /// Frames (a prefix, a multiple of `chunk` unless all) whose blocks are in `store`.
    cached: usize,
    /// Per cached frame: `U_i` (n_q × n_q, column-major), `W_i` (n_q × n_f), `g_i` (n_q).
    store: Vec<f64>,
    /// Frames (all or none) whose damped factor `L_i` (n_q × n_q) of the last [`solve`] is
    /// in `factors`.
    factored: usize,
    factors: Vec<f64>,
    /// Whether `factors` hold the factors of the last successful [`solve`].
    factors_valid: bool,
    /// `V` (n_f × n_f, column-major).
    pub v: Vec<f64>,
    /// `g_s` (n_f).
    pub gs: Vec<f64>,
    /// The reduced matrix `S` of the last [`reduce`] (n_f × n_f, column-major).
    pub schur: Vec<f64>,
    /// The reduced right-hand side of the last [`reduce`] (n_f).
    pub rhs: Vec<f64>,
    /// Objective at the assembly point (m²).
    pub cost: f64,
    /// Parameters of the assembly point (to recompute uncached frames).
    p: Vec<f64>,
    /// Half-ranges of the free parameters.
    half: Vec<f64>,
    /// Damping of the last successful [`solve`].
    lambda: f64,
    /// Workspaces of the parallel passes.
    pool: ScratchPool,
    /// The coordinates bounded to their range (`index, lower, upper`): OpenSim's `clamped`
    /// ones when the problem's inverse kinematics clamps ([`crate::ik::IkOptions::clamp`]);
    /// empty for every built-in model.
    pub(crate) bounds: Vec<(usize, f64, f64)>,
}

/// The clamped coordinates of `prob`'s model as `(index, lower, upper)`, when its inverse
/// kinematics bounds them; else none.
pub(crate) fn coordinate_bounds(prob: &Problem) -> Vec<(usize, f64, f64)> {
    if !prob.ik.clamp {
        return Vec::new();
    }
    prob.model
        .coordinates()
        .iter()
        .enumerate()
        .filter(|(_, c)| c.clamped)
        .map(|(i, c)| (i, c.range[0], c.range[1]))
        .collect()
}

/// Holds, in one frame's blocks at coordinates `q` (`u` = `U`, n_q × n_q; `w` = `W` stored
/// parameter-major, `w[k·n_q + a]`; `g` = the coordinates' half negative gradient), every
/// bounded coordinate that sits at a bound with its descent direction pointing out of the
/// range: its row and column of `U` and its entries of `W` zeroed (the diagonal kept) and
/// `g` = 0, so the step leaves it where it is (projected Gauss–Newton, Bertsekas 1982; as
/// [`crate::ik`] does for the same coordinates frame by frame), and the reduced system of the
/// uncertainty analysis treats it as fixed.
pub(crate) fn hold_at_bounds(
    bounds: &[(usize, f64, f64)],
    q: &[f64],
    u: &mut [f64],
    w: &mut [f64],
    g: &mut [f64],
) {
    let nq = q.len();
    for &(a, lo, hi) in bounds {
        if !((q[a] <= lo && g[a] < 0.0) || (q[a] >= hi && g[a] > 0.0)) {
            continue;
        }
        for c in (0..nq).filter(|&c| c != a) {
            u[c * nq + a] = 0.0;
            u[a * nq + c] = 0.0;
        }
        for wk in w.chunks_exact_mut(nq) {
            wk[a] = 0.0;
        }
        g[a] = 0.0;
    }
}

/// [`hold_at_bounds`] on one frame's `[U | W | g]` as [`Blocks`] stores it.
fn hold_split(bounds: &[(usize, f64, f64)], q: &[f64], nf: usize, out: &mut [f64]) {
    let nq = q.len();
    let (u, rest) = out.split_at_mut(nq * nq);
    let (w, g) = rest.split_at_mut(nq * nf);
    hold_at_bounds(bounds, q, u, w, g);
}

impl Blocks {
    /// Room for the blocks of `n_frames` frames within [`CACHE_BYTES`].
    pub(crate) fn new(prob: &Problem) -> Self {
        Self::with_budget(prob, CACHE_BYTES)
    }

    /// As [`Blocks::new`] with a cache of at most `bytes` (0: recompute every frame).
    pub(crate) fn with_budget(prob: &Problem, bytes: usize) -> Self {
        let nq = prob.model.coordinates().len();
        let nf = prob.n_free();
        let frames = prob.frames.len();
        let per = nq * nq + nq * nf + nq;
        let fit = bytes / (8 * per.max(1));
        let chunk = chunk_len(frames);
        let cached = if fit >= frames {
            frames
        } else {
            fit / chunk * chunk
        };
        // The damped factors too when every frame's blocks and factor fit in the budget
        // (short trials); long trials factor again in `back_substitute` (the same numbers).
        let factored = if cached == frames && frames * (per + nq * nq) * 8 <= bytes {
            frames
        } else {
            0
        };
        Blocks {
            nq,
            nf,
            frames,
            chunk,
            cached,
            store: vec![0.0; cached * per],
            factored,
            factors: vec![0.0; factored * nq * nq],
            factors_valid: false,
            v: vec![0.0; nf * nf],
            gs: vec![0.0; nf],
            schur: vec![0.0; nf * nf],
            rhs: vec![0.0; nf],
            cost: 0.0,
            p: Vec::new(),
            half: (0..nf).map(|k| prob.half_range(k)).collect(),
            lambda: 0.0,
            pool: ScratchPool::default(),
            bounds: coordinate_bounds(prob),
        }
    }

    /// The damping of the last reduction (that of the kept factors).
    pub(crate) fn damping(&self) -> f64 {
        self.lambda
    }

    /// Whether a step may keep the curvature of an earlier point ([`assemble_gradient`],
    /// [`reduce_gradient`]): every frame's blocks and damped factors are held, the factors
    /// are those of the last reduction, and no coordinate is bounded (a held coordinate's
    /// blocks depend on its gradient's sign).
    pub(crate) fn can_keep(&self) -> bool {
        self.nq > 0
            && self.cached == self.frames
            && self.factored == self.frames
            && self.factors_valid
            && self.bounds.is_empty()
    }

    fn per(&self) -> usize {
        self.nq * self.nq + self.nq * self.nf + self.nq
    }

    fn chunks(&self) -> usize {
        self.frames.div_ceil(self.chunk)
    }

    fn chunk_frames(&self, c: usize) -> std::ops::Range<usize> {
        c * self.chunk..((c + 1) * self.chunk).min(self.frames)
    }

    /// Frame f's `[U | W | g]`: from the cache, or recomputed at the assembly point (`tb`:
    /// room for the frame's targets).
    fn frame<'a>(
        &'a self,
        prob: &Problem,
        qs: &[Vec<f64>],
        f: usize,
        sc: &'a mut FrameScratch,
        tb: &mut Vec<Vector3<f64>>,
    ) -> &'a [f64] {
        let per = self.per();
        if f < self.cached {
            return &self.store[f * per..(f + 1) * per];
        }
        let targets = prob.frames.fill(f, tb);
        frame_gram(prob, &self.p, &qs[f], targets, &self.half, sc);
        let mut out = std::mem::take(&mut sc.buf);
        out.resize(per, 0.0);
        split(&sc.gram, self.nq, self.nf, &sc.grad, &mut out);
        hold_split(&self.bounds, &qs[f], self.nf, &mut out);
        sc.buf = out;
        &sc.buf
    }
}

/// Copies `U`, `W` and `g` out of a frame's Gram matrix and gradient into `[U | W | g]`.
#[inline(always)]
fn split(gram: &[f64], nq: usize, nf: usize, grad: &[f64], out: &mut [f64]) {
    let n = nq + nf;
    for c in 0..nq {
        out[c * nq..(c + 1) * nq].copy_from_slice(&gram[c * n..c * n + nq]);
    }
    let w = &mut out[nq * nq..nq * nq + nq * nf];
    for k in 0..nf {
        w[k * nq..(k + 1) * nq].copy_from_slice(&gram[(nq + k) * n..(nq + k) * n + nq]);
    }
    out[nq * nq + nq * nf..].copy_from_slice(&grad[..nq]);
}

/// Assembles the normal equations at `(p, qs)`: `V`, `g_s`, the objective, and the cached
/// frames' blocks.
pub(crate) fn assemble(prob: &Problem, p: &[f64], qs: &[Vec<f64>], b: &mut Blocks) {
    let per = b.per();
    b.p = p.to_vec();
    b.factors_valid = false;
    let chunks = b.chunks();
    let chunk = b.chunk;
    let mut slots: Vec<Option<&mut [f64]>> = b.store.chunks_mut(chunk * per).map(Some).collect();
    slots.resize_with(chunks, || None);
    let half = &b.half;
    let pool = &b.pool;
    let bounds = &b.bounds;
    let parts: Vec<(Vec<f64>, Vec<f64>, f64)> = slots
        .into_par_iter()
        .enumerate()
        .map_init(
            || (pool.take(prob), Vec::new()),
            |(sc, tb), (c, slot)| {
                let chunk = AssembleChunk {
                    prob,
                    p,
                    qs,
                    half,
                    bounds,
                    start: c * chunk,
                    end: ((c + 1) * chunk).min(qs.len()),
                    per,
                };
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the processor supports AVX2 (checked just above).
                    return unsafe { chunk.run_avx2(slot, sc, tb) };
                }
                chunk.run(slot, sc, tb)
            },
        )
        .collect();
    b.v.fill(0.0);
    b.gs.fill(0.0);
    b.cost = 0.0;
    for (v, gs, cost) in parts {
        add(&mut b.v, &v);
        add(&mut b.gs, &gs);
        b.cost += cost;
    }
    b.cost += prob.add_prior(p, &mut b.gs, &mut b.v);
}

/// The gradient and objective at `(p, qs)` into `b` with the curvature blocks (`U_i`,
/// `W_i`, `V`) and the damped factors of the last assembly and reduction kept: `g_i` of
/// every frame, `g_s` and the objective, by [`frame_gradient`] (the kinematics and the
/// columns' twists, not the Gram matrix's products). Only where [`Blocks::can_keep`].
pub(crate) fn assemble_gradient(prob: &Problem, p: &[f64], qs: &[Vec<f64>], b: &mut Blocks) {
    debug_assert!(b.can_keep());
    let (per, nq, nf, chunk) = (b.per(), b.nq, b.nf, b.chunk);
    b.p = p.to_vec();
    let half = &b.half;
    let pool = &b.pool;
    let parts: Vec<(Vec<f64>, f64)> = b
        .store
        .par_chunks_mut(chunk * per)
        .enumerate()
        .map_init(
            || (pool.take(prob), Vec::new()),
            |(sc, tb), (c, slot)| {
                let mut gs = vec![0.0; nf];
                let mut cost = 0.0;
                for (i, out) in slot.chunks_exact_mut(per).enumerate() {
                    let f = c * chunk + i;
                    let targets = prob.frames.fill(f, tb);
                    cost += frame_gradient(prob, p, &qs[f], targets, half, sc);
                    out[per - nq..].copy_from_slice(&sc.grad[..nq]);
                    for (g, x) in gs.iter_mut().zip(&sc.grad[nq..nq + nf]) {
                        *g += x;
                    }
                }
                (gs, cost)
            },
        )
        .collect();
    b.gs.fill(0.0);
    b.cost = 0.0;
    for (gs, cost) in parts {
        add(&mut b.gs, &gs);
        b.cost += cost;
    }
    // The prior's gradient at `p`; its curvature, a constant, is in the kept `V`.
    let mut v = vec![0.0; nf * nf];
    b.cost += prob.add_prior(p, &mut b.gs, &mut v);
}

/// One chunk of frames of [`assemble`]: its share of `V`, `g_s` and the objective, and its
/// frames' blocks into `slot` when they are cached.
struct AssembleChunk<'a, 'p> {
    prob: &'a Problem<'p>,
    p: &'a [f64],
    qs: &'a [Vec<f64>],
    half: &'a [f64],
    bounds: &'a [(usize, f64, f64)],
    start: usize,
    end: usize,
    per: usize,
}

impl AssembleChunk<'_, '_> {
    #[inline(always)]
    fn run(
        &self,
        mut slot: Option<&mut [f64]>,
        sc: &mut FrameScratch,
        tb: &mut Vec<Vector3<f64>>,
    ) -> (Vec<f64>, Vec<f64>, f64) {
        let (prob, per, start) = (self.prob, self.per, self.start);
        let nq = prob.model.coordinates().len();
        let nf = self.half.len();
        let n = nq + nf;
        let mut v = vec![0.0; nf * nf];
        let mut gs = vec![0.0; nf];
        let mut cost = 0.0;
        for f in start..self.end {
            let targets = prob.frames.fill(f, tb);
            cost += frame_gram(prob, self.p, &self.qs[f], targets, self.half, sc);
            for l in 0..nf {
                let src = &sc.gram[(nq + l) * n + nq..(nq + l + 1) * n];
                for (x, y) in v[l * nf..(l + 1) * nf].iter_mut().zip(src) {
                    *x += y;
                }
                gs[l] += sc.grad[nq + l];
            }
            if let Some(slot) = slot.as_deref_mut() {
                let out = &mut slot[(f - start) * per..(f - start + 1) * per];
                split(&sc.gram, nq, nf, &sc.grad, out);
                hold_split(self.bounds, &self.qs[f], nf, out);
            }
        }
        (v, gs, cost)
    }

    /// [`Self::run`] compiled for AVX2: the element-wise sums and copies four numbers wide,
    /// the same operations in the same order.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(
        &self,
        slot: Option<&mut [f64]>,
        sc: &mut FrameScratch,
        tb: &mut Vec<Vector3<f64>>,
    ) -> (Vec<f64>, Vec<f64>, f64) {
        self.run(slot, sc, tb)
    }
}

/// `acc += x`, element by element.
fn add(acc: &mut [f64], x: &[f64]) {
    for (a, b) in acc.iter_mut().zip(x) {
        *a += b;
    }
}

/// Parameters at a bound whose descent direction points outward are held for the step.
pub(crate) fn active_bounds(s: &[f64], gs: &[f64]) -> Vec<bool> {
    s.iter()
        .zip(gs)
        .map(|(&s, &g)| (s <= -1.0 && g < 0.0) || (s >= 1.0 && g > 0.0))
        .collect()
}

/// Objective at `(p, qs)` without derivatives (m²), summed over fixed chunks of frames
/// (`b`: the workspaces).
pub(crate) fn cost_at(prob: &Problem, b: &Blocks, p: &[f64], qs: &[Vec<f64>]) -> f64 {
    let parts: Vec<f64> = qs
        .par_chunks(b.chunk)
        .enumerate()
        .map_init(
            || (b.pool.take(prob), Vec::new()),
            |(sc, tb), (c, qs)| {
                let kin = &mut sc.kin;
                let mut total = 0.0;
                for (i, q) in qs.iter().enumerate() {
                    let targets = prob.frames.fill(c * b.chunk + i, tb);
                    forward_kinematics(prob.model, p, q, Want::Positions, kin);
                    for (j, m) in prob.model.markers().iter().enumerate() {
                        if !targets[j].x.is_nan() && m.weight > 0.0 {
                            total += m.weight * (targets[j] - kin.markers[j]).norm_squared();
                        }
                    }
                }
                total
            },
        )
        .collect();
    parts.iter().sum::<f64>() + prob.prior_cost(p)
}

#[path = "schur_step.rs"]
mod step;
pub(crate) use step::{
    back_substitute, frame_share, reduce, reduce_gradient, solve_reduced_at_bounds,
};

/// Every frame's bounded coordinates ([`coordinate_bounds`]) projected into their ranges.
pub(crate) fn project_coords(qs: &mut [Vec<f64>], bounds: &[(usize, f64, f64)]) {
    for q in qs {
        for &(c, lo, hi) in bounds {
            q[c] = q[c].clamp(lo, hi);
        }
    }
}

#[cfg(test)]
#[path = "schur_tests.rs"]
mod tests;
