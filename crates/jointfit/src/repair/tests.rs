//! Repairs against synthetic truth: rigid segments moving smoothly, with seeded gaps and
//! label swaps.

use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::ik::MarkerMap;
use crate::model::lower_limb::{lower_limb, Side};

const FRAMES: usize = 200;
const RATE: f64 = 100.0;

/// The built-in right leg's markers, each segment moving as a rigid body (its own smooth
/// rotation and translation), so every segment keeps the model's inter-marker distances.
fn truth() -> (Model, Trial) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let labels: Vec<String> = model.markers().iter().map(|m| m.name.clone()).collect();
    let mut positions = Vec::new();
    for f in 0..FRAMES {
        let t = f as f64 / RATE;
        for m in model.markers() {
            let s = m.segment.0 as f64;
            let rot = Rotation3::from_euler_angles(
                0.3 * (2.0 * t + s).sin(),
                0.2 * (1.3 * t + 0.5 * s).cos(),
                0.6 * (1.1 * t + s).sin(),
            );
            let centre = Vector3::new(1.2 * t, 0.9 - 0.25 * s + 0.02 * (6.0 * t).sin(), 0.1 * s);
            positions.push(rot * m.local + centre);
        }
    }
    (model, Trial::new(labels, RATE, 1, positions).unwrap())
}

fn max_error(a: &Trial, b: &Trial) -> f64 {
    a.positions()
        .iter()
        .zip(b.positions())
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

#[test]
fn swap_arguments() {
    let s = "RTHI,RTHP@750".parse::<Swap>().unwrap();
    assert_eq!((s.from, s.to), (Some(750), None));
    assert_eq!(s.to_arg(), "RTHI,RTHP@750");
    let s = "A, B@10-20".parse::<Swap>().unwrap();
    assert_eq!(
        (s.a.as_str(), s.b.as_str(), s.from, s.to),
        ("A", "B", Some(10), Some(20))
    );
    assert_eq!("A,B".parse::<Swap>().unwrap().to_arg(), "A,B");
    for bad in ["A", "A,A", "A,B@x", "A,B@20-10", ",B"] {
        assert!(bad.parse::<Swap>().is_err(), "{bad}");
    }
}

/// Seeded gaps of up to 10 frames in thigh and shank markers: the rigid fill gives the truth
/// back (to rounding: each side's prediction is exact for rigid motion).
#[test]
fn rigid_fill_recovers_seeded_gaps() {
    let (model, truth) = truth();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut gappy = truth.clone();
    let n = gappy.labels().len();
    let mut seeded = 0;
    // Disjoint windows of 15 frames, so a segment always keeps three markers.
    for (k, name) in ["RTHI", "RKNE", "RTIB", "RANK"].iter().enumerate() {
        let j = truth.index_of(name).unwrap();
        for i in 0..3 {
            let start = 5 + 15 * (3 * k + i) + rng.gen_range(0..5);
            let len = rng.gen_range(1..=10);
            for f in start..start + len {
                gappy.positions_mut()[f * n + j] = Vector3::repeat(f64::NAN);
            }
            seeded += len;
        }
    }
    let opts = RepairOptions {
        fill_gaps: 10,
        ..RepairOptions::default()
    };
    let (filled, actions) = repair(&gappy, Some(&model), &opts).unwrap();
    assert!(seeded > 0);
    assert!(
        max_error(&filled, &truth) < 1e-9,
        "{}",
        max_error(&filled, &truth)
    );
    assert!(actions.iter().all(|a| matches!(
        a,
        Action::Filled {
            method: FillMethod::Rigid,
            ..
        }
    )));
    assert!(
        actions[0].to_string().contains("rigid-body fill"),
        "{}",
        actions[0]
    );
    // A limit below the longest gap leaves it, and says so.
    let short = RepairOptions {
        fill_gaps: 1,
        ..RepairOptions::default()
    };
    let (_, actions) = repair(&gappy, Some(&model), &short).unwrap();
    assert!(actions
        .iter()
        .any(|a| matches!(a, Action::LeftUnfilled { .. })));
}

/// Without a model (no segment mates), short gaps are bridged by the cubic spline: a smooth
/// trajectory comes back within a fraction of a millimetre.
#[test]
fn spline_fill_bridges_short_gaps() {
    let (_, truth) = truth();
    let mut gappy = truth.clone();
    let n = gappy.labels().len();
    let j = truth.index_of("RHEE").unwrap();
    for f in 100..104 {
        gappy.positions_mut()[f * n + j] = Vector3::repeat(f64::NAN);
    }
    let opts = RepairOptions {
        fill_gaps: 5,
        ..RepairOptions::default()
    };
    let (filled, actions) = repair(&gappy, None, &opts).unwrap();
    let err = max_error(&filled, &truth);
    assert!(err < 5e-4, "spline error {err} m");
    assert_eq!(
        actions,
        vec![Action::Filled {
            marker: "RHEE".into(),
            method: FillMethod::Spline,
            gaps: 1,
            frames: 4
        }]
    );
}

/// Labels swapped from frame 50 on: the check reports the swap and suggests the option that
/// undoes it; applying that option gives the truth back.
#[test]
fn swap_found_by_checks_is_undone() {
    let (model, truth) = truth();
    let (a, b) = (
        truth.index_of("RTHI").unwrap(),
        truth.index_of("RTHP").unwrap(),
    );
    let mut swapped = truth.clone();
    let n = swapped.labels().len();
    for f in 49..FRAMES {
        swapped.positions_mut().swap(f * n + a, f * n + b);
    }
    let (map, _) = MarkerMap::allowing_absent(&model, swapped.labels());
    let findings = crate::checks::check_trial(&model, &swapped, &map);
    let swap = findings
        .iter()
        .find(|f| f.kind == crate::checks::CheckKind::Swap)
        .expect("swap found");
    let fix = swap.fix.clone().expect("a fix is suggested");
    assert_eq!(fix, "--swap-labels RTHI,RTHP@50");
    let opts = RepairOptions {
        swaps: vec![fix
            .trim_start_matches("--swap-labels ")
            .parse::<Swap>()
            .unwrap()],
        ..RepairOptions::default()
    };
    let (fixed, actions) = repair(&swapped, Some(&model), &opts).unwrap();
    assert_eq!(max_error(&fixed, &truth), 0.0);
    assert_eq!(
        actions[0].to_string(),
        "swapped labels RTHI and RTHP in frames 50–200"
    );
    let (map, _) = MarkerMap::allowing_absent(&model, fixed.labels());
    assert!(crate::checks::check_trial(&model, &fixed, &map)
        .iter()
        .all(|f| f.kind != crate::checks::CheckKind::Swap));
}

#[test]
fn exclusion_and_errors() {
    let (model, truth) = truth();
    let opts = RepairOptions {
        exclude: vec!["RTHP".into()],
        ..RepairOptions::default()
    };
    let (out, actions) = repair(&truth, Some(&model), &opts).unwrap();
    assert_eq!(out.labels().len(), truth.labels().len() - 1);
    assert!(out.index_of("RTHP").is_err());
    assert_eq!(actions[0].to_string(), "excluded marker RTHP");
    let bad = RepairOptions {
        exclude: vec!["NOPE".into()],
        ..RepairOptions::default()
    };
    let e = repair(&truth, None, &bad).unwrap_err().to_string();
    assert!(
        e.starts_with("--exclude-marker names marker \"NOPE\", which the trial lacks"),
        "{e}"
    );
    let late = RepairOptions {
        swaps: vec!["RTHI,RTHP@900".parse::<Swap>().unwrap()],
        ..RepairOptions::default()
    };
    let e = repair(&truth, None, &late).unwrap_err().to_string();
    assert!(e.contains("outside the trial (frames 1–200)"), "{e}");
}
