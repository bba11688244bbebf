//! Muscle–tendon path lengths at the default pose, before and after scaling: the polyline
//! through a path's active points (module docs of [`super`]).

use std::collections::HashMap;

use jointfit::kinematics::{forward_kinematics, KinData, Pose, Want};
use jointfit::model::functions::Function;
use jointfit::model::Model;
use jointfit::scale::{scaled_spec, ScaleFactors};
use nalgebra::Vector3;
use roxmltree::{Document, Node};

use crate::osim_read::functions::function_in;
use crate::osim_read::xml::{child, elements, name, numbers, path_leaf, text};
use crate::osim_read::OsimModel;

/// One path point as the default pose sees it.
struct Point {
    body: Option<String>,
    /// Location in the body (m) before scaling.
    location: [f64; 3],
    /// Which axes are functions of a coordinate (a moving point's scaled axes).
    moving: [bool; 3],
}

fn default_pose(model: &Model) -> (KinData, HashMap<String, f64>) {
    let mut data = KinData::new(model);
    let q = model.default_coords();
    forward_kinematics(
        model,
        &model.nominal_params(),
        &q,
        Want::POSITIONS,
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
            if range.len() != 2 || q < range[0] || q > range[1] {
                return None;
            }
        }
        "MovingPathPoint" => {
            let mut location = [0.0; 3];
            let mut moving = [false; 3];
            for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                let holder = child(p, &format!("{axis}_location"))?;
                let f = Function::new(&function_in(holder, &[]).ok()?).ok()?;
                let q = coordinate(&format!("socket_{axis}_coordinate"));
                moving[k] = q.is_some();
                location[k] = f.value(q.unwrap_or(0.0));
            }
            return Some(Point {
                body,
                location,
                moving,
            });
        }
        _ => return None,
    }
    let v = numbers(p, "location").ok()?;
    Some(Point {
        body,
        location: [*v.first()?, *v.get(1)?, *v.get(2)?],
        moving: [false; 3],
    })
}

fn world(model: &Model, data: &KinData, body: &Option<String>, loc: [f64; 3]) -> Vector3<f64> {
    let pose = body
        .as_ref()
        .and_then(|b| model.segment_id(b))
        .map_or(Pose::identity(), |id| data.segment_poses[id.0]);
    pose.transform_point(&Vector3::from(loc))
}

/// `(name, ℓ'/ℓ)` of every component with a geometry path whose points all rest on bodies or
/// ground and whose default length is positive.
pub(super) fn length_ratios(
    osim: &OsimModel,
    doc: &Document,
    factors: &ScaleFactors,
) -> Result<Vec<(String, f64)>, String> {
    let before = Model::compile(&osim.spec).map_err(|e| e.to_string())?;
    let after = Model::compile(&scaled_spec(&osim.spec, factors)).map_err(|e| e.to_string())?;
    let (d0, values) = default_pose(&before);
    let (d1, _) = default_pose(&after);
    let bodies: Vec<String> = osim.spec.segments.iter().map(|s| s.name.clone()).collect();
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
        if !on_frames || points.len() < 2 {
            continue;
        }
        let (mut l0, mut l1) = (0.0, 0.0);
        let mut prev: Option<(Vector3<f64>, Vector3<f64>)> = None;
        for p in &points {
            let s = p
                .body
                .as_ref()
                .and_then(|b| factors.get(b))
                .copied()
                .unwrap_or([1.0; 3]);
            let mut scaled = p.location;
            for k in 0..3 {
                // A moving point's coordinate-driven axis is scaled through its multiplier,
                // a fixed axis is not scaled (OpenSim scales only driven axes).
                if p.moving[k] || !is_moving(p) {
                    scaled[k] *= s[k];
                }
            }
            let a = world(&before, &d0, &p.body, p.location);
            let b = world(&after, &d1, &p.body, scaled);
            if let Some((pa, pb)) = prev {
                l0 += (a - pa).norm();
                l1 += (b - pb).norm();
            }
            prev = Some((a, b));
        }
        if l0 > 0.0 {
            out.push((name(n).to_string(), l1 / l0));
        }
    }
    Ok(out)
}

fn is_moving(p: &Point) -> bool {
    p.moving.iter().any(|m| *m)
}
