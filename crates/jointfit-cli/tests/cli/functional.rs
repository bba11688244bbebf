//! Functional hip centre (SCoRE) and knee axis (SARA) on the shared Vicon functional trials
//! (`biobuddy_functional_vicon`, plug-in gait, −Z up), through `personalize`.

use jointfit::model::spec::ModelSpec;
use jointfit_testkit::{data_file, scratch};

use super::jointfit;

/// Personalizes one leg with both functional trials; returns the JSON summary and the model.
fn run(side: &str) -> Option<(serde_json::Value, ModelSpec)> {
    let s = &side[..1];
    let stat = data_file("biobuddy_functional_vicon/Test_func_anat.c3d")?;
    let hip = data_file(&format!("biobuddy_functional_vicon/Test_func_{s}hip.c3d"))?;
    let knee = data_file(&format!("biobuddy_functional_vicon/Test_func_{s}knee.c3d"))?;
    let dir = scratch("functional");
    let out = dir.join(format!("{side}.toml"));
    let (ok, stdout, stderr) = jointfit(&[
        "personalize",
        "--static",
        stat.to_str().unwrap(),
        "--markers",
        "plugin-gait-medial",
        "--side",
        side,
        "--up=-z",
        "--functional-hip",
        hip.to_str().unwrap(),
        "--functional-knee",
        knee.to_str().unwrap(),
        "--json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let spec = ModelSpec::from_toml(&std::fs::read_to_string(&out).unwrap()).unwrap();
    Some((json, spec))
}

fn num(v: &serde_json::Value, path: &[&str]) -> f64 {
    let mut x = v;
    for p in path {
        x = &x[*p];
    }
    x.as_f64().unwrap_or_else(|| panic!("{path:?} in {v}"))
}

#[test]
fn functional_hip_and_knee_agree_with_the_landmarks_and_between_legs() {
    let (Some((r, rs)), Some((l, ls))) = (run("right"), run("left")) else {
        return;
    };
    for (side, j, spec) in [("right", &r, &rs), ("left", &l, &ls)] {
        let f = &j["functional"];
        // Within the Bell regression's 95 % radius (Bell et al. 1989: 26 mm; our prior 34 mm)
        // and the epicondylar axis' 95 % angle (12.2° for 5°).
        let shift = num(f, &["hip_shift_mm"]);
        let angle = num(f, &["knee_axis_angle_deg"]);
        assert!(shift < 34.0, "{side}: hip {shift} mm from the regression");
        assert!(
            angle < 12.2,
            "{side}: knee axis {angle}° from the epicondyles"
        );
        // The trials determine them well: bootstrap SD a few mm / about a degree.
        for k in 0..3 {
            let sd = f["hip_sd_mm"][k].as_f64().unwrap();
            assert!(sd > 0.0 && sd < 4.0, "{side}: hip SD {sd}");
        }
        assert!(num(f, &["knee_axis_sd_deg"]) < 3.0);
        // The prior SDs written to the model are the bootstrap SD with the floor.
        let prior = |n: &str| {
            spec.parameters
                .iter()
                .find(|p| p.name == n)
                .and_then(|p| p.prior_sd)
                .unwrap()
        };
        let hip_sd = prior("hip_pelvis_lateral");
        assert!((0.005..0.008).contains(&hip_sd), "{side}: {hip_sd}");
        let ankle_sd = prior("talocrural_shank_frontal").to_degrees();
        assert!(
            (ankle_sd - 4.0).abs() < 1e-9,
            "landmark prior kept: {ankle_sd}"
        );
        // Nominal = prior mean (no explicit prior_mean written).
        assert!(spec.parameters.iter().all(|p| p.prior_mean.is_none()));
    }
    // One pelvis: the two functional hip centres sit symmetrically (pelvis frame, lateral
    // positive on each side) within 10 mm, as the regression does by construction.
    let hip = |j: &serde_json::Value| {
        [
            "hip_pelvis_anterior",
            "hip_pelvis_superior",
            "hip_pelvis_lateral",
        ]
        .map(|n| {
            j["parameters"]
                .as_array()
                .unwrap()
                .iter()
                .find(|p| p[0] == n)
                .unwrap()[1]
                .as_f64()
                .unwrap()
        })
    };
    let (hr, hl) = (hip(&r), hip(&l));
    eprintln!("functional hip centres (mm, pelvis frame): right {hr:?}, left {hl:?}");
    for k in 0..3 {
        assert!(
            (hr[k] - hl[k]).abs() < 10.0,
            "axis {k}: right {hr:?} left {hl:?}"
        );
    }
}
