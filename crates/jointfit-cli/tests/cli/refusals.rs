//! Refusals, one test each: no panics on huge counts, bad
//! values and data are refused by name, errors are one line with each cause once, CSV is
//! quoted. The oracle is the file system (a refused run changes nothing, `reliability.rs`'s
//! `refused`) and, for the CSV, Python's `csv` module.

use std::process::Command;

use super::jointfit;
use super::reliability::{refused, run, Scratch};

#[test]
fn huge_counts_are_refused_not_panics() {
    let s = Scratch::new("counts");
    for frames in ["18446744073709551615", "4294967296", "100000000", "0", "-1"] {
        let err = refused(
            &s,
            &[
                "synth",
                "lower-limb-right",
                "--frames",
                frames,
                "-o",
                &s.p("a.trc"),
                "--truth",
                &s.p("a.toml"),
            ],
        );
        assert!(err.contains("--frames"), "{err}");
    }
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let err = refused(
        &s,
        &[
            "calibrate",
            &m,
            &t,
            "--bootstrap",
            "100000000",
            "-o",
            &s.p("f.toml"),
        ],
    );
    assert!(err.contains("--bootstrap") && err.contains("2000"), "{err}");
    let err = refused(
        &s,
        &["convert", &t, &s.p("o.trc"), "--decimals", "1000000000"],
    );
    assert!(err.contains("--decimals"), "{err}");
}

#[test]
fn progress_interval_from_the_environment_is_validated() {
    let s = Scratch::new("progress");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let out = Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["report", &m, &t, "-o", &s.p("rep")])
        .env("JOINTFIT_PROGRESS_SECONDS", "1e20")
        .env("JOINTFIT_PROGRESS", "log")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("JOINTFIT_PROGRESS_SECONDS=1e20"), "{err}");
    assert!(s.dir.join("rep/index.html").is_file());
}

#[test]
fn bad_numbers_are_refused_by_name() {
    let s = Scratch::new("numbers");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let o = s.p("o.trc");
    for (args, name) in [
        (vec!["check", &m, &t, "--noise-mm", "NaN"], "--noise-mm"),
        (vec!["check", &m, &t, "--noise-mm=-4"], "--noise-mm"),
        (vec!["check", &m, &t, "--noise-mm", "-4"], "--noise-mm"),
        (
            vec!["check", &m, &t, "--threshold-mm", "inf"],
            "--threshold-mm",
        ),
        (vec!["convert", &t, &o, "--filter", "1e-7"], "--filter"),
        (vec!["convert", &t, &o, "--filter", "-6"], "--filter"),
        (vec!["convert", &t, &o, "--filter", "NaN"], "--filter"),
        // 30 frames at 10 Hz: 6 Hz is above Nyquist (5 Hz).
        (vec!["convert", &t, &o, "--filter", "6"], "--filter"),
        (
            vec!["ik", &m, &t, "-o", &o, "--filter", "1e-300"],
            "--filter",
        ),
        (vec!["demo", "--noise-mm", "-1"], "--noise-mm"),
        (
            vec![
                "synth", &m, "-o", &o, "--truth", "x.toml", "--rate", "1e300",
            ],
            "--rate",
        ),
        (
            vec![
                "synth",
                &m,
                "-o",
                &o,
                "--truth",
                "x.toml",
                "--perturb-mm",
                "-4",
            ],
            "--perturb-mm",
        ),
    ] {
        let err = refused(&s, &args);
        assert!(err.contains(name), "{args:?}: {err}");
        assert!(!err.contains("-- -"), "{args:?}: clap's hint: {err}");
    }
}

/// Rewrites every data line of a TRC file (after the 5 header lines) with `f`.
fn rewrite_trc(src: &str, dst: &str, f: impl Fn(usize, &str) -> String) {
    let text = std::fs::read_to_string(src).unwrap();
    let out: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i < 5 { l.to_string() } else { f(i, l) })
        .collect();
    std::fs::write(dst, out.join("\n") + "\n").unwrap();
}

#[test]
fn absurd_data_are_errors_not_rms_zero() {
    let s = Scratch::new("absurd");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let huge = s.p("huge.trc");
    rewrite_trc(&t, &huge, |_, l| {
        let mut cells: Vec<String> = l.split('\t').map(str::to_string).collect();
        for c in cells.iter_mut().skip(2) {
            if !c.is_empty() {
                *c = "1e300".into();
            }
        }
        cells.join("\t")
    });
    let err = refused(&s, &["ik", &m, &huge, "-o", &s.p("o.mot")]);
    assert!(err.contains("frame 1, marker"), "{err}");
    // A model nominal of 1e300 (with bounds that allow it).
    let spec = std::fs::read_to_string(&m).unwrap();
    let bad = s.p("bad.toml");
    let mut lines: Vec<String> = spec.lines().map(str::to_string).collect();
    let i = lines.iter().position(|l| l.starts_with("nominal")).unwrap();
    lines[i] = "nominal = 1e300".into();
    lines[i + 2] = "upper = 1e301".into();
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let err = refused(&s, &["ik", &bad, &t, "-o", &s.p("o.mot")]);
    assert!(err.contains("implausibly large"), "{err}");
    // nominal = nan is blamed on the nominal, not the bounds.
    lines[i] = "nominal = nan".into();
    lines[i + 2] = "upper = 1".into();
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let err = refused(&s, &["model", "show", &bad]);
    assert!(err.contains("nominal NaN is not a finite number"), "{err}");
    // A free joint whose three rotation axes are one.
    let zzz = spec.replacen(
        "rotation_axes = [",
        "rotation_axes = [\"z\", \"z\", \"z\"]\nold_axes = [",
        1,
    );
    assert_ne!(zzz, spec, "the model has a free joint");
    let zzz = drop_line_after(&zzz, "old_axes = [");
    std::fs::write(&bad, zzz).unwrap();
    let err = refused(&s, &["model", "show", &bad]);
    assert!(err.contains("are parallel"), "{err}");
}

/// Removes the (possibly multi-line) TOML array that starts with `start`.
fn drop_line_after(text: &str, start: &str) -> String {
    let i = text.find(start).unwrap();
    let j = i + text[i..].find(']').unwrap();
    let end = j + text[j..].find('\n').map_or(text.len() - j, |k| k + 1);
    format!("{}{}", &text[..i], &text[end..])
}

#[test]
fn errors_say_each_cause_once_on_one_line() {
    let s = Scratch::new("messages");
    std::fs::write(s.dir.join("empty.c3d"), b"").unwrap();
    let err = refused(&s, &["inspect", &s.p("empty.c3d")]);
    assert_eq!(err.matches("too short").count(), 1, "{err}");
    let err = refused(&s, &["inspect", &s.p("none.trc")]);
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
    std::fs::write(s.dir.join("bad.toml"), "name = \"x\"\n[[bad\n").unwrap();
    let err = refused(&s, &["model", "show", &s.p("bad.toml")]);
    assert!(err.contains("line 2, column 6"), "{err}");
    assert_eq!(err.matches("invalid table header").count(), 1, "{err}");
    // A 5 MB line in a model file.
    let long = format!("name = \"{}\n", "x".repeat(5_000_000));
    std::fs::write(s.dir.join("long.toml"), long).unwrap();
    let err = refused(&s, &["model", "show", &s.p("long.toml")]);
    assert!(err.len() < 1500, "{} bytes", err.len());
    // A DataRate of 1e300 is not printed with 300 digits.
    let text = std::fs::read_to_string(s.p("t.trc")).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let rates = lines[2].to_string();
    let fields: Vec<&str> = rates.split('\t').collect();
    let new_rates = format!("1e300\t1e300\t{}", fields[2..].join("\t"));
    lines[2] = &new_rates;
    std::fs::write(s.dir.join("rate.trc"), lines.join("\n")).unwrap();
    let out = run(&["inspect", &s.p("rate.trc")]);
    let all =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(!all.contains("0000000000000000000000000"), "{all}");
}

#[test]
fn errors_csv_quotes_labels_with_commas_and_quotes() {
    let Some(python) = jointfit_testkit::python() else {
        println!("skipped: no JOINTFIT_PYTHON");
        return;
    };
    let s = Scratch::new("csv");
    let m = s.p("m.toml");
    let spec = std::fs::read_to_string(&m)
        .unwrap()
        .replace("\"RASI\"", "\"R,ASI\"")
        .replace("\"RTHI\"", "\"R\\\"THI\"");
    let odd = s.p("odd.toml");
    std::fs::write(&odd, spec).unwrap();
    let (t, truth) = (s.p("odd.trc"), s.p("odd_truth.toml"));
    let (ok, _, err) = jointfit(&[
        "synth", &odd, "--motion", "hip", "-o", &t, "--truth", &truth,
    ]);
    assert!(ok, "{err}");
    let csv = s.p("e.csv");
    let (ok, _, err) = jointfit(&["ik", &odd, &t, "-o", &s.p("o.mot"), "--errors", &csv]);
    assert!(ok, "{err}");
    let script = "import csv,sys,json\nrows=list(csv.reader(open(sys.argv[1],newline='')))\nprint(json.dumps([rows[0],sorted(set(len(r) for r in rows))]))";
    let out = Command::new(python)
        .args(["-c", script, &csv])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let header: Vec<&str> = v[0]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap())
        .collect();
    assert!(header.contains(&"R,ASI_mm"), "{header:?}");
    assert!(header.contains(&"R\"THI_mm"), "{header:?}");
    assert_eq!(
        v[1],
        serde_json::json!([header.len()]),
        "every row as wide as the header"
    );
}
