//! The resampling estimators of the parameter covariance: the moving-block bootstrap (refits
//! of resampled trials) and the linearised delete-block jackknife (see the parent module).

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::super::joint::{solve_joint, JointOptions};
use super::super::{Fit, Problem};
use super::estimators::{continuity, pseudo_solve};
use super::Reduced;

/// Moving-block bootstrap: covariance (scaled units) of refitted `s` and the count of
/// replicates that did not converge.
pub(super) fn block_bootstrap(
    prob: &Problem,
    fit: &Fit,
    replicates: usize,
    block: usize,
    seed: u64,
) -> (DMatrix<f64>, usize) {
    let n = prob.frames.len();
    let same = continuity(prob);
    // Candidate blocks: every window of `block` consecutive frames inside one run.
    let mut runs = Vec::new();
    let mut start = 0;
    for i in 0..n {
        if same.get(i) != Some(&true) {
            runs.push((start, i + 1));
            start = i + 1;
        }
    }
    let mut windows = Vec::new();
    for &(a, b) in &runs {
        let len = block.min(b - a);
        for s in a..=b - len {
            windows.push((s, len));
        }
    }
    // Standard errors need the refit to a small fraction of the spread, not to 1e-10.
    let opts = JointOptions {
        max_iterations: 50,
        tolerance: 1e-6,
        ..JointOptions::default()
    };
    let results: Vec<(Vec<f64>, bool)> = (0..replicates)
        .into_par_iter()
        .map(|r| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(r as u64 + 1);
            let mut idx = Vec::with_capacity(n + block);
            while idx.len() < n {
                let (s, len) = windows[rng.gen_range(0..windows.len())];
                idx.extend(s..s + len);
            }
            idx.truncate(n);
            let mut sub = prob.clone();
            sub.frames = prob.frames.select(idx.iter().copied());
            sub.origin = idx.iter().map(|&i| prob.origin[i]).collect();
            let q0 = idx.iter().map(|&i| fit.coords[i].clone()).collect();
            let f = solve_joint(&sub, &fit.s, q0, &opts, &mut crate::solver::NoObserver);
            let converged = f.converged();
            (f.s, converged)
        })
        .collect();
    let nf = fit.s.len();
    let mean: Vec<f64> = (0..nf)
        .map(|k| results.iter().map(|r| r.0[k]).sum::<f64>() / replicates as f64)
        .collect();
    let mut cov = DMatrix::zeros(nf, nf);
    for (s, _) in &results {
        let d = DVector::from_iterator(nf, s.iter().zip(&mean).map(|(a, m)| a - m));
        cov += &d * d.transpose();
    }
    cov /= (replicates.max(2) - 1) as f64;
    (cov, results.iter().filter(|r| !r.1).count())
}

/// Linearised delete-block jackknife over `blocks` contiguous blocks of frames: dropping
/// block k moves the optimum by `δ_k = (S − A_k)⁻¹ B_k` (one Gauss–Newton step, `A_k`, `B_k`
/// the block's share of `S` and of the scores), and `C = (K−1)/K Σ_k (δ_k − δ̄)(δ_k − δ̄)ᵀ`.
/// Correlation within a block is kept whole; the removal of the block's own influence makes
/// it conservative where the fit absorbs part of the noise (few frames per parameter). The
/// blocks are whole groups of [`Reduced::group_normals`] (single frames up to
/// [`super::reduced::MAX_GROUPS`] frames).
pub(super) fn block_jackknife(
    red: &Reduced,
    scores: &[DVector<f64>],
    blocks: usize,
) -> DMatrix<f64> {
    let n = scores.len();
    let nf = red.normal.nrows();
    let groups = red.group_normals.len();
    let gs = red.group_size;
    // Each block's removal is independent of the others': they run in parallel and are
    // collected in block order (the same bits on any number of threads).
    let deltas: Vec<DVector<f64>> = (0..blocks)
        .into_par_iter()
        .map(|k| {
            let (ga, gb) = (k * groups / blocks, (k + 1) * groups / blocks);
            let mut s = red.normal.clone();
            let mut g = DVector::zeros(nf);
            for ai in &red.group_normals[ga..gb] {
                s -= ai;
            }
            for si in &scores[(ga * gs).min(n)..(gb * gs).min(n)] {
                g += si;
            }
            pseudo_solve(&((&s + s.transpose()) * 0.5), &g)
        })
        .collect();
    let mean = deltas.iter().fold(DVector::zeros(nf), |a, d| a + d) / blocks as f64;
    let mut c = DMatrix::zeros(nf, nf);
    for d in &deltas {
        let e = d - &mean;
        c += &e * e.transpose();
    }
    c * ((blocks - 1) as f64 / blocks as f64)
}
