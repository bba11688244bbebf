//! The data rows of a TRC text cut into blocks of whole lines without splitting the whole
//! text first: the header's five lines are taken one by one, the rest is cut at the first
//! line end after every [`BLOCK_BYTES`] bytes. Each block's lines are numbered from 0 while
//! it is parsed (in parallel, `rows.rs`); the join adds the lines of the blocks before it.
//! The lines are those of `text::numbered_lines` (LF, CRLF or, in a text without LF, bare
//! CR; a final line end starts no empty line), and the blocks depend on the text alone,
//! never on the number of threads.

use super::TrcErrorKind;

/// Bytes per block (at least; a block ends at a line end): about 600 rows of 51 markers,
/// a few thousand rows of a few markers.
pub(super) const BLOCK_BYTES: usize = 1 << 20;

/// The line separator of `text`: LF when it has one (CRLF lines lose their CR), else CR.
pub(super) fn separator(text: &str) -> u8 {
    if text.as_bytes().contains(&b'\n') {
        b'\n'
    } else {
        b'\r'
    }
}

/// The first `n` lines of `text` (numbered from 1; fewer when the text has fewer) and the
/// rest of the text after them.
pub(super) fn head(text: &str, sep: u8, n: usize) -> (Vec<(usize, &str)>, &str) {
    let mut out = Vec::with_capacity(n);
    let mut rest = text;
    while out.len() < n && !rest.is_empty() {
        let (line, after) = match rest.as_bytes().iter().position(|&b| b == sep) {
            // The separator is ASCII, so both sides are character boundaries.
            Some(i) => (&rest[..i], &rest[i + 1..]),
            None => (rest, ""),
        };
        out.push((out.len() + 1, strip_cr(line)));
        rest = after;
    }
    (out, rest)
}

fn strip_cr(line: &str) -> &str {
    line.strip_suffix('\r').unwrap_or(line)
}

/// A block of whole lines (each but the last of the text ends with its line end).
#[derive(Clone, Copy)]
pub(super) struct Block<'a> {
    pub(super) text: &'a str,
    sep: u8,
}

impl<'a> Block<'a> {
    /// A block of `text`'s whole lines, separated by `sep`.
    pub(super) fn new(text: &'a str, sep: u8) -> Self {
        Block { text, sep }
    }

    /// The block's lines, numbered from 0.
    pub(super) fn lines(&self) -> impl Iterator<Item = (usize, &'a str)> + 'a {
        // A block ends with a separator unless it ends the text; the piece after a final
        // separator is no line.
        let sep = char::from(self.sep);
        let body = self.text.strip_suffix(sep).unwrap_or(self.text);
        (!self.text.is_empty())
            .then(|| body.split(sep))
            .into_iter()
            .flatten()
            .map(strip_cr)
            .enumerate()
    }
}

/// `text` cut into blocks of whole lines of at least `block_bytes` bytes (the last may be
/// shorter).
pub(super) fn blocks(text: &str, sep: u8, block_bytes: usize) -> Vec<Block<'_>> {
    let bytes = text.as_bytes();
    let mut cuts = vec![0];
    let mut at: usize = 0;
    while at.saturating_add(block_bytes) < bytes.len() {
        match bytes[at + block_bytes..].iter().position(|&b| b == sep) {
            Some(i) => {
                at += block_bytes + i + 1;
                if at < bytes.len() {
                    cuts.push(at);
                }
            }
            None => break,
        }
    }
    cuts.push(bytes.len());
    cuts.windows(2)
        .map(|w| Block {
            text: &text[w[0]..w[1]],
            sep,
        })
        .collect()
}

/// A data row's error with its line number moved by `by` (from a block's numbering to the
/// file's).
pub(super) fn shift_error(e: TrcErrorKind, by: usize) -> TrcErrorKind {
    use TrcErrorKind::*;
    match e {
        BadFrameNumber { line, value } => BadFrameNumber {
            line: line + by,
            value,
        },
        FrameNumberJump {
            line,
            previous,
            found,
        } => FrameNumberJump {
            line: line + by,
            previous,
            found,
        },
        BadTime { line, value } => BadTime {
            line: line + by,
            value,
        },
        TooFewValues {
            line,
            marker,
            expected,
            found,
        } => TooFewValues {
            line: line + by,
            marker,
            expected,
            found,
        },
        ExtraValues {
            line,
            column,
            value,
            last_marker,
        } => ExtraValues {
            line: line + by,
            column,
            value,
            last_marker,
        },
        BadNumber {
            line,
            column,
            marker,
            value,
        } => BadNumber {
            line: line + by,
            column,
            marker,
            value,
        },
        // The row parser reports no other error.
        other => other,
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::read::parse_in_blocks;
    use super::*;
    use crate::text::numbered_lines;

    /// Header and blocks give the lines and numbers of `numbered_lines`, for every block size
    /// and line-end style, including blank lines, a missing final line end and a short text.
    #[test]
    fn blocks_number_lines_as_numbered_lines() {
        let texts = [
            "",
            "a",
            "a\n",
            "a\nb",
            "h1\nh2\nh3\nh4\nh5\n1\t2\n\n3\t4\n5\n",
            "h1\r\nh2\r\nh3\r\nh4\r\nh5\r\n1\r\n22\r\n\r\n333\r\n4444",
            "h1\rh2\rh3\rh4\rh5\r1\r22\r\r333\r",
            "h1\nh2\nh3\nh4\nh5\nx\n\n\n",
            "h1\nh2\nh3\nh4\nh5",
            "h1\nh2\nh3\nh4\nh5\n",
        ];
        for text in texts {
            let sep = separator(text);
            for size in [1, 2, 3, 5, 8, 1000] {
                let (h, rest) = head(text, sep, 5);
                let mut got = h.clone();
                let mut before = h.len() + 1;
                for b in blocks(rest, sep, size) {
                    let lines: Vec<(usize, &str)> = b.lines().collect();
                    got.extend(lines.iter().map(|&(i, l)| (before + i, l)));
                    before += lines.len();
                }
                assert_eq!(got, numbered_lines(text), "{text:?} in blocks of {size}");
            }
        }
    }

    /// The parse of one block against blocks of 1 byte (every line its own block) and of a
    /// few kilobytes, on every TRC file of the shared data, all markers and every other one:
    /// the same trial bit for bit, times, header and notes, or the same error.
    #[test]
    fn every_shared_trc_parses_the_same_in_any_blocks() {
        let Some(files) = jointfit_testkit::data_files(&["trc"]) else {
            return;
        };
        assert!(files.len() >= 20, "{files:?}");
        for path in files {
            let bytes = std::fs::read(&path).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            let odd = |l: &str| l.len() % 2 == 1;
            for select in [None, Some(&odd as super::super::Select)] {
                let one = describe(parse_in_blocks(&text, select, usize::MAX));
                for size in [1, 4096] {
                    let got = describe(parse_in_blocks(&text, select, size));
                    assert!(got == one, "{}: blocks of {size}", path.display());
                }
            }
        }
    }

    /// `line` (a data row) made bad at random: a bad number, a jump of the frame number, a
    /// short row, a value after the last marker, or a bad time.
    pub(in crate::trc) fn bad_row(line: &str, rng: &mut impl rand::Rng) -> String {
        let cells: Vec<&str> = line.split('\t').collect();
        match rng.gen_range(0..5) {
            0 => line.replacen('.', "x", 3),
            1 => {
                let frame = (cells[0].trim().parse::<i64>().unwrap() + 3).to_string();
                let mut c = cells.clone();
                c[0] = &frame;
                c.join("\t")
            }
            2 => cells[..cells.len() / 2].join("\t"),
            3 => format!("{line}\t\t7"),
            _ => line.replacen(cells[1], "t", 1),
        }
    }

    /// Bad rows at random places of walking1 (a bad number, a jump of the frame number, a
    /// short row, a value after the last marker, a bad time), several at once: in blocks of
    /// 1 byte, 1 kB and one block the error is the same, the one on the first bad line.
    #[test]
    fn first_error_in_line_order_in_any_blocks() {
        use rand::{Rng, SeedableRng};
        let Some(path) = jointfit_testkit::data_file("opencap_expert1/walking1.trc") else {
            return;
        };
        let text = std::fs::read_to_string(path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for round in 0..40 {
            let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            let mut bad = Vec::new();
            for _ in 0..rng.gen_range(1..4) {
                let i = rng.gen_range(5..lines.len());
                if lines[i].trim().is_empty() {
                    continue;
                }
                edited[i] = bad_row(lines[i], &mut rng);
                bad.push(i + 1);
            }
            let edited = edited.join("\n");
            let one = describe(parse_in_blocks(&edited, None, usize::MAX));
            assert!(one.starts_with("Err"), "round {round}: {bad:?}");
            let first = *bad.iter().min().unwrap();
            // The message names the first bad line (or, for a jump, the line after it when
            // the jump is the next row's frame number against this one's).
            assert!(
                one.contains(&format!("line: {first},"))
                    || one.contains(&format!("line: {},", first + 1)),
                "round {round}: bad lines {bad:?}: {one}"
            );
            for size in [1, 1024] {
                let got = describe(parse_in_blocks(&edited, None, size));
                assert_eq!(got, one, "round {round}: blocks of {size}");
            }
        }
    }

    /// A parse result as text: positions as bits, the rest as `Debug`.
    pub(in crate::trc) fn describe(
        r: Result<crate::trc::TrcFile, crate::trc::TrcErrorKind>,
    ) -> String {
        match r {
            Ok(f) => {
                let bits: Vec<u64> = f
                    .trial
                    .positions()
                    .iter()
                    .flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                    .collect();
                format!(
                    "Ok {bits:?} {:?} {:?} {:?} {:?} {:?}",
                    f.trial.labels(),
                    f.trial.times(),
                    f.times.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
                    f.header,
                    f.notes
                )
            }
            Err(e) => format!("Err {e:?}"),
        }
    }
}
