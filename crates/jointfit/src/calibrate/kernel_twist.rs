//! The frame Gram matrix from column twists and composite marker moments.
//!
//! Every column of the calibration's frame Jacobian, a coordinate or a (scaled) free
//! parameter, moves the markers it reaches rigidly: its steps are rotations about, or
//! translations along, world axes ([`crate::kinematics`]), so with the twist `ξ_a = (ω_a, v_a)`
//! of column `a` about a reference point `P`,
//!
//! `∂x_j/∂θ_a = ω_a × (x_j − P) + v_a`, `ω_a = Σ_rot c_k ω_k`,
//! `v_a = Σ_rot c_k ω_k × (P − o_k) + Σ_trans c_k ω_k`,
//!
//! for every marker `j` the column moves, *provided its steps are the same for all of them*
//! (they all lie on the path from the root to each marker's segment). The entries of
//! `G = J̃ᵀJ̃` and `h = J̃ᵀr̃` ([`super::kernel`]) are then
//!
//! `G_ab = Σ_{j moved by a and b} w_j J_a(x_j)·J_b(x_j) = ξ_aᵀ K_S ξ_b`,
//! `h_a = ω_a·ρ₁(S_a) + v_a·ρ₀(S_a)`,
//!
//! where `S` is the set of marker-carrying segments both columns move and `K_S` the 6 × 6
//! moments of its present markers. With `d_j = x_j − P`, `r_j = m_j − x_j` and sums over the
//! markers of `S`: `M = Σ w_j`, `c = Σ w_j d_j`, `Θ = Σ w_j (‖d_j‖² I − d_j d_jᵀ)`,
//! `ρ₀ = Σ w_j r_j`, `ρ₁ = Σ w_j d_j × r_j`, and
//!
//! `ξ_aᵀ K ξ_b = ω_a·(Θ ω_b + c × v_b) + v_a·(M v_b + ω_b × c)`.
//!
//! On a tree the segment sets of two columns are nested or disjoint (each column moves the
//! subtree below its joint), so `S` is the set of the *deeper* column, and its moments are
//! composite moments: the sum of its segments' moments, as in Featherstone's composite
//! rigid-body algorithm (*Rigid Body Dynamics Algorithms*, Springer 2008, §6.2). The same
//! algebra forms the inverse kinematics' normal equations ([`crate::ik`], `composite.rs`);
//! here the columns also include the joint parameters (steps like the coordinates'). With
//! `y_b = K_S ξ_b` formed once per column (`S` its own set), each entry `G[a, b] = ξ_a·y_b`
//! (`a` the column whose set contains `b`'s) costs 6 multiply-adds, instead of 3 per marker row
//! of the explicit product, and neither Jacobian matrix is filled. The entries are formed
//! column by column, four rows `a` at a time under a fixed 0/1 mask that keeps each pair once,
//! then mirrored (`notebook/performance.md`).
//!
//! The reference point `P` is the weighted centroid of the frame's present markers, so that
//! the moments stay of the size of the marker cloud (no cancellation between large terms).
//!
//! When some column's steps differ between the segments it moves (a coordinate that drives
//! joints of two branches, or two joints of one chain through couplers), or two columns move
//! overlapping but not nested sets, [`TwistPlan::new`] returns `None` and the tiled kernel of
//! [`super::kernel`] serves the problem.
//!
//! Every frame runs the same operations in the same order: results do not depend on threads.

use nalgebra::Vector3;

use super::Problem;
use crate::kinematics::twist::{
    column_twist, group_columns, twist_products, weighted_centroid, Steps,
};
use crate::kinematics::KinData;

/// Moments of a set of markers about the reference point (module docs).
#[derive(Debug, Clone, Copy)]
struct Mom {
    mass: f64,
    c: Vector3<f64>,
    /// `Θ` by its six entries `(xx, yy, zz, xy, xz, yz)` (symmetric).
    theta: [f64; 6],
    r0: Vector3<f64>,
    r1: Vector3<f64>,
}

impl Mom {
    fn zero() -> Self {
        Mom {
            mass: 0.0,
            c: Vector3::zeros(),
            theta: [0.0; 6],
            r0: Vector3::zeros(),
            r1: Vector3::zeros(),
        }
    }

    /// Adds a marker of weight `w` at `d` from the reference point, with residual `r`.
    #[inline(always)]
    fn add_marker(&mut self, w: f64, d: Vector3<f64>, r: Vector3<f64>) {
        self.mass += w;
        self.c += w * d;
        let wd = w * d;
        let t = &mut self.theta;
        t[0] += wd.y * d.y + wd.z * d.z;
        t[1] += wd.x * d.x + wd.z * d.z;
        t[2] += wd.x * d.x + wd.y * d.y;
        t[3] -= wd.x * d.y;
        t[4] -= wd.x * d.z;
        t[5] -= wd.y * d.z;
        self.r0 += w * r;
        self.r1 += w * d.cross(&r);
    }

    fn add(&mut self, o: &Mom) {
        self.mass += o.mass;
        self.c += o.c;
        for (t, o) in self.theta.iter_mut().zip(&o.theta) {
            *t += o;
        }
        self.r0 += o.r0;
        self.r1 += o.r1;
    }
}

/// The twist kernel's plan for one problem, and its per-frame scratch.
#[derive(Debug, Clone)]
pub(crate) struct TwistPlan {
    n_q: usize,
    /// The markers of each marker-carrying segment.
    segments: Vec<Vec<usize>>,
    /// Per kernel column (coordinates, then free parameters): its step contributions.
    col_steps: Vec<Steps>,
    /// Per group (a distinct segment set of some column): its segments, indices into
    /// `segments`.
    groups: Vec<Vec<usize>>,
    /// Per column: its group (`usize::MAX`: moves no marker).
    col_group: Vec<usize>,
    /// Columns rounded up to a multiple of 4 (the column stride of `mask` and `c`).
    np: usize,
    /// `mask[b·np + a]`: 1 where entry `(a, b)` of `G` is formed in column `b`, as
    /// `ξ_a·(K_S ξ_b)` with `S` the group of `b`: `a`'s segment set contains `S`, and `a ≤ b`
    /// when both have the set `S` (each pair once); 0 elsewhere.
    mask: Vec<f64>,
    /// Per column b: the groups of four rows `a` (of `mask`, `c`) from the first to the last
    /// where its mask is not all 0; outside them column b of `c` stays 0.
    quads: Vec<std::ops::Range<usize>>,
    seg_mom: Vec<Mom>,
    grp_mom: Vec<Mom>,
    /// The twists `ξ = (ω, v)` of the columns by groups of four columns, each group
    /// component-major: component k of column a at `xs[a / 4][k][a mod 4]`.
    xs: Vec<[[f64; 4]; 6]>,
    /// Per column: `K ξ`, split as `(Θω + c×v, Mv + ω×c)`.
    y: Vec<[f64; 6]>,
    /// `c[b·np + a] = mask · ξ_a·y_b` (n columns of `np`).
    c: Vec<f64>,
}

impl TwistPlan {
    /// The plan of `prob`'s frame Gram matrix, `None` when some column is not a single twist
    /// on a nested segment set (module docs).
    pub(crate) fn new(prob: &Problem) -> Option<Self> {
        let model = prob.model;
        let n_q = model.coordinates().len();
        let n = n_q + prob.n_free();
        let mut free_col = vec![usize::MAX; model.parameters().len()];
        for (k, &pi) in prob.free.iter().enumerate() {
            free_col[pi] = n_q + k;
        }
        let mut segments = Vec::new();
        let mut owners: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut col_steps: Vec<Steps> = vec![Vec::new(); n];
        for (s, markers) in model.plan.markers_by_segment.iter().enumerate() {
            if markers.is_empty() {
                continue;
            }
            let si = segments.len();
            segments.push(markers.clone());
            let mut steps: Vec<(usize, Steps)> = Vec::new();
            let q = model.plan.cols_q[s].iter().map(|c| (c.col, c));
            let p = model.plan.cols_p[s].iter().map(|c| (free_col[c.col], c));
            for (col, c) in q.chain(p) {
                if col == usize::MAX {
                    continue;
                }
                let entry = (c.step, c.scale, c.rotation);
                match steps.iter_mut().find(|(k, _)| *k == col) {
                    Some((_, list)) => list.push(entry),
                    None => steps.push((col, vec![entry])),
                }
            }
            for (col, mine) in steps {
                if owners[col].is_empty() {
                    col_steps[col] = mine;
                } else if col_steps[col] != mine {
                    return None;
                }
                owners[col].push(si);
            }
        }
        let (groups, col_group) = group_columns(&owners);
        let np = n.div_ceil(4) * 4;
        let mut mask = vec![0.0; n * np];
        for b in 0..n {
            let g = col_group[b];
            if g == usize::MAX {
                continue;
            }
            let set = &groups[g];
            for a in 0..n {
                let mine = &owners[a];
                let common = set.iter().filter(|s| mine.contains(s)).count();
                if common == set.len() {
                    if col_group[a] != g || a <= b {
                        mask[b * np + a] = 1.0;
                    }
                } else if common != 0 && common != mine.len() {
                    // Overlapping, not nested.
                    return None;
                }
            }
        }
        let quads = mask
            .chunks_exact(np)
            .map(|m| {
                let nonzero: Vec<usize> = (0..np / 4)
                    .filter(|&t| m[4 * t..4 * t + 4].iter().any(|&x| x != 0.0))
                    .collect();
                match (nonzero.first(), nonzero.last()) {
                    (Some(&lo), Some(&hi)) => lo..hi + 1,
                    _ => 0..0,
                }
            })
            .collect();
        let n_groups = groups.len();
        Some(TwistPlan {
            n_q,
            seg_mom: vec![Mom::zero(); segments.len()],
            segments,
            col_steps,
            groups,
            col_group,
            np,
            quads,
            mask,
            grp_mom: vec![Mom::zero(); n_groups],
            xs: vec![[[0.0; 4]; 6]; np / 4],
            y: vec![[0.0; 6]; n],
            c: vec![0.0; n * np],
        })
    }

    /// The segments' and groups' moments of the frame (`kin`, `targets`) about the weighted
    /// centroid of its present markers, which it returns (`None`: no marker present).
    #[inline(always)]
    fn moments(
        &mut self,
        prob: &Problem,
        kin: &KinData,
        targets: &[Vector3<f64>],
    ) -> Option<Vector3<f64>> {
        let markers = prob.model.markers();
        let weight = |j: usize| {
            let w = markers[j].weight;
            if targets[j].x.is_nan() || w <= 0.0 {
                0.0
            } else {
                w
            }
        };
        // The reference point: the weighted centroid of the present markers.
        let centre = weighted_centroid(&self.segments, kin, weight)?;
        for (seg, mom) in self.segments.iter().zip(&mut self.seg_mom) {
            *mom = Mom::zero();
            for &j in seg {
                let w = weight(j);
                if w > 0.0 {
                    mom.add_marker(w, kin.markers[j] - centre, targets[j] - kin.markers[j]);
                }
            }
        }
        for (set, mom) in self.groups.iter().zip(&mut self.grp_mom) {
            *mom = Mom::zero();
            for &s in set {
                mom.add(&self.seg_mom[s]);
            }
        }
        Some(centre)
    }

    /// `h` alone (n) of [`TwistPlan::gram`]: the same numbers, bit for bit, without the
    /// products of `G`.
    #[inline(always)]
    pub(crate) fn gradient(
        &mut self,
        prob: &Problem,
        kin: &KinData,
        targets: &[Vector3<f64>],
        half: &[f64],
        grad: &mut [f64],
    ) {
        let n = self.y.len();
        let Some(centre) = self.moments(prob, kin, targets) else {
            grad[..n].fill(0.0);
            return;
        };
        let cols = self.col_steps.iter().zip(&self.col_group);
        for (a, (steps, &g)) in cols.enumerate() {
            if g == usize::MAX {
                grad[a] = 0.0;
                continue;
            }
            let (w, v) = scaled_twist(kin, steps, &centre, (a, self.n_q), half);
            let k = &self.grp_mom[g];
            grad[a] = w.dot(&k.r1) + v.dot(&k.r0);
        }
    }

    /// Writes `G` (n × n, column-major) and `h` (n) of the frame whose kinematics (poses,
    /// markers, every step's frame) `kin` holds, with targets `targets` (NaN: missing) and
    /// free-parameter scales `half`. Inlined into the kernel's AVX2 entry point, where the
    /// products over the columns run four lanes wide (the same operations in the same order).
    #[inline(always)]
    pub(crate) fn gram(
        &mut self,
        prob: &Problem,
        kin: &KinData,
        targets: &[Vector3<f64>],
        half: &[f64],
        gram: &mut [f64],
        grad: &mut [f64],
    ) {
        let (n, np) = (self.y.len(), self.np);
        let Some(centre) = self.moments(prob, kin, targets) else {
            gram[..n * n].fill(0.0);
            grad[..n].fill(0.0);
            return;
        };
        // The columns' twists and `K ξ` (borrowed apart, so that the stores into `xs` and `y`
        // are not taken to alias the plan's other vectors).
        let (n_q, grp_mom, xs, ys) = (self.n_q, &self.grp_mom, &mut self.xs, &mut self.y);
        let cols = self
            .col_steps
            .iter()
            .zip(&self.col_group)
            .zip(ys.iter_mut());
        for (a, ((steps, &g), ya)) in cols.enumerate() {
            let xq = &mut xs[a / 4];
            let lane = a % 4;
            if g == usize::MAX {
                grad[a] = 0.0;
                *ya = [0.0; 6];
                for xk in xq.iter_mut() {
                    xk[lane] = 0.0;
                }
                continue;
            }
            let (w, v) = scaled_twist(kin, steps, &centre, (a, n_q), half);
            let k = &grp_mom[g];
            grad[a] = w.dot(&k.r1) + v.dot(&k.r0);
            let t = &k.theta;
            let yw = Vector3::new(
                t[0] * w.x + t[3] * w.y + t[4] * w.z,
                t[3] * w.x + t[1] * w.y + t[5] * w.z,
                t[4] * w.x + t[5] * w.y + t[2] * w.z,
            ) + k.c.cross(&v);
            let yv = k.mass * v + w.cross(&k.c);
            for (xk, x) in xq.iter_mut().zip([w.x, w.y, w.z, v.x, v.y, v.z]) {
                xk[lane] = x;
            }
            *ya = [yw.x, yw.y, yw.z, yv.x, yv.y, yv.z];
        }
        let c = &mut self.c;
        twist_products(&self.y, &self.xs, &self.mask, &self.quads, np, c);
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor supports AVX2 (checked just above).
            unsafe { mirror_avx2(c, n, np, gram) };
            return;
        }
        mirror(c, n, np, gram);
    }
}

/// The twist of column `a` (of `n_q` coordinates, then the free parameters) about `centre`,
/// a free parameter's scaled by its half-range `half`.
#[inline(always)]
fn scaled_twist(
    kin: &KinData,
    steps: &Steps,
    centre: &Vector3<f64>,
    (a, n_q): (usize, usize),
    half: &[f64],
) -> (Vector3<f64>, Vector3<f64>) {
    let (w, v) = column_twist(kin, steps, centre);
    match a.checked_sub(n_q) {
        Some(k) => (w * half[k], v * half[k]),
        None => (w, v),
    }
}

/// `G = C + Cᵀ` off the diagonal (of each pair, one of the two is formed, the other an exact
/// 0), C on it; `G` n × n column-major, C n columns of `np`.
#[inline(always)]
fn mirror(c: &[f64], n: usize, np: usize, gram: &mut [f64]) {
    assert!(c.len() >= n * np && gram.len() >= n * n && n <= np);
    let cp = c.as_ptr();
    let g = gram.as_mut_ptr();
    for b in 0..n {
        // SAFETY: every index is below n·np into `c` and below n·n into `gram` (a, b < n
        // ≤ np, asserted above).
        unsafe {
            *g.add(b * n + b) = *cp.add(b * np + b);
            for a in b + 1..n {
                let v = *cp.add(b * np + a) + *cp.add(a * np + b);
                *g.add(b * n + a) = v;
                *g.add(a * n + b) = v;
            }
        }
    }
}

/// The transpose of a 4 × 4 block held as four registers (rows in, columns out).
#[cfg(target_arch = "x86_64")]
macro_rules! transpose4 {
    ($r0:expr, $r1:expr, $r2:expr, $r3:expr) => {{
        let t0 = _mm256_unpacklo_pd($r0, $r1);
        let t1 = _mm256_unpackhi_pd($r0, $r1);
        let t2 = _mm256_unpacklo_pd($r2, $r3);
        let t3 = _mm256_unpackhi_pd($r2, $r3);
        [
            _mm256_permute2f128_pd(t0, t2, 0x20),
            _mm256_permute2f128_pd(t1, t3, 0x20),
            _mm256_permute2f128_pd(t0, t2, 0x31),
            _mm256_permute2f128_pd(t1, t3, 0x31),
        ]
    }};
}

/// [`mirror`] by 4 × 4 blocks: block (A, B) of G (A below B) is C's block plus the transpose
/// of C's block (B, A), and block (B, A) its transpose (the same sums: `x + y = y + x`
/// exactly); on a diagonal block the diagonal is C's alone. Rows and columns past the last
/// full block as [`mirror`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn mirror_avx2(c: &[f64], n: usize, np: usize, gram: &mut [f64]) {
    use std::arch::x86_64::*;
    assert!(c.len() >= n * np && gram.len() >= n * n && n <= np);
    let (cp, g) = (c.as_ptr(), gram.as_mut_ptr());
    let full = n / 4 * 4;
    // SAFETY: every block's rows and columns are below `full` ≤ n ≤ np, the rest below n
    // (asserted above).
    unsafe {
        for b0 in (0..full).step_by(4) {
            for a0 in (b0..full).step_by(4) {
                // c_i: C's column b0 + i, rows a0..a0 + 4; r_j: column a0 + j, rows b0..b0 + 4.
                let col = |i: usize| cp.add((b0 + i) * np + a0);
                let row = |j: usize| cp.add((a0 + j) * np + b0);
                let (c0, c1, c2, c3) = (
                    _mm256_loadu_pd(col(0)),
                    _mm256_loadu_pd(col(1)),
                    _mm256_loadu_pd(col(2)),
                    _mm256_loadu_pd(col(3)),
                );
                let rt = transpose4!(
                    _mm256_loadu_pd(row(0)),
                    _mm256_loadu_pd(row(1)),
                    _mm256_loadu_pd(row(2)),
                    _mm256_loadu_pd(row(3))
                );
                let mut s0 = _mm256_add_pd(c0, rt[0]);
                let mut s1 = _mm256_add_pd(c1, rt[1]);
                let mut s2 = _mm256_add_pd(c2, rt[2]);
                let mut s3 = _mm256_add_pd(c3, rt[3]);
                if a0 == b0 {
                    // The diagonal entries (lane i of column i) from C alone.
                    s0 = _mm256_blend_pd(s0, c0, 0b0001);
                    s1 = _mm256_blend_pd(s1, c1, 0b0010);
                    s2 = _mm256_blend_pd(s2, c2, 0b0100);
                    s3 = _mm256_blend_pd(s3, c3, 0b1000);
                }
                let out = |i: usize| g.add((b0 + i) * n + a0);
                _mm256_storeu_pd(out(0), s0);
                _mm256_storeu_pd(out(1), s1);
                _mm256_storeu_pd(out(2), s2);
                _mm256_storeu_pd(out(3), s3);
                if a0 != b0 {
                    let st = transpose4!(s0, s1, s2, s3);
                    for (j, sj) in st.into_iter().enumerate() {
                        _mm256_storeu_pd(g.add((a0 + j) * n + b0), sj);
                    }
                }
            }
        }
        let rem = n - full;
        if rem > 0 {
            // The last, partial block of rows (a ≥ full) against each full block of columns:
            // C's rows past n are 0 (its padding) and its columns past n are not read (0).
            let lanes = _mm256_setr_epi64x(
                if rem > 0 { -1 } else { 0 },
                if rem > 1 { -1 } else { 0 },
                if rem > 2 { -1 } else { 0 },
                0,
            );
            let row = |j: usize, b0: usize| {
                if j < rem {
                    _mm256_loadu_pd(cp.add((full + j) * np + b0))
                } else {
                    _mm256_setzero_pd()
                }
            };
            for b0 in (0..full).step_by(4) {
                let col = |i: usize| _mm256_loadu_pd(cp.add((b0 + i) * np + full));
                let rt = transpose4!(row(0, b0), row(1, b0), row(2, b0), row(3, b0));
                let s0 = _mm256_add_pd(col(0), rt[0]);
                let s1 = _mm256_add_pd(col(1), rt[1]);
                let s2 = _mm256_add_pd(col(2), rt[2]);
                let s3 = _mm256_add_pd(col(3), rt[3]);
                for (i, si) in [s0, s1, s2, s3].into_iter().enumerate() {
                    _mm256_maskstore_pd(g.add((b0 + i) * n + full), lanes, si);
                }
                let st = transpose4!(s0, s1, s2, s3);
                for (j, sj) in st.into_iter().enumerate().take(rem) {
                    _mm256_storeu_pd(g.add((full + j) * n + b0), sj);
                }
            }
            for b in full..n {
                *g.add(b * n + b) = *cp.add(b * np + b);
                for a in b + 1..n {
                    let v = *cp.add(b * np + a) + *cp.add(a * np + b);
                    *g.add(b * n + a) = v;
                    *g.add(a * n + b) = v;
                }
            }
        }
    }
}

#[cfg(test)]
#[path = "kernel_twist_tests.rs"]
mod tests;
