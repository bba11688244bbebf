//! Progress of long commands on stderr: a bar with elapsed time and ETA on a terminal, a plain
//! log line every few seconds otherwise (logs and CI), nothing for runs shorter than that.
//!
//! ```ignore
//! let mut bar = Progress::new("ik walking1.trc", Some(n_frames as u64));
//! for f in 0..n_frames {
//!     // ... work ...
//!     bar.set(f as u64 + 1, "");
//! }
//! bar.finish("done");
//! ```
//!
//! `JOINTFIT_PROGRESS` overrides the choice: `bar`, `log` (a line every
//! `JOINTFIT_PROGRESS_SECONDS`, default 5), or `quiet`; `auto` (default) is `bar` when
//! stderr is a terminal and `log` otherwise. Progress never goes to stdout, so `--json` output
//! stays clean.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Redrawn in place on a terminal.
    Bar,
    /// A plain line every `interval`.
    Log,
    Quiet,
}

impl Mode {
    /// The mode from `JOINTFIT_PROGRESS` (or whether stderr is a terminal).
    pub fn from_env() -> Mode {
        match std::env::var("JOINTFIT_PROGRESS").as_deref() {
            Ok("bar") => Mode::Bar,
            Ok("log") => Mode::Log,
            Ok("quiet") | Ok("never") | Ok("0") => Mode::Quiet,
            _ if std::io::stderr().is_terminal() => Mode::Bar,
            _ => Mode::Log,
        }
    }
}

/// One task's progress: position out of an optional total, plus a free-form message.
pub struct Progress {
    label: String,
    total: Option<u64>,
    /// What is counted ("iterations", "frames"), shown after the count.
    unit: String,
    pos: u64,
    message: String,
    mode: Mode,
    start: Instant,
    last: Option<Instant>,
    interval: Duration,
    printed: bool,
    done: bool,
}

const BAR_WIDTH: usize = 20;

/// Longest log interval `JOINTFIT_PROGRESS_SECONDS` may set (one day).
pub const MAX_LOG_SECONDS: f64 = 86_400.0;

/// The log interval in `JOINTFIT_PROGRESS_SECONDS`: a finite number of seconds from 0 to
/// [`MAX_LOG_SECONDS`], else `None`.
fn log_interval(s: &str) -> Option<f64> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| (0.0..=MAX_LOG_SECONDS).contains(v))
}
const SPINNER: [char; 4] = ['|', '/', '-', '\\'];

impl Progress {
    /// A task called `label`, with `total` steps when known.
    pub fn new(label: &str, total: Option<u64>) -> Progress {
        let mode = Mode::from_env();
        let secs = match std::env::var("JOINTFIT_PROGRESS_SECONDS") {
            Ok(s) => log_interval(&s).unwrap_or_else(|| {
                // One warning per run, however many tasks report progress.
                static WARNED: std::sync::Once = std::sync::Once::new();
                WARNED.call_once(|| {
                    eprintln!(
                        "jointfit: warning: JOINTFIT_PROGRESS_SECONDS={}: not a number of seconds \
                     from 0 to {MAX_LOG_SECONDS}; using 5",
                        crate::output::tidy(&s)
                    )
                });
                5.0
            }),
            Err(_) => 5.0,
        };
        Progress::with_mode(label, total, mode, Duration::from_secs_f64(secs))
    }

    /// As [`Progress::new`] with an explicit mode and log interval (tests).
    pub fn with_mode(label: &str, total: Option<u64>, mode: Mode, interval: Duration) -> Progress {
        Progress {
            label: label.to_string(),
            total,
            unit: String::new(),
            pos: 0,
            message: String::new(),
            mode,
            start: Instant::now(),
            last: None,
            interval,
            printed: false,
            done: false,
        }
    }

    /// Names what is counted, e.g. `"iterations"` (builder style).
    pub fn unit(mut self, unit: &str) -> Progress {
        self.unit = unit.to_string();
        self
    }

    pub fn set_total(&mut self, total: Option<u64>) {
        self.total = total;
    }

    /// Moves to step `pos` with a message (e.g. the current cost); redraws when due.
    pub fn set(&mut self, pos: u64, message: &str) {
        self.pos = pos;
        if message != self.message {
            self.message = message.to_string();
        }
        self.tick(false);
    }

    #[allow(dead_code)] // API for per-item loops (batch IK)
    pub fn inc(&mut self, n: u64) {
        self.pos += n;
        self.tick(false);
    }

    /// Ends the task: on a terminal the bar is replaced by a summary line; in log mode a last
    /// line is written only if earlier lines were.
    pub fn finish(&mut self, message: &str) {
        if self.done {
            return;
        }
        self.message = message.to_string();
        self.done = true;
        match self.mode {
            Mode::Bar => {
                let line = format!(
                    "{}: {} in {}{}",
                    self.label,
                    self.count(),
                    human(self.start.elapsed()),
                    self.suffix()
                );
                eprint!("\r\x1b[2K{line}\n");
            }
            Mode::Log if self.printed => {
                eprintln!(
                    "jointfit: {}: done, {} in {}{}",
                    self.label,
                    self.count(),
                    human(self.start.elapsed()),
                    self.suffix()
                );
            }
            _ => {}
        }
    }

    /// Elapsed time and estimated time left (known total and at least one step done).
    pub fn eta(&self) -> Option<Duration> {
        let total = self.total?;
        if self.pos == 0 || self.pos >= total {
            return None;
        }
        let per = self.start.elapsed().as_secs_f64() / self.pos as f64;
        Duration::try_from_secs_f64(per * (total - self.pos) as f64).ok()
    }

    fn count(&self) -> String {
        let n = match self.total {
            Some(t) => format!("{}/{}", self.pos, t),
            None => format!("{}", self.pos),
        };
        if self.unit.is_empty() {
            n
        } else {
            format!("{n} {}", self.unit)
        }
    }

    fn suffix(&self) -> String {
        if self.message.is_empty() {
            String::new()
        } else {
            format!(", {}", self.message)
        }
    }

    /// The line as drawn on a terminal.
    pub fn bar_line(&self) -> String {
        let elapsed = self.start.elapsed();
        let mut line = format!("{} ", self.label);
        match self.total {
            Some(t) if t > 0 => {
                let frac = (self.pos as f64 / t as f64).clamp(0.0, 1.0);
                let fill = (frac * BAR_WIDTH as f64).round() as usize;
                line.push('[');
                line.push_str(&"#".repeat(fill));
                line.push_str(&"-".repeat(BAR_WIDTH - fill));
                // The bar says what is counted; the unit would only crowd the line.
                line.push_str(&format!("] {}/{} {:>3.0}%", self.pos, t, 100.0 * frac));
            }
            _ => {
                let k = (elapsed.as_millis() / 120) as usize % SPINNER.len();
                line.push_str(&format!("{} {}", SPINNER[k], self.count()));
            }
        }
        line.push_str(&format!("  {}", human(elapsed)));
        if let Some(eta) = self.eta() {
            line.push_str(&format!("  ETA {}", human(eta)));
        }
        if !self.message.is_empty() {
            line.push_str("  ");
            line.push_str(&self.message);
        }
        let width = terminal_width().max(20);
        if line.chars().count() >= width {
            line = line.chars().take(width - 1).collect();
        }
        line
    }

    /// The line written in log mode.
    pub fn log_line(&self) -> String {
        let mut line = format!("jointfit: {}: {}", self.label, self.count());
        if let Some(t) = self.total.filter(|t| *t > 0) {
            line.push_str(&format!(" ({:.0}%)", 100.0 * self.pos as f64 / t as f64));
        }
        line.push_str(&format!(", {} elapsed", human(self.start.elapsed())));
        if let Some(eta) = self.eta() {
            line.push_str(&format!(", ETA {}", human(eta)));
        }
        line.push_str(&self.suffix());
        line
    }

    fn tick(&mut self, force: bool) {
        let now = Instant::now();
        match self.mode {
            Mode::Quiet => {}
            Mode::Bar => {
                let due = self
                    .last
                    .is_none_or(|t| now - t >= Duration::from_millis(100));
                if due || force {
                    self.last = Some(now);
                    eprint!("\r\x1b[2K{}", self.bar_line());
                    let _ = std::io::stderr().flush();
                    self.printed = true;
                }
            }
            Mode::Log => {
                let since = now - self.last.unwrap_or(self.start);
                if since >= self.interval || force {
                    self.last = Some(now);
                    eprintln!("{}", self.log_line());
                    self.printed = true;
                }
            }
        }
    }
}

impl Drop for Progress {
    /// A bar left behind by an early return (an error) is erased, so the error line that
    /// follows starts at column 0.
    fn drop(&mut self) {
        if self.mode == Mode::Bar && self.printed && !self.done {
            eprint!("\r\x1b[2K");
        }
    }
}

/// Columns of the terminal on stderr: `$COLUMNS` if set, else the kernel's window size, else 80.
fn terminal_width() -> usize {
    if let Some(c) = std::env::var("COLUMNS")
        .ok()
        .and_then(|c| c.parse::<usize>().ok())
    {
        return c;
    }
    #[cfg(unix)]
    {
        let mut ws = libc::winsize {
            ws_row: 0,
            ws_col: 0,
            ws_xpixel: 0,
            ws_ypixel: 0,
        };
        // SAFETY: TIOCGWINSZ only writes a `winsize` into the pointer it is given.
        let ok = unsafe { libc::ioctl(libc::STDERR_FILENO, libc::TIOCGWINSZ, &mut ws) } == 0;
        if ok && ws.ws_col > 0 {
            return ws.ws_col as usize;
        }
    }
    80
}

/// `850 ms`, `12.3 s`, `4 min 05 s`, `2 h 03 min`.
pub fn human(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 1.0 {
        format!("{:.0} ms", s * 1e3)
    } else if s < 60.0 {
        format!("{s:.1} s")
    } else if s < 3600.0 {
        format!("{} min {:02} s", (s / 60.0) as u64, s as u64 % 60)
    } else {
        format!(
            "{} h {:02} min",
            (s / 3600.0) as u64,
            (s as u64 % 3600) / 60
        )
    }
}

/// Progress of a task in named stages (e.g. a particle swarm, then a polish): one
/// [`Progress`] per stage, the previous one finished when the stage changes.
pub struct StageProgress {
    current: Option<(String, Progress)>,
    last_message: String,
    unit: String,
}

impl StageProgress {
    /// Stages counting `unit` (e.g. "iterations").
    pub fn new(unit: &str) -> StageProgress {
        StageProgress {
            current: None,
            last_message: String::new(),
            unit: unit.to_string(),
        }
    }

    /// Step `pos` of `stage` (out of `total` when known), with a message.
    pub fn step(&mut self, stage: &str, pos: u64, total: Option<u64>, message: &str) {
        if self.current.as_ref().is_none_or(|(s, _)| s != stage) {
            self.finish();
            let p = Progress::new(stage, total).unit(&self.unit);
            self.current = Some((stage.to_string(), p));
        }
        if let Some((_, p)) = &mut self.current {
            p.set(pos, message);
        }
        self.last_message = message.to_string();
    }

    /// Starts `stage`, which has no steps to count, with a line at once (unless quiet), so
    /// that a long step without iterations is not silent; the next stage or
    /// [`StageProgress::finish`] writes its end and duration.
    pub fn announce(&mut self, stage: &str) {
        self.finish();
        let mut p = Progress::new(stage, None);
        if p.mode != Mode::Quiet {
            eprintln!("jointfit: {stage}: started");
            p.printed = true;
            // A terminal gets a summary line at the end, no bar to redraw.
            if p.mode == Mode::Bar {
                p.mode = Mode::Log;
            }
        }
        self.current = Some((stage.to_string(), p));
        self.last_message = String::new();
    }

    /// Finishes the current stage, if any.
    pub fn finish(&mut self) {
        if let Some((_, mut p)) = self.current.take() {
            p.finish(&self.last_message);
        }
    }
}

impl Drop for StageProgress {
    fn drop(&mut self) {
        self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_well() {
        assert_eq!(human(Duration::from_millis(850)), "850 ms");
        assert_eq!(human(Duration::from_secs_f64(12.34)), "12.3 s");
        assert_eq!(human(Duration::from_secs(245)), "4 min 05 s");
        assert_eq!(human(Duration::from_secs(7380)), "2 h 03 min");
    }

    #[test]
    fn bar_shows_fraction_eta_and_message() {
        let mut p = Progress::with_mode("pso", Some(200), Mode::Quiet, Duration::ZERO);
        p.set(50, "cost 12.5 mm²");
        let line = p.bar_line();
        assert!(
            line.starts_with("pso [#####---------------] 50/200  25%"),
            "{line}"
        );
        assert!(line.contains("ETA"), "{line}");
        assert!(line.ends_with("cost 12.5 mm²"), "{line}");
        let log = p.log_line();
        assert!(log.starts_with("jointfit: pso: 50/200 (25%), "), "{log}");
        assert!(log.ends_with(", cost 12.5 mm²"), "{log}");
    }

    #[test]
    fn unknown_total_has_no_eta() {
        let mut p = Progress::with_mode("joint", None, Mode::Quiet, Duration::ZERO);
        p.set(7, "");
        assert_eq!(p.eta(), None);
        assert!(p.bar_line().contains(" 7  "), "{}", p.bar_line());
        assert!(!p.log_line().contains('%'));
        let mut p =
            Progress::with_mode("joint", None, Mode::Quiet, Duration::ZERO).unit("iterations");
        p.set(3, "");
        assert!(
            p.log_line().starts_with("jointfit: joint: 3 iterations, "),
            "{}",
            p.log_line()
        );
    }

    #[test]
    fn eta_scales_with_remaining_steps() {
        let mut p = Progress::with_mode("x", Some(4), Mode::Quiet, Duration::ZERO);
        std::thread::sleep(Duration::from_millis(40));
        p.set(1, "");
        let eta = p.eta().unwrap().as_secs_f64();
        // Three steps left at >= 40 ms per step.
        assert!(eta >= 0.119, "{eta}");
        p.set(4, "");
        assert_eq!(p.eta(), None);
    }

    #[test]
    fn log_interval_is_bounded() {
        assert_eq!(log_interval("2.5"), Some(2.5));
        assert_eq!(log_interval("0"), Some(0.0));
        for bad in ["1e20", "-1", "NaN", "inf", "x", "86401"] {
            assert_eq!(log_interval(bad), None, "{bad}");
        }
    }
}
