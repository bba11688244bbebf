//! [`jointfit_io::osim_scale`] against OpenSim 4.6's own `Model::scale` (preserve mass
//! distribution, a given total mass) for the same per-body factors, non-uniform on every
//! body: both files loaded by OpenSim, and every quantity scaling changes compared (bodies'
//! masses, mass centres, inertias; body origins at the default pose, which carry the joint
//! offset frames and the scaled translation functions; offset frame translations; markers;
//! muscle path points at the default pose; wrap objects; optimal fibre and tendon slack
//! lengths, which follow the path length over wrap cylinders). Everything must agree to
//! round-off.

use std::collections::BTreeMap;
use std::path::Path;

use jointfit_io::osim_read::read_osim;
use jointfit_io::osim_scale::{path_lengths, scale_osim, ScaleOptions};
use jointfit_scale::geometry::ScaleFactors;
use jointfit_testkit::script::Script;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

/// OpenSim writes `opensim.log` into the working directory: the scratch one.
fn dump(python: &Path, model: &Path, cwd: &Path) -> Value {
    Script::new(python, "osim_scale_check.py")
        .args(&["dump", &model.to_string_lossy()])
        .current_dir(cwd)
        .run_json()
}

fn triples(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// Largest difference over the keys of two `{name: [numbers]}` maps (and the key sets agree).
fn max_diff(a: &Value, b: &Value, field: Option<&str>) -> f64 {
    let (a, b) = (a.as_object().unwrap(), b.as_object().unwrap());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "same components"
    );
    let mut worst: f64 = 0.0;
    for (k, va) in a {
        let (va, vb) = match field {
            Some(f) => (&va[f], &b[k][f]),
            None => (va, &b[k]),
        };
        let (xa, xb) = match va {
            Value::Number(_) => (vec![va.as_f64().unwrap()], vec![vb.as_f64().unwrap()]),
            _ => (triples(va), triples(vb)),
        };
        for (x, y) in xa.iter().zip(&xb) {
            worst = worst.max((x - y).abs() / x.abs().max(y.abs()).max(1.0));
        }
    }
    worst
}

/// The generic model scaled by jointfit and by OpenSim with the same random factors, both
/// dumped by OpenSim: `(ours, OpenSim's)`; `None` without Python or data.
fn scaled_pair(relative: &str, seed: u64, mass: f64, scale_masses: bool) -> Option<(Value, Value)> {
    let (Some(python), Some(generic)) = (
        jointfit_testkit::python(),
        jointfit_testkit::data_file(relative),
    ) else {
        println!("skipped: no $JOINTFIT_PYTHON or data");
        return None;
    };
    let dir = jointfit_testkit::scratch::scratch("osim_scale");
    let osim = read_osim(&generic).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut factors = ScaleFactors::new();
    for s in &osim.spec.segments {
        let f: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.85..1.2));
        factors.insert(s.name.clone(), f);
    }
    let ours = scale_osim(
        &osim,
        &generic,
        &factors,
        &ScaleOptions {
            total_mass: Some(mass),
            markers: vec![],
            scale_masses,
        },
    )
    .unwrap();
    let mine = dir.path().join("ours.osim");
    std::fs::write(&mine, &ours.text).unwrap();
    let theirs = dir.path().join("opensim.osim");
    let json: BTreeMap<&str, [f64; 3]> = factors.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let fpath = dir.path().join("factors.json");
    std::fs::write(&fpath, serde_json::to_string(&json).unwrap()).unwrap();
    Script::new(&python, "osim_scale_check.py")
        .args(&[
            "scale",
            &generic.to_string_lossy(),
            &fpath.to_string_lossy(),
            &mass.to_string(),
            &theirs.to_string_lossy(),
            if scale_masses { "grow" } else { "keep" },
        ])
        .current_dir(dir.path())
        .run_json();
    Some((
        dump(&python, &mine, dir.path()),
        dump(&python, &theirs, dir.path()),
    ))
}

/// Every scaled quantity but the muscle lengths: equal to round-off. Returns report lines.
fn compare_geometry(relative: &str, a: &Value, b: &Value) -> Vec<String> {
    let mut report = Vec::new();
    for (what, key, field) in [
        ("mass", "bodies", Some("mass")),
        ("mass centre", "bodies", Some("mass_center")),
        ("inertia", "bodies", Some("inertia")),
        ("body origin at the default pose", "origins", None),
        ("offset frame translation", "frames", None),
        ("marker location", "markers", None),
        ("path point at the default pose", "points", None),
        ("wrap object translation", "wraps", Some("translation")),
        ("wrap object size", "wraps", Some("size")),
    ] {
        if a[key].as_object().unwrap().is_empty() {
            continue;
        }
        let d = max_diff(&a[key], &b[key], field);
        report.push(format!("{what}: {d:.1e}"));
        assert!(d <= 1e-12, "{relative}: {what} differs by {d:e}");
    }
    report
}

/// Largest relative difference of the optimal fibre and tendon slack lengths over the
/// muscles with (`wrapped`) or without wrap objects, and the muscle where it occurs.
fn worst_muscle(a: &Value, b: &Value, wrapped: bool) -> (f64, String) {
    let (ma, mb) = (
        a["muscles"].as_object().unwrap(),
        b["muscles"].as_object().unwrap(),
    );
    let mut worst = (0.0, String::new());
    for (name, x) in ma {
        if (x["wraps"].as_u64().unwrap() > 0) != wrapped {
            continue;
        }
        let y = &mb[name];
        for f in ["optimal_fiber_length", "tendon_slack_length"] {
            let (u, v) = (x[f].as_f64().unwrap(), y[f].as_f64().unwrap());
            let rel = (u - v).abs() / v.abs();
            if rel > worst.0 {
                worst = (rel, format!("{name} {f}"));
            }
        }
    }
    worst
}

fn check_model(relative: &str, seed: u64, mass: f64, scale_masses: bool) {
    let Some((a, b)) = scaled_pair(relative, seed, mass, scale_masses) else {
        return;
    };
    let mut report = compare_geometry(relative, &a, &b);
    let (plain, at) = worst_muscle(&a, &b, false);
    let (wrapped, wat) = worst_muscle(&a, &b, true);
    report.push(format!(
        "fibre/tendon length, unwrapped muscles: {plain:.1e} ({at}), wrapped: {wrapped:.1e} ({wat}) (relative)"
    ));
    println!("{relative}:\n  {}", report.join("\n  "));
    assert!(
        plain <= 1e-9,
        "{relative}: unwrapped muscle lengths differ by {plain:e} ({at})"
    );
    assert!(
        wrapped <= 1e-12,
        "{relative}: wrapped muscle lengths differ by {wrapped:e} ({wat})"
    );
}

#[test]
fn gait2392_scaled_as_opensim_scales_it() {
    check_model(
        "opensim_gait2392_subject01/gait2392_thelen2003muscle.osim",
        7,
        81.5,
        false,
    );
}

/// `preserve_mass_distribution` false: masses grow with the product of the factors first.
#[test]
fn gait2392_with_masses_scaled_by_volume_as_opensim_scales_it() {
    check_model(
        "opensim_gait2392_subject01/gait2392_thelen2003muscle.osim",
        5,
        70.0,
        true,
    );
}

#[test]
fn opencap_lai_uhlrich_scaled_as_opensim_scales_it() {
    check_model("opencap_expert1/generic.osim", 11, 64.0, false);
}

/// Every muscle's path length at the default pose (wrapping over cylinders) against
/// OpenSim's `GeometryPath::getLength`, on the generic model.
#[test]
fn path_lengths_at_the_default_pose_are_opensims() {
    let relative = "opencap_expert1/generic.osim";
    let (Some(python), Some(generic)) = (
        jointfit_testkit::python(),
        jointfit_testkit::data_file(relative),
    ) else {
        println!("skipped: no $JOINTFIT_PYTHON or data");
        return;
    };
    let dir = jointfit_testkit::scratch::scratch("osim_scale");
    let theirs = dump(&python, &generic, dir.path());
    let osim = read_osim(&generic).unwrap();
    let ours = path_lengths(&osim, &generic, &ScaleFactors::new()).unwrap();
    let mut worst = (0.0, String::new());
    let mut rows = Vec::new();
    for (name, l) in &ours {
        let Some(m) = theirs["muscles"].get(name) else {
            continue;
        };
        let v = m["length"].as_f64().unwrap();
        let rel = (l[0] - v).abs() / v;
        if rel > 1e-6 {
            rows.push(format!(
                "{name}: {:.6} vs {v:.6} ({} wraps)",
                l[0], m["wraps"]
            ));
        }
        if rel > worst.0 {
            worst = (rel, name.clone());
        }
    }
    println!("{}", rows.join("\n"));
    println!(
        "worst path length difference: {:.1e} ({})",
        worst.0, worst.1
    );
    assert!(ours.len() >= 80);
    assert!(worst.0 <= 1e-12, "{worst:?}");
}
