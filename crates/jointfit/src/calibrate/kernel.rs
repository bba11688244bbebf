//! The per-frame kernel of the joint normal equations: one frame's weighted Gram matrix.
//!
//! For frame i with weighted Jacobian `J̃ = √W [J_q | J_s]` (the parameter columns scaled by
//! the half-range of each free parameter, see [`super::Problem::half_range`]) and weighted
//! residual `r̃ = √W (m_i − x_i)`, the kernel forms `G = J̃ᵀJ̃` (`n × n`, `n = n_q + n_f`) and
//! `h = J̃ᵀr̃`, whose blocks are `U_i`, `W_i`, `V_i`, `g_i`, `g_s,i` of [`super::schur`].
//!
//! Each column of `J̃` is nonzero only on the rows of the markers its coordinate or parameter
//! moves, so every Gram entry is a dot product over the overlap of two columns' nonzero row
//! ranges. The dot products run with four independent partial sums in a fixed order; on x86-64
//! processors with AVX2 the same code is compiled for 256-bit registers and chosen at run time
//! (the same operations in the same order, so the results are identical bit for bit).

use nalgebra::Vector3;

use super::Problem;
use crate::kinematics::{forward_kinematics, KinData, Want};

/// Which blocks of the Gram matrix to form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Part {
    /// `U`, `W`, `V`, `g`, `g_s`: everything.
    All,
    /// `U`, `W`, `g` only (what the Schur elimination of a frame needs).
    Coordinates,
}

/// Per-thread workspace of the kernel; holds the last frame's Gram matrix and gradient.
pub(crate) struct FrameScratch {
    pub kin: KinData,
    rows: Vec<(usize, f64)>,
    jw: Vec<f64>,
    rw: Vec<f64>,
    range: Vec<(usize, usize)>,
    /// `G` (n × n, column-major). With [`Part::Coordinates`] the `V` block is stale.
    pub gram: Vec<f64>,
    /// `h = [g; g_s]` (n). With [`Part::Coordinates`] the `g_s` part is stale.
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
            gram: vec![0.0; n * n],
            grad: vec![0.0; n],
            buf: Vec::new(),
            fac: Vec::new(),
            vec: Vec::new(),
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
    part: Part,
    sc: &mut FrameScratch,
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { frame_gram_avx2(prob, p, q, targets, half, part, sc) };
    }
    frame_gram_impl(prob, p, q, targets, half, part, sc)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn frame_gram_avx2(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    part: Part,
    sc: &mut FrameScratch,
) -> f64 {
    frame_gram_impl(prob, p, q, targets, half, part, sc)
}

#[inline(always)]
fn frame_gram_impl(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    part: Part,
    sc: &mut FrameScratch,
) -> f64 {
    let model = prob.model;
    let nq = model.n_q();
    let n = nq + prob.n_free();
    let nrows = 3 * model.n_markers();
    forward_kinematics(model, p, q, Want::BOTH, &mut sc.kin);
    // Rows: (model row 3j + axis, √w_j) of the present markers.
    sc.rows.clear();
    let mut cost = 0.0;
    for (j, m) in model.markers.iter().enumerate() {
        let t = targets[j];
        if t.x.is_nan() || m.weight <= 0.0 {
            continue;
        }
        let r = t - sc.kin.markers[j];
        cost += m.weight * r.norm_squared();
        let sw = m.weight.sqrt();
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
        let lo = col.iter().position(|&x| x != 0.0).unwrap_or(nr);
        let hi = col.iter().rposition(|&x| x != 0.0).map_or(lo, |i| i + 1);
        sc.range[a] = (lo, hi.max(lo));
    }
    let rw = &sc.rw[..nr];
    let jw = &sc.jw;
    let range = &sc.range;
    let gram = &mut sc.gram;
    let top = match part {
        Part::All => n,
        Part::Coordinates => nq,
    };
    for a in 0..n {
        let (lo_a, hi_a) = range[a];
        let col_a = &jw[a * nr..(a + 1) * nr];
        if a < top {
            sc.grad[a] = dot(&col_a[lo_a..hi_a], &rw[lo_a..hi_a]);
        }
        // Part::Coordinates: U (c ≤ a < n_q) and W (c < n_q ≤ a), not V.
        let last = if part == Part::All { a } else { a.min(nq - 1) };
        for c in 0..=last {
            let lo = lo_a.max(range[c].0);
            let hi = hi_a.min(range[c].1);
            let value = if lo < hi {
                dot(&col_a[lo..hi], &jw[c * nr + lo..c * nr + hi])
            } else {
                0.0
            };
            gram[c * n + a] = value;
            gram[a * n + c] = value;
        }
    }
    cost
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
