//! A digest of file contents and a settings string: two runs get the same digest exactly when
//! every file holds the same bytes and the settings read the same, whatever the files'
//! names, paths or modification times. Format-free (the files are hashed as bytes); SHA-256
//! (FIPS 180-4) through the `sha2` crate.

use std::io::Read;
use std::path::Path;

use sha2::{Digest, Sha256};

/// The hex SHA-256 of: for each file in order, its length and bytes; then `settings`. Each
/// part is length-prefixed, so no two different inputs share their concatenation.
pub fn hash_files_and(files: &[&Path], settings: &str) -> std::io::Result<String> {
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    for p in files {
        let mut f = std::fs::File::open(p)
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", p.display())))?;
        let len = f.metadata()?.len();
        h.update(b"file");
        h.update(len.to_le_bytes());
        loop {
            let n = f.read(&mut buf)?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
        }
    }
    h.update(b"settings");
    h.update((settings.len() as u64).to_le_bytes());
    h.update(settings.as_bytes());
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The digest of known input against SHA-256's published test vector (FIPS 180-2,
    /// "abc"), through the same hasher; then: content, not names or times, decides.
    #[test]
    fn content_decides_not_names_or_times() {
        let abc: String = Sha256::digest(b"abc")
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(
            abc,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.trc"), dir.path().join("b.trc"));
        std::fs::write(&a, b"one").unwrap();
        std::fs::write(&b, b"one").unwrap();
        let ha = hash_files_and(&[&a], "s").unwrap();
        assert_eq!(
            ha,
            hash_files_and(&[&b], "s").unwrap(),
            "same bytes, other name"
        );
        assert_ne!(ha, hash_files_and(&[&a], "t").unwrap(), "other settings");
        let t = std::fs::metadata(&a).unwrap().modified().unwrap();
        std::fs::write(&a, b"two").unwrap();
        std::fs::File::options()
            .write(true)
            .open(&a)
            .unwrap()
            .set_modified(t)
            .unwrap();
        assert_ne!(ha, hash_files_and(&[&a], "s").unwrap(), "edited, same time");
        // Length prefixes: ["ab", "c"] is not ["a", "bc"].
        let (c, d) = (dir.path().join("c"), dir.path().join("d"));
        std::fs::write(&a, b"ab").unwrap();
        std::fs::write(&b, b"c").unwrap();
        std::fs::write(&c, b"a").unwrap();
        std::fs::write(&d, b"bc").unwrap();
        assert_ne!(
            hash_files_and(&[&a, &b], "").unwrap(),
            hash_files_and(&[&c, &d], "").unwrap()
        );
    }
}
