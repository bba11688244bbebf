//! `calibrate` with the model file's priors (the default) against `--prior none`, on the
//! shared OpenCap walking trial.

use jointfit_testkit::{scratch, ScratchDir};

use super::jointfit;

fn tmp(dir: &ScratchDir, name: &str) -> String {
    dir.join(name).display().to_string()
}

fn hip_shift(rep: &serde_json::Value) -> f64 {
    rep["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["name"].as_str().unwrap().starts_with("hip_pelvis_"))
        .map(|p| p["change"].as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn map_fit_holds_the_hip_closer_and_reports_where_information_came_from() {
    let dir = scratch("priors");
    let Some((model, walk)) = super::opencap_subject(&dir, "oc.toml") else {
        return;
    };
    let model = model.to_str().unwrap().to_string();
    let fit = |prior: &str, json: bool| {
        let out = tmp(&dir, &format!("fit-{prior}.toml"));
        let mut args = vec![
            "calibrate",
            &model,
            walk.to_str().unwrap(),
            "--filter",
            "6",
            "--prior",
            prior,
            "-o",
            &out,
        ];
        if json {
            args.push("--json");
        }
        let (ok, stdout, stderr) = jointfit(&args);
        assert!(ok, "{stderr}");
        (stdout, stderr, out)
    };
    let (map, _, map_out) = fit("model", true);
    let (plain, _, _) = fit("none", true);
    let map: serde_json::Value = serde_json::from_str(&map).unwrap();
    let plain: serde_json::Value = serde_json::from_str(&plain).unwrap();
    assert!(map["prior_noise_mm"].as_f64().unwrap() > 0.0);
    assert!(map["prior_noise_estimated"].as_bool().unwrap());
    assert!(plain["prior_noise_mm"].is_null());
    // The unregularized fit minimizes the marker term, so it fits the markers at least as
    // well; the MAP fit keeps the hip centre closer to the landmark estimate.
    let rms = |r: &serde_json::Value| r["rms_after_mm"].as_f64().unwrap();
    assert!(
        rms(&plain) <= rms(&map) + 1e-9,
        "{} vs {}",
        rms(&plain),
        rms(&map)
    );
    assert!(rms(&map) < 0.85 * map["rms_before_mm"].as_f64().unwrap());
    let (hm, hp) = (hip_shift(&map), hip_shift(&plain));
    assert!(
        hm < 0.8 * hp,
        "hip moved {hm:.1} mm with the prior, {hp:.1} without"
    );
    // Every parameter says where its information came from; shares lie in [0, 1].
    for p in map["parameters"].as_array().unwrap() {
        let share = p["data_share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share), "{p}");
        assert!(p["source"].is_string(), "{p}");
        assert!(p["prior_sd"].as_f64().unwrap() > 0.0);
    }
    assert!(plain["parameters"][0]["source"].is_null());
    // Plausibility is checked after both fits; the plain fit violates more.
    let bad = |r: &serde_json::Value| {
        r["plausibility"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|c| !c["ok"].as_bool().unwrap())
            .count()
    };
    assert!(map["plausibility"].as_array().unwrap().len() >= 5);
    assert!(bad(&map) < bad(&plain), "{} vs {}", bad(&map), bad(&plain));
    // The fitted model keeps the prior mean of the input (the landmark value).
    let fitted = std::fs::read_to_string(&map_out).unwrap();
    assert!(fitted.contains("prior_mean"), "{fitted}");
    // Text output: one summary instead of a warning per parameter.
    let (text, stderr, _) = fit("model", false);
    assert!(text.contains("maximum a posteriori fit"), "{text}");
    assert!(text.contains("determined by the trial: "), "{text}");
    assert!(!stderr.contains("poorly determined"), "{stderr}");
}

#[test]
fn bad_prior_overrides_are_one_line_errors() {
    for (arg, needle) in [
        ("knee=5", "needs a unit"),
        ("elbow=5mm", "no parameter or group"),
        ("knee", "expected NAME=VALUE"),
    ] {
        let dir = scratch("priors-bad");
        let out = tmp(&dir, "never.toml");
        let (ok, _, err) = jointfit(&[
            "calibrate",
            "lower-limb-right",
            "no-such-trial.trc",
            "--prior-sd",
            arg,
            "-o",
            &out,
        ]);
        assert!(!ok);
        assert!(err.contains(needle), "{arg}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}
