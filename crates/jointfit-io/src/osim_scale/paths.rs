//! Muscle–tendon path lengths at the default pose, before and after scaling, as OpenSim's
//! `GeometryPath` computes them: the active path points joined by straight segments, with
//! the path's wrap objects inserting their tangent points and surface arcs
//! (`GeometryPath::applyWrapObjects`, module docs of [`super::wrap`] for a cylinder):
//!
//! * each `PathWrap` of the path, in order, is tried on every segment between the active
//!   points of its `range` (1-based; `-1` the first or last point); a segment crossing the
//!   object (a mandatory wrap) is taken at once, otherwise the wrapped segment that lengthens
//!   the path least; its two tangent points are inserted into the path;
//! * with two or more wrap objects this is repeated (each pass starting from the previous
//!   one's path) until the length changes by less than 0.5 mm, at most 8 passes; after the
//!   first pass, the first two objects swap order when the first did not wrap and the second
//!   had a point inside it;
//! * the length is the sum of the straight segments plus each wrap's surface length.
//!
//! Only `WrapCylinder` is followed (the wrap type of the OpenCap/Rajagopal-family models;
//! gait2392 and Hamner's model carry no wrap objects); a path over a `WrapSphere`,
//! `WrapEllipsoid` or `WrapTorus`, or a wrap object on an offset frame, is taken as not
//! wrapping over it.

use std::collections::HashMap;

use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::functions::Function;
use jointfit::model::offset_rotation;
use jointfit::model::Model;
use jointfit::spatial::Pose;
use jointfit_scale::geometry::scaled_spec;
use jointfit_scale::geometry::ScaleFactors;
use nalgebra::Vector3;
use roxmltree::{Document, Node};

use crate::osim_read::functions::function_in;
use crate::osim_read::xml::{child, elements, name, numbers, path_leaf, text};
use crate::osim_read::OsimModel;

use super::wrap::{quadrant, Arc, Cylinder, Outcome};
use super::{frame_stretch, owner_frame};

type V = Vector3<f64>;

/// One path point as the default pose sees it.
struct Point {
    body: Option<String>,
    /// Location in the body (m) before scaling.
    location: [f64; 3],
    /// Which axes are functions of a coordinate (a moving point's scaled axes).
    moving: [bool; 3],
    /// A conditional point's coordinate is inside its range (others: always).
    active: bool,
}

fn default_pose(model: &Model) -> (KinData, HashMap<String, f64>) {
    let mut data = KinData::new(model);
    let q = model.default_coords();
    forward_kinematics(
        model,
        &model.nominal_params(),
        &q,
        Want::Positions,
        &mut data,
    );
    let mut values: HashMap<String, f64> = model
        .coordinates()
        .iter()
        .map(|c| (c.name.clone(), c.default))
        .collect();
    for d in model.dependents() {
        values.insert(d.name.clone(), d.default);
    }
    (data, values)
}

fn point(p: Node, bodies: &[String], values: &HashMap<String, f64>) -> Option<Point> {
    let parent = path_leaf(text(p, "socket_parent_frame")?).to_string();
    let body = bodies.contains(&parent).then_some(parent);
    let mut active = true;
    let coordinate = |tag: &str| {
        text(p, tag)
            .map(path_leaf)
            .and_then(|c| values.get(c).copied())
    };
    match p.tag_name().name() {
        "PathPoint" => {}
        "ConditionalPathPoint" => {
            let range = numbers(p, "range").ok()?;
            let q = coordinate("socket_coordinate")?;
            if range.len() != 2 {
                return None;
            }
            active = q >= range[0] && q <= range[1];
        }
        "MovingPathPoint" => {
            let mut location = [0.0; 3];
            let mut moving = [false; 3];
            for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                let holder = child(p, &format!("{axis}_location"))?;
                let f = Function::try_from(&function_in(holder, &[]).ok()?).ok()?;
                let q = coordinate(&format!("socket_{axis}_coordinate"));
                moving[k] = q.is_some();
                location[k] = f.eval(q.unwrap_or(0.0)).0;
            }
            return Some(Point {
                body,
                location,
                moving,
                active,
            });
        }
        _ => return None,
    }
    let v = numbers(p, "location").ok()?;
    Some(Point {
        body,
        location: [*v.first()?, *v.get(1)?, *v.get(2)?],
        moving: [false; 3],
        active,
    })
}

fn body_pose(model: &Model, data: &KinData, body: &Option<String>) -> Pose {
    body.as_ref()
        .and_then(|b| model.segments().iter().position(|s| s.name == *b))
        .map_or(Pose::identity(), |s| data.segment_poses[s])
}

/// A wrap object as a path sees it (unscaled).
struct WrapObject {
    body: Option<String>,
    rotation: [f64; 3],
    translation: [f64; 3],
    /// `None`: a shape this module does not follow (module docs).
    cylinder: Option<Cylinder>,
    active: bool,
}

/// The wrap objects of the model by name (the first of a name, as OpenSim finds it).
fn wrap_objects(doc: &Document, bodies: &[String]) -> Result<HashMap<String, WrapObject>, String> {
    let mut out = HashMap::new();
    let kinds = ["WrapCylinder", "WrapSphere", "WrapEllipsoid", "WrapTorus"];
    for n in doc
        .descendants()
        .filter(|n| kinds.contains(&n.tag_name().name()))
    {
        let owner = owner_frame(n).unwrap_or("");
        let on_ground = n.ancestors().any(|a| a.tag_name().name() == "Ground");
        let body = bodies.iter().find(|b| *b == owner).cloned();
        let three = |tag: &str| -> [f64; 3] {
            match numbers(n, tag).ok().as_deref() {
                Some([x, y, z]) => [*x, *y, *z],
                _ => [0.0; 3],
            }
        };
        let one = |tag: &str| numbers(n, tag).ok().and_then(|v| v.first().copied());
        let mut cylinder = None;
        if n.tag_name().name() == "WrapCylinder" && (body.is_some() || on_ground) {
            let q = quadrant(text(n, "quadrant").unwrap_or("all"))
                .map_err(|e| format!("wrap object {:?}: {e}", name(n)))?;
            cylinder = Some(Cylinder {
                radius: one("radius").unwrap_or(0.0),
                length: one("length").unwrap_or(0.0),
                quadrant: q,
            });
        }
        let active = text(n, "active").is_none_or(|t| t != "false");
        out.entry(name(n).to_string()).or_insert(WrapObject {
            body,
            rotation: three("xyz_body_rotation"),
            translation: three("translation"),
            cylinder,
            active,
        });
    }
    Ok(out)
}

/// A path's wrap over one object, placed at a pose.
struct Placed {
    /// Index of the wrap object (two path wraps over the same object compare equal).
    object: usize,
    world_from_wrap: Pose,
    cylinder: Option<Cylinder>,
    active: bool,
    /// `range` of the path wrap (1-based, < 1: the first / last point).
    range: [i64; 2],
}

/// An element of the current path: a path point, or the first / second tangent point of a
/// path wrap.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Elem {
    Point(usize),
    First(usize),
    Second(usize),
}

/// A path at one pose: its points in ground, their activity, its wraps.
struct Geometry<'a> {
    points: &'a [(V, bool)],
    wraps: &'a [Placed],
}

/// The current path while wraps are applied, with each wrap's tangent points (ground) and
/// surface length.
///
/// OpenSim caches a point's location in ground the first time it is asked for within a
/// state (`Point::getLocationInGround`) and does not refresh it when a later pass moves a
/// wrap's tangent point (`PathWrapPoint::setLocation` changes only the point's location in
/// its body): distances along the path use the first ground location of each tangent point,
/// the wrapping itself uses the current one. `seen` keeps those first locations.
struct Current {
    path: Vec<Elem>,
    arcs: Vec<Option<(V, V, f64)>>,
    seen: Vec<[Option<V>; 2]>,
}

impl Geometry<'_> {
    /// The element's current location (the one wrapping uses).
    fn at(&self, c: &Current, e: Elem) -> V {
        match e {
            Elem::Point(i) => self.points[i].0,
            Elem::First(w) => c.arcs[w].expect("placed").0,
            Elem::Second(w) => c.arcs[w].expect("placed").1,
        }
    }

    /// The element's location in ground as OpenSim's distances see it (`Current` docs).
    fn ground(&self, c: &mut Current, e: Elem) -> V {
        let now = self.at(c, e);
        let slot = match e {
            Elem::Point(_) => return now,
            Elem::First(w) => &mut c.seen[w][0],
            Elem::Second(w) => &mut c.seen[w][1],
        };
        *slot.get_or_insert(now)
    }

    fn object(&self, e: Elem) -> Option<usize> {
        match e {
            Elem::Point(_) => None,
            Elem::First(w) | Elem::Second(w) => Some(self.wraps[w].object),
        }
    }

    /// OpenSim's `calcLengthAfterPathComputation`.
    fn length(&self, c: &mut Current) -> f64 {
        let mut total = 0.0;
        for k in 1..c.path.len() {
            let (a, b) = (c.path[k - 1], c.path[k]);
            match (self.object(a), self.object(b), b) {
                (Some(x), Some(y), Elem::Second(w)) if x == y => {
                    total += c.arcs[w].expect("placed").2;
                }
                (Some(x), Some(y), _) if x == y => {}
                _ => total += (self.ground(c, a) - self.ground(c, b)).norm(),
            }
        }
        total
    }

    /// Wraps the segment `a b` over wrap `w`: the outcome and the arc in ground.
    fn wrap_segment(&self, c: &Current, w: usize, a: Elem, b: Elem) -> (Outcome, Option<Arc>) {
        let p = &self.wraps[w];
        let Some(cyl) = p.cylinder else {
            return (Outcome::NoWrap, None);
        };
        let to_wrap = p.world_from_wrap.inverse();
        let (p1, p2) = (
            to_wrap.transform_point(&self.at(c, a)),
            to_wrap.transform_point(&self.at(c, b)),
        );
        let (outcome, arc) = cyl.wrap_line(p1, p2, self.wraps.len() == 1);
        let arc = arc.map(|arc| Arc {
            r1: p.world_from_wrap.transform_point(&arc.r1),
            r2: p.world_from_wrap.transform_point(&arc.r2),
            length: arc.length,
        });
        (outcome, arc)
    }

    /// The positions in the current path of the first and last active points of a range.
    fn range_in_path(&self, c: &Current, range: [i64; 2]) -> Option<(usize, usize)> {
        let n = self.points.len();
        let lo = if range[0] < 1 {
            0
        } else {
            range[0] as usize - 1
        };
        let hi = if range[1] < 1 {
            n - 1
        } else {
            range[1] as usize - 1
        };
        let first = (lo..=hi.min(n - 1)).find(|&j| self.points[j].1)?;
        let last = (lo..=hi.min(n - 1)).rev().find(|&j| self.points[j].1)?;
        let pos = |j: usize| c.path.iter().position(|e| *e == Elem::Point(j));
        Some((pos(first)?, pos(last)?))
    }

    /// One path wrap applied to the current path (its old tangent points removed first);
    /// `None` when its range has no active point (OpenSim then stops wrapping).
    fn apply(&self, c: &mut Current, w: usize) -> Option<Outcome> {
        if let Some(k) = c.path.iter().position(|e| *e == Elem::First(w)) {
            c.path.drain(k..k + 2);
        }
        c.arcs[w] = None;
        if !self.wraps[w].active {
            return Some(Outcome::NoWrap);
        }
        let (start, end) = self.range_in_path(c, self.wraps[w].range)?;
        let mut outcome = Outcome::NoWrap;
        let mut best: Option<(Arc, usize)> = None;
        let mut least = f64::INFINITY;
        for k in start..end {
            let (a, b) = (c.path[k], c.path[k + 1]);
            if self.object(a).is_some() && self.object(a) == self.object(b) {
                continue;
            }
            let (o, arc) = self.wrap_segment(c, w, a, b);
            outcome = o;
            match (o, arc) {
                (Outcome::Mandatory, Some(arc)) => {
                    best = Some((arc, k + 1));
                    break;
                }
                (Outcome::Wrapped, Some(arc)) => {
                    let (pa, pb) = (self.ground(c, a), self.ground(c, b));
                    let change =
                        (pa - arc.r1).norm() + arc.length + (pb - arc.r2).norm() - (pa - pb).norm();
                    if change < least {
                        least = change;
                        best = Some((arc, k + 1));
                    }
                }
                _ => {}
            }
        }
        if let Some((arc, at)) = best {
            c.arcs[w] = Some((arc.r1, arc.r2, arc.length));
            c.path.insert(at, Elem::First(w));
            c.path.insert(at + 1, Elem::Second(w));
        }
        Some(outcome)
    }

    /// The path length (module docs).
    fn path_length(&self) -> f64 {
        let n = self.wraps.len();
        let mut c = Current {
            path: (0..self.points.len())
                .filter(|&i| self.points[i].1)
                .map(Elem::Point)
                .collect(),
            arcs: vec![None; n],
            seen: vec![[None; 2]; n],
        };
        let mut order: Vec<usize> = (0..n).collect();
        let mut outcomes = vec![Outcome::NoWrap; n];
        let mut last = f64::INFINITY;
        for pass in 0..(if n < 2 { 1 } else { 8 }) {
            for i in 0..n {
                match self.apply(&mut c, order[i]) {
                    Some(o) => outcomes[i] = o,
                    None => return self.length(&mut c),
                }
            }
            let length = self.length(&mut c);
            if (length - last).abs() < 0.0005 {
                break;
            }
            last = length;
            if pass == 0
                && n > 1
                && outcomes[0] == Outcome::NoWrap
                && outcomes[1] == Outcome::InsideRadius
            {
                order.swap(0, 1);
                if let Some(k) = c.path.iter().position(|e| *e == Elem::First(0)) {
                    c.path.drain(k..k + 2);
                }
            }
        }
        self.length(&mut c)
    }
}

/// The model at its default pose, before or after scaling.
struct Posed<'a> {
    model: &'a Model,
    data: KinData,
    factors: Option<&'a ScaleFactors>,
}

impl Posed<'_> {
    fn factor(&self, body: &Option<String>) -> [f64; 3] {
        match (self.factors, body) {
            (Some(f), Some(b)) => f.get(b).copied().unwrap_or([1.0; 3]),
            _ => [1.0; 3],
        }
    }

    fn point(&self, p: &Point) -> (V, bool) {
        let s = self.factor(&p.body);
        let mut loc = p.location;
        let moving = p.moving.iter().any(|m| *m);
        for k in 0..3 {
            // A moving point's coordinate-driven axis is scaled through its multiplier,
            // a fixed axis is not scaled (OpenSim scales only driven axes).
            if p.moving[k] || !moving {
                loc[k] *= s[k];
            }
        }
        let pose = body_pose(self.model, &self.data, &p.body);
        (pose.transform_point(&V::from(loc)), p.active)
    }

    fn wrap(&self, object: usize, o: &WrapObject, range: [i64; 2]) -> Placed {
        let s = self.factor(&o.body);
        let l = frame_stretch(o.rotation, s);
        let cylinder = o.cylinder.map(|c| Cylinder {
            radius: c.radius * (l[0] + l[1]) * 0.5,
            length: c.length * l[2],
            ..c
        });
        let r = o.rotation;
        let offset = Pose {
            rot: offset_rotation(r[0], r[1], r[2]),
            trans: V::from(super::mul(o.translation, s)),
        };
        Placed {
            object,
            world_from_wrap: body_pose(self.model, &self.data, &o.body) * offset,
            cylinder,
            active: o.active,
            range,
        }
    }
}

/// A path's wraps: (object name, range).
fn path_wraps(path: Node) -> Vec<(String, [i64; 2])> {
    let Some(objs) = child(path, "PathWrapSet").and_then(|s| child(s, "objects")) else {
        return Vec::new();
    };
    elements(objs)
        .filter_map(|w| {
            let object = text(w, "wrap_object")?.to_string();
            let range = match numbers(w, "range").ok().as_deref() {
                Some([a, b]) => [*a as i64, *b as i64],
                _ => [-1, -1],
            };
            Some((object, range))
        })
        .collect()
}

/// `(name, ℓ'/ℓ)` of every component with a geometry path whose points all rest on bodies or
/// ground and whose default length is positive.
pub(super) fn length_ratios(
    osim: &OsimModel,
    doc: &Document,
    factors: &ScaleFactors,
) -> Result<Vec<(String, f64)>, String> {
    Ok(lengths(osim, doc, factors)?
        .into_iter()
        .filter(|(_, l)| l[0] > 0.0)
        .map(|(n, l)| (n, l[1] / l[0]))
        .collect())
}

/// `(name, [ℓ, ℓ'])`: every geometry path's length at the default pose before and after
/// scaling by `factors` (paths with points on other frames are left out).
pub(super) fn lengths(
    osim: &OsimModel,
    doc: &Document,
    factors: &ScaleFactors,
) -> Result<Vec<(String, [f64; 2])>, String> {
    let before = Model::compile(&osim.spec).map_err(|e| e.to_string())?;
    let after = Model::compile(&scaled_spec(&osim.spec, factors)).map_err(|e| e.to_string())?;
    let (d0, values) = default_pose(&before);
    let (d1, _) = default_pose(&after);
    let posed = [
        Posed {
            model: &before,
            data: d0,
            factors: None,
        },
        Posed {
            model: &after,
            data: d1,
            factors: Some(factors),
        },
    ];
    let bodies: Vec<String> = osim.spec.segments.iter().map(|s| s.name.clone()).collect();
    let objects = wrap_objects(doc, &bodies)?;
    let index: HashMap<&str, usize> = objects
        .keys()
        .enumerate()
        .map(|(i, k)| (k.as_str(), i))
        .collect();
    let mut out = Vec::new();
    for n in doc.descendants().filter(|n| n.is_element()) {
        let path = child(n, "GeometryPath")
            .or_else(|| child(n, "path").and_then(|p| child(p, "GeometryPath")));
        let Some(path) = path else {
            continue;
        };
        let Some(objs) = child(path, "PathPointSet").and_then(|s| child(s, "objects")) else {
            continue;
        };
        let raw: Vec<Node> = elements(objs).collect();
        let points: Vec<Point> = raw
            .iter()
            .filter_map(|p| point(*p, &bodies, &values))
            .collect();
        let on_frames = raw.iter().all(|p| {
            text(*p, "socket_parent_frame").is_some_and(|f| {
                let leaf = path_leaf(f);
                bodies.iter().any(|b| b == leaf) || leaf == "ground"
            })
        });
        if !on_frames || points.len() != raw.len() || points.iter().filter(|p| p.active).count() < 2
        {
            continue;
        }
        let wraps: Vec<(usize, &WrapObject, [i64; 2])> = path_wraps(path)
            .into_iter()
            .filter_map(|(o, range)| {
                let object = objects.get(&o)?;
                Some((index[o.as_str()], object, range))
            })
            .collect();
        let l = [&posed[0], &posed[1]].map(|p| {
            let at: Vec<(V, bool)> = points.iter().map(|x| p.point(x)).collect();
            let placed: Vec<Placed> = wraps.iter().map(|(i, o, r)| p.wrap(*i, o, *r)).collect();
            Geometry {
                points: &at,
                wraps: &placed,
            }
            .path_length()
        });
        out.push((name(n).to_string(), l));
    }
    Ok(out)
}
