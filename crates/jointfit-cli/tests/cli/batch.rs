//! `jointfit batch`: each job's fitted model equals `jointfit calibrate`'s for the same
//! inputs (byte for byte), failures stay per job, a rerun skips finished jobs, one-line
//! manifest errors.

use std::path::Path;

use super::jointfit;

/// `jointfit calibrate ARGS` (model, trials and options) writes the same model file, byte
/// for byte, as job `id` of the batch whose output folder is `dir/out`, and reaches the same
/// verdict (level and reasons) as that job's row of `results.json`.
fn calibrate_equals_batch(dir: &Path, id: &str, args: &[&str]) {
    let fitted = dir.join(format!("cli_{id}.toml"));
    let mut all = vec!["calibrate"];
    all.extend(args);
    // The batch keeps unconverged fits (flagged).
    all.extend([
        "-o",
        fitted.to_str().unwrap(),
        "--accept-unconverged",
        "--json",
    ]);
    let (ok, out, err) = jointfit(&all);
    assert!(ok, "{id}: {err}");
    let cli = std::fs::read_to_string(&fitted).unwrap();
    let batch = std::fs::read_to_string(dir.join(format!("out/models/{id}.toml"))).unwrap();
    assert_eq!(
        cli, batch,
        "job {id}: batch and calibrate fitted differently"
    );
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/results.json")).unwrap())
            .unwrap();
    let row = rows
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["id"] == id)
        .unwrap();
    assert_eq!(row["verdict"], report["verdict"]["level"], "job {id}");
    assert_eq!(
        row["verdict_reasons"], report["verdict"]["reasons"],
        "job {id}"
    );
}

/// `jointfit synth` trials of the built-in right leg in `dir`: `<motion>.trc` and the true
/// model `<motion>_truth.toml`, skin noise seeded by `seed`.
fn synth_trials(dir: &Path, trials: &[(&str, &str)]) {
    for (motion, seed) in trials {
        let trc = dir.join(format!("{motion}.trc"));
        let truth = dir.join(format!("{motion}_truth.toml"));
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
            trc.to_str().unwrap(),
            "--truth",
            truth.to_str().unwrap(),
        ]);
        assert!(ok, "{err}");
    }
}

/// Three jobs: two that fit (one joint, one gradient on two trials) and one that fails.
const THREE_JOBS: &str = r#"
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
"#;

/// `jointfit batch MANIFEST -o OUT --jobs N`: exit status, stdout, stderr.
fn batch(manifest: &Path, out: &Path, jobs: &str) -> (Option<i32>, String, String) {
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_jointfit"))
        .args(["batch", manifest.to_str().unwrap(), "-o"])
        .arg(out)
        .args(["--jobs", jobs])
        .output()
        .unwrap();
    (
        run.status.code(),
        String::from_utf8_lossy(&run.stdout).into_owned(),
        String::from_utf8_lossy(&run.stderr).into_owned(),
    )
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A rerun of the batch skips the two finished jobs, tries the failed one again, and
/// writes the same results (but for `resumed`).
fn rerun_resumes(manifest: &Path, out: &Path) {
    let first = read_json(&out.join("results.json"));
    let (_, _, err) = batch(manifest, out, "1");
    assert_eq!(err.matches("done earlier, skipped").count(), 2, "{err}");
    let mut again = read_json(&out.join("results.json"));
    for (k, row) in again.as_array_mut().unwrap().iter_mut().enumerate() {
        assert_eq!(row["resumed"], k != 1, "row {k}");
        row["resumed"] = serde_json::Value::Bool(false);
    }
    assert_eq!(again, first, "resumed rows differ");
}

#[test]
fn batch_equals_calibrate_keeps_failures_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    synth_trials(dir.path(), &[("knee", "2"), ("ankle", "3")]);
    let manifest = dir.path().join("jobs.toml");
    std::fs::write(&manifest, THREE_JOBS).unwrap();
    let out = dir.path().join("out");
    let (code, stdout, err) = batch(&manifest, &out, "2");
    assert_eq!(code, Some(4), "a failed job: exit status 4; {err}");
    assert!(err.contains("jointfit: error: 1 of 3 jobs failed"), "{err}");
    assert!(
        err.contains("bad: FAILED: unknown parameter group \"elbow\""),
        "{err}"
    );
    assert!(stdout.contains("2 fitted"), "{stdout}");
    // The same fits through `calibrate`: identical model files and verdicts.
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
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 4);
    assert!(rows[1].starts_with("a,ok,,false,joint,"));
    assert!(rows[2].starts_with("bad,failed,"));
    assert!(rows[3].starts_with("b,ok,,false,gradient,"));
    rerun_resumes(&manifest, &out);
}

/// On a real walking trial with a personalized subject (priors: the marker policy, the
/// anatomical envelope and the prior–data conflict step all run), `calibrate` and a batch
/// job fit the same model and reach the same verdict.
#[test]
fn batch_equals_calibrate_on_a_real_walk() {
    let dir = tempfile::tempdir().unwrap();
    let Some((subject, walk)) = super::opencap_subject(dir.path(), "subject.toml") else {
        return;
    };
    let manifest = dir.path().join("jobs.toml");
    std::fs::write(
        &manifest,
        format!(
            "[[job]]\nid = \"walk\"\nmodel = {:?}\ntrials = [{:?}]\nfilter = 6.0\n",
            subject.display().to_string(),
            walk.display().to_string()
        ),
    )
    .unwrap();
    let (code, _, err) = batch(&manifest, &dir.path().join("out"), "1");
    assert_eq!(code, Some(0), "{err}");
    let (subject, walk) = (subject.to_str().unwrap(), walk.to_str().unwrap());
    calibrate_equals_batch(dir.path(), "walk", &[subject, walk, "--filter", "6"]);
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
