//! Coordinates no marker of a trial determines (e.g. the toe joint of an OpenSim model on a
//! trial without toe markers), held at their default values: [`lock_undetermined`] on a
//! description, [`hold_undetermined`] on a compiled model. OpenSim's inverse kinematics leaves
//! such a coordinate where it starts, its default; jointfit's frames need every coordinate in
//! `q` determined ([`crate::ik::solvable`]), so the coordinate leaves `q` (locked).

use crate::ik::lm::IkWorkspace;
use crate::ik::{undetermined_coordinate, IkOptions, MarkerMap};
use crate::model::spec::{CoordinateSpec, JointKindSpec, ModelSpec};
use crate::model::{Model, ModelError};
use crate::trial::Trial;

/// Locks, at their default values, the coordinates of `spec` that the markers of the
/// trials leave undetermined ([`jointfit::ik::undetermined_coordinate`]: the structural rank
/// test of the marker Jacobian at the frame of each trial with the most markers present), one
/// at a time until every such frame is solvable; returns their names. OpenSim's inverse
/// kinematics leaves such a coordinate where it starts; the calibration's frames need every
/// coordinate determined. Coordinates of non-custom joints are never locked (the core can
/// lock only custom-joint coordinates; every joint read from an `.osim` is custom).
pub(crate) fn lock_undetermined(
    spec: &mut ModelSpec,
    trials: &[&Trial],
) -> Result<Vec<String>, ModelError> {
    let mut locked = Vec::new();
    let opts = IkOptions::default();
    let mut targets = Vec::new();
    for _ in 0..64 {
        let model = Model::compile(spec)?;
        let p = model.nominal_params();
        let mut ws = IkWorkspace::new(&model);
        let mut found = None;
        for trial in trials {
            let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
            let best = (0..trial.n_frames()).max_by_key(|&f| {
                map.targets(trial, f, &mut targets);
                targets.iter().filter(|t| !t.x.is_nan()).count()
            });
            let Some(f) = best else { continue };
            map.targets(trial, f, &mut targets);
            if let Some(c) = undetermined_coordinate(&model, &p, &targets, &opts, &mut ws) {
                found = Some(model.coordinates()[c].name.clone());
                break;
            }
        }
        let Some(name) = found else { break };
        let mut done = false;
        for joint in &mut spec.joints {
            if !matches!(joint.kind, JointKindSpec::Custom { .. }) {
                continue;
            }
            for c in &mut joint.coordinates {
                if c.name() != name {
                    continue;
                }
                *c = match c.clone() {
                    CoordinateSpec::Name(name) => CoordinateSpec::Full {
                        name,
                        range: None,
                        default: 0.0,
                        locked: true,
                        clamped: false,
                    },
                    CoordinateSpec::Full {
                        name,
                        range,
                        default,
                        clamped,
                        ..
                    } => CoordinateSpec::Full {
                        name,
                        range,
                        default,
                        locked: true,
                        clamped,
                    },
                };
                done = true;
            }
        }
        if !done {
            break;
        }
        locked.push(name);
    }
    Ok(locked)
}

/// [`lock_undetermined`] on a compiled model: `None` when every coordinate is determined
/// (use `model` as it is), else the model with the returned coordinates locked.
pub fn hold_undetermined(
    model: &Model,
    trials: &[&Trial],
) -> Result<(Option<Model>, Vec<String>), ModelError> {
    let mut spec = model.spec().clone();
    let held = lock_undetermined(&mut spec, trials)?;
    if held.is_empty() {
        return Ok((None, held));
    }
    Ok((Some(Model::compile(&spec)?), held))
}
