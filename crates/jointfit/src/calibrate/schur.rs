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

use nalgebra::Vector3;

use super::Problem;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::linalg::{backward_solve, Cholesky};

#[derive(Debug, Clone)]
pub(crate) struct Blocks {
    pub nq: usize,
    pub nf: usize,
    /// Per frame `n_q × n_q`, column-major.
    pub u: Vec<f64>,
    /// Per frame `n_q × n_f`, column-major.
    pub w: Vec<f64>,
    /// Per frame `n_q`.
    pub g: Vec<f64>,
    /// `n_f × n_f`.
    pub v: Vec<f64>,
    pub gs: Vec<f64>,
    /// Per frame `J_s,iᵀ W r_i` (n_f each): frame i's share of `gs`.
    pub gs_frame: Vec<f64>,
    /// Per frame `J_s,iᵀ W J_s,i` (n_f × n_f each, column-major): frame i's share of `v`.
    pub v_frame: Vec<f64>,
    /// Objective at the assembly point (m²).
    pub cost: f64,
    // Per frame: the Cholesky factor `L` of `U*`, `Z = L⁻¹ W` and `y = L⁻¹ g`.
    l_fac: Vec<f64>,
    y_mat: Vec<f64>,
    y_vec: Vec<f64>,
}

impl Blocks {
    pub fn new(n_frames: usize, nq: usize, nf: usize) -> Self {
        Blocks {
            nq,
            nf,
            u: vec![0.0; n_frames * nq * nq],
            w: vec![0.0; n_frames * nq * nf],
            g: vec![0.0; n_frames * nq],
            v: vec![0.0; nf * nf],
            gs: vec![0.0; nf],
            gs_frame: vec![0.0; n_frames * nf],
            v_frame: vec![0.0; n_frames * nf * nf],
            cost: 0.0,
            l_fac: vec![0.0; n_frames * nq * nq],
            y_mat: vec![0.0; n_frames * nq * nf],
            y_vec: vec![0.0; n_frames * nq],
        }
    }
}

/// Assembles the normal equations at `(p, qs)`.
///
/// Per frame the weighted Jacobian `√W [J_q | J_s]` is gathered column by column over the
/// present markers' rows; each column is nonzero only on the rows of the markers its
/// coordinate or parameter moves, so every Gram entry is a dot product over the overlap of
/// two columns' nonzero row ranges.
pub(crate) fn assemble(
    prob: &Problem,
    p: &[f64],
    qs: &[Vec<f64>],
    kin: &mut KinData,
    b: &mut Blocks,
) {
    let model = prob.model;
    let (nq, nf) = (b.nq, b.nf);
    let n = nq + nf;
    let nrows = 3 * model.n_markers();
    let half: Vec<f64> = (0..nf).map(|k| prob.half_range(k)).collect();
    b.v.fill(0.0);
    b.gs.fill(0.0);
    b.cost = 0.0;
    // Rows: (model row 3j + axis, √w_j) of the present markers.
    let mut rows: Vec<(usize, f64)> = Vec::with_capacity(nrows);
    let mut jw = vec![0.0; n * nrows];
    let mut rw = vec![0.0; nrows];
    let mut range = vec![(0usize, 0usize); n];
    let mut gram = vec![0.0; n * n];
    for (f, targets) in prob.frames.iter().enumerate() {
        forward_kinematics(model, p, &qs[f], Want::BOTH, kin);
        rows.clear();
        for (j, m) in model.markers().iter().enumerate() {
            let t: Vector3<f64> = targets[j];
            if t.x.is_nan() || m.weight <= 0.0 {
                continue;
            }
            let r = t - kin.markers[j];
            b.cost += m.weight * r.norm_squared();
            let sw = m.weight.sqrt();
            for axis in 0..3 {
                rw[rows.len()] = sw * r[axis];
                rows.push((3 * j + axis, sw));
            }
        }
        let nr = rows.len();
        let jq = kin.jq().as_slice();
        let jp = kin.jp().as_slice();
        for a in 0..n {
            let (src, scale) = if a < nq {
                (&jq[a * nrows..(a + 1) * nrows], 1.0)
            } else {
                let k = a - nq;
                let pi = prob.free[k];
                (&jp[pi * nrows..(pi + 1) * nrows], half[k])
            };
            let col = &mut jw[a * nr..(a + 1) * nr];
            for (x, &(row, sw)) in col.iter_mut().zip(&rows) {
                *x = sw * scale * src[row];
            }
            let lo = col.iter().position(|&x| x != 0.0).unwrap_or(nr);
            let hi = col.iter().rposition(|&x| x != 0.0).map_or(lo, |i| i + 1);
            range[a] = (lo, hi.max(lo));
        }
        let rw = &rw[..nr];
        for a in 0..n {
            let (lo_a, hi_a) = range[a];
            let col_a = &jw[a * nr..(a + 1) * nr];
            let g = dot(&col_a[lo_a..hi_a], &rw[lo_a..hi_a]);
            if a < nq {
                b.g[f * nq + a] = g;
            } else {
                b.gs[a - nq] += g;
                b.gs_frame[f * nf + a - nq] = g;
            }
            for c in 0..=a {
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
        // Split the symmetric Gram matrix into U_i, W_i and V.
        let u = &mut b.u[f * nq * nq..(f + 1) * nq * nq];
        for c in 0..nq {
            u[c * nq..(c + 1) * nq].copy_from_slice(&gram[c * n..c * n + nq]);
        }
        let w = &mut b.w[f * nq * nf..(f + 1) * nq * nf];
        for k in 0..nf {
            w[k * nq..(k + 1) * nq].copy_from_slice(&gram[(nq + k) * n..(nq + k) * n + nq]);
        }
        for l in 0..nf {
            let src = &gram[(nq + l) * n + nq..(nq + l + 1) * n];
            b.v_frame[(f * nf + l) * nf..(f * nf + l + 1) * nf].copy_from_slice(src);
            for (v, x) in b.v[l * nf..(l + 1) * nf].iter_mut().zip(src) {
                *v += x;
            }
        }
    }
}

/// The decrease of the objective that the linearized model predicts for the step
/// `(δq, δs)`: `2 gᵀδ − δᵀ H δ` with `H = JᵀWJ` in block form (the objective is
/// `Σ w‖r‖²` and `g = JᵀW r`). The ratio of actual to predicted decrease drives the damping.
pub(crate) fn predicted_decrease(b: &Blocks, ds: &[f64], dq: &[Vec<f64>]) -> f64 {
    let (nq, nf) = (b.nq, b.nf);
    let mut lin = dot(&b.gs, ds);
    let mut quad = 0.0;
    for k in 0..nf {
        quad += ds[k] * dot(&b.v[k * nf..(k + 1) * nf], ds);
    }
    for (f, d) in dq.iter().enumerate() {
        lin += dot(&b.g[f * nq..(f + 1) * nq], d);
        let u = &b.u[f * nq * nq..(f + 1) * nq * nq];
        let w = &b.w[f * nq * nf..(f + 1) * nq * nf];
        for a in 0..nq {
            quad += d[a] * dot(&u[a * nq..(a + 1) * nq], d);
        }
        for k in 0..nf {
            quad += 2.0 * ds[k] * dot(&w[k * nq..(k + 1) * nq], d);
        }
    }
    2.0 * lin - quad
}

/// Damped step: fills `ds` (n_f) and `dq` (per frame n_q). `fixed[k]` pins parameter k
/// (`δs_k = 0`). Returns false when a system is not positive definite at this damping.
pub(crate) fn solve(
    b: &mut Blocks,
    lambda: f64,
    fixed: &[bool],
    ds: &mut [f64],
    dq: &mut [Vec<f64>],
) -> bool {
    let (nq, nf) = (b.nq, b.nf);
    let frames = b.g.len() / nq;
    let mut s = b.v.clone();
    for k in 0..nf {
        s[k * nf + k] *= 1.0 + lambda;
    }
    let mut rhs = b.gs.clone();
    for f in 0..frames {
        let u = &b.u[f * nq * nq..(f + 1) * nq * nq];
        let l = &mut b.l_fac[f * nq * nq..(f + 1) * nq * nq];
        l.copy_from_slice(u);
        let max_diag = (0..nq).fold(0.0f64, |m, i| m.max(u[i * nq + i]));
        for i in 0..nq {
            l[i * nq + i] += lambda * u[i * nq + i] + 1e-14 * max_diag + 1e-300;
        }
        let Some(chol) = Cholesky::factor(l, nq) else {
            return false;
        };
        // With U* = L Lᵀ: Wᵀ U*⁻¹ W = ZᵀZ and Wᵀ U*⁻¹ g = Zᵀy for Z = L⁻¹W, y = L⁻¹g, so
        // only forward substitutions are needed here (back-substitution finishes δq).
        let w = &b.w[f * nq * nf..(f + 1) * nq * nf];
        let z = &mut b.y_mat[f * nq * nf..(f + 1) * nq * nf];
        z.copy_from_slice(w);
        for k in 0..nf {
            chol.forward(&mut z[k * nq..(k + 1) * nq]);
        }
        let y = &mut b.y_vec[f * nq..(f + 1) * nq];
        y.copy_from_slice(&b.g[f * nq..(f + 1) * nq]);
        chol.forward(y);
        // ZᵀZ is symmetric: compute one triangle, mirror it.
        for k in 0..nf {
            let zk = &z[k * nq..(k + 1) * nq];
            rhs[k] -= dot(zk, y);
            for c in 0..=k {
                let value = dot(zk, &z[c * nq..(c + 1) * nq]);
                s[c * nf + k] -= value;
                if c != k {
                    s[k * nf + c] -= value;
                }
            }
        }
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
    back_substitute(b, ds, dq);
    true
}

/// `δq_i = U_i*⁻¹ (g_i − W_i δs) = L_i⁻ᵀ (y_i − Z_i δs)` for a given (possibly clamped) `δs`.
pub(crate) fn back_substitute(b: &Blocks, ds: &[f64], dq: &mut [Vec<f64>]) {
    let (nq, nf) = (b.nq, b.nf);
    for (f, d) in dq.iter_mut().enumerate() {
        let z = &b.y_mat[f * nq * nf..(f + 1) * nq * nf];
        d.copy_from_slice(&b.y_vec[f * nq..(f + 1) * nq]);
        for k in 0..nf {
            let dk = ds[k];
            for (x, zk) in d.iter_mut().zip(&z[k * nq..(k + 1) * nq]) {
                *x -= zk * dk;
            }
        }
        backward_solve(&b.l_fac[f * nq * nq..(f + 1) * nq * nq], nq, d);
    }
}

/// `Σ a_i b_i` with four independent accumulators (vectorizes).
fn dot(a: &[f64], b: &[f64]) -> f64 {
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

/// Parameters at a bound whose descent direction points outward are held for the step.
pub(crate) fn active_bounds(s: &[f64], gs: &[f64]) -> Vec<bool> {
    s.iter()
        .zip(gs)
        .map(|(&s, &g)| (s <= -1.0 && g < 0.0) || (s >= 1.0 && g > 0.0))
        .collect()
}

/// Objective at `(p, qs)` without derivatives (m²).
pub(crate) fn cost_at(prob: &Problem, p: &[f64], qs: &[Vec<f64>], kin: &mut KinData) -> f64 {
    let mut total = 0.0;
    for (f, targets) in prob.frames.iter().enumerate() {
        forward_kinematics(prob.model, p, &qs[f], Want::POSITIONS, kin);
        for (j, m) in prob.model.markers().iter().enumerate() {
            if !targets[j].x.is_nan() && m.weight > 0.0 {
                total += m.weight * (targets[j] - kin.markers[j]).norm_squared();
            }
        }
    }
    total
}
