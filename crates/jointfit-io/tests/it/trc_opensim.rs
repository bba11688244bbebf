//! The sample TRC files that read (`trc_files.rs`'s cases) against OpenSim's own TRC reader,
//! and written back.

use jointfit_io::trc::{format_trc, parse_trc_file, read_trc_file, TrcNote, TrcWriteOptions};
use jointfit_testkit::data_dir;

use crate::oracle::{self, num, same};
use crate::trc_files::{assert_same_trial, cases, Expect};

/// Our reader against OpenSim's `TimeSeriesTableVec3` on every file both accept: same labels,
/// rows, times (bit for bit), and coordinates (to a few ulps after the unit conversion); gaps
/// agree except where we read an all-zero sample as missing.
#[test]
fn opensim_reads_the_same_values() {
    let Some(dir) = data_dir() else { return };
    let readable: Vec<(String, jointfit_io::trc::TrcFile)> = cases()
        .iter()
        .filter(|c| matches!(c.expect, Expect::Read { .. }))
        .map(|c| {
            let p = dir.join(c.file);
            (p.display().to_string(), read_trc_file(&p).unwrap())
        })
        .collect();
    let args: Vec<&str> = std::iter::once("trc-read")
        .chain(readable.iter().map(|(p, _)| p.as_str()))
        .collect();
    let Some(lines) = oracle::run(&args) else {
        return;
    };
    let mut by_file: Vec<(String, Vec<Vec<String>>)> = Vec::new();
    for l in lines {
        if l[0] == "FILE" {
            by_file.push((l[1].clone(), Vec::new()));
        } else {
            by_file.last_mut().unwrap().1.push(l);
        }
    }
    assert_eq!(by_file.len(), readable.len());
    for ((path, ours), (opath, olines)) in readable.iter().zip(&by_file) {
        assert_eq!(path, opath);
        assert!(
            olines[0][0] != "ERROR",
            "OpenSim refused {path}: {:?}",
            olines[0]
        );
        let field = |k: &str| olines.iter().find(|l| l[0] == k).unwrap();
        let t = &ours.trial;
        let labels: Vec<String> = field("labels")[1..]
            .iter()
            .map(|s| s.trim().to_string())
            .collect();
        assert_eq!(labels, t.labels(), "{path}");
        assert_eq!(
            field("rows")[1].parse::<usize>().unwrap(),
            t.n_frames(),
            "{path}"
        );
        let per_metre = 1.0 / ours.header.units.to_metres();
        let rows: Vec<&Vec<String>> = olines.iter().filter(|l| l[0] == "row").collect();
        let (mut zeros, mut compared) = (0usize, 0usize);
        for (f, row) in rows.iter().enumerate() {
            assert!(
                same(num(&row[1]), ours.times[f]),
                "{path}: time of frame {f}"
            );
            for k in 0..t.labels().len() {
                let o: Vec<f64> = (0..3).map(|j| num(&row[2 + 3 * k + j])).collect();
                match t.get(f, k) {
                    None if o.iter().any(|v| v.is_nan()) => {}
                    None => {
                        assert_eq!(
                            o,
                            vec![0.0; 3],
                            "{path}: frame {f} {} missing",
                            t.labels()[k]
                        );
                        zeros += 1;
                    }
                    Some(p) => {
                        for j in 0..3 {
                            let ours_v = p[j] * per_metre;
                            assert!(
                                (ours_v - o[j]).abs() <= 4.0 * f64::EPSILON * o[j].abs(),
                                "{path}: frame {f} {} coord {j}: {ours_v} vs OpenSim {}",
                                t.labels()[k],
                                o[j]
                            );
                        }
                        compared += 1;
                    }
                }
            }
        }
        let noted = ours.notes.iter().find_map(|n| match n {
            TrcNote::ZeroSamples { count, .. } => Some(*count),
            _ => None,
        });
        assert_eq!(noted.unwrap_or(0), zeros, "{path}");
        eprintln!(
            "{path}: {compared} samples equal to OpenSim's, {zeros} zero samples read as gaps"
        );
    }
}

/// File → Trial → TRC (source units, 6 decimals, which every sample file fits) → Trial gives
/// back the same numbers bit for bit, and writing again gives the same text.
#[test]
fn real_files_round_trip_exactly() {
    let Some(dir) = data_dir() else { return };
    for case in cases() {
        if !matches!(case.expect, Expect::Read { .. }) {
            continue;
        }
        let f = read_trc_file(&dir.join(case.file)).unwrap();
        // Six decimals of a millimetre; a file in metres (OpenCap's) carries seven.
        let opts = TrcWriteOptions {
            units: f.header.units,
            decimals: match f.header.units {
                jointfit_io::trc::TrcUnits::Metres => 7,
                _ => 6,
            },
        };
        let text = format_trc(&f.trial, "copy.trc", &opts).unwrap();
        let back = parse_trc_file(&text, "copy.trc").unwrap();
        assert!(back.notes.is_empty(), "{}: {:?}", case.file, back.notes);
        assert_same_trial(&f.trial, &back.trial, case.file);
        assert_eq!(format_trc(&back.trial, "copy.trc", &opts).unwrap(), text);
    }
}
