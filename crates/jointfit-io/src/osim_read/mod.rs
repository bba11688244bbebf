//! OpenSim 4.x models (`.osim`) in: the kinematic part becomes a jointfit
//! [`ModelSpec`]; everything else (muscles, geometry, forces, comments) stays in the file
//! text, which [`write_back`] edits in place.
//!
//! Read: bodies (`BodySet`), joints (every OpenSim 4 joint type, see [`joints`]) with their
//! `PhysicalOffsetFrame`s as the joints' parent and child offsets (`translation`, then the
//! body-fixed x-y-z `orientation`: the same convention as [`jointfit::model::spec::OffsetSpec`]),
//! coordinates (range, default, locked, clamped), enforced `CoordinateCouplerConstraint`s
//! (`dependent = scale_factor · f(independent)`), and markers (an offset-frame parent is
//! folded into the body position). Kinematic components that jointfit cannot represent
//! (other constraints, multi-coordinate functions, prescribed coordinates, unknown joint or
//! function types, nested offset frames) are errors naming the component and its line.
//!
//! Checked against OpenSim 4.6 (marker and body positions at random poses) in
//! `tests/it/osim_read.rs`.

pub(crate) mod functions;
mod joints;
pub mod personalize;
mod write;
pub(crate) mod xml;

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use jointfit::model::functions::FunctionSpec;
use jointfit::model::offset_rotation;
use jointfit::model::spec::{CouplerSpec, MarkerSpec, ModelSpec, SegmentSpec};
use nalgebra::Vector3;
use roxmltree::{Document, Node};
use thiserror::Error;

pub use write::{write_back, WriteBackError};
use xml::{child, elements, flag, label, name, number, path_leaf, text, vec3};

#[derive(Debug, Error)]
pub enum OsimReadError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: line {line}: {message}")]
    Invalid {
        path: PathBuf,
        line: u32,
        message: String,
    },
}

/// An error at a byte position of the document (turned into a line number by the caller).
#[derive(Debug)]
pub(crate) struct Fail {
    pub(crate) pos: usize,
    pub(crate) msg: String,
}

impl Fail {
    pub(crate) fn at(node: Node, msg: String) -> Fail {
        Fail {
            pos: node.range().start,
            msg,
        }
    }
    pub(crate) fn context(mut self, what: &str) -> Fail {
        self.msg = format!("{what}: {}", self.msg);
        self
    }
}

/// Which end of a joint an offset frame serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Parent,
    Child,
}

/// Where a joint's offset frame sits in the file, for write-back.
#[derive(Debug, Clone)]
pub struct OffsetSite {
    pub joint: String,
    pub side: Side,
    /// The `PhysicalOffsetFrame`'s name.
    pub frame: String,
    /// Byte range of the text inside `<translation>` / `<orientation>` (`None`: element
    /// absent, value 0).
    pub translation: Option<Range<usize>>,
    pub orientation: Option<Range<usize>>,
    /// (tx, ty, tz, rx, ry, rz) as read.
    pub value: [f64; 6],
}

/// Where a marker's location sits in the file (markers attached to a body directly).
#[derive(Debug, Clone)]
pub struct MarkerSite {
    pub name: String,
    pub location: Range<usize>,
}

/// A read `.osim`: the kinematic model plus the file text and the spans of its editable
/// values.
#[derive(Debug, Clone)]
pub struct OsimModel {
    pub spec: ModelSpec,
    pub text: String,
    pub offsets: Vec<OffsetSite>,
    pub markers: Vec<MarkerSite>,
}

impl OsimModel {
    /// The offset site of a joint's end.
    pub fn site(&self, joint: &str, side: Side) -> Option<&OffsetSite> {
        self.offsets
            .iter()
            .find(|s| s.joint == joint && s.side == side)
    }
}

/// Reads an `.osim` file.
pub fn read_osim(path: &Path) -> Result<OsimModel, OsimReadError> {
    let text = crate::limits::read_text(path, crate::limits::DOCUMENT_BYTES, "model").map_err(
        |source| OsimReadError::Read {
            path: path.to_path_buf(),
            source,
        },
    )?;
    parse_osim(text, path)
}

/// Parses `.osim` text (`path` names it in errors).
pub fn parse_osim(text: String, path: &Path) -> Result<OsimModel, OsimReadError> {
    let invalid = |line: u32, message: String| OsimReadError::Invalid {
        path: path.to_path_buf(),
        line,
        message,
    };
    let doc = Document::parse(&text).map_err(|e| invalid(e.pos().row, format!("not XML: {e}")))?;
    let parsed = parse(&doc, path);
    let (spec, offsets, markers) =
        parsed.map_err(|f| invalid(doc.text_pos_at(f.pos).row, f.msg))?;
    drop(doc);
    Ok(OsimModel {
        spec,
        text,
        offsets,
        markers,
    })
}

/// The end of a joint or the parent of a marker: a body (or ground) and maybe an offset frame.
#[derive(Debug, Clone)]
pub(crate) struct End {
    pub body: String,
    pub site: Option<OffsetSite>,
}

/// Bodies, ground and the offset frames outside joints.
pub(crate) struct Frames<'a, 'i> {
    ground: String,
    bodies: Vec<String>,
    loose: HashMap<&'a str, Vec<Node<'a, 'i>>>,
}

fn span(node: Node, tag: &str) -> Option<Range<usize>> {
    let c = child(node, tag)?;
    let t = crate::xml::value_piece(c).ok()??;
    Some(t.range())
}

impl<'a, 'i> Frames<'a, 'i> {
    fn offset(&self, f: Node) -> Result<End, String> {
        let parent = text(f, "socket_parent").ok_or("offset frame has no <socket_parent>")?;
        let leaf = path_leaf(parent);
        let body = if leaf == self.ground || leaf == "ground" {
            "ground".to_string()
        } else if self.bodies.iter().any(|b| b == leaf) {
            leaf.to_string()
        } else {
            return Err(format!(
                "PhysicalOffsetFrame {:?} sits on {parent:?}, not on a body (nested offset \
                 frames are not supported)",
                name(f)
            ));
        };
        let t = if child(f, "translation").is_some() {
            vec3(f, "translation").map_err(|e| e.msg)?
        } else {
            [0.0; 3]
        };
        let r = if child(f, "orientation").is_some() {
            vec3(f, "orientation").map_err(|e| e.msg)?
        } else {
            [0.0; 3]
        };
        Ok(End {
            body,
            site: Some(OffsetSite {
                joint: String::new(),
                side: Side::Parent,
                frame: name(f).to_string(),
                translation: span(f, "translation"),
                orientation: span(f, "orientation"),
                value: [t[0], t[1], t[2], r[0], r[1], r[2]],
            }),
        })
    }

    /// A frame by name: the joint's own offset frames first, then bodies, ground, and
    /// offset frames elsewhere in the model.
    pub(crate) fn resolve(&self, leaf: &str, joint: Option<Node>) -> Result<End, String> {
        if let Some(fs) = joint.and_then(|j| child(j, "frames")) {
            if let Some(f) = elements(fs).find(|f| name(*f) == leaf) {
                if f.tag_name().name() != "PhysicalOffsetFrame" {
                    return Err(format!("{} is not supported", label(f)));
                }
                return self.offset(f);
            }
        }
        if self.bodies.iter().any(|b| b == leaf) {
            return Ok(End {
                body: leaf.to_string(),
                site: None,
            });
        }
        if leaf == self.ground {
            return Ok(End {
                body: "ground".into(),
                site: None,
            });
        }
        match self.loose.get(leaf).map(Vec::as_slice) {
            Some([f]) => self.offset(*f),
            Some(_) => Err(format!("several frames are named {leaf:?}")),
            None => Err("no such frame".into()),
        }
    }
}

type Parsed = (ModelSpec, Vec<OffsetSite>, Vec<MarkerSite>);

fn parse(doc: &Document, path: &Path) -> Result<Parsed, Fail> {
    let root = doc.root_element();
    if root.tag_name().name() != "OpenSimDocument" {
        return Err(Fail::at(root, "not an OpenSim document".into()));
    }
    check_version(root)?;
    let model = child(root, "Model").ok_or_else(|| Fail::at(root, "no <Model>".into()))?;
    let frames = frames(model)?;
    let mut offsets = Vec::new();
    let mut joint_specs = Vec::new();
    for j in set(model, "JointSet") {
        if !joints::JOINT_TYPES.contains(&j.tag_name().name()) {
            return Err(Fail::at(
                j,
                format!("{} is a joint type jointfit does not support", label(j)),
            ));
        }
        joint_specs.push(joints::joint(j, &frames, &mut offsets)?);
    }
    let (markers, marker_sites) = markers(model, &frames)?;
    let mut couplers = Vec::new();
    for c in set(model, "ConstraintSet") {
        if flag(c, "isEnforced", true)? {
            couplers.push(coupler(c)?);
        }
    }
    let stem = path
        .file_stem()
        .map_or("model".to_string(), |s| s.to_string_lossy().into_owned());
    let spec = ModelSpec {
        name: match name(model) {
            "" => stem,
            n => n.to_string(),
        },
        description: format!(
            "{}{}",
            jointfit::checks::offsets::OSIM_DESCRIPTION,
            path.display()
        ),
        segments: frames
            .bodies
            .iter()
            .map(|b| SegmentSpec {
                name: b.clone(),
                description: String::new(),
            })
            .collect(),
        joints: joint_specs,
        parameters: vec![],
        markers,
        couplers,
        lab_up: None,
    };
    Ok((spec, offsets, marker_sites))
}

/// The document's `Version`: an integer (as OpenSim reads it) of at least 40000.
fn check_version(root: Node) -> Result<(), Fail> {
    let Some(raw) = root.attribute("Version") else {
        return Err(Fail::at(
            root,
            "<OpenSimDocument> has no Version attribute; only OpenSim 4 models (Version ≥ \
             40000) are read"
                .into(),
        ));
    };
    let version: u32 = match raw.trim().parse::<i32>() {
        Ok(v) if v >= 0 => v as u32,
        _ => {
            return Err(Fail::at(
                root,
                format!(
                    "OpenSim document Version {raw:?} is unsupported: not a version number \
                     (OpenSim reads it as an integer, e.g. 40000, and refuses this file too)"
                ),
            ))
        }
    };
    if version < 40000 {
        return Err(Fail::at(
            root,
            format!(
                "OpenSim document version {version}: only OpenSim 4 models (Version ≥ 40000) \
                 are read; open and save it in OpenSim 4 first"
            ),
        ));
    }
    Ok(())
}

/// The objects of one of the model's sets (`BodySet`, `JointSet`, …); none when absent.
fn set<'a, 'i>(model: Node<'a, 'i>, tag: &str) -> impl Iterator<Item = Node<'a, 'i>> {
    child(model, tag)
        .and_then(|s| child(s, "objects"))
        .into_iter()
        .flat_map(elements)
}

/// Ground, the bodies, and the offset frames outside joints.
fn frames<'a, 'i>(model: Node<'a, 'i>) -> Result<Frames<'a, 'i>, Fail> {
    let ground = child(model, "Ground").map_or("ground".to_string(), |g| name(g).to_string());
    let mut bodies = Vec::new();
    for b in set(model, "BodySet") {
        if b.tag_name().name() != "Body" {
            return Err(Fail::at(b, format!("{} is not supported", label(b))));
        }
        bodies.push(name(b).to_string());
    }
    let mut loose: HashMap<&str, Vec<Node>> = HashMap::new();
    for f in model
        .descendants()
        .filter(|n| n.tag_name().name() == "PhysicalOffsetFrame")
    {
        let in_joint = f.parent().is_some_and(|p| p.tag_name().name() == "frames")
            && f.parent()
                .and_then(|p| p.parent())
                .is_some_and(|j| joints::JOINT_TYPES.contains(&j.tag_name().name()));
        if !in_joint {
            loose.entry(name(f)).or_default().push(f);
        }
    }
    Ok(Frames {
        ground,
        bodies,
        loose,
    })
}

/// The markers (those fixed in ground left out) and where their locations sit in the file.
fn markers(model: Node, frames: &Frames) -> Result<(Vec<MarkerSpec>, Vec<MarkerSite>), Fail> {
    let mut markers = Vec::new();
    let mut marker_sites = Vec::new();
    for m in set(model, "MarkerSet") {
        let what = label(m);
        let parent = text(m, "socket_parent_frame")
            .ok_or_else(|| Fail::at(m, format!("{what}: no <socket_parent_frame>")))?;
        let end = frames
            .resolve(path_leaf(parent), None)
            .map_err(|e| Fail::at(m, format!("{what}: {parent:?}: {e}")))?;
        if end.body == "ground" {
            continue; // a marker fixed in ground carries no information about the model
        }
        let loc = vec3(m, "location")?;
        let mut position = loc;
        match &end.site {
            Some(site) => {
                let v = site.value;
                let p = offset_rotation(v[3], v[4], v[5]) * Vector3::from(loc)
                    + Vector3::new(v[0], v[1], v[2]);
                position = [p.x, p.y, p.z];
            }
            None => {
                if let Some(r) = span(m, "location") {
                    marker_sites.push(MarkerSite {
                        name: name(m).to_string(),
                        location: r,
                    });
                }
            }
        }
        markers.push(MarkerSpec {
            name: name(m).to_string(),
            segment: end.body,
            position,
            weight: 1.0,
        });
    }
    Ok((markers, marker_sites))
}

/// An enforced `CoordinateCouplerConstraint`.
fn coupler(c: Node) -> Result<CouplerSpec, Fail> {
    let what = label(c);
    if c.tag_name().name() != "CoordinateCouplerConstraint" {
        return Err(Fail::at(
            c,
            format!(
                "{what}: enforced constraints other than CoordinateCouplerConstraint are not \
                 supported"
            ),
        ));
    }
    let holder = child(c, "coupled_coordinates_function")
        .ok_or_else(|| Fail::at(c, format!("{what}: no <coupled_coordinates_function>")))?;
    let f = functions::function_in(holder, &[]).map_err(|e| e.context(&what))?;
    let indep: Vec<&str> = text(c, "independent_coordinate_names")
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let [independent] = indep[..] else {
        return Err(Fail::at(
            c,
            format!(
                "{what}: needs exactly one independent coordinate, has {}",
                indep.len()
            ),
        ));
    };
    let dependent = text(c, "dependent_coordinate_name")
        .filter(|d| !d.is_empty())
        .ok_or_else(|| Fail::at(c, format!("{what}: no dependent coordinate")))?;
    let scale = match child(c, "scale_factor") {
        Some(_) => number(c, "scale_factor")?,
        None => 1.0,
    };
    let function = if scale == 1.0 {
        f
    } else {
        FunctionSpec::Multiplier {
            scale,
            function: Box::new(f),
        }
    };
    Ok(CouplerSpec {
        name: name(c).to_string(),
        dependent: dependent.to_string(),
        independent: independent.to_string(),
        function,
    })
}
