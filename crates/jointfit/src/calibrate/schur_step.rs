//! The damped step of the block-arrow system ([`super`]'s module docs): the Schur reduction
//! `S = V* − Σ W_iᵀ U_i*⁻¹ W_i`, its solve in the parameters, and the back substitution for
//! every frame's coordinates.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::kernel::{dot, FrameScratch};
use super::super::Problem;
use super::{add, Blocks};
use crate::linalg::{cholesky_in_place, cholesky_solve, Cholesky};

/// Solves `L Y = B` in place for `B` (`n × m`, row-major): row by row, `y_i = (b_i −
/// Σ_{k<i} l_ik y_k) / l_ii`, each subtraction an operation on contiguous numbers, in the
/// order k = 0, 1, …, i − 1 for every entry. The row is taken 16, 8 and 4 numbers at a time,
/// each piece kept in registers while the products of every earlier row are subtracted (the
/// same subtractions, in the same order, as over the whole width at once).
#[inline(always)]
fn forward_solve_rows(l: &[f64], n: usize, m: usize, b: &mut [f64]) {
    assert!(l.len() >= n * n && b.len() >= n * m);
    for i in 0..n {
        let (done, rest) = b.split_at_mut(i * m);
        let row = &mut rest[..m];
        // Row i of L left of the diagonal: l_ik for k = 0, …, i − 1.
        let li = || l[i..].iter().step_by(n).take(i).copied();
        let mut start = 0;
        while start + 16 <= m {
            subtract_rows::<16>(li(), done, m, start, row);
            start += 16;
        }
        if start + 8 <= m {
            subtract_rows::<8>(li(), done, m, start, row);
            start += 8;
        }
        if start + 4 <= m {
            subtract_rows::<4>(li(), done, m, start, row);
            start += 4;
        }
        if start < m {
            for (yk, lik) in done.chunks_exact(m).zip(li()) {
                for (x, y) in row[start..].iter_mut().zip(&yk[start..]) {
                    *x -= lik * y;
                }
            }
        }
        let d = 1.0 / l[i * n + i];
        for x in row.iter_mut() {
            *x *= d;
        }
    }
}

/// `row[start..start + W] −= l_ik · y_k[start..start + W]` for k = 0, 1, … in order (`li`:
/// the l_ik; `done`: the rows `y_k`, m numbers each), the W numbers held in a local
/// (registers) throughout.
#[inline(always)]
fn subtract_rows<const W: usize>(
    li: impl Iterator<Item = f64>,
    done: &[f64],
    m: usize,
    start: usize,
    row: &mut [f64],
) {
    assert!(start + W <= m && row.len() == m);
    let mut acc: [f64; W] = row[start..start + W].try_into().expect("W numbers");
    for (yk, lik) in done.chunks_exact(m).zip(li) {
        let y: &[f64; W] = yk[start..start + W].try_into().expect("W numbers");
        for (x, y) in acc.iter_mut().zip(y) {
            *x -= lik * y;
        }
    }
    row[start..start + W].copy_from_slice(&acc);
}

/// `U* = U + λ diag(U) + ε` factored in place into `l` (`ε` a tiny ridge relative to the
/// largest diagonal). False when not positive definite.
fn factor_damped(u: &[f64], nq: usize, lambda: f64, l: &mut Vec<f64>) -> bool {
    l.clear();
    l.extend_from_slice(u);
    let max_diag = (0..nq).fold(0.0f64, |m, i| m.max(u[i * nq + i]));
    for i in 0..nq {
        l[i * nq + i] += lambda * u[i * nq + i] + 1e-14 * max_diag + 1e-300;
    }
    cholesky_in_place(l, nq)
}

/// Damped step on the parameters: fills `ds` (n_f). `fixed[k]` pins parameter k (`δs_k = 0`).
/// `qs` are the coordinates of the last [`assemble`]. Returns false when a system is not
/// positive definite at this damping. [`back_substitute`] then gives the coordinate steps.
#[cfg(test)]
pub(crate) fn solve(
    prob: &Problem,
    qs: &[Vec<f64>],
    b: &mut Blocks,
    lambda: f64,
    fixed: &[bool],
    ds: &mut [f64],
) -> bool {
    reduce(prob, qs, b, lambda) && solve_reduced(b, None, fixed, ds)
}

/// The reduced system at damping `lambda`: `S = V* − Σ W_iᵀ U_i*⁻¹ W_i` into
/// [`Blocks::schur`] and `g_s − Σ W_iᵀ U_i*⁻¹ g_i` into [`Blocks::rhs`] (at λ = 0 the
/// Gauss–Newton reduced normal matrix and the reduced gradient, as a half negative gradient
/// of the objective with the coordinates at their linearized optimum). False when a frame's
/// `U_i*` is not positive definite. [`back_substitute`] then uses this damping.
pub(crate) fn reduce(prob: &Problem, qs: &[Vec<f64>], b: &mut Blocks, lambda: f64) -> bool {
    let (nq, nf) = (b.nq, b.nf);
    b.factors_valid = false;
    let mut factors = std::mem::take(&mut b.factors);
    let mut slots: Vec<Option<&mut [f64]>> = factors
        .chunks_mut((b.chunk * nq * nq).max(1))
        .map(Some)
        .collect();
    slots.resize_with(b.chunks(), || None);
    let blocks = &*b;
    let m = nf + 1;
    let parts: Vec<Option<Vec<f64>>> = slots
        .into_par_iter()
        .enumerate()
        .map_init(
            || (blocks.pool.take(prob), Vec::new()),
            |(sc, tb), (c, slot)| {
                let chunk = ReduceChunk {
                    prob,
                    qs,
                    blocks,
                    lambda,
                    c,
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
    b.factors = factors;
    let mut s = b.v.clone();
    for k in 0..nf {
        s[k * nf + k] *= 1.0 + lambda;
    }
    let mut rhs = b.gs.clone();
    let mut zz = vec![0.0; m * m];
    for part in parts {
        let Some(part) = part else {
            return false;
        };
        add(&mut zz, &part);
    }
    // The lower triangle, mirrored (the product's two triangles may differ in the last bit).
    for k in 0..nf {
        rhs[k] -= zz[nf * m + k];
        for c in 0..=k {
            s[c * nf + k] -= zz[c * m + k];
            if c != k {
                s[k * nf + c] -= zz[c * m + k];
            }
        }
    }
    b.schur = s;
    b.rhs = rhs;
    b.lambda = lambda;
    b.factors_valid = true;
    true
}

/// The reduced right-hand side `g_s − Σ W_iᵀ U_i*⁻¹ g_i` into [`Blocks::rhs`] from the
/// gradient of [`super::assemble_gradient`] and the kept blocks and damped factors of the
/// last [`reduce`] (its `S` and damping stay): the step of the kept curvature at the new
/// point. Only where [`Blocks::can_keep`].
pub(crate) fn reduce_gradient(b: &mut Blocks) {
    debug_assert!(b.can_keep());
    let (nq, nf, per) = (b.nq, b.nf, b.per());
    let blocks = &*b;
    let parts: Vec<Vec<f64>> = (0..b.chunks())
        .into_par_iter()
        .map(|c| {
            let mut acc = vec![0.0; nf];
            let mut x = vec![0.0; nq];
            for f in blocks.chunk_frames(c) {
                let blk = &blocks.store[f * per..(f + 1) * per];
                let (w, g) = blk[nq * nq..].split_at(nq * nf);
                x.copy_from_slice(g);
                cholesky_solve(&blocks.factors[f * nq * nq..(f + 1) * nq * nq], nq, &mut x);
                for (a, wk) in acc.iter_mut().zip(w.chunks_exact(nq)) {
                    *a += dot(wk, &x);
                }
            }
            acc
        })
        .collect();
    let mut rhs = b.gs.clone();
    let mut sum = vec![0.0; nf];
    for part in parts {
        add(&mut sum, &part);
    }
    for (r, s) in rhs.iter_mut().zip(&sum) {
        *r -= s;
    }
    b.rhs = rhs;
}

/// One chunk of frames of [`reduce`]: its frames' factors (into `slot` when the factors are
/// kept) and its share `[Z | y]ᵀ[Z | y]` of the reduction (`None`: a `U_i*` is not positive
/// definite).
struct ReduceChunk<'a, 'p> {
    prob: &'a Problem<'p>,
    qs: &'a [Vec<f64>],
    blocks: &'a Blocks,
    lambda: f64,
    c: usize,
}

impl ReduceChunk<'_, '_> {
    #[inline(always)]
    fn run(
        &self,
        mut slot: Option<&mut [f64]>,
        sc: &mut FrameScratch,
        tb: &mut Vec<Vector3<f64>>,
    ) -> Option<Vec<f64>> {
        let (blocks, lambda) = (self.blocks, self.lambda);
        let (nq, nf) = (blocks.nq, blocks.nf);
        let m = nf + 1;
        let range = blocks.chunk_frames(self.c);
        let mut l = std::mem::take(&mut sc.fac);
        // The chunk's Z_i = L_i⁻¹ [W_i | g_i] stacked: (frames·n_q) × (n_f + 1), row-major,
        // so that the substitution runs along contiguous rows. Every entry is written below,
        // so the buffer's old contents need no clearing.
        let mut z = std::mem::take(&mut sc.vec);
        z.resize(range.len() * nq * m, 0.0);
        for (i, f) in range.clone().enumerate() {
            let blk = blocks.frame(self.prob, self.qs, f, sc, tb);
            let (u, rest) = blk.split_at(nq * nq);
            let (w, g) = rest.split_at(nq * nf);
            if !factor_damped(u, nq, lambda, &mut l) {
                sc.fac = l;
                sc.vec = z;
                return None;
            }
            let zf = &mut z[i * nq * m..(i + 1) * nq * m];
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor supports AVX2 (checked just above).
                unsafe { fill_rows_avx2(w, g, nq, zf) };
            } else {
                fill_rows(w, g, nq, zf);
            }
            #[cfg(not(target_arch = "x86_64"))]
            fill_rows(w, g, nq, zf);
            forward_solve_rows(&l, nq, m, zf);
            if let Some(slot) = slot.as_deref_mut() {
                slot[i * nq * nq..(i + 1) * nq * nq].copy_from_slice(&l[..nq * nq]);
            }
        }
        // With U* = L Lᵀ: Wᵀ U*⁻¹ W = ZᵀZ and Wᵀ U*⁻¹ g = Zᵀy, so the chunk's share of both is
        // one product [Z | y]ᵀ[Z | y] ((n_f + 1) × (n_f + 1), column-major).
        let zz = gram_of_rows(&z, range.len() * nq, m);
        sc.fac = l;
        sc.vec = z;
        Some(zz)
    }

    /// [`Self::run`] compiled for AVX2: the element-wise row updates four numbers wide, the
    /// same operations in the same order.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(
        &self,
        slot: Option<&mut [f64]>,
        sc: &mut FrameScratch,
        tb: &mut Vec<Vector3<f64>>,
    ) -> Option<Vec<f64>> {
        self.run(slot, sc, tb)
    }
}

/// `[W | g]` row by row into `zf` (`n_q` rows of `m = n_f + 1` numbers): row a is
/// `(W_{a,0}, …, W_{a,n_f−1}, g_a)`, W stored parameter-major (`w[k·n_q + a]`).
#[inline(always)]
fn fill_rows(w: &[f64], g: &[f64], nq: usize, zf: &mut [f64]) {
    let m = zf.len() / nq.max(1);
    for (k, wk) in w.chunks_exact(nq).enumerate() {
        for (row, &x) in zf.chunks_exact_mut(m).zip(wk) {
            row[k] = x;
        }
    }
    for (row, &x) in zf.chunks_exact_mut(m).zip(g) {
        row[m - 1] = x;
    }
}

/// [`fill_rows`] by 4 × 4 blocks transposed in registers (the same numbers copied).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_rows_avx2(w: &[f64], g: &[f64], nq: usize, zf: &mut [f64]) {
    use std::arch::x86_64::*;
    let m = zf.len() / nq.max(1);
    let nf = m - 1;
    assert!(w.len() >= nq * nf && g.len() >= nq && zf.len() >= nq * m);
    let (a4, k4) = (nq / 4 * 4, nf / 4 * 4);
    let (wp, zp) = (w.as_ptr(), zf.as_mut_ptr());
    // SAFETY: every block's rows a0..a0 + 4 ≤ n_q and columns k0..k0 + 4 ≤ n_f are inside
    // `w` and `zf` (asserted above).
    unsafe {
        for a0 in (0..a4).step_by(4) {
            for k0 in (0..k4).step_by(4) {
                let r0 = _mm256_loadu_pd(wp.add(k0 * nq + a0));
                let r1 = _mm256_loadu_pd(wp.add((k0 + 1) * nq + a0));
                let r2 = _mm256_loadu_pd(wp.add((k0 + 2) * nq + a0));
                let r3 = _mm256_loadu_pd(wp.add((k0 + 3) * nq + a0));
                let t0 = _mm256_unpacklo_pd(r0, r1);
                let t1 = _mm256_unpackhi_pd(r0, r1);
                let t2 = _mm256_unpacklo_pd(r2, r3);
                let t3 = _mm256_unpackhi_pd(r2, r3);
                _mm256_storeu_pd(zp.add(a0 * m + k0), _mm256_permute2f128_pd(t0, t2, 0x20));
                _mm256_storeu_pd(
                    zp.add((a0 + 1) * m + k0),
                    _mm256_permute2f128_pd(t1, t3, 0x20),
                );
                _mm256_storeu_pd(
                    zp.add((a0 + 2) * m + k0),
                    _mm256_permute2f128_pd(t0, t2, 0x31),
                );
                _mm256_storeu_pd(
                    zp.add((a0 + 3) * m + k0),
                    _mm256_permute2f128_pd(t1, t3, 0x31),
                );
            }
        }
    }
    for (a, row) in zf.chunks_exact_mut(m).enumerate().take(nq) {
        let from = if a < a4 { k4 } else { 0 };
        for (k, x) in row.iter_mut().enumerate().take(nf).skip(from) {
            *x = w[k * nq + a];
        }
        row[nf] = g[a];
    }
}

/// One frame's `[W | g]ᵀ U⁻¹ [W | g]` ((n_f + 1) × (n_f + 1), column-major) from the
/// Cholesky factor `l` of its `U` (`n_q × n_q`; `w` parameter-major as [`super::Blocks`]
/// stores it): [`reduce`]'s share of a single frame at λ = 0, by the same row kernels (the
/// uncertainty analysis keeps every frame's share). `z`: room for the frame's rows.
pub(crate) fn frame_share(
    l: &[f64],
    w: &[f64],
    g: &[f64],
    (nq, nf): (usize, usize),
    z: &mut Vec<f64>,
) -> Vec<f64> {
    if nq == 0 {
        // No coordinates: nothing to eliminate.
        return vec![0.0; (nf + 1) * (nf + 1)];
    }
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { frame_share_avx2(l, w, g, nq, z) };
    }
    frame_share_rows(l, w, g, nq, z)
}

#[inline(always)]
fn frame_share_rows(l: &[f64], w: &[f64], g: &[f64], nq: usize, z: &mut Vec<f64>) -> Vec<f64> {
    let m = w.len() / nq.max(1) + 1;
    z.resize(nq * m, 0.0);
    fill_rows(w, g, nq, z);
    forward_solve_rows(l, nq, m, z);
    gram_of_rows(z, nq, m)
}

/// [`frame_share_rows`] compiled for AVX2: the same operations in the same order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn frame_share_avx2(
    l: &[f64],
    w: &[f64],
    g: &[f64],
    nq: usize,
    z: &mut Vec<f64>,
) -> Vec<f64> {
    let m = w.len() / nq.max(1) + 1;
    z.resize(nq * m, 0.0);
    // SAFETY: the caller checked AVX2.
    unsafe { fill_rows_avx2(w, g, nq, z) };
    forward_solve_rows(l, nq, m, z);
    gram_of_rows(z, nq, m)
}

/// `ZᵀZ` (m × m, column-major) of the row-major `rows × m` matrix `z`.
fn gram_of_rows(z: &[f64], rows: usize, m: usize) -> Vec<f64> {
    assert!(z.len() >= rows * m, "z holds rows × m values");
    let mut zz = vec![0.0; m * m];
    // SAFETY: A = Zᵀ (m × rows) and B = Z (rows × m) read z (rows·m, checked above) with
    // strides (1, m) and (m, 1); C (m × m, column-major) is zz.
    unsafe {
        matrixmultiply::dgemm(
            m,
            rows,
            m,
            1.0,
            z.as_ptr(),
            1,
            m as isize,
            z.as_ptr(),
            m as isize,
            1,
            0.0,
            zz.as_mut_ptr(),
            1,
            m as isize,
        );
    }
    zz
}

/// Solves the system of the last [`reduce`], plus `extra` (n_f × n_f, column-major: a model
/// term of the parameters' block: the joint solver's secant correction) when given, for `ds`; `fixed[k]` pins
/// parameter k. False when the matrix is not positive definite.
pub(crate) fn solve_reduced(
    b: &Blocks,
    extra: Option<&[f64]>,
    fixed: &[bool],
    ds: &mut [f64],
) -> bool {
    let nf = b.nf;
    let mut s = b.schur.clone();
    let mut rhs = b.rhs.clone();
    if let Some(a) = extra {
        add(&mut s, a);
    }
    for k in 0..nf {
        if fixed[k] {
            for c in 0..nf {
                s[c * nf + k] = 0.0;
                s[k * nf + c] = 0.0;
            }
            s[k * nf + k] = 1.0;
            rhs[k] = 0.0;
        }
    }
    let max_diag = (0..nf).fold(0.0f64, |m, i| m.max(s[i * nf + i]));
    for k in 0..nf {
        s[k * nf + k] += 1e-14 * max_diag + 1e-300;
    }
    let Some(chol) = Cholesky::factor(&mut s, nf) else {
        return false;
    };
    ds.copy_from_slice(&rhs);
    chol.solve(ds);
    true
}

/// `δq_i = U_i*⁻¹ (g_i − W_i δs)` for a given (possibly clamped) `δs`, at the damping of the
/// last [`solve`]. Returns the decrease of the objective that the linearized model predicts
/// for the step `(δq, δs)`: `2 hᵀδ − δᵀ H δ` with `H = JᵀWJ` (undamped) and `h = JᵀWr` in
/// block form (the objective is `Σ w‖r‖²`); the ratio of actual to predicted decrease drives
/// the damping.
pub(crate) fn back_substitute(
    prob: &Problem,
    qs: &[Vec<f64>],
    b: &Blocks,
    ds: &[f64],
    dq: &mut [Vec<f64>],
) -> f64 {
    let nf = b.nf;
    let parts: Vec<f64> = dq
        .par_chunks_mut(b.chunk)
        .enumerate()
        .map_init(
            || (b.pool.take(prob), Vec::new()),
            |(sc, tb), (c, dq)| {
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the processor supports AVX2 (checked just above).
                    return unsafe { back_substitute_chunk_avx2(prob, qs, b, ds, c, dq, sc, tb) };
                }
                back_substitute_chunk(prob, qs, b, ds, c, dq, sc, tb)
            },
        )
        .collect();
    let mut quad = 0.0;
    for k in 0..nf {
        quad += ds[k] * dot(&b.v[k * nf..(k + 1) * nf], ds);
    }
    parts.iter().sum::<f64>() + 2.0 * dot(&b.gs, ds) - quad
}

/// The coordinate steps of chunk `c`'s frames into `dq` ([`back_substitute`]) and their
/// share of the predicted decrease.
#[allow(clippy::too_many_arguments)] // the pass's inputs and the chunk's workspaces
#[inline(always)]
fn back_substitute_chunk(
    prob: &Problem,
    qs: &[Vec<f64>],
    b: &Blocks,
    ds: &[f64],
    c: usize,
    dq: &mut [Vec<f64>],
    sc: &mut FrameScratch,
    tb: &mut Vec<Vector3<f64>>,
) -> f64 {
    let (nq, nf) = (b.nq, b.nf);
    let mut l = std::mem::take(&mut sc.fac);
    let mut wd = std::mem::take(&mut sc.vec);
    let mut pred = 0.0;
    for (f, d) in b.chunk_frames(c).zip(dq.iter_mut()) {
        let blk = b.frame(prob, qs, f, sc, tb);
        let (u, rest) = blk.split_at(nq * nq);
        let (w, g) = rest.split_at(nq * nf);
        // Positive definite: the same factorisation succeeded in `solve`, which kept it when
        // there was room.
        if b.factors_valid && f < b.factored {
            l.clear();
            l.extend_from_slice(&b.factors[f * nq * nq..(f + 1) * nq * nq]);
        } else {
            let ok = factor_damped(u, nq, b.lambda, &mut l);
            debug_assert!(ok);
        }
        d.copy_from_slice(g);
        for (wk, &dk) in w.chunks_exact(nq).zip(ds) {
            for (x, wk) in d.iter_mut().zip(wk) {
                *x -= wk * dk;
            }
        }
        cholesky_solve(&l, nq, d);
        // Frame i's share of 2 hᵀδ − δᵀHδ: 2 gᵀδq − δqᵀUδq − 2 δsᵀWᵀδq.
        let mut quad = 0.0;
        for (a, ua) in u.chunks_exact(nq).enumerate() {
            quad += d[a] * dot(ua, d);
        }
        wd.clear();
        wd.extend(w.chunks_exact(nq).map(|wk| dot(wk, d)));
        pred += 2.0 * dot(g, d) - quad - 2.0 * dot(ds, &wd);
    }
    sc.fac = l;
    sc.vec = wd;
    pred
}

/// [`back_substitute_chunk`] compiled for AVX2: the element-wise updates four numbers wide,
/// the same operations in the same order.
#[allow(clippy::too_many_arguments)]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn back_substitute_chunk_avx2(
    prob: &Problem,
    qs: &[Vec<f64>],
    b: &Blocks,
    ds: &[f64],
    c: usize,
    dq: &mut [Vec<f64>],
    sc: &mut FrameScratch,
    tb: &mut Vec<Vector3<f64>>,
) -> f64 {
    back_substitute_chunk(prob, qs, b, ds, c, dq, sc, tb)
}

/// [`solve_reduced`] with every parameter at a bound whose step points out of it held
/// (`fixed` grows), solved again until no held-back parameter would leave its bound.
///
/// Clamping such a component after the solve changes the step of every parameter it is
/// coupled with, and the clamped step need not descend: on gait2392 subject01 walk1 the model
/// predicted an increase for five steps in a row with the ankle-axis parameters at their
/// bounds, which raised the damping 10⁴-fold (`notebook/solver_tail.md`). Held and solved
/// again, the step is the Gauss–Newton step of the free parameters (Bertsekas 1982, projected
/// Newton methods).
pub(crate) fn solve_reduced_at_bounds(
    blocks: &Blocks,
    extra: Option<&[f64]>,
    s: &[f64],
    fixed: &mut [bool],
    ds: &mut [f64],
) -> bool {
    loop {
        if !solve_reduced(blocks, extra, fixed, ds) {
            return false;
        }
        let mut changed = false;
        for k in 0..s.len() {
            if !fixed[k] && ((s[k] >= 1.0 && ds[k] > 0.0) || (s[k] <= -1.0 && ds[k] < 0.0)) {
                fixed[k] = true;
                changed = true;
            }
        }
        if !changed {
            return true;
        }
    }
}

#[cfg(test)]
mod solve_rows_tests {
    use super::{fill_rows, forward_solve_rows};

    /// `[W | g]` copied row by row: every entry in its place, the AVX2 blocks the same.
    #[test]
    fn rows_hold_w_transposed_and_g() {
        for nq in [1usize, 4, 6, 12, 13] {
            for nf in [1usize, 3, 4, 8, 27] {
                let m = nf + 1;
                let w: Vec<f64> = (0..nq * nf).map(|x| x as f64 + 0.5).collect();
                let g: Vec<f64> = (0..nq).map(|a| -(a as f64) - 1.0).collect();
                let mut plain = vec![f64::NAN; nq * m];
                fill_rows(&w, &g, nq, &mut plain);
                for a in 0..nq {
                    for k in 0..nf {
                        assert_eq!(plain[a * m + k], w[k * nq + a], "nq {nq}, nf {nf}");
                    }
                    assert_eq!(plain[a * m + nf], g[a]);
                }
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("avx2") {
                    let mut wide = vec![f64::NAN; nq * m];
                    // SAFETY: AVX2 is present (checked just above).
                    unsafe { super::fill_rows_avx2(&w, &g, nq, &mut wide) };
                    assert_eq!(wide, plain, "nq {nq}, nf {nf}");
                }
            }
        }
    }

    /// The register-held pieces give, bit for bit, the plain solve that subtracts every
    /// earlier row over the whole width in turn, for widths that are and are not multiples
    /// of 4, 8 and 16; and the solution satisfies `L Y = B`.
    #[test]
    fn pieces_solve_exactly_as_whole_rows() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for n in [1usize, 2, 5, 12] {
            // Lower triangular, column-major, a dominant diagonal.
            let mut l = vec![0.0; n * n];
            for k in 0..n {
                l[k * n + k] = 1.0 + next().abs();
                for i in k + 1..n {
                    l[k * n + i] = next();
                }
            }
            for m in 1..=40 {
                let b: Vec<f64> = (0..n * m).map(|_| next() * 1e3).collect();
                let mut plain = b.clone();
                for i in 0..n {
                    let (done, rest) = plain.split_at_mut(i * m);
                    let row = &mut rest[..m];
                    for k in 0..i {
                        let lik = l[k * n + i];
                        for (x, y) in row.iter_mut().zip(&done[k * m..(k + 1) * m]) {
                            *x -= lik * y;
                        }
                    }
                    let d = 1.0 / l[i * n + i];
                    for x in row.iter_mut() {
                        *x *= d;
                    }
                }
                let mut got = b.clone();
                forward_solve_rows(&l, n, m, &mut got);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&plain), "n = {n}, m = {m}");
                for i in 0..n {
                    for c in 0..m {
                        let lhs: f64 = (0..=i).map(|k| l[k * n + i] * got[k * m + c]).sum();
                        let rhs = b[i * m + c];
                        assert!((lhs - rhs).abs() <= 1e-9 * (1.0 + rhs.abs()), "L Y = B");
                    }
                }
            }
        }
    }

    /// One frame's share is `[W | g]ᵀ U⁻¹ [W | g]`: against nalgebra's solve of the same
    /// symmetric positive definite `U`, for sizes that are and are not multiples of 4.
    #[test]
    fn frame_share_is_the_frames_reduction() {
        use nalgebra::DMatrix;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (nq, nf) in [(0usize, 3usize), (1, 1), (6, 4), (12, 27), (13, 9)] {
            let a = DMatrix::from_fn(nq, nq + 2, |_, _| next());
            let u = &a * a.transpose() + DMatrix::identity(nq, nq) * 0.1;
            let w: Vec<f64> = (0..nq * nf).map(|_| next()).collect();
            let g: Vec<f64> = (0..nq).map(|_| next()).collect();
            let mut l = u.as_slice().to_vec();
            assert!(crate::linalg::cholesky_in_place(&mut l, nq));
            let got = super::frame_share(&l, &w, &g, (nq, nf), &mut Vec::new());
            // [W | g] as an n_q × (n_f + 1) matrix, and its product by hand.
            let m = nf + 1;
            let wg = DMatrix::from_fn(nq, m, |a, k| if k < nf { w[k * nq + a] } else { g[a] });
            let y = u.clone().cholesky().expect("positive definite").solve(&wg);
            let want = wg.transpose() * y;
            for c in 0..m {
                for k in 0..m {
                    let (x, e) = (got[c * m + k], want[(k, c)]);
                    assert!((x - e).abs() <= 1e-10 * (1.0 + e.abs()), "nq {nq}, nf {nf}");
                }
            }
        }
    }
}
