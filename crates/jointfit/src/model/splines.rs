//! The spline coefficients of [`super::functions`]: the FMM cubic (`SimmSpline`,
//! `NaturalCubicSpline`) and the natural interpolating spline of odd degree (`GCVSpline`),
//! both as [`Pieces`] (the math is stated in the parent module's docs).

use nalgebra::{DMatrix, DVector};

use super::functions::Pieces;

pub(super) fn check_points(x: &[f64], y: &[f64], min: usize) -> Result<(), String> {
    if x.len() != y.len() {
        return Err(format!("{} x values but {} y values", x.len(), y.len()));
    }
    if x.len() < min {
        return Err(format!("needs at least {min} points, has {}", x.len()));
    }
    if !x.iter().chain(y).all(|v| v.is_finite()) {
        return Err("points must be finite".into());
    }
    if let Some(i) = (1..x.len()).find(|&i| x[i] <= x[i - 1]) {
        return Err(format!(
            "x values must increase strictly (x[{}] = {} after {})",
            i,
            x[i],
            x[i - 1]
        ));
    }
    Ok(())
}

/// Forsythe–Malcolm–Moler cubic spline (module docs), as local cubics
/// `y_i + b_i t + c_i t² + d_i t³`, `t = x − x_i`, rewritten in `s = t/h_i`.
pub(super) fn fmm_spline(x: &[f64], y: &[f64]) -> Pieces {
    let n = x.len();
    let (mut b, mut c, mut d) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    if n == 2 {
        b[0] = (y[1] - y[0]) / (x[1] - x[0]);
        b[1] = b[0];
    } else {
        // Tridiagonal system for σ_i: diagonal b, off-diagonal d, right-hand side c.
        d[0] = x[1] - x[0];
        c[1] = (y[1] - y[0]) / d[0];
        for i in 1..n - 1 {
            d[i] = x[i + 1] - x[i];
            b[i] = 2.0 * (d[i - 1] + d[i]);
            c[i + 1] = (y[i + 1] - y[i]) / d[i];
            c[i] = c[i + 1] - c[i];
        }
        b[0] = -d[0];
        b[n - 1] = -d[n - 2];
        c[0] = 0.0;
        c[n - 1] = 0.0;
        if n > 3 {
            c[0] = c[2] / (x[3] - x[1]) - c[1] / (x[2] - x[0]);
            c[n - 1] = c[n - 2] / (x[n - 1] - x[n - 3]) - c[n - 3] / (x[n - 2] - x[n - 4]);
            c[0] = c[0] * d[0] * d[0] / (x[3] - x[0]);
            c[n - 1] = -c[n - 1] * d[n - 2] * d[n - 2] / (x[n - 1] - x[n - 4]);
        }
        for i in 1..n {
            let t = d[i - 1] / b[i - 1];
            b[i] -= t * d[i - 1];
            c[i] -= t * c[i - 1];
        }
        c[n - 1] /= b[n - 1];
        for i in (0..n - 1).rev() {
            c[i] = (c[i] - d[i] * c[i + 1]) / b[i];
        }
        b[n - 1] = (y[n - 1] - y[n - 2]) / d[n - 2] + d[n - 2] * (c[n - 2] + 2.0 * c[n - 1]);
        for i in 0..n - 1 {
            b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i]);
            d[i] = (c[i + 1] - c[i]) / d[i];
            c[i] *= 3.0;
        }
        c[n - 1] *= 3.0;
    }
    let coef = (0..n - 1)
        .map(|i| {
            let h = x[i + 1] - x[i];
            vec![y[i], b[i] * h, c[i] * h * h, d[i] * h * h * h]
        })
        .collect();
    Pieces {
        x: x.to_vec(),
        coef,
        left: vec![y[0], b[0]],
        right: vec![y[n - 1], b[n - 1]],
        right_at_knots: false,
    }
}

/// `k!/(k−j)!`.
fn falling(k: usize, j: usize) -> f64 {
    ((k - j + 1)..=k).map(|v| v as f64).product()
}

/// The natural interpolating spline of degree `2m − 1` (module docs), solved for all pieces
/// at once in the scaled variable: piece `i` is `Σ_{k<2m} a_{ik} s^k`, `s = (x − x_i)/h_i`,
/// so `f^{(j)}(x_i) = j! a_{ij} / h_i^j`.
pub(super) fn natural_spline(x: &[f64], y: &[f64], m: usize) -> Result<Pieces, String> {
    let n = x.len();
    let deg = 2 * m; // coefficients per piece
    let np = n - 1;
    let size = deg * np;
    let h: Vec<f64> = (0..np).map(|i| x[i + 1] - x[i]).collect();
    let mut a = DMatrix::<f64>::zeros(size, size);
    let mut rhs = DVector::<f64>::zeros(size);
    let mut row = 0;
    let col = |i: usize, k: usize| i * deg + k;
    for i in 0..np {
        a[(row, col(i, 0))] = 1.0;
        rhs[row] = y[i];
        row += 1;
        for k in 0..deg {
            a[(row, col(i, k))] = 1.0;
        }
        rhs[row] = y[i + 1];
        row += 1;
    }
    // Continuity of derivatives 1 … 2m−2 at interior knots, multiplied by h_i^j:
    // Σ_k a_{ik} k!/(k−j)! = j! a_{i+1,j} (h_i/h_{i+1})^j.
    for i in 0..np.saturating_sub(1) {
        for j in 1..=deg - 2 {
            for k in j..deg {
                a[(row, col(i, k))] = falling(k, j);
            }
            a[(row, col(i + 1, j))] = -falling(j, j) * (h[i] / h[i + 1]).powi(j as i32);
            row += 1;
        }
    }
    // Natural end conditions: derivatives m … 2m−2 vanish at both ends.
    for j in m..=deg - 2 {
        a[(row, col(0, j))] = 1.0;
        row += 1;
        for k in j..deg {
            a[(row, col(np - 1, k))] = falling(k, j);
        }
        row += 1;
    }
    debug_assert_eq!(row, size);
    let sol = a
        .lu()
        .solve(&rhs)
        .ok_or_else(|| "spline system is singular".to_string())?;
    let coef: Vec<Vec<f64>> = (0..np)
        .map(|i| (0..deg).map(|k| sol[col(i, k)]).collect())
        .collect();
    // Taylor polynomials of degree m−1 at the ends, in absolute units.
    let left = (0..m).map(|j| coef[0][j] / h[0].powi(j as i32)).collect();
    let last = &coef[np - 1];
    let hl = h[np - 1];
    let right = (0..m)
        .map(|j| {
            // f^{(j)}(x_n)/j! = Σ_k a_k C(k, j) / h^j
            let dj: f64 = (j..deg).map(|k| last[k] * falling(k, j)).sum();
            dj / falling(j, j) / hl.powi(j as i32)
        })
        .collect();
    Ok(Pieces {
        x: x.to_vec(),
        coef,
        left,
        right,
        right_at_knots: true,
    })
}
