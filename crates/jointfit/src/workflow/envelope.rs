//! The anatomical envelope as a constraint of the fit: the hip centre stays medial to the
//! ASIS.
//!
//! [`crate::plausibility`] checks after a fit that the hip centre's lateral offset from the
//! pelvis midline (the mid-ASIS plane of a personalized model) is at most
//! [`HIP_LATERAL_FRACTION`]` × PW/2` (PW the inter-ASIS distance of the static trial's ASIS
//! markers): Bell et al. 1990 put the hip centre 0.36·PW from the midline (0.72·PW/2),
//! Harrington et al. 2007 at 0.33·PW + 7 mm (0.72·PW/2 for a 230 mm pelvis), so 0.9·PW/2
//! leaves about 20 mm, 3 SDs of the lateral prior (7 mm, `model::population`), for a 230 mm
//! pelvis. A maximum a posteriori fit of a gait trial can still walk past it
//! when the markers pull (opensim-c3d walking2/5: landmark 70–71 mm, limit 88–89 mm, fit
//! 89.6–97.1 mm; `docs/priors.md`). Here the limit becomes the upper bound of
//! `hip_pelvis_lateral` (and of `_r`/`_l` on both legs), less [`ENVELOPE_MARGIN`], so every
//! solver (the joint/Schur solver, the two-level solver and the particle swarm, which all
//! search inside the parameters' bounds) respects it. A parameter that ends on this bound is
//! reported as held at the anatomical limit, not as determined by the trial.
//!
//! The bound is imposed only when the fit without it ends outside the envelope
//! (`refine::calibrate_refined` then fits again with it): a fit that ends inside is the
//! bounded problem's optimum as well. Bounding every fit would change results that never
//! reach the bound, because the bounds set the parameters' scaling to `[−1, 1]`, which the
//! HAC bandwidth rule and so the marker-noise estimate see: on opencap walking1 (right) a
//! bound 5 mm beyond the fit moved σ from 10.11 to 12.28 mm and the hip centre by 12 mm.
//!
//! Applied only to a maximum a posteriori fit (`FitSettings::priors`) with
//! `FitSettings::anatomical_envelope`: `--prior none` and `reproduce table1|table2` keep the
//! paper's unregularized fit in Reinbolt's bounds. Nothing changes when the start (or the
//! model's nominal value) already lies outside the envelope (a functional hip centre may):
//! the bound would exclude the prior's own mean; the plausibility check still reports it.

use serde::Serialize;

use crate::model::spec::ModelSpec;
use crate::model::Model;
use crate::plausibility::{half_pelvis_width, HIP_LATERAL_FRACTION};

/// How far inside the plausibility limit the bound sits (m): the held-out check measures the
/// inter-ASIS width on marker centres again, and rounds; 1 mm keeps a fit held at the bound
/// inside the check's limit.
pub(crate) const ENVELOPE_MARGIN: f64 = 0.001;

/// The hip-lateral parameters the envelope bounds.
const HIP_LATERAL: [&str; 3] = [
    "hip_pelvis_lateral",
    "hip_pelvis_lateral_r",
    "hip_pelvis_lateral_l",
];

/// One bound of the envelope.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EnvelopeBound {
    pub parameter: String,
    /// What the bound keeps: "hip centre medial to the ASIS".
    pub what: &'static str,
    /// The bound (m): `0.9 × PW/2 − margin`.
    pub limit: f64,
    /// The model's own upper bound it replaced (m).
    pub model_upper: f64,
    /// Whether the fitted value sits on the bound (set after the fit, [`mark_active`]).
    pub active: bool,
    /// Where the fit without the bound ended (m) when it ended outside the envelope and the
    /// fit was redone with the bound; `None` when it ended inside (the bound was not needed).
    pub unbounded_fit: Option<f64>,
}

/// Text of an active bound, as the outputs print it.
pub(crate) const HELD_AT_LIMIT: &str =
    "held at the anatomical limit: hip centre medial to the ASIS";

/// The envelope's bounds for `model` started at `start`, and the model description with
/// them (`None`: nothing to bound: no ASIS markers on the pelvis z axis, no hip-lateral
/// parameter, or the start or nominal value already outside the envelope).
pub(crate) fn bounded_spec(
    model: &Model,
    start: &[f64],
) -> Option<(ModelSpec, Vec<EnvelopeBound>)> {
    let half = half_pelvis_width(model)?;
    let limit = HIP_LATERAL_FRACTION * half - ENVELOPE_MARGIN;
    let mut spec = model.spec().clone();
    let mut bounds = Vec::new();
    for name in HIP_LATERAL {
        let Some(id) = model.param_id(name) else {
            continue;
        };
        let par = &spec.parameters[id.0];
        if limit >= par.upper || start[id.0] >= limit || par.nominal >= limit {
            continue;
        }
        bounds.push(EnvelopeBound {
            parameter: name.to_string(),
            what: "hip centre medial to the ASIS",
            limit,
            model_upper: par.upper,
            active: false,
            unbounded_fit: None,
        });
        spec.parameters[id.0].upper = limit;
    }
    (!bounds.is_empty()).then_some((spec, bounds))
}

/// Marks each bound whose parameter ends within 1 µm of it (`p` the fitted vector of
/// `model`, which has the bounded parameters under the same names).
pub(crate) fn mark_active(bounds: &mut [EnvelopeBound], model: &Model, p: &[f64]) {
    for b in bounds {
        if let Some(id) = model.param_id(&b.parameter) {
            b.active = p[id.0] >= b.limit - 1e-6;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{builtin, lower_limb, Side};
    use crate::model::population::{fill_landmark_priors, HipCentreMethod};

    #[test]
    fn bound_at_the_plausibility_limit_less_the_margin() {
        // The template's ASIS sit at (0, 0, ±120 mm): limit 0.9 × 120 − 1 = 107 mm.
        let mut spec = lower_limb(Side::Right);
        fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
        let m = Model::compile(&spec).unwrap();
        let (bounded, b) = bounded_spec(&m, &m.nominal_params()).unwrap();
        assert_eq!(b.len(), 1);
        assert!((b[0].limit - 0.107).abs() < 1e-12, "{b:?}");
        let i = m.param_id("hip_pelvis_lateral").unwrap().0;
        assert!((bounded.parameters[i].upper - 0.107).abs() < 1e-12);
        // Nothing else changed.
        let mut back = bounded.clone();
        back.parameters[i].upper = spec.parameters[i].upper;
        assert_eq!(&back, m.spec());
        // A start outside the envelope: no bound.
        let mut p = m.nominal_params();
        p[i] = 0.108;
        assert!(bounded_spec(&m, &p).is_none());
    }

    #[test]
    fn both_legs_are_bounded() {
        let m = Model::compile(&builtin("lower-limb").unwrap()).unwrap();
        let (_, b) = bounded_spec(&m, &m.nominal_params()).unwrap();
        let names: Vec<&str> = b.iter().map(|b| b.parameter.as_str()).collect();
        assert_eq!(names, ["hip_pelvis_lateral_r", "hip_pelvis_lateral_l"]);
    }
}
