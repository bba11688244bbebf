//! `jointfit bench`: the speed figures of the core, printed (wall-clock, this machine).
//!
//! Forward kinematics with its Jacobians, inverse kinematics on a real gait trial (whole
//! trial from scratch, and warm-started frames), IK throughput on several cores, and the
//! 27-parameter calibration solvers. The real trial is OpenCap's `opencap_expert1/walking1`
//! with the subject's landmark model (`personalize` on `static1`, preset `opencap`, right
//! leg), or any subject and trial given with `--static`/`--model` and `--trial`
//! ([`crate::bench_workload`]); without the shared data a synthetic gait of the built-in leg
//! stands in, and the output says so. Timings are the median of repeated runs.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use jointfit::calibrate::params_for_groups;
use jointfit::ik::lm::IkWorkspace;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::Model;
use jointfit::solver::NoObserver;
use jointfit::trial::Trial;
use jointfit::workflow::Method;
use rayon::prelude::*;
use serde::Serialize;

use crate::bench_perf;

mod fit;

#[derive(Args)]
pub struct BenchArgs {
    /// Shared data directory of the default workload (default: $JOINTFIT_DATA, else
    /// ../shared/data).
    #[arg(long, conflicts_with = "subject")]
    data: Option<PathBuf>,
    /// The subject and trial to time (default: OpenCap's expert walking1, `bench_workload`).
    #[command(flatten)]
    subject: crate::bench_workload::SubjectArgs,
    /// Also time the particle swarm (hip, 50 frames; several seconds).
    #[arg(long)]
    pso: bool,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
    /// Frames of the synthetic calibration timed on 1 and 2 threads (0: skip).
    #[arg(long, default_value_t = 10_000, value_parser = crate::validate::bench_frames)]
    long_frames: usize,
    /// Frames of the synthetic calibration whose peak memory is measured (0: skip).
    #[arg(long, default_value_t = 20_000, value_parser = crate::validate::bench_frames)]
    rss_frames: usize,
    /// Frames of the trial (the workload repeated) whose `ik` run is timed for the share of
    /// file reading and writing (0: skip).
    #[arg(long, default_value_t = 100_000, value_parser = crate::validate::bench_frames)]
    io_frames: usize,
    #[command(flatten)]
    stream: crate::bench_stream::StreamBenchArgs,
    /// Only the 27-parameter joint calibration of the workload, this many times: each wall
    /// time and the fastest (for profilers and quick comparisons; 0: the full bench).
    #[arg(long, default_value_t = 0, value_parser = crate::validate::runs_or_zero)]
    fit_only: usize,
    /// Only one part of the bench, `--repeat` times (for profilers; `bench_profile.rs`):
    /// ik, checked, before, after, read or write.
    #[arg(long, value_name = "PART")]
    profile: Option<String>,
    /// With `--profile`: how many times.
    #[arg(long, default_value_t = 10, requires = "profile", value_parser = crate::validate::runs)]
    repeat: usize,
    /// Internal: run one calibration of this many frames and print its peak RSS.
    #[arg(long, hide = true, value_parser = crate::validate::bench_frames)]
    rss_child: Option<usize>,
    /// With `--rss-child`: cap the outer iterations (probes and finishing solves alike, as
    /// `calibrate --max-iterations`), to measure the memory of a very long trial in less time;
    /// the peak is reached in the first iterations.
    #[arg(long, requires = "rss_child", value_parser = crate::validate::iterations)]
    rss_max_iterations: Option<usize>,
}

#[derive(Serialize, Default)]
struct Figures {
    /// The workload of every figure but `long_fit` and `peak_rss_mb` (and `ik_io`: this
    /// trial repeated).
    source: String,
    markers: usize,
    frames: usize,
    /// Free parameters of the workload's calibrations (27 for one leg of `personalize`).
    parameters: usize,
    /// What `long_fit` and `peak_rss_mb` time: the synthetic built-in leg, whatever the
    /// workload.
    synthetic_workload: &'static str,
    fk_us: f64,
    fk_dq_us: f64,
    fk_dq_dp_us: f64,
    ik_trial_us_per_frame: f64,
    /// The data checks (`jointfit::checks::check_trial`) alongside the whole-trial IK
    /// (`jointfit::workflow::ik::ik_checked`, the two in parallel), per frame:
    /// what `jointfit ik` spends after reading the file.
    ik_checked_us_per_frame: f64,
    ik_checked_frames_per_second: f64,
    /// The whole-trial IK and the IK with the data checks on a pool of one thread (the
    /// figures above use every thread: the trial's chunks and the checks in parallel).
    ik_trial_1_thread_us_per_frame: f64,
    ik_checked_1_thread_us_per_frame: f64,
    ik_checked_1_thread_frames_per_second: f64,
    ik_warm_us_per_frame: f64,
    ik_iterations_per_frame: f64,
    ik_warm_frames_per_second: f64,
    threads: usize,
    ik_parallel_frames_per_second: f64,
    ik_parallel_speedup: f64,
    joint_27_ms: f64,
    gradient_27_ms: f64,
    pso_hip_50_ms: Option<f64>,
    opensim: Option<bench_perf::OpenSimIk>,
    /// OpenSim's IK solver time over jointfit's whole-trial IK on every thread (goal ≥ 100).
    opensim_ik_over_jointfit_ik: Option<f64>,
    /// The same over jointfit's whole-trial IK on one thread.
    opensim_ik_over_jointfit_ik_1_thread: Option<f64>,
    /// jointfit's 27-parameter fit over one OpenSim IK solve of the trial (goal ≤ 0.1).
    fit_over_opensim_ik: Option<f64>,
    long_fit: Option<bench_perf::LongFit>,
    rss_frames: usize,
    /// Peak RSS of the `rss_frames` calibration (MB; goal ≤ 150 at 20 k frames).
    peak_rss_mb: Option<f64>,
    /// Reading and writing in an `ik` run on the workload repeated to `io_frames` frames.
    ik_io: Option<bench_perf::IkIo>,
    /// `jointfit stream` through pipes (`bench_stream`).
    stream: Option<crate::bench_stream::StreamFigures>,
}

/// Median wall time (s) of `runs` calls of `f`.
fn median_time(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// The trial as `jointfit ik` holds it: `ik` reads only the model's markers (`docs/io.md`),
/// so its data checks see only those.
pub fn for_model(model: &Model, trial: &Trial) -> Result<Trial> {
    let names: Vec<&str> = model
        .markers()
        .iter()
        .map(|m| m.name.as_str())
        .filter(|n| trial.labels().iter().any(|l| l == n))
        .collect();
    Ok(trial.select(&names)?)
}

/// The modes that time one part alone (`--rss-child`, `--fit-only`, `--profile`,
/// `--stream-only`): `Some` when one ran.
fn single_mode(args: &BenchArgs, w: &crate::bench_workload::Workload) -> Option<Result<()>> {
    let p = w.model.nominal_params();
    if args.fit_only > 0 {
        return Some(fit::fit_only(
            &w.model,
            &p,
            &w.trial,
            &w.source,
            args.fit_only,
        ));
    }
    if let Some(part) = &args.profile {
        return Some(crate::bench_profile::run(
            &w.model,
            &w.trial,
            part,
            args.repeat,
            args.io_frames,
        ));
    }
    if args.stream.stream_only {
        return Some((|| {
            let s = crate::bench_stream::run(&w.model, &w.trial, &args.stream)?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&s)?);
            } else {
                println!("workload: {}", w.source);
                crate::bench_stream::print(&s);
            }
            Ok(())
        })());
    }
    None
}

/// Forward kinematics at the solved poses: positions, + ∂x/∂q, + ∂x/∂p (µs).
fn time_kinematics(model: &Model, p: &[f64], poses: &[&Vec<f64>], fig: &mut Figures) {
    let mut kin = KinData::new(model);
    let mut fk = |want: Want| {
        let reps = 20_000;
        median_time(7, || {
            for i in 0..reps {
                forward_kinematics(model, p, poses[i % poses.len()], want, &mut kin);
            }
        }) / reps as f64
            * 1e6
    };
    fig.fk_us = fk(Want::Positions);
    fig.fk_dq_us = fk(Want::Dq);
    fig.fk_dq_dp_us = fk(Want::DqDp);
}

/// IK of the whole trial from scratch, with and without the data checks, on every thread
/// and on one.
fn time_ik_trial(model: &Model, p: &[f64], trial: &Trial, fig: &mut Figures) -> Result<()> {
    let opts = IkOptions::default();
    let n = trial.n_frames() as f64;
    fig.ik_trial_us_per_frame = median_time(21, || {
        jointfit::workflow::ik::ik_trial(model, p, trial, &opts).expect("validated above");
    }) / n
        * 1e6;
    let for_model = for_model(model, trial)?;
    let checked_run = || {
        median_time(21, || {
            let (run, findings) = jointfit::workflow::ik::ik_checked(model, p, &for_model, &opts);
            std::hint::black_box((run.expect("validated above"), findings));
        }) / n
    };
    let checked = checked_run();
    fig.ik_checked_us_per_frame = checked * 1e6;
    fig.ik_checked_frames_per_second = 1.0 / checked;
    let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    fig.ik_trial_1_thread_us_per_frame = one_thread.install(|| {
        median_time(21, || {
            jointfit::workflow::ik::ik_trial(model, p, trial, &opts).expect("validated above");
        })
    }) / n
        * 1e6;
    let checked_1 = one_thread.install(checked_run);
    fig.ik_checked_1_thread_us_per_frame = checked_1 * 1e6;
    fig.ik_checked_1_thread_frames_per_second = 1.0 / checked_1;
    Ok(())
}

/// IK of the warm-started frames alone (after the first solved one).
fn time_ik_warm(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    reference: &[Vec<f64>],
    fig: &mut Figures,
) -> Result<()> {
    let map = MarkerMap::by_name(model, trial.labels())?;
    let opts = IkOptions::default();
    let first = reference
        .iter()
        .position(|q| q[0].is_finite())
        .context("no frame of the trial could be solved")?;
    let warm_frames = (first + 1..trial.n_frames()).count().max(1) as f64;
    let mut iterations = 0usize;
    let warm = median_time(21, || {
        iterations = warm_started(model, p, trial, &map, first, &reference[first], &opts);
    });
    fig.ik_warm_us_per_frame = warm / warm_frames * 1e6;
    fig.ik_warm_frames_per_second = warm_frames / warm;
    fig.ik_iterations_per_frame = iterations as f64 / warm_frames;
    Ok(())
}

/// Solves frames `first + 1 ..` of `trial` in order, each from the linear extrapolation
/// `2 q_{i−1} − q_{i−2}` of the two solutions before it (the second from the first),
/// starting from `q_first`, the solution of frame `first`: the warm-started inner loop of
/// `workflow::ik::ik_trial` without seeding. Returns the iterations summed over the frames.
fn warm_started(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    map: &MarkerMap,
    first: usize,
    q_first: &[f64],
    opts: &IkOptions,
) -> usize {
    let mut ws = IkWorkspace::new(model);
    let mut targets = Vec::with_capacity(model.markers().len());
    let mut iterations = 0;
    let mut before = q_first.to_vec();
    let mut q = before.clone();
    for f in first + 1..trial.n_frames() {
        let row = trial.frame(f);
        targets.clear();
        targets.extend(map.columns.iter().map(|c| match c {
            Some(c) => row[*c],
            None => nalgebra::Vector3::repeat(f64::NAN),
        }));
        let mut next: Vec<f64> = if f > first + 1 {
            q.iter().zip(&before).map(|(a, b)| 2.0 * a - b).collect()
        } else {
            q.clone()
        };
        iterations += ws.solve(model, p, &targets, &mut next, opts).iterations;
        before = std::mem::replace(&mut q, next);
    }
    iterations
}

/// Throughput on every core: independent copies of the trial (a batch of trials).
fn time_ik_batch(model: &Model, p: &[f64], trial: &Trial, fig: &mut Figures) {
    let opts = IkOptions::default();
    let n = trial.n_frames() as f64;
    fig.threads = rayon::current_num_threads();
    let copies = 32 * fig.threads;
    let batch = |threads: usize| -> f64 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let t = median_time(5, || {
            pool.install(|| {
                (0..copies).into_par_iter().for_each(|_| {
                    jointfit::workflow::ik::ik_trial(model, p, trial, &opts)
                        .expect("validated above");
                })
            })
        });
        copies as f64 * n / t
    };
    batch(fig.threads); // warm-up: thread start, page faults, clock ramp
    let one = batch(1);
    fig.ik_parallel_frames_per_second = batch(fig.threads);
    fig.ik_parallel_speedup = fig.ik_parallel_frames_per_second / one;
}

/// Calibration of all 27 parameters from the subject model as `jointfit calibrate` runs it
/// with no options (`fit::command_fit`: marker policy, σ estimate, global phase, envelope,
/// uncertainty, trade-offs), with `--method` joint, gradient or pso.
fn time_calibration(
    model: &Model,
    p: &[f64],
    trial: &Trial,
    pso: bool,
    fig: &mut Figures,
) -> Result<()> {
    let all = params_for_groups(model, &["all"])?;
    // The problem builds (else an error here, not a panic in the timed fits).
    jointfit::workflow::marker_rms::marker_rms(model, p, &[trial])?;
    let fit = |method: Method, free: &[jointfit::model::ParamId], trial: &Trial| {
        fit::command_fit(model, p, trial, free, method, &mut NoObserver).expect("validated above");
    };
    fig.joint_27_ms = median_time(5, || fit(Method::Joint, &all, trial)) * 1e3;
    fig.gradient_27_ms = median_time(3, || fit(Method::Gradient, &all, trial)) * 1e3;
    if pso {
        let hip = params_for_groups(model, &["hip"])?;
        let short = trial.slice_frames(0, 50.min(trial.n_frames()));
        fig.pso_hip_50_ms = Some(median_time(1, || fit(Method::Pso, &hip, &short)) * 1e3);
    }
    Ok(())
}

/// OpenSim's IK on the same model and trial, against ours: the line to print when it is not
/// available.
fn time_opensim(w: &crate::bench_workload::Workload, fig: &mut Figures) -> String {
    let Some(input) = &w.opensim else {
        return String::from("OpenSim: not available (synthetic workload)");
    };
    match bench_perf::opensim_ik(&w.model, &w.trial, input, 3) {
        Ok(os) => {
            let ours_ms = fig.ik_trial_us_per_frame * fig.frames as f64 / 1e3;
            fig.opensim_ik_over_jointfit_ik = Some(os.solver_ms / ours_ms);
            let ours_1_ms = fig.ik_trial_1_thread_us_per_frame * fig.frames as f64 / 1e3;
            fig.opensim_ik_over_jointfit_ik_1_thread = Some(os.solver_ms / ours_1_ms);
            fig.fit_over_opensim_ik = Some(fig.joint_27_ms / os.solver_ms);
            fig.opensim = Some(os);
            String::new()
        }
        Err(e) => format!("OpenSim: not available ({e})"),
    }
}

/// The optional figures: the long calibration, the peak memory, the share of I/O in `ik`,
/// the live feed.
fn optional_figures(
    args: &BenchArgs,
    model: &Model,
    trial: &Trial,
    fig: &mut Figures,
) -> Result<()> {
    if args.long_frames > 0 {
        fig.long_fit = Some(bench_perf::long_fit(args.long_frames)?);
    }
    fig.rss_frames = args.rss_frames;
    if args.rss_frames > 0 {
        fig.peak_rss_mb = Some(bench_perf::peak_rss(args.rss_frames)?.0);
    }
    if args.io_frames > 0 {
        fig.ik_io = Some(bench_perf::ik_io(model, trial, args.io_frames, 3)?);
    }
    if args.stream.stream_frames > 0 {
        fig.stream = Some(crate::bench_stream::run(model, trial, &args.stream)?);
    }
    Ok(())
}

pub fn run(args: BenchArgs) -> Result<()> {
    if let Some(frames) = args.rss_child {
        return bench_perf::rss_child(frames, args.rss_max_iterations);
    }
    let w = crate::bench_workload::workload(&args.subject, args.data.clone())?;
    if let Some(done) = single_mode(&args, &w) {
        return done;
    }
    let (model, trial) = (&w.model, &w.trial);
    let p = model.nominal_params();
    MarkerMap::by_name(model, trial.labels())?;
    let mut fig = Figures {
        source: w.source.clone(),
        markers: model.markers().len(),
        parameters: model.parameters().len(),
        synthetic_workload: bench_perf::SYNTHETIC_WORKLOAD,
        frames: trial.n_frames(),
        ..Figures::default()
    };
    let reference = jointfit::workflow::ik::ik_trial(model, &p, trial, &IkOptions::default())?.fit;
    let poses: Vec<&Vec<f64>> = reference
        .coords
        .iter()
        .filter(|q| q[0].is_finite())
        .collect();
    time_kinematics(model, &p, &poses, &mut fig);
    time_ik_trial(model, &p, trial, &mut fig)?;
    time_ik_warm(model, &p, trial, &reference.coords, &mut fig)?;
    time_ik_batch(model, &p, trial, &mut fig);
    time_calibration(model, &p, trial, args.pso, &mut fig)?;
    let opensim_note = time_opensim(&w, &mut fig);
    optional_figures(&args, model, trial, &mut fig)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&fig)?);
        return Ok(());
    }
    print_figures(&fig, &opensim_note);
    Ok(())
}

/// The figures as text.
fn print_figures(fig: &Figures, opensim_note: &str) {
    println!(
        "workload: {} ({} markers, {} frames, {} free parameters)",
        fig.source, fig.markers, fig.frames, fig.parameters
    );
    if fig.long_fit.is_some() || fig.peak_rss_mb.is_some() {
        println!(
            "  (the long calibration and peak RSS below: {}, not this workload)",
            fig.synthetic_workload
        );
    }
    println!("forward kinematics          {:8.3} µs", fig.fk_us);
    println!("  + ∂x/∂q                   {:8.3} µs", fig.fk_dq_us);
    println!("  + ∂x/∂q + ∂x/∂p           {:8.3} µs", fig.fk_dq_dp_us);
    println!(
        "IK, whole trial (seeded)    {:8.2} µs/frame  on {} threads; {:.2} on 1",
        fig.ik_trial_us_per_frame, fig.threads, fig.ik_trial_1_thread_us_per_frame
    );
    println!(
        "  + data checks             {:8.2} µs/frame  ({:.0} frames/s; on 1 thread {:.2} µs/frame, {:.0} frames/s)",
        fig.ik_checked_us_per_frame,
        fig.ik_checked_frames_per_second,
        fig.ik_checked_1_thread_us_per_frame,
        fig.ik_checked_1_thread_frames_per_second
    );
    println!(
        "IK, warm-started frame      {:8.2} µs/frame  ({:.0} frames/s, {:.2} iterations/frame)",
        fig.ik_warm_us_per_frame, fig.ik_warm_frames_per_second, fig.ik_iterations_per_frame
    );
    println!(
        "IK, batch on {} threads      {:8.0} frames/s  (×{:.2} of one thread)",
        fig.threads, fig.ik_parallel_frames_per_second, fig.ik_parallel_speedup
    );
    println!(
        "calibrate 27, joint         {:8.1} ms  (the command's default)",
        fig.joint_27_ms
    );
    println!("calibrate 27, gradient      {:8.1} ms", fig.gradient_27_ms);
    if let Some(ms) = fig.pso_hip_50_ms {
        println!("calibrate hip, PSO, 50 fr.  {:8.1} ms", ms);
    }
    match (
        &fig.opensim,
        fig.opensim_ik_over_jointfit_ik,
        fig.opensim_ik_over_jointfit_ik_1_thread,
        fig.fit_over_opensim_ik,
    ) {
        (Some(os), Some(ik), Some(ik_1), Some(fit)) => {
            println!(
                "OpenSim 4.6 IK solver       {:8.1} ms  (tool with files {:.1} ms)",
                os.solver_ms, os.tool_ms
            );
            println!(
                "  OpenSim IK / jointfit IK  {ik:8.1}   (goal ≥ 100; {ik_1:.1} with jointfit on 1 thread)"
            );
            println!("  jointfit fit / OpenSim IK {fit:8.3}   (goal ≤ 0.1)");
        }
        _ => println!("{opensim_note}"),
    }
    if let Some(l) = &fig.long_fit {
        println!(
            "calibrate 27, {} synthetic frames: {:.2} s on 1 thread, {:.2} s on 2 \
             (2/1 = {:.2}, goal ≤ 0.65; {} iterations)",
            l.frames, l.fit_1_thread_s, l.fit_2_threads_s, l.two_over_one, l.iterations
        );
        println!(
            "  uncertainty               {:8.3} s  ({:.3} of the fit, goal ≤ 0.1)",
            l.uncertainty_s, l.uncertainty_over_fit
        );
    }
    if let Some(mb) = fig.peak_rss_mb {
        println!(
            "peak RSS, calibrate 27 on {} synthetic frames: {:.0} MB (goal ≤ 150 at 20 k)",
            fig.rss_frames, mb
        );
    }
    if let Some(io) = &fig.ik_io {
        println!(
            "ik on {} frames (the trial repeated): read {:.3} s, solve {:.3} s, write {:.3} s (I/O share {:.2}, goal < 0.33)",
            io.frames, io.read_s, io.ik_s, io.write_s, io.io_share
        );
    }
    if let Some(s) = &fig.stream {
        crate::bench_stream::print(s);
    }
}
