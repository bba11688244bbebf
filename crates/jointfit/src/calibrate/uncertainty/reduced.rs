//! The reduced normal matrix `S` and the per-frame profile scores (see the parent module).

use nalgebra::{DMatrix, DVector};

use super::super::schur::{assemble, Blocks};
use super::super::Problem;
use crate::kinematics::KinData;
use crate::linalg::Cholesky;

/// The reduced normal equations at one point `(p, q_1 … q_N)`.
#[derive(Debug, Clone)]
pub struct Reduced {
    /// `S` (n_f × n_f) in scaled parameter units (m² per scaled unit²).
    pub normal: DMatrix<f64>,
    /// Per fitted frame, the profile score `ψ_i` (n_f, m² per scaled unit).
    pub scores: Vec<DVector<f64>>,
    /// Per fitted frame, its share `A_i = J_red,iᵀ W J_red,i` of `S` (n_f × n_f).
    pub frame_normals: Vec<DMatrix<f64>>,
    /// Weighted squared residual sum `e` (m²).
    pub cost: f64,
    /// Scalar residuals `m`: 3 per present, weighted marker sample.
    pub observations: usize,
    /// Coordinates per frame `n_q`.
    pub n_q: usize,
}

impl Reduced {
    /// Residual degrees of freedom `m − N·n_q − n_f` (0 when the data are too few).
    pub fn dof(&self) -> usize {
        let used = self.scores.len() * self.n_q + self.normal.nrows();
        self.observations.saturating_sub(used)
    }
    /// Residual variance per scalar residual `σ²` (m²); infinite without degrees of freedom.
    pub fn sigma2(&self) -> f64 {
        match self.dof() {
            0 => f64::INFINITY,
            d => self.cost / d as f64,
        }
    }
}

/// Builds `S` and the per-frame scores at parameters `p` and coordinates `qs` (one per frame
/// of `prob`).
pub fn reduced_system(prob: &Problem, p: &[f64], qs: &[Vec<f64>]) -> Reduced {
    let nq = prob.model.n_q();
    let nf = prob.n_free();
    let frames = prob.frames.len();
    let mut kin = KinData::new(prob.model);
    let mut b = Blocks::new(frames, nq, nf);
    assemble(prob, p, qs, &mut kin, &mut b);
    let mut normal = DMatrix::from_column_slice(nf, nf, &b.v);
    let mut scores = Vec::with_capacity(frames);
    let mut frame_normals = Vec::with_capacity(frames);
    let mut l = vec![0.0; nq * nq];
    let mut y = vec![0.0; nq * nf];
    let mut yg = vec![0.0; nq];
    for f in 0..frames {
        let u = &b.u[f * nq * nq..(f + 1) * nq * nq];
        let max_diag = (0..nq).fold(0.0f64, |m, i| m.max(u[i * nq + i]));
        // The same tiny regularisation the solver uses; more only if a frame's coordinates
        // are themselves undetermined (then they absorb nothing along that direction).
        let mut ridge = 1e-14 * max_diag + 1e-300;
        let chol = loop {
            l.copy_from_slice(u);
            for i in 0..nq {
                l[i * nq + i] += ridge;
            }
            if let Some(chol) = Cholesky::factor(&mut l, nq) {
                break chol;
            }
            ridge *= 100.0;
        };
        let w = &b.w[f * nq * nf..(f + 1) * nq * nf];
        y.copy_from_slice(w);
        for k in 0..nf {
            chol.solve(&mut y[k * nq..(k + 1) * nq]);
        }
        yg.copy_from_slice(&b.g[f * nq..(f + 1) * nq]);
        chol.solve(&mut yg);
        let mut psi = DVector::zeros(nf);
        let mut a = DMatrix::from_column_slice(nf, nf, &b.v_frame[f * nf * nf..(f + 1) * nf * nf]);
        for k in 0..nf {
            let wk = &w[k * nq..(k + 1) * nq];
            psi[k] = b.gs_frame[f * nf + k] - dot(wk, &yg);
            for c in 0..nf {
                let d = dot(wk, &y[c * nq..(c + 1) * nq]);
                normal[(k, c)] -= d;
                a[(k, c)] -= d;
            }
        }
        scores.push(psi);
        frame_normals.push(a);
    }
    normal = (&normal + normal.transpose()) * 0.5;
    let observations = prob
        .frames
        .iter()
        .map(|t| {
            t.iter()
                .zip(prob.model.markers())
                .filter(|(x, m)| !x.x.is_nan() && m.weight > 0.0)
                .count()
                * 3
        })
        .sum();
    Reduced {
        normal,
        scores,
        frame_normals,
        cost: b.cost,
        observations,
        n_q: nq,
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
