//! `jointfit synth` and `jointfit reproduce`: the known synthetic truth is the oracle.

use jointfit::model::spec::Unit;
use jointfit::model::Model;
use jointfit_testkit::data_dir;

use super::jointfit;
use jointfit_testkit::ScratchDir;

fn tmp(tag: &str) -> ScratchDir {
    jointfit_testkit::scratch(&format!("synth-{tag}"))
}

fn load(path: &std::path::Path) -> Model {
    jointfit_io::model_file::load_model(path.to_str().unwrap()).unwrap()
}

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

/// Noiseless synth with a perturbed truth, then calibrate from the subject's nominal values:
/// every parameter of the truth file comes back to 1e-6 mm / 1e-6 deg, through the TRC file.
#[test]
fn synth_then_calibrate_recovers_the_truth_file() {
    let dir = tmp("roundtrip");
    let (trc, truth, fitted) = (dir.join("m.trc"), dir.join("t.toml"), dir.join("f.toml"));
    let (ok, out, err) = jointfit(&[
        "synth",
        "lower-limb-right",
        "--motion",
        "all",
        "--noise",
        "none",
        "--seed",
        "3",
        "--perturb-mm",
        "10",
        "--perturb-deg",
        "5",
        "-o",
        s(&trc),
        "--truth",
        s(&truth),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["frames"], 50);
    assert_eq!(v["noise_rms_3d_mm"], 0.0);
    let (ok, _, err) = jointfit(&["calibrate", "lower-limb-right", s(&trc), "-o", s(&fitted)]);
    assert!(ok, "{err}");
    let (t, f) = (load(&truth), load(&fitted));
    let nominal = Model::compile(&jointfit::model::lower_limb::lower_limb(
        jointfit::model::lower_limb::Side::Right,
    ))
    .unwrap();
    let mut moved = 0.0f64;
    for ((a, b), n) in t
        .parameters()
        .iter()
        .zip(f.parameters())
        .zip(nominal.parameters())
    {
        assert_eq!(a.name, b.name);
        let k = match a.unit {
            Unit::Metre => 1e3,
            Unit::Radian => 180.0 / std::f64::consts::PI,
        };
        let e = (a.nominal - b.nominal).abs() * k;
        assert!(e <= 1e-6, "{}: {e:e}", a.name);
        moved = moved.max((a.nominal - n.nominal).abs() * k);
    }
    assert!(moved > 2.0, "the truth must differ from the start: {moved}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Skin noise is reported per axis and in 3-D; white noise of σ = 2 mm shows σ per axis;
/// without perturbation the truth file carries the subject's nominal values.
#[test]
fn synth_noise_is_reported() {
    let dir = tmp("noise");
    let (trc, truth) = (dir.join("m.trc"), dir.join("t.toml"));
    let (ok, out, err) = jointfit(&[
        "synth",
        "lower-limb-left",
        "--motion",
        "knee",
        "--noise",
        "skin",
        "--seed",
        "4",
        "-o",
        s(&trc),
        "--truth",
        s(&truth),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let r3 = v["noise_rms_3d_mm"].as_f64().unwrap();
    assert!((4.0..10.0).contains(&r3), "{v}");
    let axes: Vec<f64> = (0..3)
        .map(|k| v["noise_rms_axis_mm"][k].as_f64().unwrap())
        .collect();
    assert!((axes.iter().map(|a| a * a).sum::<f64>().sqrt() - r3).abs() < 1e-9);
    assert!(v["noise_max_axis_mm"].as_f64().unwrap() <= 10.0);
    let t = load(&truth);
    let left = Model::compile(&jointfit::model::lower_limb::lower_limb(
        jointfit::model::lower_limb::Side::Left,
    ))
    .unwrap();
    assert_eq!(t.nominal_params(), left.nominal_params());
    let trial = jointfit_io::trc::read_trc(&trc).unwrap();
    assert_eq!(trial.n_frames(), 50);
    assert_eq!(trial.labels().len(), left.markers().len());

    let (ok, out, err) = jointfit(&[
        "synth",
        "lower-limb-right",
        "--motion",
        "hip",
        "--noise",
        "white",
        "--white-mm",
        "2",
        "--frames",
        "400",
        "-o",
        s(&trc),
        "--truth",
        s(&truth),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for k in 0..3 {
        let a = v["noise_rms_axis_mm"][k].as_f64().unwrap();
        assert!((a - 2.0).abs() < 0.15, "{v}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn synth_errors_are_one_line_and_name_the_culprit() {
    let dir = tmp("errors");
    let (trc, truth) = (dir.join("m.trc"), dir.join("t.toml"));
    let cases: [(&[&str], &str); 4] = [
        (&["--motion", "elbow"], "unknown motion \"elbow\""),
        (&["--motion", "gait:/no/such/walk.trc"], "/no/such/walk.trc"),
        (&["--rate", "0"], "--rate"),
        (&["--perturb-mm=-1"], "--perturb-mm"),
    ];
    for (extra, needle) in cases {
        let mut args = vec![
            "synth",
            "lower-limb-right",
            "-o",
            s(&trc),
            "--truth",
            s(&truth),
        ];
        args.extend_from_slice(extra);
        let (ok, out, err) = jointfit(&args);
        assert!(!ok, "{extra:?}");
        assert!(out.is_empty(), "{out}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with("jointfit: error: ") && err.contains(needle),
            "{err}"
        );
    }
    assert!(!trc.exists() && !truth.exists(), "nothing written on error");
    let (ok, _, err) = jointfit(&[
        "synth",
        "no-such-model",
        "-o",
        s(&trc),
        "--truth",
        s(&truth),
    ]);
    assert!(!ok && err.contains("no-such-model"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A small synthetic Table 1: the three files, parseable, with exact noiseless recovery and
/// noisy fits below the truth's cost.
#[test]
fn reproduce_table1_synthetic_only() {
    let dir = tmp("t1");
    let (ok, out, err) = jointfit(&[
        "reproduce",
        "table1",
        "--synthetic-only",
        "--seeds",
        "2",
        "--starts",
        "2",
        "--frames",
        "30",
        "-o",
        s(&dir),
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("| synthetic without noise | marker distances (mm) |"),
        "{out}"
    );
    assert!(
        out.contains("Outer optimizer: joint (2 starts per fit)"),
        "{out}"
    );
    for ext in ["md", "json", "csv"] {
        assert!(dir.join(format!("table1.{ext}")).is_file());
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("table1.json")).unwrap()).unwrap();
    let cols = v["synthetic"].as_array().unwrap();
    assert_eq!(cols.len(), 4);
    assert_eq!(v["settings"]["seeds"], 2);
    assert!(v["version"].is_string());
    for c in cols {
        let n = &c["noiseless"];
        assert!(n["marker_rms_mm"].as_f64().unwrap() <= 1e-6, "{c}");
        assert!(n["position_rms_mm"].as_f64().unwrap() <= 1e-6, "{c}");
        for r in c["noisy"].as_array().unwrap() {
            assert!(r["cost_fit"].as_f64() < r["cost_truth"].as_f64(), "{r}");
        }
    }
    let csv = std::fs::read_to_string(dir.join("table1.csv")).unwrap();
    assert!(csv.starts_with("table,data,column,quantity,statistic,ours,paper\n"));
    assert!(csv.contains("1,synthetic with noise,Ankle only,orientation_deg,mean,"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn reproduce_names_missing_data() {
    let dir = tmp("nodata");
    let (ok, _, err) = jointfit(&[
        "reproduce",
        "table1",
        "--data",
        "/no/such/data",
        "-o",
        s(&dir),
    ]);
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("/no/such/data") && err.contains("--synthetic-only"),
        "{err}"
    );
    assert!(
        err.contains("biobuddy_functional_vicon/Test_func_rhip.c3d"),
        "{err}"
    );
    // A data directory that lacks some files: each missing file is named.
    let partial = dir.join("data");
    std::fs::create_dir_all(partial.join("opencap_expert1")).unwrap();
    std::fs::write(partial.join("opencap_expert1/static1.trc"), "").unwrap();
    let (ok, _, err) = jointfit(&["reproduce", "table2", "--data", s(&partial), "-o", s(&dir)]);
    assert!(!ok);
    assert!(err.contains("opencap_expert1/walking1.trc"), "{err}");
    assert!(!err.contains("opencap_expert1/static1.trc"), "{err}");
    assert!(!dir.join("table2.md").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The gait motion: IK of a real walking trial with the subject's model, replayed without
/// noise; calibrating the subject on it recovers the (perturbed) truth.
#[test]
fn synth_gait_from_a_real_trial() {
    let dir = tmp("gait");
    let Some((subject, walk)) = super::opencap_subject(&dir, "subject.toml") else {
        return;
    };
    let (trc, truth, fitted) = (dir.join("g.trc"), dir.join("t.toml"), dir.join("f.toml"));
    let motion = format!("gait:{}", s(&walk));
    let (ok, out, err) = jointfit(&[
        "synth",
        s(&subject),
        "--motion",
        &motion,
        "--filter",
        "6",
        "--perturb-mm",
        "5",
        "--perturb-deg",
        "3",
        "-o",
        s(&trc),
        "--truth",
        s(&truth),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["rate_hz"], 100.0);
    assert!(v["frames"].as_u64().unwrap() >= 140, "{v}");
    // The paper's unregularized fit (the default MAP fit holds toward the landmark priors).
    let (ok, _, err) = jointfit(&[
        "calibrate",
        s(&subject),
        s(&trc),
        "--prior",
        "none",
        "-o",
        s(&fitted),
    ]);
    assert!(ok, "{err}");
    let (t, f) = (load(&truth), load(&fitted));
    let worst = t
        .parameters()
        .iter()
        .zip(f.parameters())
        .map(|(a, b)| (a.nominal - b.nominal).abs())
        .fold(0.0, f64::max);
    // Gait exercises some axes little (the paper's point), but without noise the optimum is
    // still the truth.
    assert!(worst < 1e-6, "worst parameter error {worst:e} (m or rad)");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Table 2 from the shared data: 27 rows per subject, landmark column = personalized model.
#[test]
fn reproduce_table2_with_data() {
    let Some(data) = data_dir() else {
        return;
    };
    let dir = tmp("t2");
    // Every 8th frame keeps the debug-build test short; the full run is `reproduce table2`.
    let (ok, _, err) = jointfit(&[
        "reproduce",
        "table2",
        "--stride",
        "8",
        "--starts",
        "1",
        "--data",
        s(&data),
        "-o",
        s(&dir),
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("table2.json")).unwrap()).unwrap();
    let t2 = v["table2"].as_array().unwrap();
    assert_eq!(t2.len(), 2);
    for t in t2 {
        let rows = t["rows"].as_array().unwrap();
        assert_eq!(rows.len(), 27);
        // The fitted hip centre in the pelvis moved but stayed plausible (mm).
        let lateral = rows[2][2][2].as_f64().unwrap();
        assert!((60.0..180.0).contains(&lateral), "{t}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Every option and value the help lists has a description: `synth --noise none` and
/// `reproduce --first-seed` had none.
#[test]
fn help_describes_noise_none_and_first_seed() {
    let (ok, out, err) = jointfit(&["synth", "--help"]);
    assert!(ok, "{err}");
    assert!(out.contains("none:") && out.contains("No noise"), "{out}");
    let (ok, out, err) = jointfit(&["reproduce", "--help"]);
    assert!(ok, "{err}");
    let at = out.find("--first-seed").unwrap();
    assert!(out[at..].contains("Seed of the first noisy run"), "{out}");
}
