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
        if prior == "none" {
            // The unregularized fit puts this trial's ankle axis 30° off the landmark axis:
            // rejected as implausible unless kept on purpose.
            args.push("--accept-rejected");
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
    // The held-out criterion (a): the MAP hip centre stays medial to 0.9 × half the
    // inter-ASIS width (the unregularized one does not on this trial).
    let lateral_ok = |r: &serde_json::Value| {
        r["plausibility"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| {
                c["check"]
                    .as_str()
                    .unwrap()
                    .starts_with("hip centre lateral")
            })
            .unwrap()["ok"]
            .as_bool()
            .unwrap()
    };
    assert!(lateral_ok(&map), "{}", map["plausibility"]);
    assert!(!lateral_ok(&plain));
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

/// `--refine-markers` on real gait: the markers move (JSON names how far and which offsets
/// trade off with which joint parameters), the fitted TOML and its .osim export carry the
/// refined positions in the original segments, and the markers fit better.
#[test]
fn refined_markers_are_reported_and_carried_by_the_fitted_model() {
    let (Some(stat), Some(walk)) = (
        jointfit_testkit::data_file("opencap_expert1/static1.trc"),
        jointfit_testkit::data_file("opencap_expert1/walking1.trc"),
    ) else {
        return;
    };
    let dir = scratch("priors-refine");
    let model = tmp(&dir, "oc.toml");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        stat.to_str().unwrap(),
        "--markers",
        "opencap",
        "--side",
        "right",
        "-o",
        &model,
    ]);
    assert!(ok, "{err}");
    let fit = |extra: &[&str], name: &str| {
        let out = tmp(&dir, name);
        let mut args = vec![
            "calibrate",
            &model,
            walk.to_str().unwrap(),
            "--filter",
            "6",
            "--json",
            "-o",
            &out,
        ];
        args.extend_from_slice(extra);
        let (ok, stdout, stderr) = jointfit(&args);
        assert!(ok, "{stderr}");
        let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        (v, out)
    };
    let (plain, _) = fit(&[], "plain.toml");
    let (refined, out) = fit(
        &["--refine-markers", "--marker-prior-sd-mm", "10"],
        "ref.toml",
    );
    let moved = refined["refined_markers"].as_array().unwrap();
    assert!(moved.len() >= 10, "{moved:?}");
    assert!(moved.iter().any(|m| m["shift_mm"].as_f64().unwrap() > 1.0));
    let trade = refined["marker_trade_offs"].as_array().unwrap();
    assert!(!trade.is_empty());
    assert!(trade[0]["marker_parameter"]
        .as_str()
        .unwrap()
        .starts_with("marker_"));
    assert!(plain.get("refined_markers").is_none());
    let rms = |r: &serde_json::Value| r["rms_after_mm"].as_f64().unwrap();
    assert!(
        rms(&refined) < rms(&plain),
        "{} vs {}",
        rms(&refined),
        rms(&plain)
    );
    // The fitted model: same structure as the input, markers at the refined positions.
    let input = jointfit_io::model_file::load_spec(&model).unwrap();
    let fitted = jointfit_io::model_file::load_spec(&out).unwrap();
    assert_eq!(fitted.segments.len(), input.segments.len());
    assert_eq!(fitted.parameters.len(), input.parameters.len());
    let biggest = moved
        .iter()
        .max_by(|a, b| {
            a["shift_mm"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["shift_mm"].as_f64().unwrap())
        })
        .unwrap();
    let name = biggest["name"].as_str().unwrap();
    let m = fitted.markers.iter().find(|m| m.name == name).unwrap();
    let m0 = input.markers.iter().find(|m| m.name == name).unwrap();
    assert_eq!(m.segment, m0.segment);
    for k in 0..3 {
        let want = biggest["fitted_mm"][k].as_f64().unwrap();
        assert!((m.position[k] * 1e3 - want).abs() < 1e-6, "{name} {k}");
    }
    // The .osim export carries the refined position.
    let osim = dir.join("ref.osim");
    let (ok, _, err) = jointfit(&["export", "osim", &out, "-o", osim.to_str().unwrap()]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&osim).unwrap();
    let at = text.find(&format!("<Marker name=\"{name}\">")).unwrap();
    let block = &text[at..at + text[at..].find("</Marker>").unwrap()];
    let loc = block.split("<location>").nth(1).unwrap();
    let loc = &loc[..loc.find("</location>").unwrap()];
    let xyz: Vec<f64> = loc.split_whitespace().map(|v| v.parse().unwrap()).collect();
    for (v, want) in xyz.iter().zip(m.position) {
        assert!((v - want).abs() < 1e-9, "{loc} vs {:?}", m.position);
    }
}
