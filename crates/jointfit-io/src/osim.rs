//! OpenSim 4 model export: a compiled [`Model`] and a parameter vector → an `.osim` XML file.
//!
//! # What maps to what
//!
//! | jointfit | OpenSim |
//! |---|---|
//! | segment | `Body` (placeholder mass and inertia, see below) |
//! | joint (free, gimbal, universal, pin, slider) | `CustomJoint` with a `SpatialTransform` |
//! | weld joint | `WeldJoint` |
//! | parent / child offset | `PhysicalOffsetFrame` `<parent>_offset` / `<child>_offset` owned by the joint |
//! | coordinate | `Coordinate` of that joint: same name, radians or metres, range, default, not clamped |
//! | marker | `Marker` in `MarkerSet`: same name, parent body, location in the body frame |
//!
//! # Why the transforms agree
//!
//! jointfit places a child segment by (see [`jointfit::model::spec`])
//!
//! `parent_from_child = parent_from_pjf · motion(q) · child_from_cjf⁻¹`,
//!
//! with each offset `segment_from_jf = T(tx, ty, tz) · Rx(rx) · Ry(ry) · Rz(rz)`. OpenSim
//! places a joint's child body by `X_PC = X_PF · X_FM(q) · X_CM⁻¹`, where `X_PF` and `X_CM`
//! are the joint's parent and child `PhysicalOffsetFrame`s, whose `translation` is the origin
//! in the owning frame and whose `orientation` is a frame-fixed (body-fixed) X-Y-Z sequence:
//! the same `T(t)·Rx·Ry·Rz`. So the offsets are written as they evaluate for the given
//! parameters (`value = scale · p[k]` or the fixed value), and what remains is the joint
//! motion `X_FM(q) = motion(q)`.
//!
//! A `CustomJoint` is a Simbody `MobilizedBody::FunctionBased`: three rotations, then three
//! translations. With `f_i` the value of transform axis `i` and `a_i` its unit axis,
//!
//! `X_FM = [R, p]`, `R = Rot(a_1, f_1) · Rot(a_2, f_2) · Rot(a_3, f_3)` (each axis in the frame
//! the previous rotations produced: body-fixed), `p = Σ_{i=4..6} f_i a_i` in `F`,
//!
//! i.e. `X_FM = T(p) · R`. Each coordinate drives one axis through the identity
//! `LinearFunction` (`f = 1·q + 0`, which also makes OpenSim classify the coordinate as
//! rotational or translational); unused axes hold a `Constant` 0. A negative jointfit axis
//! such as the knee's `−z` is written as the axis vector `(0, 0, −1)`, so coordinate values are
//! identical in both programs. jointfit's joint motions are (all intrinsic):
//!
//! - free: `T(x q1) T(y q2) T(z q3) · Rot(a1, q4) Rot(a2, q5) Rot(a3, q6) = T(q1, q2, q3) · R`:
//!   rotation axes `a1, a2, a3` and translation axes `x, y, z` of the parent joint frame;
//! - gimbal: `Rot(a1, q1) Rot(a2, q2) Rot(a3, q3)`: the three rotation axes, no translation;
//! - universal: `Rot(a1, q1) Rot(a2, q2)`: two rotation axes, the third `a1 × a2` held at 0;
//! - pin: `Rot(a, q)`, the other two rotation axes completing an orthonormal basis, held at 0;
//! - slider: `T(a q)`, likewise with the translations.
//!
//! Why `CustomJoint` and not OpenSim's `PinJoint`, `SliderJoint`, `UniversalJoint`,
//! `GimbalJoint` or `FreeJoint`: those fix their axes to the joint frames (a pin turns about
//! z, a gimbal is a body-fixed X-Y-Z sequence, a free joint's rotations are X-Y-Z too), so
//! jointfit's arbitrary axes and orders (the knee about −z, the hip z-x-y, the pelvis z-x-y)
//! would need extra rotated offset frames and, for negative axes, negated coordinates. A
//! `CustomJoint` takes the axes as they are: the offset frames stay exactly jointfit's and
//! every coordinate has the same value, sign and unit in both programs, so a `.mot` from
//! `jointfit ik` drives the OpenSim model directly. A weld has no motion, so OpenSim's own
//! `WeldJoint` (`X_FM = identity`) is exact.
//!
//! OpenSim rejects a `CustomJoint` whose rotation (or translation) axes include two parallel
//! ones, so a gimbal or free joint with a repeated axis (e.g. a z-x-z gimbal) or a universal
//! joint with parallel axes cannot be exported: [`OsimError::ParallelAxes`].
//!
//! `tests/it/osim.rs` checks all of this against OpenSim 4.6 itself (`crates/jointfit-cli/assets/osim_check.py`):
//! marker positions in ground for random coordinates, for every joint kind.
//!
//! # Placeholders and names
//!
//! jointfit models carry no mass properties: every body gets 1 kg at its origin and inertia
//! 0.01 kg·m² about each axis, said so in a comment in the file. The model is for kinematics
//! (marker positions, inverse kinematics), not for dynamics. Marker weights are not part of
//! an OpenSim model (they belong to an IK task set); the comment lists those that are not 1.
//!
//! OpenSim component names may not contain `\ / * +` or white space, and `.`/`..` are path
//! steps: such a segment, joint, coordinate or marker name is an error
//! ([`OsimError::BadName`]). The model name is only a label and is sanitized instead.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use jointfit::model::spec::JointSpec;
use jointfit::model::{Coordinate, JointKind, Model};
use nalgebra::Vector3;
use thiserror::Error;

use crate::atomic::write_atomic;
use crate::text::format_shortest;
use crate::xml::escape;

mod axes;
mod names;

use axes::{eval_offset, spatial_axes, Offset};
use names::{check_names, comment_safe, sanitize};

/// Placeholder mass of every body (kg).
pub const PLACEHOLDER_MASS: f64 = 1.0;
/// Placeholder principal moment of inertia of every body about its origin (kg·m²).
pub const PLACEHOLDER_INERTIA: f64 = 0.01;

/// Why a model could not be exported.
#[derive(Debug, Error)]
pub enum OsimError {
    #[error("parameter vector has {got} values, the model has {expected} parameters")]
    ParamLength { got: usize, expected: usize },
    #[error("parameter {name:?} = {value} is not finite")]
    NonFiniteParam { name: String, value: f64 },
    #[error(
        "{kind} name {name:?} is not a valid OpenSim component name (no \\ / * + or white \
         space; not \".\" or \"..\")"
    )]
    BadName { kind: &'static str, name: String },
    #[error(
        "joint {joint:?}: {what} axes {first} and {second} are parallel; an OpenSim CustomJoint \
         needs independent axes, so this joint cannot be exported"
    )]
    ParallelAxes {
        joint: String,
        what: &'static str,
        first: usize,
        second: usize,
    },
    #[error(
        "joint {joint:?} is a custom joint (read from an .osim): its model is written back into \
         the original file (calibrate MODEL.osim … -o OUT.osim), not exported"
    )]
    CustomJoint { joint: String },
    #[error("joint {joint:?}: offset scalar refers to unknown parameter {param:?}")]
    UnknownParameter { joint: String, param: String },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Renders the model with parameters `p` (len `n_p`, m and rad) as an OpenSim 4 `.osim`
/// document (see the module docs for the mapping).
pub fn to_osim(model: &Model, p: &[f64]) -> Result<String, OsimError> {
    if p.len() != model.parameters().len() {
        return Err(OsimError::ParamLength {
            got: p.len(),
            expected: model.parameters().len(),
        });
    }
    for (par, &v) in model.parameters().iter().zip(p) {
        if !v.is_finite() {
            return Err(OsimError::NonFiniteParam {
                name: par.name.clone(),
                value: v,
            });
        }
    }
    check_names(model)?;

    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n");
    x.push_str("<OpenSimDocument Version=\"40000\">\n");
    header_comment(&mut x, model, p);
    let _ = writeln!(
        x,
        "  <Model name=\"{}\">",
        escape(&sanitize(&model.spec().name))
    );
    let _ = writeln!(
        x,
        "    <credits>{}</credits>",
        escape(&format!(
            "exported by jointfit {} from model {:?}",
            env!("CARGO_PKG_VERSION"),
            model.spec().name
        ))
    );
    x.push_str("    <length_units>meters</length_units>\n");
    x.push_str("    <force_units>N</force_units>\n");
    x.push_str("    <gravity>0 -9.80665 0</gravity>\n");

    body_set(&mut x, model);
    x.push_str("    <JointSet name=\"jointset\">\n      <objects>\n");
    for ji in 0..model.joints().len() {
        joint_xml(&mut x, model, p, ji)?;
    }
    x.push_str("      </objects>\n    </JointSet>\n");
    marker_set(&mut x, model);
    x.push_str("  </Model>\n</OpenSimDocument>\n");
    Ok(x)
}

/// One joint of `model` (`ji`) as an OpenSim `CustomJoint` (or `WeldJoint`) with its
/// coordinates, offset frames and spatial transform.
fn joint_xml(x: &mut String, model: &Model, p: &[f64], ji: usize) -> Result<(), OsimError> {
    let joint = &model.joints()[ji];
    let spec = joint_spec(model, ji);
    let parent = match joint.parent {
        Some(s) => model.segments()[s.0].name.as_str(),
        None => "ground",
    };
    let child = model.segments()[joint.child.0].name.as_str();
    let parent_offset = eval_offset(model, p, &spec.parent_offset, &joint.name)?;
    let child_offset = eval_offset(model, p, &spec.child_offset, &joint.name)?;
    let tag = match joint.kind {
        JointKind::Weld => "WeldJoint",
        _ => "CustomJoint",
    };
    let _ = writeln!(x, "        <{tag} name=\"{}\">", escape(&joint.name));
    let _ = writeln!(
        x,
        "          <socket_parent_frame>{}_offset</socket_parent_frame>",
        escape(parent)
    );
    let _ = writeln!(
        x,
        "          <socket_child_frame>{}_offset</socket_child_frame>",
        escape(child)
    );
    let coords = &model.coordinates()[joint.coords.clone()];
    coordinates_xml(x, coords);
    x.push_str("          <frames>\n");
    offset_frame(x, parent, &parent_offset);
    offset_frame(x, child, &child_offset);
    x.push_str("          </frames>\n");
    if !matches!(joint.kind, JointKind::Weld) {
        let names: Vec<&str> = coords.iter().map(|c| c.name.as_str()).collect();
        let axes = spatial_axes(&joint.kind, &names, &joint.name)?;
        x.push_str("          <SpatialTransform>\n");
        for (k, (axis, coord)) in axes.iter().enumerate() {
            transform_axis(x, k, axis, *coord);
        }
        x.push_str("          </SpatialTransform>\n");
    }
    let _ = writeln!(x, "        </{tag}>");
    Ok(())
}

/// The `<coordinates>` of a joint (none for a joint without coordinates).
fn coordinates_xml(x: &mut String, coords: &[Coordinate]) {
    if !coords.is_empty() {
        x.push_str("          <coordinates>\n");
        for c in coords {
            let _ = writeln!(x, "            <Coordinate name=\"{}\">", escape(&c.name));
            let _ = writeln!(
                x,
                "              <default_value>{}</default_value>",
                num(c.default)
            );
            x.push_str("              <default_speed_value>0</default_speed_value>\n");
            let _ = writeln!(
                x,
                "              <range>{} {}</range>",
                num(c.range[0]),
                num(c.range[1])
            );
            x.push_str("              <clamped>false</clamped>\n");
            x.push_str("              <locked>false</locked>\n");
            x.push_str("              <prescribed>false</prescribed>\n");
            x.push_str("            </Coordinate>\n");
        }
        x.push_str("          </coordinates>\n");
    }
}

/// The `<BodySet>`: each segment with placeholder mass and inertia.
fn body_set(x: &mut String, model: &Model) {
    x.push_str("    <BodySet name=\"bodyset\">\n      <objects>\n");
    for seg in model.segments() {
        let _ = writeln!(x, "        <Body name=\"{}\">", escape(&seg.name));
        let _ = writeln!(x, "          <mass>{}</mass>", num(PLACEHOLDER_MASS));
        x.push_str("          <mass_center>0 0 0</mass_center>\n");
        let i = num(PLACEHOLDER_INERTIA);
        let _ = writeln!(x, "          <inertia>{i} {i} {i} 0 0 0</inertia>");
        x.push_str("        </Body>\n");
    }
    x.push_str("      </objects>\n    </BodySet>\n");
}

/// The `<MarkerSet>`: each marker fixed in its segment.
fn marker_set(x: &mut String, model: &Model) {
    x.push_str("    <MarkerSet name=\"markerset\">\n      <objects>\n");
    for m in model.markers() {
        let _ = writeln!(x, "        <Marker name=\"{}\">", escape(&m.name));
        let _ = writeln!(
            x,
            "          <socket_parent_frame>/bodyset/{}</socket_parent_frame>",
            escape(&model.segments()[m.segment.0].name)
        );
        let _ = writeln!(x, "          <location>{}</location>", vec3(&m.local));
        x.push_str("          <fixed>true</fixed>\n");
        x.push_str("        </Marker>\n");
    }
    x.push_str("      </objects>\n    </MarkerSet>\n");
}

/// Writes [`to_osim`] to `path` atomically (temporary file + rename).
pub fn write_osim(path: &Path, model: &Model, p: &[f64]) -> Result<(), OsimError> {
    let text = to_osim(model, p)?;
    write_atomic(path, text.as_bytes()).map_err(|source| OsimError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// The description of joint `ji` (the compiled model keeps the spec it came from).
fn joint_spec(model: &Model, ji: usize) -> &JointSpec {
    let name = &model.joints()[ji].name;
    model
        .spec()
        .joints
        .iter()
        .find(|j| &j.name == name)
        .expect("every compiled joint comes from a spec joint of the same name")
}

fn transform_axis(x: &mut String, k: usize, axis: &Vector3<f64>, coord: Option<&str>) {
    let name = if k < 3 {
        format!("rotation{}", k + 1)
    } else {
        format!("translation{}", k - 2)
    };
    let _ = writeln!(x, "            <TransformAxis name=\"{name}\">");
    let _ = writeln!(
        x,
        "              <coordinates>{}</coordinates>",
        coord.map(escape).unwrap_or_default()
    );
    let _ = writeln!(x, "              <axis>{}</axis>", vec3(axis));
    match coord {
        Some(_) => {
            x.push_str("              <LinearFunction name=\"function\">\n");
            x.push_str("                <coefficients>1 0</coefficients>\n");
            x.push_str("              </LinearFunction>\n");
        }
        None => {
            x.push_str("              <Constant name=\"function\">\n");
            x.push_str("                <value>0</value>\n");
            x.push_str("              </Constant>\n");
        }
    }
    x.push_str("            </TransformAxis>\n");
}

fn offset_frame(x: &mut String, owner: &str, o: &Offset) {
    let _ = writeln!(
        x,
        "            <PhysicalOffsetFrame name=\"{}_offset\">",
        escape(owner)
    );
    let parent = if owner == "ground" {
        "/ground".to_string()
    } else {
        format!("/bodyset/{}", escape(owner))
    };
    let _ = writeln!(x, "              <socket_parent>{parent}</socket_parent>");
    let t = Vector3::from(o.translation);
    let r = Vector3::from(o.orientation);
    let _ = writeln!(x, "              <translation>{}</translation>", vec3(&t));
    let _ = writeln!(x, "              <orientation>{}</orientation>", vec3(&r));
    x.push_str("            </PhysicalOffsetFrame>\n");
}

fn header_comment(x: &mut String, model: &Model, p: &[f64]) {
    let mut c = String::new();
    let _ = writeln!(
        c,
        "Exported by jointfit {} from model {:?}.",
        env!("CARGO_PKG_VERSION"),
        model.spec().name
    );
    if !model.spec().description.is_empty() {
        let _ = writeln!(c, "Description: {}", model.spec().description);
    }
    let _ = writeln!(
        c,
        "Kinematics only: body masses ({} kg) and inertias ({} kg m^2 about each axis of the \
         body origin) are PLACEHOLDERS, not estimates; do not use this model for dynamics.",
        PLACEHOLDER_MASS, PLACEHOLDER_INERTIA
    );
    c.push_str(
        "Joints: jointfit offsets as PhysicalOffsetFrames (T(t) Rx Ry Rz); joint motions as \
         CustomJoint SpatialTransforms (body-fixed rotations, then translations in the parent \
         joint frame; identity LinearFunctions), welds as WeldJoints.\n",
    );
    if !model.parameters().is_empty() {
        c.push_str("Joint parameters (m, rad) the offsets were evaluated with:\n");
        for (par, v) in model.parameters().iter().zip(p) {
            let _ = writeln!(c, "  {} = {}", par.name, format_shortest(*v));
        }
    }
    let weighted: Vec<String> = model
        .markers()
        .iter()
        .filter(|m| m.weight != 1.0)
        .map(|m| format!("{} {}", m.name, format_shortest(m.weight)))
        .collect();
    if !weighted.is_empty() {
        let _ = writeln!(
            c,
            "Marker weights other than 1 (give them to the IK task set): {}",
            weighted.join(", ")
        );
    }
    let _ = writeln!(x, "<!--\n{}-->", comment_safe(&c));
}

/// A number as OpenSim reads it back exactly (no `-0`).
fn num(v: f64) -> String {
    format_shortest(if v == 0.0 { 0.0 } else { v })
}

fn vec3(v: &Vector3<f64>) -> String {
    format!("{} {} {}", num(v.x), num(v.y), num(v.z))
}

#[cfg(test)]
mod tests {
    use super::axes::complete_basis;
    use super::names::valid_name;
    use super::*;

    #[test]
    fn basis_is_orthonormal_and_right_handed() {
        for a in [
            Vector3::x(),
            -Vector3::z(),
            Vector3::new(0.3, -0.9, 0.2).normalize(),
        ] {
            let (u, v) = complete_basis(&a);
            assert!((u.norm() - 1.0).abs() < 1e-15 && (v.norm() - 1.0).abs() < 1e-15);
            assert!(a.dot(&u).abs() < 1e-15 && a.dot(&v).abs() < 1e-15 && u.dot(&v).abs() < 1e-15);
            assert!((a.cross(&u) - v).norm() < 1e-15);
        }
    }

    #[test]
    fn escaping() {
        assert_eq!(comment_safe("a--b---c-"), "a- -b- - -c- ");
        assert_eq!(sanitize("my model/1"), "my_model_1");
        assert_eq!(sanitize(".."), "jointfit_model");
        assert!(valid_name("r.ASIS") && valid_name("a:b") && !valid_name("a b"));
        assert_eq!(num(-0.0), "0");
    }
}
