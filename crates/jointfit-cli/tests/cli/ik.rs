//! `jointfit ik` on real trials with gaps, sparse segments and gross errors.

use std::path::Path;

use jointfit_testkit::{data_file, scratch};
use serde_json::Value;

use super::jointfit;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub(crate) fn ik(subject: &Path, trial: &Path, mot: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["ik", s(subject), s(trial), "-o", s(mot), "--json"];
    args.extend_from_slice(extra);
    let (ok, out, err) = jointfit(&args);
    assert!(ok, "{err}");
    serde_json::from_str(&out).unwrap()
}

/// Copies a TRC, applying `edit(file frame number, label, cells of that marker)` to every
/// marker of every data row (cells: X, Y, Z as text).
pub(crate) fn edit_trc(src: &Path, dst: &Path, edit: impl Fn(i64, &str, &mut [String])) {
    let text = std::fs::read_to_string(src).unwrap();
    let lines: Vec<&str> = text.split('\n').collect();
    let labels: Vec<String> = lines[3]
        .trim_end_matches('\r')
        .split('\t')
        .skip(2)
        .step_by(3)
        .map(str::to_string)
        .collect();
    let mut out = String::new();
    for (i, line) in lines.iter().enumerate() {
        let body = line.trim_end_matches('\r');
        let mut cells: Vec<String> = body.split('\t').map(str::to_string).collect();
        if let (true, Ok(frame)) = (i >= 5, cells[0].parse::<i64>()) {
            for (k, label) in labels.iter().enumerate() {
                let at = 2 + 3 * k;
                if at + 3 <= cells.len() {
                    edit(frame, label, &mut cells[at..at + 3]);
                }
            }
        }
        out.push_str(&cells.join("\t"));
        if i + 1 < lines.len() {
            out.push('\n');
        }
    }
    std::fs::write(dst, out).unwrap();
}

fn mot_rows(path: &Path) -> Vec<Vec<f64>> {
    jointfit_io::sto::read_sto(path).unwrap().rows
}

/// JAM overground walking lacks R.MT0: the foot keeps two markers, which with the shank
/// determine its two joint angles. Before, no frame was solved ("segment foot has 2 of the 3
/// markers it needs"); now every frame is, and fits as well as the static model allows.
#[test]
fn jam_overground_with_a_two_marker_foot_is_solved() {
    let (Some(stat), Some(walk)) = (
        data_file("opensim_jam_healthy/static1.trc"),
        data_file("opensim_jam_healthy/overground_17.trc"),
    ) else {
        return;
    };
    let tmp = scratch("ik-cli-jam");
    let dir = tmp.path();
    let subject = dir.join("jam.toml");
    super::personalize(&stat, "jam", &subject);
    let v = ik(&subject, &walk, &dir.join("walk.mot"), &[]);
    assert_eq!(v["frames"], 515);
    assert_eq!(v["solved_frames"], 515);
    assert!(v["unsolved"].as_array().unwrap().is_empty());
    assert!(v["max_frame_rms_mm"].as_f64().unwrap() < 20.0, "{v}");
}

/// One coordinate of 1e21 mm in one marker of frame 41 of walking1 is refused when the file
/// is read (one line naming frame and marker). A wild sample the
/// reader lets through (the same coordinate 2 m off) is rejected by IK and reported: every
/// frame is solved, and the coordinates agree with the clean trial's (frame 41 to within what
/// dropping one marker changes, the rest to solver precision).
#[test]
fn walking1_with_a_wild_sample_recovers() {
    let tmp = scratch("ik-cli-wild");
    let dir = tmp.path();
    let Some((subject, walk)) = super::opencap_subject(dir, "subject.toml") else {
        return;
    };
    let absurd = dir.join("walking1_1e21.trc");
    edit_trc(&walk, &absurd, |frame, label, cells| {
        if frame == 41 && label == "r_knee" {
            cells[1] = "1e21".into();
        }
    });
    let (ok, _, err) = jointfit(&["ik", s(&subject), s(&absurd), "-o", s(&dir.join("a.mot"))]);
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("frame 41, marker r_knee"), "{err}");
    let wild = dir.join("walking1_wild.trc");
    edit_trc(&walk, &wild, |frame, label, cells| {
        if frame == 41 && label == "r_knee" {
            let y: f64 = cells[1].trim().parse().unwrap();
            cells[1] = format!("{:.5}", y + 2000.0);
        }
    });
    let clean = ik(&subject, &walk, &dir.join("clean.mot"), &[]);
    let v = ik(&subject, &wild, &dir.join("wild.mot"), &[]);
    assert_eq!(v["solved_frames"], v["frames"]);
    assert_eq!(v["solved_frames"], clean["solved_frames"]);
    let rejected = v["rejected"].as_array().unwrap();
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    assert_eq!(rejected[0]["frame"], 41);
    assert_eq!(rejected[0]["marker"], "r_knee");
    let d = v["max_frame_rms_mm"].as_f64().unwrap() - clean["max_frame_rms_mm"].as_f64().unwrap();
    assert!(d.abs() < 1.0, "{v}");
    let (a, b) = (
        mot_rows(&dir.join("clean.mot")),
        mot_rows(&dir.join("wild.mot")),
    );
    assert_eq!(a.len(), b.len());
    let row_41 = a.iter().position(|r| (r[0] - 0.40).abs() < 1e-9).unwrap();
    for (f, (ra, rb)) in a.iter().zip(&b).enumerate() {
        let worst = ra
            .iter()
            .zip(rb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        let tol = if f == row_41 { 2.0 } else { 1e-4 };
        assert!(worst < tol, "row {f}: differs by {worst}");
    }
}

/// Frames 50–59 without foot markers: one summary line with the range and the undetermined
/// coordinate (no line per frame), the same range in JSON; with --hold-undetermined every
/// frame is solved and the foot angles stay at frame 49's values.
#[test]
fn unsolved_frames_are_ranges_and_can_be_held() {
    let tmp = scratch("ik-cli-gap");
    let dir = tmp.path();
    let Some((subject, walk)) = super::opencap_subject(dir, "subject.toml") else {
        return;
    };
    let gap = dir.join("walking1_gap.trc");
    edit_trc(&walk, &gap, |frame, label, cells| {
        if (50..=59).contains(&frame) && ["r_calc", "r_5meta", "r_toe"].contains(&label) {
            for c in cells.iter_mut() {
                c.clear();
            }
        }
    });
    let mot = dir.join("gap.mot");
    let (ok, text, err) = jointfit(&["ik", s(&subject), s(&gap), "-o", s(&mot)]);
    assert!(ok, "{err}");
    let lines: Vec<&str> = text.lines().filter(|l| l.contains("not solved")).collect();
    assert_eq!(lines.len(), 1, "{text}");
    assert!(
        lines[0].starts_with("not solved: 10 frames"),
        "{}",
        lines[0]
    );
    assert!(lines[0].contains("50-59 ("), "{}", lines[0]);
    let v = ik(&subject, &gap, &mot, &[]);
    let unsolved = v["unsolved"].as_array().unwrap();
    assert_eq!(unsolved.len(), 1, "{v}");
    assert_eq!(unsolved[0]["first_frame"], 50);
    assert_eq!(unsolved[0]["last_frame"], 59);
    let reason = unsolved[0]["reason"].as_str().unwrap();
    assert!(
        reason == "ankle_dorsiflexion undetermined" || reason == "subtalar_inversion undetermined",
        "{reason}"
    );
    assert_eq!(
        v["solved_frames"].as_u64().unwrap() + 10,
        v["frames"].as_u64().unwrap()
    );

    let held = dir.join("held.mot");
    let v = ik(&subject, &gap, &held, &["--hold-undetermined"]);
    assert_eq!(v["solved_frames"], v["frames"]);
    assert_eq!(v["held_frames"], 10);
    let table = jointfit_io::sto::read_sto(&held).unwrap();
    let col = |name: &str| table.columns.iter().position(|c| c == name).unwrap();
    let (ankle, sub) = (col("ankle_dorsiflexion"), col("subtalar_inversion"));
    // Rows are frames 1.. of the file: frame 49 is row 48.
    for row in 49..59 {
        assert_eq!(table.rows[row][ankle], table.rows[48][ankle]);
        assert_eq!(table.rows[row][sub], table.rows[48][sub]);
    }
    // Outside the gap the result is the one without holding.
    let plain = mot_rows(&mot);
    for row in (0..49).chain(60..plain.len()) {
        let worst = plain[row]
            .iter()
            .zip(&table.rows[row])
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-3, "row {row}: {worst}");
    }
}

/// A C3D cut on a 512-byte block boundary (about half its data section) reads short; every
/// command that reads it says so on stderr (the reader's note), not only `inspect`.
#[test]
fn a_cut_c3d_is_announced_by_every_command() {
    let (Some(c3d), Some(stat)) = (
        data_file("biobuddy_functional_vicon/Test_func_rhip.c3d"),
        data_file("biobuddy_functional_vicon/anatomical_posture.c3d"),
    ) else {
        return;
    };
    let tmp = scratch("ik-cli-cut");
    let dir = tmp.path();
    let bytes = std::fs::read(&c3d).unwrap();
    let cut = dir.join("cut.c3d");
    let keep = (bytes.len() / 2) / 512 * 512;
    std::fs::write(&cut, &bytes[..keep]).unwrap();
    let full = jointfit_io::trial_file::read_trial(&c3d)
        .unwrap()
        .n_frames();
    let short = jointfit_io::trial_file::read_trial(&cut)
        .unwrap()
        .n_frames();
    assert!(short < full, "{short} of {full}");
    let subject = dir.join("pig.toml");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        s(&stat),
        "--markers",
        "plugin-gait-medial",
        "--side",
        "right",
        "--up=-z",
        "-o",
        s(&subject),
    ]);
    assert!(ok, "{err}");
    let said = |err: &str| {
        err.lines().any(|l| {
            l.starts_with("jointfit: warning: ")
                && l.contains("cut.c3d")
                && l.contains(&format!("declares {full} frames"))
        })
    };
    let (ok, _, err) = jointfit(&["convert", s(&cut), s(&dir.join("cut.trc")), "--up=-z"]);
    assert!(ok && said(&err), "convert: {err}");
    let (ok, _, err) = jointfit(&[
        "ik",
        s(&subject),
        s(&cut),
        "--up=-z",
        "-o",
        s(&dir.join("cut.mot")),
    ]);
    assert!(ok && said(&err), "ik: {err}");
    let (ok, _, err) = jointfit(&[
        "personalize",
        "--static",
        s(&cut),
        "--markers",
        "plugin-gait-medial",
        "--side",
        "right",
        "--up=-z",
        "-o",
        s(&dir.join("cut.toml")),
    ]);
    assert!(said(&err), "personalize (ok {ok}): {err}");
}

/// The `.mot` time column is the TRC's own Time column, as OpenSim's IK writes it
/// (subject01_walk1 prints 0.017 s steps at 60 Hz, 0.05 s off frame / rate by the end), so
/// that force-plate files pair with it by time. Both columns are read from the files' text.
#[test]
fn mot_times_are_the_trc_time_column() {
    let (Some(model), Some(trc)) = (
        data_file("opensim_gait2392_subject01/subject01_simbody.osim"),
        data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
    ) else {
        return;
    };
    let text = std::fs::read_to_string(&trc).unwrap();
    let trc_times: Vec<f64> = text
        .lines()
        .skip(5)
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split('\t').nth(1).unwrap().trim().parse().unwrap())
        .collect();
    assert_eq!(trc_times.len(), 151);
    let dir = scratch("ik-mot-times");
    let mot = dir.join("walk1.mot");
    ik(&model, &trc, &mot, &["--keep-outliers"]);
    let mot_times: Vec<f64> = mot_rows(&mot).iter().map(|r| r[0]).collect();
    assert_eq!(mot_times.len(), trc_times.len());
    for (f, (m, t)) in mot_times.iter().zip(&trc_times).enumerate() {
        assert!((m - t).abs() < 1e-9, "frame {f}: .mot {m} s, TRC {t} s");
    }
}
