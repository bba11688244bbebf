//! OpenSim's `clamped` coordinates: `jointfit ik` keeps every
//! coordinate a model marks `<clamped>true</clamped>` inside its range, as OpenSim's IK does,
//! and OpenSim 4.6's IK is the oracle. On OpenCap's unscaled `generic.osim` (every coordinate
//! clamped, about 95 mm RMS) with walking1 the bounded least squares has several local
//! minima; the assertions are therefore:
//!
//! * every clamped coordinate of jointfit's `.mot` inside its range in every frame;
//! * in the frames where both programs reach the same fit (frame RMS within 0.01 mm, judged
//!   by OpenSim; at least 20 such frames, the first 23 on this trial), the coordinates agree
//!   within 2° (2 mm for translations): within 0.04° in frames 0–21, 1.05° (pelvis tilt) in
//!   frame 22, where the fits differ by 1.5e-4 mm RMS: a flat valley where the two
//!   warm-start chains part;
//! * OpenSim's pose is a minimum of jointfit's bounded problem too: each frame solved by
//!   jointfit's IK from OpenSim's coordinates stays there within 0.1° / 0.1 mm, in every
//!   frame. Where the programs differ (frames 22 on), the difference is which minimum the
//!   warm-start chain tracks, and jointfit's has the lower RMS (`osim_ik`: no frame worse).

use std::path::Path;

use jointfit::ik::lm::IkWorkspace;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::model::{CoordKind, Model};
use jointfit_io::sto::{read_sto, Table};

/// The coordinates (rad or m, model order) of every row of a `.mot` in degrees.
fn coordinates(model: &Model, table: &Table) -> Vec<Vec<f64>> {
    assert!(table.in_degrees);
    let cols: Vec<usize> = model
        .coordinates()
        .iter()
        .map(|c| table.column_index(&c.name).expect("column"))
        .collect();
    table
        .rows
        .iter()
        .map(|row| {
            cols.iter()
                .zip(model.coordinates())
                .map(|(&k, c)| match c.kind {
                    CoordKind::Rotational => row[k].to_radians(),
                    CoordKind::Translational => row[k],
                })
                .collect()
        })
        .collect()
}

/// Difference in degrees (rotations) or mm (translations).
fn gap(model: &Model, c: usize, a: f64, b: f64) -> f64 {
    match model.coordinates()[c].kind {
        CoordKind::Rotational => (a - b).abs().to_degrees(),
        CoordKind::Translational => 1e3 * (a - b).abs(),
    }
}

/// `dir` holds `jointfit.mot` and `opensim_ik.mot` of `model` on `trial`; `same_fit[f]`: the
/// two frame RMS within 0.01 mm (judged by OpenSim).
pub(super) fn clamped_agree(model_path: &Path, trial_path: &Path, dir: &Path, same_fit: &[bool]) {
    let model = jointfit_io::model_file::load_model(model_path.to_str().unwrap()).unwrap();
    let clamped: Vec<usize> = (0..model.coordinates().len())
        .filter(|&c| model.coordinates()[c].clamped)
        .collect();
    assert!(!clamped.is_empty(), "the model has clamped coordinates");
    let ours = coordinates(&model, &read_sto(&dir.join("jointfit.mot")).unwrap());
    let theirs = coordinates(&model, &read_sto(&dir.join("opensim_ik.mot")).unwrap());
    assert_eq!(ours.len(), theirs.len());
    // The .mot holds 8 significant digits: a bound written in degrees reads back within 1e-9.
    for (f, q) in ours.iter().enumerate() {
        for &c in &clamped {
            let [lo, hi] = model.coordinates()[c].range;
            let name = &model.coordinates()[c].name;
            assert!(
                q[c] >= lo - 1e-9 && q[c] <= hi + 1e-9,
                "frame {f} {name} = {} outside its clamped range [{lo}, {hi}]",
                q[c]
            );
        }
    }
    // No marker of the trial determines the toes: jointfit holds them at the default,
    // OpenSim's IK leaves them where its assembler put them.
    let trial = jointfit_io::trial_file::read_trial(trial_path).unwrap();
    let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
    let p = model.nominal_params();
    let mut ws = IkWorkspace::new(&model);
    let opts = IkOptions {
        hold_undetermined: true,
        outlier_distance: f64::INFINITY,
        ..IkOptions::default()
    };
    let undetermined: Vec<usize> = (0..model.coordinates().len())
        .filter(|&c| model.coordinates()[c].name.starts_with("mtp_angle"))
        .collect();
    let mut shared = 0;
    let (mut worst_shared, mut worst_restart) = ((0.0f64, String::new()), (0.0f64, String::new()));
    for f in 0..ours.len() {
        // Model-ordered targets: the column `map` pairs with each model marker, NaN where
        // the trial lacks it.
        let row = trial.frame(f);
        let targets: Vec<nalgebra::Vector3<f64>> = map
            .columns
            .iter()
            .map(|c| c.map_or(nalgebra::Vector3::repeat(f64::NAN), |c| row[c]))
            .collect();
        let mut q = theirs[f].clone();
        let fit = ws.solve(&model, &p, &targets, &mut q, &opts);
        assert!(fit.solved(), "frame {f}: {:?}", fit.status);
        for c in (0..model.coordinates().len()).filter(|c| !undetermined.contains(c)) {
            let name = &model.coordinates()[c].name;
            let d = gap(&model, c, q[c], theirs[f][c]);
            assert!(
                d <= 0.1,
                "frame {f} {name}: from OpenSim's pose jointfit moves {:.4} → {:.4} (° or m)",
                theirs[f][c],
                q[c]
            );
            if d > worst_restart.0 {
                worst_restart = (d, format!("{name}, frame {f}"));
            }
            if same_fit[f] {
                let d = gap(&model, c, ours[f][c], theirs[f][c]);
                assert!(
                    d <= 2.0,
                    "frame {f} {name}: jointfit {:.4}, OpenSim {:.4} at the same fit",
                    ours[f][c],
                    theirs[f][c]
                );
                if d > worst_shared.0 {
                    worst_shared = (d, format!("{name}, frame {f}"));
                }
            }
        }
        shared += usize::from(same_fit[f]);
    }
    assert!(shared >= 20, "only {shared} frames at the same fit");
    eprintln!(
        "clamped: {shared} of {} frames at OpenSim's fit, coordinates within {:.4} ({}); \
         from OpenSim's poses within {:.4} ({})",
        ours.len(),
        worst_shared.0,
        worst_shared.1,
        worst_restart.0,
        worst_restart.1
    );
}
