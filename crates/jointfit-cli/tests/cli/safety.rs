//! Reproducers of a fault sweep, one test each: a model without markers is an error naming
//! it (not a panic), size options refuse past their limit, outputs never replace an input
//! (not even with `--force`, which replaces only the model it names), replaced files keep
//! their permissions and read-only ones are refused. The oracle is the file system (bytes and
//! modes before and after) and the exit status.

use super::reliability::{refused, run, Scratch};

/// `m.toml` of `s` without its markers, written as `bare.toml`; returns its path.
fn without_markers(s: &Scratch) -> String {
    let text = std::fs::read_to_string(s.dir.join("m.toml")).unwrap();
    let mut spec = jointfit::model::spec::ModelSpec::from_toml(&text).unwrap();
    spec.markers.clear();
    spec.name = "bare leg".into();
    std::fs::write(s.dir.join("bare.toml"), spec.to_toml()).unwrap();
    s.p("bare.toml")
}

#[test]
fn a_model_without_markers_is_an_error_naming_the_model() {
    let s = Scratch::new("bare");
    let (bare, t) = (without_markers(&s), s.p("t.trc"));
    let (out, rep, truth) = (s.p("o.toml"), s.p("rep"), s.p("truth.toml"));
    let cases: Vec<Vec<&str>> = vec![
        vec!["calibrate", &bare, &t, "-o", &out],
        vec!["check", &bare, &t],
        vec!["report", &bare, &t, "-o", &rep],
        vec!["ik", &bare, &t, "-o", &out],
        vec![
            "synth", &bare, "--motion", "hip", "-o", &out, "--truth", &truth,
        ],
    ];
    for args in &cases {
        let err = refused(&s, args);
        assert!(err.contains("has no markers"), "{args:?}: {err}");
        assert!(
            err.contains("bare leg") || err.contains("bare.toml"),
            "{args:?} does not name the model: {err}"
        );
    }
}

#[test]
fn bench_sizes_are_refused_with_their_limit() {
    for (opt, v) in [
        ("--io-frames", "100000000"),
        ("--long-frames", "1e9"),
        ("--rss-frames", "18446744073709551615"),
        ("--fit-only", "1000000"),
    ] {
        let out = run(&["bench", opt, v]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{opt} {v}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(opt), "{err}");
    }
    let out = run(&["bench", "--io-frames", "100000000"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("500000"), "the limit is said: {err}");
}

/// `--force` replaces the model file it names and nothing else: not the motion trial, not a
/// functional trial of `personalize`, whatever the spelling.
#[test]
fn force_never_replaces_a_trial() {
    let s = Scratch::new("force");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    std::fs::create_dir_all(s.dir.join("sub")).unwrap();
    let spelled = s.p("sub/../t.trc");
    #[cfg(unix)]
    std::os::unix::fs::symlink(s.dir.join("t.trc"), s.dir.join("link.trc")).unwrap();
    let link = s.p("link.trc");
    for out in [&t, &spelled, &link] {
        let err = refused(
            &s,
            &["calibrate", &m, &t, "--joints", "hip", "-o", out, "--force"],
        );
        assert!(err.contains("refusing to overwrite an input"), "{err}");
        assert!(
            !err.contains("--force"),
            "the error must not suggest --force: {err}"
        );
    }
    std::fs::copy(s.dir.join("t.trc"), s.dir.join("hip.trc")).unwrap();
    let hip = s.p("hip.trc");
    for opt in ["--functional-hip", "--functional-knee"] {
        let err = refused(
            &s,
            &[
                "personalize",
                "--static",
                &t,
                "--markers",
                "gait2392",
                "--side",
                "right",
                opt,
                &hip,
                "-o",
                &hip,
            ],
        );
        assert!(err.contains("refusing to overwrite an input"), "{err}");
    }
    // The model itself may be updated in place with --force.
    let out = run(&["calibrate", &m, &t, "--joints", "hip", "-o", &m, "--force"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[cfg(unix)]
#[test]
fn replaced_outputs_keep_their_permissions_and_read_only_ones_are_refused() {
    use std::os::unix::fs::PermissionsExt;
    let s = Scratch::new("perm");
    let (m, t, mot) = (s.p("m.toml"), s.p("t.trc"), s.p("x.mot"));
    let mode = |p: &str| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
    std::fs::write(&mot, b"old").unwrap();
    std::fs::set_permissions(&mot, std::fs::Permissions::from_mode(0o600)).unwrap();
    let out = run(&["ik", &m, &t, "-o", &mot]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_ne!(std::fs::read(&mot).unwrap(), b"old");
    assert_eq!(mode(&mot), 0o600);
    std::fs::set_permissions(&mot, std::fs::Permissions::from_mode(0o444)).unwrap();
    let err = refused(&s, &["ik", &m, &t, "-o", &mot]);
    assert!(err.contains("read-only"), "{err}");
    std::fs::set_permissions(s.dir.join("m.toml"), std::fs::Permissions::from_mode(0o400)).unwrap();
    let err = refused(
        &s,
        &["calibrate", &m, &t, "--joints", "hip", "-o", &m, "--force"],
    );
    assert!(err.contains("read-only"), "{err}");
}

/// `ik -o x.mot --errors x.csv` in `s` with the commit paused between its two renames:
/// returns the child once the first output has landed (its bytes changed from "old").
#[cfg(target_os = "linux")]
fn paused_in_commit(s: &Scratch) -> std::process::Child {
    let (m, t, mot, csv) = (s.p("m.toml"), s.p("t.trc"), s.p("x.mot"), s.p("x.csv"));
    std::fs::write(&mot, b"old").unwrap();
    std::fs::write(&csv, b"old").unwrap();
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["ik", &m, &t, "-o", &mot, "--errors", &csv])
        .env("JOINTFIT_TEST_PAUSE_BETWEEN_RENAMES", "3")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while std::fs::read(&mot).unwrap() == b"old" {
        assert!(
            start.elapsed().as_secs() < 60,
            "the first rename never came"
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child
}

/// A run killed between the renames of its outputs leaves a journal; the next command that
/// writes into the directory completes the commit, so the `.mot` and `.csv` match again (the
/// same bytes as an uninterrupted run), and no temporary file or journal is left. SIGINT in
/// the same place waits for the last rename and exits 0: everything was written.
#[cfg(target_os = "linux")]
#[test]
fn a_commit_cut_by_a_kill_is_completed_and_an_interrupt_reports_success() {
    let s = Scratch::new("commit");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let out = run(&["ik", &m, &t, "-o", &s.p("r.mot"), "--errors", &s.p("r.csv")]);
    assert!(out.status.success());
    let want_csv = std::fs::read(s.dir.join("r.csv")).unwrap();
    let want_mot = std::fs::read(s.dir.join("r.mot")).unwrap();
    let hidden = |s: &Scratch| -> Vec<String> {
        s.snapshot()
            .into_iter()
            .map(|(n, _)| n)
            .filter(|n| n.contains("/.") || n.starts_with('.'))
            .collect()
    };
    let mut child = paused_in_commit(&s);
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(std::fs::read(s.dir.join("x.csv")).unwrap(), b"old");
    assert!(
        !hidden(&s).is_empty(),
        "a journal and a temporary file remain"
    );
    let out = run(&["ik", &m, &t, "-o", &s.p("y.mot")]);
    assert!(out.status.success());
    assert_eq!(std::fs::read(s.dir.join("x.csv")).unwrap(), want_csv);
    assert_eq!(std::fs::read(s.dir.join("x.mot")).unwrap(), want_mot);
    assert_eq!(hidden(&s), Vec::<String>::new());

    let child = paused_in_commit(&s);
    // SAFETY: signalling our own child process.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    let done = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&done.stderr);
    assert_eq!(done.status.code(), Some(0), "{err}");
    assert!(err.contains("every output was written"), "{err}");
    assert_eq!(std::fs::read(s.dir.join("x.csv")).unwrap(), want_csv);
    assert_eq!(hidden(&s), Vec::<String>::new());
}

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

/// An `.osim` coordinate range with its minimum above its maximum is an error naming the
/// coordinate (it was replaced by an invented range of ±1 rad around the minimum).
#[test]
fn an_osim_range_upside_down_is_an_error() {
    let s = Scratch::new("range");
    let osim = s.p("m.osim");
    let out = run(&["export", "osim", &s.p("m.toml"), "-o", &osim]);
    assert!(out.status.success());
    let text = std::fs::read_to_string(&osim).unwrap();
    let at = text.find("<range>").unwrap() + "<range>".len();
    let end = at + text[at..].find("</range>").unwrap();
    let nums: Vec<&str> = text[at..end].split_whitespace().collect();
    let flipped = format!("{}{} {}{}", &text[..at], nums[1], nums[0], &text[end..]);
    std::fs::write(&osim, flipped).unwrap();
    let err = refused(&s, &["model", "show", &osim]);
    assert!(err.contains("minimum above its maximum"), "{err}");
    assert!(err.contains("coordinate"), "{err}");
}

/// Batch resume follows the contents of the inputs: a trial replaced by other data with the
/// same modification time is fitted again (it used to be "done earlier, skipped" with the old
/// result); an untouched job is skipped. A job id too long to name a file is refused before
/// any fit.
#[test]
fn batch_resume_is_keyed_by_content_and_ids_are_checked_first() {
    let s = Scratch::new("resume");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let jobs = s.dir.join("jobs.toml");
    let manifest = |id: &str| {
        format!(
            "[defaults]\njoints = [\"hip\"]\n\n[[job]]\nid = \"{id}\"\nmodel = {m:?}\ntrials = \
             [{t:?}]\n"
        )
    };
    std::fs::write(&jobs, manifest("a")).unwrap();
    let out = s.p("out");
    let batch = || run(&["batch", jobs.to_str().unwrap(), "-o", &out, "--jobs", "1"]);
    let first = batch();
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let again = batch();
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("done earlier, skipped"), "{err}");
    // Other data (the trial with its coordinates shifted by 1 mm), same modification time.
    let stamp = std::fs::metadata(&t).unwrap().modified().unwrap();
    let text = std::fs::read_to_string(&t).unwrap();
    let edited = text.replacen("950.000000000", "951.000000000", 5);
    assert_ne!(edited, text);
    std::fs::write(&t, edited).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&t)
        .unwrap()
        .set_modified(stamp)
        .unwrap();
    let third = batch();
    let err = String::from_utf8_lossy(&third.stderr);
    assert!(third.status.success(), "{err}");
    assert!(!err.contains("done earlier, skipped"), "{err}");
    // A 251-character id: refused up front, nothing fitted, no results table.
    let long = "x".repeat(251);
    std::fs::write(&jobs, manifest(&long)).unwrap();
    let out2 = s.p("out2");
    let refused = run(&["batch", jobs.to_str().unwrap(), "-o", &out2]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(err.contains("at most 100 characters"), "{err}");
    assert!(!s.dir.join("out2").exists());
}

/// Help that cannot be written is a failure; an absurd thread count is capped with one
/// warning instead of minutes of thread start-up.
#[cfg(target_os = "linux")]
#[test]
fn help_to_a_full_disk_fails_and_thread_counts_are_capped() {
    let full = std::fs::File::options()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let st = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .arg("--help")
        .stdout(full)
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert_eq!(st.code(), Some(1));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["model", "show", "lower-limb-right"])
        .env("RAYON_NUM_THREADS", "100000")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(err.matches("threads per core").count(), 1, "{err}");
}

/// Prior SDs too small for the objective to represent (1e-200 mm used to drop the prior
/// silently, or to end in a confusing rejection) are one-line errors naming the parameter,
/// from the model file, from `--prior-sd` and from `--marker-prior-sd-mm`.
#[test]
fn prior_sds_below_what_the_fit_represents_are_refused_naming_the_prior() {
    let s = Scratch::new("prior-sd");
    let (m, t, out) = (s.p("m.toml"), s.p("t.trc"), s.p("o.toml"));
    let text = std::fs::read_to_string(s.dir.join("m.toml")).unwrap();
    let mut spec = jointfit::model::spec::ModelSpec::from_toml(&text).unwrap();
    let p = &mut spec.parameters[0];
    let name = p.name.clone();
    p.prior_sd = Some(1e-203);
    p.prior_mean = Some(p.nominal);
    std::fs::write(s.dir.join("tiny.toml"), spec.to_toml()).unwrap();
    let tiny = s.p("tiny.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["calibrate", &tiny, &t, "-o", &out], &name),
        (
            vec![
                "calibrate",
                &m,
                &t,
                "-o",
                &out,
                "--prior-sd",
                "hip=1e-200mm",
            ],
            "hip_pelvis",
        ),
        (
            vec![
                "calibrate",
                &m,
                &t,
                "-o",
                &out,
                "--prior-sd",
                "knee=1e-300deg",
            ],
            "knee",
        ),
        (
            vec![
                "calibrate",
                &m,
                &t,
                "-o",
                &out,
                "--refine-markers",
                "--marker-prior-sd-mm",
                "1e-200",
            ],
            "marker_",
        ),
    ];
    for (args, names) in &cases {
        let err = refused(&s, args);
        assert!(err.contains("prior"), "{args:?}: {err}");
        assert!(
            err.contains(names),
            "{args:?} does not name the prior: {err}"
        );
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

/// `--keep-markers` with a name the model lacks is refused listing the model's markers;
/// `--swap-labels` given the same pair twice (either order) or two pairs sharing a marker
/// in the same frames is refused instead of cancelling.
#[test]
fn marker_options_that_name_nothing_or_cancel_are_refused() {
    let s = Scratch::new("marker-options");
    let (m, t, out) = (s.p("m.toml"), s.p("t.trc"), s.p("o.toml"));
    let err = refused(
        &s,
        &[
            "calibrate",
            &m,
            &t,
            "-o",
            &out,
            "--keep-markers",
            "RASI,nope",
        ],
    );
    assert!(err.contains("--keep-markers nope"), "{err}");
    assert!(err.contains("RASI, LASI"), "lists the valid names: {err}");
    for pairs in [
        ["RKNE,RANK", "RKNE,RANK"],
        ["RKNE,RANK", "RANK,RKNE"],
        ["RKNE,RANK", "RANK,RHEE"],
        ["RKNE,RANK@5", "RKNE,RTOE@10-20"],
    ] {
        let err = refused(
            &s,
            &[
                "calibrate",
                &m,
                &t,
                "-o",
                &out,
                "--swap-labels",
                pairs[0],
                "--swap-labels",
                pairs[1],
            ],
        );
        assert!(err.contains("--swap-labels"), "{pairs:?}: {err}");
        assert!(err.contains("same frames"), "{pairs:?}: {err}");
    }
}

/// A NaN, negative or huge progress interval is warned about once per run, however many
/// tasks report progress.
#[test]
fn a_bad_progress_interval_is_warned_once() {
    let s = Scratch::new("progress-env");
    let (m, t, out) = (s.p("m.toml"), s.p("t.trc"), s.p("o.toml"));
    for bad in ["NaN", "-1", "0x10", "1e300"] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
            .args([
                "calibrate",
                &m,
                &t,
                "-o",
                &out,
                "--force",
                "--accept-rejected",
            ])
            .env("JOINTFIT_PROGRESS_SECONDS", bad)
            .env("JOINTFIT_PROGRESS", "log")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{bad}: {err}");
        let warned = err
            .lines()
            .filter(|l| l.contains("JOINTFIT_PROGRESS_SECONDS"))
            .count();
        assert_eq!(warned, 1, "{bad}: {err}");
    }
}

/// Every input file has a size limit: a model, motion trial or setup file that is a 2 GiB
/// (sparse) file or the endless `/dev/zero` is refused within seconds, the limit named.
#[test]
fn oversized_inputs_are_refused_quickly_naming_the_limit() {
    let s = Scratch::new("sizes");
    let (m, t, out) = (s.p("m.toml"), s.p("t.trc"), s.p("o.mot"));
    // The oversized files live outside the directory `refused` compares before and after.
    let big = jointfit_testkit::scratch("rel-sizes-big");
    let b = |name: &str| big.join(name).display().to_string();
    let mut cases: Vec<(Vec<String>, &str)> = Vec::new();
    for name in ["big.toml", "big.osim", "big.trc", "big.c3d"] {
        let f = std::fs::File::create(big.join(name)).unwrap();
        f.set_len(2 << 30).unwrap();
    }
    #[cfg(unix)]
    for name in ["zero.trc", "zero.c3d", "zero.osim"] {
        std::os::unix::fs::symlink("/dev/zero", big.join(name)).unwrap();
    }
    let ik = |model: &str, trial: &str| -> Vec<String> {
        ["ik", model, trial, "-o", &out]
            .iter()
            .map(|a| a.to_string())
            .collect()
    };
    cases.push((ik(&b("big.toml"), &t), "256 MiB"));
    cases.push((ik(&b("big.osim"), &t), "256 MiB"));
    cases.push((ik("/dev/zero", &t), "256 MiB"));
    cases.push((ik(&m, &b("big.trc")), "1024 MiB"));
    cases.push((ik(&m, &b("big.c3d")), "1024 MiB"));
    #[cfg(unix)]
    {
        cases.push((ik(&b("zero.osim"), &t), "256 MiB"));
        cases.push((ik(&m, &b("zero.trc")), "1024 MiB"));
        cases.push((ik(&m, &b("zero.c3d")), "1024 MiB"));
    }
    // A marker set and a batch manifest are read under the same limit as a model.
    let words = |w: &[&str]| -> Vec<String> { w.iter().map(|a| a.to_string()).collect() };
    let outdir = s.p("batch-out");
    cases.push((
        words(&[
            "personalize",
            "--static",
            &t,
            "--markers",
            &b("big.toml"),
            "-o",
            &s.p("subject.toml"),
        ]),
        "256 MiB",
    ));
    cases.push((words(&["batch", &b("big.toml"), "-o", &outdir]), "256 MiB"));
    for (args, limit) in &cases {
        let clock = std::time::Instant::now();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let err = refused(&s, &args);
        assert!(
            err.contains("limit") && err.contains(limit),
            "{args:?}: {err}"
        );
        assert!(
            clock.elapsed().as_secs() < 30,
            "{args:?} took {:?}",
            clock.elapsed()
        );
    }
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

/// `jointfit stream` bounds a single input line: an endless line (`/dev/zero` on standard
/// input, no line end ever) is refused within seconds naming the limit, not read until
/// memory runs out.
#[test]
fn stream_refuses_an_endless_line() {
    let clock = std::time::Instant::now();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["stream", "lower-limb-right"])
        .stdin(std::fs::File::open("/dev/zero").unwrap())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("line 1 is longer than 1048576 bytes"), "{err}");
    assert!(clock.elapsed().as_secs() < 30, "{:?}", clock.elapsed());
}

/// A model output named as another format (`.osim` for a TOML model, `.mot`, `.trc`) is
/// refused before any fit and nothing is written; `.toml` in any letter case and a name
/// without an extension are written.
#[test]
fn model_outputs_named_as_another_format_are_refused() {
    let s = Scratch::new("out-ext");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    for name in ["fit.osim", "fit.mot", "fit.trc"] {
        let out = s.p(name);
        let err = refused(&s, &["calibrate", &m, &t, "-o", &out]);
        assert!(err.contains("name the output .toml"), "{name}: {err}");
        assert!(!s.dir.join(name).exists(), "{name} was written");
    }
    for name in ["fit.TOML", "fit"] {
        let o = run(&["calibrate", &m, &t, "-o", &s.p(name)]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let text = std::fs::read_to_string(s.dir.join(name)).unwrap();
        assert!(
            jointfit::model::spec::ModelSpec::from_toml(&text).is_ok(),
            "{name} holds a model"
        );
    }
}
