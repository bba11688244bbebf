//! Tracking-marker refinement as ordinary joint parameters.
//!
//! A marker placed a centimetre off its intended spot (or a cluster whose position in its
//! segment the static trial got slightly wrong) leaves a residual that a calibration
//! otherwise explains by moving a joint. Refinement makes each refined marker's position in
//! its segment three more parameters with a prior `N(static position, s²)` (`s` ≈ 1 cm, as
//! in AddBiomechanics, Werling et al. 2023, PLoS ONE 18:e0295152, and in the NMSM
//! Pipeline's joint model personalization), so the fit can put the residual where it
//! belongs.
//!
//! The positions enter forward kinematics linearly in the segment frame,
//! `x_j = world_from_segment(q, p) · (c_j)`, which is exactly what a translation offset of a
//! weld joint does. [`with_marker_parameters`] therefore rewrites the description: marker
//! `M` on segment `S` moves to a new segment `marker frame M`, welded to `S` with the parent
//! offset `(tx, ty, tz) = (marker_M_x, marker_M_y, marker_M_z)`, three parameters of group
//! `markers`. Every solver (joint Schur, variable projection, particle swarm), the exact
//! derivatives ∂x/∂p and the sparse structure (the new parameters are global parameters
//! like any other, with no coordinates) then apply unchanged, and so do the priors
//! ([`crate::calibrate::prior`]) and the identifiability analysis, which names the marker
//! offsets that trade off with joint parameters. The new segments, joints and parameters come
//! after the original ones, so original parameter, coordinate and marker indices are
//! unchanged. [`fold_marker_parameters`] writes the fitted offsets back as marker positions
//! in the original structure.

use nalgebra::Vector3;

use super::spec::{JointKindSpec, MarkerSpec, OffsetSpec, ParameterSpec, ScalarSpec, SegmentSpec};
use super::spec::{JointSpec, ModelSpec, Unit};
use super::{Model, SegmentId};

/// Prefix of the segments that carry one refined marker each.
pub(crate) const MARKER_FRAME_PREFIX: &str = "marker frame ";
/// Parameter group of the marker offsets.
pub(crate) const MARKER_GROUP: &str = "markers";
/// Default prior SD of a refined marker position (m) per axis.
pub(crate) const DEFAULT_MARKER_PRIOR_SD: f64 = 0.010;
/// Search bound around the static position, in prior SDs.
pub(crate) const BOUND_IN_SD: f64 = 5.0;

/// The parameter holding axis `axis` (0, 1, 2: x, y, z of the segment frame) of marker
/// `marker`'s position.
pub(crate) fn marker_param_name(marker: &str, axis: usize) -> String {
    format!("marker_{marker}_{}", ["x", "y", "z"][axis])
}

fn frame_name(marker: &str) -> String {
    format!("{MARKER_FRAME_PREFIX}{marker}")
}

/// The description with the positions of `markers` (names of markers of `spec`; others are
/// ignored) as parameters of group [`MARKER_GROUP`], nominal = the given position, prior SD
/// `prior_sd` (m), bounds ± [`BOUND_IN_SD`]·`prior_sd` (module docs).
pub(crate) fn with_marker_parameters(
    spec: &ModelSpec,
    markers: &[&str],
    prior_sd: f64,
) -> ModelSpec {
    let mut out = spec.clone();
    for m in out.markers.iter_mut() {
        if !markers.contains(&m.name.as_str()) {
            continue;
        }
        let frame = frame_name(&m.name);
        let mut offset = OffsetSpec::default();
        for (axis, slot) in [&mut offset.tx, &mut offset.ty, &mut offset.tz]
            .into_iter()
            .enumerate()
        {
            let name = marker_param_name(&m.name, axis);
            *slot = ScalarSpec::Param(name.clone());
            let v = m.position[axis];
            out.parameters.push(ParameterSpec {
                name,
                group: MARKER_GROUP.to_string(),
                unit: Unit::Metre,
                nominal: v,
                lower: v - BOUND_IN_SD * prior_sd,
                upper: v + BOUND_IN_SD * prior_sd,
                description: format!(
                    "marker {} position in {}, {} axis",
                    m.name,
                    m.segment,
                    ["x", "y", "z"][axis]
                ),
                prior_sd: Some(prior_sd),
                prior_mean: None,
            });
        }
        out.segments.push(SegmentSpec {
            name: frame.clone(),
            description: format!("carries marker {} (refined position)", m.name),
        });
        out.joints.push(JointSpec {
            name: frame.clone(),
            parent: m.segment.clone(),
            child: frame.clone(),
            kind: JointKindSpec::Weld,
            coordinates: Vec::new(),
            parent_offset: offset,
            child_offset: OffsetSpec::default(),
        });
        m.segment = frame;
        m.position = [0.0; 3];
    }
    out
}

/// Undoes [`with_marker_parameters`]: every marker on a marker frame goes back to the
/// frame's parent segment at the frame's offset (the parameters' `nominal`, i.e. the fitted
/// values of a fitted description) plus its own position; the frames, their welds and their
/// parameters are removed. A description without marker frames is returned unchanged.
pub(crate) fn fold_marker_parameters(spec: &ModelSpec) -> ModelSpec {
    let mut out = spec.clone();
    let value = |s: &ScalarSpec| -> f64 {
        match s {
            ScalarSpec::Fixed(v) => *v,
            _ => {
                let (name, scale) = s.as_param().expect("a parameter");
                scale
                    * spec
                        .parameters
                        .iter()
                        .find(|p| p.name == name)
                        .map_or(0.0, |p| p.nominal)
            }
        }
    };
    let mut removed_params: Vec<String> = Vec::new();
    for j in spec
        .joints
        .iter()
        .filter(|j| j.child.starts_with(MARKER_FRAME_PREFIX))
    {
        let o = &j.parent_offset;
        let t = Vector3::new(value(&o.tx), value(&o.ty), value(&o.tz));
        for m in out.markers.iter_mut().filter(|m| m.segment == j.child) {
            let c = t + Vector3::from(m.position);
            m.segment = j.parent.clone();
            m.position = [c.x, c.y, c.z];
        }
        for s in o.scalars() {
            if let Some((n, _)) = s.as_param() {
                removed_params.push(n.to_string());
            }
        }
    }
    out.joints
        .retain(|j| !j.child.starts_with(MARKER_FRAME_PREFIX));
    out.segments
        .retain(|s| !s.name.starts_with(MARKER_FRAME_PREFIX));
    out.parameters.retain(|p| !removed_params.contains(&p.name));
    out
}

/// Where marker `j` of `model` sits at its prior (static-trial) position: the segment it is
/// fixed in and its position there (m), looking through a marker frame to the segment the
/// frame is welded to (then the position is the offset parameters' prior means).
pub(crate) fn marker_home(model: &Model, j: usize) -> (SegmentId, Vector3<f64>) {
    let m = &model.markers()[j];
    let seg = &model.segments()[m.segment.0];
    if !seg.name.starts_with(MARKER_FRAME_PREFIX) {
        return (m.segment, m.local);
    }
    let joint = &model.joints()[m.segment.0];
    let name = &seg.name[MARKER_FRAME_PREFIX.len()..];
    let mean = |axis: usize| {
        model
            .param_id(&marker_param_name(name, axis))
            .map_or(0.0, |id| model.parameters()[id.0].prior_mean)
    };
    match joint.parent {
        Some(parent) => (parent, m.local + Vector3::new(mean(0), mean(1), mean(2))),
        None => (m.segment, m.local),
    }
}

/// The markers of `spec` a refinement should free: weight > 0 and measured (not all NaN) in
/// at least one of the `present` name lists.
pub(crate) fn tracking_markers<'s>(spec: &'s ModelSpec, present: &[Vec<String>]) -> Vec<&'s str> {
    spec.markers
        .iter()
        .filter(|m: &&MarkerSpec| m.weight > 0.0 && present.iter().any(|l| l.contains(&m.name)))
        .map(|m| m.name.as_str())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{forward_kinematics, KinData, Want};
    use crate::model::lower_limb::{lower_limb, Side};

    #[test]
    fn refined_model_moves_markers_like_the_original_and_folds_back() {
        let spec = lower_limb(Side::Right);
        let names: Vec<&str> = spec.markers.iter().map(|m| m.name.as_str()).collect();
        let aug_spec = with_marker_parameters(&spec, &names, 0.01);
        let (orig, aug) = (
            Model::compile(&spec).unwrap(),
            Model::compile(&aug_spec).unwrap(),
        );
        assert_eq!(
            aug.parameters().len(),
            orig.parameters().len() + 3 * names.len()
        );
        assert_eq!(aug.coordinates().len(), orig.coordinates().len());
        // Same marker positions at the nominal parameters in any pose.
        let q: Vec<f64> = (0..orig.coordinates().len())
            .map(|i| 0.1 * (i as f64 + 1.0).sin())
            .collect();
        let (mut k0, mut k1) = (KinData::new(&orig), KinData::new(&aug));
        forward_kinematics(&orig, &orig.nominal_params(), &q, Want::Positions, &mut k0);
        forward_kinematics(&aug, &aug.nominal_params(), &q, Want::Positions, &mut k1);
        for (a, b) in k0.markers.iter().zip(&k1.markers) {
            assert!((a - b).norm() < 1e-12);
        }
        // Moving a marker parameter moves that marker by the same amount in its segment.
        let mut p = aug.nominal_params();
        let id = aug.param_id(&marker_param_name(names[0], 1)).unwrap();
        p[id.0] += 0.007;
        let folded = fold_marker_parameters(&aug.spec_with_nominal(&p));
        assert_eq!(folded.segments.len(), spec.segments.len());
        assert_eq!(folded.parameters.len(), spec.parameters.len());
        let (m0, m1) = (&spec.markers[0], &folded.markers[0]);
        assert_eq!(m0.segment, m1.segment);
        assert!((m1.position[1] - m0.position[1] - 0.007).abs() < 1e-12);
        assert!((m1.position[0] - m0.position[0]).abs() < 1e-12);
        // The home of a marker is its static position in its own segment.
        let (seg, local) = marker_home(&aug, 0);
        assert_eq!(seg, orig.markers()[0].segment);
        assert!((local - orig.markers()[0].local).norm() < 1e-12);
        // Folding a description without marker frames changes nothing.
        assert_eq!(fold_marker_parameters(&spec), spec);
    }
}
