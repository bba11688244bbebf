//! OpenSim joints → custom joints of the core model.
//!
//! Every OpenSim 4 joint becomes a list of transform axes applied in order (see
//! `jointfit::model::custom`), following Simbody's mobilizers as OpenSim builds them:
//!
//! | OpenSim | coordinates | axes, in order |
//! |---|---|---|
//! | `CustomJoint` | as listed | translation1..3 (parent-frame axes), then rotation1..3, each rotation about the axis carried by the rotations before it |
//! | `PinJoint` | θ | rotation about z |
//! | `SliderJoint` | d | translation along x |
//! | `UniversalJoint` | θx, θy | rotation about x, then y |
//! | `GimbalJoint`, `BallJoint` | θx, θy, θz | body-fixed x, y, z |
//! | `FreeJoint` | θx, θy, θz, x, y, z | translations x, y, z, then body-fixed x, y, z |
//! | `PlanarJoint` | θz, x, y | translations x, y, then rotation about z |
//! | `WeldJoint` | — | none |
//!
//! (`BallJoint` and `FreeJoint` with OpenSim's Euler-angle coordinates.)

use jointfit::model::functions::FunctionSpec;
use jointfit::model::spec::{
    AxisMotion, AxisSpec, CoordinateSpec, JointKindSpec, JointSpec, OffsetSpec, ScalarSpec,
    TransformAxisSpec,
};
use roxmltree::Node;

use super::functions::function_in;
use super::xml::{child, elements, flag, label, name, number, numbers, path_leaf, text};
use super::{Fail, Frames, OffsetSite, Side};

pub(crate) const JOINT_TYPES: [&str; 9] = [
    "CustomJoint",
    "PinJoint",
    "SliderJoint",
    "UniversalJoint",
    "GimbalJoint",
    "BallJoint",
    "FreeJoint",
    "PlanarJoint",
    "WeldJoint",
];

fn coordinate(c: Node, joint: &str) -> Result<CoordinateSpec, Fail> {
    let what = format!("joint {joint:?} coordinate {:?}", name(c));
    let range = match child(c, "range") {
        Some(_) => {
            let r = numbers(c, "range")?;
            let [lo, hi] = r[..] else {
                return Err(Fail::at(c, format!("{what}: <range> needs two numbers")));
            };
            if lo > hi {
                return Err(Fail::at(
                    c,
                    format!(
                        "{what}: <range> {lo} {hi} has its minimum above its maximum (write \
                         the smaller value first)"
                    ),
                ));
            }
            Some([lo, hi])
        }
        None => None,
    };
    if flag(c, "prescribed", false)? {
        return Err(Fail::at(
            c,
            format!("{what}: prescribed coordinates are not supported"),
        ));
    }
    let default = match child(c, "default_value") {
        Some(_) => number(c, "default_value")?,
        None => 0.0,
    };
    let locked = flag(c, "locked", false)?;
    // OpenSim accepts an empty range (lo = hi) for a locked coordinate; the core needs lo < hi
    // (a range with lo > hi was refused above).
    let range = range.map(|[lo, hi]| {
        if lo < hi {
            [lo, hi]
        } else {
            [lo - 1.0, lo + 1.0]
        }
    });
    Ok(CoordinateSpec::Full {
        name: name(c).to_string(),
        range,
        default,
        locked,
        clamped: flag(c, "clamped", false)?,
    })
}

fn axis(motion: AxisMotion, v: [f64; 3], coordinate: Option<&str>) -> TransformAxisSpec {
    TransformAxisSpec {
        motion,
        axis: AxisSpec::Vector(v),
        coordinate: coordinate.map(str::to_string),
        function: FunctionSpec::identity(),
    }
}

/// The transform axes of a `SpatialTransform`: translations first, then rotations.
fn spatial_transform(j: Node, joint: &str) -> Result<Vec<TransformAxisSpec>, Fail> {
    let st = child(j, "SpatialTransform")
        .ok_or_else(|| Fail::at(j, format!("joint {joint:?}: no <SpatialTransform>")))?;
    let mut by_name: Vec<(String, TransformAxisSpec)> = Vec::new();
    for ta in elements(st).filter(|e| e.tag_name().name() == "TransformAxis") {
        let what = format!("joint {joint:?} {}", label(ta));
        let coords: Vec<&str> = text(ta, "coordinates")
            .unwrap_or("")
            .split_whitespace()
            .collect();
        if coords.len() > 1 {
            return Err(Fail::at(
                ta,
                format!("{what}: functions of several coordinates are not supported"),
            ));
        }
        let v = super::xml::vec3(ta, "axis")?;
        let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let function = function_in(ta, &["coordinates", "axis"]).map_err(|f| f.context(&what))?;
        let motion = if name(ta).starts_with("rotation") {
            AxisMotion::Rotation
        } else if name(ta).starts_with("translation") {
            AxisMotion::Translation
        } else {
            return Err(Fail::at(ta, format!("{what}: unknown transform axis name")));
        };
        let constant = function.constant_value();
        if constant == Some(0.0) {
            continue; // no motion, whatever the axis
        }
        if !(norm.is_finite() && norm > 0.0) {
            return Err(Fail::at(ta, format!("{what}: axis is zero")));
        }
        let mut spec = axis(motion, v, coords.first().copied());
        if constant.is_some() {
            spec.coordinate = None;
        }
        spec.function = function;
        by_name.push((name(ta).to_string(), spec));
    }
    by_name.sort_by_key(|(n, _)| {
        let rank = if n.starts_with("translation") { 0 } else { 10 };
        rank + n.chars().last().and_then(|c| c.to_digit(10)).unwrap_or(0)
    });
    Ok(by_name.into_iter().map(|(_, a)| a).collect())
}

/// The kind and coordinates of a joint element (module docs).
fn kind(j: Node, joint: &str, coords: &[CoordinateSpec]) -> Result<Vec<TransformAxisSpec>, Fail> {
    use AxisMotion::{Rotation as R, Translation as T};
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let tag = j.tag_name().name();
    let want = match tag {
        "PinJoint" | "SliderJoint" => 1,
        "UniversalJoint" => 2,
        "GimbalJoint" | "BallJoint" | "PlanarJoint" => 3,
        "FreeJoint" => 6,
        "WeldJoint" => 0,
        _ => coords.len(),
    };
    if coords.len() != want {
        return Err(Fail::at(
            j,
            format!(
                "joint {joint:?}: {tag} needs {want} coordinates, has {}",
                coords.len()
            ),
        ));
    }
    let c = |k: usize| Some(coords[k].name());
    Ok(match tag {
        "CustomJoint" => spatial_transform(j, joint)?,
        "PinJoint" => vec![axis(R, z, c(0))],
        "SliderJoint" => vec![axis(T, x, c(0))],
        "UniversalJoint" => vec![axis(R, x, c(0)), axis(R, y, c(1))],
        "GimbalJoint" | "BallJoint" => vec![axis(R, x, c(0)), axis(R, y, c(1)), axis(R, z, c(2))],
        "FreeJoint" => vec![
            axis(T, x, c(3)),
            axis(T, y, c(4)),
            axis(T, z, c(5)),
            axis(R, x, c(0)),
            axis(R, y, c(1)),
            axis(R, z, c(2)),
        ],
        "PlanarJoint" => vec![axis(T, x, c(1)), axis(T, y, c(2)), axis(R, z, c(0))],
        _ => vec![],
    })
}

/// One joint element → joint spec, plus the offset frames it uses (for write-back).
pub(crate) fn joint(
    j: Node,
    frames: &Frames,
    sites: &mut Vec<OffsetSite>,
) -> Result<JointSpec, Fail> {
    let jname = name(j).to_string();
    let coords = match child(j, "coordinates") {
        Some(cs) => elements(cs)
            .filter(|c| c.tag_name().name() == "Coordinate")
            .map(|c| coordinate(c, &jname))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![],
    };
    let axes = kind(j, &jname, &coords)?;
    let mut ends = Vec::new();
    for (side, socket) in [
        (Side::Parent, "socket_parent_frame"),
        (Side::Child, "socket_child_frame"),
    ] {
        let path = text(j, socket)
            .ok_or_else(|| Fail::at(j, format!("joint {jname:?}: no <{socket}>")))?;
        let end = frames
            .resolve(path_leaf(path), Some(j))
            .map_err(|msg| Fail::at(j, format!("joint {jname:?} {socket} {path:?}: {msg}")))?;
        let mut offset = OffsetSpec::default();
        if let Some(site) = &end.site {
            let v = site.value;
            for (slot, x) in offset.scalars_mut().into_iter().zip(v) {
                *slot = ScalarSpec::Fixed(x);
            }
            let mut site = site.clone();
            site.joint = jname.clone();
            site.side = side;
            sites.push(site);
        }
        ends.push((end.body, offset));
    }
    let (child_body, child_offset) = ends.pop().expect("two ends");
    let (parent_body, parent_offset) = ends.pop().expect("two ends");
    Ok(JointSpec {
        name: jname,
        parent: parent_body,
        child: child_body,
        kind: JointKindSpec::Custom { axes },
        coordinates: coords,
        parent_offset,
        child_offset,
    })
}
