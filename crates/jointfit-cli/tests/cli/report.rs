//! HTML reports and progress output through the binary: `calibrate --report`, `report`, and
//! progress lines on stderr that never touch stdout.

use std::path::Path;
use std::process::Command;

use jointfit_report::check::{external_references, parse, Element};
use jointfit_testkit::data_file;
use jointfit_testkit::ScratchDir;

/// Runs the binary with extra environment variables: (success, stdout, stderr).
fn run(args: &[&str], env: &[(&str, &str)]) -> (bool, String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_jointfit"));
    cmd.args(args).env_remove("JOINTFIT_PROGRESS");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().expect("jointfit runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn scratch(name: &str) -> ScratchDir {
    jointfit_testkit::scratch(&format!("cli-{name}"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Parses a written report and checks what every report must satisfy.
fn checked_page(path: &Path) -> Element {
    let raw = std::fs::read_to_string(path).unwrap();
    let root = parse(&raw).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let refs = external_references(&root, &raw);
    assert!(refs.is_empty(), "{}: {refs:?}", path.display());
    for id in [
        "summary",
        "fig-frame-error",
        "fig-marker-rms",
        "fig-joint-angles",
        "tbl-parameters",
        "fig-convergence",
        "tbl-settings",
    ] {
        assert!(root.by_id(id).is_some(), "{}: no #{id}", path.display());
    }
    root
}

/// The two numbers of the summary's "RMS marker error" card: baseline and fitted (mm).
fn summary_rms(root: &Element) -> (f64, f64) {
    let card = root
        .by_id("summary")
        .unwrap()
        .descendants()
        .into_iter()
        .find(|e| e.attr("class") == Some("v"))
        .unwrap()
        .all_text();
    let nums: Vec<f64> = card
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|t| t.parse().ok())
        .collect();
    assert_eq!(nums.len(), 2, "{card}");
    (nums[0], nums[1])
}

#[test]
fn calibrate_report_and_report_command_on_a_real_walking_trial() {
    let Some(stat) = data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let walk = data_file("opencap_expert1/walking1.trc").unwrap();
    let dir = scratch("report");
    let subj = dir.join("subj.toml");
    let fitted = dir.join("fitted.toml");
    super::personalize(&stat, "opencap", &subj);
    let rep = dir.join("calibrated");
    let (ok, out, err) = run(
        &[
            "calibrate",
            s(&subj),
            s(&walk),
            // One local fit: the chart below counts one solver stage.
            "--probes",
            "0",
            "--filter",
            "6",
            "-o",
            s(&fitted),
            "--report",
            s(&rep),
            "--json",
        ],
        &[],
    );
    assert!(ok, "{err}");
    // Stdout is still exactly the JSON report; a short run off a terminal prints no progress.
    let json: serde_json::Value = serde_json::from_str(&out).expect("stdout is JSON");
    assert!(err.is_empty(), "{err}");
    let root = checked_page(&rep.join("index.html"));
    // How the trial was read and what the data checks found: in the JSON and on the page.
    assert_eq!(json["trials_read"][0]["up_from"], "model");
    assert!(json["trials_read"][0]["checks"].is_array());
    let page = std::fs::read_to_string(rep.join("index.html")).unwrap();
    assert!(page.contains("id=\"sec-data-checks\""));
    let (before, after) = summary_rms(&root);
    // The report's own inverse kinematics agrees with the calibration's numbers.
    let rms_before = json["rms_before_mm"].as_f64().unwrap();
    let rms_after = json["rms_after_mm"].as_f64().unwrap();
    assert!(
        (before - rms_before).abs() < 0.02,
        "{before} vs {rms_before}"
    );
    assert!((after - rms_after).abs() < 0.02, "{after} vs {rms_after}");
    assert!(after < before);
    charts_match_the_json(&root, &json);
    let settings = root.by_id("tbl-settings").unwrap().all_text();
    for needle in ["walking1.trc", "joint", "6 Hz", "jointfit calibrate", "UTC"] {
        assert!(
            settings.contains(needle),
            "{needle} not in settings: {settings}"
        );
    }

    // The report command on the same fit: same numbers, no convergence history.
    let rep2 = dir.join("report");
    let (ok, out, err) = run(
        &[
            "report",
            s(&fitted),
            s(&walk),
            "--landmark",
            s(&subj),
            "--filter",
            "6",
            "-o",
            s(&rep2),
        ],
        &[],
    );
    assert!(ok, "{err}");
    assert!(out.contains("wrote "), "{out}");
    let root2 = checked_page(&rep2.join("index.html"));
    assert_eq!(summary_rms(&root2), (before, after));
    assert!(root2
        .by_id("fig-convergence")
        .unwrap()
        .all_text()
        .contains("Not available"));

    // Errors name the file and write nothing.
    report_errors_write_nothing(&dir, &fitted, &walk, &subj);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The marker chart has every model marker; the convergence chart has the joint solver's
/// iterations (plus the starting point), as the JSON report's history has them.
fn charts_match_the_json(root: &Element, json: &serde_json::Value) {
    // Every model marker has its two bars; every parameter a row; the convergence chart
    // has the joint solver's iterations (plus the starting point).
    let markers = root.by_id("fig-marker-rms").unwrap().all_text();
    for name in ["r.ASIS", "r_thigh1", "r_knee", "r_calc", "r_toe"] {
        assert!(markers.contains(name), "{name} missing");
    }
    let conv = root.by_id("fig-convergence").unwrap();
    let views = conv.find_all("svg");
    assert_eq!(views.len(), 2);
    let iterations = json["iterations"].as_u64().unwrap() as usize;
    assert_eq!(views[0].find_all("circle").len(), iterations + 1);
    // The JSON report carries the same history: the starting objective, then one per
    // iteration, ending at the final cost.
    let stage = &json["convergence"][0];
    let hist: Vec<f64> = stage["objective_mm2"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(hist.len(), iterations + 1);
    let mm2 = 1e6;
    let cost_before = json["cost_before"].as_f64().unwrap() * mm2;
    let cost_after = json["cost_after"].as_f64().unwrap() * mm2;
    assert!((hist[0] - cost_before).abs() <= 1e-9 * cost_before);
    assert!((hist[iterations] - cost_after).abs() <= 1e-9 * cost_after);
    assert!(hist.windows(2).all(|w| w[1] <= w[0]), "{hist:?}");
    // The excess over the best value leaves out the iterations that reached it.
    let excess = views[1].find_all("circle").len();
    assert!(excess >= 1 && excess <= iterations, "{excess}");
}

/// `report` with a missing trial or a landmark model lacking a parameter: one line naming
/// the file, nothing written.
fn report_errors_write_nothing(dir: &ScratchDir, fitted: &Path, walk: &Path, subj: &Path) {
    let bad = dir.join("bad");
    let (ok, _, err) = run(&["report", s(fitted), "no-such.trc", "-o", s(&bad)], &[]);
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no-such.trc"), "{err}");
    assert!(!bad.exists());
    let renamed = dir.join("renamed.toml");
    let text = std::fs::read_to_string(subj).unwrap();
    std::fs::write(
        &renamed,
        text.replace("hip_pelvis_anterior", "hip_pelvis_front"),
    )
    .unwrap();
    let (ok, _, err) = run(
        &[
            "report",
            s(fitted),
            s(walk),
            "--landmark",
            s(&renamed),
            "-o",
            s(&bad),
        ],
        &[],
    );
    assert!(!ok);
    assert!(
        err.contains("renamed.toml") && err.contains("hip_pelvis_anterior"),
        "{err}"
    );
    assert!(!bad.exists());
}

/// `calibrate --report FILE` where FILE is an existing file is refused before the fit (a long
/// fit must not end on this error): one line naming it, nothing written, the file untouched.
#[test]
fn calibrate_refuses_a_report_directory_that_is_a_file_before_fitting() {
    let Some(stat) = data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let walk = data_file("opencap_expert1/walking1.trc").unwrap();
    let dir = scratch("report-file");
    let subj = dir.join("subj.toml");
    let (ok, _, err) = run(
        &[
            "personalize",
            s(&stat),
            "--markers",
            "opencap",
            "--side",
            "right",
            "-o",
            s(&subj),
        ],
        &[],
    );
    assert!(ok, "{err}");
    let taken = dir.join("notes.txt");
    std::fs::write(&taken, "mine").unwrap();
    let fitted = dir.join("fitted.toml");
    let (ok, out, err) = run(
        &[
            "calibrate",
            s(&subj),
            s(&walk),
            "-o",
            s(&fitted),
            "--report",
            s(&taken),
        ],
        &[],
    );
    assert!(!ok);
    assert!(out.is_empty(), "{out}");
    let line = err.trim();
    assert_eq!(line.lines().count(), 1, "{err}");
    assert!(
        line.contains("notes.txt: --report exists and is not a directory"),
        "{err}"
    );
    assert!(!fitted.exists());
    assert_eq!(std::fs::read_to_string(&taken).unwrap(), "mine");
}

#[test]
fn progress_lines_go_to_stderr_when_asked() {
    // 60 frames: more than the probes' 25, so the best start is finished on every frame
    // (with 20 a probe may already converge and no finishing stage runs).
    let args = ["demo", "--frames", "60", "--noise-mm", "2"];
    let (ok, quiet_out, err) = run(&args, &[]);
    assert!(ok, "{err}");
    // Off a terminal a short run prints no progress; identifiability warnings may remain.
    assert!(
        err.lines().all(|l| l.starts_with("jointfit: warning:")),
        "no progress off a terminal for a short run: {err}"
    );
    let (ok, out, err) = run(
        &args,
        &[
            ("JOINTFIT_PROGRESS", "log"),
            ("JOINTFIT_PROGRESS_SECONDS", "0"),
        ],
    );
    assert!(ok, "{err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.starts_with("jointfit: warning:"))
        .collect();
    assert!(
        lines.iter().any(|l| l.starts_with("jointfit: ")
            && l.contains("joint Levenberg-Marquardt: 1 iterations")),
        "{err}"
    );
    assert!(
        lines.last().unwrap().contains(": done, ") && lines.last().unwrap().contains("mm²"),
        "{err}"
    );
    // No escape codes in log mode, and stdout does not change (apart from timings).
    assert!(!err.contains('\x1b'));
    let strip = |s: &str| {
        s.lines()
            .filter(|l| !l.contains(" s") && !l.contains("ms"))
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(&out), strip(&quiet_out));
    let (ok, _, err) = run(&args, &[("JOINTFIT_PROGRESS", "quiet")]);
    assert!(
        ok && err.lines().all(|l| l.starts_with("jointfit: warning:")),
        "{err}"
    );
}

/// The marker names and the number of "n/a" values of a page's per-marker figure.
fn marker_figure(root: &Element) -> (Vec<String>, usize) {
    let fig = root.by_id("fig-marker-rms").unwrap();
    let texts: Vec<String> = fig
        .descendants()
        .into_iter()
        .filter(|e| e.name == "text")
        .map(|e| e.all_text())
        .collect();
    let na = texts.iter().filter(|t| t.trim() == "n/a").count();
    (texts, na)
}

/// A model marker the trial lacks is shown the same way by `calibrate --report` and by
/// `report`: listed in the per-marker figure with "n/a" for each model (no sample to measure),
/// said in a note, never dropped. Oracle: the two pages agree, and the marker that is in the
/// trial has numbers.
#[test]
fn a_marker_absent_from_the_trial_is_na_in_both_reports() {
    let dir = scratch("report-absent");
    let (t, m) = (dir.join("t.trc"), dir.join("m.toml"));
    let (ok, _, err) = run(
        &[
            "synth",
            "lower-limb-right",
            "--motion",
            "hip",
            "--frames",
            "30",
            "-o",
            s(&t),
            "--truth",
            s(&m),
        ],
        &[],
    );
    assert!(ok, "{err}");
    // The trial without RTHA (the thigh keeps three markers).
    let keep = "RASI,LASI,RPSI,LPSI,RTHI,RTHP,RKNE,RTIB,RTIA,RTIP,RANK,RHEE,RTOE,RMT5";
    let sub = dir.join("sub.trc");
    let (ok, _, err) = run(&["convert", s(&t), s(&sub), "--markers", keep], &[]);
    assert!(ok, "{err}");
    let (cal_dir, rep_dir) = (dir.join("cal"), dir.join("rep"));
    let fitted = dir.join("f.toml");
    let (ok, _, err) = run(
        &[
            "calibrate",
            s(&m),
            s(&sub),
            "--joints",
            "hip",
            "-o",
            s(&fitted),
            "--report",
            s(&cal_dir),
        ],
        &[],
    );
    assert!(ok, "{err}");
    assert!(err.contains("lacks model markers RTHA"), "{err}");
    let (ok, _, err) = run(
        &[
            "report",
            s(&fitted),
            s(&sub),
            "--landmark",
            s(&m),
            "-o",
            s(&rep_dir),
        ],
        &[],
    );
    assert!(ok, "{err}");
    assert!(err.contains("lacks model markers RTHA"), "{err}");
    assert!(!err.contains("left out of"), "{err}");
    let mut pages = Vec::new();
    for d in [&cal_dir, &rep_dir] {
        let path = d.join("index.html");
        let root = checked_page(&path);
        let (texts, na) = marker_figure(&root);
        assert!(
            texts.iter().any(|x| x == "RTHA"),
            "{}: {texts:?}",
            path.display()
        );
        assert!(texts.iter().any(|x| x == "RTHP"), "{}", path.display());
        // Two bars for RTHA (start/landmark and fitted), both n/a; no other n/a.
        assert_eq!(na, 2, "{}: {texts:?}", path.display());
        let page = std::fs::read_to_string(&path).unwrap();
        assert!(
            page.contains("lacks model markers RTHA"),
            "{}: no note",
            path.display()
        );
        let names: Vec<String> = texts
            .into_iter()
            .filter(|x| x.starts_with('R') || x.starts_with('L'))
            .collect();
        pages.push(names);
    }
    assert_eq!(pages[0], pages[1], "the two reports list the same markers");
}
