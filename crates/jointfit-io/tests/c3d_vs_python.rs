//! jointfit's C3D reader against two independent Python readers, ezc3d and `c3d`, on every
//! `.c3d` file of the shared sample set (`$JOINTFIT_DATA/c3d_reader/**` and
//! `$JOINTFIT_DATA/biobuddy_functional_vicon/`).
//!
//! `scripts/c3d_reference.py` dumps what each Python reader makes of each file (frame and
//! point counts, labels, first frame, rate, coordinates in mm with its own missing marks,
//! scaled analog samples, and `c3d`'s residuals). This test normalises the oracle side to
//! jointfit's conventions, and only that side:
//! - a sample is missing when the oracle says so (ezc3d: NaN from a negative residual word;
//!   `c3d`: residual −1) *or* when it is exactly (0, 0, 0), which neither oracle treats as a gap;
//! - ezc3d's header first frame is 0-based (the script adds 1);
//! - label lists are compared over the points present (POINT:LABELS may hold more names than
//!   points; `c3d` does not read LABELS2…);
//! - ezc3d's "residuals" are the camera byte (it swaps the two bytes of the residual word), so
//!   residuals are compared with `c3d` only.
//!
//! Every other disagreement fails the test unless it is listed in [`KNOWN`] with the reason,
//! and each file that both Python readers fail on is pinned in [`BOTH_FAIL`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use jointfit_io::c3d::{read_c3d, C3d, C3dError};
use jointfit_testkit::{data_dir, python};
use serde_json::Value;

#[path = "c3d_vs_python/known.rs"]
mod known;
use known::{Expect, BOTH_FAIL, KNOWN};

/// Largest accepted coordinate difference, mm.
const TOL_MM: f64 = 1e-3;

/// What one Python reader made of one file.
struct Oracle {
    frames: usize,
    points: usize,
    first_frame: i64,
    rate: f64,
    labels: Vec<String>,
    analog_channels: usize,
    analog_samples: usize,
    xyz_mm: Vec<f64>,
    analog: Vec<f64>,
    residual_mm: Option<Vec<f64>>,
}

fn load_f64(path: &Path) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn oracle(meta: &Value, dir: &Path, index: usize, reader: &str) -> Result<Oracle, String> {
    if let Some(e) = meta.get("error") {
        return Err(e.as_str().unwrap_or("?").to_string());
    }
    let u = |k: &str| meta[k].as_u64().unwrap_or_else(|| panic!("{k} in {meta}")) as usize;
    let strings = |k: &str| -> Vec<String> {
        meta[k]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|s| s.as_str().unwrap_or("").trim().to_string())
                    .collect()
            })
            .unwrap_or_default()
    };
    let file = |what: &str| dir.join(format!("{index}_{reader}_{what}.f64"));
    Ok(Oracle {
        frames: u("frames"),
        points: u("points"),
        first_frame: meta["first_frame"].as_i64().unwrap(),
        rate: meta["rate"].as_f64().unwrap(),
        labels: strings("labels"),
        analog_channels: u("analog_channels"),
        analog_samples: u("analog_samples"),
        xyz_mm: load_f64(&file("points")),
        analog: load_f64(&file("analog")),
        residual_mm: (reader == "c3d").then(|| load_f64(&file("residual"))),
    })
}

fn known(file: &str, reader: &str, aspect: &str) -> bool {
    KNOWN
        .iter()
        .any(|(f, r, a, _)| *f == file && *r == reader && *a == aspect)
}

/// Compares jointfit with one oracle; returns (summary cell, max diff mm, failures).
fn compare(file: &str, reader: &str, ours: &C3d, o: &Oracle) -> (String, f64, Vec<String>) {
    let mut fails = Vec::new();
    if known(file, reader, "layout") {
        return (format!("known ({}x{})", o.frames, o.points), 0.0, fails);
    }
    if !compare_shape(file, reader, ours, o, &mut fails) {
        return ("SHAPE".into(), f64::NAN, fails);
    }
    let (present, max_diff) = compare_points(file, reader, ours, o, &mut fails);
    compare_residuals(file, reader, ours, o, &mut fails);
    let analog_note = compare_analog(file, reader, ours, o, &mut fails);
    let cell = if fails.is_empty() {
        format!("ok {present}{analog_note}")
    } else {
        "FAIL".into()
    };
    (cell, max_diff, fails)
}

/// Frames, points, labels, first frame and rate; false when the shapes differ (nothing else
/// can be compared then).
fn compare_shape(
    file: &str,
    reader: &str,
    ours: &C3d,
    o: &Oracle,
    fails: &mut Vec<String>,
) -> bool {
    let p = &ours.points;
    let np = p.n_points();
    if o.frames != p.n_frames || o.points != np {
        fails.push(format!(
            "{file} vs {reader}: {}x{} (frames x points), jointfit {}x{np}",
            o.frames, o.points, p.n_frames
        ));
        return false;
    }
    for (i, (a, b)) in p.labels.iter().zip(&o.labels).enumerate() {
        if a != b {
            fails.push(format!(
                "{file} vs {reader}: label {i} {b:?}, jointfit {a:?}"
            ));
        }
    }
    if o.first_frame != p.first_frame && !known(file, reader, "first_frame") {
        fails.push(format!(
            "{file} vs {reader}: first frame {}, jointfit {}",
            o.first_frame, p.first_frame
        ));
    }
    if o.rate > 0.0 && (o.rate - p.rate).abs() > 1e-9 * o.rate && !known(file, reader, "rate") {
        fails.push(format!(
            "{file} vs {reader}: rate {}, jointfit {}",
            o.rate, p.rate
        ));
    }
    true
}

/// Coordinates and the missing set; returns (samples present, max difference mm).
fn compare_points(
    file: &str,
    reader: &str,
    ours: &C3d,
    o: &Oracle,
    fails: &mut Vec<String>,
) -> (usize, f64) {
    let p = &ours.points;
    let np = p.n_points();
    let (mut max_diff, mut miss_mismatch, mut present) = (0.0f64, 0usize, 0usize);
    let mut first_mismatch = None;
    for (k, ours_m) in p.positions.iter().enumerate() {
        let c = &o.xyz_mm[3 * k..3 * k + 3];
        let o_missing = c.iter().any(|v| v.is_nan()) || c.iter().all(|&v| v == 0.0);
        let j_missing = ours_m.x.is_nan();
        if o_missing != j_missing {
            miss_mismatch += 1;
            first_mismatch.get_or_insert(k);
            continue;
        }
        if !j_missing {
            present += 1;
            for a in 0..3 {
                max_diff = max_diff.max((ours_m[a] * 1000.0 - c[a]).abs());
            }
        }
    }
    if miss_mismatch > 0 && !known(file, reader, "missing") {
        let k = first_mismatch.unwrap();
        fails.push(format!(
            "{file} vs {reader}: {miss_mismatch} samples missing on one side only (first: \
             frame {}, point {})",
            k / np.max(1),
            k % np.max(1)
        ));
    }
    if max_diff > TOL_MM {
        fails.push(format!(
            "{file} vs {reader}: max coordinate difference {max_diff:.3e} mm"
        ));
    }
    (present, max_diff)
}

/// Residuals (c3d only: ezc3d swaps the bytes of the residual word).
fn compare_residuals(file: &str, reader: &str, ours: &C3d, o: &Oracle, fails: &mut Vec<String>) {
    let Some(r) = &o.residual_mm else { return };
    let worst = ours
        .points
        .residuals
        .iter()
        .zip(r)
        .filter(|(a, b)| !a.is_nan() && **b >= 0.0)
        .map(|(a, b)| (a * 1000.0 - b).abs())
        .fold(0.0, f64::max);
    if worst > TOL_MM {
        fails.push(format!(
            "{file} vs {reader}: residuals differ by {worst:.3e} mm"
        ));
    }
}

/// Analog shape and samples; returns the note for the summary cell.
fn compare_analog(
    file: &str,
    reader: &str,
    ours: &C3d,
    o: &Oracle,
    fails: &mut Vec<String>,
) -> &'static str {
    let a = &ours.analog;
    if known(file, reader, "analog") {
        return " (analog: known)";
    }
    if (o.analog_channels, o.analog_samples) != (a.n_channels(), a.n_samples()) {
        fails.push(format!(
            "{file} vs {reader}: analog {}x{} (channels x samples), jointfit {}x{}",
            o.analog_channels,
            o.analog_samples,
            a.n_channels(),
            a.n_samples()
        ));
        return " (analog shape!)";
    }
    let worst = a
        .samples
        .iter()
        .zip(&o.analog)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1.0))
        .fold(0.0, f64::max);
    if worst > 1e-9 {
        fails.push(format!(
            "{file} vs {reader}: analog differs by {worst:.3e} (relative)"
        ));
    }
    ""
}

/// Sanity of a file no oracle reads: coordinates inside ±20 m, at least one sample present,
/// and fewer than 0.5 % of frame-to-frame steps of a point longer than 0.2 m at 100 Hz
/// (20 m/s; real data have the odd label swap, a misread layout makes most steps jump).
fn sane(c: &C3d) -> Result<(), String> {
    let p = &c.points;
    let n = p.n_points();
    let present = p.positions.iter().filter(|v| !v.x.is_nan()).count();
    if present == 0 {
        return Err("no sample present".into());
    }
    if let Some(v) = p.positions.iter().find(|v| v.amax() > 20.0) {
        return Err(format!("coordinate out of range: {v:?}"));
    }
    let max_step = 0.2 * 100.0 / p.rate.max(100.0);
    let (mut steps, mut jumps) = (0usize, 0usize);
    for f in 1..p.n_frames {
        for m in 0..n {
            let (a, b) = (p.positions[(f - 1) * n + m], p.positions[f * n + m]);
            if !a.x.is_nan() && !b.x.is_nan() {
                steps += 1;
                if (a - b).norm() > max_step {
                    jumps += 1;
                }
            }
        }
    }
    if jumps * 200 > steps {
        return Err(format!(
            "{jumps} of {steps} frame-to-frame steps jump > {max_step} m"
        ));
    }
    Ok(())
}

/// Every `.c3d` / `.C3D` file of the sample set, sorted.
fn sample_files(data: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("c3d")) {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(&data.join("c3d_reader"), &mut files);
    walk(&data.join("biobuddy_functional_vicon"), &mut files);
    files.sort();
    files
}

fn file_name(p: &Path) -> String {
    p.file_name().unwrap().to_string_lossy().into_owned()
}

/// One line of the summary table: file, frames, points, ezc3d cell, c3d cell, max diff mm.
type Row = (String, usize, usize, String, String, f64);

/// Runs `scripts/c3d_reference.py` on `files`; returns its output directory and index.
fn run_oracle(py: &Path, files: &[PathBuf]) -> (jointfit_testkit::ScratchDir, Vec<Value>) {
    let out = jointfit_testkit::scratch("c3d-ref");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/c3d_reference.py");
    let status = Command::new(py)
        .arg(&script)
        .arg(out.path())
        .args(files)
        .status()
        .expect("run the Python oracle");
    assert!(status.success(), "{} failed: {status}", script.display());
    let index: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("index.json")).unwrap()).unwrap();
    let entries = index.as_array().unwrap().clone();
    assert_eq!(entries.len(), files.len());
    (out, entries)
}

/// A file both Python readers fail on: jointfit must do what [`BOTH_FAIL`] pins.
fn both_fail_row(
    rel: String,
    name: &str,
    errors: (Option<String>, Option<String>),
    ours: &Result<C3d, C3dError>,
    fails: &mut Vec<String>,
) -> Option<Row> {
    let Some((_, expect)) = BOTH_FAIL.iter().find(|(f, _)| *f == name) else {
        fails.push(format!(
            "{rel}: both Python readers fail ({:?} / {:?}) and BOTH_FAIL does not say what \
             jointfit should do (jointfit: {:?})",
            errors.0,
            errors.1,
            ours.as_ref()
                .map(|c| c.points.n_frames)
                .map_err(|e| e.to_string())
        ));
        return None;
    };
    let cell = match (expect, ours) {
        (Expect::Rejects(is, what), Err(e)) => {
            let inner = match e {
                C3dError::InFile { source, .. } => source.as_ref(),
                e => e,
            };
            if !is(inner) {
                fails.push(format!("{rel}: expected {what}, got {e}"));
            }
            format!("rejected: {what}")
        }
        (
            Expect::Reads {
                frames,
                points,
                first_label,
            },
            Ok(c),
        ) => {
            let p = &c.points;
            if (p.n_frames, p.n_points()) != (*frames, *points)
                || p.labels.first().map(String::as_str) != Some(*first_label)
            {
                fails.push(format!(
                    "{rel}: expected {frames}x{points} starting {first_label:?}, got {}x{} \
                     starting {:?}",
                    p.n_frames,
                    p.n_points(),
                    p.labels.first()
                ));
            }
            if let Err(e) = sane(c) {
                fails.push(format!("{rel}: {e}"));
            }
            "read, sane".into()
        }
        (_, r) => {
            fails.push(format!(
                "{rel}: unexpected outcome {:?}",
                r.as_ref()
                    .map(|c| c.points.n_frames)
                    .map_err(|e| e.to_string())
            ));
            "FAIL".into()
        }
    };
    let (fr, pt) = ours
        .as_ref()
        .map_or((0, 0), |c| (c.points.n_frames, c.points.n_points()));
    Some((rel, fr, pt, "both fail".to_string(), cell, f64::NAN))
}

/// A file at least one Python reader reads: jointfit against each reader that reads it.
fn compared_row(
    rel: String,
    name: &str,
    oracles: [(&str, &Result<Oracle, String>); 2],
    ours: Result<C3d, C3dError>,
    fails: &mut Vec<String>,
) -> Option<Row> {
    let c = match ours {
        Ok(c) => c,
        Err(e) => {
            fails.push(format!(
                "{rel}: a Python reader reads it, jointfit fails: {e}"
            ));
            return None;
        }
    };
    let mut cells = BTreeMap::new();
    let mut worst = 0.0f64;
    for (reader, o) in oracles {
        let cell = match o {
            Err(e) => format!("err: {}", e.split(':').next().unwrap_or(e)),
            Ok(o) => {
                let (cell, diff, f) = compare(name, reader, &c, o);
                worst = worst.max(diff);
                fails.extend(f);
                cell
            }
        };
        cells.insert(reader, cell);
    }
    if name == "kyowadengyo.c3d" {
        if let Err(e) = sane(&c) {
            fails.push(format!("{rel}: {e}"));
        }
    }
    Some((
        rel,
        c.points.n_frames,
        c.points.n_points(),
        cells["ezc3d"].clone(),
        cells["c3d"].clone(),
        worst,
    ))
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<58} {:>6} {:>4}  {:<28} {:<28} {:>9}",
        "file", "frames", "pts", "ezc3d", "c3d", "max mm"
    );
    for (rel, fr, pt, ez, cp, d) in rows {
        println!("{rel:<58} {fr:>6} {pt:>4}  {ez:<28} {cp:<28} {d:>9.2e}");
    }
    println!("known disagreements:");
    for (f, r, a, why) in KNOWN {
        println!("  {f} / {r} / {a}: {why}");
    }
}

#[test]
fn c3d_matches_ezc3d_and_c3d_on_every_sample() {
    let Some(data) = data_dir() else { return };
    let Some(py) = python() else { return };
    let files = sample_files(&data);
    assert!(
        files.len() >= 50,
        "expected the C3D sample set, found {}",
        files.len()
    );
    let (out, entries) = run_oracle(&py, &files);
    let mut fails = Vec::new();
    let mut rows = Vec::new();
    let mut both_fail_seen = Vec::new();
    for (i, (path, entry)) in files.iter().zip(&entries).enumerate() {
        let name = file_name(path);
        let rel = path
            .strip_prefix(&data)
            .unwrap_or(path)
            .display()
            .to_string();
        let ez = oracle(&entry["ezc3d"], &out, i, "ezc3d");
        let cp = oracle(&entry["c3d"], &out, i, "c3d");
        let ours = read_c3d(path);
        let row = if ez.is_err() && cp.is_err() {
            both_fail_seen.push(name.clone());
            both_fail_row(rel, &name, (ez.err(), cp.err()), &ours, &mut fails)
        } else {
            compared_row(rel, &name, [("ezc3d", &ez), ("c3d", &cp)], ours, &mut fails)
        };
        rows.extend(row);
    }
    for (f, _) in BOTH_FAIL {
        if !both_fail_seen.iter().any(|s| s == f) {
            fails.push(format!(
                "{f} is in BOTH_FAIL but a Python reader now reads it"
            ));
        }
    }
    print_table(&rows);
    drop(out);
    assert!(
        fails.is_empty(),
        "{} failures:\n{}",
        fails.len(),
        fails.join("\n")
    );
}

/// Without Python: every sample file is read, or refused with the error BOTH_FAIL names.
#[test]
fn every_sample_file_reads_or_fails_as_pinned() {
    let Some(data) = data_dir() else { return };
    for path in sample_files(&data) {
        let name = file_name(&path);
        match (read_c3d(&path), BOTH_FAIL.iter().find(|(f, _)| *f == name)) {
            (Err(e), Some((_, Expect::Rejects(is, what)))) => {
                let C3dError::InFile { source, .. } = &e else {
                    panic!("{name}: error without the file name: {e}");
                };
                assert!(is(source), "{name}: expected {what}, got {e}");
                assert!(e.to_string().contains(&name), "{e}");
            }
            (Ok(c), expect) => {
                assert!(
                    !matches!(expect, Some((_, Expect::Rejects(..)))),
                    "{name} should be rejected"
                );
                let p = &c.points;
                assert_eq!(p.positions.len(), p.n_frames * p.n_points(), "{name}");
                if p.rate > 0.0 && p.n_points() > 0 {
                    let t = c.to_trial().unwrap_or_else(|e| panic!("{name}: {e}"));
                    assert_eq!(t.n_frames(), p.n_frames);
                }
            }
            (Err(e), _) => panic!("{name}: {e}"),
        }
    }
}

/// A file of 70,000 frames written by ezc3d (an independent writer): its header's last frame
/// saturates at 65535, POINT:FRAMES too, and no TRIAL:ACTUAL_END_FIELD is written. jointfit
/// reads every frame the writer stored (counted from the data size, with a note), and each
/// coordinate is the one written. (ezc3d 1.5 reads such a file back as 65,535 frames; the `c3d`
/// package reads 65,535 and warns that bytes remain: both cut it.)
#[test]
fn ezc3d_file_past_65535_frames_is_read_whole() {
    let Some(py) = python() else { return };
    let dir = jointfit_testkit::scratch("c3d-long");
    let path = dir.join("long.c3d");
    let code = "import sys, ezc3d, numpy as np\n\
                c = ezc3d.c3d()\n\
                c['parameters']['POINT']['RATE']['value'] = [200]\n\
                c['parameters']['POINT']['UNITS']['value'] = ['mm']\n\
                c['parameters']['POINT']['LABELS']['value'] = ['A', 'B']\n\
                n = 70000\n\
                p = np.ones((4, 2, n))\n\
                p[0, 0, :] = np.arange(n) * 0.5 + 1\n\
                p[1, 1, :] = 3000 - np.arange(n) * 0.01\n\
                c['data']['points'] = p\n\
                c.write(sys.argv[1])\n";
    let status = Command::new(&py)
        .args(["-c", code])
        .arg(&path)
        .status()
        .expect("run ezc3d");
    assert!(status.success(), "ezc3d failed to write: {status}");
    let c = read_c3d(&path).unwrap();
    let p = &c.points;
    assert_eq!((p.n_frames, p.n_points()), (70_000, 2), "{:?}", c.warnings);
    assert_eq!(p.rate, 200.0);
    assert!(
        c.warnings
            .iter()
            .any(|w| w.contains("65535") && w.contains("70000")),
        "{:?}",
        c.warnings
    );
    for f in [0, 65_534, 65_535, 69_999] {
        let a = p.positions[2 * f] * 1000.0;
        let b = p.positions[2 * f + 1] * 1000.0;
        assert!(
            (a.x - (f as f64 * 0.5 + 1.0)).abs() < 1e-3,
            "frame {f}: {a:?}"
        );
        assert!(
            (b.y - (3000.0 - f as f64 * 0.01)).abs() < 1e-3,
            "frame {f}: {b:?}"
        );
    }
}
