//! Temporary directories for tests, removed when dropped, also when the test panics (the
//! directory is dropped while the panic unwinds). Set `JOINTFIT_KEEP_SCRATCH=1` to keep them
//! for a look after a failure; their paths are then printed.

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A fresh, empty directory under the system temporary directory, named
/// `jointfit-TAG-XXXXXX` (unique per call, so parallel tests never share one).
/// Dereferences to its [`Path`].
#[derive(Debug)]
pub struct ScratchDir {
    dir: Option<tempfile::TempDir>,
    path: PathBuf,
}

/// A new [`ScratchDir`] whose name starts with `jointfit-TAG-`.
///
/// # Panics
/// When the directory cannot be created.
pub fn scratch(tag: &str) -> ScratchDir {
    let dir = tempfile::Builder::new()
        .prefix(&format!("jointfit-{tag}-"))
        .tempdir()
        .unwrap_or_else(|e| panic!("cannot create a scratch directory: {e}"));
    let path = dir.path().to_path_buf();
    ScratchDir {
        dir: Some(dir),
        path,
    }
}

impl ScratchDir {
    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if std::env::var_os("JOINTFIT_KEEP_SCRATCH").is_some_and(|v| !v.is_empty() && v != "0") {
            if let Some(dir) = self.dir.take() {
                eprintln!("kept scratch directory {}", dir.keep().display());
            }
        }
        // Otherwise `TempDir` removes the directory and everything in it.
    }
}

/// The names of the entries of `dir` (not recursive), sorted: what a test compares to tell
/// that a run left no temporary or partial file.
///
/// # Panics
/// When the directory cannot be read.
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Every entry under `root`, recursively, with its bytes, sorted by path relative to
/// `root`: directories end in `/` and symlinks in `@` (both with no bytes). Two snapshots
/// are equal exactly when no file was added, removed or changed.
///
/// # Panics
/// When a directory or file cannot be read.
pub fn snapshot(root: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let e = e.unwrap();
            let path = e.path();
            let rel = path.strip_prefix(root).unwrap().display().to_string();
            let ft = e.file_type().unwrap();
            if ft.is_dir() {
                out.push((format!("{rel}/"), Vec::new()));
                walk(root, &path, out);
            } else if ft.is_symlink() {
                out.push((format!("{rel}@"), Vec::new()));
            } else {
                out.push((rel, std::fs::read(&path).unwrap()));
            }
        }
    }
    let mut out = Vec::new();
    walk(root, root, &mut out);
    out.sort();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removed_on_drop_and_after_a_panic() {
        let d = scratch("selftest");
        let p = d.to_path_buf();
        std::fs::write(d.join("a.txt"), "x").unwrap();
        assert!(p.join("a.txt").exists());
        assert!(p
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("jointfit-selftest-"));
        drop(d);
        assert!(!p.exists());

        let (tx, rx) = std::sync::mpsc::channel();
        let r = std::thread::spawn(move || {
            let d = scratch("selftest-panic");
            tx.send(d.to_path_buf()).unwrap();
            std::fs::write(d.join("b.txt"), "y").unwrap();
            panic!("a failing test");
        })
        .join();
        assert!(r.is_err());
        let p = rx.recv().unwrap();
        assert!(!p.exists(), "{} survived the panic", p.display());
    }

    #[test]
    fn entries_and_snapshots_list_what_is_there() {
        let d = scratch("list");
        std::fs::create_dir(d.join("sub")).unwrap();
        std::fs::write(d.join("sub/b.txt"), "b").unwrap();
        std::fs::write(d.join("a.txt"), "a").unwrap();
        assert_eq!(entries(&d), ["a.txt", "sub"]);
        let names: Vec<String> = snapshot(&d).into_iter().map(|(n, _)| n).collect();
        assert_eq!(names, ["a.txt", "sub/", "sub/b.txt"]);
        assert_eq!(snapshot(&d)[2].1, b"b");
    }

    #[test]
    fn two_scratch_directories_differ() {
        let (a, b) = (scratch("same"), scratch("same"));
        assert_ne!(a.path(), b.path());
    }
}
