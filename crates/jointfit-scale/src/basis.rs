//! Marker positions of the scaled model as an exact linear function of the scale factors.
//!
//! At a fixed pose `q`, OpenSim's scaling changes only translations: a joint's parent offset
//! (`t ⊙ s_parent`), its child offset (`t ⊙ s_child`), a custom joint's translation functions
//! (`|a|·s_parent · f(q)`), a translational coupler's dependent value (`sx · f`) and a
//! marker's place in its body (`s_b ⊙ c`). Rotations never depend on the factors. A point's
//! world position is the sum along its chain of each translation turned into the world by the
//! rotation of the frame it is expressed in, `x = Σ_i R_i(q) τ_i`, and every `τ_i` is linear
//! in one factor of one body, so
//!
//! `x(q; g) = x(q; 1) + Σ_k (g_k − 1) (x(q; 1 + e_k) − x(q; 1))`
//!
//! holds exactly for every pose, where `g` are the fitted factors (one per group, or three),
//! `1` all of them at one (bodies held at given factors keep those), and `1 + e_k` factor `k`
//! at two. The same holds for `∂x/∂q`, the derivative of an identity in `q`. So `∂x/∂g_k` is
//! the difference of two fixed models' marker positions, and the model at any factors is a
//! combination of `K + 1` models compiled once (`K` fitted factors), not recompiled per step.
//!
//! A marker's offset `δ` from its scaled generic place enters the same way: the position is
//! affine in the marker's place `p` in its body (`x = R_b p + o_b`), so three more models
//! with every marker moved by one metre along `x`, `y`, `z` of its body give
//! `x(q; p + δ) = x(q; p) + Σ_a δ_a (x(q; p + e_a) − x(q; p))` and its `∂/∂q`, and
//! `∂x/∂δ = R_b` (the differences themselves).

use nalgebra::{DMatrix, Matrix3, Vector3};

use crate::fit::ScaleGroup;
use crate::geometry::{scaled_spec, ScaleFactors};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::spec::ModelSpec;
use jointfit::model::{Model, ModelError};

/// Every body's factors: `fixed`, then each group's bodies at its fitted factors `g` (one
/// per group, or three with `per_axis`, in the groups' order).
pub(crate) fn factors_of(groups: &[ScaleGroup], g: &[f64], fixed: &ScaleFactors) -> ScaleFactors {
    let mut f = fixed.clone();
    let mut k = 0;
    for grp in groups {
        let s = if grp.per_axis {
            [g[k], g[k + 1], g[k + 2]]
        } else {
            [g[k]; 3]
        };
        k += grp.n_factors();
        for b in &grp.bodies {
            f.insert(b.clone(), s);
        }
    }
    f
}

/// The `K + 1` models of the module docs.
pub(crate) struct FactorBasis {
    /// Every fitted factor at one: `x(q; 1)`.
    base: Model,
    /// Per fitted factor `k`: the model with that factor at two.
    unit: Vec<Model>,
    /// The base model with every marker moved by one metre along x, y, z of its body.
    moved: Vec<Model>,
}

/// The markers of one frame at given factors and offsets: positions and, when asked,
/// `∂x/∂q` and `∂x/∂g_k` (rows `3j..3j+3` for marker `j`) and `∂x_j/∂δ_j`.
pub(crate) struct FramePoints {
    pub(crate) markers: Vec<Vector3<f64>>,
    pub(crate) jq: DMatrix<f64>,
    pub(crate) jg: DMatrix<f64>,
    pub(crate) jd: Vec<Matrix3<f64>>,
}

/// Workspaces for evaluating the basis models.
pub(crate) struct BasisData {
    data: Vec<KinData>,
    params: Vec<Vec<f64>>,
}

impl FactorBasis {
    /// Compiles the base model and one model per fitted factor (`groups` in order, three per
    /// group with `per_axis`), with `fixed` applied to every one of them.
    pub(crate) fn new(
        spec: &ModelSpec,
        groups: &[ScaleGroup],
        fixed: &ScaleFactors,
    ) -> Result<Self, ModelError> {
        let ones = vec![1.0; groups.iter().map(ScaleGroup::n_factors).sum()];
        let at_base = scaled_spec(spec, &factors_of(groups, &ones, fixed));
        let base = Model::compile(&at_base)?;
        let mut unit = Vec::new();
        for k in 0..ones.len() {
            let mut g = ones.clone();
            g[k] = 2.0;
            unit.push(Model::compile(&scaled_spec(
                spec,
                &factors_of(groups, &g, fixed),
            ))?);
        }
        let mut moved = Vec::new();
        for a in 0..3 {
            let mut sp = at_base.clone();
            for m in sp.markers.iter_mut() {
                m.position[a] += 1.0;
            }
            moved.push(Model::compile(&sp)?);
        }
        Ok(FactorBasis { base, unit, moved })
    }

    /// The model with every fitted factor at one (its rotations are every model's).
    pub(crate) fn base(&self) -> &Model {
        &self.base
    }

    pub(crate) fn workspace(&self) -> BasisData {
        let models = self.models();
        BasisData {
            data: models.clone().map(KinData::new).collect(),
            params: models.map(Model::nominal_params).collect(),
        }
    }

    fn models(&self) -> impl Iterator<Item = &Model> + Clone {
        std::iter::once(&self.base)
            .chain(&self.unit)
            .chain(&self.moved)
    }

    /// The markers of pose `q` at factors `g` and offsets `delta` (per model marker, in its
    /// body; module docs), with the Jacobians when `jac`.
    pub(crate) fn points(
        &self,
        g: &[f64],
        delta: &[Vector3<f64>],
        q: &[f64],
        jac: bool,
        ws: &mut BasisData,
    ) -> FramePoints {
        let want = if jac { Want::Dq } else { Want::Positions };
        for ((m, d), p) in self.models().zip(&mut ws.data).zip(&ws.params) {
            forward_kinematics(m, p, q, want, d);
        }
        let (d0, rest) = ws.data.split_first().expect("the base model");
        let (units, moved) = rest.split_at(self.unit.len());
        let nm = d0.markers.len();
        let mut out = FramePoints {
            markers: d0.markers.clone(),
            jq: if jac {
                d0.jq.clone()
            } else {
                DMatrix::zeros(0, 0)
            },
            jg: DMatrix::zeros(if jac { 3 * nm } else { 0 }, g.len()),
            jd: vec![Matrix3::zeros(); nm],
        };
        // Each model's weight, per marker: the factors' `g_k − 1`, the offsets' `δ_a`, and
        // the base's one minus their sum.
        let mut own = vec![1.0; nm];
        for (k, (dk, gk)) in units.iter().zip(g).enumerate() {
            for (j, w) in own.iter_mut().enumerate() {
                let diff = dk.markers[j] - d0.markers[j];
                out.markers[j] += (gk - 1.0) * diff;
                *w -= gk - 1.0;
                if jac {
                    out.jg.view_mut((3 * j, k), (3, 1)).copy_from(&diff);
                }
            }
        }
        for (a, dk) in moved.iter().enumerate() {
            for (j, d) in delta.iter().enumerate() {
                out.markers[j] += d[a] * (dk.markers[j] - d0.markers[j]);
                own[j] -= d[a];
            }
        }
        if jac {
            let rows = 3 * nm;
            let o = out.jq.as_mut_slice();
            o.fill(0.0);
            combine(o, d0.jq.as_slice(), rows, |j| own[j]);
            for (dk, gk) in units.iter().zip(g) {
                combine(o, dk.jq.as_slice(), rows, |_| gk - 1.0);
            }
            for (a, dk) in moved.iter().enumerate() {
                combine(o, dk.jq.as_slice(), rows, |j| delta[j][a]);
            }
        }
        for (a, dk) in moved.iter().enumerate() {
            for j in 0..nm {
                out.jd[j].set_column(a, &(dk.markers[j] - d0.markers[j]));
            }
        }
        out
    }
}

/// `out += w(j) · jm` over column-major matrices of `rows` rows, `j` the marker of a row.
fn combine(out: &mut [f64], jm: &[f64], rows: usize, w: impl Fn(usize) -> f64) {
    for (oc, jc) in out.chunks_exact_mut(rows).zip(jm.chunks_exact(rows)) {
        for (r, (o, v)) in oc.iter_mut().zip(jc).enumerate() {
            *o += w(r / 3) * v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::groups::default_groups;
    use jointfit::model::functions::FunctionSpec;
    use jointfit::model::lower_limb::{lower_limb, Side};
    use jointfit::model::spec::{AxisMotion, AxisSpec, JointKindSpec, TransformAxisSpec};

    /// Marker positions and `∂x/∂q` of the model compiled at the factors, each marker moved
    /// by its offset.
    fn compiled_at(
        spec: &ModelSpec,
        f: &ScaleFactors,
        delta: &[Vector3<f64>],
        q: &[f64],
    ) -> (Vec<Vector3<f64>>, DMatrix<f64>) {
        let mut sp = scaled_spec(spec, f);
        for (m, d) in sp.markers.iter_mut().zip(delta) {
            for a in 0..3 {
                m.position[a] += d[a];
            }
        }
        let m = Model::compile(&sp).unwrap();
        let mut d = KinData::new(&m);
        forward_kinematics(&m, &m.nominal_params(), q, Want::Dq, &mut d);
        (d.markers.clone(), d.jq.clone())
    }

    /// The basis reproduces the recompiled model's markers and `∂x/∂q` at factors far from
    /// one and markers moved, and `∂x/∂g`, `∂x/∂δ` equal central differences over
    /// recompiled models.
    #[test]
    fn factor_derivatives_match_finite_differences_of_recompiled_models() {
        let mut spec = lower_limb(Side::Right);
        // The knee as a custom joint whose translation follows its angle (scaled by the
        // thigh's factors, as OpenSim scales a knee's translation functions).
        let knee = spec
            .joints
            .iter_mut()
            .find(|j| j.coordinates.iter().any(|c| c.name().contains("knee")))
            .expect("a knee");
        let coord = knee.coordinates[0].name().to_string();
        let JointKindSpec::Pin { axis } = knee.kind.clone() else {
            panic!("the knee is a pin joint");
        };
        let translation = |axis: &str, slope: f64| TransformAxisSpec {
            motion: AxisMotion::Translation,
            axis: AxisSpec::Named(axis.to_string()),
            coordinate: Some(coord.clone()),
            function: FunctionSpec::Linear {
                slope,
                intercept: 0.004,
            },
        };
        knee.kind = JointKindSpec::Custom {
            axes: vec![
                TransformAxisSpec {
                    motion: AxisMotion::Rotation,
                    axis,
                    coordinate: Some(coord.clone()),
                    function: FunctionSpec::identity(),
                },
                translation("x", 0.02),
                translation("y", -0.01),
            ],
        };
        let mut groups = default_groups(&spec, false, false);
        groups[1].per_axis = true;
        let held = groups.pop().unwrap();
        let mut fixed = ScaleFactors::new();
        for b in &held.bodies {
            fixed.insert(b.clone(), [0.93, 1.04, 1.11]);
        }
        let basis = FactorBasis::new(&spec, &groups, &fixed).unwrap();
        let n: usize = groups.iter().map(ScaleGroup::n_factors).sum();
        let g: Vec<f64> = (0..n).map(|k| 0.8 + 0.07 * k as f64).collect();
        let mut q = basis.base().default_coords();
        for (k, v) in q.iter_mut().enumerate() {
            *v += 0.3 * ((k as f64) * 2.3).sin();
        }
        let delta: Vec<Vector3<f64>> = (0..spec.markers.len())
            .map(|j| 0.02 * Vector3::new((j as f64).sin(), (2.0 * j as f64).cos(), 0.5))
            .collect();
        let mut ws = basis.workspace();
        let pts = basis.points(&g, &delta, &q, true, &mut ws);
        let at = |g: &[f64], delta: &[Vector3<f64>]| {
            compiled_at(&spec, &factors_of(&groups, g, &fixed), delta, &q)
        };
        let (x, jq) = at(&g, &delta);
        for (a, b) in pts.markers.iter().zip(&x) {
            assert!((a - b).norm() < 1e-13, "{a} vs {b}");
        }
        assert!((&pts.jq - &jq).amax() < 1e-12);
        let h = 1e-4;
        for k in 0..n {
            let (mut up, mut down) = (g.clone(), g.clone());
            up[k] += h;
            down[k] -= h;
            let (xu, _) = at(&up, &delta);
            let (xd, _) = at(&down, &delta);
            for j in 0..x.len() {
                let fd = (xu[j] - xd[j]) / (2.0 * h);
                for a in 0..3 {
                    let exact = pts.jg[(3 * j + a, k)];
                    assert!(
                        (exact - fd[a]).abs() < 1e-9,
                        "factor {k} marker {j}: {exact} vs {}",
                        fd[a]
                    );
                }
            }
        }
        for j in 0..x.len() {
            for a in 0..3 {
                let (mut up, mut down) = (delta.clone(), delta.clone());
                up[j][a] += h;
                down[j][a] -= h;
                let fd = (at(&g, &up).0[j] - at(&g, &down).0[j]) / (2.0 * h);
                let exact = pts.jd[j].column(a);
                assert!((exact - fd).amax() < 1e-9, "marker {j} axis {a}");
            }
        }
        assert!(pts.jg.amax() > 0.01, "the factors move the markers");
    }
}
