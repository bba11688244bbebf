//! The verdict end to end (`workflow::verdict`): inputs that do not belong together are
//! refused with exit status 5 and nothing written, naming the trial and the cause in one
//! line; matching trials end with `ok` or `caution`; `--accept-rejected` keeps a rejected
//! fit; the JSON carries `verdict`.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

/// Runs `jointfit args`: exit code, stdout, stderr.
fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(args)
        .output()
        .expect("jointfit runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A copy of the TRC `src` with the marker labels of line 4 exchanged pairwise.
fn swap_labels(src: &Path, dst: &Path, pairs: &[(&str, &str)]) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut names: Vec<String> = lines[3].split('\t').map(str::to_string).collect();
    for (a, b) in pairs {
        let ia = names.iter().position(|n| n == a).expect("label a");
        let ib = names.iter().position(|n| n == b).expect("label b");
        names.swap(ia, ib);
    }
    lines[3] = names.join("\t");
    std::fs::write(dst, lines.join("\n") + "\n").unwrap();
}

/// A copy of the TRC `src` with every coordinate multiplied by `factor` (a units mistake or
/// a body of another size), the five header lines as they are.
fn scaled_trc(src: &Path, dst: &Path, factor: f64) {
    let text = std::fs::read_to_string(src).unwrap();
    let scaled: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i < 5 {
                return l.to_string();
            }
            l.split('\t')
                .enumerate()
                .map(|(k, v)| match (k, v.trim().parse::<f64>()) {
                    (k, Ok(x)) if k >= 2 => format!("{}", x * factor),
                    _ => v.to_string(),
                })
                .collect::<Vec<_>>()
                .join("\t")
        })
        .collect();
    std::fs::write(dst, scaled.join("\n") + "\n").unwrap();
}

/// `calibrate MODEL TRIAL -o OUT` refused: exit 5, no output file, one error line that
/// names the trial's file; the line returned.
fn assert_refused(model: &Path, trial: &Path, out: &Path) -> String {
    let (code, _, err) = run(&[
        "calibrate",
        model.to_str().unwrap(),
        trial.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 5, "{err}");
    assert!(!out.exists(), "a refused fit writes nothing");
    let line = err
        .lines()
        .find(|l| l.starts_with("jointfit: error: rejected:"))
        .unwrap_or_else(|| panic!("no rejection line: {err}"));
    // Long paths are shortened in the middle of a one-line error: the file name's end stays.
    let name = trial.file_name().unwrap().to_str().unwrap();
    assert!(
        line.contains(&name[name.len().saturating_sub(10)..]),
        "{line}"
    );
    line.to_string()
}

#[test]
fn mismatched_inputs_are_refused_and_matching_ones_are_not() {
    let Some(g_static) =
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_static.trc")
    else {
        return;
    };
    let g_walk =
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_walk1.trc").unwrap();
    let h_static =
        jointfit_testkit::data_file("opensim_hamner_subject02/subject02_static.trc").unwrap();
    let h_run =
        jointfit_testkit::data_file("opensim_hamner_subject02/subject02_running.trc").unwrap();
    let dir = jointfit_testkit::scratch("verdict-mismatch");
    let (g, h) = (dir.path().join("g.toml"), dir.path().join("h.toml"));
    super::personalize(&g_static, "gait2392", &g);
    super::personalize(&h_static, "gait2392", &h);
    let out = dir.path().join("fit.toml");
    // Another subject's static trial with the same marker set, both ways.
    for (model, trial) in [(&g, &h_run), (&h, &g_walk)] {
        let line = assert_refused(model, trial, &out);
        assert!(line.contains("not the same marker placement"), "{line}");
    }
    // A marker map that names other markers: a thigh and a shank marker exchanged.
    let swapped = dir.path().join("swapped.trc");
    swap_labels(&g_walk, &swapped, &[("R.Thigh.Upper", "R.Shank.Upper")]);
    let line = assert_refused(&g, &swapped, &out);
    assert!(
        line.contains("labels do not name the same markers"),
        "{line}"
    );
    // The matching trial: exit 0, a verdict that is not reject, the JSON's verdict object.
    let (code, stdout, err) = run(&[
        "calibrate",
        g.to_str().unwrap(),
        g_walk.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let r: Value = serde_json::from_str(&stdout).unwrap();
    let level = r["verdict"]["level"].as_str().unwrap();
    assert!(level == "ok" || level == "caution", "{}", r["verdict"]);
    assert!(r["verdict"]["reasons"].is_array());
    // The override: the mismatched fit runs, is written, and says reject.
    std::fs::remove_file(&out).unwrap();
    let (code, stdout, err) = run(&[
        "calibrate",
        g.to_str().unwrap(),
        h_run.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--accept-rejected",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.exists());
    let last: Vec<&str> = stdout.lines().rev().take(8).collect();
    assert!(
        stdout.contains("verdict: reject\n"),
        "the verdict closes the text output: {last:?}"
    );
}

/// Millimetre data declared as metres, and a left–right exchange of every leg marker: both
/// refused before any fit.
#[test]
fn units_and_sides_that_do_not_match_are_refused() {
    let Some(dir) = jointfit_testkit::data_dir() else {
        return;
    };
    let scratch = jointfit_testkit::scratch("verdict-units");
    let Some((subject, walk)) = super::opencap_subject(scratch.path(), "s.toml") else {
        return;
    };
    let _ = dir;
    let out = scratch.path().join("fit.toml");
    let sides = scratch.path().join("sides.trc");
    let pairs: Vec<(String, String)> = ["ASIS", "PSIS"]
        .iter()
        .map(|m| (format!("r.{m}"), format!("L.{m}")))
        .chain(
            [
                "knee", "ankle", "thigh1", "thigh2", "thigh3", "sh2", "sh3", "calc", "toe", "5meta",
            ]
            .iter()
            .map(|m| (format!("r_{m}"), format!("L_{m}"))),
        )
        .collect();
    let refs: Vec<(&str, &str)> = pairs
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str()))
        .collect();
    swap_labels(&walk, &sides, &refs);
    let line = assert_refused(&subject, &sides, &out);
    assert!(line.contains("markers sit elsewhere"), "{line}");
    // The same trial in centimetres declared as millimetres (every distance ×0.1).
    let cm = scratch.path().join("cm.trc");
    scaled_trc(&walk, &cm, 0.1);
    let (code, _, err) = run(&[
        "calibrate",
        subject.to_str().unwrap(),
        cm.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0, "{err}");
    assert!(!out.exists());
    assert!(
        err.contains("units") || err.contains("times as far apart"),
        "the cause names the units: {err}"
    );
}

/// `demo`: the verdict closes the output, and the run says nothing on stderr besides it. The
/// reported 95 % intervals cover the known true parameters about as often as they claim (at
/// least 20 of 27; the intervals and the truth compared in the same units).
#[test]
fn demo_is_a_clean_run_with_a_verdict() {
    let (code, stdout, err) = run(&["demo", "--frames", "60"]);
    assert_eq!(code, 0, "{err}");
    let covered: usize = stdout
        .lines()
        .find_map(|l| l.strip_prefix("true value inside the reported 95% interval for "))
        .and_then(|l| l.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("the coverage line");
    assert!(covered >= 20, "{covered} of 27 covered:\n{stdout}");
    let last = stdout.lines().last().unwrap();
    assert!(last.starts_with("verdict: "), "{last}");
    assert!(!err.contains("warning"), "{err}");
}

/// A static trial at 0.3 of its size (a units or export error): `personalize` refuses it with
/// exit status 5 naming the measures and their adult ranges, and writes nothing; the real one
/// passes.
#[test]
fn personalize_refuses_a_static_trial_of_no_adult_size() {
    let Some(stat) = jointfit_testkit::data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let dir = jointfit_testkit::scratch("verdict-anthropometry");
    let small = dir.path().join("small.trc");
    scaled_trc(&stat, &small, 0.3);
    let out = dir.path().join("s.toml");
    let args = |trial: &Path| {
        run(&[
            "personalize",
            trial.to_str().unwrap(),
            "--markers",
            "opencap",
            "-o",
            out.to_str().unwrap(),
        ])
    };
    let (code, _, err) = args(&small);
    assert_eq!(code, 5, "{err}");
    assert!(!out.exists());
    assert!(
        err.contains("thigh length") && err.contains("of adults"),
        "{err}"
    );
    let (code, _, err) = args(&stat);
    assert_eq!(code, 0, "{err}");
    assert!(out.exists());
}

/// A one-sided functional trial (the right knee flexed through 135°, the left leg standing)
/// on a bilateral model: the left knee is held at its landmark values with one line that
/// names it, its range and the threshold, and is neither among the fitted parameters nor
/// changed in the written model; the right knee is fitted.
#[test]
fn a_one_sided_trial_holds_the_standing_knee() {
    let Some(stat) = jointfit_testkit::data_file("biobuddy_functional_vicon/Test_func_anat.c3d")
    else {
        return;
    };
    let knee =
        jointfit_testkit::data_file("biobuddy_functional_vicon/Test_func_rknee.c3d").unwrap();
    let dir = jointfit_testkit::scratch("verdict-one-sided");
    let (model, out) = (dir.path().join("both.toml"), dir.path().join("fit.toml"));
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (code, _, err) = run(&[
        "personalize",
        &s(&stat),
        "--markers",
        "plugin-gait-medial",
        "--up=-z",
        "-o",
        &s(&model),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, stdout, err) = run(&[
        "calibrate",
        &s(&model),
        &s(&knee),
        "--up=-z",
        "-o",
        &s(&out),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let r: Value = serde_json::from_str(&stdout).unwrap();
    let reasons: Vec<&str> = r["verdict"]["reasons"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let line = reasons
        .iter()
        .find(|l| l.starts_with("held ") && l.contains("knee_l"))
        .unwrap_or_else(|| panic!("{reasons:?}"));
    assert!(
        line.contains("below 15°") && line.contains("knee_r"),
        "{line}"
    );
    let fitted: Vec<&str> = r["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert!(fitted
        .iter()
        .any(|n| n.starts_with("knee_") && n.ends_with("_r")));
    assert!(
        !fitted
            .iter()
            .any(|n| n.starts_with("knee_") && n.ends_with("_l")),
        "{fitted:?}"
    );
    // The written model keeps the left knee's landmark values exactly.
    let nominal = |path: &Path| -> Vec<(String, f64)> {
        let spec =
            jointfit::model::spec::ModelSpec::from_toml(&std::fs::read_to_string(path).unwrap())
                .unwrap();
        spec.parameters
            .iter()
            .filter(|p| p.name.starts_with("knee_") && p.name.ends_with("_l"))
            .map(|p| (p.name.clone(), p.nominal))
            .collect()
    };
    let (before, after) = (nominal(&model), nominal(&out));
    assert!(!before.is_empty());
    assert_eq!(before, after);
}
