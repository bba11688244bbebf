//! The prior–data conflict step end to end (`workflow::conflict`), on a jointfit model and on
//! an OpenSim model: one record per joint in JSON, a joint rejected at p < 0.01 flagged with
//! its intervals widened by τ and the estimate unchanged, one text line per flagged joint;
//! `--no-prior-conflict` runs without it.

use std::collections::HashMap;

use serde_json::Value;

use super::jointfit;

/// `calibrate` with `args` (ending in `-o OUT`) plus `extra`; its stdout.
fn run(args: &[&str], extra: &[&str]) -> String {
    let mut all = args.to_vec();
    all.extend_from_slice(extra);
    let (ok, stdout, stderr) = jointfit(&all);
    assert!(ok, "{stderr}");
    stdout
}

/// Fitted value and SE by parameter name.
fn params(r: &Value) -> HashMap<String, (f64, f64)> {
    r["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let name = p["name"].as_str().unwrap().to_string();
            (
                name,
                (p["fitted"].as_f64().unwrap(), p["se"].as_f64().unwrap()),
            )
        })
        .collect()
}

/// Runs `args` with and without the step and checks the step's contract; the joints
/// (in order) and the flagged ones.
fn check_step(args: &[&str]) -> (Vec<String>, Vec<String>) {
    let with: Value = serde_json::from_str(&run(args, &["--json"])).unwrap();
    let without: Value =
        serde_json::from_str(&run(args, &["--json", "--no-prior-conflict"])).unwrap();
    let joints = with["prior_conflict"].as_array().expect("prior_conflict");
    assert!(without["prior_conflict"]
        .as_array()
        .is_none_or(|a| a.is_empty()));
    let (pw, po) = (params(&with), params(&without));
    let mut flagged = Vec::new();
    for j in joints {
        let (chi2, p, tau) = (
            j["chi2"].as_f64().unwrap(),
            j["p_value"].as_f64().unwrap(),
            j["tau"].as_f64().unwrap(),
        );
        let members = j["parameters"].as_array().unwrap();
        assert!(j["dof"].as_u64().unwrap() as usize <= members.len(), "{j}");
        assert!(chi2 >= 0.0 && (0.0..=1.0).contains(&p) && tau >= 1.0, "{j}");
        let is_flagged = j["flagged"].as_bool().unwrap();
        assert_eq!(is_flagged, p < 0.01, "{j}");
        let scale = j["interval_scale"].as_f64().unwrap();
        assert_eq!(scale, if is_flagged { tau } else { 1.0 }, "{j}");
        for m in members {
            let m = m.as_str().unwrap();
            // The estimate keeps the stated prior.
            assert_eq!(pw[m].0, po[m].0, "{m}");
            if is_flagged && tau > 1.01 {
                assert!(pw[m].1 > po[m].1, "{m}: {} vs {}", pw[m].1, po[m].1);
            }
        }
        if is_flagged {
            flagged.push(j["joint"].as_str().unwrap().to_string());
        }
    }
    // (A flagged joint's wider prior also moves the intervals of the parameters correlated
    // with it; with no joint flagged the step changes nothing.)
    if flagged.is_empty() {
        assert_eq!(with["parameters"], without["parameters"]);
    }
    let text = run(args, &[]);
    for joint in &flagged {
        let line = format!("prior–data conflict at the {joint}: intervals widened");
        assert_eq!(text.matches(&line).count(), 1, "{text}");
    }
    assert_eq!(
        text.matches("prior–data conflict at the").count(),
        flagged.len(),
        "{text}"
    );
    assert!(!run(args, &["--no-prior-conflict"]).contains("prior–data conflict"));
    let names = joints
        .iter()
        .map(|j| j["joint"].as_str().unwrap().to_string())
        .collect();
    (names, flagged)
}

#[test]
fn prior_data_conflict_widens_only_the_flagged_joints_intervals() {
    let dir = jointfit_testkit::scratch("priors-conflict");
    let Some((model, walk)) = super::opencap_subject(&dir, "oc.toml") else {
        return;
    };
    let out = dir.join("fit.toml").display().to_string();
    let (model, walk) = (model.to_str().unwrap(), walk.to_str().unwrap());
    let args = ["calibrate", model, walk, "--filter", "6", "-o", &out];
    let (joints, flagged) = check_step(&args);
    assert_eq!(joints, ["hip", "knee", "talocrural", "subtalar"]);
    // The shared walking1 contradicts the landmark hip (χ² ≈ 20 on 6 dof; notebook/gait_table.md).
    assert!(flagged.contains(&"hip".to_string()), "{flagged:?}");
}

/// The OpenSim-model calibration takes the same step, per joint of the file and per side.
/// On the hand-scaled OpenCap model and squats1 the right knee's offsets are far from the
/// file's (χ² ≈ 49 on 9 dof), the other three joints are not flagged. (On walking1 the left
/// knee was flagged, χ² ≈ 110, while the joint solver let the clamped knee angle leave its
/// range; kept inside it, the trial agrees with the file there: χ² ≈ 14 on 8 dof.)
#[test]
fn osim_calibration_takes_the_conflict_step_per_joint_of_the_file() {
    let (Some(model), Some(walk)) = (
        jointfit_testkit::data_file("opencap_expert1/hand_scaled.osim"),
        jointfit_testkit::data_file("opencap_expert1/squats1.trc"),
    ) else {
        assert!(!jointfit_testkit::in_ci(), "CI needs $JOINTFIT_DATA");
        eprintln!("skipped: no data");
        return;
    };
    let dir = jointfit_testkit::scratch("osim-conflict");
    let out = dir.join("fit.osim").display().to_string();
    let (model, walk) = (model.to_str().unwrap(), walk.to_str().unwrap());
    let joints = "hip_r,walker_knee_r,hip_l,walker_knee_l";
    let args = ["calibrate", model, walk, "--joints", joints, "-o", &out];
    let (names, flagged) = check_step(&args);
    assert_eq!(names, ["hip_r", "walker_knee_r", "hip_l", "walker_knee_l"]);
    assert_eq!(flagged, ["walker_knee_r"]);
}
