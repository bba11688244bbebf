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
//! # Journal
//!
//! A commit renames files one by one, possibly in several directories; a process killed
//! between two renames would leave new files beside old ones. [`Batch::commit`] therefore
//! first takes an exclusive advisory lock (`flock`) on every destination directory (so two
//! processes committing into the same directories take turns instead of interleaving their
//! renames), then writes a journal `.jointfit-commit.<pid>.journal` listing every
//! (temporary file, destination) pair into each destination directory, renames, and
//! removes the journals. The commit point is the last journal copy: [`recover`], which the
//! next write into any of those directories runs first, completes a dead writer's commit
//! whose journal is in all its directories (the temporary files were complete and synced
//! before the journal was written) and undoes one whose journal is not (no rename had
//! happened yet). Either way the directories end with all of the new files or none.
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
    /// destinations, all or nothing across a crash (see [`journal`](self#journal)): the
    /// destination directories are locked (an advisory lock that other `jointfit` processes
    /// committing into them wait for), a journal listing every rename is written into each of
    /// them, the renames follow, then the journals go. If a rename fails, the files not yet
    /// renamed are removed (the renamed ones stay: a rename within one directory is the last
    /// step and cannot be undone).
    pub fn commit(self) -> io::Result<Vec<PathBuf>> {
        let state = batch().take();
        std::mem::forget(self);
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
        if pending.is_empty() {
            return Ok(Vec::new());
        }
        let moves: Vec<(PathBuf, PathBuf)> = pending
            .iter()
            .map(|p| (absolute(&p.tmp), absolute(&p.dest)))
            .collect();
        let dirs = directories(moves.iter().map(|(_, d)| d.as_path()));
        let _locks = lock_all(&dirs);
        let journal = Journal {
            pid: std::process::id(),
            dirs: dirs.clone(),
            moves,
        };
        let written = journal.write();
        let mut done = Vec::new();
        let mut pending = pending.into_iter();
        let mut first = true;
        for p in pending.by_ref() {
            if !first {
                pause_between_renames();
            }
            first = false;
            let r = fs::rename(&p.tmp, &p.dest);
            unregister(p.slot);
            if let Err(e) = r {
                let _ = fs::remove_file(&p.tmp);
                for rest in pending {
                    let _ = fs::remove_file(&rest.tmp);
                    unregister(rest.slot);
                }
                journal.remove();
                return Err(io::Error::new(
                    e.kind(),
                    format!("{}: cannot rename into place: {e}", p.dest.display()),
                ));
            }
            done.push(p.dest);
        }
        for d in &dirs {
            crate::atomic::sync_parent(&d.join("x"));
        }
        if written {
            journal.remove();
        }
        Ok(done)
    }
}

/// Testing hook: seconds to wait between two renames of a commit (at most 30), so that a test
/// can kill a process in the middle of its commit.
pub const PAUSE_BETWEEN_RENAMES: &str = "JOINTFIT_TEST_PAUSE_BETWEEN_RENAMES";

fn pause_between_renames() {
    if let Some(s) = std::env::var(PAUSE_BETWEEN_RENAMES)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| (0.0..=30.0).contains(s))
    {
        std::thread::sleep(std::time::Duration::from_secs_f64(s));
    }
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// The distinct parent directories of `paths`, sorted (the order locks are taken in).
fn directories<'a>(paths: impl Iterator<Item = &'a Path>) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = paths
        .map(|p| match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        })
        .collect();
    dirs.sort();
    dirs.dedup();
    dirs
}

/// Exclusive advisory locks (`flock`) on the directories `dirs`, taken in their sorted order
/// so that two committers never wait for each other in a cycle; released when dropped. A
/// directory that cannot be locked (a file system without locks) is skipped.
fn lock_all(dirs: &[PathBuf]) -> Vec<fs::File> {
    dirs.iter()
        .filter_map(|d| {
            let f = fs::File::open(d).ok()?;
            f.lock().ok()?;
            Some(f)
        })
        .collect()
}

/// The record of one commit (see [`journal`](self#journal)).
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Journal {
    pid: u32,
    /// Every destination directory; each holds a copy of the journal.
    dirs: Vec<PathBuf>,
    /// (temporary file, destination), in commit order.
    moves: Vec<(PathBuf, PathBuf)>,
}

const JOURNAL_PREFIX: &str = ".jointfit-commit.";
const JOURNAL_SUFFIX: &str = ".journal";

fn journal_name(pid: u32) -> String {
    format!("{JOURNAL_PREFIX}{pid}{JOURNAL_SUFFIX}")
}

impl Journal {
    /// Writes a copy into every directory (each through a synced `.part` file and a rename);
    /// `false` if any copy failed (the copies written are removed: the commit then goes on
    /// without a journal, as before journals existed).
    fn write(&self) -> bool {
        let Ok(text) = serde_json::to_vec(self) else {
            return false;
        };
        let name = journal_name(self.pid);
        for d in &self.dirs {
            let part = d.join(format!("{name}.part"));
            let ok = (|| -> io::Result<()> {
                let mut f = fs::File::create(&part)?;
                io::Write::write_all(&mut f, &text)?;
                f.sync_all()?;
                fs::rename(&part, d.join(&name))?;
                crate::atomic::sync_parent(&part);
                Ok(())
            })();
            if ok.is_err() {
                let _ = fs::remove_file(&part);
                self.remove();
                return false;
            }
        }
        true
    }

    /// Removes every copy.
    fn remove(&self) {
        let name = journal_name(self.pid);
        for d in &self.dirs {
            let _ = fs::remove_file(d.join(&name));
            crate::atomic::sync_parent(&d.join(&name));
        }
    }

    /// Whether every directory holds its copy: the commit point was passed.
    fn complete(&self) -> bool {
        let name = journal_name(self.pid);
        self.dirs.iter().all(|d| d.join(&name).is_file())
    }
}

/// Whether process `pid` is gone (not running); `false` when unknown.
#[cfg(unix)]
fn is_gone(pid: u32) -> bool {
    if pid == std::process::id() || pid == 0 || pid > i32::MAX as u32 {
        return false;
    }
    // SAFETY: kill with signal 0 only checks whether the process exists.
    let failed = unsafe { libc::kill(pid as libc::pid_t, 0) } != 0;
    failed && io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
}

#[cfg(not(unix))]
fn is_gone(_pid: u32) -> bool {
    false
}

/// Finishes the commits in `dir` of writers that died in the middle of one (see
/// [`journal`](self#journal)): a commit whose journal is in every one of its directories is
/// completed (its remaining temporary files renamed into place), one whose journal copies
/// were not all written is undone (its temporary files removed). Returns the destinations
/// completed. Best effort, never an error: a directory that cannot be read holds no journal.
pub fn recover(dir: &Path) -> Vec<PathBuf> {
    let mut done = Vec::new();
    let Ok(entries) = fs::read_dir(dir) else {
        return done;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(rest) = name.strip_prefix(JOURNAL_PREFIX) else {
            continue;
        };
        let (pid, part) = match rest.strip_suffix(JOURNAL_SUFFIX) {
            Some(pid) => (pid, false),
            None => match rest.strip_suffix(".journal.part") {
                Some(pid) => (pid, true),
                None => continue,
            },
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        if !is_gone(pid) {
            continue;
        }
        if part {
            let _ = fs::remove_file(e.path());
            continue;
        }
        let Some(journal) = fs::read(e.path())
            .ok()
            .and_then(|b| serde_json::from_slice::<Journal>(&b).ok())
        else {
            let _ = fs::remove_file(e.path());
            continue;
        };
        let _locks = lock_all(&journal.dirs);
        if !e.path().exists() {
            continue; // another process recovered it meanwhile
        }
        let complete = journal.complete();
        for (tmp, dest) in &journal.moves {
            if !tmp.exists() {
                continue;
            }
            if complete && fs::rename(tmp, dest).is_ok() {
                done.push(dest.clone());
            } else {
                let _ = fs::remove_file(tmp);
            }
        }
        for d in &journal.dirs {
            crate::atomic::sync_parent(&d.join("x"));
        }
        journal.remove();
    }
    done
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
    recover(dir);
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

    /// A writer killed in the middle of its commit: with its journal in every directory, the
    /// next look at either directory completes the commit; with a journal copy missing (killed
    /// while writing the journals, before any rename), it is undone. Either way no old file
    /// sits beside a new one and no temporary file or journal is left.
    #[test]
    fn an_interrupted_commit_is_completed_or_undone() {
        let root = tempfile::tempdir().unwrap();
        let (d1, d2) = (root.path().join("one"), root.path().join("two"));
        for complete in [true, false] {
            for d in [&d1, &d2] {
                let _ = fs::remove_dir_all(d);
                fs::create_dir_all(d).unwrap();
            }
            let (a, b) = (d1.join("a.mot"), d2.join("b.csv"));
            fs::write(&a, b"old a").unwrap();
            fs::write(&b, b"old b").unwrap();
            let dead = 2_147_483_600;
            let (ta, tb) = (
                d1.join(format!(".a.mot.{dead}.0.tmp")),
                d2.join(format!(".b.csv.{dead}.1.tmp")),
            );
            fs::write(&ta, b"new a").unwrap();
            fs::write(&tb, b"new b").unwrap();
            let journal = Journal {
                pid: dead,
                dirs: vec![d1.clone(), d2.clone()],
                moves: vec![(ta.clone(), a.clone()), (tb.clone(), b.clone())],
            };
            let text = serde_json::to_vec(&journal).unwrap();
            fs::write(d1.join(journal_name(dead)), &text).unwrap();
            if complete {
                fs::write(d2.join(journal_name(dead)), &text).unwrap();
                fs::rename(&ta, &a).unwrap(); // the first rename happened
            }
            let done = recover(&d2);
            let want: &[&[u8]] = if complete {
                assert_eq!(done, vec![b.clone()]);
                &[b"new a", b"new b"]
            } else {
                assert_eq!(recover(&d1), Vec::<PathBuf>::new());
                &[b"old a", b"old b"]
            };
            assert_eq!(fs::read(&a).unwrap(), want[0]);
            assert_eq!(fs::read(&b).unwrap(), want[1]);
            assert_eq!(entries(&d1), vec!["a.mot"], "complete: {complete}");
            assert_eq!(entries(&d2), vec!["b.csv"], "complete: {complete}");
        }
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
