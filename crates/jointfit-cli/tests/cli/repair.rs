//! `--exclude-marker`, `--swap-labels`, `--fill-gaps` on a real walk with seeded damage: the
//! checks suggest the option, the option undoes the damage, and both are in the JSON.

use std::path::Path;

use jointfit_testkit::{data_file, scratch};
use serde_json::Value;

use super::ik::{edit_trc, ik};
use super::jointfit;
use super::personalize;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn fixes(v: &Value, kind: &str) -> Vec<String> {
    v["checks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["kind"] == kind)
        .filter_map(|c| c["fix"].as_str().map(str::to_string))
        .collect()
}

#[test]
fn seeded_swap_and_gap_are_found_and_repaired() {
    let (Some(stat), Some(walk)) = (
        data_file("opencap_expert1/static1.trc"),
        data_file("opencap_expert1/walking1.trc"),
    ) else {
        println!("skipped: no data");
        return;
    };
    let tmp = scratch("repair-cli");
    let dir = tmp.path();
    let subject = dir.join("subject.toml");
    personalize(&stat, "opencap", &subject);
    // r_thigh1 and r_thigh4 exchanged from file frame 60 on.
    let swapped = dir.join("swapped.trc");
    write_swapped(&walk, &swapped, "r_thigh1", "r_thigh4", 60);
    let clean = ik(&subject, &walk, &dir.join("clean.mot"), &[]);
    let bad = ik(&subject, &swapped, &dir.join("bad.mot"), &[]);
    let swap_fixes = fixes(&bad, "swap");
    // One seeded swap, one finding: the pair whose distances to r_thigh1 and r_thigh4
    // mirror each other (r_thigh2, r_thigh5) used to read as a second swap.
    assert_eq!(
        swap_fixes,
        ["--swap-labels r_thigh1,r_thigh4@60"],
        "{swap_fixes:?}"
    );
    let fixed = ik(
        &subject,
        &swapped,
        &dir.join("fixed.mot"),
        &["--swap-labels", "r_thigh1,r_thigh4@60"],
    );
    assert_eq!(
        std::fs::read(dir.join("fixed.mot")).unwrap(),
        std::fs::read(dir.join("clean.mot")).unwrap()
    );
    assert_eq!(fixed["checks"], clean["checks"]);
    let repairs = fixed["trial"]["repairs"].as_array().unwrap();
    assert!(repairs[0]
        .as_str()
        .unwrap()
        .starts_with("swapped labels r_thigh1 and r_thigh4 in frames 60–"));
    assert_eq!(fixed["trial"]["up"], "y");
    assert_eq!(fixed["trial"]["up_from"], "model");

    // A 6-frame gap in r_thigh2: the check suggests --fill-gaps 6, the rigid fill closes it
    // within a few millimetres of the recorded samples.
    let gappy = dir.join("gappy.trc");
    edit_trc(&walk, &gappy, |frame, label, cells| {
        if label == "r_thigh2" && (80..86).contains(&frame) {
            for c in cells.iter_mut() {
                c.clear();
            }
        }
    });
    let g = ik(&subject, &gappy, &dir.join("g.mot"), &[]);
    assert_eq!(fixes(&g, "gaps"), vec!["--fill-gaps 6".to_string()]);
    let f = ik(
        &subject,
        &gappy,
        &dir.join("f.mot"),
        &["--fill-gaps", "6", "--exclude-marker", "r_thigh5"],
    );
    let repairs: Vec<&str> = f["trial"]["repairs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    assert!(repairs.contains(&"excluded marker r_thigh5"), "{repairs:?}");
    assert!(
        repairs
            .iter()
            .any(|r| r.starts_with("filled 6 frames of r_thigh2 in 1 gap(s) by rigid-body fill")),
        "{repairs:?}"
    );
    assert!(fixes(&f, "gaps").is_empty(), "{f}");
    // A bad option value is one line naming it.
    let (ok, _, err) = jointfit(&[
        "ik",
        s(&subject),
        s(&walk),
        "-o",
        s(&dir.join("x.mot")),
        "--swap-labels",
        "r_thigh1",
    ]);
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("--swap-labels \"r_thigh1\""), "{err}");
}

/// `walk` with the samples of markers `a` and `b` exchanged from file frame `from` on,
/// written to `out`.
fn write_swapped(walk: &Path, out: &Path, a: &str, b: &str, from: i64) {
    let text = std::fs::read_to_string(walk).unwrap();
    let labels: Vec<&str> = text.lines().nth(3).unwrap().split('\t').collect();
    let col = |name: &str| labels.iter().position(|l| l.trim() == name).unwrap();
    let (ca, cb) = (col(a), col(b));
    let lines: Vec<String> = text
        .split('\n')
        .enumerate()
        .map(|(i, line)| {
            let mut cells: Vec<&str> = line.split('\t').collect();
            if i >= 5
                && cells.len() > cb + 2
                && cells[0].trim().parse::<i64>().is_ok_and(|f| f >= from)
            {
                for k in 0..3 {
                    cells.swap(ca + k, cb + k);
                }
            }
            cells.join("\t")
        })
        .collect();
    std::fs::write(out, lines.join("\n")).unwrap();
}
