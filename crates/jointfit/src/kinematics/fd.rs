//! Central finite-difference twins of the analytic marker Jacobians (test oracles).
//!
//! `∂m/∂x_i ≈ (m(x + h e_i) − m(x − h e_i)) / 2h`, truncation error O(h²).

use nalgebra::DMatrix;

use super::{forward_kinematics, KinData, Want};
use crate::model::Model;

fn marker_vector(model: &Model, p: &[f64], q: &[f64], data: &mut KinData) -> Vec<f64> {
    forward_kinematics(model, p, q, Want::Positions, data);
    data.markers.iter().flat_map(|m| [m.x, m.y, m.z]).collect()
}

/// `∂(marker coordinates)/∂q` by central differences with step `h`.
pub(crate) fn jacobian_q(model: &Model, p: &[f64], q: &[f64], h: f64) -> DMatrix<f64> {
    let mut data = KinData::new(model);
    let mut out = DMatrix::zeros(3 * model.markers().len(), model.coordinates().len());
    let mut x = q.to_vec();
    for i in 0..q.len() {
        x[i] = q[i] + h;
        let plus = marker_vector(model, p, &x, &mut data);
        x[i] = q[i] - h;
        let minus = marker_vector(model, p, &x, &mut data);
        x[i] = q[i];
        for r in 0..plus.len() {
            out[(r, i)] = (plus[r] - minus[r]) / (2.0 * h);
        }
    }
    out
}

/// `∂(marker coordinates)/∂p` by central differences with step `h`.
pub(crate) fn jacobian_p(model: &Model, p: &[f64], q: &[f64], h: f64) -> DMatrix<f64> {
    let mut data = KinData::new(model);
    let mut out = DMatrix::zeros(3 * model.markers().len(), model.parameters().len());
    let mut x = p.to_vec();
    for i in 0..p.len() {
        x[i] = p[i] + h;
        let plus = marker_vector(model, &x, q, &mut data);
        x[i] = p[i] - h;
        let minus = marker_vector(model, &x, q, &mut data);
        x[i] = p[i];
        for r in 0..plus.len() {
            out[(r, i)] = (plus[r] - minus[r]) / (2.0 * h);
        }
    }
    out
}
