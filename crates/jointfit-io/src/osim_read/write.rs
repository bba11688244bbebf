//! Write-back: the user's `.osim` text with only the changed values replaced.
//!
//! Each edited value is the text inside one `<translation>`, `<orientation>` or
//! `<location>` element; every other byte (muscles, geometry, comments, the number
//! formatting of untouched values) is copied unchanged. New numbers are written in Rust's
//! shortest round-trip form, so reading the output gives back exactly the fitted values.

use std::ops::Range;

use thiserror::Error;

use super::{OsimModel, Side};

#[derive(Debug, Error, PartialEq)]
pub enum WriteBackError {
    #[error("joint {joint:?} has no {side} offset frame in the file to write into")]
    NoFrame { joint: String, side: &'static str },
    #[error("joint {joint:?} {side} offset frame has no <{element}> element to write into")]
    NoElement {
        joint: String,
        side: &'static str,
        element: &'static str,
    },
    #[error("marker {0:?} has no <location> of its own in the file (it sits on an offset frame)")]
    NoMarker(String),
    #[error("{0} value is not finite")]
    NotFinite(String),
    #[error("offset frame {frame:?} is shared by two joints that were given different values")]
    Conflict { frame: String },
}

/// One new offset: (joint, side, [tx, ty, tz, rx, ry, rz]).
pub type OffsetValue<'a> = (&'a str, Side, [f64; 6]);

fn side_name(s: Side) -> &'static str {
    match s {
        Side::Parent => "parent",
        Side::Child => "child",
    }
}

fn triple(v: &[f64]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

/// The file text with the given offsets (and marker locations, metres in the body frame)
/// replaced; values equal to the file's are left untouched.
pub fn write_back(
    model: &OsimModel,
    offsets: &[OffsetValue],
    markers: &[(&str, [f64; 3])],
) -> Result<String, WriteBackError> {
    let mut edits: Vec<(Range<usize>, String)> = Vec::new();
    let mut push = |range: Range<usize>, text: String, frame: &str| {
        if let Some((_, t)) = edits.iter().find(|(r, _)| *r == range) {
            return if *t == text {
                Ok(())
            } else {
                Err(WriteBackError::Conflict {
                    frame: frame.to_string(),
                })
            };
        }
        edits.push((range, text));
        Ok(())
    };
    for (joint, side, v) in offsets {
        if v.iter().any(|x| !x.is_finite()) {
            return Err(WriteBackError::NotFinite(format!("joint {joint:?} offset")));
        }
        let site = model
            .site(joint, *side)
            .ok_or_else(|| WriteBackError::NoFrame {
                joint: joint.to_string(),
                side: side_name(*side),
            })?;
        for (k, element) in [(0usize, "translation"), (3, "orientation")] {
            if v[k..k + 3] == site.value[k..k + 3] {
                continue;
            }
            let range = if k == 0 {
                &site.translation
            } else {
                &site.orientation
            };
            let range = range.clone().ok_or_else(|| WriteBackError::NoElement {
                joint: joint.to_string(),
                side: side_name(*side),
                element,
            })?;
            push(range, triple(&v[k..k + 3]), &site.frame)?;
        }
    }
    for (name, loc) in markers {
        if loc.iter().any(|x| !x.is_finite()) {
            return Err(WriteBackError::NotFinite(format!(
                "marker {name:?} location"
            )));
        }
        let site = model
            .markers
            .iter()
            .find(|m| m.name == *name)
            .ok_or_else(|| WriteBackError::NoMarker(name.to_string()))?;
        let old = model.spec.markers.iter().find(|m| m.name == *name);
        if old.is_some_and(|m| m.position == *loc) {
            continue;
        }
        push(site.location.clone(), triple(loc), name)?;
    }
    edits.sort_by_key(|(r, _)| r.start);
    let mut out = String::with_capacity(model.text.len() + 64 * edits.len());
    let mut at = 0;
    for (r, t) in &edits {
        out.push_str(&model.text[at..r.start]);
        out.push_str(t);
        at = r.end;
    }
    out.push_str(&model.text[at..]);
    Ok(out)
}
