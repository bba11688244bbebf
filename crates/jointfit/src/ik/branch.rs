//! Which of the equivalent coordinate vectors of one pose inverse kinematics reports.
//!
//! Marker positions do not change when
//!
//! * a coordinate that drives a single rotation step linearly (angle `s = k·q`) and nothing
//!   else moves by a whole turn, `q → q + 2π/|k|` (its *period*);
//! * three consecutive rotation steps of one segment about mutually orthogonal axes
//!   `e₁, e₂, e₃` (an Euler or Tait–Bryan triple: OpenSim's hip, pelvis and lumbar
//!   `rotation1..3`, a gimbal joint, the rotations of a free joint), each driven so by its
//!   own coordinate, change to the *other branch* of the same rotation,
//!   `(s₁, s₂, s₃) → (s₁ + π, π − s₂, s₃ + π)`.
//!
//! The second identity: a half turn about `e₁` reverses `e₂` and `e₃`, so
//! `R(e₁, π) R(e₂, θ) = R(e₂, −θ) R(e₁, π)`, and two half turns about perpendicular axes
//! compose to a half turn about the axis perpendicular to both, `R(e₁, π) R(e₃, π) =
//! R(e₂, π)`; hence `R(e₁, s₁ + π) R(e₂, π − s₂) R(e₃, s₃ + π) = R(e₁, s₁) R(e₂, s₂ − π)
//! R(e₂, π) R(e₃, s₃) = R(e₁, s₁) R(e₂, s₂) R(e₃, s₃)` (every Euler-angle sequence has two
//! solutions away from gimbal lock; e.g. Diebel, *Representing Attitude*, 2006).
//!
//! The cost of inverse kinematics is the same on every branch, so a warm-started chain of
//! frames keeps whichever branch its seed or an earlier frame happened to reach, and a
//! solution can drift whole turns away from zero. Before the result is reported,
//! [`Branches::canonicalize`] picks, for every triple, the branch whose coordinates lie
//! farthest inside the model's coordinate ranges (least total distance outside them; the
//! solved branch on a tie), then moves every periodic coordinate by whole periods into its
//! range (or nearest to it; no move when it is already inside). A function of the frame's
//! coordinates alone: the same on any chunking and thread count, and the warm-start chain
//! itself is not changed.

use std::f64::consts::PI;

use nalgebra::Vector3;

use crate::model::{Item, Model, Motion, Source};

/// Mutually orthogonal: `|eᵢ·eⱼ|` at most this.
const ORTHOGONAL: f64 = 1e-9;

/// The equivalent-coordinate structure of a model (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct Branches {
    /// Per coordinate: its period (rad), or 0 when it has none.
    period: Vec<f64>,
    /// Euler triples: `(coordinate, k)` of each step in chain order (angle `s = k·q`).
    triples: Vec<[(usize, f64); 3]>,
    range: Vec<[f64; 2]>,
}

impl Branches {
    pub(crate) fn new(model: &Model) -> Self {
        let n = model.coordinates().len();
        // Per coordinate: (steps it drives, k of the last linear rotation step, any other use).
        let mut uses = vec![(0usize, 0.0f64, false); n];
        for step in &model.steps {
            match step.source {
                Source::Coord { index, scale } => {
                    let u = &mut uses[index];
                    u.0 += 1;
                    u.1 = scale;
                    u.2 |= !step.motion.is_rotation() || scale == 0.0;
                }
                Source::Func { index, .. } => uses[index].2 = true,
                Source::Const(_) | Source::Param { .. } => {}
            }
        }
        for d in model.dependents() {
            if let crate::model::custom::CoordRule::Coupled { independent, .. } = d.rule {
                uses[independent].2 = true;
            }
        }
        let period: Vec<f64> = uses
            .iter()
            .map(|&(count, k, other)| {
                if count == 1 && !other {
                    2.0 * PI / k.abs()
                } else {
                    0.0
                }
            })
            .collect();
        let mut triples = Vec::new();
        for items in &model.plan.items {
            let mut i = 0;
            while i + 3 <= items.len() {
                match triple(model, &items[i..i + 3], &period) {
                    Some(t) => {
                        triples.push(t);
                        i += 3;
                    }
                    None => i += 1,
                }
            }
        }
        Branches {
            period,
            triples,
            range: model.coordinates().iter().map(|c| c.range).collect(),
        }
    }

    /// The Euler triples found, as coordinate indices in chain order.
    #[cfg(test)]
    pub(crate) fn triples(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        self.triples.iter().map(|t| t.map(|(c, _)| c))
    }

    /// The coordinate's period (rad; 0: none).
    #[cfg(test)]
    pub(crate) fn period(&self, c: usize) -> f64 {
        self.period[c]
    }

    /// Replaces `q` by the equivalent coordinates inside the ranges (see the module docs);
    /// the marker positions stay the same (to rounding). NaN coordinates are left alone.
    pub(crate) fn canonicalize(&self, q: &mut [f64]) {
        for &[(a, ka), (b, kb), (c, kc)] in &self.triples {
            let solved = [q[a], q[b], q[c]];
            let other = [
                solved[0] + PI / ka,
                PI / kb - solved[1],
                solved[2] + PI / kc,
            ];
            let cost = |v: [f64; 3]| -> f64 {
                [a, b, c]
                    .iter()
                    .zip(v)
                    .map(|(&i, x)| self.wrapped(i, x).1)
                    .sum()
            };
            if cost(other) < cost(solved) {
                q[a] = other[0];
                q[b] = other[1];
                q[c] = other[2];
            }
        }
        for (i, v) in q.iter_mut().enumerate() {
            *v = self.wrapped(i, *v).0;
        }
    }

    /// Coordinate `i`'s value `v` moved by whole periods into its range (the fewest periods
    /// among those inside; nearest to the range when none is), with its distance outside.
    fn wrapped(&self, i: usize, v: f64) -> (f64, f64) {
        let [lo, hi] = self.range[i];
        let outside = |x: f64| (lo - x).max(x - hi).max(0.0);
        let t = self.period[i];
        if t == 0.0 || !v.is_finite() || (lo..=hi).contains(&v) {
            return (v, outside(v));
        }
        // Shifts n with v + n t ≥ lo, and with v + n t ≤ hi.
        let n1 = ((lo - v) / t).ceil();
        let n2 = ((hi - v) / t).floor();
        let n = if n1 <= n2 {
            0.0f64.clamp(n1, n2)
        } else {
            // No whole period lands inside: the nearer of the values just below and above.
            let (below, above) = (outside(v + n2 * t), outside(v + n1 * t));
            if below < above || (below == above && n2.abs() < n1.abs()) {
                n2
            } else {
                n1
            }
        };
        let x = if n == 0.0 { v } else { v + n * t };
        (x, outside(x))
    }
}

/// The triple of three consecutive coordinate steps of one segment, when they are rotations
/// about mutually orthogonal axes, each by its own periodic coordinate.
fn triple(model: &Model, items: &[Item], period: &[f64]) -> Option<[(usize, f64); 3]> {
    let mut out = [(0usize, 0.0f64); 3];
    let mut axes = [Vector3::zeros(); 3];
    for (slot, item) in items.iter().enumerate() {
        let Item::Coord(k) = *item else {
            return None;
        };
        let step = &model.steps[k];
        let Source::Coord { index, scale } = step.source else {
            return None;
        };
        if period[index] == 0.0 || out[..slot].iter().any(|&(c, _)| c == index) {
            return None;
        }
        axes[slot] = match &step.motion {
            Motion::RotX => Vector3::x(),
            Motion::RotY => Vector3::y(),
            Motion::RotZ => Vector3::z(),
            Motion::Rot(u) => u.into_inner(),
            _ => return None,
        };
        out[slot] = (index, scale);
    }
    let orthogonal = |i: usize, j: usize| axes[i].dot(&axes[j]).abs() <= ORTHOGONAL;
    (orthogonal(0, 1) && orthogonal(1, 2) && orthogonal(0, 2)).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{forward_kinematics, KinData, Want};
    use crate::model::lower_limb::{lower_limb, Side};

    fn markers(model: &Model, q: &[f64]) -> Vec<Vector3<f64>> {
        let mut kin = KinData::new(model);
        forward_kinematics(model, &model.nominal_params(), q, Want::Positions, &mut kin);
        kin.markers.clone()
    }

    /// On the leg (free pelvis, gimbal z-x-y hip): the triples are the pelvis rotations and
    /// the hip; for in-range poses the other branch and whole turns give the same markers
    /// (to 1e-12 m) and [`Branches::canonicalize`] brings them back to the in-range pose.
    #[test]
    fn other_branch_and_whole_turns_return_to_the_range() {
        let model = Model::compile(&lower_limb(Side::Left)).unwrap();
        let branches = Branches::new(&model);
        let name = |c: usize| model.coordinates()[c].name.as_str();
        let triples: Vec<[&str; 3]> = branches.triples().map(|t| t.map(name)).collect();
        assert!(
            triples.contains(&["hip_flexion", "hip_adduction", "hip_rotation"]),
            "{triples:?}"
        );
        let hip = triples
            .iter()
            .position(|t| t[0] == "hip_flexion")
            .map(|i| branches.triples().nth(i).unwrap())
            .unwrap();
        for case in 0..50 {
            // In-range pose, away from the range edges by 2 %.
            let q: Vec<f64> = model
                .coordinates()
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let u = 0.5 + 0.48 * ((i * 13 + case * 7) as f64 * 0.77).sin();
                    c.range[0] + u * (c.range[1] - c.range[0])
                })
                .collect();
            let mut other = q.clone();
            other[hip[0]] += PI;
            other[hip[1]] = PI - other[hip[1]];
            other[hip[2]] += PI - 4.0 * PI * (case % 2) as f64;
            for (i, v) in other.iter_mut().enumerate() {
                if branches.period(i) > 0.0 && i != hip[2] {
                    *v += 2.0 * PI * ((case + i) % 3) as f64 - 2.0 * PI;
                }
            }
            let (x, y) = (markers(&model, &q), markers(&model, &other));
            for (a, b) in x.iter().zip(&y) {
                assert!((a - b).norm() < 1e-12, "case {case}: same markers");
            }
            let mut back = other.clone();
            branches.canonicalize(&mut back);
            for (i, (a, b)) in q.iter().zip(&back).enumerate() {
                assert!((a - b).abs() < 1e-12, "case {case} {}: {a} vs {b}", name(i));
            }
            // An in-range pose is left as it is, bit for bit.
            let mut same = q.clone();
            branches.canonicalize(&mut same);
            assert_eq!(same, q);
        }
    }
}
