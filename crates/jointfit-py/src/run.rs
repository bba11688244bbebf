//! Long solves from Python: interruptible, with progress, and never a panic into Python.
//!
//! A solve runs on a worker thread while the calling thread waits with the GIL released. The
//! calling thread wakes at least every [`POLL`] to run Python's signal handlers (Ctrl-C,
//! Jupyter's interrupt button) and to hand the solver's progress to a Python callback. On an
//! exception (KeyboardInterrupt, or one raised by the callback) it sets a cancel flag and
//! raises at once; the solver sees the flag at its next observer hook (after the current
//! outer iteration) and unwinds, so it stops soon after instead of running to its end.
//! A panic of the solver becomes a `JointfitError` ([`panic_error`]).

use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::Duration;

use jointfit::solver::Observer;
use jointfit::solver::Termination;
use pyo3::prelude::*;

use crate::msg;

/// How often the waiting thread looks at Python's signals.
const POLL: Duration = Duration::from_millis(50);

/// The payload a cancelled solve unwinds with (no panic message is printed for it).
struct Cancelled;

/// What the solver reports.
enum Event {
    Stage(String),
    Iteration(usize, f64),
    Progress(usize, usize),
}

enum Msg<T> {
    Event(Event),
    Done(std::thread::Result<T>),
}

/// The observer handed to the solver: forwards progress, unwinds when cancelled.
struct Relay<T> {
    cancel: Arc<AtomicBool>,
    tx: Sender<Msg<T>>,
}

impl<T> Relay<T> {
    fn check(&self) {
        if self.cancel.load(Ordering::Relaxed) {
            resume_unwind(Box::new(Cancelled));
        }
    }
    fn send(&self, e: Event) {
        self.check();
        let _ = self.tx.send(Msg::Event(e));
    }
}

impl<T> Observer for Relay<T> {
    fn stage_started(&mut self, stage: &str, _budget: Option<usize>) {
        self.send(Event::Stage(stage.to_string()));
    }
    fn iteration(&mut self, iteration: usize, objective: f64) {
        self.send(Event::Iteration(iteration, objective));
    }
    fn stage_ended(&mut self, _termination: Termination) {
        self.check();
    }
    fn progress(&mut self, done: usize, total: usize) {
        self.send(Event::Progress(done, total));
    }
}

/// The `JointfitError` of a panic: an internal error, with the panic's message.
pub(crate) fn panic_error(payload: Box<dyn Any + Send>) -> PyErr {
    let text = if let Some(s) = payload.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "no message".to_string()
    };
    msg(format!(
        "internal error of jointfit (please report it with the call that caused it): {text}"
    ))
}

/// Runs `f`, turning a panic into a `JointfitError`.
pub(crate) fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| Err(panic_error(p)))
}

/// Runs `work` on a worker thread (see the module docs); `progress` is called on this thread
/// as `progress(stage, iteration, objective)` (the objective in m²; `iteration` 0 and the
/// objective NaN when a stage begins, or when a unit of a long job is done, then the stage
/// is `"done k of n"`).
pub(crate) fn interruptible<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&mut dyn Observer) -> T + Send + 'static,
) -> PyResult<T> {
    let cancel = Arc::new(AtomicBool::new(false));
    let (tx, rx) = channel::<Msg<T>>();
    // Locked only by this thread: the lock makes the receiver shareable with `detach`.
    let rx = std::sync::Mutex::new(rx);
    let mut relay = Relay {
        cancel: cancel.clone(),
        tx: tx.clone(),
    };
    std::thread::Builder::new()
        .name("jointfit solve".into())
        .spawn(move || {
            let out = catch_unwind(AssertUnwindSafe(|| work(&mut relay)));
            let _ = tx.send(Msg::Done(out));
        })
        .map_err(|e| msg(format!("cannot start the solver thread: {e}")))?;
    let stop = |e: PyErr| {
        cancel.store(true, Ordering::Relaxed);
        e
    };
    let mut stage = String::new();
    loop {
        match py.detach(|| {
            rx.lock().map_or(Err(RecvTimeoutError::Disconnected), |r| {
                r.recv_timeout(POLL)
            })
        }) {
            Ok(Msg::Done(Ok(v))) => return Ok(v),
            Ok(Msg::Done(Err(payload))) => return Err(panic_error(payload)),
            Ok(Msg::Event(e)) => {
                if let Some(cb) = progress {
                    let call = match e {
                        Event::Stage(s) => {
                            stage = s;
                            cb.call1((stage.as_str(), 0usize, f64::NAN))
                        }
                        Event::Iteration(i, c) => cb.call1((stage.as_str(), i, c)),
                        Event::Progress(done, total) => {
                            cb.call1((format!("done {done} of {total}"), 0usize, f64::NAN))
                        }
                    };
                    call.map_err(stop)?;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                return Err(msg(
                    "internal error of jointfit: the solver thread ended without a result",
                ))
            }
        }
        py.check_signals().map_err(stop)?;
    }
}

/// The progress argument: None or False (none), True (a tqdm bar when tqdm is installed,
/// else lines on stderr: `jointfit._progress.Progress`, closed by [`close_progress`]), or a
/// callable.
pub(crate) fn progress_arg<'py>(
    py: Python<'py>,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let Some(p) = progress else {
        return Ok(None);
    };
    if p.is_none() {
        return Ok(None);
    }
    if let Ok(b) = p.cast::<pyo3::types::PyBool>() {
        if !b.is_true() {
            return Ok(None);
        }
        let bar = py
            .import("jointfit._progress")?
            .getattr("Progress")?
            .call0()?;
        return Ok(Some(bar));
    }
    if !p.is_callable() {
        return Err(msg(format!(
            "progress must be None, True, False or a callable progress(stage, iteration, objective), not {}",
            crate::args::type_name(p)
        )));
    }
    Ok(Some(p.clone()))
}

/// Closes a progress bar made by [`progress_arg`] (a user's callable is left alone).
pub(crate) fn close_progress(py: Python<'_>, progress: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
    if let Some(p) = progress {
        let ours = py.import("jointfit._progress")?.getattr("Progress")?;
        if p.is_instance(&ours)? {
            p.call_method0("close")?;
        }
    }
    Ok(())
}
