//! File safety, one test each: outputs never destroy inputs, a
//! failed run writes nothing, a full stdout or a signal leaves no file behind. The refusals of
//! bad values and data are in `refusals.rs`, which shares this file's `Scratch` and
//! `refused`. The oracle is the file system (bytes before and after, directory listings).

use std::process::{Command, Output, Stdio};

use jointfit_testkit::ScratchDir;

use super::jointfit;

/// A scratch directory with a small noiseless synthetic trial `t.trc` and its model `m.toml`.
pub struct Scratch {
    pub dir: ScratchDir,
}

impl Scratch {
    pub fn new(tag: &str) -> Scratch {
        let dir = jointfit_testkit::scratch(&format!("rel-{tag}"));
        let s = Scratch { dir };
        let (ok, _, err) = jointfit(&[
            "synth",
            "lower-limb-right",
            "--motion",
            "hip",
            "--frames",
            "30",
            "-o",
            &s.p("t.trc"),
            "--truth",
            &s.p("m.toml"),
        ]);
        assert!(ok, "{err}");
        s
    }

    /// The path of `name` in the directory, as a string.
    pub fn p(&self, name: &str) -> String {
        self.dir.join(name).to_str().unwrap().to_string()
    }

    /// Every entry of the directory (recursively), with its bytes (directories: empty).
    pub fn snapshot(&self) -> Vec<(String, Vec<u8>)> {
        jointfit_testkit::snapshot(&self.dir)
    }
}

pub(super) fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(args)
        .output()
        .expect("jointfit runs")
}

/// A refused run: non-zero exit, no panic, one line on stderr, nothing in the directory
/// changed; returns stderr.
pub(super) fn refused(s: &Scratch, args: &[&str]) -> String {
    let before = s.snapshot();
    let out = run(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert_ne!(out.status.code(), Some(101), "{args:?} panicked: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    assert!(err.starts_with("jointfit: error: "), "{err}");
    assert!(
        s.snapshot() == before,
        "{args:?} changed the directory: {err}"
    );
    err
}

#[test]
fn outputs_never_overwrite_inputs() {
    let s = Scratch::new("inputs");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    std::fs::create_dir_all(s.dir.join("sub")).unwrap();
    let spelled = s.p("sub/../t.trc");
    let cases: Vec<Vec<&str>> = vec![
        vec!["ik", &m, &t, "-o", &t],
        vec!["ik", &m, &t, "-o", "/dev/null/x.mot", "--errors", &t],
        vec!["ik", &m, &t, "-o", &spelled],
        vec![
            "personalize",
            "--static",
            &t,
            "--markers",
            "gait2392",
            "--side",
            "right",
            "-o",
            &t,
        ],
        vec!["calibrate", &m, &t, "-o", &t],
        vec!["export", "osim", &m, "-o", &m],
        vec!["synth", &m, "-o", &m, "--truth", "/dev/null/x.toml"],
        vec!["convert", &t, &t],
        vec!["convert", &t, &spelled],
    ];
    let gait = format!("gait:{t}");
    let mut cases = cases;
    cases.push(vec![
        "synth",
        "lower-limb-right",
        "--motion",
        &gait,
        "-o",
        &t,
        "--truth",
        "/dev/null/x.toml",
    ]);
    for args in &cases {
        let err = refused(&s, args);
        assert!(
            err.contains("refusing to overwrite an input"),
            "{args:?}: {err}"
        );
    }
    // Two outputs naming one file (the TRC used to be replaced by the TOML).
    let x = s.p("x");
    let x2 = s.p("./sub/../x");
    let err = refused(&s, &["synth", "lower-limb-right", "-o", &x, "--truth", &x2]);
    assert!(err.contains("are the same file"), "{err}");
}

#[cfg(unix)]
#[test]
fn links_are_the_same_file() {
    let s = Scratch::new("links");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    std::os::unix::fs::symlink(&t, s.dir.join("sym.trc")).unwrap();
    std::fs::hard_link(&t, s.dir.join("hard.trc")).unwrap();
    for out in [s.p("sym.trc"), s.p("hard.trc")] {
        let err = refused(&s, &["convert", &t, &out]);
        assert!(err.contains("refusing to overwrite an input"), "{err}");
        let err = refused(&s, &["ik", &m, &out, "-o", &t]);
        assert!(err.contains("refusing to overwrite an input"), "{err}");
    }
}

/// `calibrate M.toml … -o M.toml` is refused without --force and updates M.toml with it.
#[test]
fn calibrate_updates_a_model_in_place_only_with_force() {
    let s = Scratch::new("force");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let err = refused(&s, &["calibrate", &m, &t, "--joints", "hip", "-o", &m]);
    assert!(err.contains("add --force"), "{err}");
    let before = std::fs::read(&m).unwrap();
    let (ok, _, err) = jointfit(&["calibrate", &m, &t, "--joints", "hip", "-o", &m, "--force"]);
    assert!(ok, "{err}");
    let after = std::fs::read_to_string(&m).unwrap();
    assert_ne!(before, after.as_bytes());
    assert!(after.contains("(fitted)"), "{after}");
}

#[test]
fn a_failed_multi_file_run_writes_nothing() {
    let s = Scratch::new("partial");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let ok_mot = s.p("ok.mot");
    let bad_csv = s.p("nodir/e.csv");
    refused(&s, &["ik", &m, &t, "-o", &ok_mot, "--errors", &bad_csv]);
    refused(
        &s,
        &[
            "synth",
            "lower-limb-right",
            "-o",
            &s.p("new.trc"),
            "--truth",
            "/nonexistent/t.toml",
        ],
    );
    // A report into a new directory whose trial cannot be read leaves no directory.
    refused(&s, &["report", &m, &s.p("missing.trc"), "-o", &s.p("rep")]);
    // A calibration whose model and report are both written, then fails (stdout full):
    // neither file nor the report's new directory stays.
    #[cfg(target_os = "linux")]
    {
        let before = s.snapshot();
        let out = Command::new(env!("CARGO_BIN_EXE_jointfit"))
            .args(["calibrate", &m, &t, "--joints", "hip", "-o", &s.p("f.toml")])
            .args(["--report", &s.p("crep/deeper")])
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("cannot write to standard output"), "{err}");
        assert!(
            s.snapshot() == before,
            "{:?}",
            s.snapshot().iter().map(|x| &x.0).collect::<Vec<_>>()
        );
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_full_stdout_is_an_error_not_a_panic() {
    let s = Scratch::new("full");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let mot = s.p("o.mot");
    let cases: Vec<Vec<&str>> = vec![
        vec!["model", "show", "lower-limb-right"],
        vec!["model", "show", &m, "--json"],
        vec!["inspect", &t, "--json"],
        vec!["ik", &m, &t, "-o", &mot],
    ];
    for args in cases {
        let before = s.snapshot();
        let out = Command::new(env!("CARGO_BIN_EXE_jointfit"))
            .args(&args)
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(
            err.trim(),
            "jointfit: error: cannot write to standard output: No space left on device (os error 28)",
            "{args:?}"
        );
        assert!(s.snapshot() == before, "{args:?} left a file");
    }
}

/// Interrupting a run while its temporary files exist removes them (SIGINT, SIGTERM); a
/// SIGKILL leaves them, and the next write into the directory sweeps them.
#[cfg(target_os = "linux")]
#[test]
fn signals_leave_no_temporary_file() {
    let s = Scratch::new("signals");
    let (m, t) = (s.p("m.toml"), s.p("t.trc"));
    let temps = |s: &Scratch| -> Vec<String> {
        s.snapshot()
            .into_iter()
            .map(|(n, _)| n)
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    };
    for (sig, args) in [
        (libc::SIGINT, vec!["convert", &t, &s.p("c.trc")]),
        (
            libc::SIGTERM,
            vec!["ik", &m, &t, "-o", &s.p("i.mot"), "--errors", &s.p("e.csv")],
        ),
        (libc::SIGKILL, vec!["convert", &t, &s.p("k.trc")]),
    ] {
        let before = s.snapshot();
        let mut child = Command::new(env!("CARGO_BIN_EXE_jointfit"))
            .args(&args)
            .env("JOINTFIT_TEST_PAUSE_BEFORE_COMMIT", "20")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while temps(&s).is_empty() {
            assert!(start.elapsed().as_secs() < 60, "no temporary file appeared");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        // SAFETY: signalling our own child process.
        unsafe {
            libc::kill(child.id() as libc::pid_t, sig);
        }
        let status = child.wait().unwrap();
        assert!(!status.success());
        if sig == libc::SIGKILL {
            assert!(!temps(&s).is_empty(), "SIGKILL cannot be caught");
            let (ok, _, err) = jointfit(&["convert", &t, &s.p("k.trc")]);
            assert!(ok, "{err}");
            assert!(temps(&s).is_empty(), "{:?}", temps(&s));
        } else {
            use std::os::unix::process::ExitStatusExt;
            assert_eq!(status.signal(), Some(sig));
            assert!(s.snapshot() == before, "signal {sig} left {:?}", temps(&s));
        }
    }
}
