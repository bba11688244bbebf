//! An OpenSim model scaled by per-body factors, written as OpenSim 4.x `Model::scale` would
//! write it (the ScaleTool with `preserve_mass_distribution` true), editing the model's own
//! text: every value OpenSim's scaling changes is replaced, every other byte is kept.
//!
//! With `s = [sx, sy, sz]` the factors of the body a component sits on (the base body of its
//! frame; bodies without factors and ground are left alone), OpenSim 4.x changes:
//!
//! * `PhysicalOffsetFrame` translation `t ← t ⊙ s` (joint frames and free-standing ones);
//! * `Marker` and `PathPoint` / `ConditionalPathPoint` location `r ← r ⊙ s`;
//! * `MovingPathPoint`: each location function `f` driven by a coordinate becomes
//!   `MultiplierFunction(f, s_k)` (an existing multiplier's scale is multiplied);
//! * `CustomJoint` translation axes `a` whose function is not the identity `q ↦ q`:
//!   `f ← MultiplierFunction(f, |a|·s_parent)`;
//! * `CoordinateCouplerConstraint` with a translational dependent coordinate:
//!   `scale_factor ← scale_factor · sx` of the dependent joint's parent body;
//! * wrap objects: translation `⊙ s`; with `R` the wrap frame (`xyz_body_rotation`, body-fixed
//!   X-Y-Z) and `ℓ_i = ‖R e_i ⊙ s‖`: ellipsoid dimensions `d_i ← d_i ℓ_i`, cylinder radius
//!   `← r (ℓ_x + ℓ_y)/2` and length `← L ℓ_z`, torus radii `← r (ℓ_x + ℓ_y)/2`, sphere radius
//!   `← r (sx + sy + sz)/3`;
//! * attached geometry `scale_factors ⊙ s` (bodies and offset frames);
//! * body mass centre `⊙ s`; inertia (mass kept): uniform `s` gives `I s²`; otherwise
//!   OpenSim's cylinder model (`Body::scaleInertialProperties`): the smallest principal
//!   moment is the cylinder's axis `a`, `r² = 2 I_aa / m`, `L² = 12 (I_oo − m r²/4) / m`
//!   (`o` another axis), `L ← L s_a`, `r² ← r² s_b s_c`, `I_aa = m r²/2`, the other two
//!   `m (L²/12 + r²/4)`, products `I_ij ← I_ij s_i s_j`;
//! * with `preserve_mass_distribution` false ([`ScaleOptions::scale_masses`]): each body's
//!   mass and inertia also times `|sx sy sz|`;
//! * then every mass and inertia times `M / Σ m` when a total mass `M` is given;
//! * muscles: `optimal_fiber_length` and `tendon_slack_length` times `ℓ'/ℓ`, the ratio of the
//!   path length after to before scaling at the default pose (`Muscle::postScale`); a
//!   `Ligament`'s or `PathSpring`'s `resting_length` likewise.
//!
//! Contact geometry is not scaled by OpenSim and stays as it is. Path lengths are OpenSim's
//! `GeometryPath` lengths at the default pose (conditional points active at the default
//! coordinate values, moving points at their default-pose location, wrapping over
//! `WrapCylinder`s followed; module `paths`).

mod paths;
pub mod record;
pub mod setup;
mod wrap;

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use jointfit::model::offset_rotation;
use jointfit_scale::geometry;
use jointfit_scale::geometry::ScaleFactors;
use nalgebra::{Matrix3, Vector3};
use roxmltree::{Document, Node};
use thiserror::Error;

use crate::osim_read::xml::{child, elements, name, numbers, path_leaf, text};
use crate::osim_read::OsimModel;

#[derive(Debug, Error)]
pub enum OsimScaleError {
    #[error("{path}: line {line}: {message}")]
    Invalid {
        path: PathBuf,
        line: u32,
        message: String,
    },
    #[error("{path}: {message}")]
    Model { path: PathBuf, message: String },
}

/// What to write besides the factors.
#[derive(Debug, Clone, Default)]
pub struct ScaleOptions {
    /// Total mass of the scaled model (kg); `None`: the generic model's.
    pub total_mass: Option<f64>,
    /// New marker locations (m, in the marker's parent frame, after scaling) that replace the
    /// scaled generic ones (the registered markers).
    pub markers: Vec<(String, [f64; 3])>,
    /// Masses grow with the product of their body's factors (OpenSim's
    /// `preserve_mass_distribution` false), before the total mass is set; false: masses kept.
    pub scale_masses: bool,
}

/// The written model and what changed.
#[derive(Debug, Clone)]
pub struct Scaled {
    pub text: String,
    /// Total mass of the generic model (kg).
    pub generic_mass: f64,
    /// Total mass written (kg).
    pub total_mass: f64,
    /// Per muscle (or ligament, path spring): the path length ratio `ℓ'/ℓ` at the default pose.
    pub length_ratios: Vec<(String, f64)>,
}

struct Fail {
    pos: usize,
    msg: String,
}

fn fail(node: Node, msg: String) -> Fail {
    Fail {
        pos: node.range().start,
        msg,
    }
}

fn vec3(node: Node, tag: &str) -> Result<Option<[f64; 3]>, Fail> {
    if child(node, tag).is_none() {
        return Ok(None);
    }
    let v = numbers(node, tag).map_err(|f| Fail {
        pos: f.pos,
        msg: f.msg,
    })?;
    match v[..] {
        [x, y, z] => Ok(Some([x, y, z])),
        _ => Err(fail(
            node,
            format!("<{tag}> needs three numbers, has {}", v.len()),
        )),
    }
}

fn scalar(node: Node, tag: &str) -> Result<Option<f64>, Fail> {
    if child(node, tag).is_none() {
        return Ok(None);
    }
    let v = numbers(node, tag).map_err(|f| Fail {
        pos: f.pos,
        msg: f.msg,
    })?;
    match v[..] {
        [x] => Ok(Some(x)),
        _ => Err(fail(
            node,
            format!("<{tag}> needs one number, has {}", v.len()),
        )),
    }
}

/// The byte range of an element's text (an empty range right after the start tag when the
/// element is empty).
fn text_range(node: Node, tag: &str) -> Option<Range<usize>> {
    let c = child(node, tag)?;
    c.first_child().filter(|t| t.is_text()).map(|t| t.range())
}

fn triple(v: [f64; 3]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

/// How a wrap object's frame axes stretch under body factors `s`: `ℓ_k = ‖R e_k ⊙ s‖`
/// with `R` the frame's `xyz_body_rotation` (body-fixed X-Y-Z).
fn frame_stretch(rotation: [f64; 3], s: [f64; 3]) -> [f64; 3] {
    let rm = offset_rotation(rotation[0], rotation[1], rotation[2]);
    std::array::from_fn(|k| {
        let c: Vector3<f64> = rm.column(k).into_owned();
        Vector3::new(c.x * s[0], c.y * s[1], c.z * s[2]).norm()
    })
}

fn mul(a: [f64; 3], s: [f64; 3]) -> [f64; 3] {
    [a[0] * s[0], a[1] * s[1], a[2] * s[2]]
}

/// Which body a frame name rests on.
struct Frames {
    ground: String,
    bodies: Vec<String>,
    /// Offset frame name → its parent frame's name (last path component).
    parents: HashMap<String, String>,
}

impl Frames {
    fn base(&self, frame: &str) -> Option<&str> {
        let mut leaf = frame;
        for _ in 0..32 {
            if let Some(b) = self.bodies.iter().find(|b| *b == leaf) {
                return Some(b);
            }
            if leaf == self.ground || leaf == "ground" {
                return None;
            }
            leaf = self.parents.get(leaf)?;
        }
        None
    }
}

const FUNCTION_TAGS: [&str; 9] = [
    "Constant",
    "LinearFunction",
    "PolynomialFunction",
    "PiecewiseLinearFunction",
    "SimmSpline",
    "NaturalCubicSpline",
    "GCVSpline",
    "MultiplierFunction",
    "PiecewiseConstantFunction",
];

/// The function element held by `holder` (directly, or inside a `<function>` wrapper).
fn function_node<'a, 'i>(holder: Node<'a, 'i>) -> Option<Node<'a, 'i>> {
    if let Some(f) = elements(holder).find(|c| FUNCTION_TAGS.contains(&c.tag_name().name())) {
        return Some(f);
    }
    let w = child(holder, "function")?;
    elements(w).find(|c| FUNCTION_TAGS.contains(&c.tag_name().name()))
}

struct Edits<'t> {
    text: &'t str,
    list: Vec<(Range<usize>, String)>,
}

impl Edits<'_> {
    fn set(&mut self, range: Range<usize>, value: String) {
        self.list.push((range, value));
    }
    /// Multiplies the function element `f` by `scale` (OpenSim's MultiplierFunction).
    fn multiply_function(&mut self, f: Node, scale: f64) -> Result<(), Fail> {
        if f.tag_name().name() == "MultiplierFunction" {
            let old = scalar(f, "scale")?.unwrap_or(1.0);
            match text_range(f, "scale") {
                Some(r) => self.set(r, format!("{}", old * scale)),
                None => {
                    return Err(fail(f, "MultiplierFunction has no <scale>".into()));
                }
            }
            return Ok(());
        }
        let r = f.range();
        let inner = &self.text[r.clone()];
        let named = match f.attribute("name") {
            Some(n) => format!(" name=\"{}\"", crate::xml::escape(n)),
            None => String::new(),
        };
        self.set(
            r,
            format!(
                "<MultiplierFunction{named}><function>{inner}</function><scale>{scale}</scale></MultiplierFunction>"
            ),
        );
        Ok(())
    }
}

/// Scales `model` (read from `path`, named in errors) by `factors` (module docs).
pub fn scale_osim(
    model: &OsimModel,
    path: &Path,
    factors: &ScaleFactors,
    opts: &ScaleOptions,
) -> Result<Scaled, OsimScaleError> {
    let doc = Document::parse(&model.text).map_err(|e| OsimScaleError::Invalid {
        path: path.to_path_buf(),
        line: e.pos().row,
        message: format!("not XML: {e}"),
    })?;
    let lengths =
        paths::length_ratios(model, &doc, factors).map_err(|message| OsimScaleError::Model {
            path: path.to_path_buf(),
            message,
        })?;
    scale_doc(model, &doc, factors, opts, lengths).map_err(|f| OsimScaleError::Invalid {
        path: path.to_path_buf(),
        line: doc.text_pos_at(f.pos).row,
        message: f.msg,
    })
}

/// `(name, [ℓ, ℓ'])`: the length (m) of every muscle's (ligament's, path spring's) path at
/// the default pose, in the model and in the model scaled by `factors`, as OpenSim computes
/// it (wrap cylinders followed; `paths` module docs).
pub fn path_lengths(
    model: &OsimModel,
    path: &Path,
    factors: &ScaleFactors,
) -> Result<Vec<(String, [f64; 2])>, OsimScaleError> {
    let doc = Document::parse(&model.text).map_err(|e| OsimScaleError::Invalid {
        path: path.to_path_buf(),
        line: e.pos().row,
        message: format!("not XML: {e}"),
    })?;
    paths::lengths(model, &doc, factors).map_err(|message| OsimScaleError::Model {
        path: path.to_path_buf(),
        message,
    })
}

fn frames_of(model: Node) -> Frames {
    let ground = child(model, "Ground").map_or("ground".to_string(), |g| name(g).to_string());
    let bodies = child(model, "BodySet")
        .and_then(|s| child(s, "objects"))
        .map(|o| elements(o).map(|b| name(b).to_string()).collect())
        .unwrap_or_default();
    let mut parents = HashMap::new();
    for f in model
        .descendants()
        .filter(|n| n.tag_name().name() == "PhysicalOffsetFrame")
    {
        if let Some(p) = text(f, "socket_parent") {
            parents.insert(name(f).to_string(), path_leaf(p).to_string());
        }
    }
    Frames {
        ground,
        bodies,
        parents,
    }
}

/// The frame a wrap object or geometry sits in: its nearest Body / offset frame ancestor.
fn owner_frame<'a>(node: Node<'a, '_>) -> Option<&'a str> {
    node.ancestors()
        .skip(1)
        .find(|a| {
            matches!(
                a.tag_name().name(),
                "Body" | "PhysicalOffsetFrame" | "Ground"
            )
        })
        .map(|a| name(a))
}

fn is_equal(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-14 * a.abs().max(b.abs()).max(1.0)
}

/// OpenSim's `Body::scaleInertialProperties` with the mass kept (module docs).
pub fn scaled_inertia(inertia: [f64; 6], mass: f64, s: [f64; 3]) -> [f64; 6] {
    let [xx, yy, zz, xy, xz, yz] = inertia;
    let mut m = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    if mass <= f64::EPSILON {
        m *= 0.0;
    } else if is_equal(s[0], s[1]) && is_equal(s[1], s[2]) {
        m *= s[0] * s[0];
    } else {
        let axis = if m[(0, 0)] <= m[(1, 1)] {
            if m[(0, 0)] <= m[(2, 2)] {
                0
            } else {
                2
            }
        } else if m[(1, 1)] <= m[(2, 2)] {
            1
        } else {
            2
        };
        let term = 2.0 * m[(axis, axis)] / mass;
        let radius = if term < 0.0 { 0.0 } else { term.sqrt() };
        let oa = if axis == 0 { 1 } else { 0 };
        let term = 12.0 * (m[(oa, oa)] - 0.25 * mass * radius * radius) / mass;
        let mut length = if term < 0.0 { 0.0 } else { term.sqrt() };
        length *= s[axis];
        let (b, c) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        let r2 = radius * s[b] * radius * s[c];
        let side = mass * (length * length / 12.0 + 0.25 * r2);
        for k in 0..3 {
            m[(k, k)] = if k == axis { 0.5 * mass * r2 } else { side };
        }
        for i in 0..3 {
            for j in 0..3 {
                if i != j {
                    m[(i, j)] *= s[i] * s[j];
                }
            }
        }
    }
    [
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 2)],
    ]
}

/// What the component edits need: the model, its frames, the factors, registered markers.
struct Ctx<'a> {
    model: &'a OsimModel,
    frames: Frames,
    factors: &'a ScaleFactors,
    registered: HashMap<&'a str, [f64; 3]>,
}

impl Ctx<'_> {
    fn factor_of(&self, frame: &str) -> Option<[f64; 3]> {
        self.frames
            .base(frame)
            .and_then(|b| self.factors.get(b))
            .copied()
    }
}

/// Bodies' mass centres, inertias and masses (module docs); returns the generic and the
/// written total mass.
fn scale_bodies(
    m: Node,
    factors: &ScaleFactors,
    opts: &ScaleOptions,
    ed: &mut Edits,
) -> Result<(f64, f64), Fail> {
    let bodies: Vec<Node> = child(m, "BodySet")
        .and_then(|s| child(s, "objects"))
        .map(|o| elements(o).collect())
        .unwrap_or_default();
    // Mass factor of each body: the product of its factors when masses scale with volume.
    let grow = |b: Node| -> f64 {
        match factors.get(name(b)) {
            Some(s) if opts.scale_masses => (s[0] * s[1] * s[2]).abs(),
            _ => 1.0,
        }
    };
    let (mut generic_mass, mut grown_mass) = (0.0, 0.0);
    for b in &bodies {
        let mass = scalar(*b, "mass")?.unwrap_or(0.0);
        generic_mass += mass;
        grown_mass += mass * grow(*b);
    }
    let total_mass = opts.total_mass.unwrap_or(grown_mass);
    let normalise = if opts.total_mass.is_some() && grown_mass > 0.0 {
        total_mass / grown_mass
    } else {
        1.0
    };
    for b in &bodies {
        let s = factors.get(name(*b)).copied();
        let mass = scalar(*b, "mass")?.unwrap_or(0.0);
        let k = grow(*b) * normalise;
        if k != 1.0 {
            if let Some(r) = text_range(*b, "mass") {
                ed.set(r, format!("{}", mass * k));
            }
        }
        if let Some(s) = s {
            if let (Some(c), Some(r)) = (vec3(*b, "mass_center")?, text_range(*b, "mass_center")) {
                ed.set(r, triple(mul(c, s)));
            }
        }
        if child(*b, "inertia").is_none() {
            continue;
        }
        let v = numbers(*b, "inertia").map_err(|f| Fail {
            pos: f.pos,
            msg: f.msg,
        })?;
        let [xx, yy, zz, xy, xz, yz] = v[..] else {
            return Err(fail(
                *b,
                format!("<inertia> needs six numbers, has {}", v.len()),
            ));
        };
        let mut i = [xx, yy, zz, xy, xz, yz];
        if let Some(s) = s {
            i = scaled_inertia(i, mass, s);
        }
        if s.is_some() || k != 1.0 {
            let i = i.map(|x| x * k);
            if let Some(r) = text_range(*b, "inertia") {
                ed.set(
                    r,
                    format!("{} {} {} {} {} {}", i[0], i[1], i[2], i[3], i[4], i[5]),
                );
            }
        }
    }
    Ok((generic_mass, total_mass))
}

/// Attached geometry: `scale_factors ⊙ s`.
fn scale_geometry(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(s) = owner_frame(n).and_then(|f| ctx.factor_of(f)) else {
        return Ok(());
    };
    for g in elements(n) {
        if let (Some(v), Some(r)) = (vec3(g, "scale_factors")?, text_range(g, "scale_factors")) {
            ed.set(r, triple(mul(v, s)));
        }
    }
    Ok(())
}

/// A `PhysicalOffsetFrame`: translation `⊙ s` of its parent's body.
fn scale_offset_frame(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(s) = text(n, "socket_parent").and_then(|p| ctx.factor_of(path_leaf(p))) else {
        return Ok(());
    };
    if let (Some(t), Some(r)) = (vec3(n, "translation")?, text_range(n, "translation")) {
        ed.set(r, triple(mul(t, s)));
    }
    Ok(())
}

/// A marker (its registered place when given) or a fixed path point: location `⊙ s`.
fn scale_point(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let parent = text(n, "socket_parent_frame").map(path_leaf);
    let new = if n.tag_name().name() == "Marker" {
        ctx.registered.get(name(n)).copied()
    } else {
        None
    };
    let s = parent.and_then(|p| ctx.factor_of(p));
    let Some(r) = text_range(n, "location") else {
        return Ok(());
    };
    match (new, s, vec3(n, "location")?) {
        (Some(v), _, _) => ed.set(r, triple(v)),
        (None, Some(s), Some(loc)) => ed.set(r, triple(mul(loc, s))),
        _ => {}
    }
    Ok(())
}

/// A `MovingPathPoint`: each coordinate-driven location function times `s_k`.
fn scale_moving_point(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(s) = text(n, "socket_parent_frame").and_then(|p| ctx.factor_of(path_leaf(p))) else {
        return Ok(());
    };
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let driven = text(n, &format!("socket_{axis}_coordinate")).is_some_and(|c| !c.is_empty());
        if !driven {
            continue;
        }
        if let Some(f) = child(n, &format!("{axis}_location")).and_then(function_node) {
            ed.multiply_function(f, s[k])?;
        }
    }
    Ok(())
}

/// A `CustomJoint`'s translation axes with a function other than `q ↦ q`: times
/// `|a|·s_parent`.
fn scale_custom_joint(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(s) = text(n, "socket_parent_frame").and_then(|p| ctx.factor_of(path_leaf(p))) else {
        return Ok(());
    };
    let Some(st) = child(n, "SpatialTransform") else {
        return Ok(());
    };
    for ax in elements(st).filter(|a| {
        a.tag_name().name() == "TransformAxis"
            && matches!(name(*a), "translation1" | "translation2" | "translation3")
    }) {
        let Some(f) = function_node(ax) else {
            continue;
        };
        if f.tag_name().name() == "LinearFunction" {
            let c = numbers(f, "coefficients").unwrap_or_default();
            if c.len() == 2 && c[0] == 1.0 && c[1] == 0.0 {
                continue;
            }
        }
        let a = vec3(ax, "axis")?.unwrap_or([0.0; 3]);
        let k = a[0].abs() * s[0] + a[1].abs() * s[1] + a[2].abs() * s[2];
        ed.multiply_function(f, k)?;
    }
    Ok(())
}

/// A `CoordinateCouplerConstraint` of a translational coordinate: `scale_factor · sx`.
fn scale_coupler(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(dep) = text(n, "dependent_coordinate_name") else {
        return Ok(());
    };
    if !geometry::is_translational(&ctx.model.spec, dep) {
        return Ok(());
    }
    let parent = ctx
        .model
        .spec
        .joints
        .iter()
        .find(|j| j.coordinates.iter().any(|c| c.name() == dep))
        .map(|j| j.parent.clone());
    let Some(s) = parent.and_then(|p| ctx.factors.get(&p).copied()) else {
        return Ok(());
    };
    if !(is_equal(s[0], s[1]) && is_equal(s[1], s[2])) {
        return Err(fail(
            n,
            format!(
                "coupler of translational coordinate {dep:?}: OpenSim scales it \
                 only with equal factors on all three axes"
            ),
        ));
    }
    let old = scalar(n, "scale_factor")?.unwrap_or(1.0);
    match text_range(n, "scale_factor") {
        Some(r) => ed.set(r, format!("{}", old * s[0])),
        None => return Err(fail(n, "coupler has no <scale_factor>".into())),
    }
    Ok(())
}

/// A wrap object: translation `⊙ s`, its size by the stretch of its axes (module docs).
fn scale_wrap(ctx: &Ctx, n: Node, ed: &mut Edits) -> Result<(), Fail> {
    let Some(s) = owner_frame(n).and_then(|f| ctx.factor_of(f)) else {
        return Ok(());
    };
    if let (Some(t), Some(r)) = (vec3(n, "translation")?, text_range(n, "translation")) {
        ed.set(r, triple(mul(t, s)));
    }
    let rot = vec3(n, "xyz_body_rotation")?.unwrap_or([0.0; 3]);
    let l = frame_stretch(rot, s);
    let mut set_scalar = |tag: &str, k: f64| -> Result<(), Fail> {
        if let (Some(v), Some(r)) = (scalar(n, tag)?, text_range(n, tag)) {
            ed.set(r, format!("{}", v * k));
        }
        Ok(())
    };
    match n.tag_name().name() {
        "WrapSphere" => set_scalar("radius", (s[0] + s[1] + s[2]) / 3.0)?,
        "WrapCylinder" => {
            set_scalar("radius", (l[0] + l[1]) * 0.5)?;
            set_scalar("length", l[2])?;
        }
        "WrapTorus" => {
            set_scalar("inner_radius", (l[0] + l[1]) * 0.5)?;
            set_scalar("outer_radius", (l[0] + l[1]) * 0.5)?;
        }
        _ => {
            if let (Some(d), Some(r)) = (vec3(n, "dimensions")?, text_range(n, "dimensions")) {
                ed.set(r, triple([d[0] * l[0], d[1] * l[1], d[2] * l[2]]));
            }
        }
    }
    Ok(())
}

/// Path actuators, ligaments, path springs: lengths times the path length ratio.
fn scale_path_lengths(m: Node, lengths: &[(String, f64)], ed: &mut Edits) -> Result<(), Fail> {
    let ratio: HashMap<&str, f64> = lengths.iter().map(|(n, r)| (n.as_str(), *r)).collect();
    for n in m.descendants().filter(|n| n.is_element()) {
        let Some(&k) = ratio.get(name(n)) else {
            continue;
        };
        if child(n, "GeometryPath").is_none() && child(n, "path").is_none() {
            continue;
        }
        for tag in [
            "optimal_fiber_length",
            "tendon_slack_length",
            "resting_length",
        ] {
            if let (Some(v), Some(r)) = (scalar(n, tag)?, text_range(n, tag)) {
                ed.set(r, format!("{}", v * k));
            }
        }
    }
    Ok(())
}

impl Edits<'_> {
    /// The text with every edit applied (edits must not overlap).
    fn apply(self) -> Result<String, Fail> {
        let mut list = self.list;
        list.sort_by_key(|(r, _)| r.start);
        for w in list.windows(2) {
            if w[0].0.end > w[1].0.start {
                return Err(Fail {
                    pos: w[1].0.start,
                    msg: "two scaled values overlap in the file".into(),
                });
            }
        }
        let mut out = String::with_capacity(self.text.len() + 64 * list.len());
        let mut at = 0;
        for (r, t) in &list {
            out.push_str(&self.text[at..r.start]);
            out.push_str(t);
            at = r.end;
        }
        out.push_str(&self.text[at..]);
        Ok(out)
    }
}

fn scale_doc(
    model: &OsimModel,
    doc: &Document,
    factors: &ScaleFactors,
    opts: &ScaleOptions,
    lengths: Vec<(String, f64)>,
) -> Result<Scaled, Fail> {
    let root = doc.root_element();
    let m = child(root, "Model").ok_or_else(|| fail(root, "no <Model>".into()))?;
    let mut ed = Edits {
        text: &model.text,
        list: Vec::new(),
    };
    let (generic_mass, total_mass) = scale_bodies(m, factors, opts, &mut ed)?;
    let ctx = Ctx {
        model,
        frames: frames_of(m),
        factors,
        registered: opts.markers.iter().map(|(n, v)| (n.as_str(), *v)).collect(),
    };
    for n in m.descendants().filter(|n| n.is_element()) {
        match n.tag_name().name() {
            "attached_geometry" => scale_geometry(&ctx, n, &mut ed)?,
            "PhysicalOffsetFrame" => scale_offset_frame(&ctx, n, &mut ed)?,
            "Marker" | "PathPoint" | "ConditionalPathPoint" => scale_point(&ctx, n, &mut ed)?,
            "MovingPathPoint" => scale_moving_point(&ctx, n, &mut ed)?,
            "CustomJoint" => scale_custom_joint(&ctx, n, &mut ed)?,
            "CoordinateCouplerConstraint" => scale_coupler(&ctx, n, &mut ed)?,
            "WrapSphere" | "WrapCylinder" | "WrapEllipsoid" | "WrapTorus" => {
                scale_wrap(&ctx, n, &mut ed)?
            }
            _ => {}
        }
    }
    scale_path_lengths(m, &lengths, &mut ed)?;
    Ok(Scaled {
        text: ed.apply()?,
        generic_mass,
        total_mass,
        length_ratios: lengths,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_inertia_scales_by_the_square() {
        let i = scaled_inertia([1.0, 2.0, 3.0, 0.1, 0.2, 0.3], 5.0, [1.5; 3]);
        let e = [2.25, 4.5, 6.75, 0.225, 0.45, 0.675];
        for k in 0..6 {
            assert!((i[k] - e[k]).abs() < 1e-14);
        }
    }

    #[test]
    fn cylinder_inertia_of_a_solid_cylinder_scales_exactly() {
        // a solid cylinder along y: I_yy = m r²/2, I_xx = I_zz = m (L²/12 + r²/4)
        let (m, r, l) = (3.0, 0.05, 0.4);
        let side = m * (l * l / 12.0 + r * r / 4.0);
        let i = scaled_inertia(
            [side, 0.5 * m * r * r, side, 0.0, 0.0, 0.0],
            m,
            [1.2, 1.1, 1.2],
        );
        let (r2, l2) = (r * r * 1.44, l * 1.1 * l * 1.1);
        assert!((i[1] - 0.5 * m * r2).abs() < 1e-15);
        assert!((i[0] - m * (l2 / 12.0 + r2 / 4.0)).abs() < 1e-15);
        assert!((i[2] - i[0]).abs() < 1e-15);
    }
}
