//! TRC files as the field writes them, with OpenSim 4.6 as the oracle: every variant OpenSim
//! reads, we read with the same labels, frame count and values. The variants: OpenSim's own
//! pipeline layout (doubled tabs on the header value line, `100.0` as NumFrames and
//! NumMarkers), doubled tabs on both header lines, Windows line ends, blank cells between
//! header values. Variants OpenSim refuses (extra header fields, trailing data columns) must
//! not panic here; what we do with them is stated in the asserts.

use jointfit_io::trc::read_trc_file;
use jointfit_testkit::scratch;

use super::oracle::{self, num};

const KEYS: &str = "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t\
                    OrigDataStartFrame\tOrigNumFrames";

/// A 6-frame, 3-marker trial in mm with the given header lines, row suffix and line end.
fn variant(keys: &str, values: &str, row_end: &str, nl: &str) -> String {
    let mut t = String::new();
    t.push_str("PathFileType\t4\t(X/Y/Z)\tfield.trc\n");
    t.push_str(keys);
    t.push('\n');
    t.push_str(values);
    t.push('\n');
    t.push_str("Frame#\tTime\tR.ASIS\t\t\tR.Knee\t\t\tR.Ankle\t\t\n");
    t.push_str("\t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\n\n");
    for f in 0..6 {
        t.push_str(&format!("{}\t{:.3}", f + 1, f as f64 / 100.0));
        for m in 0..3 {
            for c in 0..3 {
                let v = 100.0 * m as f64 + 7.25 * c as f64 + 0.5 * f as f64 - 300.0;
                t.push_str(&format!("\t{v:.5}"));
            }
        }
        t.push_str(row_end);
        t.push('\n');
    }
    t.replace('\n', nl)
}

#[test]
fn field_trc_variants_read_as_opensim_reads_them() {
    let tmp = scratch("trc-field");
    let dir = tmp.path();
    let cases = field_variants();
    let paths: Vec<String> = cases
        .iter()
        .map(|(name, text, _)| {
            let p = dir.join(format!("{name}.trc"));
            std::fs::write(&p, text).unwrap();
            p.display().to_string()
        })
        .collect();
    let Some(by_file) = opensim_reads(&paths) else {
        return;
    };
    assert_eq!(by_file.len(), cases.len());
    for (((name, _, opensim_reads), path), theirs) in cases.iter().zip(&paths).zip(&by_file) {
        let refused = theirs[0][0] == "ERROR";
        assert_eq!(
            !refused, *opensim_reads,
            "{name}: OpenSim said {:?}",
            theirs[0]
        );
        let ours = read_trc_file(std::path::Path::new(path));
        if refused {
            // Extra header fields are matched by name (harmless); a value beyond the last
            // marker is an error naming the line, as in OpenSim.
            match *name {
                "extra-header-fields" => assert!(ours.is_ok(), "{name}: {:?}", ours.err()),
                _ => {
                    let e = ours.expect_err(name).to_string();
                    assert!(e.contains("line 7"), "{name}: {e}");
                }
            }
            continue;
        }
        let ours = ours.unwrap_or_else(|e| panic!("{name}: {e}"));
        let field = |k: &str| theirs.iter().find(|l| l[0] == k).unwrap();
        let t = &ours.trial;
        assert_eq!(&field("labels")[1..], t.labels(), "{name}");
        let rows = field("rows")[1].parse::<usize>().unwrap();
        assert_eq!(rows, t.n_frames(), "{name}");
        assert_eq!(rows, ours.header.num_frames, "{name}: header frame count");
        assert_eq!(ours.header.num_markers, 3, "{name}");
        assert_eq!(ours.header.data_rate, 100.0, "{name}");
        let per_metre = 1.0 / ours.header.units.to_metres();
        for (f, row) in theirs.iter().filter(|l| l[0] == "row").enumerate() {
            for k in 0..t.labels().len() {
                let p = t.get(f, k).unwrap();
                for j in 0..3 {
                    let o = num(&row[2 + 3 * k + j]);
                    assert!(
                        (p[j] * per_metre - o).abs() <= 4.0 * f64::EPSILON * o.abs(),
                        "{name}: frame {f} marker {k}"
                    );
                }
            }
        }
    }
}

/// (name, text, whether OpenSim reads it) of each header and line-ending variant seen in the
/// field.
fn field_variants() -> Vec<(&'static str, String, bool)> {
    let plain_values = "100\t100\t6\t3\tmm\t100\t1\t6";
    vec![
        // (name, text, must OpenSim read it)
        ("plain", variant(KEYS, plain_values, "", "\n"), true),
        (
            "pipeline",
            variant(
                KEYS,
                "100.0\t\t100.0\t\t6.0\t\t3.0\t\tmm\t\t100.0\t\t1\t\t6",
                "",
                "\n",
            ),
            true,
        ),
        (
            "doubled-both",
            variant(
                &KEYS.replace('\t', "\t\t"),
                &plain_values.replace('\t', "\t\t"),
                "",
                "\n",
            ),
            true,
        ),
        (
            "count-as-decimal",
            variant(KEYS, "100\t100\t6.0\t3\tmm\t100\t1\t6", "", "\n"),
            true,
        ),
        ("crlf", variant(KEYS, plain_values, "", "\r\n"), true),
        (
            "crlf-pipeline",
            variant(
                KEYS,
                "100.0\t\t100.0\t\t6.0\t\t3.0\t\tmm\t\t100.0\t\t1\t\t6",
                "",
                "\r\n",
            ),
            true,
        ),
        (
            "extra-header-fields",
            variant(
                &format!("{KEYS}\tSubject\tSession"),
                &format!("{plain_values}\tS01\t2"),
                "",
                "\n",
            ),
            false,
        ),
        (
            "trailing-columns",
            variant(KEYS, plain_values, "\t1.0\t2.0", "\n"),
            false,
        ),
    ]
}

/// What OpenSim reads from each file: its output lines per file; `None` without the oracle.
fn opensim_reads(paths: &[String]) -> Option<Vec<Vec<Vec<String>>>> {
    let args: Vec<&str> = std::iter::once("trc-read")
        .chain(paths.iter().map(String::as_str))
        .collect();
    let lines = oracle::run(&args)?;
    let mut by_file: Vec<Vec<Vec<String>>> = Vec::new();
    for l in lines {
        if l[0] == "FILE" {
            by_file.push(Vec::new());
        } else {
            by_file.last_mut().unwrap().push(l);
        }
    }
    Some(by_file)
}
