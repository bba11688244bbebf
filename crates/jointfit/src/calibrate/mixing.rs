//! Anderson mixing of the joint solver's steps in the tail.
//!
//! **Why.** Near the optimum of a large-residual problem Gauss–Newton converges linearly:
//! its model misses the second-order term `Σ w rᵢ∇²rᵢ`, so the iterate map
//! `x ↦ G(x) = x + f(x)`, `f` the Gauss–Newton step, contracts the error by a fixed matrix
//! `M = I − H_GN⁻¹H` whose largest eigenvalues set the rate. On gait2392 walk1 the finishing
//! solve's objective fell by a ratio of 0.41 per iteration from its seventh iteration to its
//! nineteenth (`notebook/solver_tail.md`). The slow modes are shared by the parameters and
//! every frame's coordinates: mixing the parameters' steps alone, with the coordinates
//! eliminated again for the mixed parameters, left the tail as it was.
//!
//! **The method** (Anderson, *Iterative procedures for nonlinear integral equations*, J. ACM
//! 12, 1965; Walker & Ni, *Anderson acceleration for fixed-point iterations*, SIAM J. Numer.
//! Anal. 49, 2011). With the last `m` Gauss–Newton steps `f_j` and the steps `Δx_j` actually
//! taken, `ΔF_j = f_{j+1} − f_j` (the newest `f_{j+1}` is the current step `f_k`), the
//! coefficients `γ` minimise `‖f_k − Σ γ_j ΔF_j‖` and the step taken is
//! `f_k − Σ γ_j (Δx_j + ΔF_j)`. On an affine map this is GMRES on `(I − M) e = f`: the
//! slow eigenvectors that the `m` differences span are removed at once.
//!
//! The norm is that of the parameters' components alone (scaled to their half-ranges, so
//! dimensionless and of one size): the coordinates follow the parameters (the joint
//! problem's coordinates are, to first order, a function of the parameters), and a norm
//! over thousands of coordinates would let them choose `γ` for what the data resolve least.
//! The same combination moves the coordinates of every frame.
//!
//! **When.** The method needs one fixed map `G`. The Levenberg–Marquardt step is one where
//! the damping is negligible (λ ≤ [`super::RESOLUTION_MAX_DAMPING`], the Gauss–Newton step),
//! and nearly one where the damping has settled: on long large-residual trials the gain
//! ratio stays below ½ and the damping drifts by about 10 % per iteration to the end (Hamner
//! running: λ ≈ 2e-5 … 1e-4 for 20 iterations). So steps are remembered and mixed when
//! undamped, or when the damping is within a factor of 2 of the remembered steps' and the
//! point is within a standard error of its model's optimum: the step's predicted decrease
//! below σ² (the solver's noise variance; `d² σ²` is the predicted decrease at Mahalanobis
//! distance `d`, [`super`]'s module docs). Mixing the damped steps farther out was measured
//! and not kept: on one synthetic leg (4 cm skin noise) it carried the solve into another
//! optimum, 2.4 SE away and 0.7 % higher. The history is cleared by a rejected step, by a
//! step outside these conditions and when the set of parameters held at bounds changes. A mixed step that raises the objective is not taken: the plain Gauss–Newton
//! step at the same damping is tried instead, and the history restarts. The history holds
//! `2m` vectors of every frame's coordinates and the current step's copy, so it is kept only
//! while they fit in [`MIXING_BYTES`] (up to 49,000 frames of the built-in leg's 12
//! coordinates, 29,000 of gait2392's 23; beyond, the tail is plain Gauss–Newton).
//!
//! **The damping and the stopping rule** see the Gauss–Newton step of the current point: its
//! predicted decrease is the model decrease of the statistical stopping rule and the
//! denominator of the gain ratio ρ (a mixed step that does better raises ρ, and the damping,
//! already negligible here, falls). The result is a point within the same resolution of the
//! same optimum, reached by a different path, so its last digits differ from the plain
//! solve's.

use rayon::prelude::*;

/// Steps remembered (`m`): two differences. On gait2392 walk1 depths 2, 3 and 5 gave the
/// same finishing solve (19 → 11 iterations); 2 keeps the least memory.
const DEPTH: usize = 2;

/// Memory for the history of the coordinates' steps and the current step's copy (bytes).
pub(crate) const MIXING_BYTES: usize = 32 << 20;

/// Bytes of one frame's coordinate vector beside its numbers: the `Vec` header and the
/// allocator's rounding (a 12-coordinate vector is a 112-byte chunk and 24 bytes of header).
const VEC_OVERHEAD: usize = 40;

/// Frames per parallel task of the element-wise combination.
const PAR_FRAMES: usize = 1024;

/// One remembered iteration: its Gauss–Newton step `f` and the step taken `Δx`, each as
/// (parameters, every frame's coordinates).
struct Entry {
    f_s: Vec<f64>,
    f_q: Vec<Vec<f64>>,
    dx_s: Vec<f64>,
    dx_q: Vec<Vec<f64>>,
    held: Vec<bool>,
    /// The damping of the step.
    lambda: f64,
}

impl Entry {
    /// Whether a step with parameters `held` at bounds, at damping `lambda`, continues this
    /// one's map (the history stays valid).
    fn continued_by(&self, held: &[bool], lambda: f64) -> bool {
        self.held == held && same_map(self.lambda, lambda)
    }
}

/// The history of the tail's steps, oldest first.
pub(crate) struct Mixing {
    enabled: bool,
    past: Vec<Entry>,
}

impl Mixing {
    /// Mixing for a solve over `frames` frames of `nq` coordinates when `wanted` (off when
    /// the history would not fit in [`MIXING_BYTES`]).
    pub(crate) fn new(frames: usize, nq: usize, wanted: bool) -> Self {
        let per_frame = (2 * DEPTH + 1) * (nq * std::mem::size_of::<f64>() + VEC_OVERHEAD);
        let bytes = frames * per_frame;
        Mixing {
            enabled: wanted && bytes <= MIXING_BYTES,
            past: Vec::with_capacity(DEPTH + 1),
        }
    }

    /// Whether steps are remembered and mixed at all.
    pub(crate) fn on(&self) -> bool {
        self.enabled
    }

    pub(crate) fn clear(&mut self) {
        self.past.clear();
    }

    /// Remembers an accepted step: the Gauss–Newton step `(f_s, f_q)` at its point and the
    /// step taken `(dx_s, dx_q)`, with the parameters held at bounds.
    pub(crate) fn push(
        &mut self,
        f_s: &[f64],
        f_q: &[Vec<f64>],
        dx_s: &[f64],
        dx_q: &[Vec<f64>],
        held: &[bool],
        lambda: f64,
    ) {
        if !self.enabled {
            return;
        }
        if self
            .past
            .last()
            .is_some_and(|e| !e.continued_by(held, lambda))
        {
            self.past.clear();
        }
        // The oldest entry's buffers are reused for the newest.
        let mut e = if self.past.len() == DEPTH {
            self.past.remove(0)
        } else {
            Entry {
                f_s: Vec::new(),
                f_q: Vec::new(),
                dx_s: Vec::new(),
                dx_q: Vec::new(),
                held: Vec::new(),
                lambda: 0.0,
            }
        };
        copy(&mut e.f_s, f_s);
        copy_frames(&mut e.f_q, f_q);
        copy(&mut e.dx_s, dx_s);
        copy_frames(&mut e.dx_q, dx_q);
        copy(&mut e.held, held);
        e.lambda = lambda;
        self.past.push(e);
    }

    /// The mixed step from the current Gauss–Newton step `(f_s, f_q)` into `(out_s, out_q)`
    /// (the held parameters' components zero); false when there is no history for the same
    /// held parameters or the differences are degenerate (then the outputs are untouched).
    pub(crate) fn mix(
        &self,
        f_s: &[f64],
        f_q: &[Vec<f64>],
        held: &[bool],
        lambda: f64,
        out_s: &mut [f64],
        out_q: &mut [Vec<f64>],
    ) -> bool {
        if self
            .past
            .last()
            .is_none_or(|e| !e.continued_by(held, lambda))
        {
            return false;
        }
        let Some(gamma) = self.coefficients(f_s) else {
            return false;
        };
        for (i, o) in out_s.iter_mut().enumerate() {
            let mut v = f_s[i];
            for (j, e) in self.past.iter().enumerate() {
                let next = self.newer(j, f_s, f_q).0[i];
                v -= gamma[j] * (e.dx_s[i] + next - e.f_s[i]);
            }
            *o = if held[i] { 0.0 } else { v };
        }
        out_q
            .par_iter_mut()
            .enumerate()
            .with_min_len(PAR_FRAMES)
            .for_each(|(t, o)| {
                for (i, o) in o.iter_mut().enumerate() {
                    let mut v = f_q[t][i];
                    for (j, e) in self.past.iter().enumerate() {
                        let next = self.newer(j, f_s, f_q).1[t][i];
                        v -= gamma[j] * (e.dx_q[t][i] + next - e.f_q[t][i]);
                    }
                    *o = v;
                }
            });
        true
    }

    /// The Gauss–Newton step that follows entry `j`: the next entry's, or the current one
    /// (`f_s`, `f_q`) after the last.
    fn newer<'a>(
        &'a self,
        j: usize,
        f_s: &'a [f64],
        f_q: &'a [Vec<f64>],
    ) -> (&'a [f64], &'a [Vec<f64>]) {
        match self.past.get(j + 1) {
            Some(e) => (&e.f_s, &e.f_q),
            None => (f_s, f_q),
        }
    }

    /// `γ = argmin ‖f − ΔF γ‖` over the parameters' components (normal equations, a
    /// relative ridge of 1e-10 on their diagonal); `None` when they are singular.
    fn coefficients(&self, f_s: &[f64]) -> Option<Vec<f64>> {
        let k = self.past.len();
        let diff = |j: usize| -> Vec<f64> {
            self.newer(j, f_s, &[])
                .0
                .iter()
                .zip(&self.past[j].f_s)
                .map(|(a, b)| a - b)
                .collect()
        };
        let d: Vec<Vec<f64>> = (0..k).map(diff).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let mut a = nalgebra::DMatrix::from_fn(k, k, |i, j| dot(&d[i], &d[j]));
        let b = nalgebra::DVector::from_fn(k, |i, _| dot(&d[i], f_s));
        let scale = (0..k).fold(0.0f64, |m, i| m.max(a[(i, i)]));
        if scale <= 0.0 {
            return None;
        }
        for i in 0..k {
            a[(i, i)] += 1e-10 * scale;
        }
        let gamma = a.cholesky()?.solve(&b);
        gamma
            .iter()
            .all(|g| g.is_finite())
            .then(|| gamma.iter().copied().collect())
    }
}

/// Whether steps at dampings `a` and `b` are steps of (nearly) one map: both undamped, or
/// within a factor of 2 of each other.
fn same_map(a: f64, b: f64) -> bool {
    let undamped = super::RESOLUTION_MAX_DAMPING;
    (a <= undamped && b <= undamped) || (a <= 2.0 * b && b <= 2.0 * a)
}

fn copy<T: Copy>(dst: &mut Vec<T>, src: &[T]) {
    dst.clear();
    dst.extend_from_slice(src);
}

pub(crate) fn copy_frames(dst: &mut Vec<Vec<f64>>, src: &[Vec<f64>]) {
    dst.resize_with(src.len(), Vec::new);
    for (d, s) in dst.iter_mut().zip(src) {
        copy(d, s);
    }
}

#[cfg(test)]
#[path = "mixing_tests.rs"]
mod tests;
