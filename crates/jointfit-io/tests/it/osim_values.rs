//! `.osim` values next to XML comments and odd `Version` attributes, read by jointfit and by
//! OpenSim 4.6 (the oracle, through `$JOINTFIT_PYTHON`) from the same files: each variant of
//! the shared gait2392 subject model either loads in both with the same marker location or
//! is refused by both, jointfit with a one-line message naming the cause and the line.
//! OpenSim reads a value from the one non-blank text piece of an element (comments beside it
//! set aside) and refuses an element whose text comments split into several pieces.

use std::path::{Path, PathBuf};
use std::process::Command;

use jointfit_io::osim_read::read_osim;
use jointfit_testkit::{data_file, python, scratch};

const MODEL: &str = "opensim_gait2392_subject01/subject01_simbody.osim";
const ASIS: &str = "<location>0.0228989 0.035862400000000003 0.13011600000000001</location>";
const HIP: &str = "<translation>-0.072437600000000005 -0.067724500000000007 \
                   0.085552199999999995</translation>";
const VERSION: &str = "<OpenSimDocument Version=\"40000\">";

/// One variant: a name, the replacement of one piece of text, and what jointfit must do
/// (`Ok` = load; `Err(words)` = refuse with a message holding every word).
struct Variant {
    name: &'static str,
    from: &'static str,
    to: &'static str,
    expect: Result<(), &'static [&'static str]>,
}

fn variants() -> Vec<Variant> {
    let comment: &[&str] = &["comments split", "line", "OpenSim"];
    let version: &[&str] = &["unsupported", "Version"];
    vec![
        Variant {
            name: "comment_between_elements",
            from: ASIS,
            to: "<!-- c -->\n<location>0.0228989 0.035862400000000003 0.13011600000000001</location>",
            expect: Ok(()),
        },
        Variant {
            name: "comment_before_the_numbers",
            from: ASIS,
            to: "<location> <!-- c --> 0.0228989 0.035862400000000003 0.13011600000000001</location>",
            expect: Ok(()),
        },
        Variant {
            name: "comments_before_and_after_the_numbers",
            from: ASIS,
            to: "<location><!-- a --><?pi x?> 0.0228989 0.035862400000000003 0.13011600000000001\n<!-- b --> </location>",
            expect: Ok(()),
        },
        Variant {
            name: "comment_among_the_numbers",
            from: ASIS,
            to: "<location>0.0228989 <!-- c -->0.035862400000000003 0.13011600000000001</location>",
            expect: Err(comment),
        },
        Variant {
            name: "comment_in_a_joint_offset",
            from: HIP,
            to: "<translation>-0.0724376 -0.0677245<!-- r --> 0.0855522</translation>",
            expect: Err(comment),
        },
        Variant {
            name: "version_50000",
            from: VERSION,
            to: "<OpenSimDocument Version=\"50000\">",
            expect: Ok(()),
        },
        Variant {
            name: "version_overflow",
            from: VERSION,
            to: "<OpenSimDocument Version=\"99999999999999999999\">",
            expect: Err(version),
        },
        Variant {
            name: "version_text",
            from: VERSION,
            to: "<OpenSimDocument Version=\"4.0\">",
            expect: Err(version),
        },
    ]
}

fn write_variants(source: &Path, dir: &Path) -> Vec<(Variant, PathBuf)> {
    let text = std::fs::read_to_string(source).unwrap();
    variants()
        .into_iter()
        .map(|v| {
            assert_eq!(text.matches(v.from).count(), 1, "{}", v.name);
            let path = dir.join(format!("{}.osim", v.name));
            std::fs::write(&path, text.replacen(v.from, v.to, 1)).unwrap();
            (v, path)
        })
        .collect()
}

/// OpenSim 4.6's verdict per file: the R.ASIS location, or `None` when it refuses the file.
fn opensim_verdicts(py: &Path, files: &[PathBuf]) -> Vec<Option<[f64; 3]>> {
    let code = "import sys, opensim as osim\n\
                for f in sys.argv[1:]:\n\
                \x20   try:\n\
                \x20       m = osim.Model(f)\n\
                \x20       l = m.getMarkerSet().get('R.ASIS').get_location()\n\
                \x20       print('@@', l.get(0), l.get(1), l.get(2))\n\
                \x20   except Exception:\n\
                \x20       print('@@ refused')\n";
    let out = Command::new(py)
        .args(["-c", code])
        .args(files)
        .output()
        .expect("run OpenSim");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("@@ "))
        .map(|l| {
            let v: Vec<f64> = l.split(' ').filter_map(|t| t.parse().ok()).collect();
            <[f64; 3]>::try_from(v).ok()
        })
        .collect()
}

fn asis(path: &Path) -> Result<[f64; 3], String> {
    let m = read_osim(path).map_err(|e| e.to_string())?;
    let marker = m.spec.markers.iter().find(|k| k.name == "R.ASIS").unwrap();
    Ok(marker.position)
}

#[test]
fn comments_and_versions_read_or_refused_as_opensim_does() {
    let Some(source) = data_file(MODEL) else {
        return;
    };
    let dir = scratch("osim-values");
    let files = write_variants(&source, &dir);
    for (v, path) in &files {
        match (asis(path), v.expect) {
            (Ok(p), Ok(())) => {
                let want = [0.0228989, 0.0358624, 0.130116];
                assert!(
                    (0..3).all(|i| (p[i] - want[i]).abs() < 1e-12),
                    "{}: {p:?}",
                    v.name
                );
            }
            (Err(e), Err(words)) => {
                assert_eq!(e.lines().count(), 1, "{}: {e}", v.name);
                for w in words {
                    assert!(e.contains(w), "{}: {e:?} lacks {w:?}", v.name);
                }
                assert!(!e.contains("version 0"), "{e}");
            }
            (got, _) => panic!("{}: {got:?}, expected {:?}", v.name, v.expect),
        }
    }
    let Some(py) = python() else { return };
    let paths: Vec<PathBuf> = files.iter().map(|(_, p)| p.clone()).collect();
    let verdicts = opensim_verdicts(&py, &paths);
    assert_eq!(verdicts.len(), files.len());
    for ((v, path), verdict) in files.iter().zip(verdicts) {
        match (asis(path), verdict) {
            (Ok(ours), Some(theirs)) => {
                assert!(
                    (0..3).all(|i| (ours[i] - theirs[i]).abs() < 1e-9),
                    "{}",
                    v.name
                )
            }
            (Err(_), None) => {}
            (ours, theirs) => panic!("{}: jointfit {ours:?}, OpenSim {theirs:?}", v.name),
        }
    }
}
