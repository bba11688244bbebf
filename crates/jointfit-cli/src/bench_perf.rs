//! The performance goals of `jointfit bench`: OpenSim's IK solver on the same model
//! and trial, 1- against 2-thread wall time of a long calibration, the uncertainty step's
//! share, the peak memory of a long calibration (measured in a child process) and the share of
//! file reading and writing in an `ik` run. Every calibration here is
//! [`jointfit::workflow::calibration::calibrate`] with `FitSettings::default()` on the built-in leg, which
//! has no priors: the command's calibration (`jointfit_app::FitOptions::default().settings()`, whose marker
//! policy and envelope need a prior) without its uncertainty step, which is timed by itself
//! from the start to the end of its own stage (the [`Observer`] hooks the workflow calls
//! around it).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use jointfit::calibrate::params_for_groups;
use jointfit::calibrate::uncertainty::UncertaintyOptions;
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::{Model, ParamId};
use jointfit::solver::NoObserver;
use jointfit::solver::Observer;
use jointfit::solver::Termination;
use jointfit::trial::Trial;
use jointfit::workflow::calibration::Calibration;
use jointfit::workflow::calibration::UNCERTAINTY_STAGE;
use jointfit::workflow::FitSettings;
use jointfit_experiments::synth;
use serde::Serialize;

/// OpenSim 4.6's IK on the subject model and trial (best of `repeat`), through the OpenSim
/// check script (built into the binary) and `$JOINTFIT_PYTHON`; `None` without Python.
#[derive(Serialize, Clone, Copy)]
pub struct OpenSimIk {
    /// `InverseKinematicsSolver`: assemble on the first frame, track each next one (ms).
    pub solver_ms: f64,
    /// `InverseKinematicsTool.run()`, file reading and writing included (ms).
    pub tool_ms: f64,
}

/// The OpenSim check script, built into the binary: `bench` writes it to its private
/// scratch folder and runs it there, so the binary needs no source tree.
const OSIM_CHECK: &str = include_str!("../assets/osim_check.py");

/// Why OpenSim cannot be timed here, or its timings: its IK on `input`'s model and trial
/// ([`crate::bench_workload::OpenSimInput`]): the user's `.osim`, else `model` exported; the
/// trial file, else `trial` written to a temporary TRC (millimetres, 5 decimals, gaps as
/// blank cells), removed with the scratch folder afterwards.
pub fn opensim_ik(
    model: &Model,
    trial: &Trial,
    input: &crate::bench_workload::OpenSimInput,
    repeat: usize,
) -> Result<OpenSimIk, String> {
    let python = std::env::var_os("JOINTFIT_PYTHON")
        .map(PathBuf::from)
        .ok_or("JOINTFIT_PYTHON is not set")?;
    let dir = scratch_dir("jointfit-bench-").map_err(|e| e.to_string())?;
    let script = dir.path().join("osim_check.py");
    std::fs::write(&script, OSIM_CHECK)
        .map_err(|e| format!("{}: cannot write: {e}", script.display()))?;
    opensim_in(&python, &script, dir.path(), model, trial, input, repeat)
}

/// A new private scratch folder in the system's temporary directory: an unpredictable name
/// created exclusively with mode 0700 (`tempfile`), so no other user can plant a file or a
/// symlink in it; removed with its contents when the value is dropped.
pub fn scratch_dir(prefix: &str) -> Result<tempfile::TempDir> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o700));
    }
    builder.tempdir().map_err(|e| {
        anyhow::anyhow!(
            "cannot create a scratch folder in {}: {e}",
            std::env::temp_dir().display()
        )
    })
}

/// [`opensim_ik`] with its scratch folder `dir`.
fn opensim_in(
    python: &Path,
    script: &Path,
    dir: &Path,
    model: &Model,
    trial: &Trial,
    input: &crate::bench_workload::OpenSimInput,
    repeat: usize,
) -> Result<OpenSimIk, String> {
    // Scratch files for the OpenSim subprocess, written now: the command's staged outputs
    // appear only when the command ends, and this folder is gone by then.
    let osim = match &input.osim {
        Some(path) => path.clone(),
        None => {
            let osim = dir.join("subject.osim");
            let text = jointfit_io::osim::to_osim(model, &model.nominal_params())
                .map_err(|e| format!("exporting the model: {e}"))?;
            std::fs::write(&osim, text).map_err(|e| format!("{}: {e}", osim.display()))?;
            osim
        }
    };
    let trc = match &input.trc {
        Some(path) => path.clone(),
        None => {
            let trc = dir.join("trial.trc");
            let text = jointfit_io::trc::format_trc(trial, "trial.trc", &Default::default())
                .map_err(|e| format!("writing the trial as TRC: {e}"))?;
            std::fs::write(&trc, gaps_as_nan(&text))
                .map_err(|e| format!("{}: {e}", trc.display()))?;
            trc
        }
    };
    let weights: serde_json::Map<String, serde_json::Value> = model
        .markers()
        .iter()
        .map(|m| (m.name.clone(), serde_json::json!(m.weight)))
        .collect();
    let request = serde_json::json!({"model": osim, "trc": trc, "out_dir": dir,
        "weights": weights, "accuracy": 1e-8, "repeat": repeat});
    let mut child = Command::new(python)
        .arg(script)
        .arg("ik")
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", python.display()))?;
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().ok_or("no stdin")?;
        stdin
            .write_all(request.to_string().as_bytes())
            .map_err(|e| e.to_string())?;
    }
    let out = child.wait_with_output().map_err(|e| e.to_string())?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(format!(
            "osim_check.py failed: {}",
            err.lines().last().unwrap_or("")
        ));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix("@@"))
        .ok_or("osim_check.py printed no result")?;
    let v: serde_json::Value = serde_json::from_str(line).map_err(|e| e.to_string())?;
    let ms = |key: &str| v[key].as_f64().map(|s| s * 1e3).ok_or(format!("no {key}"));
    Ok(OpenSimIk {
        solver_ms: ms("solver_seconds")?,
        tool_ms: ms("seconds")?,
    })
}

/// TRC text with every blank cell of the data rows written `NaN`: OpenSim 4.6's TRC reader
/// drops a row's last cell when it is blank (a gap of the last marker) and then refuses the
/// row ("Unexpected number of columns"); it reads `NaN` as a gap. The header is the first
/// five lines and a blank one.
fn gaps_as_nan(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 8);
    for (k, line) in text.lines().enumerate() {
        if k < 6 || line.is_empty() {
            out.push_str(line);
        } else {
            let cells: Vec<&str> = line
                .split('\t')
                .map(|c| if c.is_empty() { "NaN" } else { c })
                .collect();
            out.push_str(&cells.join("\t"));
        }
        out.push('\n');
    }
    out
}

/// What [`long_trial`] is, for the bench's output.
pub const SYNTHETIC_WORKLOAD: &str =
    "synthetic gait of the built-in lower-limb-right (150-frame cycle repeated, skin noise)";

/// A long synthetic trial: the built-in right leg's 150-frame motion repeated to `frames`,
/// markers from parameters moved off nominal, with the paper's skin noise (seeded).
pub fn long_trial(frames: usize) -> Result<(Model, Vec<f64>, Trial)> {
    let model = Model::compile(&lower_limb(Side::Right))?;
    let cycle = synth::coordinates(&model, synth::Motion::All, 150)?;
    let coords: Vec<Vec<f64>> = (0..frames).map(|f| cycle[f % 150].clone()).collect();
    let p_true: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, x)| x.nominal + 0.1 * (x.upper - x.lower) * (k as f64 * 1.7).sin())
        .collect();
    let (trial, _) = synth::markers(
        &model,
        &p_true,
        &coords,
        100.0,
        Some(&synth::SkinNoise::default()),
    );
    Ok((model, p_true, trial))
}

/// Wall time of `f` on a pool of `threads` threads (s), best of `runs`.
fn on_threads(threads: usize, runs: usize, f: impl Fn() + Send + Sync) -> Result<f64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let t = Instant::now();
        pool.install(&f);
        best = best.min(t.elapsed().as_secs_f64());
    }
    Ok(best)
}

/// Figures of a long calibration (all 27 parameters, default settings of `calibrate`).
#[derive(Serialize, Default)]
pub struct LongFit {
    pub frames: usize,
    pub fit_1_thread_s: f64,
    pub fit_2_threads_s: f64,
    /// 2-thread over 1-thread wall time (goal ≤ 0.65).
    pub two_over_one: f64,
    pub uncertainty_s: f64,
    /// Uncertainty (white, Newey–West, jackknife) over the fit's 2-thread time (goal ≤ 0.1).
    pub uncertainty_over_fit: f64,
    pub iterations: usize,
}

/// Records when the uncertainty stage started and ended (the workflow names it
/// [`UNCERTAINTY_STAGE`], with a suffix for bootstrap refits).
#[derive(Default)]
struct UncertaintyClock {
    started: Option<Instant>,
    ended: Option<Instant>,
}

impl UncertaintyClock {
    /// Seconds the uncertainty stage took (0 when it did not run).
    fn seconds(&self) -> f64 {
        match (self.started, self.ended) {
            (Some(a), Some(b)) => b.duration_since(a).as_secs_f64(),
            _ => 0.0,
        }
    }
}

impl Observer for UncertaintyClock {
    fn stage_started(&mut self, stage: &str, _budget: Option<usize>) {
        if stage.starts_with(UNCERTAINTY_STAGE) {
            self.started = Some(Instant::now());
        }
    }

    fn stage_ended(&mut self, _termination: Termination) {
        if self.started.is_some() && self.ended.is_none() {
            self.ended = Some(Instant::now());
        }
    }
}

/// All 27 parameters of the built-in leg on `trial` with `settings`, through the workflow.
fn calibrate_all(
    model: &Model,
    trial: &Trial,
    free: &[ParamId],
    settings: &FitSettings,
    observer: &mut dyn Observer,
) -> Result<Calibration> {
    let p = model.nominal_params();
    Ok(jointfit::workflow::calibration::calibrate(
        model,
        &p,
        &[trial],
        free,
        settings,
        observer,
    )?)
}

pub fn long_fit(frames: usize) -> Result<LongFit> {
    let (model, _, trial) = long_trial(frames)?;
    let all = params_for_groups(&model, &["all"])?;
    let settings = FitSettings::default();
    let cal = calibrate_all(&model, &trial, &all, &settings, &mut NoObserver)?;
    let run = || {
        calibrate_all(&model, &trial, &all, &settings, &mut NoObserver).expect("ran above");
    };
    let one = on_threads(1, 1, run)?;
    let two = on_threads(2, 1, run)?;
    let with_uncertainty = FitSettings {
        uncertainty: Some(UncertaintyOptions::default()),
        ..settings.clone()
    };
    let mut clock = UncertaintyClock::default();
    calibrate_all(&model, &trial, &all, &with_uncertainty, &mut clock)?;
    let unc = clock.seconds();
    Ok(LongFit {
        frames,
        fit_1_thread_s: one,
        fit_2_threads_s: two,
        two_over_one: two / one,
        uncertainty_s: unc,
        uncertainty_over_fit: unc / two,
        iterations: cal.iterations,
    })
}

/// Child side of [`peak_rss`]: one calibration of `frames` frames (default settings of
/// `calibrate`, the outer iterations capped at `max_iterations` when given); prints its peak
/// RSS (kB), iterations, objective (m²) and the calibration's wall time (s, the synthetic
/// trial's generation excluded).
pub fn rss_child(frames: usize, max_iterations: Option<usize>) -> Result<()> {
    let (model, _, trial) = long_trial(frames)?;
    let all = params_for_groups(&model, &["all"])?;
    let settings = FitSettings {
        max_iterations,
        ..FitSettings::default()
    };
    let t = Instant::now();
    let cal = calibrate_all(&model, &trial, &all, &settings, &mut NoObserver)?;
    let seconds = t.elapsed().as_secs_f64();
    println!(
        "@@{} {} {} {seconds:.1}",
        peak_kb().context("reading /proc/self/status")?,
        cal.iterations,
        cal.cost_after
    );
    Ok(())
}

/// This process's peak resident set (kB), from `VmHWM` in `/proc/self/status` (Linux).
fn peak_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
}

/// Peak RSS (MB) of a calibration of `frames` synthetic frames, run as a child process
/// (`jointfit bench --rss-child FRAMES`), and its iterations.
pub fn peak_rss(frames: usize) -> Result<(f64, usize)> {
    let exe = std::env::current_exe()?;
    let out = Command::new(exe)
        .args(["bench", "--rss-child", &frames.to_string()])
        .output()?;
    if !out.status.success() {
        bail!(
            "bench child failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix("@@"))
        .context("bench child printed no result")?;
    let mut parts = line.split_whitespace();
    let kb: f64 = parts.next().context("no RSS")?.parse()?;
    let iterations: usize = parts.next().context("no iterations")?.parse()?;
    Ok((kb / 1024.0, iterations))
}

/// Wall times (s) of an `ik` run on a long trial: reading the TRC file, the inverse
/// kinematics with the data checks (the command's `ik_cmd::solve`), writing the `.mot` file.
#[derive(Serialize, Default)]
pub struct IkIo {
    pub frames: usize,
    pub read_s: f64,
    /// `ik_cmd::solve`: the IK with the data checks alongside, as `jointfit ik` runs it.
    pub ik_s: f64,
    pub write_s: f64,
    /// (read + write) over the whole run (goal: under a third).
    pub io_share: f64,
}

/// `trial` repeated to `frames` frames (numbered from 1).
pub fn repeat_trial(trial: &Trial, frames: usize) -> Result<Trial> {
    let n = trial.n_frames().max(1);
    let positions: Vec<_> = (0..frames)
        .flat_map(|f| trial.frame(f % n).iter().copied())
        .collect();
    Ok(Trial::new(
        trial.labels().to_vec(),
        trial.rate(),
        1,
        positions,
    )?)
}

/// `trial` repeated to `frames` frames, written as a TRC file in a scratch folder, then read,
/// solved and written as `jointfit ik` does (best of `runs`): read with
/// [`crate::common::load_for_model`] (the model's markers, checks, rotation), solved by
/// [`crate::ik_cmd::solve`] (the units check, the IK with the other data checks alongside,
/// the moved-cluster check), the `.mot` formatted by `format_sto` and synced to disk.
pub fn ik_io(model: &Model, trial: &Trial, frames: usize, runs: usize) -> Result<IkIo> {
    let long = repeat_trial(trial, frames)?;
    let scratch = scratch_dir("jointfit-bench-io-")?;
    let dir = scratch.path();
    let result = (|| -> Result<IkIo> {
        let trc = dir.join("long.trc");
        let mot = dir.join("long.mot");
        // Plain writes: the command's atomic writes are staged until it exits, after this
        // folder is gone. The `.mot` is written and synced to disk as `write_sto` does.
        let text = jointfit_io::trc::format_trc(&long, "long.trc", &Default::default())?;
        std::fs::write(&trc, text)?;
        let mut best = IkIo {
            frames,
            read_s: f64::INFINITY,
            ik_s: f64::INFINITY,
            write_s: f64::INFINITY,
            io_share: 0.0,
        };
        for _ in 0..runs {
            let t = Instant::now();
            // As `jointfit ik` reads it: the model's markers only (`common::Columns`). The
            // trial was rotated to Y up already: read it so, whatever the model's `lab_up`.
            let y_up = crate::common::TrialArgs {
                up: Some(crate::common::Up::Y),
                ..Default::default()
            };
            let read = crate::common::load_for_model(
                &trc,
                &y_up,
                model,
                None,
                crate::common::Columns::ForModel,
            )?
            .trial;
            let t_read = t.elapsed().as_secs_f64();
            let t = Instant::now();
            // Quiet: the repeated trial jumps where it wraps around, and the checks say so.
            let solved =
                crate::ik_cmd::solve(model, &read, &trc, "bench", &Default::default(), true)?;
            let run_model = solved.held_model.as_ref().unwrap_or(model);
            let t_ik = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let table = crate::ik_cmd::angles_table(run_model, &read, &solved.fit);
            let mut file = std::fs::File::create(&mot)?;
            jointfit_io::sto::write_sto_to(&mut file, &table, &mot)?;
            file.sync_all()?;
            let t_write = t.elapsed().as_secs_f64();
            best.read_s = best.read_s.min(t_read);
            best.ik_s = best.ik_s.min(t_ik);
            best.write_s = best.write_s.min(t_write);
        }
        best.io_share = (best.read_s + best.write_s) / (best.read_s + best.ik_s + best.write_s);
        Ok(best)
    })();
    drop(scratch);
    result
}

#[cfg(test)]
mod scratch_tests {
    /// Scratch folders of `bench` are private: fresh unpredictable names, mode 0700, gone
    /// with their contents when dropped (never a `/tmp/jointfit-*-<pid>` another user could
    /// plant a symlink at).
    #[test]
    fn scratch_folders_are_private_and_removed() {
        let a = super::scratch_dir("jointfit-bench-").unwrap();
        let b = super::scratch_dir("jointfit-bench-").unwrap();
        assert_ne!(a.path(), b.path());
        let pid = std::process::id().to_string();
        assert!(!a.path().to_string_lossy().ends_with(&pid));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(a.path()).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o700);
        }
        std::fs::write(a.path().join("long.trc"), b"x").unwrap();
        let kept = a.path().to_path_buf();
        drop(a);
        assert!(!kept.exists());
    }
}
