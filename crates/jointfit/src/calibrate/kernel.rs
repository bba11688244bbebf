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

use super::Problem;
use crate::kinematics::{forward_kinematics, KinData, Want};

/// Per-thread workspace of the kernel; holds the last frame's Gram matrix and gradient.
pub(crate) struct FrameScratch {
    pub kin: KinData,
    rows: Vec<(usize, f64)>,
    jw: Vec<f64>,
    rw: Vec<f64>,
    /// Per column, its first nonzero row and one past its last.
    range: Vec<(usize, usize)>,
    /// The markers in depth-first order of their segments ([`depth_first_markers`]).
    order: Vec<usize>,
    /// Per marker, its weighted residual `√w (m − x)` (NaN: absent or weight 0).
    res: Vec<Vector3<f64>>,
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
    pub fn new(prob: &Problem) -> Self {
        let model = prob.model;
        let n = model.n_q() + prob.n_free();
        let nrows = 3 * model.n_markers();
        FrameScratch {
            kin: KinData::new(model),
            rows: Vec::with_capacity(nrows),
            jw: vec![0.0; n * nrows],
            rw: vec![0.0; nrows],
            range: vec![(0, 0); n],
            order: depth_first_markers(model),
            res: vec![Vector3::zeros(); model.n_markers()],
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
    pub fn take<'a>(&'a self, prob: &Problem) -> Pooled<'a> {
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
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above). The gathers compile to
        // wider moves; the arithmetic is the same in the same order.
        return unsafe { frame_gram_avx2(prob, p, q, targets, half, sc) };
    }
    frame_gram_impl(prob, p, q, targets, half, sc)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn frame_gram_avx2(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    frame_gram_impl(prob, p, q, targets, half, sc)
}

#[inline(always)]
fn frame_gram_impl(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    let model = prob.model;
    let nq = model.n_q();
    let n = nq + prob.n_free();
    let nrows = 3 * model.n_markers();
    forward_kinematics(model, p, q, Want::BOTH, &mut sc.kin);
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
    let jq = sc.kin.jq().as_slice();
    let jp = sc.kin.jp().as_slice();
    for a in 0..n {
        let (src, scale) = if a < nq {
            (&jq[a * nrows..(a + 1) * nrows], 1.0)
        } else {
            let k = a - nq;
            let pi = prob.free[k];
            (&jp[pi * nrows..(pi + 1) * nrows], half[k])
        };
        let col = &mut sc.jw[a * nr..(a + 1) * nr];
        for (x, &(row, sw)) in col.iter_mut().zip(&sc.rows) {
            *x = sw * scale * src[row];
        }
        // The first nonzero row, and the end of the last marker with a nonzero row (`(0, 0)`:
        // none). Whole markers at the end: on a chain every column then reaches the last
        // row, and the sums are those of a dot product to the end.
        let first = col.iter().position(|&x| x != 0.0).unwrap_or(nr);
        let end = col
            .iter()
            .rposition(|&x| x != 0.0)
            .map_or(0, |i| (i / 3 + 1) * 3);
        sc.range[a] = if first < end { (first, end) } else { (0, 0) };
    }
    // G and h by dot products of columns, each over the rows where both columns can be
    // nonzero (the rows outside hold a zero in one of them): the lower triangle column by
    // column, mirrored.
    let (jw, range, rw) = (&sc.jw, &sc.range, &sc.rw[..nr]);
    let gram = &mut sc.gram;
    for b in 0..n {
        let (rb, eb) = range[b];
        let cb = &jw[b * nr..(b + 1) * nr];
        sc.grad[b] = dot(&rw[rb..eb], &cb[rb..eb]);
        gram[b * n + b] = dot(&cb[rb..eb], &cb[rb..eb]);
        for a in b + 1..n {
            let (lo, hi) = (rb.max(range[a].0), eb.min(range[a].1));
            gram[b * n + a] = if lo < hi {
                dot(&cb[lo..hi], &jw[a * nr + lo..a * nr + hi])
            } else {
                0.0
            };
        }
    }
    for b in 0..n {
        for a in b + 1..n {
            gram[a * n + b] = gram[b * n + a];
        }
    }
    cost
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
    let mut order: Vec<usize> = (0..model.n_markers()).collect();
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
mod tests {
    use super::*;
    use crate::calibrate::params_for_groups;
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::model::Model;
    use crate::trial::Trial;
    use nalgebra::DMatrix;

    /// The kernel's `G` and `h` against the dense products `J̃ᵀJ̃`, `J̃ᵀr̃` formed with nalgebra
    /// from the kinematics' Jacobians, with a missing marker and unequal weights.
    #[test]
    fn gram_matches_dense_products() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let p = model.nominal_params();
        let mut q = model.default_coords();
        for (i, v) in q.iter_mut().enumerate() {
            *v += 0.2 * (i as f64 + 1.0).sin();
        }
        let mut kin = KinData::new(&model);
        forward_kinematics(&model, &p, &q, Want::POSITIONS, &mut kin);
        let mut targets: Vec<Vector3<f64>> = kin
            .markers
            .iter()
            .enumerate()
            .map(|(j, x)| x + Vector3::new(0.01, -0.02, 0.015) * ((j as f64) * 0.7).cos())
            .collect();
        targets[3] = Vector3::from_element(f64::NAN);
        let labels = model.markers().iter().map(|m| m.name.clone()).collect();
        let flat: Vec<Vector3<f64>> = targets.clone();
        let trial = Trial::new(labels, 100.0, 1, flat).unwrap();
        let all = params_for_groups(&model, &["all"]).unwrap();
        let prob = Problem::new(&model, p.clone(), &all, &[&trial]).unwrap();
        let half: Vec<f64> = (0..prob.n_free()).map(|k| prob.half_range(k)).collect();
        let mut sc = FrameScratch::new(&prob);
        let cost = frame_gram(&prob, &p, &q, &targets, &half, &mut sc);

        forward_kinematics(&model, &p, &q, Want::BOTH, &mut kin);
        let (nq, nf) = (model.n_q(), prob.n_free());
        let n = nq + nf;
        let rows = 3 * model.n_markers();
        let mut j = DMatrix::zeros(rows, n);
        let mut r = DMatrix::zeros(rows, 1);
        let mut expected_cost = 0.0;
        for (m, mk) in model.markers().iter().enumerate() {
            if targets[m].x.is_nan() {
                continue;
            }
            let sw = mk.weight.sqrt();
            let d = targets[m] - kin.markers[m];
            expected_cost += mk.weight * d.norm_squared();
            for axis in 0..3 {
                let row = 3 * m + axis;
                r[row] = sw * d[axis];
                for a in 0..nq {
                    j[(row, a)] = sw * kin.jq()[(row, a)];
                }
                for k in 0..nf {
                    j[(row, nq + k)] = sw * half[k] * kin.jp()[(row, prob.free[k])];
                }
            }
        }
        let g = j.transpose() * &j;
        let h = j.transpose() * &r;
        assert!((cost - expected_cost).abs() <= 1e-12 * expected_cost);
        let scale = g.amax();
        for a in 0..n {
            assert!((sc.grad[a] - h[a]).abs() <= 1e-12 * h.amax(), "h[{a}]");
            for b in 0..n {
                let got = sc.gram[b * n + a];
                assert!((got - g[(a, b)]).abs() <= 1e-12 * scale, "G[{a},{b}]");
                assert_eq!(got, sc.gram[a * n + b], "symmetric");
            }
        }
    }
}
