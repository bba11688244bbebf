//! Writing `.mot`/`.sto` tables (the layout of the parent module's docs).

use std::io::Write;
use std::path::Path;

use super::{StoWriteError, Table};
use crate::atomic::write_atomic_with;
use crate::text::push_shortest;

fn check(table: &Table) -> Result<(), StoWriteError> {
    if table.name.contains(['\n', '\r', '=']) || table.name.trim() != table.name {
        return Err(StoWriteError::BadName(table.name.clone()));
    }
    match table.columns.first() {
        Some(t) if t == "time" => {}
        other => {
            return Err(StoWriteError::NoTimeColumn {
                found: other.cloned(),
            })
        }
    }
    for (i, label) in table.columns.iter().enumerate() {
        let reason = if label.is_empty() {
            Some("empty")
        } else if label.contains(['\t', '\n', '\r']) {
            Some("contains a tab or line break")
        } else if label.trim() != label {
            Some("leading or trailing blanks would be lost")
        } else if table.columns[..i].contains(label) {
            Some("duplicate")
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(StoWriteError::BadLabel {
                column: i + 1,
                label: label.clone(),
                reason,
            });
        }
    }
    for line in &table.extra_header {
        let key = line.split('=').next().unwrap_or("").trim();
        let reserved =
            line.contains('=') && ["version", "nRows", "nColumns", "inDegrees"].contains(&key);
        if line.contains(['\n', '\r'])
            || line.trim().eq_ignore_ascii_case("endheader")
            || reserved
            || line.trim_end() != line
        {
            return Err(StoWriteError::BadHeaderLine(line.clone()));
        }
    }
    let mut previous = f64::NEG_INFINITY;
    for (r, row) in table.rows.iter().enumerate() {
        if row.len() != table.columns.len() {
            return Err(StoWriteError::RowLength {
                row: r,
                expected: table.columns.len(),
                found: row.len(),
            });
        }
        let t = row[0];
        if !t.is_finite() || t <= previous {
            return Err(StoWriteError::BadTime { row: r, time: t });
        }
        previous = t;
        if let Some((c, &v)) = row.iter().enumerate().find(|(_, v)| v.is_infinite()) {
            return Err(StoWriteError::Infinite {
                row: r,
                column: table.columns[c].clone(),
                value: v,
            });
        }
    }
    Ok(())
}

/// The header of a table (up to and including the column labels' line).
fn header(table: &Table) -> String {
    let mut out = String::new();
    if !table.name.is_empty() {
        out.push_str(&table.name);
        out.push('\n');
    }
    out.push_str(&format!(
        "version=1\nnRows={}\nnColumns={}\ninDegrees={}\n",
        table.rows.len(),
        table.columns.len(),
        if table.in_degrees { "yes" } else { "no" }
    ));
    for line in &table.extra_header {
        out.push_str(line);
        out.push('\n');
    }
    out.push_str("endheader\n");
    out.push_str(&table.columns.join("\t"));
    out.push('\n');
    out
}

/// The rows in chunks of [`ROWS_PER_CHUNK`] formatted on every thread, in order (formatting
/// the numbers is most of the writing time).
fn row_chunks(table: &Table) -> Vec<String> {
    use rayon::prelude::*;
    table
        .rows
        .par_chunks(ROWS_PER_CHUNK)
        .map(|rows| {
            let mut text = String::with_capacity(rows.len() * table.columns.len() * 12);
            for row in rows {
                for (i, &v) in row.iter().enumerate() {
                    if i > 0 {
                        text.push('\t');
                    }
                    if v.is_nan() {
                        text.push_str("NaN");
                    } else {
                        push_shortest(&mut text, v);
                    }
                }
                text.push('\n');
            }
            text
        })
        .collect()
}

/// Formats a table in the layout of the module docs.
pub fn format_sto(table: &Table) -> Result<String, StoWriteError> {
    check(table)?;
    let mut out = header(table);
    let chunks = row_chunks(table);
    out.reserve(chunks.iter().map(|c| c.len()).sum());
    for c in &chunks {
        out.push_str(c);
    }
    Ok(out)
}

/// Writes the text of [`format_sto`] to `w`, chunk by chunk: the same bytes without joining
/// them into one string first. `path` names the destination in errors.
pub fn write_sto_to(w: &mut impl Write, table: &Table, path: &Path) -> Result<(), StoWriteError> {
    check(table)?;
    let chunks = row_chunks(table);
    write_parts(w, &header(table), &chunks).map_err(|source| StoWriteError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn write_parts(w: &mut impl Write, header: &str, chunks: &[String]) -> std::io::Result<()> {
    w.write_all(header.as_bytes())?;
    for c in chunks {
        w.write_all(c.as_bytes())?;
    }
    Ok(())
}

/// Rows per chunk that [`format_sto`] formats on one thread.
const ROWS_PER_CHUNK: usize = 4096;

/// Writes a table as a `.mot`/`.sto` file, atomically (see [`write_atomic_with`]): the
/// bytes of [`format_sto`], formatted before the file is created and written chunk by chunk.
pub fn write_sto(path: &Path, table: &Table) -> Result<(), StoWriteError> {
    check(table)?;
    let chunks = row_chunks(table);
    let header = header(table);
    write_atomic_with(path, |file| write_parts(file, &header, &chunks)).map_err(|source| {
        StoWriteError::Io {
            path: path.display().to_string(),
            source,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table of `rows` rows (several chunks) with awkward values: short decimals, long
    /// fractions, NaN, tiny and huge magnitudes.
    fn long_table(rows: usize) -> Table {
        let mut t = Table::new("Coordinates", &["a", "b", "c"], true);
        for r in 0..rows {
            let x = (r as f64 * 0.7310585786300049).sin();
            let gap = if r % 97 == 3 { f64::NAN } else { x * 1e-7 };
            t.rows
                .push(vec![r as f64 / 100.0, x * 57.29577951308232, gap, x * 1e17]);
        }
        t
    }

    /// `write_sto` and `write_sto_to` write the bytes of `format_sto`, on a table of several
    /// chunks and on every storage file of the shared data read back; nothing else is left in
    /// the folder.
    #[test]
    fn written_files_hold_the_formatted_text() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.mot");
        let mut tables = vec![long_table(3 * ROWS_PER_CHUNK + 5), long_table(1)];
        for p in jointfit_testkit::data_files(&["mot", "sto"]).unwrap_or_default() {
            if let Ok(t) = crate::sto::read_sto(&p) {
                tables.push(t);
            }
        }
        let mut written = 0;
        for t in &tables {
            let Ok(text) = format_sto(t) else {
                assert!(write_sto(&out, t).is_err());
                continue;
            };
            write_sto(&out, t).unwrap();
            assert_eq!(std::fs::read(&out).unwrap(), text.as_bytes());
            let mut buf = Vec::new();
            write_sto_to(&mut buf, t, &out).unwrap();
            assert_eq!(buf, text.as_bytes());
            written += 1;
        }
        assert!(written >= 2);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1);
    }
}
