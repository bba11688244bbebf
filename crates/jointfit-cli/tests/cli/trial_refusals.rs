//! Trials and statics a fit can learn nothing from, refused before any work with their cause
//! in one line: units off by powers of ten, fewer than two frames or no marker moving, the
//! causes of "no frame has enough markers to fit" told apart (no model marker, labels that
//! differ in case or by a prefix, every marker gapped, a segment without markers), and
//! shrunk or flattened statics. The oracle is the exit status, the message and the file system
//! (nothing written).

use super::reliability::{refused, run, Scratch};

/// `t.trc` of `s` with every coordinate multiplied by `factor` (units line unchanged), as
/// `name`; returns its path.
fn scaled(s: &Scratch, factor: f64, name: &str) -> String {
    let text = std::fs::read_to_string(s.dir.join("t.trc")).unwrap();
    let out: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i < 5 || l.trim().is_empty() {
                return l.to_string();
            }
            l.split('\t')
                .enumerate()
                .map(|(k, c)| match (k, c.parse::<f64>()) {
                    (k, Ok(v)) if k >= 2 => format!("{}", v * factor),
                    _ => c.to_string(),
                })
                .collect::<Vec<_>>()
                .join("\t")
        })
        .collect();
    std::fs::write(s.dir.join(name), out.join("\n") + "\n").unwrap();
    s.p(name)
}

/// Units wrong by 10, 0.1 or 1000 are one clear error, whatever the span: the model's marker
/// distances show the factor even where the span alone looks like a person; the span check
/// says the limits it applies.
#[test]
fn units_off_by_powers_of_ten_are_one_error() {
    let s = Scratch::new("units");
    let m = s.p("m.toml");
    for (factor, name, hint) in [
        (0.1, "tenth.trc", "centimetre data read as millimetres"),
        (10.0, "ten.trc", "millimetre data read as centimetres"),
        (1000.0, "thousand.trc", "millimetre data read as metres"),
    ] {
        let t = scaled(&s, factor, name);
        for cmd in ["ik", "calibrate"] {
            let out = s.p("o.out");
            let err = refused(&s, &[cmd, &m, &t, "-o", &out]);
            assert!(err.contains(hint), "{cmd} ×{factor}: {err}");
            assert!(!err.contains("moved"), "{err}");
            if err.contains("span") {
                assert!(err.contains("accepts 0.05–6 m"), "{err}");
            }
        }
    }
}

/// `t.trc` of `s` rewritten: `rows` picks and edits the data rows (frame, time and values,
/// tab-separated), `label` renames each label of the marker row; the header's frame counts
/// follow. Written as `name`; returns its path.
fn edited_trc(
    s: &Scratch,
    name: &str,
    rows: impl Fn(&[&str]) -> Vec<String>,
    label: impl Fn(&str) -> String,
) -> String {
    let text = std::fs::read_to_string(s.dir.join("t.trc")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let data: Vec<&str> = lines[5..]
        .iter()
        .copied()
        .filter(|l| !l.trim().is_empty())
        .collect();
    let new_rows = rows(&data);
    let mut head: Vec<String> = lines[..5].iter().map(|l| l.to_string()).collect();
    let mut counts: Vec<String> = head[2].split('\t').map(str::to_string).collect();
    counts[2] = new_rows.len().to_string();
    counts[7] = new_rows.len().to_string();
    head[2] = counts.join("\t");
    head[3] = head[3]
        .split('\t')
        .enumerate()
        .map(|(i, l)| {
            if i >= 2 && !l.is_empty() {
                label(l)
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\t");
    let out = format!("{}\n{}\n", head.join("\n"), new_rows.join("\n"));
    std::fs::write(s.dir.join(name), out).unwrap();
    s.p(name)
}

/// Row `r` with frame number `frame` and time `(frame − 1) / 10`.
fn renumbered(r: &str, frame: usize) -> String {
    let mut cells: Vec<String> = r.split('\t').map(str::to_string).collect();
    cells[0] = frame.to_string();
    cells[1] = format!("{:.6}", (frame - 1) as f64 / 10.0);
    cells.join("\t")
}

/// Trials a calibration can learn nothing from are refused with their cause, not fitted to a
/// "100 % lower" error: one frame, two identical frames, every marker still.
#[test]
fn degenerate_trials_are_refused_with_their_cause() {
    let s = Scratch::new("degenerate");
    let same = |l: &str| l.to_string();
    let one = edited_trc(&s, "one.trc", |d| vec![renumbered(d[0], 1)], same);
    let two = edited_trc(
        &s,
        "two.trc",
        |d| vec![renumbered(d[3], 1), renumbered(d[3], 2)],
        same,
    );
    let still = edited_trc(
        &s,
        "still.trc",
        |d| (1..=20).map(|f| renumbered(d[5], f)).collect(),
        same,
    );
    let (m, out) = (s.p("m.toml"), s.p("o.toml"));
    for (t, words) in [
        (&one, &["1 frame", "two frames"][..]),
        (&two, &["no marker moves"][..]),
        (&still, &["no marker moves", "20 frames"][..]),
    ] {
        let err = refused(&s, &["calibrate", &m, t, "-o", &out]);
        for w in words {
            assert!(err.contains(w), "{t}: {err}");
        }
        assert!(err.contains(t.as_str()), "names the trial: {err}");
    }
}

/// The causes of "no frame has enough markers to fit" are told apart, naming markers:
/// no marker of the model in the trial, labels that differ in case or by a prefix, every
/// model marker gapped in every frame, and a segment whose markers are all missing (the
/// foot's three: the ankle is undetermined in every frame).
#[test]
fn unfittable_trials_name_their_markers() {
    let s = Scratch::new("no-frames");
    let all = |d: &[&str]| d.iter().map(|r| r.to_string()).collect::<Vec<_>>();
    let other = edited_trc(&s, "other.trc", all, |l| l.chars().rev().collect());
    let lower = edited_trc(&s, "lower.trc", all, |l| l.to_ascii_lowercase());
    let prefixed = edited_trc(&s, "prefixed.trc", all, |l| format!("Pat01_{l}"));
    let gapped = edited_trc(
        &s,
        "gapped.trc",
        |d| {
            d.iter()
                .map(|r| {
                    let c: Vec<&str> = r.split('\t').collect();
                    let blanks = vec![""; c.len() - 2].join("\t");
                    format!("{}\t{}\t{blanks}", c[0], c[1])
                })
                .collect()
        },
        |l| l.to_string(),
    );
    let footless = edited_trc(
        &s,
        "footless.trc",
        |d| d.iter().map(|r| without_foot(r)).collect(),
        |l| l.to_string(),
    );
    let (m, out) = (s.p("m.toml"), s.p("o.toml"));
    for (t, words) in [
        (
            &footless,
            &[
                "ankle_dorsiflexion is undetermined in 30 of 30 frames",
                "segment talus",
                "RHEE (never present)",
                "RMT5 (never present)",
            ][..],
        ),
        (&other, &["none of the model's", "RASI", "ISAR"][..]),
        (&lower, &["case", "rasi (RASI?)"][..]),
        (&prefixed, &["prefix", "Pat01_RASI (RASI?)"][..]),
        (&gapped, &["missing in all 30 frames", "RASI"][..]),
    ] {
        // The data checks may warn first (the gapped trial's gaps); one error line follows.
        let o = run(&["calibrate", &m, t, "-o", &out]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(1), "{t}: {err}");
        let errors: Vec<&str> = err
            .lines()
            .filter(|l| l.starts_with("jointfit: error: "))
            .collect();
        assert_eq!(errors.len(), 1, "{err}");
        let err = errors[0];
        for w in words {
            assert!(err.contains(w), "{t}: {w:?} not in {err}");
        }
    }
}

/// A row of the synthetic trial (frame, time, then x y z of 15 markers) with the foot's
/// markers (the last three: RHEE, RTOE, RMT5) blank.
fn without_foot(row: &str) -> String {
    let mut c: Vec<&str> = row.split('\t').collect();
    let n = c.len();
    for v in &mut c[n - 9..] {
        *v = "";
    }
    c.join("\t")
}

/// A static trial shrunk to 0.3 of its size, or flattened onto a plane (one lab axis set
/// to a constant), is refused by `personalize`, never written as a subject model: the shrunk
/// one by the adult anthropometry check (exit 5), the flattened ones by the pelvis frame.
#[test]
fn shrunk_and_flattened_statics_are_refused_by_personalize() {
    let Some(src) = jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_static.trc")
    else {
        return;
    };
    let s = Scratch::new("bad-static");
    let text = std::fs::read_to_string(&src).unwrap();
    let variant = |name: &str, f: &dyn Fn(usize, f64) -> f64| -> String {
        let lines: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i < 5 {
                    return l.to_string();
                }
                l.split('\t')
                    .enumerate()
                    .map(|(k, c)| match c.trim().parse::<f64>() {
                        Ok(v) if k >= 2 => format!("{:.6}", f(k - 2, v)),
                        _ => c.to_string(),
                    })
                    .collect::<Vec<_>>()
                    .join("\t")
            })
            .collect();
        std::fs::write(s.dir.join(name), lines.join("\n")).unwrap();
        s.p(name)
    };
    let out = s.p("subject.toml");
    let cases = [
        (
            variant("shrunk.trc", &|_, v| 0.3 * v),
            Some(5),
            "not a plausible adult leg",
        ),
        (
            variant("flat_z.trc", &|k, v| if k % 3 == 2 { 0.0 } else { v }),
            Some(1),
            "pelvis",
        ),
        (
            variant("flat_y.trc", &|k, v| if k % 3 == 1 { 900.0 } else { v }),
            Some(1),
            "pelvis",
        ),
    ];
    for (trial, code, words) in &cases {
        let args = [
            "personalize",
            "--static",
            trial,
            "--markers",
            "gait2392",
            "--side",
            "right",
            "-o",
            &out,
        ];
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), *code, "{trial}: {err}");
        assert!(err.contains(words), "{trial}: {err}");
        assert!(
            !s.dir.join("subject.toml").exists(),
            "{trial}: a model was written"
        );
    }
}
