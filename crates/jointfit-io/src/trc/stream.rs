//! A TRC file read block by block, each block by the thread that parses it: the data rows are
//! never all in memory at once, and the copy out of the page cache, the UTF-8 check and the
//! line splitting run on every thread instead of before the parse.
//!
//! The header is read first, up to the end of line 5. The data after it (from byte `d`) is cut
//! on a grid of `block` bytes: block `k` runs from just after the first line end at or after
//! byte `d + k·block` (block 0 from `d`) to just after the first line end at or after
//! `d + (k+1)·block` (or the end of the file). A block holds whole lines, and the cuts depend
//! on the bytes alone, never on the number of threads. The reader of block `k` reads from
//! `d + k·block` into a buffer its thread reuses, and on past the grid to the line end.
//!
//! Everything else is the reading of a text in memory (`read.rs`, `rows.rs`): the same
//! header, rows, notes and errors. What this path does not handle it leaves to that one
//! (`None`): a file of fewer than two blocks, a header without LF line ends (bare CR lines),
//! a header of only blanks, or bytes that are not UTF-8 anywhere (the whole text is then
//! decoded as `text::decode` does).

use std::cell::Cell;
use std::fs::File;
use std::io;

use super::blocks::{head, Block};
use super::read::{finish, parse_head};
use super::rows::{read_rows, BlockSource, Stop};
use super::{Select, TrcErrorKind, TrcFile};

/// Reads the extra bytes past a block's grid end in steps of this many, up to its line end.
const STEP: usize = 64 * 1024;

/// Header lines longer than this (all five together) leave the file to the in-memory path.
const MAX_HEADER: usize = 16 << 20;

thread_local! {
    /// Each thread's block buffer, reused from block to block (no page faults after the
    /// first block).
    static BUFFER: Cell<Vec<u8>> = const { Cell::new(Vec::new()) };
}

/// Reads the open TRC `file` of `len` bytes in blocks of `block` bytes; `None` when the
/// in-memory path must read it (see the module docs).
pub(super) fn read(
    file: &File,
    len: u64,
    select: Option<Select>,
    block: usize,
) -> Option<Result<TrcFile, TrcErrorKind>> {
    let block = block.max(1);
    let len = usize::try_from(len).ok()?;
    if len / 2 < block {
        return None;
    }
    let (header, d) = match read_header(file, len) {
        Ok(Some(found)) => found,
        Ok(None) => return None,
        Err(e) => return Some(Err(TrcErrorKind::Io(e))),
    };
    let text = header.strip_prefix('\u{feff}').unwrap_or(&header);
    if text.trim().is_empty() {
        return None;
    }
    let (lines, rest) = head(text, b'\n', 5);
    debug_assert!(rest.is_empty());
    let head = match parse_head(&lines, select) {
        Ok(h) => h,
        Err(e) => return Some(Err(e)),
    };
    let source = FileBlocks {
        file,
        len,
        d,
        block,
    };
    match read_rows(&source, 6, &head.labels, &head.keep, head.scale) {
        Ok(rows) => Some(finish(head, rows)),
        Err(Stop::Error(e)) => Some(Err(e)),
        Err(Stop::NotUtf8) => None,
    }
}

/// The text up to the end of line 5 and its length in bytes; `None` if the file has fewer
/// than five LF line ends in its first [`MAX_HEADER`] bytes or they are not UTF-8.
fn read_header(file: &File, len: usize) -> io::Result<Option<(String, usize)>> {
    let mut buf = Vec::new();
    let mut want = STEP.min(len);
    loop {
        let from = buf.len();
        buf.resize(want, 0);
        read_exact_at(file, &mut buf[from..], from)?;
        let mut ends = 0;
        if let Some(end) = buf.iter().position(|&b| {
            ends += usize::from(b == b'\n');
            ends == 5
        }) {
            buf.truncate(end + 1);
            let d = buf.len();
            return Ok(String::from_utf8(buf).ok().map(|h| (h, d)));
        }
        if want == len || want >= MAX_HEADER {
            return Ok(None);
        }
        want = (2 * want).min(len);
    }
}

/// The data rows of a file, on the grid of the module docs.
struct FileBlocks<'f> {
    file: &'f File,
    len: usize,
    /// Where the data rows start.
    d: usize,
    block: usize,
}

impl BlockSource for FileBlocks<'_> {
    fn count(&self) -> usize {
        (self.len - self.d).div_ceil(self.block)
    }

    fn with_block<R>(&self, k: usize, f: impl FnOnce(Block<'_>) -> R) -> Result<R, Stop> {
        let mut buf = BUFFER.take();
        let result = self.read_block(k, &mut buf).and_then(|(start, end)| {
            let text = std::str::from_utf8(&buf[start..end]).map_err(|_| Stop::NotUtf8)?;
            Ok(f(Block::new(text, b'\n')))
        });
        BUFFER.set(buf);
        result
    }
}

impl FileBlocks<'_> {
    /// Reads block `k` into `buf` (from its grid start); returns where its lines start and end
    /// in `buf`. `buf` keeps its length from block to block: only what is read is written.
    fn read_block(&self, k: usize, buf: &mut Vec<u8>) -> Result<(usize, usize), Stop> {
        let io = |e| Stop::Error(TrcErrorKind::Io(e));
        let from = self.d + k * self.block;
        let grid_end = (from + self.block).min(self.len);
        let mut have = grid_end - from;
        if buf.len() < have {
            buf.resize(have, 0);
        }
        read_exact_at(self.file, &mut buf[..have], from).map_err(io)?;
        let start = if k == 0 {
            0
        } else {
            match buf[..have].iter().position(|&b| b == b'\n') {
                Some(i) => i + 1,
                // The first line end at or after the grid start is also the first at or
                // after the grid end: the block is empty.
                None => return Ok((0, 0)),
            }
        };
        // The end: just after the first line end at or after the grid end.
        let mut searched = grid_end - from;
        loop {
            if let Some(i) = buf[searched..have].iter().position(|&b| b == b'\n') {
                return Ok((start, searched + i + 1));
            }
            if from + have == self.len {
                return Ok((start, have));
            }
            searched = have;
            let more = STEP.min(self.len - from - have);
            if buf.len() < have + more {
                buf.resize(have + more, 0);
            }
            read_exact_at(self.file, &mut buf[have..have + more], from + have).map_err(io)?;
            have += more;
        }
    }
}

/// Fills `buf` from byte `at` of `file`; a file shorter than that is an error (it changed
/// while it was read).
#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], at: usize) -> io::Result<()> {
    use std::os::unix::fs::FileExt;
    file.read_exact_at(buf, at as u64)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut at: usize) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, at as u64) {
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => {
                buf = &mut buf[n..];
                at += n;
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::blocks::tests::describe;
    use super::super::read::parse_in_blocks;
    use super::super::Select;
    use crate::trc::read_trc_in_blocks;

    /// Every TRC file of the shared data, whole: the path of each test below.
    fn shared_trc_files() -> Vec<std::path::PathBuf> {
        jointfit_testkit::data_files(&["trc"]).unwrap_or_default()
    }

    /// The file read block by block (blocks of `block` bytes), against its text parsed in
    /// memory as one block: the same trial bit for bit, times, header and notes, or the same
    /// error. Returns whether the streamed path read it (rather than leaving it).
    fn same_as_in_memory(path: &std::path::Path, select: Option<Select>, block: usize) -> bool {
        let bytes = std::fs::read(path).unwrap();
        let text =
            String::from_utf8(bytes.clone()).unwrap_or_else(|e| crate::text::decode(e.as_bytes()));
        let want = describe(parse_in_blocks(&text, select, usize::MAX));
        let file = std::fs::File::open(path).unwrap();
        let streamed = super::read(&file, bytes.len() as u64, select, block);
        let used = streamed.is_some();
        if let Some(r) = streamed {
            assert_eq!(describe(r), want, "{}: blocks of {block}", path.display());
        }
        // And through the public entry (which falls back when the stream leaves the file).
        let got = describe(read_trc_in_blocks(path, select, block).map_err(|e| e.kind));
        assert_eq!(got, want, "{}: read in blocks of {block}", path.display());
        used
    }

    /// Every TRC file of the shared data, all markers and every other one, in blocks of 64
    /// and 4096 bytes: what the in-memory parse gives.
    #[test]
    fn every_shared_trc_reads_as_in_memory() {
        let files = shared_trc_files();
        if files.is_empty() {
            return;
        }
        assert!(files.len() >= 20, "{files:?}");
        let odd = |l: &str| l.len() % 2 == 1;
        let mut streamed = 0;
        for path in &files {
            for select in [None, Some(&odd as Select)] {
                for block in [64, 4096] {
                    streamed += usize::from(same_as_in_memory(path, select, block));
                }
            }
        }
        // Most files have LF line ends and are read by the streamed path (small ones in
        // blocks of 64 bytes only).
        assert!(streamed >= files.len(), "{streamed} of {}", files.len() * 4);
    }

    /// walking1 with seeded bad rows (a bad number, a frame-number jump, a short row, a value
    /// after the last marker, a bad time), CRLF line ends, a BOM, a missing final line end,
    /// bytes that are not UTF-8, a blank header: read block by block as in memory.
    #[test]
    fn edited_files_read_as_in_memory() {
        use rand::{Rng, SeedableRng};
        let Some(path) = jointfit_testkit::data_file("opencap_expert1/walking1.trc") else {
            return;
        };
        let text = std::fs::read_to_string(path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("edited.trc");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let mut variants: Vec<Vec<u8>> = vec![
            text.replace('\n', "\r\n").into_bytes(),
            format!("\u{feff}{text}").into_bytes(),
            text.trim_end().as_bytes().to_vec(),
            format!("{text}\n\n\n").into_bytes(),
            format!("\n\n\n\n\n{text}").into_bytes(),
            text.replace('\n', "\r").into_bytes(),
        ];
        let mut latin = text.clone().into_bytes();
        let at = latin.len() * 2 / 3;
        latin[at] = 0xe9;
        variants.push(latin);
        for _ in 0..20 {
            let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            for _ in 0..rng.gen_range(1..4) {
                let i = rng.gen_range(5..lines.len());
                edited[i] = crate::trc::blocks::tests::bad_row(lines[i], &mut rng);
            }
            variants.push(edited.join("\n").into_bytes());
        }
        let first5 = |l: &str| l.starts_with('r');
        for (v, bytes) in variants.iter().enumerate() {
            std::fs::write(&out, bytes).unwrap();
            for select in [None, Some(&first5 as Select)] {
                for block in [50, 1000, 5000] {
                    same_as_in_memory(&out, select, block);
                }
            }
            assert!(v < variants.len());
        }
    }
}
