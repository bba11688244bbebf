//! Tests of `rows.rs`: the chunked parse against the standard one, errors in line order.

use crate::trc::blocks::{blocks, head, separator, BLOCK_BYTES};
use crate::trc::{parse_trc, TrcErrorKind};

/// A TRC text of `frames` rows of two markers (mm), values from a simple formula with
/// up to 17 significant digits, and the values as printed.
fn text(frames: usize) -> (String, Vec<String>) {
    let mut out = format!(
        "PathFileType\t4\t(X/Y/Z)\tt.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\t\
         Units\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         100\t100\t{frames}\t2\tmm\t100\t1\t{frames}\nFrame#\tTime\tA\t\t\tB\t\t\n\
         \t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
    );
    let mut cells = Vec::new();
    for f in 0..frames {
        out.push_str(&format!("{}\t{}", f + 1, f as f64 / 100.0));
        for k in 0..6 {
            let v = ((f * 6 + k) as f64 * 0.7310585786300049).sin() * 1234.5;
            let s = if k % 2 == 0 {
                format!("{v}")
            } else {
                format!("{v:.5}")
            };
            out.push('\t');
            out.push_str(&s);
            cells.push(s);
        }
        out.push('\n');
    }
    (out, cells)
}

/// Rows enough for three blocks and a part (about 80 bytes a row).
const FRAMES: usize = 3 * BLOCK_BYTES / 80 + 17;

/// The data line numbers at which the blocks of `text` start.
fn block_starts(text: &str) -> Vec<usize> {
    let sep = separator(text);
    let (_, rest) = head(text, sep, 5);
    let mut line = 6;
    blocks(rest, sep, BLOCK_BYTES)
        .iter()
        .map(|b| {
            let first = line;
            line += b.lines().count();
            first
        })
        .collect()
}

/// Blocks joined in order: every value has the bits of the standard parser's reading
/// (scaled to metres as one multiplication), over several blocks.
#[test]
fn chunked_rows_equal_the_standard_parse() {
    let frames = FRAMES;
    let (t, cells) = text(frames);
    assert!(block_starts(&t).len() >= 4);
    let trial = parse_trc(&t, "t.trc").unwrap();
    assert_eq!(trial.n_frames(), frames);
    let got: Vec<f64> = trial
        .positions()
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    for (g, c) in got.iter().zip(&cells) {
        assert_eq!(
            g.to_bits(),
            (c.parse::<f64>().unwrap() * 1e-3).to_bits(),
            "{c}"
        );
    }
}

/// Errors come in line order whichever block holds them: a frame-number jump at the first
/// row of a block is found before a bad number in a later block.
#[test]
fn first_error_in_line_order_across_chunks() {
    let frames = FRAMES;
    let (t, _) = text(frames);
    let starts = block_starts(&t);
    let mut lines: Vec<String> = t.lines().map(str::to_string).collect();
    // Data rows start at line 6 (index 5); row i of the data is line 6 + i.
    let jump_row = starts[1] - 6; // first row of the second block
    lines[5 + jump_row] = lines[5 + jump_row].replacen(
        &format!("{}\t", jump_row + 1),
        &format!("{}\t", jump_row + 5),
        1,
    );
    let bad_row = starts[2] - 6 + 3;
    lines[5 + bad_row] = lines[5 + bad_row].replacen("\t", "\tx", 2);
    let err = parse_trc(&lines.join("\n"), "t.trc").unwrap_err();
    match err.kind {
        TrcErrorKind::FrameNumberJump {
            line,
            previous,
            found,
        } => {
            assert_eq!(line, 6 + jump_row);
            assert_eq!((previous, found), (jump_row as i64, jump_row as i64 + 5));
        }
        other => panic!("{other:?}"),
    }
}
