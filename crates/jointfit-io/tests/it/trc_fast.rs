//! The TRC reader's fast path and selective reads (`read_trc_selected`) against an oracle
//! written here: each cell split by tabs and parsed by `str::parse::<f64>`, times the unit.

use jointfit_io::trc::{parse_trc_file, parse_trc_selected, read_trc_file, TrcErrorKind};
use jointfit_testkit::data_files;

/// The positions the oracle reads from `text` (labels of line 4 in every third cell from
/// the third): per data row, per marker, `Some([x, y, z])` in metres or `None` for a gap
/// (a blank or non-finite cell, or `0 0 0`).
fn oracle(text: &str, markers: usize, scale: f64) -> Vec<Vec<Option<[f64; 3]>>> {
    let sep = if text.contains('\n') { '\n' } else { '\r' };
    text.split(sep)
        .skip(5)
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let cells: Vec<&str> = l.split('\t').collect();
            (0..markers)
                .map(|k| {
                    let mut xyz = [0.0; 3];
                    for (j, v) in xyz.iter_mut().enumerate() {
                        let x: f64 = cells[2 + 3 * k + j].trim().parse().ok()?;
                        if !x.is_finite() {
                            return None;
                        }
                        *v = x * scale;
                    }
                    (xyz != [0.0; 3]).then_some(xyz)
                })
                .collect()
        })
        .collect()
}

/// On every TRC file of the shared data that reads: every position has the bits of the
/// oracle's, and a read of every other marker gives those markers' columns of the full read,
/// bit for bit, with the same times and frames.
#[test]
fn every_shared_trc_reads_bit_identically() {
    let Some(files) = data_files(&["trc"]) else {
        return;
    };
    assert!(files.len() >= 20, "{} TRC files", files.len());
    let mut read = 0;
    for path in &files {
        let Ok(full) = read_trc_file(path) else {
            continue;
        };
        read += 1;
        let bytes = std::fs::read(path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let t = &full.trial;
        let expected = oracle(text, t.labels().len(), full.header.units.to_metres());
        assert_eq!(expected.len(), t.n_frames(), "{}", path.display());
        for (f, row) in expected.iter().enumerate() {
            for (k, e) in row.iter().enumerate() {
                let got = t.frame(f)[k];
                match e {
                    Some(xyz) => {
                        let bits: Vec<u64> = xyz.iter().map(|v| v.to_bits()).collect();
                        let got_bits: Vec<u64> = got.iter().map(|v| v.to_bits()).collect();
                        assert_eq!(got_bits, bits, "{} row {f} marker {k}", path.display());
                    }
                    None => assert!(got.x.is_nan(), "{} row {f} marker {k}", path.display()),
                }
            }
        }
        // Every other marker, starting with the second: runs of kept and skipped columns.
        let keep: Vec<String> = t.labels().iter().skip(1).step_by(2).cloned().collect();
        let select = |l: &str| keep.iter().any(|k| k == l);
        let part = parse_trc_selected(text, &path.display().to_string(), Some(&select)).unwrap();
        assert_eq!(part.trial.labels(), &keep[..], "{}", path.display());
        assert_eq!(part.times, full.times);
        assert_eq!(part.trial.first_frame(), t.first_frame());
        assert_eq!(part.trial.times(), t.times());
        for f in 0..t.n_frames() {
            for (i, k) in (1..t.labels().len()).step_by(2).enumerate() {
                let (a, b) = (part.trial.frame(f)[i], t.frame(f)[k]);
                for j in 0..3 {
                    assert_eq!(a[j].to_bits(), b[j].to_bits(), "{}", path.display());
                }
            }
        }
    }
    assert!(read >= 20, "{read} files read");
}

/// A small file of three markers whose row 2 has the given cells after the time.
fn small(row2: &str) -> String {
    format!(
        "PathFileType\t4\t(X/Y/Z)\tt.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n\
         100\t100\t2\t3\tmm\nFrame#\tTime\tA\t\t\tB\t\t\tC\t\t\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\t\
         Y3\tZ3\n1\t0\t1\t2\t3\t4\t5\t6\t7\t8\t9\n2\t0.01\t{row2}\n"
    )
}

/// Rows the fast path leaves to the general one read the same (exponents, NaN, blanks, a
/// partial and a zero sample, padding, a trailing tab); selective reads keep their notes.
#[test]
fn unusual_rows_read_like_the_general_path() {
    for row in [
        "1e1\t2\t3\t4\t5\t6\t7\t8\t9",
        " 1.5 \t+2\t-3.\t\t\t\t7\t8\t9\t",
        "NaN\tnan\tNAN\t4\t5\t6\t0\t0\t0",
        "1\t\t3\t4\t5\t6\t7\t8\t9",
        "12345678901234567890\t0.1234567890123456789012\t3\t4\t5\t6\t7\t8\t9",
    ] {
        let text = small(row);
        let full = parse_trc_file(&text, "t.trc").unwrap();
        let oracle = oracle(&text, 3, 1e-3);
        for (f, r) in oracle.iter().enumerate() {
            for (k, e) in r.iter().enumerate() {
                let got = full.trial.frame(f)[k];
                match e {
                    Some(xyz) => assert_eq!(
                        [got.x, got.y, got.z].map(f64::to_bits),
                        xyz.map(f64::to_bits),
                        "{row}"
                    ),
                    None => assert!(got.x.is_nan(), "{row}"),
                }
            }
        }
        let part = parse_trc_selected(&text, "t.trc", Some(&|l: &str| l != "B")).unwrap();
        assert_eq!(
            part.trial.frame(1)[0].x.to_bits(),
            full.trial.frame(1)[0].x.to_bits()
        );
        assert_eq!(
            part.trial.frame(1)[1].x.to_bits(),
            full.trial.frame(1)[2].x.to_bits()
        );
    }
}

/// A selective read steps over the other markers' cells unread, but still refuses a short
/// row (naming the marker where it ends) and a value after the last marker.
#[test]
fn selective_reads_still_check_the_row() {
    let skip_b = |l: &str| l != "B";
    let bad_in_b = small("1\t2\t3\tx\t5\t6\t7\t8\t9");
    let e = parse_trc_file(&bad_in_b, "t.trc").unwrap_err();
    assert!(
        matches!(&e.kind, TrcErrorKind::BadNumber { line: 7, marker, .. } if marker == "B"),
        "{e}"
    );
    assert!(parse_trc_selected(&bad_in_b, "t.trc", Some(&skip_b)).is_ok());

    let short = small("1\t2\t3\t4\t5\t6\t7");
    for select in [None, Some(&skip_b as &dyn Fn(&str) -> bool)] {
        let e = parse_trc_selected(&short, "t.trc", select).unwrap_err();
        assert!(
            matches!(&e.kind, TrcErrorKind::TooFewValues { line: 7, marker, .. } if marker == "C"),
            "{e}"
        );
    }
    let extra = small("1\t2\t3\t4\t5\t6\t7\t8\t9\t\t10");
    let e = parse_trc_selected(&extra, "t.trc", Some(&skip_b)).unwrap_err();
    assert!(
        matches!(
            e.kind,
            TrcErrorKind::ExtraValues {
                line: 7,
                column: 13,
                ..
            }
        ),
        "{e}"
    );
    // A selection that keeps no marker reads them all.
    let none = parse_trc_selected(&bad_in_b.replace('x', "4"), "t.trc", Some(&|_: &str| false));
    assert_eq!(none.unwrap().trial.labels().len(), 3);
    // A skipped marker's cells may be anything; the row must still hold them.
    let short_in_b = small("1\t2\t3\t4");
    let e = parse_trc_selected(&short_in_b, "t.trc", Some(&skip_b)).unwrap_err();
    assert!(
        matches!(&e.kind, TrcErrorKind::TooFewValues { marker, .. } if marker == "B"),
        "{e}"
    );
}
