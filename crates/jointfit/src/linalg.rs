//! Small dense linear algebra on column-major slices, allocation-free for the hot loops.

/// In-place Cholesky factorisation `A = L Lᵀ` of a symmetric positive-definite `n × n`
/// matrix stored column-major in `a` (only the lower triangle is read; `L` overwrites it).
/// Returns false (leaving `a` partly overwritten) when a pivot is not positive.
pub fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    debug_assert_eq!(a.len(), n * n);
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
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    forward_solve(l, n, b);
    backward_solve(l, n, b);
}

/// Solves `L y = b` in place (forward substitution with the lower factor).
pub fn forward_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// Solves `Lᵀ x = y` in place (backward substitution with the lower factor).
pub fn backward_solve(l: &[f64], n: usize, b: &mut [f64]) {
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
        assert!(cholesky_in_place(&mut l, n));
        let mut x = b.clone();
        cholesky_solve(&l, n, &mut x);
        let reference = a
            .clone()
            .cholesky()
            .unwrap()
            .solve(&nalgebra::DVector::from(b));
        for i in 0..n {
            assert!((x[i] - reference[i]).abs() < 1e-12 * (1.0 + reference[i].abs()));
        }
    }

    #[test]
    fn rejects_indefinite() {
        let mut a = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut a, 2));
    }
}
