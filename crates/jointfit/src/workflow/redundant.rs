//! Redundant parameter directions: parameters whose effect on the markers another
//! combination of free parameters and per-frame coordinates reproduces exactly, so no trial
//! can tell them apart and an unregularized fit lets them wander.
//!
//! Typical cases in OpenSim models: the parent and child offset translations of a pin joint
//! along its axis (moving both by `d` along the axis moves no point of the child), a rotation
//! of both offset frames about a pin axis, and every offset orientation of a three-rotation
//! (ball) joint (each frame's three coordinates absorb any constant rotation on either side).
//!
//! Test: the reduced normal matrix `S` of the unregularized problem
//! ([`crate::calibrate::uncertainty::reduced::reduced_system`], the Gauss-Newton information about
//! the free parameters with every frame's coordinates eliminated) at the start, with
//! coordinates from inverse kinematics, is scaled by the parameters' information before any
//! elimination, `D = diag(J_pᵀ W J_p)` summed over the frames: `C = D^{-1/2} S D^{-1/2}`.
//! The free parameters are visited in order; parameter `k` is redundant when its residual
//! information after the coordinates and the kept parameters, `C_kk − C_kK C_KK⁻¹ C_Kk` (the
//! squared sine of the angle between its Jacobian column and the span of the coordinates'
//! and the kept parameters' columns), is below [`REDUNDANT_TOL`]; otherwise it is kept. Exact redundancies give round-off (≈ 1e-14, the
//! coordinate elimination's ridge), weakly determined ones orders of magnitude more, so the
//! test separates them. The visiting order decides which member of a redundant set is held:
//! the later one (for [`crate::workflow`]'s `.osim` personalization, child frames after parent
//! frames). This is the pivoted rank-revealing Cholesky (Golub & Van Loan, Matrix
//! Computations, 4th ed., §4.2.8) with the pivot order fixed instead of greedy.

use nalgebra::DMatrix;
use serde::Serialize;

use super::{Calibration, FitSettings, Observer, WorkflowError};
use crate::calibrate::uncertainty::reduced::reduced_system;
use crate::calibrate::Problem;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::{Model, ParamId};
use crate::trial::Trial;

/// Largest residual information (relative, unit diagonal) of a redundant parameter.
pub(crate) const REDUNDANT_TOL: f64 = 1e-8;

/// A free parameter held at its start because others reproduce its effect.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Redundancy {
    /// The held parameter.
    pub parameter: String,
    /// Kept parameters whose combination (with the coordinates) reproduces it, largest
    /// share first; empty when it moves no marker or the coordinates alone absorb it (e.g.
    /// an offset rotation of a ball joint).
    pub with: Vec<String>,
}

/// Splits `free` into the parameters to fit and the redundant ones (module docs), at
/// parameters `start` on `trials`.
pub(crate) fn redundant_parameters(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
) -> Result<(Vec<ParamId>, Vec<Redundancy>), WorkflowError> {
    if free.is_empty() {
        return Ok((vec![], vec![]));
    }
    let prob = Problem::new(model, start.to_vec(), free, trials)?;
    let qs = prob.initial_coords(start);
    let s = reduced_system(&prob, start, &qs).normal;
    // Information before elimination (scaled units, as `S`).
    let mut d = vec![0.0; free.len()];
    let mut kin = KinData::new(model);
    for (targets, q) in prob.frames.iter().zip(&qs) {
        forward_kinematics(model, start, q, Want::DqDp, &mut kin);
        let jp = &kin.jp;
        for (j, (t, m)) in targets.iter().zip(model.markers()).enumerate() {
            if t.x.is_nan() || m.weight <= 0.0 {
                continue;
            }
            for (k, id) in free.iter().enumerate() {
                let h = prob.half_range(k);
                for a in 0..3 {
                    d[k] += m.weight * (jp[(3 * j + a, id.0)] * h).powi(2);
                }
            }
        }
    }
    Ok(split(&s, &d, free, |id| {
        model.parameters()[id.0].name.clone()
    }))
}

/// The test on a reduced normal matrix `s` of the parameters `free` whose information
/// before elimination is `d` (module docs).
fn split(
    s: &DMatrix<f64>,
    d: &[f64],
    free: &[ParamId],
    name: impl Fn(ParamId) -> String,
) -> (Vec<ParamId>, Vec<Redundancy>) {
    let n = free.len();
    let max_diag = d.iter().fold(0.0f64, |m, &x| m.max(x));
    let scale: Vec<f64> = d
        .iter()
        .map(|&d| {
            if d > 1e-14 * max_diag && d > 0.0 {
                1.0 / d.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let c = DMatrix::from_fn(n, n, |a, b| s[(a, b)] * scale[a] * scale[b]);
    let mut kept: Vec<usize> = Vec::new();
    let mut held = Vec::new();
    for k in 0..n {
        if scale[k] == 0.0 || c[(k, k)] < REDUNDANT_TOL {
            // Moves no marker, or the coordinates alone absorb it.
            held.push(Redundancy {
                parameter: name(free[k]),
                with: vec![],
            });
            continue;
        }
        let ckk = DMatrix::from_fn(kept.len(), kept.len(), |a, b| c[(kept[a], kept[b])]);
        let ck = nalgebra::DVector::from_fn(kept.len(), |a, _| c[(kept[a], k)]);
        let coef = if kept.is_empty() {
            Some(ck.clone())
        } else {
            ckk.cholesky().map(|ch| ch.solve(&ck))
        };
        let Some(coef) = coef else {
            kept.push(k);
            continue;
        };
        let residual = c[(k, k)] - ck.dot(&coef);
        if residual < REDUNDANT_TOL {
            let big = coef.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let mut with: Vec<(f64, String)> = kept
                .iter()
                .zip(coef.iter())
                .filter(|(_, x)| x.abs() > 1e-3 * big && big > 0.0)
                .map(|(&i, x)| (x.abs(), name(free[i])))
                .collect();
            with.sort_by(|a, b| b.0.total_cmp(&a.0));
            held.push(Redundancy {
                parameter: name(free[k]),
                with: with.into_iter().map(|(_, n)| n).collect(),
            });
        } else {
            kept.push(k);
        }
    }
    (kept.into_iter().map(|k| free[k]).collect(), held)
}

/// A calibration with its redundant parameters held ([`redundant_parameters`]).
#[derive(Debug, Clone, Serialize)]
pub struct HeldCalibration {
    #[serde(flatten)]
    pub calibration: Calibration,
    /// Parameters held at their start as redundant, in the order of `free`.
    pub held_redundant: Vec<Redundancy>,
    /// Each joint's (parameter group's) prior–data conflict ([`super::conflict::assess_and_widen`]);
    /// empty without a prior or with `prior_conflict` off.
    pub prior_conflict: Vec<super::conflict::JointConflict>,
    /// Joints the trials barely move, held at their start ([`super::motion_range`]).
    pub held_joints: Vec<super::motion_range::HeldJoint>,
}

/// [`calibrate`](super::calibrate) of the non-redundant parameters of `free`; the redundant
/// ones and those of joints the trials barely move ([`super::motion_range`]) stay at their
/// `start` values and are listed. A maximum a posteriori fit then takes the
/// prior–data conflict step ([`super::conflict::assess_and_widen`]).
pub fn calibrate_holding_redundant(
    model: &Model,
    start: &[f64],
    trials: &[&Trial],
    free: &[ParamId],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<HeldCalibration, WorkflowError> {
    let mismatches = super::verdict::check_inputs(model, trials, settings.refuse_mismatch)?;
    let (free, held_joints, seed) =
        super::motion_range::hold_still_joints(model, start, trials, free, &|_, _| None)?;
    let (kept, held_redundant) = redundant_parameters(model, start, trials, &free)?;
    let super::calibration::Kept {
        mut calibration,
        system,
        problem,
    } = super::calibration::fit_keeping_system(
        model,
        start,
        trials,
        &kept,
        settings,
        seed.as_deref(),
        observer,
    )?;
    let prior_conflict =
        super::conflict::assess_and_widen(&problem, settings, &mut calibration, system, observer)?;
    let evidence = super::verdict::Evidence {
        mismatches: &mismatches,
        conflict: &prior_conflict,
        held: &held_joints,
        ..Default::default()
    };
    calibration.verdict = super::verdict::judge(model, &calibration, &evidence);
    Ok(HeldCalibration {
        calibration,
        held_redundant,
        prior_conflict,
        held_joints,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dependent_columns_are_held_in_order() {
        // Columns of J: a, b, a + 2b (redundant), c ⟂, 0 (moves nothing).
        let j = DMatrix::from_row_slice(
            4,
            5,
            &[
                1.0, 0.0, 1.0, 0.0, 0.0, //
                0.0, 1.0, 2.0, 0.0, 0.0, //
                0.5, 0.0, 0.5, 1.0, 0.0, //
                0.0, 0.3, 0.6, 0.2, 0.0,
            ],
        );
        let s = j.transpose() * &j;
        let d: Vec<f64> = (0..5).map(|k| s[(k, k)]).collect();
        let free: Vec<ParamId> = (0..5).map(ParamId).collect();
        let (kept, held) = split(&s, &d, &free, |id| format!("p{}", id.0));
        assert_eq!(kept, vec![ParamId(0), ParamId(1), ParamId(3)]);
        assert_eq!(held.len(), 2);
        assert_eq!(held[0].parameter, "p2");
        assert_eq!(held[0].with, vec!["p1".to_string(), "p0".to_string()]);
        assert_eq!(held[1].parameter, "p4");
        assert!(held[1].with.is_empty());
        // A nearly (not exactly) dependent column is kept.
        let mut j2 = j.clone();
        j2[(3, 2)] += 1e-3;
        let s2 = j2.transpose() * &j2;
        let d2: Vec<f64> = (0..5).map(|k| s2[(k, k)]).collect();
        let (kept2, held2) = split(&s2, &d2, &free, |id| format!("p{}", id.0));
        // Absorbed by eliminated coordinates: its reduced information is tiny against its
        // information before elimination.
        let mut d3 = d2.clone();
        d3[3] = s2[(3, 3)] * 1e10;
        let (kept3, held3) = split(&s2, &d3, &free, |id| format!("p{}", id.0));
        assert_eq!(kept3.len(), 3);
        assert_eq!(held3[0].parameter, "p3");
        assert!(held3[0].with.is_empty());
        assert_eq!(kept2.len(), 4);
        assert_eq!(held2.len(), 1);
    }
}
