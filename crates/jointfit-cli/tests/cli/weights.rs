//! `calibrate --weights TASKS.xml`: the marker weights of an OpenSim IK task set weigh the
//! fit. A task set giving every marker weight 1 is the unweighted fit bit for bit; the
//! tutorial's own setup (weights 1 to 10, some markers off) moves the fitted parameters.

use std::path::Path;

use serde_json::Value;

fn fitted(args: &[&str]) -> Vec<f64> {
    let (ok, out, err) = super::jointfit(args);
    assert!(ok, "{err}");
    let r: Value = serde_json::from_str(&out).unwrap();
    r["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["fitted"].as_f64().unwrap())
        .collect()
}

#[test]
fn task_set_weights_weigh_the_calibration() {
    let (Some(stat), Some(walk), Some(setup)) = (
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_static.trc"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_walk1.trc"),
        jointfit_testkit::data_file("opensim_gait2392_subject01/subject01_Setup_IK.xml"),
    ) else {
        return;
    };
    let dir = jointfit_testkit::scratch("weights");
    let subject = dir.path().join("s.toml");
    super::personalize(&stat, "gait2392", &subject);
    // Every marker of the model with weight 1.
    let spec = jointfit_io::model_file::load_spec(subject.to_str().unwrap()).unwrap();
    let tasks: String = spec
        .markers
        .iter()
        .map(|m| {
            format!(
                "<IKMarkerTask name=\"{}\"><apply>true</apply><weight>1</weight></IKMarkerTask>",
                m.name
            )
        })
        .collect();
    let ones = dir.path().join("ones.xml");
    std::fs::write(
        &ones,
        format!(
            "<?xml version=\"1.0\"?><OpenSimDocument Version=\"30000\"><IKTaskSet><objects>\
             {tasks}</objects></IKTaskSet></OpenSimDocument>"
        ),
    )
    .unwrap();
    let out = dir.path().join("fit.toml");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let base = [
        "calibrate".to_string(),
        s(&subject),
        s(&walk),
        "--json".into(),
        "-o".into(),
        s(&out),
    ];
    let run = |extra: &[String]| {
        let mut a: Vec<&str> = base.iter().map(String::as_str).collect();
        a.extend(extra.iter().map(String::as_str));
        fitted(&a)
    };
    let plain = run(&[]);
    let unit = run(&["--weights".into(), s(&ones)]);
    assert_eq!(plain, unit, "weights of 1 are the unweighted fit");
    let tutorial = run(&["--weights".into(), s(&setup)]);
    let moved = plain
        .iter()
        .zip(&tutorial)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        moved > 1e-6,
        "the tutorial's weights change the fit ({moved})"
    );
}
