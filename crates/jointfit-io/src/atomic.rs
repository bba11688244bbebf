//! Atomic file output: a reader never sees a half-written file.
//!
//! [`write_atomic`] writes the bytes to a fresh temporary file in the destination's own
//! directory (so that the final rename never crosses a file system), flushes it to disk, and
//! renames it over the destination. If anything fails before the rename, the temporary file
//! is removed and the destination is left as it was.
//!
//! A destination that exists keeps its permissions (and, for a privileged process, its owner
//! and group); a read-only destination is refused, not replaced.
//!
//! The temporary file is registered for removal by a signal handler, and inside an open
//! [`Batch`](crate::staging::Batch) its rename waits for the batch's commit (see
//! [`crate::staging`]).

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::staging;

/// Distinguishes temporary files of concurrent writers within one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: temporary file beside it, fsync, rename.
///
/// On success the destination holds exactly `bytes` (replacing any previous file). On
/// failure the destination is untouched and no temporary file is left behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |file| file.write_all(bytes))
}

/// Like [`write_atomic`], with the bytes written by `write` (for a text made of parts that
/// need not be joined first); the file is synced, renamed or removed as there.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} does not name a file", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let base = file_name.to_string_lossy();
    // A file being replaced keeps its permissions; a read-only one is not replaced.
    let existing = fs::metadata(path).ok().filter(|m| m.is_file());
    if let Some(md) = &existing {
        if md.permissions().readonly() {
            return Err(io::Error::new(
                io::ErrorKind::PermissionDenied,
                format!("{} is read-only; refusing to replace it", path.display()),
            ));
        }
    }
    staging::sweep_stale(&dir, &base);
    let (tmp_path, mut file) = create_temp(&dir, &base)?;
    if let Some(md) = &existing {
        keep_attributes(&file, md);
    }
    let slot = staging::register(&tmp_path);
    let result = (|| {
        write(&mut file)?;
        file.sync_all()?;
        drop(file);
        if staging::defer(&tmp_path, path, slot) {
            return Ok(false);
        }
        fs::rename(&tmp_path, path).map(|()| true)
    })();
    match result {
        Ok(false) => Ok(()),
        Ok(true) => {
            staging::unregister(slot);
            sync_dir(&dir);
            Ok(())
        }
        Err(e) => {
            // The temporary file may or may not exist at this point; either way it must go.
            let _ = fs::remove_file(&tmp_path);
            staging::unregister(slot);
            Err(e)
        }
    }
}

/// Gives the temporary file `file` the permissions (and, where allowed, the owner and
/// group) of the file `md` it will replace. Best effort for the owner: only a privileged
/// process may give a file away.
fn keep_attributes(file: &File, md: &fs::Metadata) {
    let _ = file.set_permissions(md.permissions());
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let _ = std::os::unix::fs::fchown(file, Some(md.uid()), Some(md.gid()));
    }
}

/// Makes a rename into `path`'s directory durable (best effort).
pub(crate) fn sync_parent(path: &Path) {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => sync_dir(d),
        _ => sync_dir(Path::new(".")),
    }
}

/// Creates a new, previously non-existent temporary file in `dir`.
fn create_temp(dir: &Path, base: &str) -> io::Result<(PathBuf, File)> {
    let pid = std::process::id();
    let mut last_err = None;
    for _ in 0..100 {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let candidate = dir.join(format!(".{base}.{pid}.{n}.tmp"));
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&candidate)
        {
            Ok(f) => return Ok((candidate, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_err = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last_err.unwrap_or_else(|| io::Error::other("could not create a temporary file")))
}

/// Makes the rename durable where the platform allows it (best effort: a failure here does
/// not undo a write that has already replaced the destination).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    use jointfit_testkit::entries;

    #[test]
    fn writes_and_replaces_without_leftovers() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.txt");
        write_atomic(&p, b"first").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"first");
        write_atomic(&p, b"second, longer").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second, longer");
        assert_eq!(entries(dir.path()), vec!["out.txt".to_string()]);
    }

    #[test]
    fn failure_leaves_destination_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        // The destination is a non-empty directory: the rename must fail.
        let p = dir.path().join("target");
        fs::create_dir(&p).unwrap();
        fs::write(p.join("keep"), b"x").unwrap();
        assert!(write_atomic(&p, b"data").is_err());
        assert!(p.is_dir());
        assert_eq!(entries(dir.path()), vec!["target".to_string()]);
    }

    #[cfg(unix)]
    #[test]
    fn a_replaced_file_keeps_its_permissions_and_read_only_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("private.toml");
        write_atomic(&p, b"first").unwrap();
        fs::set_permissions(&p, fs::Permissions::from_mode(0o600)).unwrap();
        write_atomic(&p, b"second").unwrap();
        let mode = fs::metadata(&p).unwrap().permissions().mode() & 0o7777;
        assert_eq!(mode, 0o600);
        fs::set_permissions(&p, fs::Permissions::from_mode(0o440)).unwrap();
        let err = write_atomic(&p, b"third").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::PermissionDenied, "{err}");
        assert_eq!(fs::read(&p).unwrap(), b"second");
        assert_eq!(entries(dir.path()), vec!["private.toml".to_string()]);
    }

    #[test]
    fn missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/out.txt");
        assert!(write_atomic(&p, b"x").is_err());
        assert!(write_atomic(Path::new("/"), b"x").is_err());
    }
}
