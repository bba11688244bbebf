//! Video keypoints alone (OpenPose BODY_25, HALPE_26, COCO-WholeBody as Pose2Sim and OpenCap
//! name them: `RHip`, `RKnee`, `RAnkle`, `RHeel`, `RBigToe`, `RSmallToe`, `Neck`): the
//! hip, knee and ankle keypoints are *joint centres*, not skin markers, and the model is
//! built so.
//!
//! ## The static pose
//! Averaged over the static window (a few frames suffice; the keypoints of one frame are
//! noisy, their mean less so):
//!
//! - **Pelvis**: origin midway between the hip keypoints, z from the left to the right hip
//!   keypoint, y toward the trunk point (the `Neck`, or the mid-shoulders) made
//!   perpendicular to z, x = y × z. Keypoints give no pelvic landmark, so the pelvis tilt is
//!   the trunk's: hip flexion then includes the lumbar spine's.
//! - **Hip centre**: the hip keypoint itself (no regression). The pelvis width (which sizes
//!   the hip's search bounds) is that of virtual ASIS on the hip line, as far apart as Bell
//!   et al. 1990's regression puts the ASIS of such hip centres (hip offset 0.36 × width).
//! - **Knee and ankle**: the keypoints are the joint centres; their axes are the pelvis's
//!   medio-lateral axis made perpendicular to the thigh and shank (a standing pose has knees
//!   and ankles flexing about it). The landmark method then gets virtual epicondyles and
//!   malleoli at ±50 mm and ±35 mm from the centres along that axis (nominal widths, which
//!   also size Reinbolt's position bounds).
//! - **Foot**: heel keypoint to the mean of the toe keypoints.
//!
//! ## Tracking
//! The model's markers are the keypoints at the static pose: both hip keypoints and the
//! trunk point on the pelvis (the trunk point weighted [`TRUNK_WEIGHT`]: it is on the trunk,
//! which moves on the pelvis), the knee keypoint on the thigh, the ankle keypoint on the
//! shank, heel and toes on the foot. The joints' position parameters get the prior SD
//! [`KEYPOINT_SD`]: a keypoint is a joint centre only to a few centimetres.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::bilateral::{join_named, Outcome, PersonalizedModel, Sides};
use super::frames::{Landmarks, Medial};
use super::window::select_window;
use super::{check_options, personalize_plan, LandmarkError, PersonalizeOptions, Plan};
use jointfit::model::lower_limb::Side;
use jointfit::trial::Trial;

/// Weight of the trunk point among the pelvis markers.
pub(crate) const TRUNK_WEIGHT: f64 = 0.25;

/// Prior SD (m, per axis) of the joint-centre position parameters of a keypoint model: 3-D
/// joint centres from multi-camera pose estimation differ from marker-based ones by about
/// 2–5 cm (Needham et al. 2021, Sci Rep 11:20673); judged 25 mm per axis.
pub(crate) const KEYPOINT_SD: f64 = 0.025;

/// Half the nominal knee and ankle widths of the virtual landmarks (m).
const HALF_KNEE: f64 = 0.05;
const HALF_ANKLE: f64 = 0.035;

/// Names of the built-in keypoint sets.
pub const KEYPOINT_PRESET_NAMES: [&str; 2] = ["keypoints", "keypoints-shoulders"];

const PRESETS: [(&str, &str); 2] = [
    ("keypoints", include_str!("presets/keypoints.toml")),
    (
        "keypoints-shoulders",
        include_str!("presets/keypoints-shoulders.toml"),
    ),
];

/// A keypoint set: which keypoint is which joint centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeypointSet {
    pub name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// The trunk point: the mean of these keypoints (`Neck`, or both shoulders).
    pub trunk: Vec<String>,
    pub right: KeypointLeg,
    pub left: KeypointLeg,
}

/// One leg's keypoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeypointLeg {
    pub hip: String,
    pub knee: String,
    pub ankle: String,
    pub heel: String,
    /// Big and small toe.
    pub toes: Vec<String>,
}

impl KeypointSet {
    /// A built-in keypoint set by name ([`KEYPOINT_PRESET_NAMES`]).
    pub fn preset(name: &str) -> Result<KeypointSet, LandmarkError> {
        let (_, text) = PRESETS.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            LandmarkError::UnknownPreset {
                name: name.to_string(),
                available: KEYPOINT_PRESET_NAMES.join(", "),
            }
        })?;
        KeypointSet::from_toml(text, &format!("preset {name}"))
    }

    /// Parses a keypoint-set TOML; `name` (a file name) is used in errors.
    pub(crate) fn from_toml(text: &str, name: &str) -> Result<KeypointSet, LandmarkError> {
        let set: KeypointSet =
            toml::from_str(text).map_err(|e| LandmarkError::MarkerSetSyntax {
                source_name: name.to_string(),
                detail: e.to_string(),
            })?;
        if set.trunk.is_empty() || set.right.toes.is_empty() || set.left.toes.is_empty() {
            return Err(LandmarkError::InvalidMarkerSet {
                set: set.name,
                detail: "trunk and toes must list at least one keypoint each".into(),
            });
        }
        Ok(set)
    }

    pub(crate) fn leg(&self, side: Side) -> &KeypointLeg {
        match side {
            Side::Right => &self.right,
            Side::Left => &self.left,
        }
    }

    /// Every label the set needs, both legs.
    pub(crate) fn labels(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for side in [Side::Right, Side::Left] {
            for (_, l) in self.roles(side) {
                if !out.contains(&l) {
                    out.push(l);
                }
            }
        }
        out
    }

    /// (role, label) of one leg: the pelvis's keypoints, then the leg's.
    pub(crate) fn roles(&self, side: Side) -> Vec<(String, String)> {
        let leg = self.leg(side);
        let mut out = vec![
            ("right hip centre".to_string(), self.right.hip.clone()),
            ("left hip centre".to_string(), self.left.hip.clone()),
        ];
        out.extend(self.trunk.iter().map(|t| ("trunk".to_string(), t.clone())));
        out.push(("knee centre".into(), leg.knee.clone()));
        out.push(("ankle centre".into(), leg.ankle.clone()));
        out.push(("heel".into(), leg.heel.clone()));
        out.extend(leg.toes.iter().map(|t| ("toe".to_string(), t.clone())));
        out
    }

    fn plan(&self, side: Side) -> Plan<'_> {
        let leg = self.leg(side);
        let mut pelvis = vec![self.right.hip.clone(), self.left.hip.clone()];
        pelvis.extend(self.trunk.iter().cloned());
        let mut foot = vec![leg.heel.clone()];
        foot.extend(leg.toes.iter().cloned());
        Plan {
            set_name: &self.name,
            roles: self.roles(side),
            tracking: vec![
                ("pelvis", pelvis),
                ("thigh", vec![leg.knee.clone()]),
                ("shank", vec![leg.ankle.clone()]),
                ("foot", foot),
            ],
            weights: self
                .trunk
                .iter()
                .map(|t| (t.clone(), TRUNK_WEIGHT))
                .collect(),
        }
    }

    /// The virtual landmarks of one leg from the averaged keypoints (module docs).
    fn landmarks(
        &self,
        side: Side,
        at: &dyn Fn(&str) -> Vector3<f64>,
    ) -> Result<Landmarks, LandmarkError> {
        let leg = self.leg(side);
        let (hr, hl) = (at(&self.right.hip), at(&self.left.hip));
        let trunk: Vector3<f64> =
            self.trunk.iter().map(|t| at(t)).sum::<Vector3<f64>>() / self.trunk.len() as f64;
        let mid = 0.5 * (hr + hl);
        let z = hr - hl;
        let degenerate = |detail: &str| LandmarkError::Degenerate {
            segment: "pelvis".into(),
            detail: detail.into(),
        };
        if z.norm() < 0.05 {
            return Err(degenerate("the hip keypoints are less than 50 mm apart"));
        }
        let z = z.normalize();
        let up = trunk - mid;
        let y = up - z * z.dot(&up);
        if y.norm() < 0.05 {
            return Err(degenerate(
                "the trunk keypoint lies on the line through the hip keypoints",
            ));
        }
        let x = y.normalize().cross(&z);
        let s = side.sign();
        let (knee, ankle) = (at(&leg.knee), at(&leg.ankle));
        let toes: Vector3<f64> =
            leg.toes.iter().map(|t| at(t)).sum::<Vector3<f64>>() / leg.toes.len() as f64;
        // Virtual ASIS on the hip line, as far apart as Bell et al. 1990 put the ASIS of
        // hip centres this far apart (lateral offset 0.36 × the inter-ASIS width): the
        // pelvis's origin stays midway between the hips, its width scales the bounds.
        let half_asis = 0.5 * (hr - hl).norm() / 0.72;
        Ok(Landmarks {
            r_asis: mid + half_asis * z,
            l_asis: mid - half_asis * z,
            // A point behind the hip centres: the pelvis's x is then exactly `x`.
            back: mid - 0.1 * x,
            lat_epicondyle: knee + s * HALF_KNEE * z,
            med_epicondyle: Medial::Marker(knee - s * HALF_KNEE * z),
            lat_malleolus: ankle + s * HALF_ANKLE * z,
            med_malleolus: Medial::Marker(ankle - s * HALF_ANKLE * z),
            heel: at(&leg.heel),
            forefoot: toes,
            hip_centre: Some(match side {
                Side::Right => hr,
                Side::Left => hl,
            }),
        })
    }
}

/// Builds the subject model from a static trial of keypoints (module docs): both legs
/// joined at the pelvis over one common window, or one leg.
pub fn personalize_keypoints(
    trial: &Trial,
    set: &KeypointSet,
    sides: Sides,
    opts: &PersonalizeOptions,
) -> Result<Outcome, LandmarkError> {
    check_options(opts)?;
    let func = super::functional::apply::FunctionalTrials::default();
    let one = |side: Side, window: Option<&super::StaticWindow>| {
        let mut p = personalize_plan(trial, &set.plan(side), side, opts, &func, window, |at| {
            set.landmarks(side, at)
        })?;
        widen_priors(&mut p.spec);
        Ok::<_, LandmarkError>(p)
    };
    let window = match sides {
        Sides::One(side) => {
            return Ok(Outcome {
                model: PersonalizedModel::One(side, Box::new(one(side, None)?)),
                warning: None,
            })
        }
        Sides::Both => {
            let names = set.labels();
            let columns: Option<Vec<usize>> = names
                .iter()
                .map(|n| trial.labels().iter().position(|l| l == n))
                .collect();
            match columns {
                Some(c) => {
                    let wanted = (opts.window_seconds * trial.rate()).round().max(1.0) as usize;
                    Some(select_window(trial, &c, &names, wanted)?)
                }
                // The leg's personalization names what is missing.
                None => None,
            }
        }
    };
    let right = one(Side::Right, window.as_ref())?;
    let left = one(Side::Left, window.as_ref())?;
    Ok(Outcome {
        model: PersonalizedModel::Both(Box::new(join_named(right, left, &set.name, opts)?)),
        warning: None,
    })
}

/// The joint-centre positions of a keypoint model get the keypoint prior [`KEYPOINT_SD`].
fn widen_priors(spec: &mut jointfit::model::spec::ModelSpec) {
    for p in &mut spec.parameters {
        let position = p.unit == jointfit::model::spec::Unit::Metre;
        let joint_centre = p.name.starts_with("hip_")
            || p.name.starts_with("knee_")
            || p.name.starts_with("talocrural_");
        if position && joint_centre {
            p.prior_sd = Some(p.prior_sd.map_or(KEYPOINT_SD, |sd| sd.max(KEYPOINT_SD)));
        }
    }
}

/// The keypoint preset whose every label `labels` has, the first in
/// [`KEYPOINT_PRESET_NAMES`] order.
pub(crate) fn fitting_preset(labels: &[String]) -> Option<&'static str> {
    KEYPOINT_PRESET_NAMES.into_iter().find(|n| {
        KeypointSet::preset(n).is_ok_and(|s| s.labels().iter().all(|l| labels.contains(l)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_need_their_labels() {
        for name in KEYPOINT_PRESET_NAMES {
            let set = KeypointSet::preset(name).unwrap();
            assert_eq!(set.name, name);
            assert_eq!(fitting_preset(&set.labels()), Some(name));
        }
        assert_eq!(fitting_preset(&["RHip".to_string()]), None);
        let e = KeypointSet::from_toml("name = \"k\"\ntrunk = []\n", "k.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("marker set k.toml: "), "{e}");
    }
}
