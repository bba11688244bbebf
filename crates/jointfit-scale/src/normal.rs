//! Normal equations of the scale fit in bordered block form, and their solution by the
//! Schur complement.
//!
//! The unknowns split into the shared ones `s = (g, u, δ)` (factors, overall size, marker
//! offsets) and each frame's coordinates `q_f`; a residual row touches the shared unknowns
//! and at most one frame. With `J` the Jacobian and `r` the residuals,
//!
//! `JᵀJ = [[A, B_1 … B_F], [B_fᵀ, D_f (block diagonal)]]`, `Jᵀr = (a, b_1 … b_F)`.
//!
//! A damped Gauss–Newton step (`A`, `D_f` with `λ·diag` added) eliminates the frames:
//! `S = A − Σ_f B_f D_f⁻¹ B_fᵀ`, `S Δs = −a + Σ_f B_f D_f⁻¹ b_f`,
//! `Δq_f = −D_f⁻¹ (b_f + B_fᵀ Δs)`. Undamped, `S⁻¹` is the shared block of `(JᵀJ)⁻¹`, and
//! frame `f`'s diagonal block of `(JᵀJ)⁻¹` is `D_f⁻¹ + X_f S⁻¹ X_fᵀ`, `X_f = D_f⁻¹ B_fᵀ`.

use nalgebra::{DMatrix, DVector};

/// One frame's blocks.
#[derive(Clone)]
pub(crate) struct FrameBlock {
    /// `D_f` (n_q × n_q).
    pub(crate) d: DMatrix<f64>,
    /// `B_f` (n_s × n_q).
    pub(crate) b: DMatrix<f64>,
    /// `b_f`.
    pub(crate) g: DVector<f64>,
}

/// `JᵀJ` and `Jᵀr` in block form (module docs).
#[derive(Clone)]
pub(crate) struct Normal {
    pub(crate) a: DMatrix<f64>,
    pub(crate) g: DVector<f64>,
    pub(crate) frames: Vec<FrameBlock>,
}

/// The frames eliminated (module docs): the Schur complement `S` and, per frame, `D_f⁻¹` and
/// `X_f = D_f⁻¹ B_fᵀ`.
struct Eliminated {
    s: DMatrix<f64>,
    frames: Vec<(DMatrix<f64>, DMatrix<f64>)>,
}

/// A step: the shared unknowns' change and each frame's.
pub(crate) struct Step {
    pub(crate) shared: DVector<f64>,
    pub(crate) frames: Vec<DVector<f64>>,
}

impl Normal {
    pub(crate) fn zeros(n_s: usize, n_q: usize, frames: usize) -> Self {
        Normal {
            a: DMatrix::zeros(n_s, n_s),
            g: DVector::zeros(n_s),
            frames: vec![
                FrameBlock {
                    d: DMatrix::zeros(n_q, n_q),
                    b: DMatrix::zeros(n_s, n_q),
                    g: DVector::zeros(n_q),
                };
                frames
            ],
        }
    }

    /// The frames eliminated from the system damped by `λ` (Marquardt's scaling:
    /// `λ·max(H_kk, 10⁻⁹)` added to the diagonal of `A` and each `D_f`); `None` when a
    /// factorisation fails.
    fn eliminate(&self, lambda: f64) -> Option<Eliminated> {
        let damp = |m: &mut DMatrix<f64>| {
            for k in 0..m.nrows() {
                m[(k, k)] += lambda * m[(k, k)].max(1e-9);
            }
        };
        let mut s = self.a.clone();
        damp(&mut s);
        let mut xs = Vec::with_capacity(self.frames.len());
        for fr in &self.frames {
            let mut d = fr.d.clone();
            damp(&mut d);
            let dinv = d.cholesky()?.inverse();
            let x = &dinv * fr.b.transpose();
            s.gemm(-1.0, &fr.b, &x, 1.0);
            xs.push((dinv, x));
        }
        Some(Eliminated { s, frames: xs })
    }

    /// The damped step (`eliminate`); `None` when a factorisation fails.
    pub(crate) fn step(&self, lambda: f64) -> Option<Step> {
        let Eliminated { s, frames: xs } = self.eliminate(lambda)?;
        let mut rhs = -&self.g;
        let mut ys = Vec::with_capacity(self.frames.len());
        for (fr, (dinv, _)) in self.frames.iter().zip(&xs) {
            let y = dinv * &fr.g;
            rhs.gemv(1.0, &fr.b, &y, 1.0);
            ys.push(y);
        }
        let shared = s.cholesky()?.solve(&rhs);
        let frames = xs
            .iter()
            .zip(&ys)
            .map(|((_, x), y)| -(y + x * &shared))
            .collect();
        Some(Step { shared, frames })
    }

    /// The shared block of `(JᵀJ)⁻¹` and each frame's diagonal of `(JᵀJ)⁻¹` (module docs);
    /// `None` when singular.
    pub(crate) fn inverse_blocks(&self) -> Option<(DMatrix<f64>, Vec<DVector<f64>>)> {
        let Eliminated { s, frames: xs } = self.eliminate(0.0)?;
        let sinv = s.cholesky()?.inverse();
        let diags = xs
            .iter()
            .map(|(dinv, x)| {
                let xs = x * &sinv;
                DVector::from_fn(dinv.nrows(), |i, _| dinv[(i, i)] + xs.row(i).dot(&x.row(i)))
            })
            .collect();
        Some((sinv, diags))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random bordered system: the Schur step and inverse blocks equal the dense ones.
    #[test]
    fn schur_solution_equals_the_dense_one() {
        let (n_s, n_q, nf) = (4, 3, 3);
        let n = n_s + nf * n_q;
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        // Rows touching the shared unknowns and one frame each.
        let mut j = DMatrix::zeros(40, n);
        for r in 0..40 {
            let f = r % nf;
            for c in 0..n_s {
                j[(r, c)] = rnd();
            }
            for c in 0..n_q {
                j[(r, n_s + f * n_q + c)] = rnd();
            }
        }
        let res = DVector::from_fn(40, |_, _| rnd());
        let h = j.transpose() * &j;
        let gr = j.transpose() * &res;
        let mut nm = Normal::zeros(n_s, n_q, nf);
        nm.a = h.view((0, 0), (n_s, n_s)).into();
        nm.g = gr.rows(0, n_s).into();
        for (f, fr) in nm.frames.iter_mut().enumerate() {
            let o = n_s + f * n_q;
            fr.d = h.view((o, o), (n_q, n_q)).into();
            fr.b = h.view((0, o), (n_s, n_q)).into();
            fr.g = gr.rows(o, n_q).into();
        }
        let lambda = 0.1;
        let mut hd = h.clone();
        for k in 0..n {
            hd[(k, k)] += lambda * h[(k, k)];
        }
        let dense = hd.cholesky().unwrap().solve(&(-&gr));
        let st = nm.step(lambda).unwrap();
        assert!((st.shared - dense.rows(0, n_s)).amax() < 1e-10);
        for (f, dq) in st.frames.iter().enumerate() {
            assert!((dq - dense.rows(n_s + f * n_q, n_q)).amax() < 1e-10);
        }
        let inv = h.try_inverse().unwrap();
        let (sinv, diags) = nm.inverse_blocks().unwrap();
        assert!((sinv - inv.view((0, 0), (n_s, n_s))).amax() < 1e-9);
        for (f, d) in diags.iter().enumerate() {
            for i in 0..n_q {
                let o = n_s + f * n_q + i;
                assert!((d[i] - inv[(o, o)]).abs() < 1e-9);
            }
        }
    }
}
