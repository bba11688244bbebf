//! Size limits on input files: every reader of a model, trial, marker set, setup or subject
//! file reads through [`read_bytes`] / [`read_text`], which refuse a file past its limit
//! before reading it (a regular file, by its size) or as soon as the limit is passed (a
//! device, pipe or growing file: `/dev/zero` as a model is refused after [`DOCUMENT_BYTES`],
//! not read until memory runs out).
//!
//! The limits are far above any real file: OpenSim full-body models with muscles are a few
//! MB; an hour of 200 Hz capture of 100 markers is about 1 GB of TRC text.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Largest model (`.toml`, `.osim`), setup, marker set or subject (`.vsk`) file read: 256 MiB.
pub const DOCUMENT_BYTES: u64 = 256 << 20;

/// Largest motion file (`.trc`, `.c3d`) read: 1 GiB.
pub const TRIAL_BYTES: u64 = 1 << 30;

/// The error for a file past `limit` (`size`: its size when known).
fn too_large(what: &str, size: Option<u64>, limit: u64) -> io::Error {
    let size = match size {
        Some(s) => format!("{} MiB", s.div_ceil(1 << 20)),
        None => format!("more than {} MiB", limit >> 20),
    };
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "the file is {size}, past the {} MiB limit for a {what} file",
            limit >> 20
        ),
    )
}

/// The bytes of `path`, refused (an [`io::ErrorKind::InvalidData`] error naming the limit)
/// when it holds more than `limit` bytes; `what` names the kind of file in the message.
pub fn read_bytes(path: &Path, limit: u64, what: &str) -> io::Result<Vec<u8>> {
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(what, Some(meta.len()), limit));
    }
    let mut bytes = Vec::with_capacity(if meta.is_file() {
        usize::try_from(meta.len()).unwrap_or(0)
    } else {
        0
    });
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(what, None, limit));
    }
    Ok(bytes)
}

/// [`read_bytes`] as UTF-8 text (an [`io::ErrorKind::InvalidData`] error when it is not).
pub fn read_text(path: &Path, limit: u64, what: &str) -> io::Result<String> {
    String::from_utf8(read_bytes(path, limit, what)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not UTF-8 text"))
}

/// Refuses an open regular file larger than `limit` (see [`read_bytes`]); other files pass.
pub fn check_size(file: &File, limit: u64, what: &str) -> io::Result<()> {
    let meta = file.metadata()?;
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(what, Some(meta.len()), limit));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_past_the_limit_are_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("small");
        std::fs::write(&small, b"0123456789").unwrap();
        assert_eq!(read_bytes(&small, 10, "model").unwrap(), b"0123456789");
        let e = read_bytes(&small, 9, "model").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("limit for a model file"), "{e}");
        // A sparse 3 GiB file: refused by its size, without reading it.
        let big = dir.path().join("big");
        File::create(&big).unwrap().set_len(3 << 30).unwrap();
        let t = std::time::Instant::now();
        let e = read_bytes(&big, TRIAL_BYTES, "motion").unwrap_err();
        assert!(
            e.to_string().contains("3072 MiB") && e.to_string().contains("1024 MiB"),
            "{e}"
        );
        assert!(t.elapsed().as_secs() < 5);
        // An endless device: refused once past the limit.
        let e = read_bytes(Path::new("/dev/zero"), 1 << 20, "setup").unwrap_err();
        assert!(e.to_string().contains("more than 1 MiB"), "{e}");
        let e = read_text(&small, 100, "model").map(|t| t.len()).unwrap();
        assert_eq!(e, 10);
    }
}
