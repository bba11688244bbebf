//! `jointfit scale` end to end on OpenSim's gait2392 tutorial subject: the tutorial's own
//! ScaleTool setup runs unchanged (model and static given on the command line, since the
//! setup names a model file the data lack): its measurements group the bodies, its manual
//! scales of femur and tibia are held, not fitted; the JSON carries every body's factors and
//! the markers moved; the report on the written model shows the factors with their
//! intervals and the markers moved; OpenSim loads the written model and its inverse
//! kinematics on the walk
//! (every marker weight 1) fits with a mean marker RMS of at most 15 mm when the walk is
//! given to the fit (OpenSim's own ScaleTool result on the same data: 19.4 mm). A marker set
//! that names a body the model lacks is a one-line error naming the file and the marker.

use jointfit_testkit::script::Script;

use super::jointfit;

const DIR: &str = "opensim_gait2392_subject01";

#[test]
fn scale_gait2392_from_the_tutorial_setup() {
    let files = [
        "gait2392_thelen2003muscle.osim",
        "subject01_static.trc",
        "subject01_walk1.trc",
        "subject01_Setup_Scale.xml",
    ]
    .map(|f| jointfit_testkit::data_file(&format!("{DIR}/{f}")));
    let [Some(generic), Some(stat), Some(walk), Some(setup)] = files else {
        println!("skipped: no data");
        return;
    };
    let dir = jointfit_testkit::scratch("scale");
    let out = dir.join("subject01.osim");
    let json = scale_json(
        &[&generic, &stat, &walk],
        &["--setup", setup.to_str().unwrap()],
        &out,
    );
    let factors = json["scale_factors"].as_object().unwrap();
    for body in [
        "pelvis", "femur_r", "tibia_l", "talus_r", "calcn_l", "toes_r", "torso",
    ] {
        let f = factors[body].as_array().unwrap();
        assert_eq!(f.len(), 3);
        let v = f[0].as_f64().unwrap();
        // the setup's measurements: talus scales with the shank, toes with the foot
        assert!((0.8..1.3).contains(&v), "{body}: {v}");
    }
    // the setup's manual scales (scaling order "measurements manualScale") override the
    // thigh and shank measurements for femur and tibia
    for (body, manual) in [
        ("femur_r", 1.14724),
        ("femur_l", 1.14724),
        ("tibia_r", 0.988523),
    ] {
        let f: Vec<f64> = factors[body]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(f, vec![manual; 3], "{body}");
    }
    assert_converged(&json);
    assert_eq!(factors["talus_r"], factors["talus_l"], "shank measurement");
    assert_eq!(factors["toes_l"], factors["calcn_l"], "foot measurement");
    report_shows_the_scaling(&out, &walk, &json, &dir);
    assert!(
        json["rms_mm"].as_f64().unwrap() < 12.0,
        "{}",
        json["rms_mm"]
    );
    assert!(
        (json["total_mass"].as_f64().unwrap() - 72.6).abs() < 1e-9,
        "setup mass"
    );
    assert_eq!(
        json["markers"].as_array().unwrap().len(),
        39,
        "the marker set's markers"
    );

    if let Some(mean) = opensim_ik_mean(&out, &walk, &dir) {
        assert!(mean <= 0.015, "mean RMS {mean}");
    }
}

/// The fit stopped by its own convergence test, not at its iteration limit: no flag says
/// so, and the iterations stayed under the limit of the rounds.
fn assert_converged(json: &serde_json::Value) {
    let flags = json["flags"].as_array().unwrap();
    assert!(
        !flags
            .iter()
            .any(|f| f.as_str().unwrap().contains("iteration limit")),
        "{flags:?}"
    );
    assert!(
        json["iterations"].as_u64().unwrap() < 800,
        "{}",
        json["iterations"]
    );
}

/// OpenCap's expert 1, the generic model with the static and a walk: the fit converges (no
/// iteration-limit flag), and the walk's frames fit within 15 mm RMS.
#[test]
fn scale_opencap_expert_with_a_walk_converges() {
    let files = ["generic.osim", "static1.trc", "walking1.trc"]
        .map(|f| jointfit_testkit::data_file(&format!("opencap_expert1/{f}")));
    let [Some(generic), Some(stat), Some(walk)] = files else {
        println!("skipped: no data");
        return;
    };
    let dir = jointfit_testkit::scratch("scale-opencap");
    let json = scale_json(&[&generic, &stat, &walk], &[], &dir.join("expert1.osim"));
    assert_converged(&json);
    assert_eq!(json["frames"], 9, "{json}");
    assert!(
        json["rms_mm"].as_f64().unwrap() < 15.0,
        "{}",
        json["rms_mm"]
    );
}

/// `jointfit report` on the scaled model: a section with each group's factors and 95 %
/// interval (± 1.96 SD, as `--json` gives them) and every marker's offset.
fn report_shows_the_scaling(
    model: &std::path::Path,
    trial: &std::path::Path,
    json: &serde_json::Value,
    dir: &std::path::Path,
) {
    let out = dir.join("report");
    let (ok, _, err) = jointfit(&[
        "report",
        model.to_str().unwrap(),
        trial.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let table = |id: &str| {
        let at = html
            .find(&format!("id=\"{id}\""))
            .unwrap_or_else(|| panic!("no {id}"));
        html[at..at + html[at..].find("</table>").unwrap()].to_string()
    };
    let factors = table("tbl-scale-factors");
    for g in json["groups"].as_array().unwrap() {
        let f = g["factors"][0].as_f64().unwrap();
        let sd = g["sd"][0].as_f64().unwrap();
        let row = format!("<tr><td>{}</td>", g["name"].as_str().unwrap());
        let at = factors.find(&row).unwrap_or_else(|| panic!("{row}"));
        let row = &factors[at..at + factors[at..].find("</tr>").unwrap()];
        assert!(row.contains(&format!(">{f:.4}<")), "{row}");
        let interval = if sd == 0.0 {
            "held (given)".to_string()
        } else {
            format!(
                "{:.4}–{:.4}",
                f - 1.959_963_984_540_054 * sd,
                f + 1.959_963_984_540_054 * sd
            )
        };
        assert!(row.contains(&interval), "{row} vs {interval}");
    }
    let markers = table("tbl-marker-offsets");
    for m in json["markers"].as_array().unwrap() {
        let name = m["name"].as_str().unwrap();
        assert!(markers.contains(&format!("<tr><td>{name}</td>")), "{name}");
    }
}

#[test]
fn scale_marker_on_a_missing_body_is_a_one_line_error() {
    let (Some(generic), Some(stat)) = (
        jointfit_testkit::data_file(&format!("{DIR}/gait2392_thelen2003muscle.osim")),
        jointfit_testkit::data_file(&format!("{DIR}/subject01_static.trc")),
    ) else {
        println!("skipped: no data");
        return;
    };
    let dir = jointfit_testkit::scratch("scale-bad");
    let set = dir.join("markers.xml");
    std::fs::write(
        &set,
        "<OpenSimDocument Version=\"40000\"><MarkerSet name=\"m\"><objects>\
         <Marker name=\"R.ASIS\"><socket_parent_frame>/bodyset/humerus_r</socket_parent_frame>\
         <location>0 0 0</location></Marker></objects></MarkerSet></OpenSimDocument>",
    )
    .unwrap();
    let (ok, _, err) = jointfit(&[
        "scale",
        generic.to_str().unwrap(),
        stat.to_str().unwrap(),
        "--markerset",
        set.to_str().unwrap(),
        "-o",
        dir.join("out.osim").to_str().unwrap(),
    ]);
    assert!(!ok);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("markers.xml") && err.contains("R.ASIS") && err.contains("humerus_r"),
        "{err}"
    );
}

/// A motion trial is used when its frames hold half of the markers the static trial holds,
/// whatever the model's own marker count: Hamner's full-body model carries 37 markers its
/// running session never recorded (arms, joint centres), and the running frames still join
/// the fit (1 static + 8 running frames). A motion trial none of whose frames qualifies
/// (every label renamed) is a one-line error naming it, and nothing is written.
#[test]
fn motion_frames_count_against_the_static_trials_markers() {
    let files = [
        "FullBodyModel_Hamner2010_v2_0.osim",
        "subject02_static.trc",
        "subject02_running.trc",
    ]
    .map(|f| jointfit_testkit::data_file(&format!("opensim_hamner_subject02/{f}")));
    let [Some(generic), Some(stat), Some(run)] = files else {
        println!("skipped: no data");
        return;
    };
    let dir = jointfit_testkit::scratch("scale-motion");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let out = dir.join("subject02.osim");
    let (ok, stdout, err) = jointfit(&[
        "scale",
        &s(&generic),
        &s(&stat),
        &s(&run),
        "-o",
        &s(&out),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["frames"], 9, "{stdout}");
    assert_eq!(v["absent_markers"].as_array().unwrap().len(), 37);

    let text = std::fs::read_to_string(&run).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    lines[3] = lines[3]
        .split('\t')
        .enumerate()
        .map(|(i, l)| match i >= 2 && !l.is_empty() {
            true => format!("Pat_{l}"),
            false => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\t");
    let renamed = dir.join("renamed.trc");
    std::fs::write(&renamed, lines.join("\n")).unwrap();
    let bad = dir.join("bad.osim");
    let (ok, _, err) = jointfit(&[
        "scale",
        &s(&generic),
        &s(&stat),
        &s(&renamed),
        "-o",
        &s(&bad),
    ]);
    assert!(!ok);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("renamed.trc") && err.contains("(the most: 0)"),
        "{err}"
    );
    assert!(!bad.exists());
}

/// Hamner's full-body model from its own ScaleTool setup, whose marker-placer weights run
/// from 0 (thigh and shank clusters) to 100 (pelvis): the weights shape the static pose only,
/// the running frames weigh every marker 1, and OpenSim's inverse kinematics on the run with
/// the written model fits within 15 mm mean marker RMS (the trial's never-seen marker, all
/// zeros, left out as a gap).
#[test]
fn scale_hamner_from_its_setup_with_running_frames() {
    let dir = "opensim_hamner_subject02";
    let files = [
        "FullBodyModel_Hamner2010_v2_0.osim",
        "subject02_static.trc",
        "subject02_running.trc",
        "Setup_Scale.xml",
    ]
    .map(|f| jointfit_testkit::data_file(&format!("{dir}/{f}")));
    let [Some(generic), Some(stat), Some(run), Some(setup)] = files else {
        println!("skipped: no data");
        return;
    };
    let out_dir = jointfit_testkit::scratch("scale_hamner");
    let out = out_dir.join("subject02.osim");
    let json = scale_json(
        &[&generic, &stat, &run],
        &["--setup", setup.to_str().unwrap()],
        &out,
    );
    // the fit's own misfit over every marker sample (clusters included)
    let rms = json["rms_mm"].as_f64().unwrap();
    assert!(rms < 15.0, "{rms}");
    if let Some(mean) = opensim_ik_mean(&out, &run, &out_dir) {
        assert!(mean <= 0.015, "mean RMS {mean}");
    }
}

/// `jointfit scale ARGS… -o OUT --json`: its JSON (asserting the command succeeded).
fn scale_json(
    args: &[&std::path::Path],
    extra: &[&str],
    out: &std::path::Path,
) -> serde_json::Value {
    let mut argv: Vec<String> = vec!["scale".into()];
    argv.extend(args.iter().map(|p| p.to_str().unwrap().to_string()));
    argv.extend(extra.iter().map(|a| a.to_string()));
    argv.extend([
        "-o".into(),
        out.to_str().unwrap().to_string(),
        "--json".into(),
    ]);
    let argv: Vec<&str> = argv.iter().map(String::as_str).collect();
    let (ok, stdout, err) = jointfit(&argv);
    assert!(ok, "{err}");
    serde_json::from_str(&stdout).expect("JSON")
}

/// OpenSim's IK on `trial` with `model` (every marker weight 1): the mean over frames of the
/// marker RMS (m); `None` (printed as skipped) without `$JOINTFIT_PYTHON`.
fn opensim_ik_mean(
    model: &std::path::Path,
    trial: &std::path::Path,
    dir: &std::path::Path,
) -> Option<f64> {
    let Some(python) = jointfit_testkit::python() else {
        println!("skipped: no $JOINTFIT_PYTHON");
        return None;
    };
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let ik = Script::new(&python, "scale_compare.py")
        .args(&["ik", &s(model), &s(trial), &s(&dir.join("ik"))])
        .current_dir(dir)
        .run_json();
    let mean = ik["mean_rms"].as_f64().unwrap();
    println!(
        "OpenSim IK on {} with {}: mean marker RMS {:.1} mm",
        trial.display(),
        model.display(),
        mean * 1e3
    );
    Some(mean)
}
