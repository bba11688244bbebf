//! Small dense linear algebra on column-major slices, allocation-free for the hot loops.
//!
//! [`Cholesky`] is the public face: a factor exists only when the factorisation succeeded,
//! so a failed one cannot be used by mistake. The raw routines stay inside the crate for
//! the Schur solver, which keeps its per-frame factors between calls.

/// The Cholesky factor `L` (`A = L Lᵀ`) of a symmetric positive-definite `n × n` matrix,
/// held in the caller's column-major buffer (allocation-free).
#[derive(Debug)]
pub(crate) struct Cholesky<'a> {
    l: &'a [f64],
    n: usize,
}

impl<'a> Cholesky<'a> {
    /// Factors `a` (column-major `n × n`, only the lower triangle read) in place; `None`
    /// when a pivot is not positive (then `a` is partly overwritten and no factor exists).
    pub(crate) fn factor(a: &'a mut [f64], n: usize) -> Option<Cholesky<'a>> {
        cholesky_in_place(a, n).then_some(Cholesky { l: a, n })
    }

    /// Solves `A x = b` in place (`b` becomes `x`).
    pub(crate) fn solve(&self, b: &mut [f64]) {
        cholesky_solve(self.l, self.n, b);
    }

    #[cfg(test)]
    /// Solves `L y = b` in place.
    pub(crate) fn forward(&self, b: &mut [f64]) {
        forward_solve(self.l, self.n, b);
    }

    #[cfg(test)]
    /// Solves `Lᵀ x = y` in place.
    pub(crate) fn backward(&self, b: &mut [f64]) {
        backward_solve(self.l, self.n, b);
    }
}

/// In-place Cholesky factorisation `A = L Lᵀ` of a symmetric positive-definite `n × n`
/// matrix stored column-major in `a` (only the lower triangle is read; `L` overwrites it).
/// Returns false (leaving `a` partly overwritten) when a pivot is not positive.
pub(crate) fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    debug_assert_eq!(a.len(), n * n);
    // The IK's usual sizes with the size a compile-time constant: the loops unroll and lose
    // their bounds checks; the same operations in the same order, so the same bits.
    match n {
        6 => cholesky_fixed::<6>(a),
        12 => cholesky_fixed::<12>(a),
        18 => cholesky_fixed::<18>(a),
        _ => cholesky_general(a, n),
    }
}

fn cholesky_fixed<const N: usize>(a: &mut [f64]) -> bool {
    cholesky_general(&mut a[..N * N], N)
}

// Entry (i, j), i ≥ j, as one dot product along rows i and j of the columns before j:
// `a_ij − L_i0 L_j0 − L_i1 L_j1 − …` in that order, then divided by `L_jj`. This is the
// same sequence of roundings as subtracting column k's share from column j for k in
// order (the column form this replaced), so the factor is the same to the bit, with a
// scalar inner loop that costs fewer instructions on the IK's small matrices (12 to 40
// columns: 3.3 % of `bench --profile ik`, `notebook/ik_speed.md`).
#[inline(always)]
fn cholesky_general(a: &mut [f64], n: usize) -> bool {
    let a = &mut a[..n * n];
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            let l = a[k * n + j];
            d -= l * l;
        }
        if d.is_nan() || d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[j * n + i];
            for k in 0..j {
                s -= a[k * n + i] * a[k * n + j];
            }
            a[j * n + i] = s / d;
        }
    }
    true
}

/// Solves `L Lᵀ x = b` in place (`b` becomes `x`) with the factor from [`cholesky_in_place`].
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    forward_solve(l, n, b);
    backward_solve(l, n, b);
}

/// Solves `L y = b` in place (forward substitution with the lower factor).
pub(crate) fn forward_solve(l: &[f64], n: usize, b: &mut [f64]) {
    match n {
        6 => forward_general(&l[..36], 6, &mut b[..6]),
        12 => forward_general(&l[..144], 12, &mut b[..12]),
        18 => forward_general(&l[..324], 18, &mut b[..18]),
        _ => forward_general(l, n, b),
    }
}

#[inline(always)]
fn forward_general(l: &[f64], n: usize, b: &mut [f64]) {
    // Column by column: each b_i sees the subtractions of k = 0, 1, … in order, as a dot
    // product along row i would give, with the inner loop down a contiguous column.
    for k in 0..n {
        let x = b[k] / l[k * n + k];
        b[k] = x;
        for (bi, lik) in b[k + 1..n].iter_mut().zip(&l[k * n + k + 1..(k + 1) * n]) {
            *bi -= lik * x;
        }
    }
}

/// Solves `Lᵀ x = y` in place (backward substitution with the lower factor).
pub(crate) fn backward_solve(l: &[f64], n: usize, b: &mut [f64]) {
    match n {
        6 => backward_general(&l[..36], 6, &mut b[..6]),
        12 => backward_general(&l[..144], 12, &mut b[..12]),
        18 => backward_general(&l[..324], 18, &mut b[..18]),
        _ => backward_general(l, n, b),
    }
}

#[inline(always)]
fn backward_general(l: &[f64], n: usize, b: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    #[test]
    fn solves_like_nalgebra() {
        let n = 7;
        let m = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let a = &m * m.transpose() + DMatrix::identity(n, n);
        let b: Vec<f64> = (0..n).map(|i| i as f64 - 2.5).collect();
        let mut l = a.as_slice().to_vec();
        let chol = Cholesky::factor(&mut l, n).expect("positive definite");
        let mut x = b.clone();
        chol.solve(&mut x);
        // Forward then backward substitution is the same solve.
        let mut y = b.clone();
        chol.forward(&mut y);
        chol.backward(&mut y);
        assert_eq!(x, y);
        let reference = a
            .clone()
            .cholesky()
            .unwrap()
            .solve(&nalgebra::DVector::from(b));
        for i in 0..n {
            assert!((x[i] - reference[i]).abs() < 1e-12 * (1.0 + reference[i].abs()));
        }
    }

    /// The column form `cholesky_in_place` had before: the reference for the bits.
    fn column_form(a: &mut [f64], n: usize) -> bool {
        for j in 0..n {
            let (done, rest) = a.split_at_mut(j * n);
            let col = &mut rest[j..n];
            for k in 0..j {
                let lk = &done[k * n + j..(k + 1) * n];
                let l = lk[0];
                for (x, y) in col.iter_mut().zip(lk) {
                    *x -= y * l;
                }
            }
            let d = col[0];
            if d.is_nan() || d <= 0.0 || !d.is_finite() {
                return false;
            }
            let d = d.sqrt();
            col[0] = d;
            for x in &mut col[1..] {
                *x /= d;
            }
        }
        true
    }

    /// The dot-product form gives the column form's factor bit for bit (the same roundings
    /// in the same order), on random symmetric positive-definite matrices of 1 to 40
    /// columns, and refuses the same indefinite ones.
    #[test]
    fn factor_bits_equal_the_column_form() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for n in 1..=40 {
            for indefinite in [false, true] {
                let m = DMatrix::from_fn(n, n, |_, _| rand());
                let mut a = &m * m.transpose() + DMatrix::identity(n, n) * 1e-3;
                if indefinite {
                    a[(n / 2, n / 2)] = -1.0;
                }
                let (mut x, mut y) = (a.as_slice().to_vec(), a.as_slice().to_vec());
                let (ok_x, ok_y) = (cholesky_in_place(&mut x, n), column_form(&mut y, n));
                assert_eq!(ok_x, ok_y, "n = {n}");
                assert_eq!(ok_x, !indefinite, "n = {n}");
                if ok_x {
                    for j in 0..n {
                        for i in j..n {
                            assert_eq!(x[j * n + i].to_bits(), y[j * n + i].to_bits(), "n {n}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn rejects_indefinite() {
        let mut a = vec![1.0, 2.0, 2.0, 1.0];
        assert!(Cholesky::factor(&mut a, 2).is_none());
    }
}
