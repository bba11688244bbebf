//! Joints a trial barely moves ([`super::motion_range`]): on a bilateral model
//! and a synthetic one-sided trial (the right leg exercised, the left standing with small
//! known sways), the left joints are found with their true ranges of motion and held at their
//! start values by the calibration, which fits the right leg and says so in one line.

use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::lower_limb::bilateral::bilateral;
use crate::model::Model;
use crate::solver::NoObserver;
use crate::trial::Trial;
use crate::workflow::motion_range::{
    hold_still_joints, HeldJoint, MOVED_RANGE_DEG, STILL_RANGE_DEG,
};
use crate::workflow::redundant::calibrate_holding_redundant;
use crate::workflow::refine::calibrate_refined;
use crate::workflow::FitSettings;

/// (coordinate, mean, amplitude) in rad: sinusoids at 1 Hz over two whole periods.
const MOTION: &[(&str, f64, f64)] = &[
    ("hip_flexion_r", 0.3, 0.45),
    ("hip_adduction_r", 0.0, 0.1),
    ("knee_flexion_r", 0.6, 0.55),
    ("ankle_dorsiflexion_r", 0.0, 0.3),
    ("subtalar_inversion_r", 0.0, 0.35),
    ("hip_flexion_l", 0.1, 0.03),
    ("hip_adduction_l", 0.0, 0.02),
    ("knee_flexion_l", 0.1, 0.05),
    ("ankle_dorsiflexion_l", 0.0, 0.04),
    ("subtalar_inversion_l", 0.0, 0.06),
];

fn one_sided_trial(model: &Model, p: &[f64]) -> Trial {
    let w = 2.0 * std::f64::consts::PI;
    let motion = |f: usize| {
        let t = f as f64 / 100.0;
        let mut q = model.default_coords();
        q[model.coord_id("pelvis_ty").unwrap()] = 0.93;
        for (k, (name, mean, amp)) in MOTION.iter().enumerate() {
            q[model.coord_id(name).unwrap()] = mean + amp * (w * t + 0.4 * k as f64).sin();
        }
        q
    };
    // Noise-free markers: the model's at each frame's coordinates, 100 Hz.
    let mut kin = KinData::new(model);
    let mut positions = Vec::with_capacity(200 * model.markers().len());
    for f in 0..200 {
        forward_kinematics(model, p, &motion(f), Want::Positions, &mut kin);
        positions.extend_from_slice(&kin.markers);
    }
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    Trial::new(labels, 100.0, 1, positions).unwrap()
}

/// The 5–95 % range of `A sin` sampled evenly over whole periods (deg): 2 A sin(0.45 π).
fn sine_range_deg(amp: f64) -> f64 {
    (2.0 * amp * (0.45 * std::f64::consts::PI).sin()).to_degrees()
}

fn amplitude(coord: &str) -> f64 {
    MOTION.iter().find(|m| m.0 == coord).unwrap().2
}

#[test]
fn the_standing_legs_joints_are_found_with_their_ranges() {
    let model = Model::compile(&bilateral()).unwrap();
    let p = model.nominal_params();
    let trial = one_sided_trial(&model, &p);
    let free: Vec<_> = (0..model.parameters().len())
        .map(crate::model::ParamId)
        .collect();
    let (kept, held, seed) = hold_still_joints(&model, &p, &[&trial], &free, &|_, _| None).unwrap();
    // The coordinates it solved are the calibration's starting ones for the parameters it
    // keeps, bit for bit (the calibration starts from them instead of solving them again).
    let prob = crate::calibrate::Problem::new(&model, p.clone(), &kept, &[&trial]).unwrap();
    let again = prob.initial_coords(&p);
    let bits = |q: &[Vec<f64>]| -> Vec<u64> { q.iter().flatten().map(|v| v.to_bits()).collect() };
    assert_eq!(bits(seed.as_deref().unwrap()), bits(&again));
    let names: Vec<&str> = held.iter().map(|h| h.joint.as_str()).collect();
    assert_eq!(names, ["hip_l", "knee_l", "talocrural_l", "subtalar_l"]);
    let want = |h: &HeldJoint| match h.joint.as_str() {
        "hip_l" => sine_range_deg(amplitude("hip_flexion_l")),
        "knee_l" => sine_range_deg(amplitude("knee_flexion_l")),
        "talocrural_l" => sine_range_deg(amplitude("ankle_dorsiflexion_l")),
        _ => sine_range_deg(amplitude("subtalar_inversion_l")),
    };
    for h in &held {
        // Noise-free markers: inverse kinematics returns the true angles; 200 samples of two
        // periods put the quantiles within 0.1° of the continuous ones.
        assert!(
            (h.range.to_degrees() - want(h)).abs() < 0.1,
            "{h:?} against {}",
            want(h)
        );
        assert!(
            h.range < STILL_RANGE_DEG.to_radians() && h.other_range >= MOVED_RANGE_DEG.to_radians()
        );
        assert!(!h.parameters.is_empty());
    }
    // Every left-leg parameter is held, every right-leg one kept.
    for id in &free {
        let name = &model.parameters()[id.0].name;
        assert_eq!(kept.contains(id), name.ends_with("_r"), "{name}");
    }
}

#[test]
fn the_calibration_holds_them_and_fits_the_moving_leg() {
    let model = Model::compile(&bilateral()).unwrap();
    let truth = model.nominal_params();
    let trial = one_sided_trial(&model, &truth);
    // The start: the right knee 10 mm and 4° off; the left one true.
    let mut start = truth.clone();
    for (name, d) in [
        ("knee_thigh_anterior_r", 0.01),
        ("knee_thigh_frontal_r", 0.07),
    ] {
        start[model.param_id(name).unwrap().0] += d;
    }
    let free: Vec<_> = model
        .params_in_group("knee_r")
        .into_iter()
        .chain(model.params_in_group("knee_l"))
        .collect();
    assert!(!free.is_empty(), "groups: {:?}", model.groups());
    let settings = FitSettings {
        probes: 0,
        ..FitSettings::default()
    };
    let fit =
        calibrate_refined(&model, &start, &[&trial], &free, &settings, &mut NoObserver).unwrap();
    let cal = &fit.calibration;
    let names: Vec<&str> = fit.held_joints.iter().map(|h| h.joint.as_str()).collect();
    assert_eq!(names, ["knee_l"]);
    // Held: exactly at the start, and not among the fitted rows.
    for id in &free {
        let par = &model.parameters()[id.0];
        let row = cal.parameters.iter().find(|r| r.name == par.name);
        if par.name.ends_with("_l") {
            assert_eq!(cal.fit.p[id.0], start[id.0], "{}", par.name);
            assert!(row.is_none(), "{} is not fitted", par.name);
        } else {
            assert!(row.is_some(), "{} is fitted", par.name);
        }
    }
    // The moving knee is fitted: the start's misfit is gone (noise-free markers).
    assert!(
        cal.rms_before > 1e-3 && cal.rms_after < 5e-5,
        "{} -> {} m",
        cal.rms_before,
        cal.rms_after
    );
    // One line of the verdict names the joint, its range and the threshold.
    let line = cal
        .verdict
        .reasons
        .iter()
        .find(|r| r.starts_with("held knee_l"))
        .unwrap_or_else(|| panic!("{:?}", cal.verdict));
    let said: f64 = line
        .split("moved knee_l ")
        .nth(1)
        .and_then(|rest| rest.split('°').next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    let want = sine_range_deg(amplitude("knee_flexion_l"));
    assert!((said - want).abs() < 0.15, "{line} against {want}");
    assert!(line.contains("below 15°"), "{line}");
}

/// The path of a user's OpenSim model ([`calibrate_holding_redundant`]) holds the standing
/// leg's joints the same way: exactly at the start, not fitted, said in the verdict.
#[test]
fn the_osim_path_holds_them_too() {
    let model = Model::compile(&bilateral()).unwrap();
    let truth = model.nominal_params();
    let trial = one_sided_trial(&model, &truth);
    let free: Vec<_> = model
        .params_in_group("knee_r")
        .into_iter()
        .chain(model.params_in_group("knee_l"))
        .collect();
    let settings = FitSettings {
        probes: 0,
        ..FitSettings::default()
    };
    let fit =
        calibrate_holding_redundant(&model, &truth, &[&trial], &free, &settings, &mut NoObserver)
            .unwrap();
    let names: Vec<&str> = fit.held_joints.iter().map(|h| h.joint.as_str()).collect();
    assert_eq!(names, ["knee_l"]);
    for id in &free {
        let name = &model.parameters()[id.0].name;
        let fitted = fit.calibration.parameters.iter().any(|r| &r.name == name);
        assert_eq!(fitted, !name.ends_with("_l"), "{name}");
        if name.ends_with("_l") {
            assert_eq!(fit.calibration.fit.p[id.0], truth[id.0], "{name}");
        }
    }
    assert!(
        fit.calibration
            .verdict
            .reasons
            .iter()
            .any(|r| r.starts_with("held knee_l")),
        "{:?}",
        fit.calibration.verdict
    );
}
