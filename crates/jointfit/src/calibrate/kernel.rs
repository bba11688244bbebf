//! The per-frame kernel of the joint normal equations: one frame's weighted Gram matrix.
//!
//! For frame i with weighted Jacobian `J̃ = √W [J_q | J_s]` (the parameter columns scaled by
//! the half-range of each free parameter, see [`super::Problem::half_range`]) and weighted
//! residual `r̃ = √W (m_i − x_i)`, the kernel forms `G = J̃ᵀJ̃` (`n × n`, `n = n_q + n_f`) and
//! `h = J̃ᵀr̃`, whose blocks are `U_i`, `W_i`, `V_i`, `g_i`, `g_s,i` of [`super::schur`].
//!
//! Each column of `J̃` is nonzero only on the rows of the markers its coordinate or parameter
//! moves (a marker moves with its segment's ancestors' joints). The rows are laid out with
//! the markers in depth-first order of their segments, so the markers a joint moves (its
//! child segment's subtree) are consecutive rows, and each entry of `G` and `h` is a dot
//! product over the rows between the later of its two columns' first nonzero rows and the
//! earlier of their last (for a chain, every row from the later first one on; for a tree, e.g.
//! a full-body OpenSim model, none at all between two legs or a leg and an arm): no
//! multiplications by the structural zeros, no copies or reordering of the columns, and a
//! working set (the `J̃` columns and `G`) that stays in the first-level cache.
//! The dot products keep four partial sums (vectorized), added in a fixed order: the same
//! operations run
//! in the same order whatever the thread count.

use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

use nalgebra::Vector3;

use super::kernel_twist::TwistPlan;
use super::Problem;
use crate::kinematics::{forward_kinematics, forward_kinematics_frames, KinData, Want};

/// Per-thread workspace of the kernel; holds the last frame's Gram matrix and gradient.
pub(crate) struct FrameScratch {
    pub kin: KinData,
    /// The twist kernel's plan ([`super::kernel_twist`]); `None`: the tiled kernel below.
    twist: Option<TwistPlan>,
    rows: Vec<(usize, f64)>,
    rw: Vec<f64>,
    /// Per column, its first nonzero row and one past its last.
    range: Vec<(usize, usize)>,
    /// The markers in depth-first order of their segments ([`depth_first_markers`]).
    order: Vec<usize>,
    /// Per marker, its weighted residual `√w (m − x)` (NaN: absent or weight 0).
    res: Vec<Vector3<f64>>,
    /// The column order of `xt`: by first row, then last row descending, then index, for
    /// the ranges of the last frame (`pos`: its inverse).
    perm: Vec<usize>,
    pos: Vec<usize>,
    /// The ranges `perm` was sorted for.
    perm_key: Vec<(usize, usize)>,
    /// The weighted Jacobian row-major in the order `perm`, the weighted residual in column
    /// n (rows × `np`, `np` = n + 1 rounded up to a multiple of 4).
    xt: Vec<f64>,
    np: usize,
    /// `G` (n × n, column-major).
    pub gram: Vec<f64>,
    /// `h = [g; g_s]` (n).
    pub grad: Vec<f64>,
    /// Scratch for the callers' small dense algebra.
    pub buf: Vec<f64>,
    pub fac: Vec<f64>,
    pub vec: Vec<f64>,
}

impl FrameScratch {
    pub(crate) fn new(prob: &Problem) -> Self {
        let mut sc = Self::tiled(prob);
        sc.twist = TwistPlan::new(prob);
        sc
    }

    /// Whether this workspace takes the twist kernel.
    #[cfg(test)]
    pub(crate) fn is_twist(&self) -> bool {
        self.twist.is_some()
    }

    /// A workspace of the tiled kernel, whatever the problem (the twist kernel's fallback,
    /// and its oracle in tests).
    pub(crate) fn tiled(prob: &Problem) -> Self {
        let model = prob.model;
        let n = model.coordinates().len() + prob.n_free();
        let nrows = 3 * model.markers().len();
        FrameScratch {
            kin: KinData::new(model),
            twist: None,
            rows: Vec::with_capacity(nrows),
            rw: vec![0.0; nrows],
            range: vec![(0, 0); n],
            order: depth_first_markers(model),
            perm: (0..n).collect(),
            pos: (0..n).collect(),
            perm_key: Vec::new(),
            xt: vec![0.0; nrows * (n + 1).div_ceil(4) * 4],
            np: (n + 1).div_ceil(4) * 4,
            res: vec![Vector3::zeros(); model.markers().len()],
            gram: vec![0.0; n * n],
            grad: vec![0.0; n],
            buf: Vec::new(),
            fac: Vec::new(),
            vec: Vec::new(),
        }
    }
}

/// Workspaces kept from one parallel pass to the next (one per worker that ran), so that a
/// pass does not build new ones. Which workspace a chunk gets does not matter: the kernel
/// overwrites everything it reads.
#[derive(Default)]
pub(crate) struct ScratchPool(Mutex<Vec<FrameScratch>>);

impl ScratchPool {
    /// A workspace from the pool (or a new one), returned to the pool when dropped.
    pub(crate) fn take<'a>(&'a self, prob: &Problem) -> Pooled<'a> {
        let sc = self
            .0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop()
            .unwrap_or_else(|| FrameScratch::new(prob));
        Pooled {
            pool: self,
            sc: Some(sc),
        }
    }
}

/// A workspace on loan from a [`ScratchPool`].
pub(crate) struct Pooled<'a> {
    pool: &'a ScratchPool,
    sc: Option<FrameScratch>,
}

impl Deref for Pooled<'_> {
    type Target = FrameScratch;
    fn deref(&self) -> &FrameScratch {
        self.sc.as_ref().expect("present until dropped")
    }
}

impl DerefMut for Pooled<'_> {
    fn deref_mut(&mut self) -> &mut FrameScratch {
        self.sc.as_mut().expect("present until dropped")
    }
}

impl Drop for Pooled<'_> {
    fn drop(&mut self) {
        if let Some(sc) = self.sc.take() {
            self.pool
                .0
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(sc);
        }
    }
}

/// Forms frame `targets`' Gram matrix and gradient at `(p, q)` into `sc.gram` and `sc.grad`
/// (scaled parameter units; `half[k]` the half-range of free parameter k) and returns the
/// frame's objective `Σ w_j ‖m_j − x_j‖²` (m²).
pub(crate) fn frame_gram(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    frame_kernel(prob, (p, q), targets, half, sc, true)
}

/// The gradient alone of [`frame_gram`] (into `sc.grad`, the same numbers) and the frame's
/// objective: the kinematics and the columns' twists without the products of the Gram
/// matrix (the whole of [`frame_gram`] where the twist kernel does not serve the problem).
pub(crate) fn frame_gradient(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    frame_kernel(prob, (p, q), targets, half, sc, false)
}

/// [`frame_gram`] (`gram`) or [`frame_gradient`].
fn frame_kernel(
    prob: &Problem,
    at: (&[f64], &[f64]),
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
    gram: bool,
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above). The gathers compile to
        // wider moves; the arithmetic is the same in the same order.
        return unsafe { frame_kernel_avx2(prob, at, targets, half, sc, gram) };
    }
    frame_kernel_impl(prob, at, targets, half, sc, gram)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn frame_kernel_avx2(
    prob: &Problem,
    at: (&[f64], &[f64]),
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
    gram: bool,
) -> f64 {
    frame_kernel_impl(prob, at, targets, half, sc, gram)
}

#[inline(always)]
fn frame_kernel_impl(
    prob: &Problem,
    (p, q): (&[f64], &[f64]),
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
    gram: bool,
) -> f64 {
    if let Some(plan) = &mut sc.twist {
        forward_kinematics_frames(prob.model, p, q, &mut sc.kin);
        if gram {
            plan.gram(prob, &sc.kin, targets, half, &mut sc.gram, &mut sc.grad);
        } else {
            plan.gradient(prob, &sc.kin, targets, half, &mut sc.grad);
        }
        return frame_cost(prob, &sc.kin, targets);
    }
    frame_gram_tiled(prob, p, q, targets, half, sc)
}

/// [`frame_gram`] by the tiled kernel (where the twist kernel does not serve the problem).
#[inline(always)]
fn frame_gram_tiled(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    let model = prob.model;
    let nq = model.coordinates().len();
    let n = nq + prob.n_free();
    let nrows = 3 * model.markers().len();
    forward_kinematics(model, p, q, Want::DqDp, &mut sc.kin);
    let mut cost = 0.0;
    for (j, m) in model.markers().iter().enumerate() {
        let t = targets[j];
        if t.x.is_nan() || m.weight <= 0.0 {
            sc.res[j].x = f64::NAN;
            continue;
        }
        let r = t - sc.kin.markers[j];
        cost += m.weight * r.norm_squared();
        sc.res[j] = r;
    }
    // Rows: (model row 3j + axis, √w_j) of the present markers, in depth-first order of
    // their segments, so that the rows a coordinate or parameter moves are contiguous.
    sc.rows.clear();
    for &j in &sc.order {
        let r = sc.res[j];
        if r.x.is_nan() {
            continue;
        }
        let sw = model.markers()[j].weight.sqrt();
        for axis in 0..3 {
            sc.rw[sc.rows.len()] = sw * r[axis];
            sc.rows.push((3 * j + axis, sw));
        }
    }
    let nr = sc.rows.len();
    let np = sc.np;
    let jq = sc.kin.jq.as_slice();
    let jp = sc.kin.jp.as_slice();
    let xt = &mut sc.xt[..nr * np];
    for a in 0..n {
        let (src, scale) = if a < nq {
            (&jq[a * nrows..(a + 1) * nrows], 1.0)
        } else {
            let k = a - nq;
            let pi = prob.free[k];
            (&jp[pi * nrows..(pi + 1) * nrows], half[k])
        };
        // Column a of J̃ into its place in `xt`, with its first nonzero row and the end of
        // the last marker with a nonzero row (`(0, 0)`: none). Whole markers at the end: on a
        // chain every column then reaches the last row, and the sums are those of a dot
        // product to the end.
        let k = sc.pos[a];
        let (mut first, mut last) = (usize::MAX, 0);
        for (i, &(row, sw)) in sc.rows.iter().enumerate() {
            let x = sw * scale * src[row];
            xt[i * np + k] = x;
            // x ≠ 0 (NaN included), without branches.
            let nonzero = x.to_bits() << 1 != 0;
            first = first.min(if nonzero { i } else { usize::MAX });
            last = if nonzero { i } else { last };
        }
        let end = if first == usize::MAX {
            0
        } else {
            (last / 3 + 1) * 3
        };
        sc.range[a] = if first < end { (first, end) } else { (0, 0) };
    }
    // The weighted residual as column n.
    for (i, &x) in sc.rw[..nr].iter().enumerate() {
        xt[i * np + n] = x;
    }
    let xt = &sc.xt[..nr * np];
    gram_tiles(n, np, &sc.perm, &sc.range, xt, &mut sc.gram, &mut sc.grad);
    // The next frame's column order, when the ranges changed (the order does not change the
    // sums, only how many of them run as tiles).
    if sc.perm_key != sc.range {
        sc.perm_key.clone_from(&sc.range);
        let range = &sc.range;
        sc.perm
            .sort_by_key(|&a| (range[a].0, std::cmp::Reverse(range[a].1), a));
        for (k, &a) in sc.perm.iter().enumerate() {
            sc.pos[a] = k;
        }
    }
    cost
}

/// The frame's objective `Σ w_j ‖m_j − x_j‖²` over its present markers, in model order.
fn frame_cost(prob: &Problem, kin: &KinData, targets: &[Vector3<f64>]) -> f64 {
    let mut cost = 0.0;
    for (j, m) in prob.model.markers().iter().enumerate() {
        let t = targets[j];
        if !t.x.is_nan() && m.weight > 0.0 {
            cost += m.weight * (t - kin.markers[j]).norm_squared();
        }
    }
    cost
}

/// `G` (both triangles) and `h` from the row-major copy `xt` of `J̃` (columns in the order
/// `perm`, the weighted residual in column n). Entry `(a, b)` of `G`, `a` not after `b` in
/// that order, is the dot product of the two columns over the rows where both can be
/// nonzero, `[max first, min end)`. When `a`'s range contains `b`'s (always on a chain, where
/// the columns are ordered by first row), that is `b`'s own range, the same for four
/// consecutive `a`: one [`tile`]; otherwise [`dot_rows`]. Entry `b` of `h` is the residual's
/// product with column b over b's range: a tile for four columns with the same range. The
/// sums are those of [`dot`] over the same rows either way, bit for bit, whatever `perm`.
#[inline(always)]
fn gram_tiles(
    n: usize,
    np: usize,
    perm: &[usize],
    range: &[(usize, usize)],
    xt: &[f64],
    gram: &mut [f64],
    grad: &mut [f64],
) {
    for pb in 0..n {
        let b = perm[pb];
        let (sb, eb) = range[b];
        let mut t = 0;
        while t <= pb {
            let lanes = (pb + 1 - t).min(4);
            let contains = perm[t..t + lanes].iter().all(|&a| {
                let (sa, ea) = range[a];
                sa <= sb && ea >= eb
            });
            if contains {
                let v = tile(xt, np, t, pb, sb, eb);
                for (l, &a) in perm[t..t + lanes].iter().enumerate() {
                    gram[b * n + a] = v[l];
                    gram[a * n + b] = v[l];
                }
            } else {
                for (l, &a) in perm[t..t + lanes].iter().enumerate() {
                    let (lo, hi) = (sb.max(range[a].0), eb.min(range[a].1));
                    let v = if lo < hi {
                        dot_rows(xt, np, t + l, pb, lo, hi)
                    } else {
                        0.0
                    };
                    gram[b * n + a] = v;
                    gram[a * n + b] = v;
                }
            }
            t += 4;
        }
    }
    let mut t = 0;
    while t < n {
        let lanes = (n - t).min(4);
        let r0 = range[perm[t]];
        if perm[t..t + lanes].iter().all(|&a| range[a] == r0) {
            let v = tile(xt, np, t, n, r0.0, r0.1);
            for (l, &a) in perm[t..t + lanes].iter().enumerate() {
                grad[a] = v[l];
            }
        } else {
            for (l, &a) in perm[t..t + lanes].iter().enumerate() {
                let (lo, hi) = range[a];
                grad[a] = dot_rows(xt, np, t + l, n, lo, hi);
            }
        }
        t += 4;
    }
}

/// The dot products of columns `t..t + 4` of `xt` (row-major, `np` wide) with its column `b`
/// over rows `lo..hi`, each summed as [`dot`] sums: four partial sums over the rows
/// `lo + 4k + i`, added `(s0 + s1) + (s2 + s3)`, then the last `(hi − lo) mod 4` rows in
/// order. The four columns are the lanes, so the four partial sums are independent chains.
#[inline(always)]
fn tile(xt: &[f64], np: usize, t: usize, b: usize, lo: usize, hi: usize) -> [f64; 4] {
    assert!(t + 4 <= np && b < np && lo <= hi && hi * np <= xt.len());
    let mut acc = [[0.0f64; 4]; 4];
    let full = lo + (hi - lo) / 4 * 4;
    // SAFETY: every row read, `lo..hi`, lies within `xt` (asserted above), and within a row
    // the reads are columns `t..t + 4` and `b`, all below `np`.
    unsafe {
        let mut row = xt.as_ptr().add(lo * np);
        for _ in 0..(full - lo) / 4 {
            for (p, acc) in acc.iter_mut().enumerate() {
                let r = row.add(p * np);
                let y = *r.add(b);
                for (l, a) in acc.iter_mut().enumerate() {
                    *a += *r.add(t + l) * y;
                }
            }
            row = row.add(4 * np);
        }
        let mut out = [0.0; 4];
        let mut tail = [0.0f64; 4];
        for _ in full..hi {
            let y = *row.add(b);
            for (l, a) in tail.iter_mut().enumerate() {
                *a += *row.add(t + l) * y;
            }
            row = row.add(np);
        }
        for l in 0..4 {
            out[l] = ((acc[0][l] + acc[1][l]) + (acc[2][l] + acc[3][l])) + tail[l];
        }
        out
    }
}

/// [`dot`] of columns `a` and `b` of `xt` (row-major, `np` wide) over rows `lo..hi`: the same
/// sums in the same order.
fn dot_rows(xt: &[f64], np: usize, a: usize, b: usize, lo: usize, hi: usize) -> f64 {
    let mut acc = [0.0f64; 4];
    let full = lo + (hi - lo) / 4 * 4;
    for quad in xt[lo * np..full * np].chunks_exact(4 * np) {
        for (p, acc) in acc.iter_mut().enumerate() {
            *acc += quad[p * np + a] * quad[p * np + b];
        }
    }
    let mut tail = 0.0;
    for row in xt[full * np..hi * np].chunks_exact(np) {
        tail += row[a] * row[b];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The markers of `model` ordered by the depth-first (preorder) position of their segments,
/// ties in model order: the markers a joint moves (its child segment's subtree) are then
/// consecutive.
fn depth_first_markers(model: &crate::model::Model) -> Vec<usize> {
    let segments = model.segments();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); segments.len()];
    let mut stack = Vec::new();
    for (i, s) in segments.iter().enumerate().rev() {
        match s.parent {
            Some(parent) => children[parent.0].push(i),
            None => stack.push(i),
        }
    }
    // Children were pushed in reverse index order, so popping visits them in index order.
    let mut position = vec![0; segments.len()];
    let mut next = 0;
    while let Some(i) = stack.pop() {
        position[i] = next;
        next += 1;
        stack.extend(children[i].iter().copied());
    }
    let mut order: Vec<usize> = (0..model.markers().len()).collect();
    order.sort_by_key(|&j| position[model.markers()[j].segment.0]);
    order
}

/// `Σ a_i b_i` with four independent partial sums, added in a fixed order.
#[inline(always)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

#[cfg(test)]
#[path = "kernel_tests.rs"]
mod tests;
