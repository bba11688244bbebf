//! Every sample TRC under `trc_reader/` and every real trial: read with the expected shape and
//! values, or rejected with the expected error (the comparison with OpenSim's own TRC reader
//! and the round trips are in `trc_opensim.rs`).

use std::collections::BTreeSet;
use std::path::Path;

use jointfit::trial::Trial;
use jointfit_io::trc::{read_trc, read_trc_file, TrcErrorKind, TrcNote, TrcUnits};
use jointfit_testkit::data_dir;

use crate::oracle::same;

/// What reading a file must give.
pub(crate) enum Expect {
    Read {
        markers: usize,
        frames: usize,
        rate: f64,
        units: TrcUnits,
        /// Kinds of the notes, in order.
        notes: &'static [&'static str],
        /// Whether `read_trc` (strict) refuses the file although `read_trc_file` reads it.
        strict_rejects: bool,
        /// (frame index, label, position in metres or None for missing).
        values: &'static [(usize, &'static str, Option<[f64; 3]>)],
    },
    Reject(&'static str),
}

pub(crate) struct Case {
    pub(crate) file: &'static str,
    pub(crate) expect: Expect,
}

const fn read(
    file: &'static str,
    markers: usize,
    frames: usize,
    rate: f64,
    values: &'static [(usize, &'static str, Option<[f64; 3]>)],
) -> Case {
    Case {
        file,
        expect: Expect::Read {
            markers,
            frames,
            rate,
            units: TrcUnits::Millimetres,
            notes: &[],
            strict_rejects: false,
            values,
        },
    }
}

/// An OpenCap video session's TRC (metres, 63 keypoints and augmented markers at 60 Hz); the
/// first frame's `Neck` as the file's text gives it.
fn video(name: &str, frames: usize, neck: [f64; 3]) -> Case {
    let file: &'static str =
        Box::leak(format!("opencap_video_subject0/{name}.trc").into_boxed_str());
    let values: &'static [(usize, &'static str, Option<[f64; 3]>)] =
        Box::leak(vec![(0, "Neck", Some(neck))].into_boxed_slice());
    Case {
        file,
        expect: Expect::Read {
            markers: 63,
            frames,
            rate: 60.0,
            units: TrcUnits::Metres,
            notes: &[],
            strict_rejects: false,
            values,
        },
    }
}

const fn reject(file: &'static str, kind: &'static str) -> Case {
    Case {
        file,
        expect: Expect::Reject(kind),
    }
}

pub(crate) fn cases() -> Vec<Case> {
    let mut v = reader_test_files();
    v.extend(opensim_test_files());
    v.extend(opencap_files());
    v.extend(lab_files());
    v
}

/// The test files of BTK's and OpenSim's TRC readers, and OpenSim's own gait example.
fn reader_test_files() -> Vec<Case> {
    vec![
        reject("trc_reader/btk/Empty.trc", "Empty"),
        // Header NumMarkers 66, labels row 33 names, rows with values past marker 33.
        reject("trc_reader/btk/Gait.trc", "MarkerCountMismatch"),
        reject("trc_reader/btk/Truncated.trc", "Truncated"),
        // Values from BTK's own reader test (TRCFileReaderTest.h); one label is written with
        // surrounding blanks, another with a blank inside.
        Case {
            file: "trc_reader/btk/Knee.trc",
            expect: Expect::Read {
                markers: 71,
                frames: 200,
                rate: 200.0,
                units: TrcUnits::Millimetres,
                notes: &["TrimmedLabels"],
                strict_rejects: false,
                values: &[
                    (
                        83,
                        "genou1_NewMarker1",
                        Some([0.30165476, 0.08411798, 0.13286554]),
                    ),
                    (82, "*Unnamed_71", None),
                    (
                        0,
                        "genou1_ NewMarker",
                        Some([0.25684422, 0.11324970, 0.12177992]),
                    ),
                ],
            },
        },
        read(
            "trc_reader/btk/Res16bits.trc",
            44,
            100,
            100.0,
            &[(0, "R.TETE", Some([0.22149382, -0.28470554, 1.50952161]))],
        ),
        read(
            "trc_reader/btk/T.trc",
            41,
            89,
            30.0,
            &[(3, "LBHD", Some([-0.17103949, 1.58179005, 0.07706285]))],
        ),
        read(
            "trc_reader/opensim/dataWithBlanksForMissingMarkers.trc",
            40,
            464,
            250.0,
            &[
                (0, "LTH3", None),
                (463, "RKJC", Some([1.77061169, 0.59912988, 0.50095572])),
            ],
        ),
        read(
            "trc_reader/opensim/dataWithNaNsOfDifferentCases.trc",
            14,
            5,
            250.0,
            &[
                (0, "thigh", None),
                (1, "thigh", None),
                (4, "thigh", None),
                (0, "toe", Some([0.175798014, -0.333753526, 0.033121135])),
            ],
        ),
        read(
            "trc_reader/opensim/dataWithNaNsWithSpaces.trc",
            42,
            427,
            100.0,
            &[(0, "LASI", None)],
        ),
        read(
            "trc_reader/opensim/gait10dof18musc_walk_CRLF_line_ending.trc",
            41,
            10,
            60.0,
            &[(0, "R.ASIS", Some([0.61724762, 1.05527502, 0.17078198]))],
        ),
    ]
}

/// OpenSim's format examples and its reference exports of C3D walks.
fn opensim_test_files() -> Vec<Case> {
    let mut v = Vec::new();
    v.extend([
        Case {
            file: "trc_reader/opensim/dataWithEformat.trc",
            expect: Expect::Read {
                markers: 14,
                frames: 5,
                rate: 119.88012,
                units: TrcUnits::Metres,
                notes: &[],
                strict_rejects: false,
                values: &[(0, "RFAsuperior", Some([-0.273, 0.0746, -1.57]))],
            },
        },
        Case {
            file: "trc_reader/opensim/exampleFormat.trc",
            expect: Expect::Read {
                markers: 3,
                frames: 5,
                rate: 100.0,
                units: TrcUnits::Metres,
                notes: &[],
                strict_rejects: false,
                values: &[
                    (0, "marker1", None),
                    (2, "marker2", None),
                    (4, "marker3", Some([-0.0517, 0.305, -1.7])),
                ],
            },
        },
    ]);
    // OpenSim's reference exports of walking2/5.c3d: every 10th frame kept, DataRate still
    // 250 Hz (the Time column's 25 Hz is used, as OpenSim does) and labels shifted by one cell.
    for (file, markers, frames) in [
        ("c3d_reader/opensim/std_walking2_markers.trc", 44, 126),
        ("c3d_reader/opensim/std_walking5_markers.trc", 40, 112),
    ] {
        v.push(Case {
            file,
            expect: Expect::Read {
                markers,
                frames,
                rate: 25.0,
                units: TrcUnits::Millimetres,
                notes: &["LabelsNotAligned", "RateFromTimeColumn"],
                strict_rejects: false,
                values: &[],
            },
        });
    }
    v
}

/// Every trial of OpenCap's expert subject: first-frame right knee marker (mm in the file).
fn opencap_files() -> Vec<Case> {
    let mut v = Vec::new();
    let opencap: [(&str, usize, usize, [f64; 3]); 12] = [
        ("DJ1", 51, 240, [-1104.12540, 797.70659, -461.26084]),
        ("DJ2", 51, 234, [-1196.33006, 803.95604, -458.87685]),
        ("STS1", 51, 1424, [-214.09673, 467.72728, -431.25959]),
        ("squats1", 51, 1302, [-224.52613, 502.44874, -486.55271]),
        ("squatsAsym1", 51, 1318, [-226.75726, 501.55314, -494.49971]),
        ("static1", 55, 265, [-206.41739, 501.66321, -391.87786]),
        ("walking1", 51, 143, [92.34549, 487.62379, -76.65274]),
        ("walking2", 51, 138, [226.32879, 487.75268, -51.48229]),
        ("walking3", 51, 145, [68.71607, 484.40053, -65.50757]),
        ("walkingTI1", 51, 145, [-89.19108, 504.14057, -74.22377]),
        ("walkingTO1", 51, 135, [134.71984, 488.13907, -62.46685]),
        ("walkingTS1", 51, 142, [44.36411, 497.93042, -100.77639]),
    ];
    for (name, markers, frames, first_mm) in opencap {
        let file: &'static str = Box::leak(format!("opencap_expert1/{name}.trc").into_boxed_str());
        let values: &'static [(usize, &'static str, Option<[f64; 3]>)] =
            Box::leak(vec![(0, "r_knee", Some(first_mm.map(|x| x / 1000.0)))].into_boxed_slice());
        v.push(read(file, markers, frames, 100.0, values));
    }
    v
}

/// Static and motion trials of the OpenSim example subjects, OpenCap's video keypoints and
/// the JAM subject.
fn lab_files() -> Vec<Case> {
    vec![
        read(
            "opensim_gait2392_subject01/subject01_static.trc",
            49,
            300,
            60.0,
            &[(0, "R.ASIS", Some([0.608664310, 1.072713130, 0.157442150]))],
        ),
        read(
            "opensim_gait2392_subject01/subject01_walk1.trc",
            41,
            151,
            60.0,
            &[(
                150,
                "Top.Head",
                Some([0.614139710, 1.776270510, 0.023298670]),
            )],
        ),
        Case {
            file: "opensim_hamner_subject02/subject02_running.trc",
            expect: Expect::Read {
                markers: 41,
                frames: 600,
                rate: 60.0,
                units: TrcUnits::Millimetres,
                // L.Bicep is written as 0 0 0 in every frame.
                notes: &["ZeroSamples"],
                strict_rejects: false,
                values: &[
                    (0, "R.ASIS", Some([0.809009400, 1.034518310, -0.064610810])),
                    (0, "L.Bicep", None),
                    (599, "L.Bicep", None),
                ],
            },
        },
        read(
            "opensim_hamner_subject02/subject02_static.trc",
            49,
            300,
            60.0,
            &[(0, "R.ASIS", Some([0.623995790, 1.069763310, 0.164409300]))],
        ),
        video("Asym_0", 899, [0.8907200, 1.4649397, 0.3429600]),
        video("Squats_0", 832, [0.9152100, 1.4629023, 0.3685200]),
        video("neutral", 96, [0.9814000, 1.4505270, 0.3857600]),
        read(
            "opensim_jam_healthy/overground_17.trc",
            40,
            515,
            200.0,
            &[(0, "R.Shoulder", Some([-1.697800, 1.355952, -0.080047]))],
        ),
        read(
            "opensim_jam_healthy/static1.trc",
            50,
            1204,
            200.0,
            &[(1203, "L.MT0", Some([0.624108, 0.279370, -2.261526]))],
        ),
    ]
}

fn note_kind(n: &TrcNote) -> &'static str {
    match n {
        TrcNote::MoreRowsThanHeader { .. } => "MoreRowsThanHeader",
        TrcNote::TimeDisagreesWithRate { .. } => "TimeDisagreesWithRate",
        TrcNote::TimeNotIncreasing { .. } => "TimeNotIncreasing",
        TrcNote::RateFromTimeColumn { .. } => "RateFromTimeColumn",
        TrcNote::LabelsNotAligned { .. } => "LabelsNotAligned",
        TrcNote::TrimmedLabels { .. } => "TrimmedLabels",
        TrcNote::ZeroSamples { .. } => "ZeroSamples",
        TrcNote::PartialSamples { .. } => "PartialSamples",
    }
}

pub fn error_kind(e: &TrcErrorKind) -> &'static str {
    match e {
        TrcErrorKind::Io(_) => "Io",
        TrcErrorKind::Empty => "Empty",
        TrcErrorKind::NotTrc { .. } => "NotTrc",
        TrcErrorKind::Truncated { .. } => "Truncated",
        TrcErrorKind::MissingHeaderKey { .. } => "MissingHeaderKey",
        TrcErrorKind::BadHeaderValue { .. } => "BadHeaderValue",
        TrcErrorKind::BadRate { .. } => "BadRate",
        TrcErrorKind::UnknownUnits { .. } => "UnknownUnits",
        TrcErrorKind::BadLabelsRow { .. } => "BadLabelsRow",
        TrcErrorKind::MarkerCountMismatch { .. } => "MarkerCountMismatch",
        TrcErrorKind::EmptyLabel { .. } => "EmptyLabel",
        TrcErrorKind::DuplicateLabel { .. } => "DuplicateLabel",
        TrcErrorKind::CoordinateRowMismatch { .. } => "CoordinateRowMismatch",
        TrcErrorKind::BadFrameNumber { .. } => "BadFrameNumber",
        TrcErrorKind::FrameNumberJump { .. } => "FrameNumberJump",
        TrcErrorKind::BadTime { .. } => "BadTime",
        TrcErrorKind::TooFewValues { .. } => "TooFewValues",
        TrcErrorKind::ExtraValues { .. } => "ExtraValues",
        TrcErrorKind::BadNumber { .. } => "BadNumber",
        TrcErrorKind::MissingFrames { .. } => "MissingFrames",
        TrcErrorKind::TimeMismatch { .. } => "TimeMismatch",
    }
}

/// Every file with extension `ext` under `dir`, as paths relative to `root`.
pub fn files_under(root: &Path, dir: &Path, ext: &[&str], out: &mut BTreeSet<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries {
        let p = e.unwrap().path();
        if p.is_dir() {
            files_under(root, &p, ext, out);
        } else if p
            .extension()
            .is_some_and(|x| ext.iter().any(|e| x.eq_ignore_ascii_case(e)))
        {
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
            out.insert(rel);
        }
    }
}

fn sample(trial: &Trial, frame: usize, label: &str) -> Option<[f64; 3]> {
    let k = trial.index_of(label).unwrap_or_else(|e| panic!("{e}"));
    trial.get(frame, k).map(|p| [p.x, p.y, p.z])
}

#[test]
fn every_sample_file_reads_or_fails_as_expected() {
    let Some(dir) = data_dir() else { return };
    let cases = cases();
    let covered: BTreeSet<&str> = cases.iter().map(|c| c.file).collect();
    let mut on_disk = BTreeSet::new();
    files_under(&dir, &dir, &["trc"], &mut on_disk);
    for f in &on_disk {
        assert!(
            covered.contains(f.as_str()),
            "{f} has no expectation in this test"
        );
    }
    let mut report = Vec::new();
    for case in &cases {
        let path = dir.join(case.file);
        let result = read_trc_file(&path);
        match (&case.expect, result) {
            (Expect::Reject(kind), Err(e)) => {
                assert_eq!(
                    error_kind(&e.kind),
                    *kind,
                    "{}: wrong error: {e}",
                    case.file
                );
                assert!(
                    e.to_string().contains(case.file),
                    "error must name the file: {e}"
                );
                report.push(format!("{:<62} rejected: {e}", case.file));
            }
            (Expect::Reject(kind), Ok(_)) => panic!("{}: read, expected {kind}", case.file),
            (Expect::Read { .. }, Err(e)) => panic!("{}: {e}", case.file),
            (
                Expect::Read {
                    markers,
                    frames,
                    rate,
                    units,
                    notes,
                    strict_rejects,
                    values,
                },
                Ok(f),
            ) => {
                let t = &f.trial;
                assert_eq!(t.labels().len(), *markers, "{}", case.file);
                assert_eq!(t.n_frames(), *frames, "{}", case.file);
                assert_eq!(f.header.num_markers, *markers, "{}", case.file);
                assert_eq!(f.header.num_frames, *frames, "{}", case.file);
                assert_eq!(f.times.len(), *frames, "{}", case.file);
                assert_eq!(t.rate(), *rate, "{}", case.file);
                assert_eq!(t.first_frame(), 1, "{}", case.file);
                assert_eq!(f.header.units, *units, "{}", case.file);
                let kinds: Vec<&str> = f.notes.iter().map(note_kind).collect();
                assert_eq!(&kinds, notes, "{}: notes {:?}", case.file, f.notes);
                for &(frame, label, want) in *values {
                    let got = sample(t, frame, label);
                    match (want, got) {
                        (None, None) => {}
                        (Some(w), Some(g)) => {
                            for j in 0..3 {
                                assert!(
                                    (w[j] - g[j]).abs() < 1e-12,
                                    "{}: {label} frame {frame}: {g:?} != {w:?}",
                                    case.file
                                );
                            }
                        }
                        _ => panic!(
                            "{}: {label} frame {frame}: {got:?}, want {want:?}",
                            case.file
                        ),
                    }
                }
                let strict = read_trc(&path);
                assert_eq!(
                    strict.is_err(),
                    *strict_rejects,
                    "{}: {strict:?}",
                    case.file
                );
                if let Err(e) = strict {
                    assert_eq!(error_kind(&e.kind), "TimeMismatch");
                }
                let missing = t.positions().iter().filter(|p| p.x.is_nan()).count();
                report.push(format!(
                    "{:<62} {} markers x {} frames, {} Hz, {:.1}% missing, notes {:?}",
                    case.file,
                    t.labels().len(),
                    t.n_frames(),
                    t.rate(),
                    100.0 * missing as f64 / t.positions().len().max(1) as f64,
                    kinds
                ));
            }
        }
    }
    eprintln!("{}", report.join("\n"));
}

pub fn assert_same_trial(a: &Trial, b: &Trial, what: &str) {
    assert_eq!(a.labels(), b.labels(), "{what}");
    assert_eq!(a.rate().to_bits(), b.rate().to_bits(), "{what}");
    assert_eq!(a.first_frame(), b.first_frame(), "{what}");
    assert_eq!(a.n_frames(), b.n_frames(), "{what}");
    for (i, (p, q)) in a.positions().iter().zip(b.positions()).enumerate() {
        for j in 0..3 {
            assert!(same(p[j], q[j]), "{what}: sample {i}: {p:?} vs {q:?}");
        }
    }
}
