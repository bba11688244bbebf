//! What the fit minimizes: the sum of squares `F(θ) = Σ r²` of four kinds of residual rows,
//! each in standard deviations, and with the Jacobian the normal equations `JᵀJ`, `Jᵀr` in
//! the block form of `crate::normal`.
//!
//! The model marker is `x_j(θ) = T_b(q_f; s) (s_b ⊙ c_j + δ_j)` (`c_j` its generic place in
//! body `b`, `s_b` the body's factors, `T_b` its pose in the scaled model), given with its
//! exact derivatives in `q`, `g` and `δ` by `crate::basis`. The rows:
//!
//! * data: `√w_fj (x_j − m_fj)/σ_d` for every present marker of every frame with weight
//!   `w_fj > 0` (the weights: `fit::markers`);
//! * marker placement prior: `δ_j/σ_j` for every free marker (the marker stays near its
//!   scaled generic place; `σ_j` starts at `σ_m` and is widened for tracking markers,
//!   `fit::markers`);
//! * anthropometric prior (optional): `(ln g_k − u)/σ_p` for every factor (the generic
//!   model's segment proportions, spread `σ_p`), and with a stature `H`:
//!   `(u − ln(H/H_generic))/σ_H`;
//! * weak pose rows `(q_fc − q⁰_fc)/1000` holding each coordinate near its start, so that a
//!   coordinate no marker determines (a toe joint without toe markers) leaves the normal
//!   equations regular; far wider than any determined coordinate's spread.
//!
//! For the covariance the data rows' share of the normal equations can be weighted by a
//! factor (`fit::results`); the cost is always the unweighted `F`.

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::problem::Problem;
use crate::basis::BasisData;
use crate::normal::Normal;

/// SD (rad or m) of the weak rows that hold coordinates no marker determines at their
/// starting values (module docs).
const POSE_SD: f64 = 1000.0;

/// One evaluation: `Σ r²`, the data rows' share and count, and with the Jacobian the normal
/// equations (the data rows' share weighted by `data_weight`).
pub(super) struct Eval {
    pub(super) cost: f64,
    pub(super) data_cost: f64,
    pub(super) data_rows: usize,
    pub(super) normal: Option<Normal>,
}

impl Eval {
    /// A residual row on shared unknowns with its nonzero Jacobian entries.
    fn shared_row(&mut self, value: f64, entries: &[(usize, f64)]) {
        self.cost += value * value;
        if let Some(nm) = self.normal.as_mut() {
            for &(i, a) in entries {
                nm.g[i] += a * value;
                for &(j, b) in entries {
                    nm.a[(i, j)] += a * b;
                }
            }
        }
    }
}

/// One marker's three data rows in frame `f`, in SDs: the residual and its Jacobian in the
/// frame's coordinates, in the factors, and in the marker's own offset (first unknown and
/// block, when free).
struct MarkerRows {
    r: Vector3<f64>,
    jq: DMatrix<f64>,
    jg: DMatrix<f64>,
    jd: Option<(usize, Matrix3<f64>)>,
}

impl MarkerRows {
    /// Adds the rows to frame `f`'s blocks and the shared blocks of `nm`, weighted by `w`;
    /// `k` factor unknowns.
    fn add_to(&self, nm: &mut Normal, f: usize, k: usize, w: f64) {
        let (r, jq, jg) = (&self.r, &self.jq, &self.jg);
        let fr = &mut nm.frames[f];
        fr.d += w * jq.transpose() * jq;
        fr.g += w * jq.transpose() * r;
        let mut gg = nm.a.view_mut((0, 0), (k, k));
        gg += w * jg.transpose() * jg;
        let mut gr = nm.g.rows_mut(0, k);
        gr += w * jg.transpose() * r;
        let mut bq = fr.b.rows_mut(0, k);
        bq += w * jg.transpose() * jq;
        if let Some((at, jd)) = &self.jd {
            self.add_offset_to(nm, f, k, w, *at, jd);
        }
    }

    /// The blocks of the marker's offset unknowns at `at` (Jacobian `jd`).
    fn add_offset_to(
        &self,
        nm: &mut Normal,
        f: usize,
        k: usize,
        w: f64,
        at: usize,
        jd: &Matrix3<f64>,
    ) {
        let (r, jq, jg) = (&self.r, &self.jq, &self.jg);
        let mut dd = nm.a.view_mut((at, at), (3, 3));
        dd += w * jd.transpose() * jd;
        let dg = w * jd.transpose() * jg;
        let mut a_dg = nm.a.view_mut((at, 0), (3, k));
        a_dg += &dg;
        let mut a_gd = nm.a.view_mut((0, at), (k, 3));
        a_gd += dg.transpose();
        let mut bd = nm.frames[f].b.rows_mut(at, 3);
        bd += w * jd.transpose() * jq;
        let mut gd = nm.g.rows_mut(at, 3);
        gd += w * jd.transpose() * r;
    }
}

impl Problem<'_> {
    /// Data rows of frame `f`, added to `ev` (their normal equations weighted by `w`).
    fn frame_rows(&self, th: &[f64], f: usize, w: f64, ev: &mut Eval, ws: &mut BasisData) {
        let pts = self.points(th, f, ev.normal.is_some(), ws);
        for (mi, m) in self.targets[f].iter().enumerate() {
            if !self.used(f, mi, m) {
                continue;
            }
            let sc = self.weight(f, mi).sqrt() / self.opts.noise_sd;
            let r = (pts.markers[mi] - m) * sc;
            ev.cost += r.norm_squared();
            ev.data_cost += r.norm_squared();
            ev.data_rows += 3;
            let Some(nm) = ev.normal.as_mut() else {
                continue;
            };
            let rows = MarkerRows {
                r,
                jq: pts.jq.rows(3 * mi, 3) * sc,
                jg: pts.jg.rows(3 * mi, 3) * sc,
                jd: self.lay.delta[mi].map(|at| (at, pts.jd[mi] * sc)),
            };
            rows.add_to(nm, f, self.lay.k, w);
        }
    }

    /// Marker placement rows `δ_j/σ_j`.
    fn placement_rows(&self, th: &[f64], ev: &mut Eval) {
        for (at, sd) in self.lay.delta.iter().zip(&self.msd) {
            let Some(at) = at else {
                continue;
            };
            for k in 0..3 {
                ev.shared_row(th[at + k] / sd, &[(at + k, 1.0 / sd)]);
            }
        }
    }

    /// Anthropometric rows: proportions about the overall size, and the stature.
    fn size_rows(&self, th: &[f64], ev: &mut Eval) {
        let Some(p) = &self.opts.prior else {
            return;
        };
        let u_at = self.lay.size.expect("a size unknown with the prior");
        let sd = p.proportion_sd;
        for k in 0..self.lay.k {
            ev.shared_row(
                (th[k].ln() - th[u_at]) / sd,
                &[(k, 1.0 / (th[k] * sd)), (u_at, -1.0 / sd)],
            );
        }
        if let Some((ratio, s)) = p.stature {
            ev.shared_row((th[u_at] - ratio.ln()) / s, &[(u_at, 1.0 / s)]);
        }
    }

    /// Weak rows holding undetermined coordinates at their starting values.
    fn pose_rows(&self, th: &[f64], ev: &mut Eval) {
        for (f, &at) in self.lay.q.iter().enumerate() {
            for c in 0..self.n_q {
                let r = (th[at + c] - self.start[at + c]) / POSE_SD;
                ev.cost += r * r;
                if let Some(nm) = ev.normal.as_mut() {
                    nm.frames[f].d[(c, c)] += 1.0 / (POSE_SD * POSE_SD);
                    nm.frames[f].g[c] += r / POSE_SD;
                }
            }
        }
    }

    /// Every row (module docs); with `jac` the normal equations, the data rows' share
    /// weighted by `data_weight`.
    pub(super) fn evaluate(
        &self,
        th: &[f64],
        jac: bool,
        data_weight: f64,
        ws: &mut BasisData,
    ) -> Eval {
        let n_s = self.lay.q[0];
        let mut ev = Eval {
            cost: 0.0,
            data_cost: 0.0,
            data_rows: 0,
            normal: jac.then(|| Normal::zeros(n_s, self.n_q, self.lay.q.len())),
        };
        for f in 0..self.targets.len() {
            self.frame_rows(th, f, data_weight, &mut ev, ws);
        }
        self.placement_rows(th, &mut ev);
        self.size_rows(th, &mut ev);
        self.pose_rows(th, &mut ev);
        ev
    }
}
