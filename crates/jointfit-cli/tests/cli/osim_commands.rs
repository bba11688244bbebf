//! A new user's walk through the commands with their own OpenSim model (gait2392 subject01
//! and its walking trial, which lacks the model's static-only medial knee and ankle markers
//! and any toe marker): `model show`, `check --joints`, `calibrate --joints -o OUT.osim`,
//! `report` on the input and on the output model; and `ik` with a model that has no markers
//! is an error, not an empty success.

use super::jointfit;

#[test]
fn osim_commands_as_a_new_user_runs_them() {
    let (Some(model), Some(trial), Some(bare)) = (
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_simbody.osim"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/gait2354_simbody.osim"),
    ) else {
        return;
    };
    let (model, trial, bare) = (
        model.to_str().unwrap(),
        trial.to_str().unwrap(),
        bare.to_str().unwrap(),
    );
    let dir = jointfit_testkit::scratch("osim-commands");
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();

    let (ok, out, err) = jointfit(&["model", "show", model]);
    assert!(ok, "{err}");
    assert!(out.contains("knee_r"), "{out}");

    // check: the offsets of the named joints are what it judges.
    let (ok, out, err) = jointfit(&["check", model, trial, "--joints", "hip_r,knee_r"]);
    assert!(ok, "{err}");
    assert!(err.contains("lack model markers R.Knee.Lat"), "{err}");
    assert!(err.contains("no marker determines mtp_angle_r"), "{err}");
    for p in ["hip_r.parent.tx", "knee_r.child.rz"] {
        assert!(out.contains(p), "{p}: {out}");
    }
    assert!(!out.contains("hip_l."), "{out}");
    let (ok, _, err) = jointfit(&["check", model, trial]);
    assert!(!ok);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("nothing selected") && err.contains("hip_r"),
        "{err}"
    );

    // calibrate, then a report on the input and on the written model.
    let fitted = path("fitted.osim");
    let (ok, _, err) = jointfit(&[
        "calibrate",
        model,
        trial,
        "--joints",
        "hip_r,knee_r",
        "-o",
        &fitted,
    ]);
    assert!(ok, "{err}");
    for (m, out_dir) in [
        (model, path("report_in")),
        (fitted.as_str(), path("report_out")),
    ] {
        let (ok, out, err) = jointfit(&["report", m, trial, "-o", &out_dir]);
        assert!(ok, "{m}: {err}");
        // As in `calibrate --report`: the absent markers stay in the report ("n/a").
        assert!(
            err.contains("lacks model markers R.Knee.Lat")
                && err.contains("they count as missing in every frame"),
            "{err}"
        );
        assert!(out.contains("RMS marker distance"), "{out}");
        assert!(std::path::Path::new(&out_dir).join("index.html").is_file());
    }

    // ik with a model without markers: an error naming the model, nothing written.
    let mot = path("bare.mot");
    let (ok, _, err) = jointfit(&["ik", bare, trial, "-o", &mot]);
    assert!(!ok, "{err}");
    assert!(err.contains("has no markers"), "{err}");
    assert!(!std::path::Path::new(&mot).exists());
}
