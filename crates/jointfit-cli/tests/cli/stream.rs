//! `jointfit stream`: the line protocol on a real gait trial and a synthetic one against
//! `jointfit ik` on the same frames, unsolvable frames as NaN lines, and one-line errors for
//! malformed input.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

/// `jointfit stream ARGS` with `input` on standard input: (success, stdout, stderr).
fn stream(args: &[&str], input: impl AsRef<[u8]>) -> (bool, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .arg("stream")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("jointfit runs");
    let mut stdin = child.stdin.take().unwrap();
    // The child may stop reading early (an error): a broken pipe here is part of the test.
    let _ = stdin.write_all(input.as_ref());
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The stream's input for a TRC file: its marker labels, then the time and the x y z cells
/// of every frame exactly as the file writes them (mm).
fn feed_from_trc(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let labels: Vec<&str> = lines[3]
        .split('\t')
        .skip(2)
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let mut out = labels.join("\t") + "\n";
    for line in lines[5..].iter().filter(|l| !l.trim().is_empty()) {
        let cells: Vec<&str> = line.split('\t').collect();
        out.push_str(&cells[1..2 + 3 * labels.len()].join("\t"));
        out.push('\n');
    }
    out
}

/// The header and rows of a `.mot` file (after `endheader`), as text cells.
fn mot_rows(path: &Path) -> (String, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().skip_while(|l| l.trim() != "endheader").skip(1);
    let header = lines.next().unwrap().to_string();
    let rows = lines
        .map(|l| l.split('\t').map(String::from).collect())
        .collect();
    (header, rows)
}

fn stream_rows(out: &str) -> (String, Vec<Vec<String>>) {
    let mut lines = out.lines();
    let header = lines.next().unwrap().to_string();
    let rows = lines
        .map(|l| l.split('\t').map(String::from).collect())
        .collect();
    (header, rows)
}

/// Streams `trc` and runs `ik` on it with `model`; asserts the same columns and frames, the
/// rows of `exact` identical as text, every value within `tolerance`. Returns the largest
/// difference.
fn stream_equals_ik(
    dir: &Path,
    model: &str,
    trc: &Path,
    exact: std::ops::Range<usize>,
    tolerance: f64,
) -> f64 {
    let mot = dir.join("ik.mot");
    let (ok, _, err) = super::jointfit(&[
        "ik",
        model,
        trc.to_str().unwrap(),
        "-o",
        mot.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let (ok, out, err) = stream(&[model], feed_from_trc(trc));
    assert!(ok, "{err}");
    let (ik_header, ik_rows) = mot_rows(&mot);
    let (header, rows) = stream_rows(&out);
    assert_eq!(header, ik_header);
    assert_eq!(rows.len(), ik_rows.len());
    let mut worst = 0.0f64;
    for (f, (a, b)) in rows.iter().zip(&ik_rows).enumerate() {
        if exact.contains(&f) {
            assert_eq!(a[1..], b[1..], "frame {f}");
        }
        for (x, y) in a.iter().zip(b).skip(1) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            worst = worst.max((x - y).abs());
            assert!((x - y).abs() <= tolerance, "frame {f}: {x} vs {y}");
        }
    }
    let summary = format!(
        "jointfit: stream: {} frames, {} solved",
        rows.len(),
        rows.len()
    );
    assert!(err.contains(&summary), "{err}");
    worst
}

/// OpenCap's walking1 (143 frames): `ik` solves it in two chunks (the second seeded at frame
/// 71), the stream in one. The first chunk's rows are the same text; the others agree within
/// ten step tolerances (1e-7 rad, shown in degrees; the translations within the same number
/// in metres).
#[test]
fn stream_equals_ik_on_walking1() {
    let tmp = jointfit_testkit::scratch("stream-walk");
    let Some((subject, walk)) = super::opencap_subject(&tmp, "subject.toml") else {
        return;
    };
    let tolerance = 1e-7f64.to_degrees();
    let worst = stream_equals_ik(&tmp, subject.to_str().unwrap(), &walk, 0..71, tolerance);
    eprintln!("walking1: largest difference from ik {worst:.2e}");
    std::fs::remove_dir_all(&tmp).unwrap();
}

/// A synthetic walk of 50 frames with skin noise: one chunk for `ik` too, so every row is the
/// same text.
#[test]
fn stream_equals_ik_on_a_synthetic_walk() {
    let tmp = jointfit_testkit::scratch("stream-synth");
    let trc = tmp.join("walk.trc");
    let (ok, _, err) = super::jointfit(&[
        "synth",
        "lower-limb-left",
        "--motion",
        "all",
        "--noise",
        "skin",
        "--seed",
        "3",
        "-o",
        trc.to_str().unwrap(),
        "--truth",
        tmp.join("truth.toml").to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let worst = stream_equals_ik(&tmp, "lower-limb-left", &trc, 0..usize::MAX, 0.0);
    assert_eq!(worst, 0.0);
    std::fs::remove_dir_all(&tmp).unwrap();
}

/// The built-in leg's markers at one pose, in mm, as a feed's cells (after the time).
fn pose_cells() -> (Vec<String>, Vec<String>) {
    let model = jointfit::model::Model::compile(&jointfit::model::lower_limb::lower_limb(
        jointfit::model::lower_limb::Side::Right,
    ))
    .unwrap();
    let p = model.nominal_params();
    let mut q = model.default_coords();
    q[model.coord_id("pelvis_ty").unwrap()] = 0.9;
    q[model.coord_id("knee_flexion").unwrap()] = 0.4;
    let mut kin = jointfit::kinematics::KinData::new(&model);
    jointfit::kinematics::forward_kinematics(
        &model,
        &p,
        &q,
        jointfit::kinematics::Want::Positions,
        &mut kin,
    );
    let labels = model.markers().iter().map(|m| m.name.clone()).collect();
    let cells = kin
        .markers
        .iter()
        .flat_map(|m| m.iter().map(|v| format!("{}", v * 1e3)).collect::<Vec<_>>())
        .collect();
    (labels, cells)
}

/// A frame whose foot markers are all missing cannot be solved: its line is NaN in every
/// coordinate and the stream goes on to solve the next; the closing line on stderr says so.
#[test]
fn an_unsolvable_frame_is_a_nan_line_and_the_stream_goes_on() {
    let (labels, cells) = pose_cells();
    let mut gappy = cells.clone();
    for c in &mut gappy[36..45] {
        c.clear();
    }
    let input = format!(
        "{}\n0\t{}\n0.01\t{}\n0.02\t{}\n",
        labels.join("\t"),
        cells.join("\t"),
        gappy.join("\t"),
        cells.join("\t")
    );
    let (ok, out, err) = stream(&["lower-limb-right"], &input);
    assert!(ok, "{err}");
    let (header, rows) = stream_rows(&out);
    assert!(header.starts_with("time\tpelvis_tx\t"), "{header}");
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[1][0], "0.01");
    assert!(rows[1][1..].iter().all(|v| v == "NaN"), "{out}");
    for r in [&rows[0], &rows[2]] {
        let knee = header
            .split('\t')
            .position(|h| h == "knee_flexion")
            .unwrap();
        let v: f64 = r[knee].parse().unwrap();
        assert!((v - 0.4f64.to_degrees()).abs() < 1e-6, "{v}");
    }
    assert!(
        err.contains("3 frames, 2 solved; 1 not solved (NaN lines; the first on input line 3:"),
        "{err}"
    );
}

/// Malformed input ends the stream with one line naming the input line; the frames before it
/// were answered.
#[test]
fn malformed_lines_are_one_line_errors_naming_the_line() {
    let (labels, cells) = pose_cells();
    let head = format!("{}\n0\t{}\n", labels.join("\t"), cells.join("\t"));
    let cases: Vec<(String, &str)> = vec![
        (
            format!("{head}0.01\t{}\n", cells[1..].join("\t")),
            "standard input line 3: 45 cells, expected 46 (the time, then x y z of each of the \
             15 markers)",
        ),
        (
            format!("{head}0.01\t{}\tx\n", cells[..44].join("\t")),
            "standard input line 3: marker RMT5, z: not a number: \"x\"",
        ),
        (
            format!("{head}0\t{}\n", cells.join("\t")),
            "standard input line 3: time 0 s does not follow the previous frame's time 0 s",
        ),
        (
            format!("{head}\n\nabc\t{}\n", cells.join("\t")),
            "standard input line 5: the time is not a number: \"abc\"",
        ),
    ];
    for (input, expected) in cases {
        let (ok, out, err) = stream(&["lower-limb-right"], &input);
        assert!(!ok, "{expected}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert_eq!(err.trim_end(), format!("jointfit: error: {expected}"));
        assert_eq!(out.lines().count(), 2, "{out}");
    }
    let (ok, out, err) = stream(&["lower-limb-right"], "");
    assert!(!ok && out.is_empty());
    assert!(err.contains("standard input is empty"), "{err}");
    let (ok, _, err) = stream(&["lower-limb-right"], "A\tB\n0\t1\t2\t3\t4\t5\t6\n");
    assert!(!ok);
    assert!(
        err.starts_with("jointfit: error: standard input line 1 (the marker labels): no label")
            && err.lines().count() == 1,
        "{err}"
    );
    let (ok, _, err) = stream(&["lower-limb-right"], b"\xff\xfe\n");
    assert!(!ok && err.lines().count() == 1, "{err}");
    let (ok, _, err) = stream(&["lower-limb-right"], "RASI\tRASI\n");
    assert!(!ok && err.contains("twice"), "{err}");
}

/// `bench --stream-only` feeds `jointfit stream` through pipes and reports every figure
/// (their values are timings, not asserted): the synthetic gait without the shared data.
#[test]
fn bench_stream_section_reports_its_figures() {
    let (ok, out, err) = super::jointfit(&[
        "bench",
        "--data",
        "/nonexistent-jointfit-data",
        "--stream-only",
        "--stream-frames",
        "3000",
        "--stream-latency-frames",
        "300",
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    for part in ["pipe_latency", "update_latency"] {
        assert_eq!(v[part]["frames"].as_u64(), Some(300), "{out}");
        let p50 = v[part]["p50_us"].as_f64().unwrap();
        let max = v[part]["max_us"].as_f64().unwrap();
        assert!(p50 > 0.0 && p50 <= max && max.is_finite(), "{out}");
    }
    assert_eq!(v["frames"].as_u64(), Some(3000));
    assert_eq!(v["unsolved_frames"].as_u64(), Some(0), "{out}");
    assert!(v["pipe_frames_per_second"].as_f64().unwrap() > 0.0);
    let (early, end) = (
        v["rss_after_1000_mb"].as_f64().unwrap(),
        v["rss_at_end_mb"].as_f64().unwrap(),
    );
    assert!(early > 0.0 && end > 0.0, "{out}");
    // The Python figure is there or says why not.
    assert!(
        v["python_update_latency"].is_object() || v["python_note"].is_string(),
        "{out}"
    );
}
