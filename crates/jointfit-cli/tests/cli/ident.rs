//! `jointfit check` and the uncertainty columns and warnings of `jointfit calibrate`
//! on synthetic trials written as TRC files.

use std::path::{Path, PathBuf};

use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion, SkinNoise};
use jointfit_io::trc::{write_trc, TrcWriteOptions};

use super::jointfit;
use jointfit_testkit::ScratchDir;

/// A synthetic trial of `motion` (true parameters perturbed from nominal, skin noise up to
/// 10 mm) written to `dir`; returns the path.
fn trial(dir: &Path, motion: Motion, seed: u64) -> PathBuf {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let truth = perturbed_params(&model, 0.3, seed);
    let coords = coordinates(&model, motion, 100).unwrap();
    let noise = SkinNoise {
        seed,
        ..SkinNoise::default()
    };
    let (t, _) = markers(&model, &truth, &coords, 50.0, Some(&noise));
    let path = dir.join(format!("{motion:?}-{seed}.trc"));
    write_trc(&path, &t, &TrcWriteOptions::default()).unwrap();
    path
}

fn tmp(name: &str) -> ScratchDir {
    jointfit_testkit::scratch(&format!("ident-{name}"))
}

#[test]
fn check_predicts_the_knee_only_trial_cannot_place_the_hip() {
    let dir = tmp("check");
    let knee = trial(&dir, Motion::Knee, 3);
    // With the skin noise level given (sinusoids up to 10 mm per axis: ≈ 4 mm RMS).
    let (ok, out, err) = jointfit(&[
        "check",
        "lower-limb-right",
        knee.to_str().unwrap(),
        "--joints",
        "hip,knee",
        "--noise-mm",
        "4",
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    let names = |key: &str| -> Vec<String> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap().to_string())
            .collect()
    };
    let (det, not) = (names("determined"), names("not_determined"));
    for p in v["prediction"]["params"].as_array().unwrap() {
        if p["group"] == "hip" {
            assert!(
                not.contains(&p["name"].as_str().unwrap().to_string()),
                "{p}"
            );
            assert!(
                p["half_width"].as_f64().unwrap_or(f64::INFINITY) > 20.0,
                "{p}"
            );
        }
    }
    assert!(
        det.iter().filter(|n| n.starts_with("knee")).count() >= 5,
        "a knee flexion trial determines most knee parameters: {det:?}"
    );
    let range = |name: &str| {
        v["ranges"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["name"] == name)
            .unwrap()["range"]
            .as_f64()
            .unwrap()
    };
    assert!(range("knee_flexion") > 60.0);
    // The hip does not move in the synthetic trial; IK with the (wrong) nominal knee shows a
    // few degrees of apparent hip motion, far below a circumduction's.
    assert!(range("hip_adduction") < 10.0);
    // The table form names the reason.
    let (ok, out, _) = jointfit(&[
        "check",
        "lower-limb-right",
        knee.to_str().unwrap(),
        "--joints",
        "hip,knee",
    ]);
    assert!(ok);
    assert!(out.contains("circumduction"), "{out}");
    // The table prints the half-width the status is judged by ("trial alone ±") beside the
    // interval's, and says which decides: every "yes" is within the 5 mm / 5° threshold in
    // that column, every "POOR" beyond it (the interval column alone looked contradictory).
    assert!(
        out.contains("trial alone ±") && out.contains("compares"),
        "{out}"
    );
    let mut rows = 0;
    for line in out.lines() {
        let cols: Vec<&str> = line.split_whitespace().collect();
        if cols.len() != 6 || !["yes", "POOR", "NO"].contains(&cols[5]) {
            continue;
        }
        rows += 1;
        let decides: f64 = cols[4].parse().unwrap_or(f64::INFINITY);
        match cols[5] {
            "yes" => assert!(decides <= 5.0, "{line}"),
            _ => assert!(decides > 5.0, "{line}"),
        }
    }
    assert!(rows >= 10, "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn calibrate_reports_intervals_warns_and_fixes_the_unidentifiable() {
    let dir = tmp("calibrate");
    let knee = trial(&dir, Motion::Knee, 4);
    let out_model = dir.join("fitted.toml");
    let (ok, out, err) = jointfit(&[
        "calibrate",
        "lower-limb-right",
        knee.to_str().unwrap(),
        "--joints",
        "hip,knee",
        "-o",
        out_model.to_str().unwrap(),
        // A knee trial leaves the hip free to wander far from any anatomy: kept on purpose.
        "--accept-rejected",
        "--verbose",
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("±95%") && out.contains("95% CI"), "{out}");
    assert!(
        out.contains("hip_thigh_superior poorly determined by this trial")
            || out.contains("hip_thigh_superior not determined by this trial"),
        "{out}"
    );
    assert!(out.contains("would determine it"), "{out}");
    assert!(out.contains("verdict: reject\n"), "{out}");
    assert!(out.contains("--fix-unidentifiable"), "{out}");
    let (ok, out, err) = jointfit(&[
        "calibrate",
        "lower-limb-right",
        knee.to_str().unwrap(),
        "--joints",
        "hip,knee",
        "--fix-unidentifiable",
        "--json",
        "-o",
        out_model.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    let fixed: Vec<&str> = v["fixed_unidentifiable"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    assert!(
        fixed.iter().filter(|n| n.starts_with("hip")).count() >= 3,
        "{fixed:?}"
    );
    assert_eq!(
        v["parameters"].as_array().unwrap().len() + fixed.len(),
        15,
        "fixed parameters are no longer free"
    );
    // After the refits the remaining parameters have finite intervals around the fit.
    for p in v["parameters"].as_array().unwrap() {
        assert!(!fixed.contains(&p["name"].as_str().unwrap()));
        let ci = p["ci95"].as_array().unwrap();
        let (lo, hi, x) = (
            ci[0].as_f64().unwrap(),
            ci[1].as_f64().unwrap(),
            p["fitted"].as_f64().unwrap(),
        );
        assert!(lo < x && x < hi, "{p}");
    }
    let u = &v["uncertainty"];
    assert!(u["corr"].as_array().unwrap().len() == v["parameters"].as_array().unwrap().len());
    assert!(u["sigma_mm"].as_f64().unwrap() > 0.5);
    std::fs::remove_dir_all(&dir).unwrap();
}
