//! The joint (Schur) calibration keeps OpenSim's `clamped` coordinates inside their ranges in
//! every frame, as the inverse kinematics does ([`crate::ik::IkOptions::clamp`]). Oracle: the
//! two-level solver, whose inner level is that bounded IK, must reach the same optimum; and
//! the bounds must matter (the unbounded fit leaves the range). The uncertainty analysis'
//! reduced system holds the same coordinates (dense finite-difference oracle).

use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::{params_for_groups, Fit, Problem};
use crate::kinematics::fd::{jacobian_p, jacobian_q};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::Model;
use nalgebra::DMatrix;

use super::solvers_tests::{joint_and_varpro, perturbed, synthetic};
use crate::ik::clamped_tests::clamped_leg;

/// Frames whose `c`-th coordinate lies outside `[lo, hi]` (1e-12 rad slack), and the
/// largest excursion.
fn outside(fit: &Fit, c: usize, lo: f64, hi: f64) -> (usize, f64) {
    fit.coords.iter().fold((0, 0.0f64), |(n, worst), q| {
        let d = (lo - q[c]).max(q[c] - hi).max(0.0);
        (n + usize::from(d > 1e-12), worst.max(d))
    })
}

/// The knee clamped to [−5°, 68.8°] while the rich motion flexes it 0.1–1.5 rad, the knee
/// parameters fitted from nominal: `(model, trial, free parameters' start, knee index, range)`.
fn knee_beyond_its_range() -> (Model, crate::trial::Trial, Vec<f64>, usize, f64, f64) {
    let (lo, hi) = (-5.0, 68.8);
    let model = clamped_leg([lo, hi], [-60.0, 60.0]);
    let knee = model.coord_id("knee_flexion").unwrap();
    let p_true = perturbed(&model, 5);
    let trial = synthetic(&model, &p_true, 60, 0.004, 9);
    let mut base = p_true.clone();
    for id in &params_for_groups(&model, &["knee"]).unwrap() {
        base[id.0] = model.parameters()[id.0].nominal;
    }
    (model, trial, base, knee, lo.to_radians(), hi.to_radians())
}

#[test]
fn joint_calibration_keeps_clamped_coordinates_in_range() {
    let (model, trial, base, knee, lo, hi) = knee_beyond_its_range();
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&base);
    let (joint, varpro) = joint_and_varpro(&prob, &s0, prob.initial_coords(&base));
    let (n, worst) = outside(&joint, knee, lo, hi);
    assert_eq!(n, 0, "joint fit: {n} frames outside, up to {worst:e} rad");
    let at_bound = joint
        .coords
        .iter()
        .filter(|q| (q[knee] - hi).abs() < 1e-12)
        .count();
    assert!(at_bound >= 5, "only {at_bound} frames at the knee's bound");
    let ds = joint
        .s
        .iter()
        .zip(&varpro.s)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let dc = (joint.cost - varpro.cost).abs() / varpro.cost;
    assert!(ds <= 1e-5, "scaled parameters differ by {ds:e}");
    assert!(dc <= 1e-8, "costs differ by {dc:e} relative");

    // Without the bound the same fit leaves the range: the bound is active, not decorative.
    let free_model = clamped_leg([-180.0, 180.0], [-60.0, 60.0]);
    let prob = Problem::new(&free_model, base.clone(), &free, &[&trial]).unwrap();
    let (unbounded, _) = joint_and_varpro(&prob, &s0, prob.initial_coords(&base));
    let (n, worst) = outside(&unbounded, knee, lo, hi);
    assert!(n >= 5 && worst > 0.05, "{n} frames, {worst} rad outside");
    assert!(unbounded.cost < joint.cost);
}

#[test]
fn unclamped_models_calibrate_as_before() {
    // A model with no clamped coordinate: the bounded and the plain solver are the same code
    // path; a range that is not clamped is informative only and does not bound the fit.
    let mut spec = crate::model::lower_limb::lower_limb(crate::model::lower_limb::Side::Right);
    for j in &mut spec.joints {
        for c in &mut j.coordinates {
            if let crate::model::spec::CoordinateSpec::Full { name, range, .. } = c {
                if name == "knee_flexion" {
                    *range = Some([0.0, 1.2]);
                }
            }
        }
    }
    let ranged = Model::compile(&spec).unwrap();
    let p_true = perturbed(&ranged, 5);
    let trial = synthetic(&ranged, &p_true, 60, 0.004, 9);
    let free = params_for_groups(&ranged, &["knee"]).unwrap();
    let knee = ranged.coord_id("knee_flexion").unwrap();
    let prob = Problem::new(&ranged, p_true.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&p_true);
    let (fit, _) = joint_and_varpro(&prob, &s0, prob.initial_coords(&p_true));
    let (n, _) = outside(&fit, knee, 0.0, 1.2);
    assert!(
        n >= 5,
        "the unclamped knee stays in its informative range ({n} frames out)"
    );
}

#[test]
fn reduced_system_holds_coordinates_at_their_bounds() {
    // Oracle: the stacked residual Jacobian over (q_1 … q_N, s) by central differences of
    // forward kinematics, with the columns of the coordinates held at a bound removed (at the
    // bound, descent J_qᵀr pointing out of the range), and the dense Schur complement onto s.
    let (model, trial, base, knee, _, hi) = knee_beyond_its_range();
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let prob = Problem::new(&model, base.clone(), &free, &[&trial]).unwrap();
    let s0 = prob.to_scaled(&base);
    let (fit, _) = joint_and_varpro(&prob, &s0, prob.initial_coords(&base));
    let red = reduced_system(&prob, &fit.p, &fit.coords);
    let (nq, nf, n) = (model.coordinates().len(), prob.n_free(), prob.frames.len());
    let rows = 3 * model.markers().len();
    let mut kin = KinData::new(&model);
    let (mut held, mut full, mut kept) = (0, DMatrix::zeros(nf, nf), DMatrix::zeros(nf, nf));
    for f in 0..n {
        let (p, q) = (&fit.p, &fit.coords[f]);
        let jq = jacobian_q(&model, p, q, 1e-6);
        let jp = jacobian_p(&model, p, q, 1e-6);
        forward_kinematics(&model, p, q, Want::Positions, &mut kin);
        let r = nalgebra::DVector::from_fn(rows, |a, _| {
            prob.frames.get(f)[a / 3][a % 3] - kin.markers[a / 3][a % 3]
        });
        let js = DMatrix::from_fn(rows, nf, |a, k| jp[(a, prob.free[k])] * prob.half_range(k));
        let outward = (jq.column(knee).transpose() * &r)[0] > 0.0;
        let hold = (q[knee] - hi).abs() < 1e-12 && outward;
        held += usize::from(hold);
        let cols: Vec<usize> = (0..nq).filter(|&c| !(hold && c == knee)).collect();
        let jk = jq.select_columns(&cols);
        let schur = |j: &DMatrix<f64>| {
            let a = j.transpose() * j;
            let b = j.transpose() * &js;
            js.transpose() * &js - b.transpose() * a.try_inverse().unwrap() * b
        };
        kept += schur(&jk);
        full += schur(&jq);
    }
    assert!(held >= 5, "only {held} frames hold the knee at its bound");
    let scale = kept.diagonal().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = (&kept - &red.data_normal).abs().max();
    assert!(
        diff <= 1e-6 * scale,
        "differs from the oracle by {diff:e} (scale {scale:e})"
    );
    // Treating the held coordinates as free gives a visibly different matrix.
    let free_diff = (&full - &red.data_normal).abs().max();
    assert!(
        free_diff >= 1e-3 * scale,
        "{free_diff:e} vs scale {scale:e}"
    );
}
