//! The reduced normal matrix `S` and the per-frame profile scores (see the parent module).

use nalgebra::{DMatrix, DVector};

use rayon::prelude::*;

use super::super::kernel::{frame_gram, FrameScratch};
use super::super::schur::{chunk_len, coordinate_bounds, frame_share, hold_at_bounds};
use super::super::Problem;
use crate::linalg::cholesky_in_place;

/// The reduced normal equations at one point `(p, q_1 … q_N)`.
#[derive(Debug, Clone)]
pub(crate) struct Reduced {
    /// `S` (n_f × n_f) in scaled parameter units (m² per scaled unit²), the prior's
    /// information on its diagonal when the problem has a prior (the posterior's).
    pub normal: DMatrix<f64>,
    /// `S` of the marker term alone (the data's information; equal to `normal` without a
    /// prior).
    pub data_normal: DMatrix<f64>,
    /// Per fitted frame, the profile score `ψ_i` (n_f, m² per scaled unit).
    pub scores: Vec<DVector<f64>>,
    /// Per group of [`Reduced::group_size`] consecutive fitted frames (the last may be
    /// shorter), the group's share `Σ_i A_i` of `S`, `A_i = J_red,iᵀ W J_red,i` (n_f × n_f):
    /// the block jackknife removes whole groups. One frame per group up to
    /// [`MAX_GROUPS`] frames; longer trials keep at most that many matrices (5.8 kB each for
    /// 27 parameters) instead of one per frame.
    pub group_normals: Vec<DMatrix<f64>>,
    /// Frames per entry of [`Reduced::group_normals`] ([`group_size`]).
    pub group_size: usize,
    /// Weighted squared residual sum `e` (m²).
    pub cost: f64,
    /// Scalar residuals `m`: 3 per present, weighted marker sample.
    pub observations: usize,
    /// Coordinates per frame `n_q`.
    pub n_q: usize,
    /// Per free parameter, the prior's information `d_k = σ_p²h_k²/s_k²` (the diagonal it
    /// adds to `normal`; zeros without a prior) and the prior's marker noise `σ_p` (m).
    pub prior_information: Vec<f64>,
    pub prior_noise: f64,
    /// Per free parameter, the factor `a_k ≥ 1` the prior weight carries
    /// ([`crate::calibrate::prior::Prior::inflation`]; ones without a prior) times the
    /// spread `τ_k²` the intervals assume ([`crate::calibrate::prior::Prior::spread`]): with
    /// the truth drawn from `N(μ_k, τ_k² s_k²)`, the prior term's score has variance
    /// `σ_p² a_k τ_k² d_k`.
    pub prior_inflation: Vec<f64>,
}

impl Reduced {
    /// Residual degrees of freedom `m − N·n_q − n_f` (0 when the data are too few).
    pub(crate) fn dof(&self) -> usize {
        let used = self.scores.len() * self.n_q + self.normal.nrows();
        self.observations.saturating_sub(used)
    }
    /// Residual variance per scalar residual `σ²` (m²); infinite without degrees of freedom.
    pub(crate) fn sigma2(&self) -> f64 {
        match self.dof() {
            0 => f64::INFINITY,
            d => self.cost / d as f64,
        }
    }
}

/// The most entries [`Reduced::group_normals`] holds.
pub(crate) const MAX_GROUPS: usize = 4096;

/// Frames per group of [`Reduced::group_normals`] for a trial of `frames` frames: 1 up to
/// [`MAX_GROUPS`] frames, else the fewest that keep the groups within it.
pub(crate) fn group_size(frames: usize) -> usize {
    frames.div_ceil(MAX_GROUPS).max(1)
}

/// Builds `S` and the per-frame scores at parameters `p` and coordinates `qs` (one per frame
/// of `prob`). Frames are processed in fixed chunks in parallel and their sums added in
/// chunk order (the same result whatever the thread count); no per-frame Jacobian blocks are
/// kept beyond the frame being reduced.
pub(crate) fn reduced_system(prob: &Problem, p: &[f64], qs: &[Vec<f64>]) -> Reduced {
    let nq = prob.model.coordinates().len();
    let nf = prob.n_free();
    let n = nq + nf;
    let frames = prob.frames.len();
    let half: Vec<f64> = (0..nf).map(|k| prob.half_range(k)).collect();
    let gs = group_size(frames);
    // OpenSim's clamped coordinates at a bound of their range are held there, as the joint
    // solver holds them: fixed, they absorb nothing of a parameter change.
    let bounds = coordinate_bounds(prob);
    // (normal, scores, (group, its sum over the chunk's frames) in frame order, cost)
    type Chunk = (
        DMatrix<f64>,
        Vec<DVector<f64>>,
        Vec<(usize, DMatrix<f64>)>,
        f64,
    );
    // The Schur passes' chunks: an even number on a short trial, so two threads split it
    // evenly.
    let chunk = chunk_len(frames);
    let parts: Vec<Chunk> = (0..frames.div_ceil(chunk))
        .into_par_iter()
        .map_init(
            || (FrameScratch::new(prob), Vec::new()),
            |(sc, tb), c| {
                let mut normal = DMatrix::zeros(nf, nf);
                let mut scores = Vec::with_capacity(chunk);
                let mut group_normals: Vec<(usize, DMatrix<f64>)> = Vec::new();
                let mut cost = 0.0;
                let mut u = vec![0.0; nq * nq];
                let mut w = vec![0.0; nq * nf];
                let mut l = vec![0.0; nq * nq];
                let mut z = Vec::new();
                let mut yg = vec![0.0; nq];
                let range = c * chunk..((c + 1) * chunk).min(frames);
                for f in range {
                    let targets = prob.frames.fill(f, tb);
                    cost += frame_gram(prob, p, &qs[f], targets, &half, sc);
                    let (gram, grad) = (&sc.gram, &sc.grad);
                    for a in 0..nq {
                        u[a * nq..(a + 1) * nq].copy_from_slice(&gram[a * n..a * n + nq]);
                    }
                    for k in 0..nf {
                        w[k * nq..(k + 1) * nq]
                            .copy_from_slice(&gram[(nq + k) * n..(nq + k) * n + nq]);
                    }
                    yg.copy_from_slice(&grad[..nq]);
                    hold_at_bounds(&bounds, &qs[f], &mut u, &mut w, &mut yg);
                    let max_diag = (0..nq).fold(0.0f64, |m, i| m.max(u[i * nq + i]));
                    // The same tiny regularisation the solver uses; more only if a frame's
                    // coordinates are themselves undetermined (then they absorb nothing along
                    // that direction).
                    let mut ridge = 1e-14 * max_diag + 1e-300;
                    loop {
                        l.copy_from_slice(&u);
                        for i in 0..nq {
                            l[i * nq + i] += ridge;
                        }
                        if cholesky_in_place(&mut l, nq) {
                            break;
                        }
                        ridge *= 100.0;
                    }
                    // [W | g]ᵀ U⁻¹ [W | g]: the reduction's share and the score's correction.
                    let zz = frame_share(&l, &w, &yg, (nq, nf), &mut z);
                    let m = nf + 1;
                    let psi = DVector::from_fn(nf, |k, _| grad[nq + k] - zz[nf * m + k]);
                    let a = DMatrix::from_fn(nf, nf, |k, c| {
                        gram[(nq + c) * n + nq + k] - zz[c * m + k]
                    });
                    normal += &a;
                    scores.push(psi);
                    match group_normals.last_mut() {
                        Some((g, sum)) if *g == f / gs => *sum += a,
                        _ => group_normals.push((f / gs, a)),
                    }
                }
                (normal, scores, group_normals, cost)
            },
        )
        .collect();
    let mut normal = DMatrix::zeros(nf, nf);
    let mut scores = Vec::with_capacity(frames);
    let mut group_normals: Vec<DMatrix<f64>> = Vec::with_capacity(frames.div_ceil(gs));
    let mut cost = 0.0;
    for (part_normal, part_scores, part_groups, part_cost) in parts {
        normal += part_normal;
        scores.extend(part_scores);
        for (g, sum) in part_groups {
            // A group split between two chunks is summed in chunk order.
            if g < group_normals.len() {
                group_normals[g] += sum;
            } else {
                group_normals.push(sum);
            }
        }
        cost += part_cost;
    }
    let data_normal = (&normal + normal.transpose()) * 0.5;
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
    let mut red = Reduced {
        normal: data_normal.clone(),
        data_normal,
        scores,
        group_normals,
        group_size: gs,
        // The marker term only: σ² is a marker-noise variance.
        cost,
        observations,
        n_q: nq,
        prior_information: Vec::new(),
        prior_noise: 0.0,
        prior_inflation: Vec::new(),
    };
    red.set_prior_of(prob);
    red
}

impl Reduced {
    /// The prior part of `self` set to `prob`'s prior (none when `prob` has none): what
    /// [`reduced_system`] gives on `prob` at the same point, bit for bit, when `prob` differs
    /// from the problem `self` was formed on only in its prior (its σ, factors or spreads).
    /// The marker term's part, the costly one, is kept.
    pub(crate) fn set_prior_of(&mut self, prob: &Problem) {
        let nf = self.data_normal.nrows();
        debug_assert_eq!(nf, prob.n_free());
        // The prior's information (zero without a prior): `S` is then the posterior's.
        self.normal.copy_from(&self.data_normal);
        self.prior_information = prob.prior_information();
        for (k, d) in self.prior_information.iter().enumerate() {
            self.normal[(k, k)] += d;
        }
        self.prior_noise = prob.prior.as_ref().map_or(0.0, |p| p.noise);
        self.prior_inflation = prob.prior.as_ref().map_or_else(
            || vec![1.0; nf],
            |p| {
                p.inflation
                    .iter()
                    .zip(&p.spread)
                    .map(|(a, t)| a * t)
                    .collect()
            },
        );
    }
}
