//! The C3D parameter section: groups of typed, named, multi-dimensional parameters.
//!
//! The section starts at block `header byte 1` (1-based, 512 bytes per block) with four bytes:
//! two reserved, the number of 512-byte parameter blocks, and the processor type
//! (84/85/86, see [`super::floats`]). Then come group and parameter records, each:
//!
//! | bytes | content |
//! |---|---|
//! | 1 | name length n (signed; negative ⇒ "locked"); 0 ends the section |
//! | 1 | group id (signed): negative ⇒ this record *is* group −id; positive ⇒ a parameter of group id |
//! | n | name (ASCII) |
//! | 2 | signed offset from this word to the next record; 0 ⇒ last record |
//! | … | group: description length (1 byte) + description |
//! | … | parameter: type (1 byte: −1 char, 1 byte, 2 int16, 4 float), number of dimensions d, d dimension bytes, the values (column-major, first dimension fastest), description length + description |
//!
//! A parameter with no dimensions is a scalar. A char parameter of dimensions `[len, n, …]`
//! is an array of fixed-width strings of `len` characters.
//!
//! Leniency (each recorded in `warnings`, never silently): records are followed by their
//! next-record offset, and when an offset points backwards, outside the file or at something
//! that is not a record, the reader falls back to the end of the record as parsed (files named
//! badParameterOffset and mocap36 in the sample set need this); records that run past the
//! number of parameter blocks the section declares are still read when the file holds them
//! (parameterOverflow); a record whose values run past the end of the file, or whose type byte
//! is unknown, is skipped. Group and parameter names are matched case-insensitively.

use std::collections::BTreeMap;

mod section;

pub(crate) use section::{parse_section, SectionError};

/// Typed values of one parameter, flattened column-major (first dimension fastest).
#[derive(Debug, Clone, PartialEq)]
pub enum ParamData {
    /// Type −1: characters (bytes as stored).
    Char(Vec<u8>),
    /// Type 1: bytes (unsigned by convention).
    Byte(Vec<u8>),
    /// Type 2: 16-bit integers (signed as stored; see [`Parameter::u16s`] for counts).
    Int(Vec<i16>),
    /// Type 4: 32-bit floats (already converted from the file's float format).
    Float(Vec<f32>),
}

/// One parameter of a group.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Name as stored (upper case by convention).
    pub name: String,
    /// Free-text description.
    pub description: String,
    /// Whether the name length was stored negative ("locked").
    pub locked: bool,
    /// Dimensions (empty for a scalar).
    pub dims: Vec<usize>,
    /// The values.
    pub data: ParamData,
}

impl Parameter {
    /// Number of values (product of the dimensions, 1 for a scalar).
    pub fn len(&self) -> usize {
        match &self.data {
            ParamData::Char(v) | ParamData::Byte(v) => v.len(),
            ParamData::Int(v) => v.len(),
            ParamData::Float(v) => v.len(),
        }
    }

    /// Whether the parameter holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Numeric values as f64 (int16 as signed, bytes as unsigned); `None` for char data.
    pub fn f64s(&self) -> Option<Vec<f64>> {
        match &self.data {
            ParamData::Char(_) => None,
            ParamData::Byte(v) => Some(v.iter().map(|&x| f64::from(x)).collect()),
            ParamData::Int(v) => Some(v.iter().map(|&x| f64::from(x)).collect()),
            ParamData::Float(v) => Some(v.iter().map(|&x| f64::from(x)).collect()),
        }
    }

    /// The first numeric value as f64.
    pub fn f64(&self) -> Option<f64> {
        match &self.data {
            ParamData::Char(_) => None,
            ParamData::Byte(v) => v.first().map(|&x| f64::from(x)),
            ParamData::Int(v) => v.first().map(|&x| f64::from(x)),
            ParamData::Float(v) => v.first().map(|&x| f64::from(x)),
        }
    }

    /// Integer values read as unsigned 16-bit words (counts such as POINT:USED go up to
    /// 65535); bytes widen, floats convert when they are whole numbers in range.
    pub fn u16s(&self) -> Option<Vec<u16>> {
        match &self.data {
            ParamData::Char(_) => None,
            ParamData::Byte(v) => Some(v.iter().map(|&x| u16::from(x)).collect()),
            ParamData::Int(v) => Some(v.iter().map(|&x| x as u16).collect()),
            ParamData::Float(v) => v
                .iter()
                .map(|&x| (x.fract() == 0.0 && (0.0..=65535.0).contains(&x)).then_some(x as u16))
                .collect(),
        }
    }

    /// The first value as an unsigned 16-bit count (see [`Parameter::u16s`]).
    pub fn u16(&self) -> Option<u16> {
        self.u16s()?.first().copied()
    }

    /// Char data as strings, trimmed of spaces and NULs at both ends: one string per column for
    /// dimensions `[len, n, …]`, a single string for `[]` or `[len]`. `None` for numeric data.
    pub fn strings(&self) -> Option<Vec<String>> {
        let ParamData::Char(bytes) = &self.data else {
            return None;
        };
        let width = match self.dims.len() {
            0 | 1 => bytes.len(),
            _ => self.dims[0],
        };
        if width == 0 {
            let n: usize = self.dims.iter().skip(1).product();
            return Some(vec![String::new(); if self.dims.len() > 1 { n } else { 1 }]);
        }
        Some(bytes.chunks(width).map(decode_text).collect())
    }

    /// The first string of char data (see [`Parameter::strings`]).
    pub fn string(&self) -> Option<String> {
        self.strings()?.into_iter().next()
    }
}

/// Decodes stored text: Latin-1 bytes to chars, trimmed of blanks and NULs at both ends.
pub(crate) fn decode_text(bytes: &[u8]) -> String {
    let s: String = bytes.iter().map(|&b| char::from(b)).collect();
    s.trim_matches(|c: char| c == '\0' || c.is_whitespace())
        .to_string()
}

/// A group of parameters.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Group {
    /// Name as stored (or `GROUP<id>` when parameters refer to a group that has no record).
    pub name: String,
    /// Free-text description.
    pub description: String,
    /// The group id (1..=127) parameters use to refer to it.
    pub id: u8,
    /// Parameters by upper-case name.
    pub params: BTreeMap<String, Parameter>,
}

/// All groups of a file, by upper-case name, with case-insensitive look-up.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Parameters {
    /// Groups by upper-case name.
    pub groups: BTreeMap<String, Group>,
}

impl Parameters {
    /// A group by name (case-insensitive).
    pub fn group(&self, group: &str) -> Option<&Group> {
        self.groups.get(&group.to_ascii_uppercase())
    }

    /// A parameter by group and name (case-insensitive), e.g. `get("POINT", "RATE")`.
    pub fn get(&self, group: &str, param: &str) -> Option<&Parameter> {
        self.group(group)?.params.get(&param.to_ascii_uppercase())
    }

    /// Strings of a char parameter continued over `NAME`, `NAME2`, `NAME3`, … (how files
    /// store more than 255 labels), concatenated in that order.
    pub fn strings_continued(&self, group: &str, param: &str) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(s) = self.get(group, param).and_then(Parameter::strings) {
            out.extend(s);
        }
        for k in 2.. {
            match self
                .get(group, &format!("{param}{k}"))
                .and_then(Parameter::strings)
            {
                Some(s) => out.extend(s),
                None => break,
            }
        }
        out
    }
}
#[cfg(test)]
#[path = "parameters_tests.rs"]
mod tests;
