//! The workflow against known synthetic truth.

use super::*;
use crate::calibrate::params_for_groups;
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::trial::Trial;
use nalgebra::Vector3;

/// Markers of `model` at `p` along a hip, knee and ankle motion of `frames` frames, plus a
/// smooth deterministic disturbance of up to `noise` metres per axis.
pub(crate) fn synthetic(model: &Model, p: &[f64], frames: usize, noise: f64) -> Trial {
    let w = std::f64::consts::TAU;
    let mut kin = KinData::new(model);
    let mut positions = Vec::new();
    for f in 0..frames {
        let t = f as f64 / frames as f64;
        let mut q = model.default_coords();
        let mut set = |name: &str, v: f64| q[model.coord_id(name).unwrap()] = v;
        set("pelvis_ty", 0.95);
        set("pelvis_tilt", 0.03 * (w * t).sin());
        set("hip_flexion", 0.35 + 0.5 * (3.0 * w * t).sin());
        set("hip_adduction", 0.25 * (3.0 * w * t).cos());
        set("hip_rotation", 0.15 * (1.5 * w * t).sin());
        set("knee_flexion", 0.85 + 0.7 * (2.0 * w * t - 1.5).sin());
        set("ankle_dorsiflexion", -0.1 + 0.3 * (2.5 * w * t).sin());
        set("subtalar_inversion", 0.25 * (2.5 * w * t).cos());
        forward_kinematics(model, p, &q, Want::Positions, &mut kin);
        for (j, x) in kin.markers.iter().enumerate() {
            let d = |k: usize| noise * ((7 * j + 3 * k) as f64 + 1.7 * f as f64).sin();
            positions.push(x + Vector3::new(d(0), d(1), d(2)));
        }
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    Trial::new(labels, 50.0, 1, positions).unwrap()
}

fn leg() -> Model {
    Model::compile(&lower_limb(Side::Right)).unwrap()
}

/// Records every call an observer gets.
#[derive(Default)]
struct Log {
    stages: Vec<String>,
    iterations: usize,
    ended: Vec<Termination>,
    progress: Vec<(usize, usize)>,
}

impl Observer for Log {
    fn stage_started(&mut self, stage: &str, _budget: Option<usize>) {
        self.stages.push(stage.to_string());
    }
    fn iteration(&mut self, _iteration: usize, _objective: f64) {
        self.iterations += 1;
    }
    fn stage_ended(&mut self, termination: Termination) {
        self.ended.push(termination);
    }
    fn progress(&mut self, done: usize, total: usize) {
        self.progress.push((done, total));
    }
}

#[test]
fn calibrate_recovers_the_truth_and_fills_the_rows() {
    let model = leg();
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let idx: Vec<usize> = free.iter().map(|id| id.0).collect();
    let start = model.nominal_params();
    let truth = perturb(&model, &start, &idx, 15.0, 8.0, 3);
    let trial = synthetic(&model, &truth, 40, 0.0);
    let mut log = Log::default();
    let cal = calibrate(
        &model,
        &start,
        &[&trial],
        &free,
        // One local fit: the global phase is tested in jointfit-experiments/tests/global.rs.
        &FitSettings {
            probes: 0,
            ..FitSettings::default()
        },
        &mut log,
    )
    .unwrap();
    assert_eq!(cal.termination, Termination::Converged);
    assert!(cal.converged);
    assert_eq!(cal.parameters.len(), free.len());
    for (row, &i) in cal.parameters.iter().zip(&idx) {
        let unit = model.parameters()[i].unit;
        assert_eq!(row.name, model.parameters()[i].name);
        assert_eq!(row.unit, unit);
        assert!(
            unit.to_display((row.fitted - truth[i]).abs()) < 1e-6,
            "{row:?}"
        );
        assert_eq!(row.start, start[i]);
        assert_eq!(row.change, row.fitted - row.start);
    }
    assert!(cal.rms_after < 1e-9 && cal.rms_before > 1e-3);
    assert_eq!(cal.frames, 40);
    assert_eq!((cal.best_start, cal.start_runs.len()), (0, 1));
    assert!(cal.multistart.is_none() && cal.uncertainty.is_none());
    // The observer saw one stage, every iteration and the start point, and how it ended.
    assert_eq!(log.stages, ["joint Levenberg-Marquardt"]);
    assert_eq!(log.iterations, cal.iterations + 1);
    assert_eq!(log.ended, [Termination::Converged]);
    assert_eq!(log.progress.last(), Some(&(1, 1)));
    // The recorded objective is the solver's: the start, then one value per iteration.
    let c = &cal.convergence[0].objective;
    assert_eq!(c.len(), cal.iterations + 1);
    assert_eq!(c[c.len() - 1], cal.cost_after);
}

/// With several starts the convergence record, the iteration count and
/// the termination all belong to the start that won (here not start 0).
#[test]
fn several_starts_are_all_recorded_and_the_best_is_reported() {
    let model = leg();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let idx: Vec<usize> = free.iter().map(|id| id.0).collect();
    let nominal = model.nominal_params();
    let truth = perturb(&model, &nominal, &idx, 10.0, 5.0, 11);
    let trial = synthetic(&model, &truth, 30, 0.004);
    // A start 60 mm / 30° off that ends in a local minimum another start escapes. (Since
    // the joint solver holds parameters that its step pushes out of their bounds, 33 of 35
    // such starts, seeds 195–229, reach the best optimum alone; seed 201, used before, is
    // one of them.)
    let start = perturb(&model, &truth, &idx, 60.0, 30.0, 198);
    let settings = FitSettings {
        starts: 4,
        seed: 6,
        ..FitSettings::default()
    };
    let mut log = Log::default();
    let cal = calibrate(&model, &start, &[&trial], &free, &settings, &mut log).unwrap();
    assert_eq!(cal.start_runs.len(), 4);
    let best = cal.best_start;
    assert_ne!(best, 0, "the case is chosen so that a moved start wins");
    let run = &cal.start_runs[best];
    assert!(cal.start_runs[0].objective > 1.2 * run.objective);
    // The panel's record is the winner's: its start point and one value per iteration.
    assert_eq!(cal.convergence[0].objective.len(), cal.iterations + 1);
    for r in &cal.start_runs {
        assert!(run.objective <= r.objective);
        let c = &r.convergence[0].objective;
        assert_eq!(c.len(), r.iterations + 1, "start {}", r.start);
        assert_eq!(c[c.len() - 1], r.objective);
    }
    assert_eq!(cal.convergence, run.convergence);
    assert_eq!(cal.iterations, run.iterations);
    assert_eq!(cal.evaluations, run.evaluations);
    assert_eq!(cal.termination, run.termination);
    // The same number: the solver's objective (m²).
    assert_eq!(run.objective, cal.cost_after);
    let ms = cal.multistart.as_ref().unwrap();
    let objectives: Vec<f64> = cal.start_runs.iter().map(|r| r.objective).collect();
    assert_eq!(ms.objective, objectives);
    assert_eq!(
        cal.start_runs.iter().map(|r| r.iterations).sum::<usize>(),
        log.iterations - 4
    );
    assert_eq!(log.stages.len(), 4);
    assert!(log.stages[3].starts_with("start 4 of 4"));
    // The same seed gives the same starts; another seed other starts.
    let again = calibrate(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap();
    assert_eq!(again.fit.p, cal.fit.p);
    assert_eq!(again.start_runs, cal.start_runs);
}

#[test]
fn restart_points_are_seeded_distinct_and_bounded() {
    let model = leg();
    let start = model.nominal_params();
    let free: Vec<usize> = (0..model.parameters().len()).collect();
    let a = restart_point(&model, &start, &free, 0.02, 10f64.to_radians(), 7, 1);
    assert_eq!(
        a,
        restart_point(&model, &start, &free, 0.02, 10f64.to_radians(), 7, 1)
    );
    assert_ne!(
        a,
        restart_point(&model, &start, &free, 0.02, 10f64.to_radians(), 7, 2)
    );
    assert_ne!(
        a,
        restart_point(&model, &start, &free, 0.02, 10f64.to_radians(), 8, 1)
    );
    for (i, par) in model.parameters().iter().enumerate() {
        let d = par.unit.to_display(a[i] - start[i]).abs();
        let limit = match par.unit {
            crate::model::spec::Unit::Metre => 20.0,
            crate::model::spec::Unit::Radian => 10.0,
        };
        assert!(d <= limit + 1e-9, "{}: {d}", par.name);
        assert!(par.lower <= a[i] && a[i] <= par.upper);
    }
}

/// A trial that moves only the knee cannot determine the hip and ankle parameters: with
/// `fix_unidentifiable` they are held at their start, the rest is fitted, and the analysis
/// covers exactly the parameters left free.
#[test]
fn unidentifiable_parameters_are_held_at_their_start() {
    let model = leg();
    let nominal = model.nominal_params();
    let mut kin = KinData::new(&model);
    let mut positions = Vec::new();
    for f in 0..40 {
        let mut q = model.default_coords();
        q[model.coord_id("pelvis_ty").unwrap()] = 0.95;
        q[model.coord_id("knee_flexion").unwrap()] = 0.2 + 1.2 * (f as f64 / 40.0);
        forward_kinematics(&model, &nominal, &q, Want::Positions, &mut kin);
        positions.extend(kin.markers.iter().copied());
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let trial = Trial::new(labels, 50.0, 1, positions).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let settings = FitSettings {
        uncertainty: Some(tests::five_mm_five_deg()),
        fix_unidentifiable: true,
        ..FitSettings::default()
    };
    let cal = calibrate(
        &model,
        &nominal,
        &[&trial],
        &free,
        &settings,
        &mut NoObserver,
    )
    .unwrap();
    assert!(!cal.fixed_unidentifiable.is_empty());
    assert_eq!(
        cal.free_parameters + cal.fixed_unidentifiable.len(),
        free.len()
    );
    let u = cal.uncertainty.as_ref().unwrap();
    assert_eq!(u.params.len(), cal.free_parameters);
    for name in &cal.fixed_unidentifiable {
        let i = model.param_id(name).unwrap().0;
        assert_eq!(cal.fit.p[i], nominal[i], "{name} held");
        assert!(cal.parameters.iter().all(|r| &r.name != name));
    }
    assert!(cal.parameters.iter().all(|r| r.identifiability.is_some()));
}

#[test]
fn predict_says_what_a_knee_only_trial_determines() {
    let model = leg();
    let p = model.nominal_params();
    let trial = synthetic(&model, &p, 40, 0.002);
    let free = params_for_groups(&model, &["knee"]).unwrap();
    let r = predict::predict(&model, &p, &[&trial], &free, &tests::five_mm_five_deg()).unwrap();
    assert_eq!(r.frames, 40);
    assert_eq!(
        r.determined.len() + r.not_determined.len(),
        r.prediction.params.len()
    );
    assert_eq!(r.prediction.params.len(), free.len());
    assert!(r.ik_rms > 5e-4 && r.ik_rms < 5e-3, "{} m", r.ik_rms);
}

#[test]
fn ik_trial_solves_every_frame_and_names_what_is_missing() {
    let model = leg();
    let p = model.nominal_params();
    let trial = synthetic(&model, &p, 20, 0.0);
    let run = ik_trial(&model, &p, &trial, &crate::ik::IkOptions::default()).unwrap();
    assert!(run.absent.is_empty());
    assert!(run.fit.frames.iter().all(|f| f.solved()));
    assert!((0..20).all(|f| crate::ik::trial_fit::rms(run.fit.errors[f].iter().copied()) < 1e-7));
    // A trial with none of the model's markers is an error, not an empty result.
    let other = Trial::new(vec!["X".into()], 50.0, 1, vec![Vector3::zeros(); 3]).unwrap();
    assert!(ik_trial(&model, &p, &other, &crate::ik::IkOptions::default()).is_err());
}

/// `seed_frame` starts the root's translations at their default values
/// (not at a centroid offset) and relies on the first iterations to carry them; a subject
/// tens of metres from the lab origin, turned about the vertical, is still found.
#[test]
fn seeding_finds_a_subject_far_from_the_origin() {
    let model = leg();
    let p = model.nominal_params();
    let near = synthetic(&model, &p, 10, 0.0);
    let turn = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), 2.5);
    let shift = Vector3::new(30.0, 0.0, -20.0);
    let far: Vec<Vector3<f64>> = near.positions().iter().map(|x| turn * x + shift).collect();
    let far = Trial::new(near.labels().to_vec(), 50.0, 1, far).unwrap();
    let opts = crate::ik::IkOptions::default();
    let mut ws = crate::ik::lm::IkWorkspace::new(&model);
    let map = crate::ik::MarkerMap::by_name(&model, far.labels()).unwrap();
    let mut targets = Vec::new();
    map.targets(&far, 0, &mut targets);
    let seed = crate::ik::seed_frame(&model, &p, &targets, &opts, &mut ws);
    let tx = model.coord_id("pelvis_tx").unwrap();
    // From the default 0 the seeding's iterations alone carry the pelvis 30 m.
    assert_eq!(model.default_coords()[tx], 0.0);
    assert!(
        (seed[tx] - 30.0).abs() < 0.05,
        "seeded pelvis_tx {}",
        seed[tx]
    );
    let run = ik_trial(&model, &p, &far, &opts).unwrap();
    for f in 0..10 {
        assert!(
            crate::ik::trial_fit::rms(run.fit.errors[f].iter().copied()) < 1e-7,
            "frame {f}: {}",
            crate::ik::trial_fit::rms(run.fit.errors[f].iter().copied())
        );
    }
}
