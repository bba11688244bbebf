//! Which coordinates the present markers of a frame determine, from the whole chain.
//!
//! A frame's coordinates are determined when the marker Jacobian `J` (rows of the present
//! markers, every coordinate a column) has full column rank. The joint constraints carry
//! information between segments: two markers on a foot fix its two joint angles once the
//! shank is known, a pelvis with two markers is fixed by the thighs that hang from it, and a
//! single marker off the axis of a one-degree-of-freedom joint (a wrist marker on the radius,
//! for pronation) fixes that joint's angle once its parent is known. A per-segment marker
//! count cannot see this; the rank of `J` can.
//!
//! The rank, with a physical tolerance. With unit weight on every present marker and
//! independent noise of standard deviation `σ` on every marker coordinate, the least-squares
//! estimate of `q` has covariance `σ² (JᵀJ)⁻¹` (Gauss–Markov; e.g. Björck, *Numerical
//! Methods for Least Squares Problems*, 1996, §1.1). A coordinate is *undetermined* when
//! `JᵀJ` is singular along a direction it takes part in, or when 1 mm of noise moves it by
//! more than [`IkOptions::max_angle_per_mm`] (default 1 rad: the markers act on it through a
//! lever arm shorter than 1 mm) or [`IkOptions::max_translation_per_mm`] (default 1 m).
//! Undetermined coordinates are removed one at a time, worst first (for a singular matrix:
//! the largest component of the eigenvector of the smallest eigenvalue of the Jacobi-scaled
//! `D^{-1/2} JᵀJ D^{-1/2}`), and the test repeats on the remaining coordinates — holding
//! one coordinate fixed can determine the others.
//!
//! Coordinate tasks (OpenSim's `IKCoordinateTask`, [`super::CoordinateTask`]) add
//! `w (q_c − q̂_c)²` to the objective: the Hessian `JᵀJ + D` (`D` positive on the task
//! coordinates `T`) is singular exactly when some `v ≠ 0` with `v_T = 0` has `Jv = 0`. A
//! coordinate with a task is therefore determined, and the test runs on the others only.
//!
//! Where `J` is evaluated. First at a fixed generic configuration (defaults plus fixed
//! non-zero angles): its rank there is the structural rank of the marker pattern, the
//! verdict depends only on which markers are present, and it is cached per marker pattern,
//! so a frame whose markers determine every coordinate pays nothing more. When that
//! configuration leaves some coordinate undetermined, the verdict is the one at the frame's
//! own starting pose (the previous frame's solution, or the seed): the actual kinematic
//! chain decides, not the arbitrary configuration.

use nalgebra::{DMatrix, SymmetricEigen, Vector3};

use super::normal::Moments;
use super::IkOptions;
use crate::kinematics::{forward_kinematics_axes, KinData};
use crate::model::{CoordKind, Model};

/// The marker noise the limits refer to (m).
const NOISE: f64 = 1e-3;
/// Eigenvalues of the Jacobi-scaled normal matrix below this (relative to the largest) are
/// treated as zero.
const RANK_TOL: f64 = 1e-10;
/// Verdicts kept before the cache is cleared.
const CACHE_SIZE: usize = 64;

/// Cached solvability verdicts for one parameter vector.
#[derive(Debug, Clone)]
pub(super) struct Solvability {
    /// The parameters `kin` was evaluated at (`None`: not yet; an empty vector is a
    /// model without parameters, not a missing evaluation).
    p: Option<Vec<f64>>,
    /// Kinematics at the generic configuration.
    kin: KinData,
    /// Kinematics at the frame's own pose (the second look, not cached).
    pose_kin: KinData,
    moments: Moments,
    /// `(key, undetermined coordinates)`.
    cache: Vec<(Vec<bool>, Vec<usize>)>,
    /// Present markers, then the coordinates a task determines.
    mask: Vec<bool>,
    a: Vec<f64>,
    g: Vec<f64>,
    weights: Vec<f64>,
}

impl Solvability {
    pub(super) fn new(model: &Model) -> Self {
        let n = model.coordinates().len();
        Solvability {
            p: None,
            kin: KinData::new(model),
            pose_kin: KinData::new(model),
            moments: Moments::new(model),
            cache: Vec::new(),
            mask: vec![false; model.markers().len() + model.coordinates().len()],
            a: vec![0.0; n * n],
            g: vec![0.0; n],
            weights: vec![0.0; model.markers().len()],
        }
    }

    /// The coordinates the markers with positive `weights` leave undetermined at the
    /// generic configuration (see the module docs), in the order they were found; empty when
    /// the frame is solvable. `known[c]`: coordinate `c` has a coordinate task.
    pub(super) fn undetermined(
        &mut self,
        model: &Model,
        p: &[f64],
        weights: &[f64],
        known: &[bool],
        opts: &IkOptions,
    ) -> &[usize] {
        if self.p.as_deref() != Some(p) {
            self.p = Some(p.to_vec());
            self.cache.clear();
            let q = generic_configuration(model);
            forward_kinematics_axes(model, p, &q, &mut self.kin);
        }
        let nm = model.markers().len();
        for (m, w) in self.mask[..nm].iter_mut().zip(weights) {
            *m = *w > 0.0;
        }
        self.mask[nm..].copy_from_slice(known);
        if let Some(k) = self.cache.iter().position(|(m, _)| *m == self.mask) {
            return &self.cache[k].1;
        }
        let verdict = self.compute(model, opts, false);
        if self.cache.len() >= CACHE_SIZE {
            self.cache.clear();
        }
        self.cache.push((self.mask.clone(), verdict));
        &self.cache.last().expect("just pushed").1
    }

    /// The undetermined coordinates of the frame (see the module docs): none when the generic
    /// configuration finds none ([`Solvability::undetermined`], cached), else those at the
    /// frame's own pose `q`.
    pub(super) fn undetermined_at(
        &mut self,
        model: &Model,
        p: &[f64],
        weights: &[f64],
        known: &[bool],
        q: &[f64],
        opts: &IkOptions,
    ) -> Vec<usize> {
        if self.undetermined(model, p, weights, known, opts).is_empty() {
            return Vec::new();
        }
        if q.iter().any(|v| !v.is_finite()) {
            return self.undetermined(model, p, weights, known, opts).to_vec();
        }
        forward_kinematics_axes(model, p, q, &mut self.pose_kin);
        self.compute(model, opts, true)
    }

    /// The verdict for the present markers and known coordinates in `self.mask`, at the generic
    /// configuration (`kin`) or at the frame's pose (`pose_kin`).
    fn compute(&mut self, model: &Model, opts: &IkOptions, at_pose: bool) -> Vec<usize> {
        let n = model.coordinates().len();
        let nm = model.markers().len();
        for (w, &m) in self.weights.iter_mut().zip(&self.mask[..nm]) {
            *w = if m { 1.0 } else { 0.0 };
        }
        let all: Vec<usize> = (0..n).collect();
        self.moments.set_active(&all);
        let kin = if at_pose { &self.pose_kin } else { &self.kin };
        let targets: Vec<Vector3<f64>> = kin.markers.clone();
        self.moments
            .normal_equations(kin, &targets, &self.weights, n, &mut self.a, &mut self.g);
        let limit = |c: usize| match model.coordinates()[c].kind {
            CoordKind::Rotational => opts.max_angle_per_mm,
            CoordKind::Translational => opts.max_translation_per_mm,
        };
        let max_diag = (0..n).fold(0.0f64, |m, i| m.max(self.a[i * n + i]));
        let mut active: Vec<usize> = Vec::with_capacity(n);
        let mut removed = Vec::new();
        for c in 0..n {
            if self.mask[nm + c] {
                // Determined by its coordinate task.
                continue;
            }
            // A coordinate that moves no present marker.
            if self.a[c * n + c] <= 1e-14 * max_diag {
                removed.push(c);
            } else {
                active.push(c);
            }
        }
        while !active.is_empty() {
            let k = active.len();
            let d: Vec<f64> = active.iter().map(|&c| self.a[c * n + c]).collect();
            let s = DMatrix::from_fn(k, k, |r, col| {
                self.a[active[col] * n + active[r]] / (d[r] * d[col]).sqrt()
            });
            let eig = SymmetricEigen::new(s);
            let (imin, &lmin) = eig
                .eigenvalues
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .expect("k > 0");
            let lmax = eig.eigenvalues.iter().fold(0.0f64, |m, &v| m.max(v));
            let worst = if lmin <= RANK_TOL * lmax {
                // Singular: the coordinate that dominates the null direction.
                let v = eig.eigenvectors.column(imin);
                (0..k).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
            } else {
                // Standard deviation per mm of noise against the limit.
                let ratio = |i: usize| {
                    let var: f64 = (0..k)
                        .map(|e| eig.eigenvectors[(i, e)].powi(2) / eig.eigenvalues[e])
                        .sum::<f64>()
                        / d[i];
                    NOISE * var.sqrt() / limit(active[i])
                };
                let (i, r) = (0..k)
                    .map(|i| (i, ratio(i)))
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .expect("k > 0");
                (r > 1.0).then_some(i)
            };
            match worst {
                Some(i) => removed.push(active.remove(i)),
                None => break,
            }
        }
        removed
    }
}

/// A fixed configuration away from the special poses (straight knee, Euler-angle gimbal
/// lock): the defaults plus distinct angles of 0.1–0.4 rad.
fn generic_configuration(model: &Model) -> Vec<f64> {
    model
        .coordinates()
        .iter()
        .enumerate()
        .map(|(i, c)| match c.kind {
            CoordKind::Rotational => c.default + 0.1 + 0.3 * ((i as f64) * 0.618).fract(),
            CoordKind::Translational => c.default,
        })
        .collect()
}
