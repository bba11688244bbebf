//! What the program writes, and how it ends.
//!
//! - **Console.** `println!`, `print!`, `eprintln!` and `eprint!` are replaced, for every
//!   module declared after this one in `main.rs`, by versions that never panic: a failed write
//!   to standard output (`> /dev/full`) is remembered, later output is dropped, and the run
//!   ends with exit status 1 and a one-line error; failed writes to standard error are ignored
//!   (there is nowhere left to report them).
//! - **Files.** [`Files`] checks, before any work, that no output is an input or another
//!   output (compared by device and inode for existing files, by canonical directory and name
//!   for new ones, so symlinks, hard links and `a/../b` spellings count). Every file is written
//!   through `jointfit_io::atomic::write_atomic` inside one `jointfit_io::staging::Batch`
//!   opened by `main`: nothing is renamed into place unless the whole command succeeded, and
//!   SIGINT/SIGTERM/SIGHUP remove the temporary files ([`install_signal_handlers`]). The
//!   commit itself is all-or-nothing across a crash and serialized with other writers of the
//!   same directories (`jointfit_io::staging`'s journal and directory locks); a signal that
//!   arrives during it waits for it, and a run whose files all landed exits 0.
//! - **Exit status.** 0 success; 1 error (nothing written); 2 bad command line; 3 a fit did
//!   not converge (nothing written; `--accept-unconverged` keeps it and exits 0); 4 some jobs
//!   of `jointfit batch` failed (its files are kept: the results table records the failures).
//! - **Errors.** [`one_line`]: the causes joined on one line, each said once, long tokens
//!   elided and huge numbers shown in scientific notation.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Mutex;

use anyhow::{bail, Result};

mod files;
pub use files::{check_model_extension, Files};

/// Exit status of a fit that did not converge (see the module docs).
pub const EXIT_UNCONVERGED: u8 = 3;
/// Exit status of a batch some of whose jobs failed (see the module docs).
pub const EXIT_PARTIAL: u8 = 4;
/// Exit status of a command line that clap rejects.
pub const EXIT_USAGE: u8 = 2;
/// Exit status of a fit rejected by its verdict, or of inputs refused as not belonging
/// together (nothing written).
pub const EXIT_REJECTED: u8 = 5;

/// `println!` that never panics (see the module docs).
macro_rules! println {
    () => {
        $crate::output::stdout_fmt(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::stdout_fmt(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` that never panics (see the module docs).
macro_rules! print {
    ($($arg:tt)*) => {
        $crate::output::stdout_fmt(format_args!($($arg)*))
    };
}

/// `eprintln!` that never panics (see the module docs).
macro_rules! eprintln {
    () => {
        $crate::output::stderr_fmt(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::stderr_fmt(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` that never panics (see the module docs).
#[allow(unused_macros)]
macro_rules! eprint {
    ($($arg:tt)*) => {
        $crate::output::stderr_fmt(format_args!($($arg)*))
    };
}

/// The first failed write to standard output, if any.
static STDOUT_ERROR: Mutex<Option<String>> = Mutex::new(None);

fn stdout_error() -> std::sync::MutexGuard<'static, Option<String>> {
    STDOUT_ERROR.lock().unwrap_or_else(|p| p.into_inner())
}

/// Writes to standard output; after the first failure, remembers it and writes nothing more.
pub fn stdout_fmt(args: std::fmt::Arguments) {
    let mut failed = stdout_error();
    if failed.is_some() {
        return;
    }
    if let Err(e) = io::stdout().lock().write_fmt(args) {
        *failed = Some(e.to_string());
    }
}

/// Writes to standard error, ignoring failures.
pub fn stderr_fmt(args: std::fmt::Arguments) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// Flushes standard output; `Err` with the first write failure of the run.
pub fn flush_stdout() -> Result<()> {
    let flushed = io::stdout().lock().flush();
    let mut failed = stdout_error();
    if let (Err(e), None) = (flushed, failed.as_ref()) {
        *failed = Some(e.to_string());
    }
    match failed.as_ref() {
        Some(e) => bail!("cannot write to standard output: {e}"),
        None => Ok(()),
    }
}

/// A fit that did not converge; `main` turns it into exit status [`EXIT_UNCONVERGED`].
#[derive(Debug)]
pub struct Unconverged(pub String);

impl std::fmt::Display for Unconverged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} did not converge; nothing written (exit status {EXIT_UNCONVERGED}; rerun with \
             --accept-unconverged to keep the result)",
            self.0
        )
    }
}

impl std::error::Error for Unconverged {}

/// A fit whose verdict is `reject`, or inputs refused before the fit; `main` turns it into
/// exit status [`EXIT_REJECTED`]. The text is the cause.
#[derive(Debug)]
pub struct Rejected(pub String);

impl std::fmt::Display for Rejected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rejected: {}; nothing written (exit status {EXIT_REJECTED}; rerun with \
             --accept-rejected to keep the result anyway)",
            self.0
        )
    }
}

impl std::error::Error for Rejected {}

/// Set while a batch's files are renamed into place.
static COMMITTING: AtomicBool = AtomicBool::new(false);
/// A cleanup signal that arrived while [`COMMITTING`] was set.
static PENDING_SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Some jobs of a batch failed; `main` keeps the files written (they record the failures)
/// and turns it into exit status [`EXIT_PARTIAL`].
#[derive(Debug)]
pub struct PartialFailure(pub String);

impl std::fmt::Display for PartialFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (exit status {EXIT_PARTIAL})", self.0)
    }
}

impl std::error::Error for PartialFailure {}

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    if COMMITTING.load(Ordering::SeqCst) {
        PENDING_SIGNAL.store(sig, Ordering::SeqCst);
        return;
    }
    jointfit_io::staging::remove_registered_temps();
    // SAFETY: signal(2) and raise(3) are async-signal-safe; the default action ends the
    // process with the signal's usual status.
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
}

/// SIGINT, SIGTERM, SIGHUP and SIGPIPE (a closed pipe) remove the temporary files of unfinished writes, then end the
/// process as the signal would have.
pub fn install_signal_handlers() {
    #[cfg(unix)]
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP, libc::SIGPIPE] {
        // SAFETY: the handler only touches atomics and calls async-signal-safe functions.
        unsafe {
            libc::signal(sig, on_signal as *const () as libc::sighandler_t);
        }
    }
}

pub use jointfit_io::message::tidy;

/// Most worker threads per core that `RAYON_NUM_THREADS` may ask for.
pub const MAX_THREADS_PER_CORE: usize = 4;

/// Starts the worker threads: `RAYON_NUM_THREADS` (0 or unset: one per core), capped at
/// [`MAX_THREADS_PER_CORE`] per core (`RAYON_NUM_THREADS=100000` would spend minutes
/// starting threads that only compete for the same cores; said once).
///
/// The command's own thread is one of them (`use_current_thread`): a parallel pass started
/// from it splits its work with the other workers and runs its share itself, instead of
/// handing the whole pass to the pool and sleeping until it ends. A fit runs some
/// hundred passes of a few hundred microseconds each, and each hand-over and wake-up cost
/// tens of microseconds (`jointfit bench --fit-only 20`: 5–8 % of the fit on two cores).
/// The work is cut into the same chunks either way, so the results are the same bits.
pub fn start_threads() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let asked = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0);
    let cap = MAX_THREADS_PER_CORE * cores;
    let threads = match asked {
        Some(n) if n > cap => {
            eprintln!(
                "jointfit: warning: RAYON_NUM_THREADS={n} is more than {MAX_THREADS_PER_CORE} \
                 threads per core; using {cap}"
            );
            cap
        }
        Some(n) => n,
        None => cores,
    };
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .use_current_thread()
        .build_global();
}

/// The error and its causes on one line (see [`jointfit_io::message::one_line`], which the
/// Python package uses too, so both say the same).
pub fn one_line(e: &anyhow::Error) -> String {
    jointfit_io::message::one_line(e.chain().map(|c| c.to_string()))
}

/// A clap error on one line (its first lines up to the usage, without the misleading
/// `-- -6` hint), or help/version text as clap prints it.
pub fn clap_error(e: clap::Error) -> std::process::ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        // Help that cannot be written (`--help > /dev/full`) is a failed run.
        let printed = e.print().and_then(|()| io::stdout().flush());
        let code = if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            EXIT_USAGE
        } else if let Err(err) = printed {
            eprintln!("jointfit: error: cannot write to standard output: {err}");
            1
        } else {
            0
        };
        return std::process::ExitCode::from(code);
    }
    let text = e.to_string();
    let mut parts = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if line.is_empty() || line.starts_with("tip: to pass") {
            continue;
        }
        parts.push(line.strip_prefix("error: ").unwrap_or(line));
    }
    eprintln!(
        "jointfit: error: {} (see --help)",
        tidy(
            &parts
                .join(" ")
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ")
        )
    );
    std::process::ExitCode::from(EXIT_USAGE)
}

/// Longest pause [`PAUSE_VARIABLE`] may ask for (s).
const MAX_PAUSE_SECONDS: f64 = 30.0;
/// Testing hook: seconds to wait between writing the temporary files and renaming them, so
/// that a test can interrupt a run while its temporary files exist (at most 30 s).
pub const PAUSE_VARIABLE: &str = "JOINTFIT_TEST_PAUSE_BEFORE_COMMIT";

fn pause_for_tests() {
    if let Some(s) = std::env::var(PAUSE_VARIABLE)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| (0.0..=MAX_PAUSE_SECONDS).contains(s))
    {
        std::thread::sleep(std::time::Duration::from_secs_f64(s));
    }
}

/// Renames a batch's files into place. An interrupt during the renames waits for the last
/// one, so that it lands before the first rename or after the last, never between two. The
/// exit status then says what happened: an interrupted run whose files all landed ends as a
/// success (with a note on stderr), one whose commit failed ends as the signal would have.
fn commit(b: jointfit_io::staging::Batch) -> Result<()> {
    COMMITTING.store(true, Ordering::SeqCst);
    let r = b.commit().map(|_| ()).map_err(anyhow::Error::from);
    COMMITTING.store(false, Ordering::SeqCst);
    let sig = PENDING_SIGNAL.swap(0, Ordering::SeqCst);
    if sig != 0 {
        if r.is_ok() {
            eprintln!(
                "jointfit: note: interrupted (signal {sig}) while the outputs were renamed into \
                 place; every output was written"
            );
        } else {
            #[cfg(unix)]
            on_signal(sig);
        }
    }
    r
}

/// Ends a run: on success with standard output intact, commits the batch of written files;
/// otherwise discards it and prints one error line. Returns the exit status.
pub fn finish(
    result: Result<()>,
    batch: Option<jointfit_io::staging::Batch>,
) -> std::process::ExitCode {
    let result = result.and_then(|()| flush_stdout());
    pause_for_tests();
    // A partly failed batch keeps its files: commit as on success, then report.
    let partial = matches!(&result, Err(e) if e.downcast_ref::<PartialFailure>().is_some());
    let (result, batch) = match (result, batch) {
        (Err(e), Some(b)) if partial => (commit(b).and(Err(e)), None),
        (r, b) => (r, b),
    };
    let result = result.and_then(|()| match batch {
        Some(b) => commit(b),
        None => Ok(()),
    });
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("jointfit: error: {}", one_line(&e));
            if e.downcast_ref::<Unconverged>().is_some() {
                std::process::ExitCode::from(EXIT_UNCONVERGED)
            } else if e.downcast_ref::<Rejected>().is_some() {
                std::process::ExitCode::from(EXIT_REJECTED)
            } else if e.downcast_ref::<PartialFailure>().is_some() {
                std::process::ExitCode::from(EXIT_PARTIAL)
            } else {
                std::process::ExitCode::FAILURE
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit_io::message::MAX_MESSAGE_CHARS;
    use std::fs;

    #[test]
    fn an_unconverged_fit_is_status_3_and_discards_the_batch() {
        use std::process::ExitCode;
        let dir = jointfit_testkit::scratch("unconv");
        let out = dir.join("fitted.toml");
        let batch = jointfit_io::staging::Batch::begin().unwrap();
        jointfit_io::atomic::write_atomic(&out, b"fit").unwrap();
        let code = finish(
            Err(Unconverged("the calibration".into()).into()),
            Some(batch),
        );
        assert_eq!(code, ExitCode::from(EXIT_UNCONVERGED));
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 0, "nothing written");
        let other = finish(Err(anyhow::anyhow!("x")), None);
        assert_eq!(other, ExitCode::FAILURE);
    }

    #[test]
    fn causes_are_said_once_on_one_line() {
        let inner = io::Error::new(io::ErrorKind::NotFound, "No such file (os error 2)");
        let e = anyhow::Error::new(inner)
            .context("x.trc: cannot read: No such file (os error 2)")
            .context("loading trial\n  second line");
        assert_eq!(
            one_line(&e),
            "loading trial second line: x.trc: cannot read: No such file (os error 2)"
        );
    }

    #[test]
    fn long_tokens_and_numbers_are_shortened() {
        let big = format!("rate {}0 Hz", "1".repeat(300));
        let t = tidy(&big);
        assert!(t.starts_with("rate 1.111") && t.ends_with("e300 Hz"), "{t}");
        let long = format!("bad value \"{}\"", "a".repeat(5000));
        let t = tidy(&long);
        assert!(t.chars().count() < 200, "{t}");
        assert!(t.contains("[4926 characters]"), "{t}");
        let many = "word ".repeat(1000);
        assert!(tidy(&many).chars().count() <= MAX_MESSAGE_CHARS + 1);
    }
}
