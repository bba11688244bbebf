//! Limits: every long loop has a documented cap (a larger value is a
//! one-line error naming the cap), the bootstrap's progress reaches stderr through the
//! workflow's observer, a fit that did not converge exits 3 and writes nothing unless
//! `--accept-unconverged`, and sizes declared in file headers never allocate: a TRC header
//! declaring 4e9 frames or markers is a one-line error.

use std::path::Path;
use std::process::{Command, Output};

use jointfit_testkit::ScratchDir;

fn run(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_jointfit"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("jointfit runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A scratch directory holding `t.trc`: 30 frames of every joint moving, synthesized from
/// the built-in right leg with its parameters moved by up to 15 mm / 8° (so a fit from the
/// built-in nominal has somewhere to go).
fn perturbed_trial(tag: &str) -> (ScratchDir, impl Fn(&str) -> String) {
    let dir = jointfit_testkit::scratch(&format!("limits-{tag}"));
    let root = dir.to_path_buf();
    let p = move |name: &str| root.join(name).to_str().unwrap().to_string();
    let out = run(
        &[
            "synth",
            "lower-limb-right",
            "--motion",
            "all",
            "--frames",
            "30",
            "--perturb-mm",
            "15",
            "--perturb-deg",
            "8",
            "-o",
            &p("t.trc"),
            "--truth",
            &p("truth.toml"),
        ],
        &[],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    (dir, p)
}

/// A refused command: exit status 2 (usage) or 1, no panic, one line naming `needle`.
fn refused_naming(args: &[&str], needles: &[&str]) {
    let out = run(args, &[]);
    let err = text(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_ne!(out.status.code(), Some(101), "{args:?} panicked: {err}");
    let first = err.lines().next().unwrap_or("");
    for n in needles {
        assert!(first.contains(n), "{args:?}: {n:?} not in {err}");
    }
    // clap adds a usage hint after its one-line error; our own errors are one line.
    if out.status.code() != Some(2) {
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    }
}

#[test]
fn an_unconverged_fit_exits_3_and_writes_nothing_unless_accepted() {
    let (_dir, p) = perturbed_trial("unconverged");
    let (t, fitted, rep) = (p("t.trc"), p("fitted.toml"), p("rep"));
    let base = [
        "calibrate",
        "lower-limb-right",
        t.as_str(),
        "--joints",
        "all",
        "--max-iter",
        "1",
        "-o",
        fitted.as_str(),
        "--report",
        rep.as_str(),
    ];
    let out = run(&base, &[]);
    let (stdout, err) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(3), "{stdout}{err}");
    assert!(
        stdout.contains("not converged: iteration limit"),
        "{stdout}"
    );
    // Warnings on what the trial determines may precede it; the error is one line.
    let errors: Vec<&str> = err
        .lines()
        .filter(|l| !l.starts_with("jointfit: warning: "))
        .collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(
        errors[0].starts_with("jointfit: error: ") && errors[0].contains("converge"),
        "{err}"
    );
    assert!(!Path::new(&fitted).exists() && !Path::new(&rep).exists());

    // --json: still exit 3, the report on stdout says why.
    let mut json = base.to_vec();
    json.push("--json");
    let out = run(&json, &[]);
    assert_eq!(out.status.code(), Some(3));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(v["termination"], "iteration_limit");
    // The kept start's whole path: one probe iteration of the global phase (the limit bounds
    // the probes too) and one finishing iteration.
    assert!(
        v["iterations"].as_u64().unwrap() <= 2,
        "{}",
        v["iterations"]
    );
    assert!(!Path::new(&fitted).exists());

    // Accepted: exit 0, the model and the report are written.
    let mut accept = base.to_vec();
    accept.push("--accept-unconverged");
    let out = run(&accept, &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("not converged"));
    assert!(Path::new(&fitted).is_file());
    assert!(Path::new(&rep).join("index.html").is_file());

    // Without the limit the same fit converges (the limit, not the data, stopped it).
    let out = run(
        &[
            "calibrate",
            "lower-limb-right",
            &t,
            "--joints",
            "all",
            "-o",
            &p("f2.toml"),
        ],
        &[],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stdout).contains("not converged"));
}

#[test]
fn every_long_loop_has_a_cap() {
    let (_dir, p) = perturbed_trial("caps");
    let (t, f) = (p("t.trc"), p("f.toml"));
    let cal = |opt: &str, v: &str| {
        vec![
            "calibrate".to_string(),
            "lower-limb-right".into(),
            t.clone(),
            opt.into(),
            v.into(),
            "-o".into(),
            f.clone(),
        ]
    };
    for (opt, v, cap) in [
        ("--starts", "1001", "1000"),
        ("--bootstrap", "2001", "2000"),
        ("--max-iter", "10001", "10000"),
        ("--max-iter", "0", "10000"),
    ] {
        let args = cal(opt, v);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused_naming(&args, &[opt, cap]);
    }
    // The batch manifest: the same caps, and at most 1024 worker threads.
    let manifest = p("jobs.toml");
    for (key, cap) in [
        ("starts = 5000", "1000"),
        ("bootstrap = 100000000", "2000"),
        ("max_iter = 0", "10000"),
        ("marker_noise_mm = -1.0", "marker_noise_mm"),
        ("prior = \"flat\"", "none"),
    ] {
        std::fs::write(
            &manifest,
            format!(
                "[[job]]\nid = \"a\"\nmodel = \"lower-limb-right\"\ntrials = [\"t.trc\"]\n{key}\n"
            ),
        )
        .unwrap();
        let k = key.split(' ').next().unwrap();
        refused_naming(
            &["batch", &manifest, "-o", &p("out")],
            &[k, cap, "job \"a\""],
        );
        assert!(!Path::new(&p("out")).exists());
    }
    refused_naming(
        &["batch", &manifest, "-o", &p("out"), "--jobs", "5000"],
        &["--jobs", "1024"],
    );
}

#[test]
fn the_bootstrap_reports_progress_on_stderr() {
    let (_dir, p) = perturbed_trial("progress");
    let (t, f) = (p("t.trc"), p("f.toml"));
    let fit = |extra: &str, mode: &str| {
        let mut args = vec!["calibrate", "lower-limb-right", &t, "--joints", "knee"];
        args.extend(["--bootstrap", "4", extra, "-o", &f]);
        run(&args, &[("JOINTFIT_PROGRESS", mode)])
    };
    let out = fit("--json", "log");
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    for end in ["started", "done"] {
        let line = format!("jointfit: uncertainty analysis (4 bootstrap refits): {end}");
        assert!(err.contains(&line), "{line:?} not in {err}");
    }
    // stdout stays clean JSON, and the bootstrap ran.
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(v["uncertainty"]["bootstrap"]["replicates"], 4, "{v}");
    // Quiet: no progress at all.
    let out = fit("--force", "quiet");
    assert!(out.status.success());
    assert!(!text(&out.stderr).contains("uncertainty analysis"));
}

/// Line 3 of `src` (the TRC header values) with NumFrames or NumMarkers replaced.
fn with_header_value(src: &str, dst: &str, column: usize, value: &str) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<String> = lines[2].split('\t').map(str::to_string).collect();
    cells[column] = value.to_string();
    lines[2] = cells.join("\t");
    std::fs::write(dst, lines.join("\n") + "\n").unwrap();
}

#[test]
fn trc_headers_declaring_billions_are_one_line_errors() {
    let (_dir, p) = perturbed_trial("headers");
    // Columns of line 3: DataRate CameraRate NumFrames NumMarkers Units ...
    for (column, value, name) in [
        (2, "4000000000", "frames"),
        (2, "18446744073709551615", "frames"),
        (2, "1e300", "frames"),
        (3, "4000000000", "markers"),
        (3, "18446744073709551615", "markers"),
    ] {
        let (bad, o) = (p("bad.trc"), p("o.trc"));
        with_header_value(&p("t.trc"), &bad, column, value);
        for args in [vec!["inspect", bad.as_str()], vec!["convert", &bad, &o]] {
            let out = run(&args, &[]);
            let err = text(&out.stderr);
            assert!(!out.status.success(), "{args:?} {value}");
            assert_ne!(out.status.code(), Some(101), "{args:?} panicked: {err}");
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
            assert!(err.contains("bad.trc"), "{err}");
            assert!(err.to_lowercase().contains(name), "{name} {value}: {err}");
            assert!(!Path::new(&o).exists());
        }
    }
}

/// Held-out variant of "outputs never destroy inputs": a batch whose job model is the fitted
/// model file the batch would write (`out/models/a.toml`), or whose trial is its results
/// table, is refused before any work, and every file stays as it was.
#[test]
fn batch_outputs_never_replace_its_inputs() {
    let (dir, p) = perturbed_trial("batch-inputs");
    std::fs::create_dir_all(dir.join("out/models")).unwrap();
    std::fs::copy(p("truth.toml"), p("out/models/a.toml")).unwrap();
    std::fs::copy(p("t.trc"), p("out/results.csv")).unwrap();
    for (model, trial, spelled) in [
        ("out/models/a.toml", "t.trc", "./sub/../out"),
        ("lower-limb-right", "out/results.csv", "out"),
    ] {
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(
            p("jobs.toml"),
            format!("[[job]]\nid = \"a\"\nmodel = \"{model}\"\ntrials = [\"{trial}\"]\n"),
        )
        .unwrap();
        let before = jointfit_testkit::snapshot(&dir);
        let out = run(&["batch", &p("jobs.toml"), "-o", &p(spelled)], &[]);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains("refusing to overwrite an input"), "{err}");
        assert!(
            jointfit_testkit::snapshot(&dir) == before,
            "{model} {trial}: files changed"
        );
    }
}
