//! Column twists and the grouping of columns by the segments they move: the pieces shared
//! by the IK's composite normal equations (`ik::composite`) and the calibration's frame
//! kernel (`calibrate::kernel_twist`).
//!
//! A column (a coordinate or a joint parameter) that reads steps `k` with scales `c_k`
//! moves every marker `x` it reaches by `∂x/∂θ = Σ_k c_k ∂x/∂s_k` (module docs of
//! [`super`]), a rigid velocity field `ω × (x − P) + v` about any point `P`, with
//! `ω = Σ_rot c_k ω_k` and `v = Σ_rot c_k ω_k × (P − o_k) + Σ_trans c_k ω_k`.

use nalgebra::Vector3;

use super::KinData;

/// One column's step contributions `(step, scale, rotation)`.
pub(crate) type Steps = Vec<(usize, f64, bool)>;

/// The distinct segment sets of the columns (`owners[c]`: the segments column `c` moves),
/// in the order of their first column, and each column's set (`usize::MAX`: moves none).
pub(crate) fn group_columns(owners: &[Vec<usize>]) -> (Vec<Vec<usize>>, Vec<usize>) {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut col_group = vec![usize::MAX; owners.len()];
    for (c, mine) in owners.iter().enumerate() {
        if mine.is_empty() {
            continue;
        }
        col_group[c] = match groups.iter().position(|g| g == mine) {
            Some(g) => g,
            None => {
                groups.push(mine.clone());
                groups.len() - 1
            }
        };
    }
    (groups, col_group)
}

/// The weighted centroid of the markers of `segments` whose `weight` is positive (`None`:
/// there are none), summed segment by segment in order.
#[inline(always)]
pub(crate) fn weighted_centroid(
    segments: &[Vec<usize>],
    kin: &KinData,
    weight: impl Fn(usize) -> f64,
) -> Option<Vector3<f64>> {
    let mut mass = 0.0;
    let mut centre = Vector3::zeros();
    for seg in segments {
        for &j in seg {
            let w = weight(j);
            if w > 0.0 {
                mass += w;
                centre += w * kin.markers[j];
            }
        }
    }
    (mass != 0.0).then(|| centre / mass)
}

/// The twist `(ω, v)` about `centre` of the column with step contributions `steps`, at the
/// last evaluation of `kin` (module docs).
#[inline(always)]
pub(crate) fn column_twist(
    kin: &KinData,
    steps: &[(usize, f64, bool)],
    centre: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let (mut w, mut v) = (Vector3::zeros(), Vector3::zeros());
    for &(step, scale, rotation) in steps {
        let (axis, origin) = kin.step_frame(step);
        if rotation {
            w += scale * axis;
            v += scale * axis.cross(&(centre - origin));
        } else {
            v += scale * axis;
        }
    }
    (w, v)
}

/// `c[b·np + a] = mask[b·np + a] · ξ_a·y_b` for every column b (`y_b = K ξ_b`, six numbers)
/// and the columns a of its `quads` (groups of four, the twists component-major in `xs`:
/// component k of column a at `xs[a / 4][k][a mod 4]`), as
/// `(ω_a·(Θω_b + c×v_b)) + (v_a·(Mv_b + ω_b×c))` summed `((x₀y₀ + x₁y₁) + x₂y₂) + ((x₃y₃ +
/// x₄y₄) + x₅y₅)`, whether the processor has AVX2 or not (the same operations in the same
/// order). Outside its quads column b of `c` is left as it was.
#[inline(always)]
pub(crate) fn twist_products(
    y: &[[f64; 6]],
    xs: &[[[f64; 4]; 6]],
    mask: &[f64],
    quads: &[std::ops::Range<usize>],
    np: usize,
    c: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above).
        unsafe { products_avx2(y, xs, mask, quads, np, c) };
        return;
    }
    products(y, xs, mask, quads, np, c);
}

/// Column b of C: `ξ_a·y_b` for every a at once, four columns a per lane group (the twists
/// component-major), masked to the entries that column b forms:
/// `c[b·np + a] = mask · ((x₀y₀ + x₁y₁ + x₂y₂) + (x₃y₃ + x₄y₄ + x₅y₅))`.
#[inline(always)]
pub(crate) fn products(
    y: &[[f64; 6]],
    xs: &[[[f64; 4]; 6]],
    mask: &[f64],
    quads: &[std::ops::Range<usize>],
    np: usize,
    c: &mut [f64],
) {
    for (((y, cb), mb), quads) in y
        .iter()
        .zip(c.chunks_exact_mut(np))
        .zip(mask.chunks_exact(np))
        .zip(quads)
    {
        let lanes = cb[4 * quads.start..4 * quads.end]
            .chunks_exact_mut(4)
            .zip(mb[4 * quads.start..4 * quads.end].chunks_exact(4))
            .zip(&xs[quads.clone()]);
        // Locals, so that the compiler sees no store into `c` alias `y` or `mask`.
        let y = *y;
        for ((out, m), x) in lanes {
            let m: [f64; 4] = m.try_into().expect("4 lanes");
            let mut o = [0.0; 4];
            for l in 0..4 {
                o[l] = m[l]
                    * ((x[0][l] * y[0] + x[1][l] * y[1] + x[2][l] * y[2])
                        + (x[3][l] * y[3] + x[4][l] * y[4] + x[5][l] * y[5]));
            }
            out.copy_from_slice(&o);
        }
    }
}

/// [`products`] with the four lanes as one AVX register: the same products and sums in the
/// same order (no fused multiply-add), one quad per step, none of the gathers the
/// auto-vectorized loop used.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn products_avx2(
    y: &[[f64; 6]],
    xs: &[[[f64; 4]; 6]],
    mask: &[f64],
    quads: &[std::ops::Range<usize>],
    np: usize,
    c: &mut [f64],
) {
    use std::arch::x86_64::*;
    let n = y.len();
    assert!(quads.len() == n && c.len() >= n * np && mask.len() >= n * np);
    assert!(quads.iter().all(|q| q.end <= xs.len() && 4 * q.end <= np));
    let (cp, mp) = (c.as_mut_ptr(), mask.as_ptr());
    for (b, (y, quads)) in y.iter().zip(quads).enumerate() {
        let y0 = _mm256_set1_pd(y[0]);
        let y1 = _mm256_set1_pd(y[1]);
        let y2 = _mm256_set1_pd(y[2]);
        let y3 = _mm256_set1_pd(y[3]);
        let y4 = _mm256_set1_pd(y[4]);
        let y5 = _mm256_set1_pd(y[5]);
        for t in quads.clone() {
            let x = &xs[t];
            // SAFETY: 4t + 4 ≤ np and b < n (asserted above): inside `c` and `mask`; `x[k]`
            // holds four numbers.
            unsafe {
                let p0 = _mm256_mul_pd(_mm256_loadu_pd(x[0].as_ptr()), y0);
                let p1 = _mm256_mul_pd(_mm256_loadu_pd(x[1].as_ptr()), y1);
                let p2 = _mm256_mul_pd(_mm256_loadu_pd(x[2].as_ptr()), y2);
                let p3 = _mm256_mul_pd(_mm256_loadu_pd(x[3].as_ptr()), y3);
                let p4 = _mm256_mul_pd(_mm256_loadu_pd(x[4].as_ptr()), y4);
                let p5 = _mm256_mul_pd(_mm256_loadu_pd(x[5].as_ptr()), y5);
                let s1 = _mm256_add_pd(_mm256_add_pd(p0, p1), p2);
                let s2 = _mm256_add_pd(_mm256_add_pd(p3, p4), p5);
                let m = _mm256_loadu_pd(mp.add(b * np + 4 * t));
                _mm256_storeu_pd(
                    cp.add(b * np + 4 * t),
                    _mm256_mul_pd(m, _mm256_add_pd(s1, s2)),
                );
            }
        }
    }
}
