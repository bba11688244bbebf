//! Which Euler-angle branch `jointfit ik` reports.
//!
//! OpenCap's unscaled `generic.osim` on walking1: the warm-started chain reached the left
//! hip's other branch of the same rotation (flexion −108°, adduction −209°, rotation −229°
//! in frame 0 where the in-range branch is 71.6°, 29.0°, −48.7°). The `.mot` must hold, for
//! every Euler triple of the model (the three rotational coordinates of a joint that has
//! three, in order: OpenSim's `rotation1..3`) and every frame, the branch no farther outside
//! the model's coordinate ranges than the other, and every rotational coordinate within half a
//! turn of its range. Every coordinate of `generic.osim` is `clamped`, and jointfit's IK now keeps them in
//! their ranges as OpenSim's does, so the branch rule has nothing left to move here; the
//! agreement with OpenSim's coordinates is asserted in `osim_clamped` (this model) and
//! `osim_ik` (the hand-scaled one).

use std::f64::consts::PI;

use jointfit::model::{CoordKind, Model};
use jointfit_io::sto::read_sto;

use super::jointfit;

#[test]
fn generic_osim_left_hip_in_range_branch() {
    let (Some(model_path), Some(trial)) = (
        jointfit_testkit::data_file("opencap_expert1/generic.osim"),
        jointfit_testkit::data_file("opencap_expert1/walking1.trc"),
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("ik-branch-generic");
    let mot = dir.join("generic.mot");
    let (ok, _, err) = jointfit(&[
        "ik",
        model_path.to_str().unwrap(),
        trial.to_str().unwrap(),
        "-o",
        mot.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let model = jointfit_io::model_file::load_model(model_path.to_str().unwrap()).unwrap();
    let table = read_sto(&mot).unwrap();
    assert!(table.in_degrees);
    let column = |name: &str| table.columns.iter().position(|c| c == name).unwrap();
    let cols: Vec<usize> = model
        .coordinates()
        .iter()
        .map(|c| column(&c.name))
        .collect();
    let rotational: Vec<bool> = model
        .coordinates()
        .iter()
        .map(|c| c.kind == jointfit::model::CoordKind::Rotational)
        .collect();
    let name = |c: usize| model.coordinates()[c].name.clone();
    let triples = euler_triples(&model);
    let hip_l = ["hip_flexion_l", "hip_adduction_l", "hip_rotation_l"];
    assert!(
        triples.iter().any(|t| t.map(name) == hip_l),
        "the left hip is a triple"
    );
    let outside = |c: usize, v: f64| {
        let [lo, hi] = model.coordinates()[c].range;
        (lo - v).max(v - hi).max(0.0)
    };
    // Total distance outside the ranges of a triple's values, each moved by whole turns to
    // the nearest it can get.
    let triple_outside = |t: &[usize; 3], v: [f64; 3]| -> f64 {
        t.iter()
            .zip(v)
            .map(|(&c, x)| {
                (-3..=3)
                    .map(|n| outside(c, x + n as f64 * 2.0 * PI))
                    .fold(f64::INFINITY, f64::min)
            })
            .sum()
    };
    let mut solved = 0;
    for (f, row) in table.rows.iter().enumerate() {
        let q: Vec<f64> = cols
            .iter()
            .zip(&rotational)
            .map(|(&i, &rot)| if rot { row[i].to_radians() } else { row[i] })
            .collect();
        if q.iter().any(|v| v.is_nan()) {
            continue;
        }
        solved += 1;
        for t in &triples {
            let v = t.map(|c| q[c]);
            let other = [v[0] + PI, PI - v[1], v[2] + PI];
            let (mine, theirs) = (triple_outside(t, v), triple_outside(t, other));
            assert!(
                mine <= theirs + 1e-9,
                "frame {f} {:?}: {:?}° is {mine:.3} rad outside the ranges, the other branch \
                 {:?}° {theirs:.3}",
                t.map(name),
                v.map(f64::to_degrees),
                other.map(f64::to_degrees)
            );
        }
        for (c, &v) in q.iter().enumerate() {
            if rotational[c] {
                let [lo, hi] = model.coordinates()[c].range;
                assert!(
                    v >= lo - PI && v <= hi + PI,
                    "frame {f} {}: {}° within half a turn of its range",
                    name(c),
                    v.to_degrees()
                );
            }
        }
        let hip = hip_l.map(|n| q[model.coord_id(n).unwrap()].to_degrees());
        assert!(
            hip[1].abs() < 90.0,
            "frame {f}: left hip {hip:?}°, adduction on the in-range branch"
        );
    }
    assert!(solved >= 140, "{solved} of {} frames", table.rows.len());
}

/// The Euler triples of `model`: the rotational coordinates of every joint that has exactly
/// three, in coordinate order (OpenSim's `rotation1..3` of a hip, the pelvis, the lumbar
/// joint).
pub(crate) fn euler_triples(model: &Model) -> Vec<[usize; 3]> {
    (0..model.joints().len())
        .filter_map(|j| {
            let rotations: Vec<usize> = (0..model.coordinates().len())
                .filter(|&c| {
                    let coord = &model.coordinates()[c];
                    coord.joint == j && coord.kind == CoordKind::Rotational
                })
                .collect();
            <[usize; 3]>::try_from(rotations).ok()
        })
        .collect()
}
