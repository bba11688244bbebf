//! The temporary files of [`write_atomic`](crate::atomic::write_atomic): a registry that a
//! signal handler can empty, and batches that make a group of writes all-or-nothing.
//!
//! **Registry.** Every temporary file is registered while it exists. A program that catches
//! SIGINT/SIGTERM calls [`remove_registered_temps`] from its handler, so an interrupted run
//! leaves no hidden temporary file behind. The registry is a fixed array of atomic pointers to
//! NUL-terminated paths allocated before registration, so the removal only loads, swaps and
//! calls `unlink(2)`, which are async-signal-safe. Whoever swaps a slot to null owns its
//! path: the handler never frees (the process is about to end), the normal path frees.
//!
//! **Batches.** While a [`Batch`] is open, `write_atomic` writes and syncs its temporary file
//! but defers the rename; [`Batch::commit`] renames every file, and dropping the batch without
//! a commit removes every temporary file and every directory the batch created through
//! [`create_dir_all`]. A command that writes several files opens one batch, so a failure in
//! the last file leaves none of them.
//!
//! **Killed runs.** SIGKILL cannot be caught; the temporary file names carry the writer's
//! process id, and the next write into the same directory removes the temporary files of
//! writers that are no longer running ([`sweep_stale`]).

use std::ffi::CString;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicPtr, Ordering};
use std::sync::Mutex;

const SLOTS: usize = 256;

static REGISTRY: [AtomicPtr<std::ffi::c_char>; SLOTS] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];

/// A registered temporary file (index into the registry), or none when the registry is full
/// or the path cannot be represented as a C string.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Slot(Option<usize>);

pub(crate) fn register(path: &Path) -> Slot {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let Ok(c) = CString::new(path.as_os_str().as_bytes()) else {
            return Slot(None);
        };
        let raw = c.into_raw();
        for (i, slot) in REGISTRY.iter().enumerate() {
            if slot
                .compare_exchange(
                    std::ptr::null_mut(),
                    raw,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                )
                .is_ok()
            {
                return Slot(Some(i));
            }
        }
        // SAFETY: `raw` came from `CString::into_raw` above and was not stored anywhere.
        drop(unsafe { CString::from_raw(raw) });
        Slot(None)
    }
    #[cfg(not(unix))]
    {
        let _ = (path, CString::default());
        Slot(None)
    }
}

pub(crate) fn unregister(slot: Slot) {
    if let Some(i) = slot.0 {
        let raw = REGISTRY[i].swap(std::ptr::null_mut(), Ordering::AcqRel);
        if !raw.is_null() {
            // SAFETY: only `register` stores pointers, all from `CString::into_raw`; the swap
            // made this call their only owner.
            drop(unsafe { CString::from_raw(raw) });
        }
    }
}

/// Removes every registered temporary file. Async-signal-safe (atomic swaps and `unlink`
/// only, no allocation, no lock): meant for a SIGINT/SIGTERM handler just before the
/// process ends. The paths are leaked, as the process is ending.
pub fn remove_registered_temps() {
    for slot in REGISTRY.iter() {
        let raw = slot.swap(std::ptr::null_mut(), Ordering::AcqRel);
        if !raw.is_null() {
            #[cfg(unix)]
            // SAFETY: `raw` is a NUL-terminated path from `CString::into_raw` that nothing
            // else can free any more (we swapped it out).
            unsafe {
                libc::unlink(raw);
            }
        }
    }
}

/// A temporary file whose rename waits for the batch's commit.
#[derive(Debug)]
struct Pending {
    tmp: PathBuf,
    dest: PathBuf,
    slot: Slot,
}

#[derive(Debug)]
struct State {
    /// Only writes from the thread that opened the batch are deferred.
    owner: std::thread::ThreadId,
    pending: Vec<Pending>,
    created_dirs: Vec<PathBuf>,
}

impl State {
    fn new() -> State {
        State {
            owner: std::thread::current().id(),
            pending: Vec::new(),
            created_dirs: Vec::new(),
        }
    }

    fn mine(&mut self) -> Option<&mut State> {
        (self.owner == std::thread::current().id()).then_some(self)
    }
}

static BATCH: Mutex<Option<State>> = Mutex::new(None);

fn batch() -> std::sync::MutexGuard<'static, Option<State>> {
    BATCH.lock().unwrap_or_else(|p| p.into_inner())
}

/// If a batch is open, takes over the temporary file `tmp` for `dest` and returns `true`.
pub(crate) fn defer(tmp: &Path, dest: &Path, slot: Slot) -> bool {
    match batch().as_mut().and_then(State::mine) {
        Some(state) => {
            state.pending.push(Pending {
                tmp: tmp.to_path_buf(),
                dest: dest.to_path_buf(),
                slot,
            });
            true
        }
        None => false,
    }
}

/// A group of writes that land together or not at all (see the module docs). One batch may
/// be open at a time in a process; it covers the writes of the thread that opened it.
#[derive(Debug)]
#[must_use = "dropping a batch without commit() discards its files"]
pub struct Batch {
    _private: (),
}

impl Batch {
    /// Opens the batch; fails if one is open already.
    pub fn begin() -> io::Result<Batch> {
        let mut b = batch();
        if b.is_some() {
            return Err(io::Error::other("a batch of writes is already open"));
        }
        *b = Some(State::new());
        Ok(Batch { _private: () })
    }

    /// Renames every staged file to its destination, in the order written, and returns the
    /// destinations. If a rename fails, the files not yet renamed are removed (the renamed
    /// ones stay: a rename within one directory is the last step and cannot be undone).
    pub fn commit(self) -> io::Result<Vec<PathBuf>> {
        let state = batch().take();
        std::mem::forget(self);
        let mut done = Vec::new();
        let pending = state.map(|s| s.pending).unwrap_or_default();
        // A destination that is a directory would fail its rename: refuse before any lands.
        if let Some(p) = pending.iter().find(|p| p.dest.is_dir()) {
            let e = io::Error::other(format!("{}: is a directory", p.dest.display()));
            for p in &pending {
                let _ = fs::remove_file(&p.tmp);
                unregister(p.slot);
            }
            return Err(e);
        }
        let mut pending = pending.into_iter();
        for p in pending.by_ref() {
            let r = fs::rename(&p.tmp, &p.dest);
            unregister(p.slot);
            if let Err(e) = r {
                let _ = fs::remove_file(&p.tmp);
                for rest in pending {
                    let _ = fs::remove_file(&rest.tmp);
                    unregister(rest.slot);
                }
                return Err(io::Error::new(
                    e.kind(),
                    format!("{}: cannot rename into place: {e}", p.dest.display()),
                ));
            }
            crate::atomic::sync_parent(&p.dest);
            done.push(p.dest);
        }
        Ok(done)
    }
}

impl Drop for Batch {
    fn drop(&mut self) {
        if let Some(state) = batch().take() {
            for p in state.pending {
                let _ = fs::remove_file(&p.tmp);
                unregister(p.slot);
            }
            for d in state.created_dirs.iter().rev() {
                // Only empty directories go: anything else in them is not ours.
                let _ = fs::remove_dir(d);
            }
        }
    }
}

/// `std::fs::create_dir_all` that, inside an open batch, remembers the directories it
/// created so that a discarded batch removes them again.
pub fn create_dir_all(dir: &Path) -> io::Result<()> {
    let mut missing = Vec::new();
    let mut cur = Some(dir);
    while let Some(d) = cur {
        if d.as_os_str().is_empty() || d.exists() {
            break;
        }
        missing.push(d.to_path_buf());
        cur = d.parent();
    }
    fs::create_dir_all(dir)?;
    if let Some(state) = batch().as_mut().and_then(State::mine) {
        state.created_dirs.extend(missing.into_iter().rev());
    }
    Ok(())
}

/// Removes temporary files `.{base}.{pid}.{n}.tmp` in `dir` left by writers that are no
/// longer running (killed with SIGKILL, say). Best effort; a live process's files are kept.
pub(crate) fn sweep_stale(dir: &Path, base: &str) {
    #[cfg(unix)]
    {
        let Ok(entries) = fs::read_dir(dir) else {
            return;
        };
        let prefix = format!(".{base}.");
        let me = std::process::id();
        for e in entries.flatten() {
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            let Some(rest) = name.strip_prefix(&prefix) else {
                continue;
            };
            let Some(rest) = rest.strip_suffix(".tmp") else {
                continue;
            };
            let mut parts = rest.split('.');
            let (Some(pid), Some(n), None) = (parts.next(), parts.next(), parts.next()) else {
                continue;
            };
            let (Ok(pid), true) = (pid.parse::<u32>(), n.bytes().all(|b| b.is_ascii_digit()))
            else {
                continue;
            };
            if pid == me || pid == 0 || pid > i32::MAX as u32 {
                continue;
            }
            // SAFETY: kill with signal 0 only checks whether the process exists.
            let gone = unsafe { libc::kill(pid as libc::pid_t, 0) } != 0
                && io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH);
            if gone {
                let _ = fs::remove_file(e.path());
            }
        }
    }
    #[cfg(not(unix))]
    let _ = (dir, base);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atomic::write_atomic;

    use jointfit_testkit::entries;

    /// One test for everything that opens a batch: a batch is process-wide, so tests that
    /// open one must not run in parallel.
    #[test]
    fn batches_commit_all_or_nothing_and_registry_empties() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        // Discarded batch: nothing lands, the directory it created goes too.
        {
            let batch = Batch::begin().unwrap();
            assert!(Batch::begin().is_err());
            let sub = dir.path().join("new/deeper");
            create_dir_all(&sub).unwrap();
            write_atomic(&a, b"one").unwrap();
            write_atomic(&sub.join("c.txt"), b"two").unwrap();
            assert!(!a.exists());
            drop(batch);
        }
        assert_eq!(entries(dir.path()), Vec::<String>::new());
        // Committed batch: both land.
        let batch = Batch::begin().unwrap();
        write_atomic(&a, b"one").unwrap();
        write_atomic(&b, b"two").unwrap();
        assert_eq!(entries(dir.path()).len(), 2, "two temporary files");
        let done = batch.commit().unwrap();
        assert_eq!(done, vec![a.clone(), b.clone()]);
        assert_eq!(fs::read(&a).unwrap(), b"one");
        assert_eq!(entries(dir.path()), vec!["a.txt", "b.txt"]);
        // The registry removes a temporary file as a signal handler would.
        let batch = Batch::begin().unwrap();
        write_atomic(&dir.path().join("c.txt"), b"three").unwrap();
        assert_eq!(entries(dir.path()).len(), 3);
        remove_registered_temps();
        assert_eq!(entries(dir.path()), vec!["a.txt", "b.txt"]);
        drop(batch);
    }

    #[test]
    fn stale_temps_of_dead_writers_are_swept() {
        let dir = tempfile::tempdir().unwrap();
        // A pid far above any pid_max in use is not running.
        let dead = dir.path().join(".out.trc.2147483600.0.tmp");
        let mine = dir
            .path()
            .join(format!(".out.trc.{}.99.tmp", std::process::id()));
        let other = dir.path().join(".other.trc.2147483600.0.tmp");
        for p in [&dead, &mine, &other] {
            fs::write(p, b"x").unwrap();
        }
        sweep_stale(dir.path(), "out.trc");
        assert!(!dead.exists());
        assert!(mine.exists() && other.exists());
    }
}
