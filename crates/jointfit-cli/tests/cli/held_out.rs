//! Held-out check: on the shared C3D walks of other labs (Qualisys.c3d
//! of the ezc3d test files, OpenSim's Vicon test walks walking2.c3d and walking5.c3d), at
//! least 98 % of the frames whose coordinates the present markers determine (pelvis ≥ 2,
//! thigh ≥ 2, shank ≥ 1, foot ≥ 2 of the model's markers present) are solved by `ik`, for
//! both legs. None of these labs has a static trial in the shared data: the subject model
//! comes from the stillest complete stretch of the walk itself (`personalize --static WALK
//! --window 0.02`), with the marker set `markers suggest` proposes (Qualisys) or the one
//! written from the labels (`scripts/markersets/opensim_test_walks.toml`; `markers suggest`
//! ignores markers missing in most frames, which these walks' pelvis markers are).
//! The oracle of "determined" is a count of present markers, independent of the solver's
//! rank test. `scripts/frames_table.py` prints the same numbers as a table.

use std::collections::HashSet;
use std::path::Path;

use jointfit_io::trial_file::read_trial;
use jointfit_testkit::script::script_path;
use jointfit_testkit::{data_file, scratch};

use super::jointfit;

const MIN_SHARE: f64 = 0.98;

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

#[test]
fn held_out_walks_solve_the_determined_frames() {
    let walks = [
        ("c3d_reader/ezc3d/Qualisys.c3d", None),
        (
            "c3d_reader/opensim/walking2.c3d",
            Some("markersets/opensim_test_walks.toml"),
        ),
        (
            "c3d_reader/opensim/walking5.c3d",
            Some("markersets/opensim_test_walks.toml"),
        ),
    ];
    let dir = scratch("held-out");
    for (rel, set) in walks {
        let Some(path) = data_file(rel) else {
            println!("skipped: no data");
            return;
        };
        let stem = Path::new(rel)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let markers = match set {
            Some(name) => s(&script_path(name)),
            None => {
                let out = dir.join(format!("{stem}_set.toml"));
                let (ok, _, err) = jointfit(&["markers", "suggest", &s(&path), "-o", &s(&out)]);
                assert!(ok, "{rel}: {err}");
                s(&out)
            }
        };
        let trial = read_trial(&path).unwrap();
        for side in ["right", "left"] {
            let subject = dir.join(format!("{stem}_{side}.toml"));
            let (ok, _, err) = jointfit(&[
                "personalize",
                "--static",
                &s(&path),
                "--markers",
                &markers,
                "--side",
                side,
                "--window",
                "0.02",
                "-o",
                &s(&subject),
            ]);
            assert!(ok, "{rel} {side}: {err}");
            let model = jointfit_io::model_file::load_model(&s(&subject)).unwrap();
            let determined = determined_frames(&model, &trial);
            assert!(!determined.is_empty(), "{rel} {side}");
            let (ok, out, err) = jointfit(&[
                "ik",
                &s(&subject),
                &s(&path),
                "-o",
                &s(&dir.join(format!("{stem}_{side}.mot"))),
                "--json",
            ]);
            assert!(ok, "{rel} {side}: {err}");
            let json: serde_json::Value = serde_json::from_str(&out).unwrap();
            let unsolved = unsolved_frames(&json);
            let solved = determined.iter().filter(|f| !unsolved.contains(f)).count();
            let share = solved as f64 / determined.len() as f64;
            println!(
                "{rel} {side}: {solved} of {} determined frames solved ({:.1} %), {} of {} \
                 frames in all",
                determined.len(),
                share * 100.0,
                json["solved_frames"],
                trial.n_frames()
            );
            assert!(share >= MIN_SHARE, "{rel} {side}: {share}");
        }
    }
}

/// The frames (file frame numbers) the model's markers determine: at least two pelvis, two
/// thigh, one shank and two foot markers present.
fn determined_frames(
    model: &jointfit::model::Model,
    trial: &jointfit::trial::Trial,
) -> HashSet<i64> {
    let need = [("pelvis", 2), ("thigh", 2), ("shank", 1), ("foot", 2)];
    (0..trial.n_frames())
        .filter(|&f| {
            need.iter().all(|&(seg, k)| {
                let present = model
                    .markers()
                    .iter()
                    .filter(|m| model.segments()[m.segment.0].name == seg)
                    .filter(|m| {
                        trial
                            .index_of(&m.name)
                            .ok()
                            .and_then(|c| trial.get(f, c))
                            .is_some()
                    })
                    .count();
                present >= k
            })
        })
        .map(|f| trial.first_frame() + f as i64)
        .collect()
}

/// The frames `ik --json` lists in its unsolved runs.
fn unsolved_frames(json: &serde_json::Value) -> HashSet<i64> {
    let mut unsolved = HashSet::new();
    for r in json["unsolved"].as_array().unwrap() {
        let (a, b) = (
            r["first_frame"].as_i64().unwrap(),
            r["last_frame"].as_i64().unwrap(),
        );
        unsolved.extend(a..=b);
    }
    unsolved
}
