//! How much each marker counts, and where the markers end up.
//!
//! **Static weights.** A marker's data rows in the static frame (`f = 0`) are weighted by the
//! weight `W_j` a setup's marker placer gives it (an `IKMarkerTask`; 1 unless given, 0
//! leaves its static data out), divided by the mean over the static markers that make data
//! rows: `w_0j = W_j / mean(W)`. OpenSim's marker placer uses these weights for one static
//! pose, where only their ratios matter; the mean makes the static frame weigh as one frame
//! whatever the setup's scale (10–100 in one lab's setup, 1–1000 in another's), so that a
//! weight of 1000 neither counts the static pose as hundreds of frames nor makes the offset
//! priors hundreds of times weaker. Motion frames weigh every marker 1: a setup's weights
//! describe the static pose, and the clusters it leaves out of that pose are what shows the
//! segments' poses best in motion.
//!
//! **Offset priors widened for tracking markers.** Every marker's offset prior starts at
//! `σ_j = σ_m`. After a solve, a marker whose offset `|δ_j|` exceeds `2σ_j` (with a 5 %
//! margin) is taken for a tracking marker placed anywhere on its segment, not a landmark:
//! its `σ_j` becomes `|δ_j|/2` and the fit resumes from where it stopped, for at most four
//! rounds (a Huber-like reweighting that keeps landmarks tight and lets clusters go where the
//! data put them).
//!
//! **Registration.** Once the fit is done, a free marker the static frame holds and no motion
//! frame does is moved onto its measured place at the fitted static pose: its offset grows by
//! `R_bᵀ (m_0j − x_j)`, `R_b` its body's rotation at that pose, as OpenSim's marker placer
//! moves every non-fixed marker of the static trial onto the data after solving the pose
//! (`MarkerPlacer::moveModelMarkersToPose`, opensim-core `OpenSim/Tools/MarkerPlacer.cpp`).
//! Its weighted static data shaped the pose and the factors; the subject's model carries it
//! where it was measured.

use nalgebra::Vector3;

use super::options::{ScaleError, ScaleOptions};
use super::problem::Problem;
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::spec::ModelSpec;

/// Prior SDs beyond which a marker's offset marks it as a tracking marker (module docs).
const ROBUST_IN_SD: f64 = 2.0;
/// Rounds of widening.
pub(super) const ROBUST_ROUNDS: usize = 4;

/// Per model marker: its weight in the static frame, divided by the mean weight of the
/// static markers that make data rows (module docs).
pub(super) fn static_weights(
    spec: &ModelSpec,
    targets: &[Vec<Vector3<f64>>],
    opts: &ScaleOptions,
) -> Vec<f64> {
    let given: Vec<f64> = spec
        .markers
        .iter()
        .map(|m| {
            opts.marker_weights
                .iter()
                .find(|(n, _)| *n == m.name)
                .map_or(1.0, |(_, w)| *w)
        })
        .collect();
    let Some(stat) = targets.first() else {
        return given;
    };
    let used: Vec<f64> = given
        .iter()
        .zip(stat)
        .filter(|(w, m)| **w > 0.0 && m.x.is_finite())
        .map(|(w, _)| *w)
        .collect();
    let mean = used.iter().sum::<f64>() / used.len().max(1) as f64;
    if mean > 0.0 {
        given.iter().map(|w| w / mean).collect()
    } else {
        given
    }
}

impl Problem<'_> {
    /// The weight of marker `mi`'s data rows in frame `f` (module docs).
    pub(super) fn weight(&self, f: usize, mi: usize) -> f64 {
        if f == 0 {
            self.weight[mi]
        } else {
            1.0
        }
    }

    /// Whether marker `mi`'s sample `m` in frame `f` makes data rows (present, weight above 0).
    pub(super) fn used(&self, f: usize, mi: usize, m: &Vector3<f64>) -> bool {
        m.x.is_finite() && self.weight(f, mi) > 0.0
    }
}

/// Widens the offset prior of every marker whose offset at `th` is beyond `ROBUST_IN_SD`
/// prior SDs (module docs; only with `ScaleOptions::robust`); whether any was widened.
pub(super) fn widen_offset_priors(pb: &mut Problem, th: &[f64]) -> bool {
    let mut widened = false;
    for (mi, at) in pb.lay.delta.iter().enumerate() {
        let Some(at) = at else {
            continue;
        };
        let d = (th[*at].powi(2) + th[at + 1].powi(2) + th[at + 2].powi(2)).sqrt();
        if pb.opts.robust && d > ROBUST_IN_SD * pb.msd[mi] * 1.05 {
            pb.msd[mi] = d / ROBUST_IN_SD;
            widened = true;
        }
    }
    widened
}

/// Moves the markers the static frame holds and no motion frame does onto their measured
/// place at the fitted static pose (module docs).
pub(super) fn register_static_only(pb: &Problem, th: &mut [f64]) -> Result<(), ScaleError> {
    let Some(stat) = pb.targets.first() else {
        return Ok(());
    };
    let model = pb.model(th)?;
    let mut data = KinData::new(&model);
    forward_kinematics(
        &model,
        &model.nominal_params(),
        pb.coords(th, 0),
        Want::Positions,
        &mut data,
    );
    let mut moves = Vec::new();
    for (j, (d, m)) in pb.lay.delta.iter().zip(stat).enumerate() {
        let in_motion = pb.targets[1..].iter().any(|t| t[j].x.is_finite());
        if let (Some(at), true, false) = (d, m.x.is_finite(), in_motion) {
            let rot = data.segment_poses[model.markers()[j].segment.0].rot;
            moves.push((*at, rot.transpose() * (m - data.markers[j])));
        }
    }
    for (at, step) in moves {
        for k in 0..3 {
            th[at + k] += step[k];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::test_leg::{factor_error, scaled_leg};
    use super::super::{fit_scale, GroupFit, ScaleOptions};
    use nalgebra::Vector3;

    /// The static weights shift trust between markers only: the same weights times 50 give the
    /// same fit, and unequal weights give another one than none.
    #[test]
    fn static_marker_weights_are_relative() {
        let (spec, groups, mut markers) = scaled_leg();
        markers[0] += Vector3::new(0.01, -0.02, 0.0);
        let opts = |scale: f64| {
            let mut o = ScaleOptions::new(groups.clone());
            o.marker_weights = spec
                .markers
                .iter()
                .enumerate()
                .map(|(j, m)| (m.name.clone(), scale * (1.0 + (j % 3) as f64)))
                .collect();
            o
        };
        let a = fit_scale(&spec, std::slice::from_ref(&markers), &opts(1.0)).unwrap();
        let b = fit_scale(&spec, std::slice::from_ref(&markers), &opts(50.0)).unwrap();
        for (ga, gb) in a.groups.iter().zip(&b.groups) {
            for k in 0..3 {
                assert!(
                    (ga.factors[k] - gb.factors[k]).abs() < 1e-9,
                    "{ga:?} {gb:?}"
                );
            }
        }
        let plain = ScaleOptions::new(groups.clone());
        let unweighted = fit_scale(&spec, &[markers], &plain).unwrap();
        let differ = |u: &GroupFit, w: &GroupFit| (u.factors[0] - w.factors[0]).abs() > 1e-6;
        assert!(unweighted
            .groups
            .iter()
            .zip(&a.groups)
            .any(|(u, w)| differ(u, w)));
    }

    /// A marker displaced by 4 cm biases the factors; with weight 0 its data are left out
    /// and the factors are the true ones again.
    #[test]
    fn a_marker_of_weight_zero_does_not_pull_the_factors() {
        let (spec, groups, mut markers) = scaled_leg();
        let bad = spec
            .markers
            .iter()
            .position(|m| m.segment == spec.segments[2].name)
            .unwrap();
        markers[bad] += Vector3::new(0.0, 0.04, 0.0);
        let mut opts = ScaleOptions::new(groups);
        opts.prior = None;
        opts.robust = false;
        let biased = fit_scale(&spec, std::slice::from_ref(&markers), &opts).unwrap();
        assert!(factor_error(&biased) > 1e-3, "{:?}", biased.groups);
        opts.marker_weights = vec![(spec.markers[bad].name.clone(), 0.0)];
        let fit = fit_scale(&spec, std::slice::from_ref(&markers), &opts).unwrap();
        assert!(factor_error(&fit) < 1e-6, "{:?}", fit.groups);
        // Registered where it was measured, as the marker placer moves every static marker.
        let m = &fit.markers[bad];
        let moved = Vector3::from(m.moved).norm();
        assert!((moved - 0.04).abs() < 1e-6, "{m:?}");
        // its misfit is the fit's, before registration
        assert!((m.rms - 0.04).abs() < 1e-6, "{m:?}");
        // In a motion frame the marker counts (weight 1): its data pull the factors again.
        let with_motion = fit_scale(&spec, &[markers.clone(), markers], &opts).unwrap();
        assert!(
            factor_error(&with_motion) > 1e-3,
            "{:?}",
            with_motion.groups
        );
    }
}
