//! [`ik_trial`]: inverse kinematics over a trial; [`ik_checked`]: the same with the data
//! checks alongside; [`transfer_params`]: parameters carried between models by name.

use super::WorkflowError;
use crate::ik::trial_fit::TrialFit;
use crate::ik::{solve_trial_alongside, IkOptions, MarkerMap};
use crate::model::Model;
use crate::trial::Trial;

/// The result of [`ik_trial`].
#[derive(Debug, Clone)]
pub struct IkRun {
    pub fit: TrialFit,
    /// Model markers the trial lacks altogether: missing in every frame.
    pub absent: Vec<String>,
}

/// Inverse kinematics of every frame of `trial` with `model` at parameters `p`: each frame
/// warm-started from the extrapolation of the two before (the first, and the first after a
/// frame that could not be solved, seeded; see [`crate::ik::trial_fit::solve_trial`]). Markers of the
/// model the trial lacks count as missing in every frame (listed in [`IkRun::absent`]);
/// frames whose segments keep too few markers are not solved. Errors when the trial shares
/// no marker with the model, or no frame can be solved.
pub fn ik_trial(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    opts: &IkOptions,
) -> Result<IkRun, WorkflowError> {
    ik_trial_alongside(model, p, trial, opts, || ()).0
}

/// [`ik_trial`] with `also` run alongside on the thread pool
/// ([`crate::ik::solve_trial_alongside`]; `also` runs in any case, first when the IK cannot
/// start).
fn ik_trial_alongside<R: Send>(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    opts: &IkOptions,
    also: impl FnOnce() -> R + Send,
) -> (Result<IkRun, WorkflowError>, R) {
    let (map, absent) = MarkerMap::allowing_absent(model, trial.labels());
    if absent.len() == model.markers().len() {
        // Nothing in common: the strict matcher's error lists both sides.
        if let Err(e) = MarkerMap::by_name(model, trial.labels()) {
            return (Err(e.into()), also());
        }
    }
    let (fit, extra) = solve_trial_alongside(model, p, trial, &map, opts, also);
    let run = fit.map_err(WorkflowError::from).and_then(|fit| {
        if !fit.frames.iter().any(|f| f.solved()) {
            let detail = match fit.unsolved_ranges().first() {
                Some(r) => format!(" (first frame: {})", r.reason),
                None => String::new(),
            };
            return Err(WorkflowError::NoFrameSolved { detail });
        }
        Ok(IkRun { fit, absent })
    });
    (run, extra)
}

/// [`ik_trial`] together with the data checks of the same trial
/// ([`crate::checks::check_trial`], markers matched as [`ik_trial`] matches them), with the
/// same findings in the same order. The checks that need no inverse kinematics run
/// alongside it, queued behind the IK's chunks ([`crate::ik::solve_trial_alongside`]: on two
/// threads each takes a chunk and the first to finish takes the checks, whose parallel
/// parts the other joins when it finishes); the moved-cluster check then reads the IK's own fit
/// ([`crate::checks::offsets::check_offsets`]) when that is the IK it would run
/// (nominal parameters, default options), instead of solving the frames a second time.
pub fn ik_checked(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    opts: &IkOptions,
) -> (Result<IkRun, WorkflowError>, Vec<crate::checks::Finding>) {
    let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
    let (run, mut findings) = ik_trial_alongside(model, p, trial, opts, || {
        crate::checks::check_trial_before_ik(model, trial, &map)
    });
    findings.extend(match &run {
        Ok(run) => {
            crate::checks::offsets::check_offsets(model, trial, &map, Some((p, opts, &run.fit)))
        }
        Err(_) => crate::checks::offsets::check_offsets(model, trial, &map, None),
    });
    (run, findings)
}

/// The parameter vector of `target` with every value taken, by name, from `source`'s
/// nominal values and clamped into `target`'s bounds (a start from an earlier fit).
/// `source_name` names `source` in the error when it lacks a parameter of `target`.
pub fn transfer_params(
    target: &Model,
    source: &Model,
    source_name: &str,
) -> Result<Vec<f64>, WorkflowError> {
    target
        .parameters()
        .iter()
        .map(|par| match source.param_id(&par.name) {
            Some(id) => Ok(source.parameters()[id.0]
                .nominal
                .clamp(par.lower, par.upper)),
            None => Err(WorkflowError::MissingParameter {
                source_model: source_name.to_string(),
                name: par.name.clone(),
            }),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};

    /// The checks alongside the IK give what each gives alone (a trial with a gap, so the
    /// checks have something to say).
    #[test]
    fn ik_checked_equals_ik_then_checks() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        let p = model.nominal_params();
        let coords: Vec<Vec<f64>> = (0..200)
            .map(|f| {
                let mut q = model.default_coords();
                q[4] = 0.9;
                q[6] = 0.4 * (f as f64 * 0.05).sin();
                q[9] = 0.5 + 0.4 * (f as f64 * 0.05).cos();
                q
            })
            .collect();
        let mut kin = crate::kinematics::KinData::new(&model);
        let mut positions = Vec::new();
        for q in &coords {
            crate::kinematics::forward_kinematics(
                &model,
                &p,
                q,
                crate::kinematics::Want::Positions,
                &mut kin,
            );
            positions.extend(kin.markers.iter().copied());
        }
        let n = model.markers().len();
        for f in 50..60 {
            positions[f * n + 3] = nalgebra::Vector3::repeat(f64::NAN);
        }
        let labels = model.markers().iter().map(|m| m.name.clone()).collect();
        let trial = Trial::new(labels, 100.0, 1, positions).unwrap();
        let opts = IkOptions::default();
        let (run, findings) = ik_checked(&model, &p, &trial, &opts);
        let run = run.unwrap();
        let alone = ik_trial(&model, &p, &trial, &opts).unwrap();
        let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
        let checks = crate::checks::check_trial(&model, &trial, &map);
        assert!(!checks.is_empty());
        assert_eq!(format!("{findings:?}"), format!("{checks:?}"));
        assert_eq!(run.fit.frames, alone.fit.frames);
        let bits = |c: &Vec<Vec<f64>>| c.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&run.fit.coords), bits(&alone.fit.coords));
    }

    #[test]
    fn transfer_takes_values_by_name_and_clamps() {
        let target = Model::compile(&lower_limb(Side::Right)).unwrap();
        let mut spec = lower_limb(Side::Right);
        // Move one parameter inside its bounds and one beyond them.
        let (a, b) = (0, 1);
        let lo_b = target.parameters()[b].lower;
        spec.parameters[a].nominal +=
            0.25 * (target.parameters()[a].upper - spec.parameters[a].nominal);
        spec.parameters[b].nominal = lo_b - 1.0;
        spec.parameters[b].lower = lo_b - 2.0;
        let source = Model::compile(&spec).unwrap();
        let p = transfer_params(&target, &source, "earlier.toml").unwrap();
        assert_eq!(p[a], source.parameters()[a].nominal);
        assert_ne!(p[a], target.parameters()[a].nominal);
        assert_eq!(p[b], lo_b);
        for (v, par) in p.iter().zip(target.parameters()).skip(2) {
            assert_eq!(*v, par.nominal);
        }
        // A source without one of the target's parameters is an error naming both.
        // The same leg with one parameter renamed (everywhere it is used).
        let text = toml::to_string(&lower_limb(Side::Right)).unwrap();
        let renamed: crate::model::spec::ModelSpec =
            toml::from_str(&text.replace("hip_thigh_anterior", "extra_offset")).unwrap();
        let wider = Model::compile(&renamed).unwrap();
        match transfer_params(&wider, &source, "x.toml") {
            Err(e) => {
                let msg = e.to_string();
                assert!(
                    msg.contains("x.toml") && msg.contains("extra_offset"),
                    "{msg}"
                );
            }
            Ok(_) => panic!("missing parameter accepted"),
        }
    }
}
