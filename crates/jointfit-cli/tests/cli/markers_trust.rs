//! `markers suggest` that can be trusted: every role printed with its confidence and what it
//! is based on (label, place, motion coherence with a motion trial); unlabelled trajectories
//! never get a role (nor make the error of a failed suggestion unreadable); ISB-style labels (Wu et al. 2002/2005 landmark names, built here by
//! relabelling a shared static and walk) get the roles the relabelling says, and the wrist
//! markers none; a preset that fits the labels is named.

use std::path::{Path, PathBuf};

use jointfit_landmarks::markerset::MarkerSet;
use jointfit_testkit::{data_file, scratch};

use super::jointfit;

/// gait2392's labels (right side; the left side the same with `L`) and their ISB-style names.
const ISB: &[(&str, &str)] = &[
    ("ASIS", "IAS"),
    ("Thigh.Upper", "TH1"),
    ("Thigh.Front", "TH2"),
    ("Thigh.Rear", "TH3"),
    ("Knee.Lat", "FLE"),
    ("Knee.Med", "FME"),
    ("Shank.Upper", "SH1"),
    ("Shank.Front", "SH2"),
    ("Shank.Rear", "SH3"),
    ("Ankle.Lat", "FAL"),
    ("Ankle.Med", "TAM"),
    ("Heel", "FCC"),
    ("Midfoot.Sup", "MFS"),
    ("Midfoot.Lat", "MFL"),
    ("Toe.Tip", "FM2"),
    ("Toe.Lat", "FM5"),
    ("Toe.Med", "FM1"),
    ("Wrist.Med", "US"),
    ("Wrist.Lat", "RS"),
    ("Elbow", "EL"),
];

/// A copy of the TRC `src` in `dir` with the labels of its label row renamed to ISB style.
fn isb_copy(src: &Path, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let labels: Vec<String> = lines[3]
        .split('\t')
        .map(|l| {
            for (side, s) in [("R.", "R"), ("L.", "L")] {
                if let Some(rest) = l.strip_prefix(side) {
                    if let Some((_, isb)) = ISB.iter().find(|(g, _)| *g == rest) {
                        return format!("{s}{isb}");
                    }
                }
            }
            match l {
                "V.Sacral" => "SACR".to_string(),
                "Sternum" => "IJ".to_string(),
                // Unlabelled trajectories as Vicon, Qualisys and others write them.
                "R.Bicep" => "*118".to_string(),
                "L.Bicep" => "Unlabeled 3".to_string(),
                "Top.Head" => "M003".to_string(),
                _ => l.to_string(),
            }
        })
        .collect();
    lines[3] = labels.join("\t");
    let path = dir.join(src.file_name().unwrap());
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

/// The rows of the roles table on stderr: (role, marker, confidence, based on).
fn roles(stderr: &str) -> Vec<(String, String, String, String)> {
    stderr
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l
                .split("  ")
                .map(str::trim)
                .filter(|c| !c.is_empty())
                .collect();
            let known = ["high", "medium", "low"];
            (cells.len() >= 4 && known.contains(&cells[2])).then(|| {
                (
                    cells[0].to_string(),
                    cells[1].to_string(),
                    cells[2].to_string(),
                    cells[3..].join(" "),
                )
            })
        })
        .collect()
}

#[test]
fn isb_labels_get_their_roles_with_confidence() {
    let (Some(stat), Some(walk)) = (
        data_file("opensim_gait2392_subject01/subject01_static.trc"),
        data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        return;
    };
    let dir = scratch("markers-isb");
    let (stat, walk) = (isb_copy(&stat, &dir), isb_copy(&walk, &dir));
    let out = dir.join("isb.toml");
    let (ok, _, err) = jointfit(&[
        "markers",
        "suggest",
        stat.to_str().unwrap(),
        "--motion",
        walk.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let set = MarkerSet::from_toml(&std::fs::read_to_string(&out).unwrap(), "isb").unwrap();
    for (s, leg) in [("R", set.right.as_ref()), ("L", set.left.as_ref())] {
        let leg = leg.unwrap_or_else(|| panic!("no {s} leg: {err}"));
        assert_eq!(leg.lateral_epicondyle, format!("{s}FLE"));
        assert_eq!(leg.medial_epicondyle, format!("{s}FME"));
        assert_eq!(leg.lateral_malleolus, format!("{s}FAL"));
        assert_eq!(leg.medial_malleolus, format!("{s}TAM"));
        assert_eq!(leg.heel, format!("{s}FCC"));
        for m in ["TH1", "TH2", "TH3"] {
            assert!(leg.thigh.contains(&format!("{s}{m}")), "{:?}", leg.thigh);
        }
        // Wrists and elbows belong to no leg segment.
        for list in [&leg.thigh, &leg.shank, &leg.foot] {
            for m in ["US", "RS", "EL"] {
                assert!(!list.contains(&format!("{s}{m}")), "{list:?}");
            }
        }
    }
    let text = std::fs::read_to_string(&out).unwrap();
    let body: String = text.lines().filter(|l| !l.starts_with('#')).collect();
    for l in ["*118", "Unlabeled 3", "M003"] {
        assert!(!body.contains(l), "{l} in {text}");
    }
    let rows = roles(&err);
    assert!(rows.len() >= 30, "{err}");
    let row = |role: &str| {
        rows.iter()
            .find(|r| r.0 == role)
            .unwrap_or_else(|| panic!("no {role} in {err}"))
    };
    // Named and in place: high; the thigh markers move with the thigh in the walk.
    let epi = row("right lateral epicondyle");
    assert_eq!(
        (epi.1.as_str(), epi.2.as_str()),
        ("RFLE", "high"),
        "{epi:?}"
    );
    assert!(epi.3.contains("label matches"), "{epi:?}");
    let thigh = rows
        .iter()
        .find(|r| r.0 == "right thigh tracking" && r.1 == "RTH1")
        .unwrap_or_else(|| panic!("{err}"));
    assert!(thigh.3.contains("moves with its segment"), "{thigh:?}");
    // Midfoot markers have no foot name: chosen by their place, so medium.
    let mid = rows
        .iter()
        .find(|r| r.1 == "RMFS")
        .unwrap_or_else(|| panic!("{err}"));
    assert_eq!(mid.2, "medium", "{mid:?}");
}

/// Plug-in Gait's static trial with 38 unlabelled trajectories (`*115`, …) and no medial
/// knee markers: no suggestion (no knee pair), one line that says why without listing the
/// unlabelled trajectories, and the preset that fits the labels named.
#[test]
fn unlabelled_trajectories_get_no_role_and_the_preset_is_named() {
    let Some(stat) = data_file("pig_pycgm/Static_trial.c3d") else {
        return;
    };
    let dir = scratch("markers-unlabelled");
    let out = dir.join("pig.toml");
    let (ok, _, err) = jointfit(&[
        "markers",
        "suggest",
        stat.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok && !out.exists(), "{err}");
    let line = err.lines().find(|l| l.contains("error:")).unwrap();
    assert!(line.contains("no pair of knee markers found"), "{line}");
    assert!(!line.contains('*'), "{line}");
    assert!(err.contains("the labels fit preset plugin-gait"), "{err}");
}
