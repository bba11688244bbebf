//! A secant model of the second-order term on the parameters' block of the joint problem.
//!
//! The joint solver's Gauss–Newton model of `F = Σ w‖r‖²` has the Hessian `2 JᵀWJ`; the true
//! one adds `2 Σ w rᵢ ∇²rᵢ`, which is not small where the residuals are large (running,
//! skin-marker artefacts). Along a direction where it cancels most of `JᵀWJ` the Gauss–Newton
//! steps are too short by the ratio of the two curvatures and the iterates converge linearly
//! (the gain ratio ρ → 2 when the true curvature is zero). On Hamner running the solve spent
//! iterations 10–80 of 110 so, at the damping floor, the parameters moving some 3e-3 (scaled)
//! per step; the secant pairs below measured `δᵀy♯ / δᵀSδ` between −0.3 and −0.9 there: the
//! missing term cancelled 30–90 % of the Gauss–Newton curvature along the steps.
//!
//! **The model.** As in NL2SOL (Dennis, Gay & Welsch, *An adaptive nonlinear least-squares
//! algorithm*, ACM TOMS 7, 1981) a matrix `A` stands for the missing term, here only on the
//! Schur-reduced system of the parameters: the coordinates of every frame are eliminated
//! exactly as before, and the reduced model is `S + A` with `S = V − Σ WᵢᵀUᵢ⁻¹Wᵢ` the
//! Gauss–Newton reduced normal matrix (`schur.rs`). With `g(s)` the reduced right-hand
//! side (`g_s − Σ WᵢᵀUᵢ⁻¹gᵢ`, a half negative gradient of the objective with the coordinates
//! at their linearized optimum) and an accepted parameter step `δ` from `s` to `s₊`, the
//! reduced Hessian must satisfy the secant condition `(S₊ + A₊) δ = y`, `y = g(s) − g(s₊)`,
//! i.e. `A₊ δ = y♯ := y − S₊ δ`.
//!
//! **The update** is the symmetric rank one (SR1) one, `A₊ = A + v vᵀ / (vᵀδ)` with
//! `v = y♯ − A δ` (Nocedal & Wright, *Numerical Optimization*, 2nd ed. 2006, §6.2): unlike the
//! DGW update of NL2SOL it needs no `yᵀδ > 0` and so learns negative curvature, the case that
//! crawls here. It is skipped when `|vᵀδ| < 1e-8 ‖v‖‖δ‖` (Nocedal & Wright's safeguard).
//! NL2SOL's sizing of `A` (times `min(1, |δᵀy♯| / |δᵀAδ|)` before the update) is not used: it
//! belongs to the DGW update, and before SR1 it makes `vᵀδ = 0` exactly whenever `δᵀAδ` and
//! `δᵀy♯` have the same sign and `A` overestimates, so the update was always skipped there
//! (found by the secant-condition test; with the sizing Hamner running took 85 iterations at
//! θ = 0.2, without it 77).
//!
//! **Choosing the model.** After each accepted step both models' predicted decreases of the
//! objective are compared with the actual one: the Gauss–Newton `p = 2hᵀΔ − ΔᵀHΔ` and the
//! augmented `p − δᵀAδ`; the next step uses the one that predicted better (NL2SOL's rule).
//! Starting from Gauss–Newton, a problem whose residuals are small keeps it.
//!
//! **Keeping the model convex.** Where the missing term exceeds `S` (negative true
//! curvature) `S + A` is indefinite and the damped system would need a large λ (raised
//! tenfold per failed factorisation) that shortens the step in every other direction too: on
//! Hamner running λ then stayed at 1e-4–1e-2 and the solve took 170 iterations instead of
//! 110. The step therefore uses `A` limited so that `S + A ⪰ θ S` (θ = [`CURVATURE_FLOOR`]):
//! in no direction is the model's curvature below θ of Gauss–Newton's, so a step is at most
//! 1/θ times Gauss–Newton's along any direction, and the gain ratio ρ decides, as before,
//! whether it is taken. θ = 0.05, 0.1, 0.2 and 0.5 were measured (`notebook/performance_fit.md`);
//! 0.2 gave the fewest iterations on Hamner running and opencap walking1.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::linalg::{cholesky_in_place, forward_solve};

/// Least fraction θ of the Gauss–Newton reduced curvature that the augmented model keeps in
/// every direction (`S + A ⪰ θ S`, [`Secant::limited`]).
pub(crate) const CURVATURE_FLOOR: f64 = 0.2;

/// `A` and what its update needs.
pub(crate) struct Secant {
    n: usize,
    /// `A` (n × n, column-major).
    a: Vec<f64>,
    /// The reduced right-hand side at the current point and the step taken from it.
    last: Option<(Vec<f64>, Vec<f64>)>,
    /// The reduced right-hand side at the current point, until the step is known.
    here: Option<Vec<f64>>,
    /// Whether the next step uses `S + A` (else Gauss–Newton's `S`).
    augmented: bool,
}

impl Secant {
    pub(crate) fn new(n: usize) -> Self {
        Secant {
            n,
            a: vec![0.0; n * n],
            last: None,
            here: None,
            augmented: false,
        }
    }

    /// Whether the next step uses the augmented model.
    pub(crate) fn augmented(&self) -> bool {
        self.augmented
    }

    /// `A` limited so that `S + A ⪰ θ S` ([`CURVATURE_FLOOR`]) for the reduced matrix `s`
    /// of the step (n × n, column-major): in the metric of `S = L Lᵀ` the eigenvalues of
    /// `L⁻¹ A L⁻ᵀ` are raised to at least `θ − 1`. `None` while `A` is zero or when `S` is not
    /// positive definite.
    pub(crate) fn limited(&self, s: &[f64]) -> Option<Vec<f64>> {
        let n = self.n;
        if self.a.iter().all(|&x| x == 0.0) {
            return None;
        }
        let mut l = s.to_vec();
        let max_diag = (0..n).fold(0.0f64, |m, i| m.max(s[i * n + i]));
        for k in 0..n {
            l[k * n + k] += 1e-14 * max_diag + 1e-300;
        }
        if !cholesky_in_place(&mut l, n) {
            return None;
        }
        // M = L⁻¹ A L⁻ᵀ: both sides by forward substitution (A symmetric).
        let mut m = DMatrix::from_column_slice(n, n, &self.a);
        for _ in 0..2 {
            for c in 0..n {
                let mut col: Vec<f64> = m.column(c).iter().copied().collect();
                forward_solve(&l, n, &mut col);
                m.column_mut(c).copy_from_slice(&col);
            }
            m.transpose_mut();
        }
        let m = (&m + m.transpose()) * 0.5;
        let eig = SymmetricEigen::new(m);
        let values = eig.eigenvalues.map(|v| v.max(CURVATURE_FLOOR - 1.0));
        let m = &eig.eigenvectors * DMatrix::from_diagonal(&values) * eig.eigenvectors.transpose();
        // A' = L M Lᵀ
        let lm = DMatrix::from_fn(n, n, |r, c| if r >= c { l[c * n + r] } else { 0.0 });
        let a = &lm * m * lm.transpose();
        let a = (&a + a.transpose()) * 0.5;
        Some(a.as_slice().to_vec())
    }

    /// `dᵀ M d` for `m` (n × n, column-major).
    pub(crate) fn curvature(&self, m: &[f64], d: &[f64]) -> f64 {
        quad(m, self.n, d)
    }

    /// At a new point: the undamped reduced matrix `s` and right-hand side `g` there. Updates
    /// `A` with the secant pair from the previous point, when there was one.
    pub(crate) fn observe(&mut self, s: &[f64], g: &[f64]) {
        if let Some((g0, d)) = self.last.take() {
            let n = self.n;
            // y♯ = g(s) − g(s₊) − S₊ δ
            let ys: Vec<f64> = (0..n)
                .map(|i| g0[i] - g[i] - (0..n).map(|k| s[k * n + i] * d[k]).sum::<f64>())
                .collect();
            self.update(&d, &ys);
        }
        self.here = Some(g.to_vec());
    }

    /// The point's data are not available (a singular frame at λ = 0): no update from it.
    pub(crate) fn forget(&mut self) {
        self.last = None;
        self.here = None;
    }

    /// The step `d` was accepted; `actual` the objective's decrease, `gauss_newton` and
    /// `augmented` the two models' predictions: picks the model for the next step.
    pub(crate) fn accepted(&mut self, d: &[f64], actual: f64, gauss_newton: f64, augmented: f64) {
        self.augmented = (actual - augmented).abs() < (actual - gauss_newton).abs();
        self.last = self.here.take().map(|g| (g, d.to_vec()));
    }

    /// The SR1 update for the pair `(d, ys)`: `A₊ d = ys`.
    fn update(&mut self, d: &[f64], ys: &[f64]) {
        let n = self.n;
        let v: Vec<f64> = (0..n)
            .map(|i| ys[i] - (0..n).map(|k| self.a[k * n + i] * d[k]).sum::<f64>())
            .collect();
        let vd: f64 = v.iter().zip(d).map(|(a, b)| a * b).sum();
        let norm = |x: &[f64]| x.iter().map(|a| a * a).sum::<f64>().sqrt();
        if vd.abs() < 1e-8 * norm(&v) * norm(d) || vd == 0.0 {
            return;
        }
        for c in 0..n {
            for r in 0..n {
                self.a[c * n + r] += v[r] * v[c] / vd;
            }
        }
    }
}

/// `dᵀ M d` for `M` (n × n, column-major).
fn quad(m: &[f64], n: usize, d: &[f64]) -> f64 {
    (0..n)
        .map(|c| d[c] * (0..n).map(|r| m[c * n + r] * d[r]).sum::<f64>())
        .sum()
}

#[cfg(test)]
#[path = "secant_tests.rs"]
mod tests;
