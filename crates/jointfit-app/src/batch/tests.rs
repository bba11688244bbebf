//! Batch runner: known synthetic truth, thread-count independence, failures kept per job,
//! resumption, the results table read back.

use super::*;
use crate::{FitOptions, ReadOptions};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;
use jointfit::trial::Trial;
use jointfit_experiments::synth::{coordinates, markers, perturbed_params, Motion};

/// A noiseless knee trial of the built-in right leg with moved ("true") parameters.
/// The knee's parameters.
fn knee(model: &Model) -> Vec<jointfit::model::ParamId> {
    jointfit::calibrate::params_for_groups(model, &["knee"]).unwrap()
}

fn knee_trial(seed: u64) -> (Model, Vec<f64>, Trial) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    // Only the knee moves from nominal: a knee-only fit from nominal can then reach the truth.
    let moved = perturbed_params(&model, 0.3, seed);
    let mut truth = model.nominal_params();
    for id in knee(&model) {
        truth[id.0] = moved[id.0];
    }
    let coords = coordinates(&model, Motion::Knee, 40).unwrap();
    let (trial, _) = markers(&model, &truth, &coords, 50.0, None);
    (model, truth, trial)
}

fn job(id: &str, seed: u64, joints: &str) -> Job {
    let (_, _, trial) = knee_trial(seed);
    Job {
        id: id.into(),
        request: Request {
            model: ModelSource::Named("lower-limb-right".into()),
            trials: vec![TrialSource::Data {
                name: format!("{id}.trial"),
                trial: Box::new(trial),
            }],
            read: ReadOptions::default(),
            fit: FitOptions {
                joints: vec![joints.into()],
                ..FitOptions::default()
            },
        },
    }
}

fn run_job(job: &Job) -> Result<Calibration, crate::Error> {
    crate::run(&job.request)
}

fn temp_dir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("jointfit-batch-{tag}"))
        .tempdir()
        .unwrap()
}

#[test]
fn job_recovers_the_true_knee() {
    let (model, truth, _) = knee_trial(3);
    let cal = run_job(&job("a", 3, "knee")).unwrap();
    assert_eq!(cal.parameters.len(), knee(&model).len());
    for row in &cal.parameters {
        let i = model.param_id(&row.name).unwrap().0;
        let tol = if row.unit == "m" { 1e-6 } else { 1e-5 };
        assert!(
            (row.fitted - truth[i]).abs() < tol,
            "{}: fitted {} true {}",
            row.name,
            row.fitted,
            truth[i]
        );
        assert_eq!(row.start, model.parameters()[i].nominal);
    }
    assert!(cal.rms_after < 1e-6 && cal.rms_before > 1e-3, "{cal:?}");
    // The fitted model carries the fitted values; the fixed ones stay nominal.
    let fitted = Model::compile(&cal.model).unwrap();
    for (i, par) in fitted.parameters().iter().enumerate() {
        match cal.parameters.iter().find(|r| r.name == par.name) {
            Some(r) => assert_eq!(par.nominal, r.fitted),
            None => assert_eq!(par.nominal, model.parameters()[i].nominal),
        }
    }
}

#[test]
fn batch_is_thread_independent_keeps_failures_and_resumes() {
    let jobs = vec![
        job("s1", 1, "knee"),
        job("bad", 2, "elbow"),
        job("s3", 3, "knee"),
    ];
    let seen = std::sync::Mutex::new(Vec::new());
    let one = run_batch(&jobs, None, 1, |k, _| seen.lock().unwrap().push(k)).unwrap();
    let mut order = seen.into_inner().unwrap();
    order.sort();
    assert_eq!(order, vec![0, 1, 2]);
    let dir = temp_dir("resume");
    let two = run_batch(&jobs, Some(dir.path()), 2, |_, _| {}).unwrap();
    assert_eq!(one, two, "thread count or saving changed a result");
    assert_eq!(
        one[1].result.as_ref().unwrap_err(),
        &run_job(&jobs[1]).unwrap_err().to_string()
    );
    assert!(one[1]
        .result
        .as_ref()
        .unwrap_err()
        .starts_with("unknown parameter group \"elbow\""));
    assert_eq!(
        one[0].result.as_ref().unwrap(),
        &run_job(&jobs[0]).unwrap(),
        "batch differs from a single run"
    );
    // Rerun: finished jobs come from disk, unchanged; the failed one is tried again.
    let again = run_batch(&jobs, Some(dir.path()), 2, |_, _| {}).unwrap();
    assert_eq!(
        again.iter().map(|o| o.resumed).collect::<Vec<_>>(),
        vec![true, false, true]
    );
    for (a, b) in again.iter().zip(&two) {
        assert_eq!(a.result, b.result);
    }
    // A changed job is not taken for a finished one.
    let mut changed = jobs.clone();
    changed[0].request.fit.joints = vec!["ankle".into()];
    let third = run_batch(&changed, Some(dir.path()), 1, |_, _| {}).unwrap();
    assert!(!third[0].resumed);
    assert_ne!(third[0].result, two[0].result);
    // The saved model is the fitted one.
    let saved =
        jointfit_io::model_file::load_spec(dir.path().join("models/s3.toml").to_str().unwrap())
            .unwrap();
    assert_eq!(&saved, &two[2].result.as_ref().unwrap().model);
}

/// The fields of one CSV line (RFC 4180 quoting: `"a, b"` is one field, `""` a quote).
fn csv_fields(line: &str) -> Vec<String> {
    let (mut out, mut cur, mut quoted) = (Vec::new(), String::new(), false);
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            (c, _) => cur.push(c),
        }
    }
    out.push(cur);
    out
}

#[test]
fn results_table_reads_back() {
    let jobs = vec![job("s1", 1, "knee"), job("bad", 2, "elbow")];
    let dir = temp_dir("table");
    let out = run_batch(&jobs, Some(dir.path()), 1, |_, _| {}).unwrap();
    let text = std::fs::read_to_string(dir.path().join("results.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 3);
    let header: Vec<String> = csv_fields(lines[0]);
    let cal = out[0].result.as_ref().unwrap();
    assert_eq!(header.len(), 14 + 3 * cal.parameters.len());
    let row: Vec<String> = csv_fields(lines[1]);
    assert_eq!(row.len(), header.len());
    let v = header.iter().position(|h| h == "verdict").unwrap();
    assert_eq!(row[v], cal.verdict.level.to_string());
    assert_eq!(row[v + 1], cal.verdict.reasons.join("; "));
    for p in &cal.parameters {
        let col = header.iter().position(|h| *h == p.name).unwrap();
        assert_eq!(row[col].parse::<f64>().unwrap(), p.fitted, "{}", p.name);
        let lo = row[col + 1].parse::<f64>().unwrap();
        assert_eq!(lo, p.ci95.unwrap()[0]);
    }
    assert!(lines[2].starts_with("bad,failed,\"unknown parameter group"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("results.json")).unwrap())
            .unwrap();
    assert_eq!(json[0]["id"], "s1");
    assert_eq!(json[0]["rms_after_m"].as_f64().unwrap(), cal.rms_after);
    assert_eq!(json[1]["status"], "failed");
}

#[test]
fn bad_ids_and_messages() {
    let mut jobs = vec![job("x", 1, "knee"), job("x", 1, "knee")];
    let e = run_batch(&jobs, None, 1, |_, _| {}).unwrap_err();
    assert_eq!(e.to_string(), "job id \"x\" appears twice");
    jobs[1].id = "../up".into();
    assert!(matches!(
        run_batch(&jobs, None, 1, |_, _| {}),
        Err(BatchError::BadId(_))
    ));
    let mut j = job("m", 1, "knee");
    j.request.model = ModelSource::Named("no-such-model".into());
    assert_eq!(
        message(&run_job(&j).unwrap_err()),
        "\"no-such-model\" is neither a model file nor a built-in model (lower-limb, lower-limb-right, lower-limb-left)"
    );
    j.request.model = ModelSource::Named("lower-limb-right".into());
    j.request.trials = vec![TrialSource::Path("/no/such/walk.c3d".into())];
    let m = message(&run_job(&j).unwrap_err());
    assert!(m.contains("/no/such/walk.c3d"), "{m}");
}

/// A knee-only trial with skin noise cannot place the hip: the warning (the text Python's
/// `warnings` shows) names the half-width the status is judged by, the trial-alone one, and
/// the interval's, so a "poorly determined" beside a narrow interval is not a riddle.
#[test]
fn poorly_determined_warning_names_the_deciding_half_width() {
    use jointfit_experiments::synth::SkinNoise;
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let truth = perturbed_params(&model, 0.3, 4);
    let coords = coordinates(&model, Motion::Knee, 100).unwrap();
    let noise = SkinNoise {
        seed: 4,
        ..SkinNoise::default()
    };
    let (trial, _) = markers(&model, &truth, &coords, 50.0, Some(&noise));
    let mut j = job("noisy", 4, "hip");
    j.request.fit.joints = vec!["hip".into(), "knee".into()];
    // A knee trial leaves the hip far from any anatomy: kept on purpose for its warnings.
    j.request.fit.accept_rejected = true;
    j.request.trials = vec![TrialSource::Data {
        name: "noisy.trial".into(),
        trial: Box::new(trial),
    }];
    let cal = run_job(&j).unwrap();
    let flagged: Vec<&String> = cal
        .warnings
        .iter()
        .filter(|w| w.contains("determined by these trials"))
        .collect();
    assert!(
        flagged.iter().any(|w| w.starts_with("hip_")),
        "{:?}",
        cal.warnings
    );
    for w in flagged {
        assert!(
            (w.contains("trial alone ") && w.contains("which decides"))
                || w.contains("(unbounded)"),
            "{w}"
        );
    }
}
