//! One marker RMS everywhere (`jointfit::workflow::marker_rms::marker_rms`, `docs/marker_rms.md`):
//! `check`, `ik`, `report` and `calibrate` (its "before") print the same number for the same
//! model and trial. The trial is OpenCap's toe-out walk, whose re-attached thigh markers make
//! the definitions that differ from it (per-frame outlier rejection, the mean of per-frame
//! RMS) print other numbers (11.5–13.8 mm against 20.3 mm).

use super::jointfit;

/// The number after `prefix` in the first line of `text` that contains it.
fn number_after(text: &str, prefix: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.contains(prefix))
        .unwrap_or_else(|| panic!("no {prefix:?} in {text}"));
    let rest = &line[line.find(prefix).unwrap() + prefix.len()..];
    let num: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    num.parse()
        .unwrap_or_else(|_| panic!("no number after {prefix:?} in {line}"))
}

#[test]
fn check_ik_report_and_calibrate_print_one_rms() {
    let Some(stat) = jointfit_testkit::data_file("opencap_expert1/static1.trc") else {
        return;
    };
    let trial = jointfit_testkit::data_file("opencap_expert1/walkingTO1.trc").unwrap();
    let dir = jointfit_testkit::scratch("one-rms");
    let d = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let t = trial.to_str().unwrap();
    super::personalize(&stat, "opencap", dir.path().join("s.toml").as_path());
    let run = |args: &[&str]| {
        let (ok, out, err) = jointfit(args);
        assert!(ok, "{args:?}: {err}");
        out
    };
    let check = number_after(
        &run(&["check", &d("s.toml"), t]),
        "RMS marker distance with the nominal model",
    );
    let ik_out = run(&["ik", &d("s.toml"), t, "-o", &d("w.mot")]);
    let ik = number_after(&ik_out, "RMS marker distance:");
    let report = number_after(
        &run(&["report", &d("s.toml"), t, "-o", &d("rep")]),
        "RMS marker distance:",
    );
    // Every marker used: the marker policy would leave the moved thigh markers out of the
    // fit (and its RMS, which then says so).
    let calibrate = number_after(
        &run(&[
            "calibrate",
            &d("s.toml"),
            t,
            "-o",
            &d("f.toml"),
            "--no-marker-policy",
            "--accept-rejected",
        ]),
        "RMS marker distance:",
    );
    for (name, v) in [("ik", ik), ("report", report), ("calibrate", calibrate)] {
        assert_eq!(v, check, "{name} prints {v} mm, check {check} mm");
    }
    // The other definition ik prints is labelled as the per-frame mean, and differs here.
    let mean = number_after(&ik_out, "RMS marker error per frame: mean");
    assert!(mean < check - 3.0, "{mean} against {check}");
}
