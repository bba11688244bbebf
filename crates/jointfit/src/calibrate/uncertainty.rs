//! Which joint parameters a trial determines: standard errors, intervals, identifiability.
//!
//! Reinbolt et al. 2005 (doi:10.1016/j.jbiomech.2004.03.031) close with an open problem: "a
//! systematic methodology for determining which joint parameters can and cannot be found
//! accurately from a particular noisy experimental data set". This module answers it for a
//! fitted (or nominal) parameter set.
//!
//! # The reduced normal matrix
//!
//! With `J_i = [J_q,i | J_s,i]` the weighted Jacobian of frame i (coordinates `q_i`, scaled
//! free parameters `s`) and `r_i = m_i − x_i`, projecting the per-frame coordinates out gives
//! the reduced (variable-projection) Jacobian `J_red,i = (I − J_q (J_qᵀWJ_q)⁻¹ J_qᵀW) J_s` and
//! the reduced normal matrix, the Schur complement of the block-arrow system of
//! [`super::schur`]:
//!
//! `S = Σ_i J_red,iᵀ W J_red,i = V − Σ_i W_iᵀ U_i⁻¹ W_i`.
//!
//! It is the Fisher information of `s` with the coordinates as nuisance parameters.
//!
//! # Covariance estimators
//!
//! * **white** (independent, equal-variance residuals): `C = σ² S⁻¹` with
//!   `σ² = e / (m − N·n_q − n_f)`, `e` the weighted squared residual sum, `m` the number of
//!   scalar residuals (3 per present marker sample), `N` frames, `n_q` coordinates per frame.
//! * **HAC sandwich** (Newey & West 1987): the per-frame profile score
//!   `ψ_i = J_red,iᵀ W r_i = J_s,iᵀWr_i − W_iᵀU_i⁻¹ J_q,iᵀWr_i` (at the optimum the second term
//!   vanishes, every `q_i` being an inner optimum) gives `C = c · S⁻¹ Ω S⁻¹` with the Bartlett
//!   long-run covariance `Ω = Σ_|l|<b (1 − |l|/b) Σ_i ψ_i ψ_{i+l}ᵀ`, pairs taken only within
//!   one trial. The bandwidth `b` is Andrews' (1991) AR(1) plug-in rule on the standardised
//!   influence series `S⁻¹ψ_i` unless given.
//! * **moving-block bootstrap** (Künsch 1989): blocks of consecutive frames are drawn with
//!   replacement until the trial length is reached, and the joint solver refits from the
//!   optimum; `C = c · cov(ŝ*)` over replicates. Seeded; replicates run in parallel but each
//!   has its own stream, so results do not depend on the thread count.
//!
//! Skin artifact is correlated in time, so the white formula understates the uncertainty;
//! the two robust estimators see that correlation. Both estimate the scatter from fitted
//! residuals, which the fit has pulled towards the model: with `n_f` parameters and `N`
//! frames the scores lose about `n_f/N` of their variance (the frame-level leverage sums to
//! `n_f`), so both are scaled by `c = N/(N − n_f)` (the usual cluster small-sample factor).
//! Each parameter's reported error is the **largest** of the available estimates, and the
//! report names the method that produced it.
//!
//! # Identifiability
//!
//! Parameters are converted to physical units with `∂p/∂s = (hi − lo)/2`. A parameter whose
//! interval half-width `z·se` exceeds a threshold (default 5 mm / 5°) is *poorly determined*;
//! one with weight on a numerically null direction of `S` (eigenvalue below `1e-10·λ_max`) is
//! *not determined* at all. The eigenvectors of `S` with the smallest eigenvalues name the
//! worst-determined combinations; their dominant components (squared weight ≥ 0.1) are put
//! into words from the parameters' descriptions, and each flagged parameter gets a reason
//! built from the range of motion of its joint's coordinates in the trial.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::joint::{solve_joint, JointOptions};
use super::schur::{assemble, Blocks};
use super::{Fit, Problem};
use crate::kinematics::KinData;
use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::model::{CoordKind, Model, Unit};

/// Eigenvalues of `S` below this fraction of the largest count as zero (not determined).
const NULL_RATIO: f64 = 1e-10;

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
        loop {
            l.copy_from_slice(u);
            for i in 0..nq {
                l[i * nq + i] += ridge;
            }
            if cholesky_in_place(&mut l, nq) {
                break;
            }
            ridge *= 100.0;
        }
        let w = &b.w[f * nq * nf..(f + 1) * nq * nf];
        y.copy_from_slice(w);
        for k in 0..nf {
            cholesky_solve(&l, nq, &mut y[k * nq..(k + 1) * nq]);
        }
        yg.copy_from_slice(&b.g[f * nq..(f + 1) * nq]);
        cholesky_solve(&l, nq, &mut yg);
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
                .zip(&prob.model.markers)
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

/// Which estimator produced a number.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SeMethod {
    /// `σ² S⁻¹`, independent residuals.
    White,
    /// Newey–West sandwich over frames.
    Hac,
    /// Moving-block bootstrap over frames with refits.
    Bootstrap,
    /// Delete-block jackknife over contiguous blocks of frames (linearised).
    Jackknife,
    /// The parameter lies on a null direction of `S`: no finite error.
    Undetermined,
}

/// How well the trial determines a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Identifiability {
    /// Interval half-width within the threshold.
    Determined,
    /// Half-width above the threshold, or the fit stopped at a bound.
    Poor,
    /// No information in the trial at all (null direction of `S`).
    Undetermined,
}

/// Settings of [`analyze`].
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyOptions {
    /// Coverage of the intervals (0.95).
    pub level: f64,
    /// Compute the Newey–West sandwich.
    pub hac: bool,
    /// Bartlett bandwidth in frames (lags `< b` get weight); `None`: Andrews' AR(1) rule.
    pub hac_bandwidth: Option<f64>,
    /// Bootstrap replicates (0, the default: no bootstrap; each replicate is a refit).
    pub bootstrap_replicates: usize,
    /// Block length in frames; `None`: the HAC bandwidth rounded up, at least 2.
    pub block_length: Option<usize>,
    /// Seed of the bootstrap.
    pub seed: u64,
    /// Contiguous blocks of the delete-block jackknife (0: no jackknife).
    pub jackknife_blocks: usize,
    /// Apply the small-sample factor `N/(N − n_f)` to the robust estimators.
    pub small_sample: bool,
    /// Assumed residual standard deviation per axis (m) instead of the one estimated from
    /// the residuals; the robust estimators are rescaled by the same variance ratio. For
    /// predictions at a nominal model, whose residuals include its misfit.
    pub assumed_sigma_m: Option<f64>,
    /// Half-width above which a length parameter is flagged (m).
    pub threshold_m: f64,
    /// Half-width above which an angle parameter is flagged (rad).
    pub threshold_rad: f64,
}

impl Default for UncertaintyOptions {
    fn default() -> Self {
        UncertaintyOptions {
            level: 0.95,
            hac: true,
            hac_bandwidth: None,
            bootstrap_replicates: 0,
            block_length: None,
            seed: 1,
            jackknife_blocks: 10,
            small_sample: true,
            assumed_sigma_m: None,
            threshold_m: 0.005,
            threshold_rad: 5f64.to_radians(),
        }
    }
}

/// One free parameter's uncertainty, in display units (mm or deg, see `unit`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamUncertainty {
    pub name: String,
    pub group: String,
    pub description: String,
    /// `"mm"` or `"deg"`.
    pub unit: String,
    /// Fitted (or evaluated) value.
    pub value: f64,
    /// Standard error of the estimator whose interval is widest; `None` when not determined.
    pub se: Option<f64>,
    /// Interval half-width: `se` times that estimator's critical value (`z`, or Student's t
    /// for the jackknife); `None` when not determined.
    pub half_width: Option<f64>,
    /// Interval `value ± half_width` at the report's level; `None` when not determined.
    pub ci: Option<[f64; 2]>,
    /// Which estimator `se` and the interval come from (the most conservative one).
    pub method: SeMethod,
    pub se_white: Option<f64>,
    pub se_hac: Option<f64>,
    pub se_bootstrap: Option<f64>,
    pub se_jackknife: Option<f64>,
    /// The value sits at a bound of the search box (the linear interval is then doubtful).
    pub at_bound: bool,
    pub status: Identifiability,
    /// Why a flagged parameter is poorly determined and which motion would determine it.
    pub reason: Option<String>,
}

/// One parameter's part in a weak direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DirectionComponent {
    pub name: String,
    /// Component of the unit eigenvector (scaled units).
    pub coefficient: f64,
    /// Interval half-width of this parameter along the direction (mm or deg); `None` for a
    /// null direction.
    pub half_width: Option<f64>,
    pub unit: String,
}

/// A poorly determined combination of parameters: an eigenvector of `S` with a small
/// eigenvalue.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeakDirection {
    /// Eigenvalue of `S` (m² per scaled unit²).
    pub eigenvalue: f64,
    /// Dominant components, largest first.
    pub components: Vec<DirectionComponent>,
    /// The combination in words.
    pub description: String,
}

/// Range of motion of one coordinate over the fitted frames, display units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoordRange {
    pub name: String,
    pub joint: String,
    /// `"deg"` or `"mm"`.
    pub unit: String,
    pub min: f64,
    pub max: f64,
    pub range: f64,
}

/// Bootstrap settings as used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BootstrapInfo {
    pub replicates: usize,
    /// Replicates whose refit did not converge (kept).
    pub not_converged: usize,
    pub block_length: usize,
    pub seed: u64,
}

/// Uncertainty and identifiability of the free parameters of one fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Interval coverage, e.g. 0.95.
    pub level: f64,
    /// Normal quantile: the critical value of the white, HAC and bootstrap intervals.
    pub z: f64,
    /// Student-t quantile with `K − 1` degrees of freedom: the jackknife's critical value.
    pub t_jackknife: Option<f64>,
    /// Blocks `K` of the delete-block jackknife, when computed.
    pub jackknife_blocks: Option<usize>,
    pub frames: usize,
    /// Scalar residuals `m`.
    pub observations: usize,
    /// Residual degrees of freedom `m − N·n_q − n_f`.
    pub dof: usize,
    /// Residual standard deviation per coordinate axis (mm): estimated, or as assumed.
    pub sigma_mm: f64,
    /// Whether `sigma_mm` was assumed (given) rather than estimated from the residuals.
    pub sigma_assumed: bool,
    /// Small-sample factor applied to the robust estimators.
    pub small_sample_factor: f64,
    /// Bartlett bandwidth of the HAC estimator (frames), when computed.
    pub hac_bandwidth: Option<f64>,
    pub bootstrap: Option<BootstrapInfo>,
    /// Flag thresholds (mm, deg).
    pub threshold_mm: f64,
    pub threshold_deg: f64,
    /// Per free parameter, in the problem's order.
    pub params: Vec<ParamUncertainty>,
    /// Correlation matrix of the free parameters from the white (Fisher) covariance; `None`
    /// entries involve an undetermined parameter.
    pub corr: Vec<Vec<Option<f64>>>,
    /// The weakest directions of `S` (smallest eigenvalue first) whose half-width exceeds
    /// the threshold for some component, at most 5.
    pub weak_directions: Vec<WeakDirection>,
    /// Range of motion of every coordinate over the frames.
    pub ranges: Vec<CoordRange>,
}

impl Uncertainty {
    /// Parameters flagged poor or undetermined.
    pub fn flagged(&self) -> impl Iterator<Item = &ParamUncertainty> {
        self.params
            .iter()
            .filter(|p| p.status != Identifiability::Determined)
    }
}

/// Display factor and unit of a parameter or coordinate.
fn display(unit: Unit) -> (f64, &'static str) {
    match unit {
        Unit::Metre => (1e3, "mm"),
        Unit::Radian => (180.0 / std::f64::consts::PI, "deg"),
    }
}

/// Symmetric pseudo-inverse and, per index, whether it touches a null direction.
fn pseudo_inverse(
    s: &DMatrix<f64>,
) -> (DMatrix<f64>, Vec<bool>, SymmetricEigen<f64, nalgebra::Dyn>) {
    let n = s.nrows();
    let eig = SymmetricEigen::new(s.clone());
    let max = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut inv = DMatrix::zeros(n, n);
    let mut null_weight = vec![0.0; n];
    for j in 0..n {
        let lam = eig.eigenvalues[j];
        let v = eig.eigenvectors.column(j);
        if lam > NULL_RATIO * max && lam > 0.0 {
            inv += (v * v.transpose()) / lam;
        } else {
            for k in 0..n {
                null_weight[k] += v[k] * v[k];
            }
        }
    }
    (inv, null_weight.iter().map(|w| *w > 1e-6).collect(), eig)
}

/// Newey–West long-run covariance of the scores with Bartlett bandwidth `b`; lags only
/// within one trial (`same[i]`: frame i+1 follows frame i in the same trial).
fn long_run(scores: &[DVector<f64>], same: &[bool], b: f64) -> DMatrix<f64> {
    let n = scores[0].len();
    let mut omega = DMatrix::zeros(n, n);
    for s in scores {
        omega += s * s.transpose();
    }
    let max_lag = (b.ceil() as usize).min(scores.len());
    for l in 1..max_lag {
        let w = 1.0 - l as f64 / b;
        if w <= 0.0 {
            break;
        }
        for i in 0..scores.len().saturating_sub(l) {
            if (i..i + l).all(|k| same[k]) {
                let g = &scores[i] * scores[i + l].transpose();
                omega += (&g + g.transpose()) * w;
            }
        }
    }
    omega
}

/// Andrews (1991) AR(1) plug-in bandwidth for the Bartlett kernel, on standardised series.
fn andrews_bandwidth(series: &[DVector<f64>]) -> f64 {
    let n = series.len();
    if n < 3 {
        return 1.0;
    }
    let dim = series[0].len();
    let (mut num, mut den) = (0.0, 0.0);
    for a in 0..dim {
        let x: Vec<f64> = series.iter().map(|v| v[a]).collect();
        let sd = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        if sd == 0.0 || !sd.is_finite() {
            continue;
        }
        let x: Vec<f64> = x.iter().map(|v| v / sd).collect();
        let sxy: f64 = x.windows(2).map(|w| w[0] * w[1]).sum();
        let sxx: f64 = x[..n - 1].iter().map(|v| v * v).sum();
        let rho = (sxy / sxx).clamp(-0.97, 0.97);
        let s2 = x
            .windows(2)
            .map(|w| (w[1] - rho * w[0]).powi(2))
            .sum::<f64>()
            / (n - 1) as f64;
        num += 4.0 * rho * rho * s2 * s2 / ((1.0 - rho).powi(6) * (1.0 + rho).powi(2));
        den += s2 * s2 / (1.0 - rho).powi(4);
    }
    if den == 0.0 {
        return 1.0;
    }
    (1.1447 * (num / den * n as f64).cbrt()).clamp(1.0, (n as f64 / 5.0).max(1.0))
}

/// Whether frame i+1 of the problem continues frame i's trial without a gap.
fn continuity(prob: &Problem) -> Vec<bool> {
    prob.origin
        .windows(2)
        .map(|w| w[0].0 == w[1].0 && w[1].1 == w[0].1 + 1)
        .collect()
}

/// Moving-block bootstrap: covariance (scaled units) of refitted `s` and the count of
/// replicates that did not converge.
fn block_bootstrap(
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
            sub.frames = idx.iter().map(|&i| prob.frames[i].clone()).collect();
            sub.origin = idx.iter().map(|&i| prob.origin[i]).collect();
            let q0 = idx.iter().map(|&i| fit.coords[i].clone()).collect();
            let f = solve_joint(&sub, &fit.s, q0, &opts);
            (f.s, f.converged)
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
/// it conservative where the fit absorbs part of the noise (few frames per parameter).
fn block_jackknife(red: &Reduced, scores: &[DVector<f64>], blocks: usize) -> DMatrix<f64> {
    let n = scores.len();
    let nf = red.normal.nrows();
    let mut deltas = Vec::with_capacity(blocks);
    for k in 0..blocks {
        let (a, b) = (k * n / blocks, (k + 1) * n / blocks);
        let mut s = red.normal.clone();
        let mut g = DVector::zeros(nf);
        for (ai, si) in red.frame_normals[a..b].iter().zip(&scores[a..b]) {
            s -= ai;
            g += si;
        }
        let (inv, _, _) = pseudo_inverse(&((&s + s.transpose()) * 0.5));
        deltas.push(inv * g);
    }
    let mean = deltas.iter().fold(DVector::zeros(nf), |a, d| a + d) / blocks as f64;
    let mut c = DMatrix::zeros(nf, nf);
    for d in &deltas {
        let e = d - &mean;
        c += &e * e.transpose();
    }
    c * ((blocks - 1) as f64 / blocks as f64)
}

/// Ranges of motion of every coordinate over the frames `qs` (display units).
pub fn coordinate_ranges(model: &Model, qs: &[Vec<f64>]) -> Vec<CoordRange> {
    model
        .coordinates
        .iter()
        .enumerate()
        .map(|(c, coord)| {
            let (k, unit) = match coord.kind {
                CoordKind::Rotational => (180.0 / std::f64::consts::PI, "deg"),
                CoordKind::Translational => (1e3, "mm"),
            };
            let vals = qs.iter().map(|q| q[c]).filter(|v| v.is_finite());
            let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
            CoordRange {
                name: coord.name.clone(),
                joint: model.joints[coord.joint.0].name.clone(),
                unit: unit.to_string(),
                min: lo * k,
                max: hi * k,
                range: (hi - lo) * k,
            }
        })
        .collect()
}

/// Rotations below this range (deg) are "barely moved" in reasons.
const SMALL_RANGE_DEG: f64 = 20.0;

/// The trial that exercises a coordinate, for the reason text.
fn suggestion(coord: &str) -> String {
    let c = coord.to_ascii_lowercase();
    if c.contains("hip") && (c.contains("adduction") || c.contains("abduction")) {
        "a hip circumduction trial (flexion-extension combined with ab-adduction) would determine it".into()
    } else if c.contains("hip") && c.contains("rotation") {
        "a trial with hip internal-external rotation would determine it".into()
    } else if c.contains("hip") {
        "a hip flexion-extension or circumduction trial would determine it".into()
    } else if c.contains("knee") {
        "a knee flexion-extension trial through at least 60° would determine it".into()
    } else if c.contains("ankle")
        || c.contains("talocrural")
        || c.contains("subtalar")
        || c.contains("inversion")
    {
        "an ankle toe-tip circumduction trial (plantar/dorsiflexion with inversion/eversion) would determine it".into()
    } else {
        format!("a trial moving {coord} through a larger range would determine it")
    }
}

/// Reason text for flagged free parameter `k` (model index `i`).
fn reason(
    model: &Model,
    i: usize,
    at_bound: bool,
    ranges: &[CoordRange],
    partner: Option<(&str, f64)>,
) -> String {
    let par = &model.parameters[i];
    let mut parts = Vec::new();
    let joint = par.uses.first().map(|u| u.joint.0);
    if let Some(j) = joint {
        let jname = &model.joints[j].name;
        let coords: Vec<&CoordRange> = ranges
            .iter()
            .zip(&model.coordinates)
            .filter(|(_, c)| c.joint.0 == j && c.kind == CoordKind::Rotational)
            .map(|(r, _)| r)
            .collect();
        // The barely moved axis to name: the smallest range, but an axial rotation only when
        // no other axis is also barely moved (circumduction excites a joint centre best).
        let small: Vec<&&CoordRange> = coords
            .iter()
            .filter(|r| r.range < SMALL_RANGE_DEG)
            .collect();
        let not_axial: Vec<&&CoordRange> = small
            .iter()
            .copied()
            .filter(|r| !r.name.contains("rotation"))
            .collect();
        let pool = if not_axial.is_empty() {
            small
        } else {
            not_axial
        };
        if let Some(small) = pool.iter().min_by(|a, b| a.range.total_cmp(&b.range)) {
            let moved: Vec<String> = coords
                .iter()
                .map(|r| format!("{} {:.0}°", r.name, r.range))
                .collect();
            parts.push(format!(
                "{jname} range of motion: {} ({} only {:.0}°); {}",
                moved.join(", "),
                small.name,
                small.range,
                suggestion(&small.name)
            ));
        } else if !coords.is_empty() {
            let moved: Vec<String> = coords
                .iter()
                .map(|r| format!("{} {:.0}°", r.name, r.range))
                .collect();
            parts.push(format!(
                "{jname} moved enough ({}), but noise is large for this many frames; a longer trial or more markers would help",
                moved.join(", ")
            ));
        }
    }
    if let Some((name, r)) = partner {
        parts.push(format!(
            "traded off against {name} (correlation {r:+.2}); fixing one would determine the other"
        ));
    }
    if at_bound {
        parts.push("the fit stopped at its bound, so the interval is only indicative".into());
    }
    parts.join("; ")
}

/// Inverse of the standard normal CDF (Acklam's rational approximation, |error| < 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        let t = (-2.0 * q.ln()).sqrt();
        (((((C[0] * t + C[1]) * t + C[2]) * t + C[3]) * t + C[4]) * t + C[5])
            / ((((D[0] * t + D[1]) * t + D[2]) * t + D[3]) * t + 1.0)
    };
    if p <= 0.0 {
        f64::NEG_INFINITY
    } else if p >= 1.0 {
        f64::INFINITY
    } else if p < 0.02425 {
        tail(p)
    } else if p > 1.0 - 0.02425 {
        -tail(1.0 - p)
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Quantile of Student's t with `nu` degrees of freedom from the normal one (Cornish–Fisher
/// expansion, Abramowitz & Stegun 26.7.5; relative error < 1e-4 for `nu ≥ 5` at 0.975).
pub fn t_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7, z9) = (z.powi(3), z.powi(5), z.powi(7), z.powi(9));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
        + (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / (92160.0 * nu.powi(4))
}

/// The covariance estimates (scaled units) of one analysis, before conversion.
struct Covariances {
    white: DMatrix<f64>,
    null: Vec<bool>,
    hac: Option<DMatrix<f64>>,
    bandwidth: Option<f64>,
    boot: Option<(DMatrix<f64>, BootstrapInfo)>,
    jack: Option<DMatrix<f64>>,
    factor: f64,
    eig: SymmetricEigen<f64, nalgebra::Dyn>,
}

/// `boot`: the problem and fit to refit for the bootstrap (none: no bootstrap). `same[i]`:
/// frame i+1 continues frame i's trial.
fn covariances(
    red: &Reduced,
    same: &[bool],
    boot: Option<(&Problem, &Fit)>,
    opts: &UncertaintyOptions,
    center_scores: bool,
) -> Covariances {
    let nf = red.normal.nrows();
    let n = red.scores.len();
    let (inv, null, eig) = pseudo_inverse(&red.normal);
    let estimated = red.sigma2();
    let sigma2 = opts.assumed_sigma_m.map_or(estimated, |s| s * s);
    // Robust estimators scale with the residuals; rescale them to the assumed noise.
    let rescale = if estimated > 0.0 && estimated.is_finite() {
        sigma2 / estimated
    } else {
        1.0
    };
    let white = &inv * sigma2;
    let factor = if opts.small_sample {
        if n > nf {
            n as f64 / (n - nf) as f64
        } else {
            f64::INFINITY
        }
    } else {
        1.0
    };
    let mut scores = red.scores.clone();
    if center_scores && n > 0 {
        // Away from the optimum the scores carry the systematic misfit; its mean is not noise.
        let mean = scores.iter().fold(DVector::zeros(nf), |a, s| a + s) / n as f64;
        for s in &mut scores {
            *s -= &mean;
        }
    }
    let (hac, bandwidth) = if opts.hac && n > 1 {
        let b = opts.hac_bandwidth.unwrap_or_else(|| {
            let sd: Vec<f64> = (0..nf).map(|k| white[(k, k)].sqrt()).collect();
            let infl: Vec<DVector<f64>> = scores
                .iter()
                .map(|s| {
                    let h = &inv * s;
                    DVector::from_iterator(
                        nf,
                        h.iter()
                            .zip(&sd)
                            .map(|(v, d)| if *d > 0.0 { v / d } else { 0.0 }),
                    )
                })
                .collect();
            andrews_bandwidth(&infl)
        });
        let omega = long_run(&scores, same, b);
        (Some(&inv * omega * &inv * (factor * rescale)), Some(b))
    } else {
        (None, None)
    };
    let boot = match boot {
        Some((prob, fit)) if opts.bootstrap_replicates > 1 => {
            let block = opts
                .block_length
                .unwrap_or_else(|| bandwidth.map_or(2, |b| (b.ceil() as usize).max(2)))
                .clamp(1, n.max(1));
            let (c, nc) = block_bootstrap(prob, fit, opts.bootstrap_replicates, block, opts.seed);
            Some((
                c * (factor * rescale),
                BootstrapInfo {
                    replicates: opts.bootstrap_replicates,
                    not_converged: nc,
                    block_length: block,
                    seed: opts.seed,
                },
            ))
        }
        _ => None,
    };
    let jack = (opts.jackknife_blocks > 1 && n >= opts.jackknife_blocks)
        .then(|| block_jackknife(red, &scores, opts.jackknife_blocks) * rescale);
    Covariances {
        white,
        null,
        hac,
        bandwidth,
        boot,
        jack,
        factor,
        eig,
    }
}

/// Uncertainty of the fitted free parameters of `fit` (a solution of `prob`).
pub fn analyze(prob: &Problem, fit: &Fit, opts: &UncertaintyOptions) -> Uncertainty {
    let red = reduced_system(prob, &fit.p, &fit.coords);
    let cov = covariances(&red, &continuity(prob), Some((prob, fit)), opts, false);
    build(prob, &fit.p, &fit.s, &fit.coords, &red, &cov, opts)
}

/// Predicted uncertainty at parameters `p` (scaled `s`) with inner solutions `qs`, before
/// any fit: white and HAC estimates only (no bootstrap), scores centred on their mean so
/// that the systematic misfit of a nominal model does not count as noise. `σ²` comes from
/// the residuals at `p`, which include that misfit: the prediction is conservative.
pub fn predict(
    prob: &Problem,
    p: &[f64],
    qs: &[Vec<f64>],
    opts: &UncertaintyOptions,
) -> Uncertainty {
    let red = reduced_system(prob, p, qs);
    let cov = covariances(&red, &continuity(prob), None, opts, true);
    build(prob, p, &prob.to_scaled(p), qs, &red, &cov, opts)
}

/// Critical values: `z` for white, HAC and bootstrap; Student's t with `K − 1` degrees of
/// freedom for the `K`-block jackknife.
fn critical(level: f64, opts: &UncertaintyOptions) -> (f64, f64) {
    let p = 0.5 + 0.5 * level;
    let k = opts.jackknife_blocks.max(2) as f64;
    (normal_quantile(p), t_quantile(p, k - 1.0))
}

/// One estimator's `(se, half-width, method)`.
type Estimate = (f64, f64, SeMethod);

/// Per estimator `(se, half-width, method)` of the quadratic form `f(C)` (a variance in
/// scaled units), and the most conservative one (largest half-width).
fn conservative(
    cov: &Covariances,
    crit: (f64, f64),
    f: impl Fn(&DMatrix<f64>) -> f64,
) -> (Vec<Estimate>, Option<Estimate>) {
    let mut all = vec![(f(&cov.white).max(0.0).sqrt(), crit.0, SeMethod::White)];
    if let Some(h) = &cov.hac {
        all.push((f(h).max(0.0).sqrt(), crit.0, SeMethod::Hac));
    }
    if let Some((b, _)) = &cov.boot {
        all.push((f(b).max(0.0).sqrt(), crit.0, SeMethod::Bootstrap));
    }
    if let Some(j) = &cov.jack {
        all.push((f(j).max(0.0).sqrt(), crit.1, SeMethod::Jackknife));
    }
    let out: Vec<Estimate> = all.iter().map(|(s, c, m)| (*s, s * c, *m)).collect();
    let best = out
        .iter()
        .copied()
        .filter(|v| v.1.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1));
    (out, best)
}

fn build(
    prob: &Problem,
    p: &[f64],
    s: &[f64],
    qs: &[Vec<f64>],
    red: &Reduced,
    cov: &Covariances,
    opts: &UncertaintyOptions,
) -> Uncertainty {
    let model = prob.model;
    let nf = prob.n_free();
    let crit = critical(opts.level, opts);
    let z = crit.0;
    let ranges = coordinate_ranges(model, qs);
    let scale: Vec<f64> = (0..nf)
        .map(|k| prob.half_range(k) * display(model.parameters[prob.free[k]].unit).0)
        .collect();
    let threshold = |k: usize| match model.parameters[prob.free[k]].unit {
        Unit::Metre => opts.threshold_m * 1e3,
        Unit::Radian => opts.threshold_rad.to_degrees(),
    };
    let corr: Vec<Vec<Option<f64>>> = (0..nf)
        .map(|a| {
            (0..nf)
                .map(|b| {
                    if cov.null[a] || cov.null[b] {
                        None
                    } else {
                        let d = (cov.white[(a, a)] * cov.white[(b, b)]).sqrt();
                        Some(if d > 0.0 { cov.white[(a, b)] / d } else { 0.0 })
                    }
                })
                .collect()
        })
        .collect();
    let params = (0..nf)
        .map(|k| {
            let i = prob.free[k];
            let par = &model.parameters[i];
            let (f, unit) = display(par.unit);
            let value = p[i] * f;
            let at_bound = s[k].abs() >= 1.0 - 1e-9;
            let (all, best) = conservative(cov, crit, |c| c[(k, k)]);
            let of = |m: SeMethod| {
                all.iter()
                    .find(|v| v.2 == m && !cov.null[k])
                    .map(|v| v.0 * scale[k])
            };
            let (se, half_width, method) = match best {
                Some((v, h, m)) if !cov.null[k] => (Some(v * scale[k]), Some(h * scale[k]), m),
                _ => (None, None, SeMethod::Undetermined),
            };
            let status = match half_width {
                None => Identifiability::Undetermined,
                Some(h) if h > threshold(k) || at_bound => Identifiability::Poor,
                Some(_) => Identifiability::Determined,
            };
            let reason = (status != Identifiability::Determined).then(|| {
                let partner = (0..nf)
                    .filter(|&b| b != k)
                    .filter_map(|b| corr[k][b].map(|r| (b, r)))
                    .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                    .filter(|(_, r)| r.abs() >= 0.9)
                    .map(|(b, r)| (model.parameters[prob.free[b]].name.as_str(), r));
                let text = reason(model, i, at_bound, &ranges, partner);
                if status == Identifiability::Undetermined {
                    format!("not determined by this trial at all: {text}")
                } else {
                    text
                }
            });
            ParamUncertainty {
                name: par.name.clone(),
                group: par.group.clone(),
                description: par.description.clone(),
                unit: unit.to_string(),
                value,
                se,
                half_width,
                ci: half_width.map(|h| [value - h, value + h]),
                method,
                se_white: of(SeMethod::White),
                se_hac: of(SeMethod::Hac),
                se_bootstrap: of(SeMethod::Bootstrap),
                se_jackknife: of(SeMethod::Jackknife),
                at_bound,
                status,
                reason,
            }
        })
        .collect();
    let weak_directions = weak_directions(prob, cov, &scale, crit, opts);
    let sigma2 = opts.assumed_sigma_m.map_or(red.sigma2(), |s| s * s);
    Uncertainty {
        level: opts.level,
        z,
        t_jackknife: cov.jack.as_ref().map(|_| crit.1),
        jackknife_blocks: cov.jack.as_ref().map(|_| opts.jackknife_blocks),
        frames: red.scores.len(),
        observations: red.observations,
        dof: red.dof(),
        sigma_mm: sigma2.sqrt() * 1e3,
        sigma_assumed: opts.assumed_sigma_m.is_some(),
        small_sample_factor: cov.factor,
        hac_bandwidth: cov.bandwidth,
        bootstrap: cov.boot.as_ref().map(|(_, b)| b.clone()),
        threshold_mm: opts.threshold_m * 1e3,
        threshold_deg: opts.threshold_rad.to_degrees(),
        params,
        corr,
        weak_directions,
        ranges,
    }
}

/// The weakest eigen-directions of `S` (at most 5) with some component over its threshold.
fn weak_directions(
    prob: &Problem,
    cov: &Covariances,
    scale: &[f64],
    crit: (f64, f64),
    opts: &UncertaintyOptions,
) -> Vec<WeakDirection> {
    let model = prob.model;
    let nf = prob.n_free();
    let max = cov
        .eig
        .eigenvalues
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let mut order: Vec<usize> = (0..nf).collect();
    order.sort_by(|&a, &b| cov.eig.eigenvalues[a].total_cmp(&cov.eig.eigenvalues[b]));
    let mut out = Vec::new();
    for j in order {
        let lam = cov.eig.eigenvalues[j];
        let v = cov.eig.eigenvectors.column(j).into_owned();
        let null = !(lam > NULL_RATIO * max && lam > 0.0);
        // Half-width along the direction: the most conservative estimator.
        let hw = if null {
            f64::INFINITY
        } else {
            conservative(cov, crit, |c| (v.transpose() * c * &v)[(0, 0)])
                .1
                .map_or(f64::INFINITY, |b| b.1)
        };
        let mut comps: Vec<usize> = (0..nf).filter(|&k| v[k] * v[k] >= 0.1).collect();
        comps.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
        let over = (0..nf).any(|k| {
            let par = &model.parameters[prob.free[k]];
            let t = match par.unit {
                Unit::Metre => opts.threshold_m * 1e3,
                Unit::Radian => opts.threshold_rad.to_degrees(),
            };
            hw * v[k].abs() * scale[k] > t
        });
        if !over {
            continue;
        }
        let components: Vec<DirectionComponent> = comps
            .iter()
            .map(|&k| {
                let par = &model.parameters[prob.free[k]];
                DirectionComponent {
                    name: par.name.clone(),
                    coefficient: v[k],
                    half_width: hw.is_finite().then(|| hw * v[k].abs() * scale[k]),
                    unit: display(par.unit).1.to_string(),
                }
            })
            .collect();
        let words: Vec<String> = comps
            .iter()
            .map(|&k| {
                let par = &model.parameters[prob.free[k]];
                let sign = if v[k] * v[comps[0]] >= 0.0 {
                    "+"
                } else {
                    "−"
                };
                let d = if par.description.is_empty() {
                    &par.name
                } else {
                    &par.description
                };
                let hw_k = if hw.is_finite() {
                    format!("±{:.1} {}", hw * v[k].abs() * scale[k], display(par.unit).1)
                } else {
                    "unbounded".to_string()
                };
                format!("{sign}[{d}] {hw_k}")
            })
            .collect();
        let lead = if null {
            "not determined at all"
        } else {
            "poorly determined"
        };
        let description = if words.is_empty() {
            format!("{lead}: a combination spread over many parameters")
        } else if words.len() == 1 {
            format!("{lead}: {}", words[0])
        } else {
            format!(
                "{lead} combination (moving together as signed): {}",
                words.join(", ")
            )
        };
        out.push(WeakDirection {
            eigenvalue: lam,
            components,
            description,
        });
        if out.len() == 5 {
            break;
        }
    }
    out
}

/// Subset selection: which free parameters (indices into `prob.free`) to hold fixed so that
/// the others are determined within the thresholds.
///
/// Greedy, on the reduced normal matrix at the fit: the reduced matrix of a subset is the
/// sub-block `S[keep, keep]` (the coordinates are projected out column by column) and the
/// HAC meat is the same sub-block of `Ω`, so no refit is needed to plan. While a kept
/// parameter is flagged, the flagged one with the largest weight in the weakest eigenvector
/// of `S[keep, keep]` is removed (Golub, Klema & Stewart 1976 style). The caller refits with
/// the rest and re-analyses.
pub fn unidentifiable_subset(prob: &Problem, fit: &Fit, opts: &UncertaintyOptions) -> Vec<usize> {
    let red = reduced_system(prob, &fit.p, &fit.coords);
    let same = continuity(prob);
    let crit = critical(opts.level, opts);
    let threshold = |k: usize| match prob.model.parameters[prob.free[k]].unit {
        Unit::Metre => opts.threshold_m,
        Unit::Radian => opts.threshold_rad,
    };
    let mut keep: Vec<usize> = (0..prob.n_free()).collect();
    let mut removed = Vec::new();
    while !keep.is_empty() {
        let m = keep.len();
        let pick = |v: &DVector<f64>| DVector::from_iterator(m, keep.iter().map(|&k| v[k]));
        let sub = Reduced {
            normal: DMatrix::from_fn(m, m, |a, b| red.normal[(keep[a], keep[b])]),
            scores: red.scores.iter().map(pick).collect(),
            frame_normals: red
                .frame_normals
                .iter()
                .map(|a| DMatrix::from_fn(m, m, |x, y| a[(keep[x], keep[y])]))
                .collect(),
            cost: red.cost,
            observations: red.observations,
            n_q: red.n_q,
        };
        let cov = covariances(&sub, &same, None, opts, false);
        let flagged: Vec<usize> = (0..m)
            .filter(|&a| {
                let hw = conservative(&cov, crit, |c| c[(a, a)]).1.map(|b| b.1);
                cov.null[a] || hw.is_none_or(|h| h * prob.half_range(keep[a]) > threshold(keep[a]))
            })
            .collect();
        if flagged.is_empty() {
            break;
        }
        let weakest = (0..m)
            .min_by(|&a, &b| cov.eig.eigenvalues[a].total_cmp(&cov.eig.eigenvalues[b]))
            .unwrap_or(0);
        let v = cov.eig.eigenvectors.column(weakest);
        let worst = *flagged
            .iter()
            .max_by(|&&a, &&b| v[a].abs().total_cmp(&v[b].abs()))
            .unwrap_or(&flagged[0]);
        removed.push(keep.remove(worst));
    }
    removed.sort();
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantile_matches_tables() {
        // Student t 0.975 quantiles: 9 dof 2.262157, 19 dof 2.093024, 4 dof 2.776445.
        assert!((t_quantile(0.975, 9.0) - 2.262157).abs() < 2e-4);
        assert!((t_quantile(0.975, 19.0) - 2.093024).abs() < 1e-5);
        assert!((t_quantile(0.975, 4.0) - 2.776445).abs() < 5e-3);
    }

    #[test]
    fn normal_quantile_matches_known_values() {
        assert!((normal_quantile(0.975) - 1.959963984540054).abs() < 1e-8);
        assert!((normal_quantile(0.5)).abs() < 1e-12);
        assert!((normal_quantile(0.005) + 2.5758293035489).abs() < 1e-8);
    }

    #[test]
    fn bartlett_long_run_of_white_scores_is_their_sum_of_squares() {
        let scores: Vec<DVector<f64>> = (0..5)
            .map(|i| DVector::from_vec(vec![i as f64, 1.0]))
            .collect();
        let same = vec![true; 4];
        let o = long_run(&scores, &same, 1.0);
        assert_eq!(o[(0, 0)], 30.0);
        // Bandwidth 2: lag-1 products get weight 1/2; not across a trial boundary.
        let o2 = long_run(&scores, &same, 2.0);
        assert_eq!(o2[(0, 0)], 30.0 + (0.0 + 2.0 + 6.0 + 12.0));
        let cut = vec![true, false, true, true];
        let o3 = long_run(&scores, &cut, 2.0);
        assert_eq!(o3[(0, 0)], 30.0 + (0.0 + 6.0 + 12.0));
    }
}
