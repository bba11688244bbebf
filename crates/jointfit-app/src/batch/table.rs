//! The results table of a batch: one row per job, in job order.
//!
//! `results.json` is a list of objects `{id, status, error, resumed, method, frames,
//! skipped_frames, rms_before_m, rms_after_m, converged, verdict, verdict_reasons,
//! iterations, parameters: [{name,
//! group, unit, start, fitted, se, ci95, identifiability}], warnings}`. `results.csv` has the
//! same scalars, then for every parameter fitted in any job the columns `<name>`,
//! `<name>_ci_low`, `<name>_ci_high` (SI units: m or rad; empty where not fitted or not
//! determined), and the warnings joined by `"; "`.

use jointfit::workflow::verdict::Level;
use std::path::Path;

use serde::Serialize;

use super::{BatchError, Outcome};
use crate::ParamRow;

#[derive(Serialize)]
struct Row<'a> {
    id: &'a str,
    /// `ok` or `failed`.
    status: &'static str,
    error: Option<&'a str>,
    resumed: bool,
    method: Option<crate::Method>,
    frames: Option<usize>,
    skipped_frames: Option<usize>,
    rms_before_m: Option<f64>,
    rms_after_m: Option<f64>,
    converged: Option<bool>,
    /// `ok`, `caution` or `reject` (a job refused or rejected by its verdict), and why.
    verdict: Option<Level>,
    verdict_reasons: &'a [String],
    iterations: Option<usize>,
    parameters: &'a [ParamRow],
    warnings: &'a [String],
}

fn row(o: &Outcome) -> Row<'_> {
    match &o.result {
        Ok(c) => Row {
            id: &o.id,
            status: "ok",
            error: None,
            resumed: o.resumed,
            method: Some(c.method),
            frames: Some(c.frames),
            skipped_frames: Some(c.skipped_frames),
            rms_before_m: Some(c.rms_before),
            rms_after_m: Some(c.rms_after),
            converged: Some(c.converged),
            verdict: Some(c.verdict.level),
            verdict_reasons: &c.verdict.reasons,
            iterations: Some(c.iterations),
            parameters: &c.parameters,
            warnings: &c.warnings,
        },
        Err(e) => Row {
            id: &o.id,
            status: "failed",
            error: Some(e),
            resumed: false,
            method: None,
            frames: None,
            skipped_frames: None,
            rms_before_m: None,
            rms_after_m: None,
            converged: None,
            verdict: e.starts_with("rejected: ").then_some(Level::Reject),
            verdict_reasons: &[],
            iterations: None,
            parameters: &[],
            warnings: &[],
        },
    }
}

/// A CSV field, quoted when it holds a comma, quote or line break (RFC 4180).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num<T: ToString>(v: Option<T>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

/// The CSV text of the results table.
pub fn csv(outcomes: &[Outcome]) -> String {
    let rows: Vec<Row> = outcomes.iter().map(row).collect();
    let mut names: Vec<&str> = Vec::new();
    for r in &rows {
        for p in r.parameters {
            if !names.contains(&p.name.as_str()) {
                names.push(&p.name);
            }
        }
    }
    let mut header: Vec<String> = [
        "id",
        "status",
        "error",
        "resumed",
        "method",
        "frames",
        "skipped_frames",
        "rms_before_m",
        "rms_after_m",
        "converged",
        "verdict",
        "verdict_reasons",
        "iterations",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for n in &names {
        header.extend([n.to_string(), format!("{n}_ci_low"), format!("{n}_ci_high")]);
    }
    header.push("warnings".into());
    let mut out = header
        .iter()
        .map(|h| field(h))
        .collect::<Vec<_>>()
        .join(",");
    out.push('\n');
    for r in &rows {
        let mut cells = vec![
            field(r.id),
            r.status.to_string(),
            field(r.error.unwrap_or("")),
            r.resumed.to_string(),
            r.method
                .map_or(String::new(), |m| format!("{m:?}").to_lowercase()),
            num(r.frames),
            num(r.skipped_frames),
            num(r.rms_before_m),
            num(r.rms_after_m),
            num(r.converged),
            r.verdict.map_or(String::new(), |l| l.to_string()),
            field(&r.verdict_reasons.join("; ")),
            num(r.iterations),
        ];
        for n in &names {
            let p = r.parameters.iter().find(|p| p.name == *n);
            cells.push(num(p.map(|p| p.fitted)));
            cells.push(num(p.and_then(|p| p.ci95).map(|c| c[0])));
            cells.push(num(p.and_then(|p| p.ci95).map(|c| c[1])));
        }
        cells.push(field(&r.warnings.join("; ")));
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// The JSON text of the results table.
pub fn json(outcomes: &[Outcome]) -> String {
    let rows: Vec<Row> = outcomes.iter().map(row).collect();
    serde_json::to_string_pretty(&rows).expect("serializable")
}

/// Writes `DIR/results.csv` and `DIR/results.json` atomically.
pub fn write_tables(dir: &Path, outcomes: &[Outcome]) -> Result<(), BatchError> {
    for (name, text) in [
        ("results.csv", csv(outcomes)),
        ("results.json", json(outcomes)),
    ] {
        let path = dir.join(name);
        jointfit_io::atomic::write_atomic(&path, text.as_bytes())
            .map_err(|source| BatchError::Io { path, source })?;
    }
    Ok(())
}
