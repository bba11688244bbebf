//! The normal equations of one frame from *composite* marker moments: each pair of columns
//! once, instead of once per segment both move.
//!
//! [`super::normal::Moments`] forms `JᵀWJ` segment by segment: column `a`'s velocity field on
//! segment `s` is rigid, `J_a(x) = ω_a × (x − P) + v_a` about any point `P`, and the segment
//! contributes `ξ_aᵀ K_s ξ_b` with `ξ = (ω, v)` and `K_s` the moments of its present markers.
//! When column `a`'s twist is the same on every segment it moves (its steps all lie on the
//! path to each of them: true unless one coordinate drives steps of two branches), the sum
//! over segments collapses onto composite moments, as in Featherstone's composite-rigid-body
//! algorithm (*Rigid Body Dynamics Algorithms*, Springer 2008, §6.2):
//!
//! `(JᵀWJ)_ab = ξ_aᵀ (Σ_{s moved by a and b} K_s) ξ_b`,
//!
//! and the segments moved by both are those moved by the "deeper" of the two (nested sets
//! on a tree). About one reference point `P` (the weighted centroid of every present marker),
//! with `d_j = x_j − P`, `r_j = m_j − x_j` and sums over the composite's markers:
//! `M = Σ w_j`, `h = Σ w_j d_j`, `Θ = Σ w_j (‖d_j‖² I − d_j d_jᵀ)`, `ρ₀ = Σ w_j r_j`,
//! `ρ₁ = Σ w_j d_j × r_j`,
//!
//! * `ξ_aᵀ K ξ_b = ω_a·(Θ ω_b + h × v_b) + v_a·(M v_b + ω_b × h)`,
//! * `(JᵀW r)_a = ω_a·ρ₁ + v_a·ρ₀`.
//!
//! On the 12-coordinate leg this is 78 column pairs instead of 199 segment-column pairs.
//! Where a column's twist differs between segments, [`Composite::new`] returns `None` and
//! the per-segment form is used.

use nalgebra::{Matrix3, Vector3};

use crate::kinematics::twist::{column_twist, group_columns, twist_products, weighted_centroid};
use crate::kinematics::KinData;

/// One marker-carrying segment for [`Composite::new`]: its markers and its column steps
/// `(column, step, scale, rotation)`.
pub(super) type SegmentPlan = (Vec<usize>, Vec<(usize, usize, f64, bool)>);

/// Moments of a set of markers about the reference point (see the module docs).
#[derive(Debug, Clone, Copy)]
struct Mom {
    mass: f64,
    h: Vector3<f64>,
    theta: Matrix3<f64>,
    r0: Vector3<f64>,
    r1: Vector3<f64>,
}

impl Mom {
    fn zero() -> Self {
        Mom {
            mass: 0.0,
            h: Vector3::zeros(),
            theta: Matrix3::zeros(),
            r0: Vector3::zeros(),
            r1: Vector3::zeros(),
        }
    }
    fn add(&mut self, o: &Mom) {
        self.mass += o.mass;
        self.h += o.h;
        self.theta += o.theta;
        self.r0 += o.r0;
        self.r1 += o.r1;
    }
}

/// The composite form's plan and scratch.
#[derive(Debug, Clone)]
pub(super) struct Composite {
    /// Markers of each marker-carrying segment.
    segments: Vec<Vec<usize>>,
    /// Per model column: `(step, scale, rotation)` of its steps (empty: moves no marker).
    col_steps: Vec<Vec<(usize, f64, bool)>>,
    /// Per model column: its group (the set of segments it moves), `usize::MAX` for none.
    col_group: Vec<usize>,
    /// Per group: the segments (indices into `segments`).
    groups: Vec<Vec<usize>>,
    /// Every pair of columns that move a common segment, once (diagonal included):
    /// `(deep, other)`, `deep` the column whose segments are the common ones.
    pairs: Vec<(usize, usize)>,
    /// The pairs of [`Self::pairs`] whose columns are both active ([`Self::set_active`]):
    /// `(deep, other, deep·n + other, other·n + deep)` with active indices in the offsets.
    active_pairs: Vec<(usize, usize, usize, usize)>,
    seg_mom: Vec<Mom>,
    grp_mom: Vec<Mom>,
    /// Model columns rounded up to a multiple of 4 (the column stride of `prod`).
    np: usize,
    /// The twists `ξ = (ω, v)` of the model columns by groups of four, component-major:
    /// component k of column c at `xs[c / 4][k][c mod 4]`.
    xs: Vec<[[f64; 4]; 6]>,
    /// Per model column: `K ξ`, as `(Θω + h×v, Mv + ω×h)`.
    y: Vec<[f64; 6]>,
    /// Per model column `deep`: the groups of four columns that hold every `other` of its
    /// pairs (the products formed for it).
    quads: Vec<std::ops::Range<usize>>,
    /// All 1 (`n_q × np`): no product is masked.
    ones: Vec<f64>,
    /// `prod[deep·np + other] = ξ_other·(K ξ_deep)`.
    prod: Vec<f64>,
}

impl Composite {
    /// The plan from each marker-carrying segment's markers and its column steps
    /// `(column, step, scale, rotation)`; `None` when some column's twist differs between
    /// segments or two columns' segment sets are not nested.
    pub(super) fn new(n_q: usize, segments: &[SegmentPlan]) -> Option<Self> {
        let mut owners: Vec<Vec<usize>> = vec![Vec::new(); n_q];
        let mut col_steps: Vec<Vec<(usize, f64, bool)>> = vec![Vec::new(); n_q];
        for (s, (_, steps)) in segments.iter().enumerate() {
            let mut cols: Vec<usize> = steps.iter().map(|&(c, ..)| c).collect();
            cols.sort_unstable();
            cols.dedup();
            for c in cols {
                let mine: Vec<(usize, f64, bool)> = steps
                    .iter()
                    .filter(|&&(col, ..)| col == c)
                    .map(|&(_, step, scale, rot)| (step, scale, rot))
                    .collect();
                if owners[c].is_empty() {
                    col_steps[c] = mine;
                } else if col_steps[c] != mine {
                    return None;
                }
                owners[c].push(s);
            }
        }
        let (groups, col_group) = group_columns(&owners);
        let mut pairs = Vec::new();
        for a in 0..n_q {
            for b in 0..=a {
                if owners[a].is_empty() || owners[b].is_empty() {
                    continue;
                }
                let common: Vec<usize> = owners[a]
                    .iter()
                    .copied()
                    .filter(|s| owners[b].contains(s))
                    .collect();
                if common.is_empty() {
                    continue;
                }
                if common == owners[b] {
                    pairs.push((b, a));
                } else if common == owners[a] {
                    pairs.push((a, b));
                } else {
                    return None;
                }
            }
        }
        let n_groups = groups.len();
        let np = n_q.div_ceil(4) * 4;
        let quads = (0..n_q)
            .map(|deep| {
                let quad = pairs.iter().filter(|p| p.0 == deep).map(|p| p.1 / 4);
                match (quad.clone().min(), quad.max()) {
                    (Some(lo), Some(hi)) => lo..hi + 1,
                    _ => 0..0,
                }
            })
            .collect();
        Some(Composite {
            segments: segments.iter().map(|(m, _)| m.clone()).collect(),
            col_steps,
            col_group,
            groups,
            pairs,
            active_pairs: Vec::new(),
            seg_mom: vec![Mom::zero(); segments.len()],
            grp_mom: vec![Mom::zero(); n_groups],
            np,
            xs: vec![[[0.0; 4]; 6]; np / 4],
            y: vec![[0.0; 6]; n_q],
            quads,
            ones: vec![1.0; n_q * np],
            prod: vec![0.0; n_q * np],
        })
    }

    /// Lists the pairs both of whose columns are active, with their places in the `n × n`
    /// matrix (`active_index[c]`: the active index of column `c`, `usize::MAX`: not active),
    /// once per active set instead of once per iteration.
    pub(super) fn set_active(&mut self, active_index: &[usize], n: usize) {
        self.active_pairs.clear();
        for &(deep, other) in &self.pairs {
            let (di, oi) = (active_index[deep], active_index[other]);
            if di != usize::MAX && oi != usize::MAX {
                self.active_pairs
                    .push((deep, other, di * n + oi, oi * n + di));
            }
        }
    }

    /// Writes `JᵀWJ` (n × n, column-major, n = active count) into `a` and `JᵀW r` into `g`;
    /// `active_index[c]`: the active index of column `c` (`usize::MAX`: not active).
    #[allow(clippy::too_many_arguments)] // the per-segment form's inputs plus the active map
    pub(super) fn normal_equations(
        &mut self,
        kin: &KinData,
        targets: &[Vector3<f64>],
        weights: &[f64],
        active_index: &[usize],
        n: usize,
        a: &mut [f64],
        g: &mut [f64],
    ) {
        a[..n * n].fill(0.0);
        g[..n].fill(0.0);
        // The reference point: the weighted centroid of the present markers.
        let Some(centre) = weighted_centroid(&self.segments, kin, |j| weights[j]) else {
            return;
        };
        for (markers, mom) in self.segments.iter().zip(&mut self.seg_mom) {
            *mom = Mom::zero();
            for &j in markers {
                let w = weights[j];
                if w > 0.0 {
                    let d = kin.markers[j] - centre;
                    let r = targets[j] - kin.markers[j];
                    mom.mass += w;
                    mom.h += w * d;
                    mom.theta +=
                        w * (Matrix3::from_diagonal_element(d.norm_squared()) - d * d.transpose());
                    mom.r0 += w * r;
                    mom.r1 += w * d.cross(&r);
                }
            }
        }
        for (members, mom) in self.groups.iter().zip(&mut self.grp_mom) {
            *mom = Mom::zero();
            for &s in members {
                mom.add(&self.seg_mom[s]);
            }
        }
        for (c, steps) in self.col_steps.iter().enumerate() {
            let ai = active_index[c];
            if ai == usize::MAX || steps.is_empty() {
                continue;
            }
            let (w, v) = column_twist(kin, steps, &centre);
            let k = &self.grp_mom[self.col_group[c]];
            g[ai] = w.dot(&k.r1) + v.dot(&k.r0);
            let (yw, yv) = (k.theta * w + k.h.cross(&v), k.mass * v + w.cross(&k.h));
            for (xk, x) in self.xs[c / 4]
                .iter_mut()
                .zip([w.x, w.y, w.z, v.x, v.y, v.z])
            {
                xk[c % 4] = x;
            }
            self.y[c] = [yw.x, yw.y, yw.z, yv.x, yv.y, yv.z];
        }
        // Every pair's `ξ_other·(K ξ_deep)` = `ω·(Θω' + h×v') + v·(Mv' + ω'×h)`, four
        // columns `other` at a time (the pairs of inactive columns are formed and not read).
        twist_products(
            &self.y,
            &self.xs,
            &self.ones,
            &self.quads,
            self.np,
            &mut self.prod,
        );
        let a = &mut a[..n * n];
        for &(deep, other, lower, upper) in &self.active_pairs {
            let value = self.prod[deep * self.np + other];
            a[lower] = value;
            a[upper] = value;
        }
    }
}
