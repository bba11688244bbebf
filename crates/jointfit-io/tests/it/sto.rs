//! .mot/.sto: every file in the data directory, OpenSim reading what we write, us reading what
//! OpenSim writes, older layouts (malformed inputs and round trips are in `sto_edges.rs`).

use std::collections::BTreeSet;
use std::path::Path;

use jointfit_io::sto::{parse_sto, read_sto, write_sto, Table};
use jointfit_testkit::data_dir;

use crate::oracle::{self, num, same};
use crate::trc_files::files_under;

/// What OpenSim's two readers made of one file.
#[derive(Default, Debug)]
struct Seen {
    tst_labels: Vec<String>,
    tst_in_degrees: String,
    tst_rows: Vec<Vec<f64>>,
    tst_error: Option<String>,
    storage_name: String,
    storage_labels: Vec<String>,
    storage_in_degrees: String,
    storage_rows: Vec<Vec<f64>>,
    storage_error: Option<String>,
}

/// Runs `sto-read` on the files; `None` without Python.
fn opensim_read(paths: &[&Path]) -> Option<Vec<Seen>> {
    let mut args = vec!["sto-read".to_string()];
    args.extend(paths.iter().map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let lines = oracle::run(&args)?;
    let mut out: Vec<Seen> = Vec::new();
    for l in lines {
        if l[0] == "FILE" {
            out.push(Seen::default());
            continue;
        }
        let s = out.last_mut().unwrap();
        let rest = || l[2..].to_vec();
        let values = || l[2..].iter().map(|v| num(v)).collect::<Vec<f64>>();
        match (l[0].as_str(), l[1].as_str()) {
            ("TST", "labels") => s.tst_labels = rest(),
            ("TST", "inDegrees") => s.tst_in_degrees = l[2].clone(),
            ("TST", "row") => s.tst_rows.push(values()),
            ("TST", "error") => s.tst_error = Some(l[2].clone()),
            ("STORAGE", "name") => s.storage_name = l.get(2).cloned().unwrap_or_default(),
            ("STORAGE", "labels") => s.storage_labels = rest(),
            ("STORAGE", "inDegrees") => s.storage_in_degrees = l[2].clone(),
            ("STORAGE", "row") => s.storage_rows.push(values()),
            ("STORAGE", "error") => s.storage_error = Some(l[2].clone()),
            _ => {}
        }
    }
    assert_eq!(out.len(), paths.len());
    Some(out)
}

pub(crate) fn assert_rows_identical(ours: &[Vec<f64>], theirs: &[Vec<f64>], what: &str) {
    assert_eq!(ours.len(), theirs.len(), "{what}: row count");
    for (i, (a, b)) in ours.iter().zip(theirs).enumerate() {
        assert_eq!(a.len(), b.len(), "{what}: row {i} length");
        for (j, (x, y)) in a.iter().zip(b).enumerate() {
            assert!(
                same(*x, *y),
                "{what}: row {i} column {j}: ours {x:e}, OpenSim {y:e}"
            );
        }
    }
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// Both OpenSim readers agree with ours, bit for bit, on every value.
fn assert_opensim_agrees(table: &Table, seen: &Seen, what: &str, storage_too: bool) {
    assert!(
        seen.tst_error.is_none(),
        "{what}: TimeSeriesTable: {:?}",
        seen.tst_error
    );
    assert_eq!(seen.tst_labels, table.columns, "{what}");
    assert_eq!(seen.tst_in_degrees, yes_no(table.in_degrees), "{what}");
    assert_rows_identical(
        &table.rows,
        &seen.tst_rows,
        &format!("{what} (TimeSeriesTable)"),
    );
    if storage_too {
        assert!(
            seen.storage_error.is_none(),
            "{what}: Storage: {:?}",
            seen.storage_error
        );
        assert_eq!(seen.storage_name, table.name, "{what}");
        assert_eq!(seen.storage_labels, table.columns, "{what}");
        assert_eq!(seen.storage_in_degrees, yes_no(table.in_degrees), "{what}");
        assert_rows_identical(
            &table.rows,
            &seen.storage_rows,
            &format!("{what} (Storage)"),
        );
    }
}

#[test]
fn every_storage_file_in_the_data_reads_as_opensim_reads_it() {
    let Some(dir) = data_dir() else { return };
    let mut files = BTreeSet::new();
    files_under(&dir, &dir, &["mot", "sto"], &mut files);
    assert!(
        files.len() >= 4,
        "expected the reference .mot files, found {files:?}"
    );
    let paths: Vec<_> = files.iter().map(|f| dir.join(f)).collect();
    let tables: Vec<Table> = paths
        .iter()
        .map(|p| read_sto(p).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    for (f, t) in files.iter().zip(&tables) {
        assert_eq!(t.columns[0], "time", "{f}");
        assert!(t.rows.iter().all(|r| r.len() == t.columns.len()), "{f}");
        eprintln!(
            "{f}: {:?}, {} columns x {} rows, inDegrees={}, {} extra header lines",
            t.name,
            t.columns.len(),
            t.rows.len(),
            yes_no(t.in_degrees),
            t.extra_header.len()
        );
    }
    let ik = &tables[files
        .iter()
        .position(|f| f.ends_with("subject01_walk1_ik.mot"))
        .unwrap()];
    assert_eq!(
        (ik.name.as_str(), ik.rows.len(), ik.columns.len()),
        ("Coordinates", 211, 24)
    );
    assert!(ik.in_degrees);
    assert_eq!(ik.column("knee_angle_r").unwrap()[0], -19.85408256);
    assert_eq!(ik.rows[0][0], 0.5);
    assert!(ik
        .extra_header
        .contains(&"Angles are in degrees.".to_string()));

    let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
    let Some(seen) = opensim_read(&refs) else {
        return;
    };
    for ((f, t), s) in files.iter().zip(&tables).zip(&seen) {
        assert_opensim_agrees(t, s, f, true);
    }
}

/// Awkward numbers: thirds, signed zero, tiny and huge magnitudes, many digits.
pub(crate) fn awkward(i: usize, j: usize) -> f64 {
    let x = (i * 7 + j * 3) as f64;
    match (i + j) % 6 {
        0 => x / 3.0,
        1 => -x * 1e-9 - 1e-300,
        2 => (x * 0.1).sin() * 180.0 / std::f64::consts::PI,
        3 => -0.0,
        4 => 1.0e20 / (x + 1.0),
        _ => -12_345.678_901_234_5 + x,
    }
}

pub(crate) fn joint_angles() -> Table {
    let mut t = Table::new(
        "Coordinates",
        &[
            "pelvis_tilt",
            "hip_flexion_r",
            "knee_angle_r",
            "ankle_angle_r",
            "pelvis_tx",
        ],
        true,
    );
    t.extra_header = vec![
        "Units are S.I. units (second, meters, Newtons, ...)".into(),
        "Angles are in degrees.".into(),
        String::new(),
    ];
    for i in 0..25 {
        let mut row = vec![i as f64 / 60.0];
        row.extend((1..6).map(|j| awkward(i, j)));
        t.rows.push(row);
    }
    t
}

fn marker_errors(with_gap: bool) -> Table {
    let mut t = Table::new(
        "Marker errors",
        &[
            "total_squared_error",
            "marker_error_RMS",
            "marker_error_max",
            "R.ASIS",
        ],
        false,
    );
    t.extra_header = vec![
        "DataType=double".into(),
        "# per-frame marker errors, metres".into(),
    ];
    for i in 0..30 {
        let e = 0.004 + 1e-4 * (i as f64).cos();
        let asis = if with_gap && i % 10 == 4 {
            f64::NAN
        } else {
            e * 0.9
        };
        t.rows
            .push(vec![0.5 + i as f64 * 0.01, 5.0 * e * e, e, 2.5 * e, asis]);
    }
    t
}

/// OpenSim 4.6 reads what `write_sto` writes, with both of its readers, to the last bit.
#[test]
fn opensim_reads_what_we_write() {
    let dir = tempfile::tempdir().unwrap();
    let mut unnamed = marker_errors(false);
    unnamed.name.clear();
    unnamed.extra_header.clear();
    let tables = [
        ("joint_angles.mot", joint_angles()),
        ("marker_errors.sto", marker_errors(false)),
        ("unnamed.sto", unnamed),
        ("with_gaps.sto", marker_errors(true)),
    ];
    let mut paths = Vec::new();
    for (name, t) in &tables {
        let p = dir.path().join(name);
        write_sto(&p, t).unwrap();
        // Our own reader gives the table back exactly.
        let back = read_sto(&p).unwrap();
        assert_eq!(back.name, t.name);
        assert_eq!(back.columns, t.columns);
        assert_eq!(back.in_degrees, t.in_degrees);
        assert_eq!(back.extra_header, t.extra_header);
        assert_rows_identical(&back.rows, &t.rows, name);
        paths.push(p);
    }
    let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
    let Some(seen) = opensim_read(&refs) else {
        return;
    };
    for ((name, t), s) in tables.iter().zip(&seen) {
        // OpenSim's Storage cannot read NaN (it stops at the first row holding one).
        let storage_too = !t.rows.iter().flatten().any(|v| v.is_nan());
        assert_opensim_agrees(t, s, name, storage_too);
        if !storage_too {
            eprintln!(
                "{name}: TimeSeriesTable read all {} rows; Storage read {} (it stops at NaN)",
                s.tst_rows.len(),
                s.storage_rows.len()
            );
        }
    }
}

/// Files written by OpenSim itself (STOFileAdapter and Storage) read as OpenSim reads them,
/// and hold the values that went in to the precision each writer prints.
#[test]
fn we_read_what_opensim_writes() {
    let dir = tempfile::tempdir().unwrap();
    let Some(lines) = oracle::run(&["sto-write", dir.path().to_str().unwrap()]) else {
        return;
    };
    let written: Vec<&str> = lines
        .iter()
        .filter(|l| l[0] == "WROTE")
        .map(|l| l[1].as_str())
        .collect();
    let labels: Vec<String> = lines.iter().find(|l| l[1] == "labels").unwrap()[2..].to_vec();
    let values: Vec<Vec<f64>> = lines
        .iter()
        .filter(|l| l[0] == "VALUES" && l[1] == "row")
        .map(|l| l[2..].iter().map(|v| num(v)).collect())
        .collect();
    let paths: Vec<&Path> = written.iter().map(Path::new).collect();
    let tables: Vec<Table> = paths.iter().map(|p| read_sto(p).unwrap()).collect();
    let seen = opensim_read(&paths).unwrap();
    // STOFileAdapter: version=3 header without a name; 16 significant digits.
    let adapter = &tables[0];
    assert_eq!(adapter.name, "");
    assert!(adapter.in_degrees);
    assert!(adapter
        .extra_header
        .contains(&"DataType=double".to_string()));
    assert_opensim_agrees(adapter, &seen[0], written[0], true);
    // Storage: version=1 header with a name; 8 decimals.
    let storage = &tables[1];
    assert_eq!(storage.name, "Coordinates");
    assert!(storage.in_degrees);
    assert_opensim_agrees(storage, &seen[1], written[1], true);
    for (t, tol_rel, tol_abs) in [(adapter, 1e-15, 0.0), (storage, 0.0, 5.000_001e-9)] {
        assert_eq!(t.columns, labels);
        assert_eq!(t.rows.len(), values.len());
        for (r, v) in t.rows.iter().zip(&values) {
            for (a, b) in r.iter().zip(v) {
                assert!((a - b).abs() <= tol_rel * b.abs() + tol_abs, "{a} vs {b}");
            }
        }
    }
}

#[test]
fn older_and_odd_layouts() {
    // SIMM-era header words, blank-separated numbers, CRLF.
    let simm = "walk\r\ndatacolumns 3\r\ndatarows 2\r\nrange 0 1\r\nendheader\r\n\
                time  a  b\r\n0.0  1.5  -2\r\n1.0  1e-3  4\r\n";
    let t = parse_sto(simm, "simm.mot").unwrap();
    assert_eq!(
        (t.name.as_str(), t.columns.len(), t.rows.len()),
        ("walk", 3, 2)
    );
    assert_eq!(t.extra_header, ["range 0 1"]);
    assert_eq!(t.rows[1], [1.0, 1e-3, 4.0]);
    assert!(!t.in_degrees);
    // OpenSim 4 layout, trailing tabs, padded numbers, NaN spellings.
    let v3 = "inDegrees=no\t\t\nDataType=double\nversion=3\nendheader\t\t\n\
              time\tx\ty\t\n   0.0\t NaN\t-nan\t\n   0.5\tnan\t 2.5E+00\t\n";
    let t = parse_sto(v3, "v3.sto").unwrap();
    assert_eq!(t.name, "");
    assert_eq!(t.extra_header, ["DataType=double"]);
    assert_eq!(t.columns, ["time", "x", "y"]);
    assert!(t.rows[0][1].is_nan() && t.rows[0][2].is_nan() && t.rows[1][1].is_nan());
    assert_eq!(t.rows[1][2], 2.5);
}
