//! `jointfit ik` on the user's own OpenSim model, judged by OpenSim: on OpenCap's scaled
//! full-body model (muscles, arms) with its walking trial, and on OpenSim's gait2392 subject01
//! with its walking trial, OpenSim evaluates jointfit's .mot and runs its own
//! InverseKinematicsTool (every marker weight 1, accuracy 1e-9); no frame of jointfit may fit
//! worse than OpenSim's by more than 0.01 mm RMS. Coordinates no marker of the trial
//! determines (the toes: no marker of the trial is on them) are held at their defaults, and
//! `ik` says so.

use std::path::Path;

use jointfit_testkit::script::osim_check;
use serde_json::{json, Value};

use super::jointfit;

/// Per frame: RMS (mm) over the markers OpenSim reports a distance for.
fn frame_rms_mm(answer: &Value) -> Vec<f64> {
    answer["errors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|row| {
            let d: Vec<f64> = row
                .as_array()
                .unwrap()
                .iter()
                .filter_map(Value::as_f64)
                .collect();
            1e3 * (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt()
        })
        .collect()
}

/// The shared `model_rel` and `trial_rel`, with `jointfit ik` and OpenSim's IK run on them
/// in scratch directory `scratch` ([`compare_files`]); `None` (the test skips) without the
/// data or the Python oracle.
struct BothRuns {
    model: std::path::PathBuf,
    trial: std::path::PathBuf,
    dir: jointfit_testkit::scratch::ScratchDir,
    /// Per-frame RMS (mm): jointfit's and OpenSim's.
    rms: (Vec<f64>, Vec<f64>),
}

fn run_both(model_rel: &str, trial_rel: &str, scratch: &str) -> Option<BothRuns> {
    let model = jointfit_testkit::data_file(model_rel)?;
    let trial = jointfit_testkit::data_file(trial_rel)?;
    let python = jointfit_testkit::python()?;
    let dir = jointfit_testkit::scratch(scratch);
    let rms = compare_files(
        model_rel,
        &model,
        &trial,
        &dir,
        &python,
        Some("no marker determines mtp_angle_r"),
    );
    Some(BothRuns {
        model,
        trial,
        dir,
        rms,
    })
}

fn compare(model_rel: &str, trial_rel: &str, triple_tolerance_deg: Option<f64>) {
    let Some(run) = run_both(model_rel, trial_rel, "osim-ik-own-model") else {
        return;
    };
    if let Some(tol) = triple_tolerance_deg {
        triples_agree(&run.model, &run.dir, tol);
    }
}

/// The coordinates of every Euler triple of the model (`super::ik_branch::euler_triples`: the
/// pelvis, hips, lumbar) in jointfit's `.mot` against OpenSim's IK within `tol` degrees, every
/// frame: the same branch of each rotation (the other branch differs by 180° in two angles).
fn triples_agree(model: &Path, dir: &jointfit_testkit::scratch::ScratchDir, tol: f64) {
    let loaded = jointfit_io::model_file::load_model(model.to_str().unwrap()).unwrap();
    let ours = jointfit_io::sto::read_sto(&dir.join("jointfit.mot")).unwrap();
    let theirs = jointfit_io::sto::read_sto(&dir.join("opensim_ik.mot")).unwrap();
    assert!(ours.in_degrees && theirs.in_degrees);
    assert_eq!(ours.rows.len(), theirs.rows.len());
    let mut worst = (0.0f64, String::new());
    for t in super::ik_branch::euler_triples(&loaded) {
        for c in t {
            let name = &loaded.coordinates()[c].name;
            let col = |table: &jointfit_io::sto::Table| {
                table.columns.iter().position(|x| x == name).unwrap()
            };
            let (a, b) = (col(&ours), col(&theirs));
            for (f, (x, y)) in ours.rows.iter().zip(&theirs.rows).enumerate() {
                let d = (x[a] - y[b]).abs();
                assert!(
                    d <= tol,
                    "frame {f} {name}: jointfit {:.3}°, OpenSim {:.3}°",
                    x[a],
                    y[b]
                );
                if d > worst.0 {
                    worst = (d, name.clone());
                }
            }
        }
    }
    eprintln!(
        "Euler-triple coordinates: largest difference {:.3}° ({})",
        worst.0, worst.1
    );
}

/// `jointfit ik` and OpenSim's IK on `model` and `trial`, judged by OpenSim; `announce`: a
/// note `ik` must print.
fn compare_files(
    model_rel: &str,
    model: &Path,
    trial: &Path,
    dir: &jointfit_testkit::scratch::ScratchDir,
    python: &Path,
    announce: Option<&str>,
) -> (Vec<f64>, Vec<f64>) {
    let mot = dir.join("jointfit.mot");
    let (ok, out, err) = jointfit(&[
        "ik",
        model.to_str().unwrap(),
        trial.to_str().unwrap(),
        "-o",
        mot.to_str().unwrap(),
        "--keep-outliers",
        "--json",
    ]);
    assert!(ok, "{model_rel}: {err}");
    if let Some(note) = announce {
        assert!(
            err.contains(note),
            "{model_rel}: {note:?} is announced: {err}"
        );
    }
    let ours: Value = serde_json::from_str(&out).unwrap();
    let n = ours["frames"].as_u64().unwrap();
    assert_eq!(ours["solved_frames"].as_u64().unwrap(), n, "{model_rel}");
    // OpenSim's IK uses the markers the trial and the model share, weight 1 each.
    let loaded = jointfit_io::model_file::load_model(model.to_str().unwrap()).unwrap();
    let labels = jointfit_io::trial_file::read_trial(trial).unwrap();
    let weights: serde_json::Map<String, Value> = loaded
        .markers()
        .iter()
        .filter(|m| labels.labels().contains(&m.name))
        .map(|m| (m.name.clone(), json!(1.0)))
        .collect();
    let theirs = osim_check(
        python,
        "ik",
        &json!({"model": model, "trc": trial, "out_dir": dir.path(), "weights": weights,
                "accuracy": 1e-9, "repeat": 1}),
        Some(dir.path()),
    );
    let mine = osim_check(
        python,
        "mot",
        &json!({"model": model, "mot": mot, "trc": trial}),
        Some(dir.path()),
    );
    let (os, jf) = (frame_rms_mm(&theirs), frame_rms_mm(&mine));
    assert_eq!(os.len(), jf.len(), "{model_rel}: same frames");
    let mut worst = f64::NEG_INFINITY;
    for (f, (a, b)) in jf.iter().zip(&os).enumerate() {
        worst = worst.max(a - b);
        assert!(
            *a <= b + 0.01,
            "{model_rel} frame {f}: jointfit {a:.4} mm RMS, OpenSim {b:.4} mm"
        );
    }
    eprintln!(
        "{model_rel}: {} frames, jointfit − OpenSim RMS at most {worst:.4} mm",
        jf.len()
    );
    (jf, os)
}

#[test]
fn ik_on_opencap_hand_scaled_osim_no_frame_worse_than_opensim() {
    compare(
        "opencap_expert1/hand_scaled.osim",
        "opencap_expert1/walking1.trc",
        Some(3.0),
    );
}

/// OpenSim's gait2392 subject01 with its walking trial (its toe markers sit on the calcaneus
/// body, so the toes are held here too). OpenSim evaluates a `.mot` by looking its frames up
/// by time, so this needs the `.mot` to carry the TRC's own Time column (at 60 Hz
/// it is printed in 0.017 s steps).
#[test]
fn ik_on_gait2392_subject01_no_frame_worse_than_opensim() {
    compare(
        "opensim_gait2392_subject01/subject01_simbody.osim",
        "opensim_gait2392_subject01/subject01_walk1.trc",
        None,
    );
}

/// Hamner's full-body model (generic, unscaled: arms, locked subtalar and mtp, spline knee)
/// with subject02's treadmill run, frames 300–359 (one second; all 600 frames take OpenSim's
/// IK about 3 minutes, and jointfit is not worse on any of them either). The trial marks its
/// missing L.Bicep with (0, 0, 0): jointfit reads those samples as gaps, and the
/// oracle gives OpenSim the same trial with them set to NaN (`osim_check.py`), which its IK
/// skips, so both fit the same observations.
#[test]
fn ik_on_hamner_running_no_frame_worse_than_opensim() {
    let rel = "opensim_hamner_subject02/FullBodyModel_Hamner2010_v2_0.osim";
    let (Some(model), Some(trial)) = (
        jointfit_testkit::data_file(rel),
        jointfit_testkit::data_file("opensim_hamner_subject02/subject02_running.trc"),
    ) else {
        return;
    };
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-ik-hamner");
    let short = dir.join("running_300_359.trc");
    std::fs::write(
        &short,
        trc_frames(&std::fs::read_to_string(&trial).unwrap(), 300, 60),
    )
    .unwrap();
    compare_files(
        rel,
        &model,
        &short,
        &dir,
        &python,
        Some("were exactly (0, 0, 0) and were read as missing"),
    );
}

/// `n` frames of a TRC's text from data row `first` (0-based), header kept, NumFrames updated.
fn trc_frames(text: &str, first: usize, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let data = 5 + lines[5..]
        .iter()
        .take_while(|l| l.trim().is_empty())
        .count();
    let mut out = String::new();
    for (i, line) in lines[..data].iter().enumerate() {
        if i == 2 {
            let mut f: Vec<String> = line.split('\t').map(str::to_string).collect();
            f[2] = n.to_string();
            out += &f.join("\t");
        } else {
            out += line;
        }
        out.push('\n');
    }
    for line in &lines[data + first..data + first + n] {
        out += line;
        out.push('\n');
    }
    out
}
/// OpenCap's unscaled generic model on the same trial: it matches the subject's markers
/// poorly (about 100 mm RMS), and warm-started frames used to fall into wrong local minima
/// (frame 20 at 683 mm where OpenSim finds 98 mm). Absurd frames are re-solved from their
/// neighbours and a fresh seed (`jointfit::ik::repair`). Every coordinate of this
/// model is `clamped`: the coordinates against OpenSim's are asserted in `osim_clamped`.
#[test]
fn ik_on_opencap_generic_osim_no_frame_worse_than_opensim() {
    let Some(run) = run_both(
        "opencap_expert1/generic.osim",
        "opencap_expert1/walking1.trc",
        "osim-ik-generic",
    ) else {
        return;
    };
    let (jf, os) = &run.rms;
    let same: Vec<bool> = jf
        .iter()
        .zip(os)
        .map(|(a, b)| (a - b).abs() <= 0.01)
        .collect();
    super::osim_clamped::clamped_agree(&run.model, &run.trial, run.dir.path(), &same);
}

/// A Rajagopal-type full-body model with forearm markers: OpenCap's scaled model
/// (`hand_scaled.osim`, arms with elbow flexion and pronation) with its marker set replaced by
/// the JAM lab's (`lenhart2015_markers.xml`: `R.Wrist`/`L.Wrist` on the radius, 17–21 mm from
/// the pronation axis, `R.Forearm` on the ulna), on the JAM overground walk, frames 200–299.
/// The wrist marker determines pronation once the elbow is known: `ik` holds only the toes
/// (no marker on them), solves `pro_sup_r` and `pro_sup_l` in every frame, fits no frame
/// worse than OpenSim's IK, and its pronation follows OpenSim's.
#[test]
fn ik_on_full_body_model_with_forearm_markers_solves_pronation() {
    let (Some(model), Some(markers), Some(trial)) = (
        jointfit_testkit::data_file("opencap_expert1/hand_scaled.osim"),
        jointfit_testkit::data_file("opensim_jam_healthy/lenhart2015_markers.xml"),
        jointfit_testkit::data_file("opensim_jam_healthy/overground_17.trc"),
    ) else {
        return;
    };
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let dir = jointfit_testkit::scratch("osim-ik-forearm");
    let osim = std::fs::read_to_string(&model).unwrap();
    let set = std::fs::read_to_string(&markers).unwrap();
    let block = |t: &str| {
        let a = t.find("<MarkerSet").unwrap();
        let b = t.find("</MarkerSet>").unwrap() + "</MarkerSet>".len();
        (a, b)
    };
    let ((a, b), (c, d)) = (block(&osim), block(&set));
    let combined = dir.join("full_body_jam_markers.osim");
    std::fs::write(
        &combined,
        format!("{}{}{}", &osim[..a], &set[c..d], &osim[b..]),
    )
    .unwrap();
    let short = dir.join("overground_200_299.trc");
    std::fs::write(
        &short,
        trc_frames(&std::fs::read_to_string(&trial).unwrap(), 200, 100),
    )
    .unwrap();
    let rel = "full body + JAM markers";
    let (jf, _) = compare_files(
        rel,
        &combined,
        &short,
        &dir,
        &python,
        Some("no marker determines mtp_angle_r, mtp_angle_l;"),
    );
    assert_eq!(jf.len(), 100);
    let ours = jointfit_io::sto::read_sto(&dir.join("jointfit.mot")).unwrap();
    let theirs = jointfit_io::sto::read_sto(&dir.join("opensim_ik.mot")).unwrap();
    for name in ["pro_sup_r", "pro_sup_l"] {
        let col = |t: &jointfit_io::sto::Table| t.columns.iter().position(|x| x == name).unwrap();
        let (i, k) = (col(&ours), col(&theirs));
        let values: Vec<f64> = ours.rows.iter().map(|r| r[i]).collect();
        let spread = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - values.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(spread > 1.0, "{name} moves: spread {spread:.3}°");
        let worst = ours
            .rows
            .iter()
            .zip(&theirs.rows)
            .map(|(x, y)| (x[i] - y[k]).abs())
            .fold(0.0, f64::max);
        eprintln!("{name}: spread {spread:.1}°, largest difference from OpenSim {worst:.2}°");
        assert!(worst < 2.0, "{name}: {worst:.2}° from OpenSim's");
    }
}
