//! TRC details on small texts: each malformed input maps to one error, odd-but-valid inputs
//! read as documented, the writer round-trips random trials, and OpenSim reads what we write.

use jointfit::trial::Trial;
use jointfit_io::trc::{
    format_trc, parse_trc, parse_trc_file, write_trc, TrcNote, TrcUnits, TrcWriteError,
    TrcWriteOptions,
};
use nalgebra::Vector3;
use proptest::prelude::*;

use crate::oracle::{self, num, same};
use crate::trc_files::{assert_same_trial, error_kind};

const HEAD: &str = "PathFileType\t4\t(X/Y/Z)\tx.trc\n\
DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n";

/// A valid file: markers A and B, three frames at 100 Hz, B missing in frames 2 and 3.
fn base() -> String {
    format!(
        "{HEAD}100\t100\t3\t2\tmm\t100\t1\t3\n\
         Frame#\tTime\tA\t\t\tB\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\
         \n\
         1\t0.00\t1\t2\t3\t4\t5\t6\n\
         2\t0.01\t1\t2\t3\t\t\t\n\
         3\t0.02\t1.5E+00\t2\t3\tNaN\tnan\tNAN\n"
    )
}

fn err_of(text: &str) -> (&'static str, String) {
    let e = parse_trc_file(text, "case.trc").expect_err("should be rejected");
    let msg = e.to_string();
    assert!(msg.starts_with("case.trc: "), "{msg}");
    (error_kind(&e.kind), msg)
}

#[test]
fn base_reads() {
    let f = parse_trc_file(&base(), "base.trc").unwrap();
    let t = &f.trial;
    assert_eq!(t.labels(), ["A", "B"]);
    assert_eq!((t.n_frames(), t.rate(), t.first_frame()), (3, 100.0, 1));
    assert_eq!(t.get(0, 1), Some(Vector3::new(0.004, 0.005, 0.006)));
    assert_eq!(t.get(2, 0), Some(Vector3::new(0.0015, 0.002, 0.003)));
    assert!(t.get(1, 1).is_none() && t.get(2, 1).is_none());
    assert_eq!(f.times, [0.0, 0.01, 0.02]);
    assert!(f.notes.is_empty(), "{:?}", f.notes);
    assert_eq!(f.header.file_name, "x.trc");
}

#[test]
fn malformed_inputs_map_to_one_error_each() {
    let b = base();
    let cases = [header_errors(&b), row_errors(&b)].concat();
    for (text, kind, fragment) in cases {
        let (got, msg) = err_of(&text);
        assert_eq!(got, kind, "{msg}");
        assert!(msg.contains(fragment), "{kind}: {msg:?} lacks {fragment:?}");
    }
}

/// (text, error kind, fragment of the message) of malformed headers and label rows of the
/// well-formed file `b`.
fn header_errors(b: &str) -> Vec<(String, &'static str, &'static str)> {
    vec![
        (String::new(), "Empty", "empty"),
        (" \n\t\n".into(), "Empty", "empty"),
        ("hello\tworld\n".into(), "NotTrc", "PathFileType"),
        (
            b.lines().take(2).collect::<Vec<_>>().join("\n"),
            "Truncated",
            "line 3",
        ),
        (
            b.lines().take(4).collect::<Vec<_>>().join("\n"),
            "Truncated",
            "line 5",
        ),
        (
            b.replace("\tUnits\t", "\tUnitz\t"),
            "MissingHeaderKey",
            "Units",
        ),
        (
            b.replace("100\t100\t3\t2", "100\t100\tx\t2"),
            "BadHeaderValue",
            "NumFrames",
        ),
        (
            b.replace("100\t100\t3\t2", "0\t100\t3\t2"),
            "BadRate",
            "DataRate",
        ),
        (
            b.replace("100\t100\t3\t2", "-5\t100\t3\t2"),
            "BadRate",
            "DataRate",
        ),
        (b.replace("\tmm\t", "\tin\t"), "UnknownUnits", "\"in\""),
        (b.replace("Frame#", "Frame"), "BadLabelsRow", "line 4"),
        (
            b.replace("\t3\t2\tmm", "\t3\t3\tmm"),
            "MarkerCountMismatch",
            "NumMarkers = 3",
        ),
        (
            b.replace("\t3\t2\tmm", "\t3\t3\tmm")
                .replace("\tB\t\t\n", "\t\t\t\tC\t\t\n"),
            "EmptyLabel",
            "marker 2",
        ),
        (
            b.replace("\tB\t", "\tA\t"),
            "DuplicateLabel",
            "markers 1 and 2",
        ),
    ]
}

/// (text, error kind, fragment of the message) of malformed data rows of `b`.
fn row_errors(b: &str) -> Vec<(String, &'static str, &'static str)> {
    vec![
        (
            b.replace("\tX2\tY2\tZ2", ""),
            "CoordinateRowMismatch",
            "expected 6",
        ),
        (
            b.replace("\n2\t0.01", "\nx\t0.01"),
            "BadFrameNumber",
            "line 8",
        ),
        (
            b.replace("\n3\t0.02", "\n4\t0.02"),
            "FrameNumberJump",
            "line 9",
        ),
        (b.replace("\t0.01\t", "\tsoon\t"), "BadTime", "line 8"),
        (
            b.replace("4\t5\t6\n", "4\n"),
            "TooFewValues",
            "marker \"B\"",
        ),
        (
            b.replace("4\t5\t6\n", "4\t5\t6\t\t7\n"),
            "ExtraValues",
            "line 7",
        ),
        (
            b.replace("\t2\t3\t4", "\t2,5\t3\t4"),
            "BadNumber",
            "marker \"A\"",
        ),
        (
            b.replace("100\t100\t3\t2", "100\t100\t4\t2"),
            "MissingFrames",
            "4 frames",
        ),
        // Absurd values must give errors, not overflow or huge allocations.
        (
            b.replace("\t3\t2\tmm", "\t3\t18446744073709551615\tmm"),
            "MarkerCountMismatch",
            "18446744073709551615",
        ),
        (
            b.replace("\n1\t0.00", "\n9223372036854775807\t0.00"),
            "FrameNumberJump",
            "line 8",
        ),
    ]
}

#[test]
fn unreadable_path_is_an_io_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("absent.trc");
    let e = jointfit_io::trc::read_trc(&p).unwrap_err();
    assert_eq!(error_kind(&e.kind), "Io");
    assert!(e.to_string().contains("absent.trc"), "{e}");
}

#[test]
fn time_column_disagreeing_with_rate() {
    // Evenly spaced at 10 Hz under DataRate 100: the Time column's rate is taken.
    let resampled = base()
        .replace("\t0.01\t", "\t0.10\t")
        .replace("\t0.02\t", "\t0.20\t");
    let t = parse_trc(&resampled, "case.trc").unwrap();
    assert_eq!(t.rate(), 10.0);
    let f = parse_trc_file(&resampled, "case.trc").unwrap();
    assert!(matches!(
        f.notes[..],
        [TrcNote::RateFromTimeColumn { header, column }] if header == 100.0 && column == 10.0
    ));
    // Unevenly spaced: no rate fits, refused.
    let text = base()
        .replace("\t0.01\t", "\t0.02\t")
        .replace("\t0.02\t1.5", "\t0.20\t1.5");
    let e = parse_trc(&text, "case.trc").unwrap_err();
    assert_eq!(error_kind(&e.kind), "TimeMismatch");
    assert!(e.to_string().contains("line 9"), "{e}");
    let f = parse_trc_file(&text, "case.trc").unwrap();
    assert!(matches!(
        f.notes[..],
        [TrcNote::TimeDisagreesWithRate {
            line: 9,
            frame: 3,
            ..
        }]
    ));
    assert_eq!(f.times, [0.0, 0.02, 0.2]);
    // Coarsely printed times are within tolerance: 60 Hz written with 2 decimals.
    let coarse = base()
        .replace("100\t100\t3", "60\t60\t3")
        .replace("\t0.01\t", "\t0.02\t")
        .replace("\t0.02\t1.5", "\t0.03\t1.5");
    assert!(parse_trc(&coarse, "coarse.trc").is_ok());
}

#[test]
fn odd_but_valid_inputs() {
    let b = base();
    let reference = parse_trc(&b, "b").unwrap();
    // Line ends: CRLF, bare CR; trailing tabs and padding everywhere; no blank line.
    for variant in [
        b.replace('\n', "\r\n"),
        b.replace('\n', "\r"),
        b.replace('\n', "\t\t\n")
            .replace("\t3\t2\t", "\t  3 \t 2\t"),
        b.replace("Z2\n\n", "Z2\n"),
        b.replace("Z2\n\n", "Z2\n\t\t\t\n"),
        b.replace("1\t2\t3\t4", "1.0E0\t 2 \t3e0\t+4"),
        b.replace("\t0.00\t", "\t0e-2147483648\t"),
        format!("\u{feff}{b}\n\n"),
    ] {
        assert_same_trial(&reference, &parse_trc(&variant, "v").unwrap(), &variant);
    }
    // Units and frame numbering.
    let cm = parse_trc(&b.replace("\tmm\t", "\tCM\t"), "cm").unwrap();
    assert_eq!(cm.get(0, 1), Some(Vector3::new(0.04, 0.05, 0.06)));
    let m = parse_trc(&b.replace("\tmm\t", "\tm\t"), "m").unwrap();
    assert_eq!(m.get(0, 1), Some(Vector3::new(4.0, 5.0, 6.0)));
    let late = b
        .replace("\n1\t0.00", "\n100\t0.00")
        .replace("\n2\t0.01", "\n101\t0.01")
        .replace("\n3\t0.02", "\n102\t0.02");
    assert_eq!(parse_trc(&late, "late").unwrap().first_frame(), 100);
    // More rows than the header says: all rows kept, with a note.
    let more = parse_trc_file(&b.replace("100\t100\t3\t2", "100\t100\t2\t2"), "more").unwrap();
    assert_eq!(more.trial.n_frames(), 3);
    assert_eq!(
        more.notes,
        [TrcNote::MoreRowsThanHeader { header: 2, rows: 3 }]
    );
    // Partial and all-zero samples become gaps, with notes.
    let odd = b
        .replace("1\t2\t3\t4\t5\t6", "1\t\t3\t4\t5\t6")
        .replace("2\t0.01\t1\t2\t3", "2\t0.01\t0\t0.000\t-0");
    let f = parse_trc_file(&odd, "odd").unwrap();
    assert!(f.trial.get(0, 0).is_none() && f.trial.get(1, 0).is_none());
    assert_eq!(
        f.notes,
        [
            TrcNote::ZeroSamples {
                count: 1,
                first_line: 8,
                marker: "A".into()
            },
            TrcNote::PartialSamples {
                count: 1,
                first_line: 7,
                marker: "A".into()
            },
        ]
    );
    // Labels shifted off the every-third-cell layout are taken in order.
    let shifted = parse_trc_file(&b.replace("Time\tA\t\t\tB\t\t", "Time\t\tA\t\tB"), "s").unwrap();
    assert_eq!(shifted.trial.labels(), ["A", "B"]);
    assert_eq!(shifted.notes, [TrcNote::LabelsNotAligned { line: 4 }]);
    // A header without rows.
    let empty = format!("{HEAD}100\t100\t0\t1\tmm\t100\t7\t0\nFrame#\tTime\tA\n\t\tX1\tY1\tZ1\n");
    let t = parse_trc(&empty, "e").unwrap();
    assert_eq!((t.n_frames(), t.labels().len(), t.first_frame()), (0, 1, 7));
}

#[test]
fn writer_layout_and_errors() {
    let t = parse_trc(&base(), "b").unwrap();
    let text = format_trc(&t, "out.trc", &TrcWriteOptions::default()).unwrap();
    let expected = format!(
        "{HEAD}100\t100\t3\t2\tmm\t100\t1\t3\n\
         Frame#\tTime\tA\t\t\tB\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\
         \n\
         1\t0.000000\t1.00000\t2.00000\t3.00000\t4.00000\t5.00000\t6.00000\n\
         2\t0.010000\t1.00000\t2.00000\t3.00000\tNaN\tNaN\tNaN\n\
         3\t0.020000\t1.50000\t2.00000\t3.00000\tNaN\tNaN\tNaN\n"
    )
    .replace("x.trc", "out.trc");
    assert_eq!(text, expected);
    let m = TrcWriteOptions {
        units: TrcUnits::Metres,
        decimals: 3,
    };
    assert!(format_trc(&t, "x", &m)
        .unwrap()
        .contains("\t0.002\t0.003\t0.004\t"));

    // A present sample that prints as 0 0 0 is written as the gap it would read back as (`NaN`).
    let tiny = Trial::new(
        vec!["T".into()],
        50.0,
        1,
        vec![Vector3::new(1e-9, -2e-9, 0.0)],
    )
    .unwrap();
    let text = format_trc(&tiny, "x", &TrcWriteOptions::default()).unwrap();
    assert!(text.ends_with("\n1\t0.000000\tNaN\tNaN\tNaN\n"), "{text}");

    let bad = |label: &str| {
        Trial::new(
            vec![label.to_string()],
            100.0,
            1,
            vec![Vector3::new(1.0, 2.0, 3.0)],
        )
        .unwrap()
    };
    for label in ["", "a\tb", " lead", "trail ", "two\nlines"] {
        let e = format_trc(&bad(label), "x", &TrcWriteOptions::default()).unwrap_err();
        assert!(
            matches!(e, TrcWriteError::BadLabel { marker: 1, .. }),
            "{e}"
        );
    }
    let too_fine = TrcWriteOptions {
        units: TrcUnits::Millimetres,
        decimals: 16,
    };
    assert!(matches!(
        format_trc(&t, "x", &too_fine),
        Err(TrcWriteError::TooManyDecimals { decimals: 16 })
    ));
    let dir = tempfile::tempdir().unwrap();
    let e = write_trc(
        &dir.path().join("no/such/dir.trc"),
        &t,
        &TrcWriteOptions::default(),
    );
    assert!(matches!(e, Err(TrcWriteError::Io { .. })));
}

fn arb_trial() -> impl Strategy<Value = Trial> {
    let rate = prop_oneof![Just(100.0), Just(60.0), Just(119.88012), 0.5f64..5000.0];
    (0usize..5, 0usize..20, rate, -50i64..5000).prop_flat_map(|(nm, nf, rate, first)| {
        let labels = proptest::collection::vec("[A-Za-z*][A-Za-z0-9_. #-]{0,8}[A-Za-z0-9]", nm);
        let sample = prop_oneof![
            1 => Just(None),
            4 => (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..3.0).prop_map(Some),
        ];
        let samples = proptest::collection::vec(sample, nm * nf);
        (labels, samples).prop_map(move |(labels, samples)| {
            let labels = labels
                .into_iter()
                .enumerate()
                .map(|(i, l)| format!("{l}_{i}"))
                .collect();
            let positions = samples
                .into_iter()
                .map(|s| s.map_or(Vector3::repeat(f64::NAN), |(x, y, z)| Vector3::new(x, y, z)))
                .collect();
            Trial::new(labels, rate, first, positions).unwrap()
        })
    })
}

fn arb_options() -> impl Strategy<Value = TrcWriteOptions> {
    let units = prop_oneof![
        Just(TrcUnits::Millimetres),
        Just(TrcUnits::Centimetres),
        Just(TrcUnits::Metres)
    ];
    (units, 0usize..=8).prop_map(|(units, decimals)| TrcWriteOptions { units, decimals })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Trial → TRC → Trial → TRC → Trial: the second write repeats the first byte for byte,
    /// the second read equals the first bit for bit, and the first read is the original
    /// rounded to the written precision (a sample rounding to 0 0 0 becomes a gap).
    #[test]
    fn trc_round_trip(trial in arb_trial(), opts in arb_options()) {
        let text1 = format_trc(&trial, "p.trc", &opts).unwrap();
        let f = parse_trc_file(&text1, "p.trc").unwrap();
        prop_assert!(f.notes.iter().all(|n| matches!(n, TrcNote::ZeroSamples { .. })), "{:?}", f.notes);
        let back = f.trial;
        let text2 = format_trc(&back, "p.trc", &opts).unwrap();
        prop_assert_eq!(&text1, &text2);
        assert_same_trial(&back, &parse_trc(&text2, "p.trc").unwrap(), "second read");

        prop_assert_eq!(back.labels(), trial.labels());
        prop_assert_eq!(back.rate().to_bits(), trial.rate().to_bits());
        prop_assert_eq!(back.first_frame(), trial.first_frame());
        prop_assert_eq!(back.n_frames(), trial.n_frames());
        let per_metre = 1.0 / opts.units.to_metres();
        let half_step = 0.5 * 10f64.powi(-(opts.decimals as i32));
        for (p, q) in trial.positions().iter().zip(back.positions()) {
            if p.x.is_nan() {
                prop_assert!(q.x.is_nan());
                continue;
            }
            let rounds_to_zero = p.iter().all(|v| {
                format!("{:.*}", opts.decimals, v * per_metre).parse::<f64>().unwrap() == 0.0
            });
            if rounds_to_zero {
                prop_assert!(q.x.is_nan());
                continue;
            }
            for j in 0..3 {
                let err = (p[j] - q[j]).abs() * per_metre;
                prop_assert!(err <= half_step * (1.0 + 1e-9) + 1e-12, "{} vs {}", p[j], q[j]);
            }
        }
    }
}

/// OpenSim's TRC reader on a file we wrote: same labels, rows, rate, values and gaps.
#[test]
fn opensim_reads_our_trc() {
    let nan = Vector3::repeat(f64::NAN);
    let labels: Vec<String> = ["R.ASIS", "L ASIS", "knee_lat"].map(String::from).to_vec();
    let mut positions = Vec::new();
    for f in 0..40 {
        let t = f as f64 / 120.0;
        positions.push(Vector3::new(0.6 + t, 1.05 - 0.01 * t, 0.17));
        positions.push(if f % 7 == 3 {
            nan
        } else {
            Vector3::new(-0.2 * t, 1.0, -0.1)
        });
        // The last marker has gaps too: a row's last cells are then the gap's.
        positions.push(if f % 5 == 2 {
            nan
        } else {
            Vector3::new(0.5, 0.5 + (f as f64).sin() * 1e-3, 1e-7 * f as f64 + 0.01)
        });
    }
    let trial = Trial::new(labels, 120.0, 11, positions).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ours.trc");
    let opts = TrcWriteOptions::default();
    write_trc(&path, &trial, &opts).unwrap();
    let written = parse_trc(&std::fs::read_to_string(&path).unwrap(), "ours").unwrap();
    let Some(lines) = oracle::run(&["trc-read", path.to_str().unwrap()]) else {
        return;
    };
    let field = |k: &str| lines.iter().find(|l| l[0] == k).unwrap().clone();
    assert_eq!(field("labels")[1..], *written.labels());
    assert_eq!(field("rows")[1], "40");
    assert_eq!(field("units")[1], "mm");
    assert_eq!(num(&field("rate")[1]), 120.0);
    let rows: Vec<&Vec<String>> = lines.iter().filter(|l| l[0] == "row").collect();
    let mut gaps = 0;
    for (f, row) in rows.iter().enumerate() {
        assert!((num(&row[1]) - f as f64 / 120.0).abs() < 1e-6);
        for k in 0..3 {
            for j in 0..3 {
                let o = num(&row[2 + 3 * k + j]);
                match written.get(f, k) {
                    None => {
                        assert!(o.is_nan(), "frame {f} marker {k}: OpenSim {o}");
                        gaps += 1;
                    }
                    Some(p) => assert!(
                        same(o, p[j] * 1000.0)
                            || (o - p[j] * 1000.0).abs() <= 4.0 * f64::EPSILON * o.abs(),
                        "frame {f} marker {k}: OpenSim {o} vs {}",
                        p[j] * 1000.0
                    ),
                }
            }
        }
    }
    assert_eq!(gaps, 3 * (6 + 8));
}
