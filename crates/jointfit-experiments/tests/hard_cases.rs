//! The hard synthetic cases with the default (maximum a posteriori) fit.
//!
//! The subject is the generic leg moved by up to 30 mm / 15° (seeds from 7401, as `jointfit
//! synth --perturb-mm 30 --perturb-deg 15`), the trial a full-leg or ankle motion with 10 mm skin
//! artefact. The model the fit starts from is the subject's landmark model: the truth moved by
//! the landmark method's published error, which `personalize` writes as the prior
//! ([`landmark_model`]). Oracles: the known truth, and the unregularized fit (`--prior none`)
//! of the same trial from the same start. The example `coverage --default --compare-none
//! --landmark-error` runs the same cases over 200 seeds (`docs/identifiability.md`).

use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::population::{fill_landmark_priors, HipCentreMethod};
use jointfit::model::spec::ModelSpec;
use jointfit::model::spec::Unit;
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::workflow::calibration::calibrate;
use jointfit::workflow::refine::calibrate_refined;
use jointfit::workflow::{perturb, FitSettings};
use jointfit_experiments::subject::landmark_model;
use jointfit_experiments::synth::{coordinates, markers, Motion, SkinNoise};

const JOINTS: [&str; 3] = ["hip", "knee", "ankle"];

/// Over the seeds: squared errors per joint and unit (mm, deg) of the default fit and of the
/// unregularized one, the reported intervals covering the truth, and the joints the
/// prior–data conflict step flagged.
#[derive(Default)]
struct Outcome {
    sq: [[[f64; 2]; 3]; 2],
    n: [[usize; 2]; 3],
    intervals: usize,
    covered: usize,
    flagged: Vec<String>,
}

impl Outcome {
    /// RMS error of fit `f` (0 default, 1 `--prior none`), joint `g`, unit `u`.
    fn rms(&self, f: usize, g: usize, u: usize) -> f64 {
        (self.sq[f][g][u] / self.n[g][u].max(1) as f64).sqrt()
    }
}

/// `seeds` trials of `motion`; with `landmark`, the fit starts from (and its prior is centred
/// on) the subject's landmark model, else on the generic model.
fn run(spec: &ModelSpec, motion: Motion, seeds: u64, landmark: bool) -> Outcome {
    let model = Model::compile(spec).unwrap();
    let coords = coordinates(&model, motion, 100).unwrap();
    let free = params_for_groups(&model, &["all"]).unwrap();
    let every: Vec<usize> = (0..model.parameters().len()).collect();
    let mut out = Outcome::default();
    for seed in 7401..7401 + seeds {
        let truth = perturb(&model, &model.nominal_params(), &every, 30.0, 15.0, seed);
        let noise = SkinNoise {
            max_amplitude: 0.010,
            seed: 10_000 + seed,
            ..SkinNoise::default()
        };
        let (trial, _) = markers(&model, &truth, &coords, 50.0, Some(&noise));
        let (fit_model, start) = match landmark {
            true => {
                let (s, start) = landmark_model(spec, &truth, seed);
                (Model::compile(&s).unwrap(), start)
            }
            false => (model.clone(), model.nominal_params()),
        };
        let settings = FitSettings {
            seed,
            uncertainty: Some(UncertaintyOptions {
                seed,
                ..UncertaintyOptions::default()
            }),
            ..FitSettings::default()
        };
        let r = calibrate_refined(
            &fit_model,
            &start,
            &[&trial],
            &free,
            &settings,
            &mut NoObserver,
        )
        .unwrap();
        let none = FitSettings {
            seed,
            priors: false,
            uncertainty: None,
            ..FitSettings::default()
        };
        let plain =
            calibrate(&fit_model, &start, &[&trial], &free, &none, &mut NoObserver).unwrap();
        let u = r.calibration.uncertainty.as_ref().unwrap();
        for (k, id) in free.iter().enumerate() {
            let par = &model.parameters()[id.0];
            let g = JOINTS.iter().position(|j| *j == par.group).unwrap();
            let unit = (par.unit == Unit::Radian) as usize;
            for (f, p) in [&r.calibration.fit.p, &plain.fit.p].into_iter().enumerate() {
                let e = jointfit_experiments::units::shown(p[id.0] - truth[id.0], par.unit);
                out.sq[f][g][unit] += e * e;
            }
            out.n[g][unit] += 1;
            let err = jointfit_experiments::units::shown(
                r.calibration.fit.p[id.0] - truth[id.0],
                par.unit,
            );
            let half = u.params[k].half_width.unwrap();
            out.intervals += 1;
            out.covered += (err.abs() <= half) as usize;
        }
        out.flagged.extend(
            r.conflict
                .iter()
                .filter(|c| c.flagged)
                .map(|c| c.joint.clone()),
        );
    }
    out
}

fn leg() -> ModelSpec {
    let mut spec = lower_limb(Side::Right);
    fill_landmark_priors(&mut spec, HipCentreMethod::Bell);
    spec
}

/// The full-leg motion determines hip and knee; the prior must not pull them off, and it
/// must help the ankle, which the motion determines poorly. Intervals cover at about 95 %.
#[test]
fn full_leg_hard_cases_are_no_worse_with_the_landmark_prior() {
    let o = run(&leg(), Motion::All, 20, true);
    for (g, joint) in JOINTS.iter().enumerate() {
        for (u, unit) in ["mm", "deg"].iter().enumerate() {
            if o.n[g][u] == 0 {
                continue;
            }
            let (map, none) = (o.rms(0, g, u), o.rms(1, g, u));
            // Hip and knee: no worse, within the scatter of 20 seeds (these seeds: knee 2.19 /
            // 2.11 mm, 1.24 / 1.18°; 200 seeds: hip 3.51 / 4.14 mm, knee 2.28 / 2.29 mm,
            // 1.21 / 1.25°). The ankle, which the motion determines poorly: clearly better.
            let limit = if *joint == "ankle" { 0.8 } else { 1.1 };
            assert!(
                map <= limit * none,
                "{joint} {unit}: {map:.2} with the prior, {none:.2} without"
            );
        }
    }
    let coverage = o.covered as f64 / o.intervals as f64;
    assert!(
        (0.90..=0.99).contains(&coverage),
        "coverage {coverage:.3} of {}",
        o.intervals
    );
    assert!(o.flagged.len() <= 2, "conflict flagged {:?}", o.flagged);
}

/// The ankle motion leaves hip and knee to the prior: without it they wander tens of mm.
#[test]
fn ankle_hard_cases_hold_the_undetermined_joints_at_the_landmark_model() {
    let o = run(&leg(), Motion::Ankle, 20, true);
    for (g, joint) in JOINTS.iter().enumerate() {
        let (map, none) = (o.rms(0, g, 0), o.rms(1, g, 0));
        let limit = if *joint == "ankle" { 1.0 } else { 0.5 };
        assert!(
            map <= limit * none,
            "{joint} mm: {map:.2} with the prior, {none:.2} without"
        );
    }
    let coverage = o.covered as f64 / o.intervals as f64;
    assert!(
        (0.90..=0.99).contains(&coverage),
        "coverage {coverage:.3} of {}",
        o.intervals
    );
}

/// The contrast: a prior centred on the generic model (a landmark model off by two to three
/// of its SDs) pulls the determined knee off, and the conflict step says so.
#[test]
fn a_prior_centred_on_the_generic_model_is_flagged_on_the_hard_cases() {
    let o = run(&leg(), Motion::All, 20, false);
    let knee = JOINTS.iter().position(|j| *j == "knee").unwrap();
    assert!(
        o.rms(0, knee, 0) > 1.5 * o.rms(1, knee, 0),
        "the generic prior biases the knee"
    );
    let knees = o.flagged.iter().filter(|j| *j == "knee").count();
    assert!(
        knees >= 10,
        "knee flagged in {knees} of 20: {:?}",
        o.flagged
    );
}
