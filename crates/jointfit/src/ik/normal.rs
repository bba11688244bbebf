//! The normal equations of one frame from segment moments.

use nalgebra::{Matrix3, Vector3};

use super::composite::{Composite, SegmentPlan};
use crate::kinematics::KinData;
use crate::model::Model;

/// The normal equations `JᵀWJ δ = JᵀW r` of one frame, formed from segment moments
/// instead of the `3·n_markers × n_q` Jacobian.
///
/// On segment `s`, column `a` of the marker Jacobian is a rigid velocity field: every step
/// that moves `s` contributes `c_k ω_k × (x − o_k)` (rotation) or `c_k ω_k` (translation)
/// ([`crate::kinematics`]), so `J_a(x) = ω_a × (x − x̄) + v_a` with the twist
/// `ω_a = Σ_rot c_k ω_k`, `v_a = Σ_rot c_k ω_k × (x̄ − o_k) + Σ_trans c_k ω_k` about the
/// weighted centroid `x̄` of the segment's present markers. With `d_j = x_j − x̄` (so
/// `Σ w_j d_j = 0`), the segment's share of the normal equations is
///
/// * `(JᵀWJ)_ab = ω_aᵀ Θ ω_b + M v_a·v_b`, `Θ = Σ w_j (‖d_j‖² I − d_j d_jᵀ)`, `M = Σ w_j`,
/// * `(JᵀW r)_a = ω_a·Σ w_j d_j × r_j + v_a·Σ w_j r_j`,
///
/// the marker cloud's inertia-like moments contracted with the column twists. The cost per
/// iteration no longer grows with markers × columns², and the Jacobian is never filled.
#[derive(Debug, Clone)]
pub(super) struct Moments {
    segments: Vec<SegmentTerms>,
    /// Active index of each coordinate (`usize::MAX`: not active).
    active_index: Vec<usize>,
    /// Twists of one segment's columns: `(ω, v)`.
    twists: Vec<(Vector3<f64>, Vector3<f64>)>,
    /// The composite form, used when the model allows it ([`super::composite`]).
    composite: Option<Composite>,
}

/// The coordinates that move one marker-carrying segment.
#[derive(Debug, Clone)]
struct SegmentTerms {
    markers: Vec<usize>,
    /// Distinct coordinate columns that move the segment.
    cols: Vec<usize>,
    /// `(local column, step, scale, rotation)` for every step contribution.
    steps: Vec<(usize, usize, f64, bool)>,
}

impl Moments {
    pub(super) fn new(model: &Model) -> Self {
        let mut segments = Vec::new();
        let mut widest = 0;
        for (s, markers) in model.plan.markers_by_segment.iter().enumerate() {
            if markers.is_empty() {
                continue;
            }
            let mut cols: Vec<usize> = Vec::new();
            let mut steps = Vec::new();
            for c in &model.plan.cols_q[s] {
                let local = match cols.iter().position(|&x| x == c.col) {
                    Some(l) => l,
                    None => {
                        cols.push(c.col);
                        cols.len() - 1
                    }
                };
                steps.push((local, c.step, c.scale, c.rotation));
            }
            widest = widest.max(cols.len());
            segments.push(SegmentTerms {
                markers: markers.clone(),
                cols,
                steps,
            });
        }
        let plan: Vec<SegmentPlan> = segments
            .iter()
            .map(|seg| {
                let steps = seg
                    .steps
                    .iter()
                    .map(|&(local, step, scale, rot)| (seg.cols[local], step, scale, rot))
                    .collect();
                (seg.markers.clone(), steps)
            })
            .collect();
        Moments {
            segments,
            active_index: vec![usize::MAX; model.coordinates().len()],
            twists: vec![(Vector3::zeros(), Vector3::zeros()); widest],
            composite: Composite::new(model.coordinates().len(), &plan),
        }
    }

    /// Whether the composite form is in use.
    #[cfg(test)]
    pub(super) fn is_composite(&self) -> bool {
        self.composite.is_some()
    }

    /// Falls back to the per-segment form (for tests of both).
    #[cfg(test)]
    pub(super) fn per_segment(mut self) -> Self {
        self.composite = None;
        self
    }

    pub(super) fn set_active(&mut self, active: &[usize]) {
        self.active_index.fill(usize::MAX);
        for (i, &c) in active.iter().enumerate() {
            self.active_index[c] = i;
        }
        if let Some(composite) = &mut self.composite {
            composite.set_active(&self.active_index, active.len());
        }
    }

    /// Writes `JᵀWJ` (n × n, column-major, n = active count) into `a` and `JᵀW r` into `g`.
    pub(super) fn normal_equations(
        &mut self,
        kin: &KinData,
        targets: &[Vector3<f64>],
        weights: &[f64],
        n: usize,
        a: &mut [f64],
        g: &mut [f64],
    ) {
        if let Some(composite) = &mut self.composite {
            composite.normal_equations(kin, targets, weights, &self.active_index, n, a, g);
            return;
        }
        a[..n * n].fill(0.0);
        g[..n].fill(0.0);
        for seg in &self.segments {
            let mut mass = 0.0;
            let mut centroid = Vector3::zeros();
            for &j in &seg.markers {
                let w = weights[j];
                if w > 0.0 {
                    mass += w;
                    centroid += w * kin.markers[j];
                }
            }
            if mass == 0.0 {
                continue;
            }
            centroid /= mass;
            let mut theta = Matrix3::zeros();
            let mut r0 = Vector3::zeros();
            let mut r1 = Vector3::zeros();
            for &j in &seg.markers {
                let w = weights[j];
                if w > 0.0 {
                    let d = kin.markers[j] - centroid;
                    let r = targets[j] - kin.markers[j];
                    theta +=
                        w * (Matrix3::from_diagonal_element(d.norm_squared()) - d * d.transpose());
                    r0 += w * r;
                    r1 += w * d.cross(&r);
                }
            }
            let twists = &mut self.twists[..seg.cols.len()];
            twists.fill((Vector3::zeros(), Vector3::zeros()));
            for &(local, step, scale, rotation) in &seg.steps {
                let (axis, origin) = kin.step_frame(step);
                let t = &mut twists[local];
                if rotation {
                    t.0 += scale * axis;
                    t.1 += scale * axis.cross(&(centroid - origin));
                } else {
                    t.1 += scale * axis;
                }
            }
            for (la, &ca) in seg.cols.iter().enumerate() {
                let ai = self.active_index[ca];
                if ai == usize::MAX {
                    continue;
                }
                let (wa, va) = twists[la];
                g[ai] += wa.dot(&r1) + va.dot(&r0);
                let theta_wa = theta * wa;
                for (lb, &cb) in seg.cols.iter().enumerate().take(la + 1) {
                    let bi = self.active_index[cb];
                    if bi == usize::MAX {
                        continue;
                    }
                    let (wb, vb) = twists[lb];
                    let value = theta_wa.dot(&wb) + mass * va.dot(&vb);
                    // Lower triangle (row ≥ column); mirrored below.
                    let (row, col) = if ai >= bi { (ai, bi) } else { (bi, ai) };
                    a[col * n + row] += value;
                }
            }
        }
        for col in 0..n {
            for row in col + 1..n {
                a[row * n + col] = a[col * n + row];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{forward_kinematics, Want};
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::model::Model;

    /// The moment form of the normal equations against `JᵀWJ`, `JᵀW r` built from the
    /// explicit Jacobian (itself proven against finite differences), with missing markers,
    /// unequal weights and a subset of active coordinates.
    #[test]
    fn moments_match_explicit_jacobian() {
        let mut spec = lower_limb(Side::Left);
        for (k, m) in spec.markers.iter_mut().enumerate() {
            m.weight = 0.5 + (k % 3) as f64;
        }
        let model = Model::compile(&spec).unwrap();
        let p = model.nominal_params();
        let mut kin = KinData::new(&model);
        for case in 0..6 {
            let q: Vec<f64> = (0..model.coordinates().len())
                .map(|i| 0.4 * ((i * 7 + case * 3) as f64).sin())
                .collect();
            forward_kinematics(&model, &p, &q, Want::Dq, &mut kin);
            let targets: Vec<Vector3<f64>> = kin
                .markers
                .iter()
                .enumerate()
                .map(|(j, x)| x + 0.01 * Vector3::new((j as f64).sin(), 0.3, (case as f64).cos()))
                .collect();
            let weights: Vec<f64> = model
                .markers()
                .iter()
                .enumerate()
                .map(|(j, m)| if (j + case) % 5 == 0 { 0.0 } else { m.weight })
                .collect();
            let active: Vec<usize> = (0..model.coordinates().len())
                .filter(|c| case % 2 == 0 || c % 3 != 1)
                .collect();
            let n = active.len();
            for composite in [true, false] {
                let mut moments = Moments::new(&model);
                assert!(moments.is_composite(), "the leg allows the composite form");
                if !composite {
                    moments = moments.per_segment();
                }
                moments.set_active(&active);
                let (mut a, mut g) = (vec![0.0; n * n], vec![0.0; n]);
                moments.normal_equations(&kin, &targets, &weights, n, &mut a, &mut g);
                let jq = &kin.jq;
                let scale = jq.norm_squared();
                for (ai, &ca) in active.iter().enumerate() {
                    let mut g_ref = 0.0;
                    for (j, &w) in weights.iter().enumerate() {
                        let r = targets[j] - kin.markers[j];
                        for k in 0..3 {
                            g_ref += w * jq[(3 * j + k, ca)] * r[k];
                        }
                    }
                    assert!(
                        (g[ai] - g_ref).abs() <= 1e-12 * scale,
                        "g[{ai}] case {case}"
                    );
                    for (bi, &cb) in active.iter().enumerate() {
                        let mut a_ref = 0.0;
                        for (j, &w) in weights.iter().enumerate() {
                            for k in 0..3 {
                                a_ref += w * jq[(3 * j + k, ca)] * jq[(3 * j + k, cb)];
                            }
                        }
                        let got = a[bi * n + ai];
                        assert!(
                            (got - a_ref).abs() <= 1e-12 * scale,
                            "A[{ai},{bi}] case {case} composite {composite}: {got} vs {a_ref}"
                        );
                    }
                }
            }
        }
    }
}
