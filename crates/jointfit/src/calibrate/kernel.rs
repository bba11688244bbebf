//! The per-frame kernel of the joint normal equations: one frame's weighted Gram matrix.
//!
//! For frame i with weighted Jacobian `J̃ = √W [J_q | J_s]` (the parameter columns scaled by
//! the half-range of each free parameter, see [`super::Problem::half_range`]) and weighted
//! residual `r̃ = √W (m_i − x_i)`, the kernel forms `G = J̃ᵀJ̃` (`n × n`, `n = n_q + n_f`) and
//! `h = J̃ᵀr̃`, whose blocks are `U_i`, `W_i`, `V_i`, `g_i`, `g_s,i` of [`super::schur`].
//!
//! Each column of `J̃` is nonzero only on the rows of the markers its coordinate or parameter
//! moves (a marker moves with its segment's ancestors' joints). With the columns reordered by
//! their first nonzero row, the nonzero entries of every row lie in a prefix of the columns, so
//! `[r̃ | J̃]ᵀ[r̃ | J̃]` is a sum over runs of rows (one run per segment when the markers are listed
//! parent segment first) of small dense products, each done by `matrixmultiply`'s `dgemm`
//! (its kernels chosen at run time for the processor's vector units). The same operations run
//! in the same order whatever the thread count.

use nalgebra::Vector3;

use super::Problem;
use crate::kinematics::{forward_kinematics, KinData, Want};

/// Per-thread workspace of the kernel; holds the last frame's Gram matrix and gradient.
pub(crate) struct FrameScratch {
    pub kin: KinData,
    rows: Vec<(usize, f64)>,
    jw: Vec<f64>,
    rw: Vec<f64>,
    /// Per column, its first nonzero row.
    range: Vec<usize>,
    perm: Vec<usize>,
    packed: Vec<f64>,
    xrow: Vec<f64>,
    /// `G` (n × n, column-major).
    pub gram: Vec<f64>,
    /// `h = [g; g_s]` (n).
    pub grad: Vec<f64>,
    /// Scratch for the callers' small dense algebra.
    pub buf: Vec<f64>,
    pub fac: Vec<f64>,
    pub vec: Vec<f64>,
}

impl FrameScratch {
    pub fn new(prob: &Problem) -> Self {
        let model = prob.model;
        let n = model.n_q() + prob.n_free();
        let nrows = 3 * model.n_markers();
        FrameScratch {
            kin: KinData::new(model),
            rows: Vec::with_capacity(nrows),
            jw: vec![0.0; n * nrows],
            rw: vec![0.0; nrows],
            range: vec![0; n],
            perm: Vec::with_capacity(n),
            packed: Vec::with_capacity((n + 1) * (n + 1)),
            xrow: Vec::with_capacity((n + 1) * nrows),
            gram: vec![0.0; n * n],
            grad: vec![0.0; n],
            buf: Vec::new(),
            fac: Vec::new(),
            vec: Vec::new(),
        }
    }
}

/// Forms frame `targets`' Gram matrix and gradient at `(p, q)` into `sc.gram` and `sc.grad`
/// (scaled parameter units; `half[k]` the half-range of free parameter k) and returns the
/// frame's objective `Σ w_j ‖m_j − x_j‖²` (m²).
pub(crate) fn frame_gram(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above). The gathers compile to
        // wider moves; the arithmetic is the same in the same order.
        return unsafe { frame_gram_avx2(prob, p, q, targets, half, sc) };
    }
    frame_gram_impl(prob, p, q, targets, half, sc)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn frame_gram_avx2(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    frame_gram_impl(prob, p, q, targets, half, sc)
}

#[inline(always)]
fn frame_gram_impl(
    prob: &Problem,
    p: &[f64],
    q: &[f64],
    targets: &[Vector3<f64>],
    half: &[f64],
    sc: &mut FrameScratch,
) -> f64 {
    let model = prob.model;
    let nq = model.n_q();
    let n = nq + prob.n_free();
    let nrows = 3 * model.n_markers();
    forward_kinematics(model, p, q, Want::BOTH, &mut sc.kin);
    // Rows: (model row 3j + axis, √w_j) of the present markers.
    sc.rows.clear();
    let mut cost = 0.0;
    for (j, m) in model.markers().iter().enumerate() {
        let t = targets[j];
        if t.x.is_nan() || m.weight <= 0.0 {
            continue;
        }
        let r = t - sc.kin.markers[j];
        cost += m.weight * r.norm_squared();
        let sw = m.weight.sqrt();
        for axis in 0..3 {
            sc.rw[sc.rows.len()] = sw * r[axis];
            sc.rows.push((3 * j + axis, sw));
        }
    }
    let nr = sc.rows.len();
    let jq = sc.kin.jq().as_slice();
    let jp = sc.kin.jp().as_slice();
    for a in 0..n {
        let (src, scale) = if a < nq {
            (&jq[a * nrows..(a + 1) * nrows], 1.0)
        } else {
            let k = a - nq;
            let pi = prob.free[k];
            (&jp[pi * nrows..(pi + 1) * nrows], half[k])
        };
        let col = &mut sc.jw[a * nr..(a + 1) * nr];
        for (x, &(row, sw)) in col.iter_mut().zip(&sc.rows) {
            *x = sw * scale * src[row];
        }
        sc.range[a] = col.iter().position(|&x| x != 0.0).unwrap_or(nr);
    }
    // Columns in order of their first nonzero row: every row's nonzero entries then lie in
    // a prefix of the reordered columns (exactly so when the markers are listed parent
    // segment first; otherwise the prefix holds a few zeros, which change nothing). The
    // residual goes first, so column 0 of `X = [r̃ | J̃ reordered]` is always active.
    let perm = &mut sc.perm;
    perm.clear();
    perm.extend(0..n);
    perm.sort_unstable_by_key(|&a| (sc.range[a], a));
    let m = n + 1;
    let x = &mut sc.xrow;
    x.clear();
    x.extend_from_slice(&sc.rw[..nr]);
    for &a in perm.iter() {
        x.extend_from_slice(&sc.jw[a * nr..(a + 1) * nr]);
    }
    // XᵀX (m × m, column-major) summed over runs of rows with the same active prefix:
    // each run is one small dense product (matrixmultiply's dgemm).
    let g = &mut sc.packed;
    g.clear();
    g.resize(m * m, 0.0);
    let mut active = 0;
    let mut r0 = 0;
    while r0 < nr {
        while active < n && sc.range[perm[active]] <= r0 {
            active += 1;
        }
        let next = if active < n {
            sc.range[perm[active]].clamp(r0 + 1, nr)
        } else {
            nr
        };
        let k = active + 1;
        let rows = next - r0;
        // SAFETY: A = Xᵀ restricted to (k × rows) reads x[c·nr + r0 + r] for c < k ≤ m,
        // r < rows ≤ nr − r0: inside x (m·nr). C (k × k, stride m) lies inside g (m·m).
        unsafe {
            matrixmultiply::dgemm(
                k,
                rows,
                k,
                1.0,
                x.as_ptr().add(r0),
                nr as isize,
                1,
                x.as_ptr().add(r0),
                1,
                nr as isize,
                1.0,
                g.as_mut_ptr(),
                1,
                m as isize,
            );
        }
        r0 = next;
    }
    let gram = &mut sc.gram;
    for a in 0..n {
        let pa = perm[a];
        sc.grad[pa] = g[a + 1];
        for c in 0..=a {
            let pc = perm[c];
            let value = g[(c + 1) * m + a + 1];
            gram[pc * n + pa] = value;
            gram[pa * n + pc] = value;
        }
    }
    cost
}

/// `Σ a_i b_i` with four independent partial sums, added in a fixed order.
#[inline(always)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}
