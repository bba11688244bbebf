//! Reproducers of a fault sweep, one test each: a model without markers is an error naming
//! it (not a panic), size options refuse past their limit, outputs never replace an input
//! (not even with `--force`, which replaces only the model it names), replaced files keep
//! their permissions and read-only ones are refused. The oracle is the file system (bytes and
//! modes before and after) and the exit status. Trials and statics refused for what they
//! hold are in `trial_refusals.rs`.

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
