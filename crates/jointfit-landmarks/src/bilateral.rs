//! Both legs from one static trial: the bilateral subject model.
//!
//! Both legs share one pelvis. Each leg is personalized as the one-sided method does
//! ([`super::personalize`]), from its own landmarks, but over one *common* static window: the
//! window with the least motion of all the markers of the pelvis and both legs together
//! ([`super::window`]), instead of each leg's own stillest window. The pelvis landmarks
//! averaged over that window, and so the pelvis frame, its markers and its static pose, are
//! then the same for both legs, and the two one-sided models are joined at the pelvis
//! ([`join_legs`]): the bilateral model's right-leg parameters are the right leg's
//! personalization over the common window, its left-leg parameters the left leg's, bit for
//! bit, with the names suffixed `_r`/`_l`. A leg differs from its one-sided personalization
//! only by the subject's sway between the common window and that leg's own window.
//!
//! (Earlier, each leg used its own window and the left leg hung from the right leg's pelvis:
//! 0.09 mm of pelvis sway between the windows on OpenCap's static trial, 5.6 mm on the Vicon
//! static of `biobuddy_functional_vicon`.) When no frame holds every marker of both legs,
//! each leg falls back to its own window and [`BothLegs::pelvis_gap`] reports the sway.
//!
//! When the static trial carries the markers of only one leg (none of the other leg's own
//! labels), [`personalize_sides`] builds that leg's one-sided model and says so in
//! [`Outcome::warning`]; a leg with only some of its markers is an error, never a silent
//! half-model.

use super::functional::apply::FunctionalTrials;
use super::window::{select_window, StaticWindow};
use super::{
    check_options, personalize_in, personalize_with, LandmarkError, MarkerSet, PersonalizeOptions,
    Personalized,
};
use jointfit::model::lower_limb::bilateral::{join_legs, PELVIS_SEGMENT};
use jointfit::model::lower_limb::Side;
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;
use jointfit::trial::Trial;

/// Which legs to personalize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sides {
    /// Both legs and the pelvis (`lower-limb` structure, 54 parameters).
    #[default]
    Both,
    /// One leg (`lower-limb-right` / `lower-limb-left` structure, 27 parameters).
    One(Side),
}

impl std::str::FromStr for Sides {
    type Err = LandmarkError;
    fn from_str(s: &str) -> Result<Sides, LandmarkError> {
        match s {
            "both" => Ok(Sides::Both),
            "right" => Ok(Sides::One(Side::Right)),
            "left" => Ok(Sides::One(Side::Left)),
            other => Err(LandmarkError::InvalidOption(format!(
                "side must be \"both\", \"right\" or \"left\", not {other:?}"
            ))),
        }
    }
}

/// Both legs personalized and joined.
#[derive(Debug, Clone)]
pub struct BothLegs {
    /// The bilateral subject model.
    pub spec: ModelSpec,
    /// Coordinates of the static pose in the compiled bilateral model's order: the pelvis and
    /// the right leg of the right leg's window, the left leg's joint angles of its own window.
    pub static_q: Vec<f64>,
    /// The one-sided personalizations the model was joined from.
    pub right: Personalized,
    pub left: Personalized,
    /// Largest distance between a pelvis marker averaged over the right leg's window and over
    /// the left leg's window (m): 0 when both legs share the common window (module docs),
    /// else how much the subject swayed between the two windows.
    pub pelvis_gap: f64,
}

/// The model [`personalize_sides`] built.
#[derive(Debug, Clone)]
pub enum PersonalizedModel {
    One(Side, Box<Personalized>),
    Both(Box<BothLegs>),
}

impl PersonalizedModel {
    pub fn spec(&self) -> &ModelSpec {
        match self {
            PersonalizedModel::One(_, p) => &p.spec,
            PersonalizedModel::Both(b) => &b.spec,
        }
    }
    pub fn spec_mut(&mut self) -> &mut ModelSpec {
        match self {
            PersonalizedModel::One(_, p) => &mut p.spec,
            PersonalizedModel::Both(b) => &mut b.spec,
        }
    }
    /// The one-sided personalizations, right first.
    pub fn legs(&self) -> Vec<(Side, &Personalized)> {
        match self {
            PersonalizedModel::One(s, p) => vec![(*s, p.as_ref())],
            PersonalizedModel::Both(b) => vec![(Side::Right, &b.right), (Side::Left, &b.left)],
        }
    }
}

/// The result of [`personalize_sides`].
#[derive(Debug, Clone)]
pub struct Outcome {
    pub model: PersonalizedModel,
    /// One line when both legs were asked for and only one could be built (the front end
    /// shows it).
    pub warning: Option<String>,
}

/// Personalizes the legs `sides` asks for (see the module docs). Functional trials belong to
/// one leg: with [`Sides::Both`] they are refused.
pub fn personalize_sides(
    trial: &Trial,
    set: &MarkerSet,
    sides: Sides,
    opts: &PersonalizeOptions,
    func: &FunctionalTrials,
) -> Result<Outcome, LandmarkError> {
    let one = |side: Side, warning: Option<String>| {
        personalize_with(trial, set, side, opts, func).map(|p| Outcome {
            model: PersonalizedModel::One(side, Box::new(p)),
            warning,
        })
    };
    if let Sides::One(side) = sides {
        return one(side, None);
    }
    if func.hip.is_some() || func.knee.is_some() {
        return Err(LandmarkError::InvalidOption(
            "functional trials belong to one leg: choose the right or the left side".into(),
        ));
    }
    set.validate()?;
    let set = &set.resolve(trial.labels());
    for (side, other) in [(Side::Right, Side::Left), (Side::Left, Side::Right)] {
        if set.leg(other).is_err() {
            let w = format!(
                "marker set {:?} has no [{}] leg: personalized the {} leg only",
                set.name, other, side
            );
            return one(side, Some(w));
        }
    }
    // A leg none of whose own labels is in the trial is absent; otherwise it must be complete.
    let absent = |side: Side| -> Result<Option<Vec<String>>, LandmarkError> {
        let own = leg_labels(set, side)?;
        let none = own.iter().all(|l| !trial.labels().contains(l));
        Ok(none.then_some(own))
    };
    match (absent(Side::Right)?, absent(Side::Left)?) {
        (Some(_), Some(_)) | (None, None) => {}
        (Some(missing), None) => return one(Side::Left, Some(fallback(Side::Right, &missing))),
        (None, Some(missing)) => return one(Side::Right, Some(fallback(Side::Left, &missing))),
    }
    let common = common_window(trial, set, opts)?;
    let right = personalize_in(trial, set, Side::Right, opts, func, common.as_ref())?;
    let left = personalize_in(trial, set, Side::Left, opts, func, common.as_ref())?;
    Ok(Outcome {
        model: PersonalizedModel::Both(Box::new(join(right, left, set, opts)?)),
        warning: None,
    })
}

/// The stillest window of every marker of the pelvis and both legs (module docs); `None`
/// when a marker is absent (the leg's personalization then names it) or no frame holds them
/// all (each leg then uses its own window).
pub fn common_window(
    trial: &Trial,
    set: &MarkerSet,
    opts: &PersonalizeOptions,
) -> Result<Option<StaticWindow>, LandmarkError> {
    check_options(opts)?;
    let mut names: Vec<String> = Vec::new();
    for side in [Side::Right, Side::Left] {
        for (_, label) in set.roles(side)? {
            if !names.contains(&label) {
                names.push(label);
            }
        }
    }
    let mut columns = Vec::with_capacity(names.len());
    for n in &names {
        match trial.labels().iter().position(|l| l == n) {
            Some(c) => columns.push(c),
            None => return Ok(None),
        }
    }
    let wanted = (opts.window_seconds * trial.rate()).round().max(1.0) as usize;
    match select_window(trial, &columns, &names, wanted) {
        Ok(w) => Ok(Some(w)),
        Err(LandmarkError::NoCompleteFrame { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

fn fallback(absent: Side, labels: &[String]) -> String {
    let shown: Vec<&str> = labels.iter().take(4).map(String::as_str).collect();
    let more = if labels.len() > shown.len() {
        ", …"
    } else {
        ""
    };
    format!(
        "the static trial has none of the {} leg's markers ({}{more}): personalized the {} leg \
         only",
        absent,
        shown.join(", "),
        match absent {
            Side::Right => "left",
            Side::Left => "right",
        }
    )
}

/// The labels of one leg that are not pelvis markers, in role order, without repeats.
fn leg_labels(set: &MarkerSet, side: Side) -> Result<Vec<String>, LandmarkError> {
    let p = &set.pelvis;
    let pelvis: Vec<&String> = [&p.right_asis, &p.left_asis]
        .into_iter()
        .chain(p.right_psis.iter())
        .chain(p.left_psis.iter())
        .chain(p.sacrum.iter())
        .chain(p.tracking.iter())
        .collect();
    let mut out: Vec<String> = Vec::new();
    for (_, label) in set.roles(side)? {
        if !pelvis.contains(&&label) && !out.contains(&label) {
            out.push(label);
        }
    }
    Ok(out)
}

/// Joins two one-sided personalizations (see the module docs).
pub(crate) fn join(
    right: Personalized,
    left: Personalized,
    set: &MarkerSet,
    opts: &PersonalizeOptions,
) -> Result<BothLegs, LandmarkError> {
    join_named(right, left, &set.name, opts)
}

/// [`join`] with the set given by name (a marker set's or a keypoint set's).
pub(crate) fn join_named(
    right: Personalized,
    left: Personalized,
    set_name: &str,
    opts: &PersonalizeOptions,
) -> Result<BothLegs, LandmarkError> {
    let mut spec = join_legs(&right.spec, &left.spec).map_err(LandmarkError::Model)?;
    spec.name = opts.name.clone();
    spec.description = format!(
        "both legs and the pelvis personalized by the anatomical-landmark method (marker set \
         {set_name:?}); right: {}; left: {}",
        right.spec.description, left.spec.description
    );
    // The static pose by coordinate name: the pelvis and the right leg from the right leg's
    // personalization, the left leg from the left's (one window when they share it).
    let model = Model::compile(&spec).map_err(LandmarkError::Model)?;
    let mut static_q = Vec::with_capacity(model.coordinates().len());
    let sides = [(&right, "_r"), (&left, "_l")];
    let compiled: Vec<Model> = sides
        .iter()
        .map(|(p, _)| Model::compile(&p.spec).map_err(LandmarkError::Model))
        .collect::<Result<_, _>>()?;
    for c in model.coordinates() {
        let (k, name) = sides
            .iter()
            .enumerate()
            .find_map(|(k, (_, s))| c.name.strip_suffix(s).map(|n| (k, n)))
            .unwrap_or((0, c.name.as_str()));
        let id = compiled[k].coord_id(name).ok_or_else(|| {
            LandmarkError::Internal(format!("coordinate {:?} of the joined model", c.name))
        })?;
        static_q.push(sides[k].0.static_q[id]);
    }
    let world = |p: &Personalized| -> Vec<(String, nalgebra::Vector3<f64>)> {
        p.spec
            .markers
            .iter()
            .filter(|m| m.segment == PELVIS_SEGMENT)
            .map(|m| {
                let x = nalgebra::Vector3::from(m.position);
                (m.name.clone(), p.frames.pelvis.transform_point(&x))
            })
            .collect()
    };
    let (wr, wl) = (world(&right), world(&left));
    let pelvis_gap = wr
        .iter()
        .filter_map(|(n, x)| wl.iter().find(|(m, _)| m == n).map(|(_, y)| (x - y).norm()))
        .fold(0.0, f64::max);
    Ok(BothLegs {
        spec,
        static_q,
        right,
        left,
        pelvis_gap,
    })
}
