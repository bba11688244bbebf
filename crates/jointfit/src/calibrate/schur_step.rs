//! The damped step of the block-arrow system ([`super`]'s module docs): the Schur reduction
//! `S = V* − Σ W_iᵀ U_i*⁻¹ W_i`, its solve in the parameters, and the back substitution for
//! every frame's coordinates.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::super::kernel::{dot, FrameScratch};
use super::super::Problem;
use super::{add, Blocks};
use crate::linalg::{cholesky_in_place, cholesky_solve, Cholesky};

/// Solves `L Y = B` in place for `B` (`n × m`, row-major): row by row, each row update an
/// operation on `m` contiguous numbers.
#[inline(always)]
fn forward_solve_rows(l: &[f64], n: usize, m: usize, b: &mut [f64]) {
    for i in 0..n {
        let (done, rest) = b.split_at_mut(i * m);
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
            for (k, wk) in w.chunks_exact(nq).enumerate() {
                for (row, &x) in zf.chunks_exact_mut(m).zip(wk) {
                    row[k] = x;
                }
            }
            for (row, &x) in zf.chunks_exact_mut(m).zip(g) {
                row[nf] = x;
            }
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
