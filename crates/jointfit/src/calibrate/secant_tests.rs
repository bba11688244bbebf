use super::*;

/// A symmetric positive-definite n × n matrix (column-major) from a fixed seed.
fn spd(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed;
    let mut next = || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let b: Vec<f64> = (0..n * n).map(|_| next()).collect();
    let mut s = vec![0.0; n * n];
    for c in 0..n {
        for r in 0..n {
            s[c * n + r] = (0..n).map(|k| b[k * n + r] * b[k * n + c]).sum::<f64>();
        }
        s[c * n + c] += 0.5;
    }
    s
}

fn mul(m: &[f64], n: usize, d: &[f64]) -> Vec<f64> {
    (0..n)
        .map(|r| (0..n).map(|c| m[c * n + r] * d[c]).sum())
        .collect()
}

/// Eigenvalues of `L⁻¹ M L⁻ᵀ` for `S = L Lᵀ`, independently of [`Secant::limited`]:
/// nalgebra's own Cholesky and inverse.
fn relative_eigenvalues(s: &[f64], m: &[f64], n: usize) -> Vec<f64> {
    let l = DMatrix::from_column_slice(n, n, s)
        .cholesky()
        .unwrap()
        .l()
        .try_inverse()
        .unwrap();
    let x = &l * DMatrix::from_column_slice(n, n, m) * l.transpose();
    let x = (&x + x.transpose()) * 0.5;
    x.symmetric_eigenvalues().iter().copied().collect()
}

/// After a step from a point, the update makes `(S₊ + A₊) δ = y` hold exactly: the secant
/// condition on the reduced gradients, whatever `A` was before (here a first update and a
/// second one on top of it).
#[test]
fn the_update_meets_the_secant_condition() {
    let n = 5;
    let s1 = spd(n, 1);
    let s2 = spd(n, 2);
    let mut sec = Secant::new(n);
    let g0 = vec![0.3, -0.2, 0.1, 0.05, -0.4];
    let d = vec![0.1, 0.2, -0.1, 0.3, 0.05];
    let g1 = vec![-0.1, 0.25, 0.0, -0.3, 0.2];
    let d2 = vec![-0.2, 0.1, 0.3, 0.0, 0.1];
    let g2 = vec![0.05, -0.05, 0.2, 0.1, -0.1];
    sec.observe(&s1, &g0);
    sec.accepted(&d, 1.0, 1.0, 1.0);
    sec.observe(&s2, &g1);
    let lhs = mul(&sec.a, n, &d);
    let sd = mul(&s2, n, &d);
    for i in 0..n {
        let want = g0[i] - g1[i] - sd[i];
        assert!((lhs[i] - want).abs() < 1e-12, "{i}: {} vs {want}", lhs[i]);
    }
    sec.accepted(&d2, 1.0, 1.0, 1.0);
    sec.observe(&s1, &g2);
    let lhs = mul(&sec.a, n, &d2);
    let sd = mul(&s1, n, &d2);
    for i in 0..n {
        let want = g1[i] - g2[i] - sd[i];
        assert!((lhs[i] - want).abs() < 1e-12, "{i}: {} vs {want}", lhs[i]);
    }
    // Symmetric.
    for c in 0..n {
        for r in 0..n {
            assert!((sec.a[c * n + r] - sec.a[r * n + c]).abs() < 1e-15);
        }
    }
}

/// On an exactly quadratic reduced objective whose Hessian is `S + C`, `C = c u uᵀ` (a
/// missing term of negative curvature, the case Gauss–Newton crawls on), one step that has a
/// component along `u` recovers `C` exactly.
#[test]
fn one_step_recovers_a_rank_one_missing_term() {
    let n = 4;
    let s = spd(n, 3);
    let u = [0.6, -0.3, 0.5, 0.2];
    let c = -0.7;
    let mut h = s.clone();
    for col in 0..n {
        for r in 0..n {
            h[col * n + r] += c * u[r] * u[col];
        }
    }
    let g0 = vec![0.2, 0.1, -0.3, 0.4];
    let d = vec![0.05, 0.1, -0.02, 0.07];
    // g is a half negative gradient: g(s + d) = g(s) − H d.
    let hd = mul(&h, n, &d);
    let g1: Vec<f64> = g0.iter().zip(&hd).map(|(a, b)| a - b).collect();
    let mut sec = Secant::new(n);
    sec.observe(&s, &g0);
    sec.accepted(&d, 1.0, 1.0, 1.0);
    sec.observe(&s, &g1);
    for col in 0..n {
        for r in 0..n {
            let want = c * u[r] * u[col];
            assert!((sec.a[col * n + r] - want).abs() < 1e-12);
        }
    }
}

/// The limited correction keeps `S + A ⪰ θ S` and leaves an `A` already inside the limit
/// as it is.
#[test]
fn the_limited_model_stays_convex() {
    let n = 6;
    let s = spd(n, 4);
    let mut sec = Secant::new(n);
    assert!(sec.limited(&s).is_none());
    // A = −2 S: a model of negative curvature in every direction, far outside the limit.
    sec.a = s.iter().map(|x| -2.0 * x).collect();
    let a = sec.limited(&s).unwrap();
    let total: Vec<f64> = s.iter().zip(&a).map(|(x, y)| x + y).collect();
    let ev = relative_eigenvalues(&s, &total, n);
    for e in &ev {
        assert!((e - CURVATURE_FLOOR).abs() < 1e-10, "{e}");
    }
    // Inside the limit: −0.5 S (the model keeps half the curvature).
    sec.a = s.iter().map(|x| -0.5 * x).collect();
    let a = sec.limited(&s).unwrap();
    for (x, y) in a.iter().zip(&sec.a) {
        assert!((x - y).abs() < 1e-12 * (1.0 + y.abs()));
    }
}

/// The next step uses the model that predicted the last decrease better.
#[test]
fn the_better_predictor_is_chosen() {
    let mut sec = Secant::new(2);
    sec.observe(&[1.0, 0.0, 0.0, 1.0], &[1.0, 1.0]);
    sec.accepted(&[0.1, 0.1], 2.0, 1.0, 1.9);
    assert!(sec.augmented());
    sec.observe(&[1.0, 0.0, 0.0, 1.0], &[0.5, 0.5]);
    sec.accepted(&[0.1, 0.1], 1.0, 1.05, 1.9);
    assert!(!sec.augmented());
}
