//! `jointfit batch`: each job's fitted model equals `jointfit calibrate`'s for the same
//! inputs (byte for byte), failures stay per job, a rerun skips finished jobs, one-line
//! manifest errors.

use std::path::Path;

use super::jointfit;

/// `jointfit calibrate ARGS` (model, trials and options) writes the same model file, byte
/// for byte, as job `id` of the batch whose output folder is `dir/out`.
fn calibrate_equals_batch(dir: &Path, id: &str, args: &[&str]) {
    let fitted = dir.join(format!("cli_{id}.toml"));
    let mut all = vec!["calibrate"];
    all.extend(args);
    // The batch keeps unconverged fits (flagged).
    all.extend(["-o", fitted.to_str().unwrap(), "--accept-unconverged"]);
    let (ok, _, err) = jointfit(&all);
    assert!(ok, "{id}: {err}");
    let cli = std::fs::read_to_string(&fitted).unwrap();
    let batch = std::fs::read_to_string(dir.join(format!("out/models/{id}.toml"))).unwrap();
    assert_eq!(
        cli, batch,
        "job {id}: batch and calibrate fitted differently"
    );
}

#[test]
fn batch_equals_calibrate_keeps_failures_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    for (motion, seed) in [("knee", "2"), ("ankle", "3")] {
        let (ok, _, err) = jointfit(&[
            "synth",
            "lower-limb-right",
            "--motion",
            motion,
            "--noise",
            "skin",
            "--seed",
            seed,
            "-o",
            &p(&format!("{motion}.trc")),
            "--truth",
            &p(&format!("{motion}_truth.toml")),
        ]);
        assert!(ok, "{err}");
    }
    let manifest = dir.path().join("jobs.toml");
    std::fs::write(
        &manifest,
        r#"
[defaults]
joints = ["knee"]

[[job]]
id = "a"
model = "lower-limb-right"
trials = ["knee.trc"]

[[job]]
id = "bad"
model = "lower-limb-right"
trials = ["knee.trc"]
joints = ["elbow"]

[[job]]
id = "b"
model = "ankle_truth.toml"
trials = ["ankle.trc", "knee.trc"]
joints = ["ankle", "knee"]
method = "gradient"
"#,
    )
    .unwrap();
    let out = p("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["batch", &p("jobs.toml"), "-o", &out, "--jobs", "2"])
        .output()
        .unwrap();
    let (stdout, err) = (
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr),
    );
    assert_eq!(
        run.status.code(),
        Some(4),
        "a failed job: exit status 4; {err}"
    );
    assert!(err.contains("jointfit: error: 1 of 3 jobs failed"), "{err}");
    assert!(
        err.contains("bad: FAILED: unknown parameter group \"elbow\""),
        "{err}"
    );
    assert!(stdout.contains("2 fitted"), "{stdout}");
    // The same fits through `calibrate`: identical model files.
    let (knee, ankle, ankle_truth) = (p("knee.trc"), p("ankle.trc"), p("ankle_truth.toml"));
    let cases = [
        (
            "a",
            vec!["lower-limb-right", knee.as_str()],
            "knee",
            "joint",
        ),
        (
            "b",
            vec![ankle_truth.as_str(), ankle.as_str(), knee.as_str()],
            "ankle,knee",
            "gradient",
        ),
    ];
    for (id, inputs, joints, method) in &cases {
        let mut args = inputs.clone();
        args.extend(["--joints", joints, "--method", method]);
        calibrate_equals_batch(dir.path(), id, &args);
    }
    let csv = std::fs::read_to_string(dir.path().join("out/results.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 4);
    assert!(rows[1].starts_with("a,ok,,false,joint,"));
    assert!(rows[2].starts_with("bad,failed,"));
    assert!(rows[3].starts_with("b,ok,,false,gradient,"));
    let json = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(name)).unwrap()).unwrap()
    };
    let first = json("out/results.json");
    // Rerun: the two finished jobs are skipped, the failed one is tried again.
    let (_, _, err) = jointfit(&["batch", &p("jobs.toml"), "-o", &out, "--jobs", "1"]);
    assert_eq!(err.matches("done earlier, skipped").count(), 2, "{err}");
    let mut again = json("out/results.json");
    for (k, row) in again.as_array_mut().unwrap().iter_mut().enumerate() {
        assert_eq!(row["resumed"], k != 1, "row {k}");
        row["resumed"] = serde_json::Value::Bool(false);
    }
    assert_eq!(again, first, "resumed rows differ");
}
#[test]
fn bad_manifest_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.toml");
    std::fs::write(
        &manifest,
        "[[job]]\nid = \"x\"\nmodel = \"lower-limb-right\"\ntrials = [\"a.trc\"]\nmethdo = \"joint\"\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let (ok, _, err) = jointfit(&[
        "batch",
        manifest.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("m.toml: line "), "{err}");
    assert!(err.contains("methdo"), "{err}");
    std::fs::write(
        &manifest,
        "[[job]]\nid = \"x\"\nmodel = \"lower-limb-right\"\ntrials = [\"missing.trc\"]\n",
    )
    .unwrap();
    let (ok, _, err) = jointfit(&[
        "batch",
        manifest.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("missing.trc"), "{err}");
}

/// Every calibrate option a manifest can give yields the same fitted model file as
/// `jointfit calibrate` with the same options (byte for byte).
#[test]
fn batch_options_equal_calibrate_options() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (ok, _, err) = jointfit(&[
        "synth",
        "lower-limb-right",
        "--motion",
        "all",
        "--frames",
        "40",
        "--noise",
        "skin",
        "--perturb-mm",
        "10",
        "-o",
        &p("t.trc"),
        "--truth",
        &p("truth.toml"),
    ]);
    assert!(ok, "{err}");
    // (The built-in model has no priors: `prior` and `marker_noise_mm` only have to reach
    // the same settings as on the command line.)
    let jobs: [(&str, &str, Vec<&str>); 3] = [
        (
            "starts",
            "joints = [\"knee\"]\nstarts = 3\nseed = 7\nfilter = 4.0\n",
            vec!["--joints", "knee", "--starts", "3", "--seed", "7", "--filter", "4"],
        ),
        (
            "fix",
            "joints = [\"ankle\"]\nfix_unidentifiable = true\nprior = \"none\"\nmarker_noise_mm = 2.0\nbootstrap = 3\n",
            vec![
                "--joints",
                "ankle",
                "--fix-unidentifiable",
                "--prior",
                "none",
                "--marker-noise-mm",
                "2",
                "--bootstrap",
                "3",
            ],
        ),
        (
            "limit",
            "joints = [\"hip\"]\nmax_iter = 2\nmethod = \"gradient\"\n",
            vec!["--joints", "hip", "--max-iter", "2", "--method", "gradient"],
        ),
    ];
    let mut manifest = String::new();
    for (id, settings, _) in &jobs {
        manifest.push_str(&format!(
            "[[job]]\nid = \"{id}\"\nmodel = \"lower-limb-right\"\ntrials = [\"t.trc\"]\n{settings}\n"
        ));
    }
    std::fs::write(p("jobs.toml"), manifest).unwrap();
    let (ok, _, err) = jointfit(&["batch", &p("jobs.toml"), "-o", &p("out"), "--jobs", "1"]);
    assert!(ok, "{err}");
    let t = p("t.trc");
    for (id, _, opts) in &jobs {
        let mut args = vec!["lower-limb-right", t.as_str()];
        args.extend(opts.iter().copied());
        calibrate_equals_batch(dir.path(), id, &args);
    }
    // The iteration limit reached the solver: that job is flagged as not converged.
    let csv = std::fs::read_to_string(p("out/results.csv")).unwrap();
    let limit = csv.lines().find(|l| l.starts_with("limit,")).unwrap();
    assert!(limit.contains("before converging"), "{limit}");
}
