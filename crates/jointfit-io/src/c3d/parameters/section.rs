//! Reading the parameter section's bytes (format and leniency rules in the parent module's
//! documentation): the four-byte head, then group and parameter records followed by their
//! next-record offsets, then the records assembled into [`Parameters`].

use std::collections::BTreeMap;

use super::{decode_text, Group, ParamData, Parameter, Parameters};
use crate::c3d::floats::Processor;

/// Why the parameter section could not be read at all.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum SectionError {
    /// The section's first four bytes lie outside the file.
    Outside { offset: usize },
    /// Byte 4 is not 84, 85 or 86.
    Processor(u8),
}

/// Result of parsing the section.
pub(crate) struct Section {
    pub processor: Processor,
    pub declared_blocks: u8,
    pub parameters: Parameters,
    pub warnings: Vec<String>,
}

enum Record {
    Group {
        id: u8,
        name: String,
        description: String,
    },
    Param {
        group: u8,
        param: Parameter,
    },
}

/// Parses the parameter section starting at byte `start` of `bytes`.
pub(crate) fn parse_section(bytes: &[u8], start: usize) -> Result<Section, SectionError> {
    let head = bytes
        .get(start..start.saturating_add(4))
        .filter(|h| h.len() == 4)
        .ok_or(SectionError::Outside { offset: start })?;
    let declared_blocks = head[2];
    let processor = Processor::from_code(head[3]).ok_or(SectionError::Processor(head[3]))?;
    let declared_end = start + usize::from(declared_blocks) * crate::c3d::header::BLOCK;
    let mut warnings = Vec::new();
    let mut records = Vec::new();
    let mut pos = start + 4;
    let mut overflow_warned = false;
    loop {
        let Some(&[len_byte, id_byte]) = bytes.get(pos..pos + 2) else {
            warnings.push(format!(
                "parameter section: no end record before the end of the file (byte {pos})"
            ));
            break;
        };
        let (name_len, id) = (len_byte as i8, id_byte as i8);
        if name_len == 0 || id == 0 {
            break;
        }
        if pos >= declared_end && !overflow_warned && declared_blocks > 0 {
            warnings.push(format!(
                "parameter section: records continue past the {declared_blocks} declared blocks"
            ));
            overflow_warned = true;
        }
        let parsed = parse_record(bytes, pos, processor);
        let (offset_pos, offset, end) = match parsed {
            Ok((record, offset_pos, offset, end)) => {
                records.push(record);
                (offset_pos, offset, Some(end))
            }
            Err(RecordError {
                offset_pos,
                offset,
                reason,
            }) => {
                warnings.push(format!(
                    "parameter section: record at byte {pos} skipped: {reason}"
                ));
                match offset_pos {
                    Some(p) => (p, offset, None),
                    None => break,
                }
            }
        };
        if offset == 0 {
            break;
        }
        let target = offset_pos as i64 + i64::from(offset);
        let target = (target > pos as i64)
            .then(|| usize::try_from(target).ok())
            .flatten();
        let target_kind = target.map_or(Kind::Garbage, |t| classify(bytes, t));
        let end_kind = end
            .filter(|&e| e > pos && Some(e) != target)
            .map_or(Kind::Garbage, |e| classify(bytes, e));
        match (target_kind, end_kind) {
            (Kind::Record, _) => pos = target.unwrap_or(pos),
            (_, Kind::Record) => {
                let e = end.unwrap_or(pos);
                warnings.push(format!(
                    "parameter section: record at byte {pos} has a bad next-record offset \
                     ({offset}); continuing right after it at byte {e}"
                ));
                pos = e;
            }
            (Kind::End, _) => break,
            (Kind::Garbage, _) => {
                warnings.push(format!(
                    "parameter section: record at byte {pos} has a bad next-record offset \
                     ({offset}); stopped reading parameters there"
                ));
                break;
            }
        }
    }
    Ok(Section {
        processor,
        declared_blocks,
        parameters: assemble(records, &mut warnings),
        warnings,
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A plausible record: non-zero name length and group id, printable ASCII name, in the file.
    Record,
    /// An end marker (name length or group id 0).
    End,
    /// Anything else, including positions outside the file.
    Garbage,
}

/// What `pos` seems to start.
fn classify(bytes: &[u8], pos: usize) -> Kind {
    let Some(&[len_byte, id_byte]) = bytes.get(pos..pos.saturating_add(2)) else {
        return Kind::Garbage;
    };
    let (n, id) = (len_byte as i8, id_byte as i8);
    if n == 0 || id == 0 {
        return Kind::End;
    }
    let n = usize::from(n.unsigned_abs());
    match bytes.get(pos + 2..pos + 2 + n + 2) {
        Some(rest) if rest[..n].iter().all(|&c| c.is_ascii_graphic() || c == b' ') => Kind::Record,
        _ => Kind::Garbage,
    }
}

struct RecordError {
    offset_pos: Option<usize>,
    offset: i16,
    reason: String,
}

/// Parses one record at `pos`: `(record, position of the offset word, offset, end of record)`.
fn parse_record(
    bytes: &[u8],
    pos: usize,
    processor: Processor,
) -> Result<(Record, usize, i16, usize), RecordError> {
    let name_len = usize::from((bytes[pos] as i8).unsigned_abs());
    let locked = (bytes[pos] as i8) < 0;
    let id = bytes[pos + 1] as i8;
    let offset_pos = pos + 2 + name_len;
    let err = |offset_pos: Option<usize>, offset: i16, reason: String| RecordError {
        offset_pos,
        offset,
        reason,
    };
    let Some(&[o0, o1]) = bytes.get(offset_pos..offset_pos + 2) else {
        return Err(err(None, 0, "name runs past the end of the file".into()));
    };
    let name = decode_text(&bytes[pos + 2..offset_pos]);
    let offset = processor.i16([o0, o1]);
    let mut at = offset_pos + 2;
    let fail = |reason: &str| Err(err(Some(offset_pos), offset, format!("{name}: {reason}")));
    if id < 0 {
        let (description, end) = read_description(bytes, at);
        let record = Record::Group {
            id: id.unsigned_abs(),
            name,
            description,
        };
        return Ok((record, offset_pos, offset, end));
    }
    let Some(&type_byte) = bytes.get(at) else {
        return fail("type byte past the end of the file");
    };
    let Some(&n_dims) = bytes.get(at + 1) else {
        return fail("dimension count past the end of the file");
    };
    at += 2;
    let Some(dim_bytes) = bytes.get(at..at + usize::from(n_dims)) else {
        return fail("dimensions past the end of the file");
    };
    let dims: Vec<usize> = dim_bytes.iter().map(|&d| usize::from(d)).collect();
    at += dims.len();
    // At most 255 dimensions of at most 255: the product can overflow, so check it.
    let count = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    let elem = match type_byte as i8 {
        -1 | 1 => 1,
        2 => 2,
        4 => 4,
        t => return fail(&format!("unknown data type {t}")),
    };
    let Some(n_bytes) = count.and_then(|c| c.checked_mul(elem)) else {
        return fail("dimensions overflow");
    };
    let Some(raw) = bytes.get(at..at.saturating_add(n_bytes)) else {
        return fail(&format!(
            "{n_bytes} bytes of values run past the end of the file"
        ));
    };
    at += n_bytes;
    let data = match type_byte as i8 {
        -1 => ParamData::Char(raw.to_vec()),
        1 => ParamData::Byte(raw.to_vec()),
        2 => ParamData::Int(
            raw.chunks_exact(2)
                .map(|c| processor.i16([c[0], c[1]]))
                .collect(),
        ),
        _ => ParamData::Float(
            raw.chunks_exact(4)
                .map(|c| processor.f32([c[0], c[1], c[2], c[3]]))
                .collect(),
        ),
    };
    let (description, end) = read_description(bytes, at);
    let param = Parameter {
        name,
        description,
        locked,
        dims,
        data,
    };
    Ok((
        Record::Param {
            group: id as u8,
            param,
        },
        offset_pos,
        offset,
        end,
    ))
}

/// Reads a length-prefixed description, truncated at the end of the file.
fn read_description(bytes: &[u8], at: usize) -> (String, usize) {
    let Some(&n) = bytes.get(at) else {
        return (String::new(), at);
    };
    let end = (at + 1 + usize::from(n)).min(bytes.len());
    (decode_text(&bytes[at + 1..end]), end)
}

/// The one warning about the parameters of group `id` that appear more than once (`names`,
/// one entry per extra appearance, in file order): the first few named, the rest counted.
fn repeated_warning(id: u8, names: &[String]) -> String {
    const SHOWN: usize = 5;
    if let [name] = names {
        return format!(
            "parameter section: parameter {name} appears twice in group id {id}; kept the first"
        );
    }
    let mut list = names[..names.len().min(SHOWN)].join(", ");
    if names.len() > SHOWN {
        list.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    format!(
        "parameter section: {} repeated parameters in group id {id} ({list}); kept the first of each",
        names.len()
    )
}

/// Puts parameters into their groups (groups may be declared after their parameters).
fn assemble(records: Vec<Record>, warnings: &mut Vec<String>) -> Parameters {
    let mut by_id: BTreeMap<u8, Group> = BTreeMap::new();
    let mut params = Vec::new();
    for r in records {
        match r {
            Record::Group {
                id,
                name,
                description,
            } => {
                let g = by_id.entry(id).or_default();
                if !g.name.is_empty() {
                    warnings.push(format!(
                        "parameter section: group id {id} declared twice ({} and {name})",
                        g.name
                    ));
                }
                g.id = id;
                g.name = name;
                g.description = description;
            }
            Record::Param { group, param } => params.push((group, param)),
        }
    }
    // Repeated parameters, per group id in order of appearance: one warning per group (a
    // Vicon file repeats thousands; one line each would bury every other message).
    let mut repeated: BTreeMap<u8, Vec<String>> = BTreeMap::new();
    for (id, p) in params {
        let g = by_id.entry(id).or_insert_with(|| Group {
            id,
            ..Group::default()
        });
        let key = p.name.to_ascii_uppercase();
        match g.params.entry(key) {
            std::collections::btree_map::Entry::Occupied(e) => {
                repeated.entry(id).or_default().push(e.key().clone())
            }
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(p);
            }
        }
    }
    for (id, names) in repeated {
        warnings.push(repeated_warning(id, &names));
    }
    let mut groups: BTreeMap<String, Group> = BTreeMap::new();
    for (id, mut g) in by_id {
        if g.name.is_empty() {
            g.name = format!("GROUP{id}");
            warnings.push(format!(
                "parameter section: parameters refer to group id {id}, which has no record"
            ));
        }
        let key = g.name.to_ascii_uppercase();
        match groups.get_mut(&key) {
            Some(existing) => {
                warnings.push(format!(
                    "parameter section: two groups named {key}; merged their parameters"
                ));
                for (k, p) in g.params {
                    existing.params.entry(k).or_insert(p);
                }
            }
            None => {
                groups.insert(key, g);
            }
        }
    }
    Parameters { groups }
}
