//! The fast path of a TRC data row: one pass over the bytes that parses the frame number, the
//! time and the selected markers' coordinates and steps over the other markers' cells.
//!
//! It handles the rows nearly every file is made of: an integer frame number, then cells that
//! are plain decimals (`[sign] digits [. digits]`, blank-padded) or, for a missing marker,
//! three blank cells, and nothing but blanks after the last marker. Anything else (exponent
//! notation, `NaN`, long mantissas, a partial or `0 0 0` sample, a short row, a stray value
//! after the last marker, a bad cell) makes it give up on the row, which the general path of
//! `rows.rs` then reads with its checks and messages. The values are those of the general
//! path bit for bit: the same exact `m / 10^k` division ([`crate::text::plain_decimal`]'s
//! Clinger fast path), then the same multiplication by the unit's scale.

use nalgebra::Vector3;

use crate::text::POW10;

/// What the fast path read from one row (its coordinates are appended to the caller's vector).
pub(super) struct FastRow {
    pub(super) frame: i64,
    pub(super) time: f64,
    /// Decimals of the time as printed (see `rows::resolution`).
    pub(super) time_decimals: i32,
}

/// One cell: a value, blank, or something only the general path reads.
enum Cell {
    Value(f64),
    Blank,
}

/// A cursor over one row's bytes.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    /// Whether the cell just read was followed by a tab (another cell follows).
    more: bool,
}

impl Cursor<'_> {
    /// Skips blanks (spaces only; other white space goes to the general path).
    #[inline]
    fn blanks(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos] == b' ' {
            self.pos += 1;
        }
    }

    /// Ends a cell: trailing blanks, then the end of the row or a tab. `None` if anything else.
    #[inline]
    fn end_cell(&mut self) -> Option<()> {
        self.blanks();
        if self.pos == self.b.len() {
            self.more = false;
            Some(())
        } else if self.b[self.pos] == b'\t' {
            self.pos += 1;
            self.more = true;
            Some(())
        } else {
            None
        }
    }

    /// A plain decimal or blank cell, with its count of decimals.
    #[inline]
    fn cell(&mut self) -> Option<(Cell, i32)> {
        self.blanks();
        let b = self.b;
        let mut i = self.pos;
        let sign = b.get(i).copied().filter(|s| matches!(s, b'-' | b'+'));
        let neg = sign == Some(b'-');
        i += usize::from(sign.is_some());
        let mut m: u64 = 0;
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add(u64::from(b[i] - b'0'));
            i += 1;
        }
        let mut digits = i - start;
        let mut after = 0;
        let point = i < b.len() && b[i] == b'.';
        if point {
            i += 1;
            let frac = i;
            while i < b.len() && b[i].is_ascii_digit() {
                m = m.wrapping_mul(10).wrapping_add(u64::from(b[i] - b'0'));
                i += 1;
            }
            after = i - frac;
            digits += after;
        }
        self.pos = i;
        if digits == 0 {
            // A sign or a point alone is not a number; an empty cell is blank.
            if point || sign.is_some() {
                return None;
            }
            self.end_cell()?;
            return Some((Cell::Blank, 0));
        }
        // Up to 19 digits cannot overflow; the value must be below 2⁵³ (then every partial
        // value was too) and the point at most 22 digits from the end: `plain_decimal`'s
        // conditions for an exact division.
        if digits > 19 || m >= 1 << 53 || after >= POW10.len() {
            return None;
        }
        self.end_cell()?;
        let v = m as f64 / POW10[after];
        Some((Cell::Value(if neg { -v } else { v }), after as i32))
    }

    /// Steps over `n ≥ 1` cells, whatever they hold; `None` if the row ends before the last.
    /// Tabs are counted eight bytes at a time (a word's zero bytes after XOR with tabs: the
    /// exact test of Hacker's Delight §6-1), then byte by byte in the word holding the n-th.
    #[inline]
    fn skip(&mut self, n: usize) -> Option<()> {
        const TABS: u64 = 0x0909_0909_0909_0909;
        const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
        let rest = &self.b[self.pos..];
        let mut tabs = 0;
        let mut i = 0;
        while let Some(word) = rest.get(i..i + 8) {
            let x = u64::from_le_bytes(word.try_into().unwrap_or([0; 8])) ^ TABS;
            let found = (!(((x & LOW7) + LOW7) | x | LOW7)).count_ones() as usize;
            if tabs + found >= n {
                break;
            }
            tabs += found;
            i += 8;
        }
        for (k, &c) in rest[i..].iter().enumerate() {
            if c == b'\t' {
                tabs += 1;
                if tabs == n {
                    self.pos += i + k + 1;
                    self.more = true;
                    return Some(());
                }
            }
        }
        // The row ends inside the last cell: fine if it is the n-th.
        self.pos = self.b.len();
        self.more = false;
        (tabs + 1 == n).then_some(())
    }
}

/// Runs of consecutive markers that are all kept or all stepped over: (kept, markers).
pub(super) fn runs(keep: &[bool]) -> Vec<(bool, usize)> {
    let mut out: Vec<(bool, usize)> = Vec::new();
    for &k in keep {
        match out.last_mut() {
            Some((last, n)) if *last == k => *n += 1,
            _ => out.push((k, 1)),
        }
    }
    out
}

/// Reads `line` (2 cells, then 3 per marker of `runs`) if it is an ordinary row: appends one
/// position per kept marker (metres: the file's value times `scale`, NaN for a missing marker) to `out` and
/// returns the frame and time. `None` (with `out` possibly extended: the caller truncates) when
/// the general path must read the row.
pub(super) fn row(
    line: &str,
    runs: &[(bool, usize)],
    scale: f64,
    out: &mut Vec<Vector3<f64>>,
) -> Option<FastRow> {
    let mut c = Cursor {
        b: line.as_bytes(),
        pos: 0,
        more: false,
    };
    let frame = match c.cell()? {
        // An integer below 2⁵³ with no point: exactly the general path's integer.
        (Cell::Value(v), 0) => v as i64,
        _ => return None,
    };
    if !c.more {
        return None;
    }
    let (time, time_decimals) = match c.cell()? {
        (Cell::Value(v), d) => (v, d),
        _ => return None,
    };
    for &(k, markers) in runs {
        if !c.more {
            return None;
        }
        if !k {
            c.skip(3 * markers)?;
            continue;
        }
        for _ in 0..markers {
            if !c.more {
                return None;
            }
            let mut xyz = [0.0; 3];
            let mut blank = 0;
            for (j, v) in xyz.iter_mut().enumerate() {
                if j > 0 && !c.more {
                    return None;
                }
                match c.cell()?.0 {
                    Cell::Value(x) => *v = x * scale,
                    Cell::Blank => blank += 1,
                }
            }
            match blank {
                0 if xyz != [0.0; 3] => out.push(Vector3::from(xyz)),
                3 => out.push(Vector3::repeat(f64::NAN)),
                // Partial and all-zero samples are counted in notes by the general path.
                _ => return None,
            }
        }
    }
    // Only blanks and tabs may follow the last marker.
    if c.more && c.b[c.pos..].iter().any(|&x| x != b' ' && x != b'\t') {
        return None;
    }
    Some(FastRow {
        frame,
        time,
        time_decimals,
    })
}
