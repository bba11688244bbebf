//! The stream section of `jointfit bench`: `jointfit stream` as a child process fed through
//! real pipes, on the workload's model and trial.
//!
//! The feed is the trial played forwards and backwards (`0, 1, …, n−1, n−2, …, 1, 0, 1, …`)
//! so that it is as long as asked and stays continuous, with the time advancing by one
//! sample period per frame; each frame's line is the markers in mm with 5 decimals, as a
//! TRC would give them.
//!
//! * **Latency**: one frame written, its answer line read, then the next frame: the wall time
//!   from before the write to after the read, per frame (percentiles and maximum).
//! * **Throughput**: a thread writes every frame as fast as the pipe takes them while the
//!   answers are read: frames over the wall time from the first write to the last answer.
//! * **Memory**: the child's resident set (`VmRSS` of `/proc/PID/status`) after the first
//!   1000 frames of the throughput run and after its last, and its peak (`VmHWM`).
//! * **In process**: [`jointfit::ik::stream::StreamingIk::update`] alone on the same frames (the solve
//!   without pipes, parsing or printing).
//! * **Python**: `jointfit.StreamingIK.update` on the same frames, timed by `$JOINTFIT_PYTHON`
//!   (or `python3`) when it imports the `jointfit` package; left out otherwise.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use jointfit::ik::stream::StreamingIk;
use jointfit::ik::IkOptions;
use jointfit::model::Model;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_app::present::MM_PER_M;
use serde::Serialize;

/// The stream options of `jointfit bench` (flattened into its arguments).
#[derive(Args, Clone)]
pub struct StreamBenchArgs {
    /// Frames fed to `jointfit stream` for its throughput and memory (0: skip the stream
    /// section).
    #[arg(long, default_value_t = 100_000)]
    pub stream_frames: usize,
    /// Frames fed one at a time for the latency.
    #[arg(long, default_value_t = 20_000)]
    pub stream_latency_frames: usize,
    /// Only the stream section.
    #[arg(long)]
    pub stream_only: bool,
}

/// Latency percentiles (µs).
#[derive(Serialize, Debug, Default, Clone)]
pub struct Percentiles {
    pub frames: usize,
    pub p50_us: f64,
    pub p90_us: f64,
    pub p99_us: f64,
    pub p999_us: f64,
    pub max_us: f64,
}

impl Percentiles {
    fn of(mut us: Vec<f64>) -> Percentiles {
        us.sort_by(f64::total_cmp);
        let at = |q: f64| us[((us.len() - 1) as f64 * q).round() as usize];
        Percentiles {
            frames: us.len(),
            p50_us: at(0.5),
            p90_us: at(0.9),
            p99_us: at(0.99),
            p999_us: at(0.999),
            max_us: at(1.0),
        }
    }
}

/// The figures of the stream section.
#[derive(Serialize, Debug, Default)]
pub struct StreamFigures {
    pub markers: usize,
    /// Write → answer through the pipes, one frame at a time (goal p99 ≤ 1000 µs).
    pub pipe_latency: Percentiles,
    /// `StreamingIk::update` alone, in this process.
    pub update_latency: Percentiles,
    /// `jointfit.StreamingIK.update` from Python (None: no interpreter with the package).
    pub python_update_latency: Option<Percentiles>,
    /// Why the Python figure is missing.
    pub python_note: Option<String>,
    /// Frames fed for throughput and memory.
    pub frames: usize,
    /// Frames per second when they arrive faster than they are solved (goal ≥ 20 000).
    pub pipe_frames_per_second: f64,
    /// The child's resident set after 1000 frames and after the last (MB), and its peak.
    pub rss_after_1000_mb: f64,
    pub rss_at_end_mb: f64,
    pub peak_rss_mb: f64,
    /// Frames the stream could not solve (NaN lines) in the throughput run.
    pub unsolved_frames: usize,
}

/// Runs the stream section on `model` with `trial` (already in the model's Y-up frame).
pub fn run(model: &Model, trial: &Trial, args: &StreamBenchArgs) -> Result<StreamFigures> {
    if trial.n_frames() < 2 {
        bail!("the stream bench needs a trial of two frames or more");
    }
    let dir = std::env::temp_dir().join(format!("jointfit-bench-stream-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let result = run_in(model, trial, args, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn run_in(
    model: &Model,
    trial: &Trial,
    args: &StreamBenchArgs,
    dir: &std::path::Path,
) -> Result<StreamFigures> {
    let model_path = dir.join("subject.toml");
    std::fs::write(&model_path, model.spec().to_toml())?;
    let feed = Feed::new(trial);
    let mut fig = StreamFigures {
        markers: trial.labels().len(),
        frames: args.stream_frames,
        ..StreamFigures::default()
    };
    fig.update_latency = in_process(model, trial, &feed, args.stream_latency_frames)?;
    fig.pipe_latency = pipe_latency(&model_path, &feed, args.stream_latency_frames)?;
    match python_latency(&model_path, trial, dir, args.stream_latency_frames) {
        Ok(p) => fig.python_update_latency = Some(p),
        Err(e) => fig.python_note = Some(format!("{e:#}")),
    }
    throughput(&model_path, &feed, args.stream_frames, &mut fig)?;
    Ok(fig)
}

/// The feed's lines: the header, and one line per frame of one forward-and-back cycle.
struct Feed {
    header: String,
    /// The marker cells of each frame of the cycle (after the time), with the line end.
    cells: Vec<String>,
    /// Frame index in the trial of each step of the cycle.
    order: Vec<usize>,
    period: f64,
}

impl Feed {
    fn new(trial: &Trial) -> Feed {
        let n = trial.n_frames();
        let order: Vec<usize> = (0..n).chain((1..n - 1).rev()).collect();
        let cells = order
            .iter()
            .map(|&f| {
                let mut s = String::new();
                for m in trial.frame(f) {
                    for v in m.iter() {
                        s.push('\t');
                        if v.is_finite() {
                            s.push_str(&format!("{:.5}", v * MM_PER_M));
                        }
                    }
                }
                s.push('\n');
                s
            })
            .collect();
        Feed {
            header: trial.labels().join("\t") + "\n",
            cells,
            order,
            period: 1.0 / trial.rate(),
        }
    }

    /// Line `k` of the feed (from 0).
    fn line(&self, k: usize) -> String {
        format!(
            "{}{}",
            k as f64 * self.period,
            self.cells[k % self.cells.len()]
        )
    }

    /// The markers of frame `k` as the stream reads them (metres).
    fn markers<'t>(&self, trial: &'t Trial, k: usize) -> &'t [nalgebra::Vector3<f64>] {
        trial.frame(self.order[k % self.order.len()])
    }
}

/// `StreamingIk::update` on `frames` frames of the feed.
fn in_process(model: &Model, trial: &Trial, feed: &Feed, frames: usize) -> Result<Percentiles> {
    let mut s = StreamingIk::new(model, trial.labels(), UpAxis::Y, IkOptions::default())?;
    let mut us = Vec::with_capacity(frames);
    for k in 0..frames.max(1) {
        let markers = feed.markers(trial, k);
        let t = Instant::now();
        let frame = s.update(k as f64 * feed.period, markers)?;
        std::hint::black_box(frame.coords);
        us.push(t.elapsed().as_secs_f64() * 1e6);
    }
    Ok(Percentiles::of(us))
}

/// Times `jointfit.StreamingIK.update` (argv: model, feed file, frames) on the feed played
/// forwards and backwards; prints the percentiles as JSON.
const PYTHON_LATENCY: &str = r#"
import json, sys, time, warnings
import numpy as np
import jointfit as jf
model_path, feed_path, frames = sys.argv[1], sys.argv[2], int(sys.argv[3])
with open(feed_path) as f:
    labels = f.readline().rstrip("\n").split("\t")
    rows = np.genfromtxt(f, delimiter="\t", dtype=np.float64, ndmin=2)
markers = rows[:, 1:].reshape(len(rows), len(labels), 3) / 1000.0
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    s = jf.StreamingIK(jf.Model.load(model_path), labels, up="y")
n = len(rows)
order = list(range(n)) + list(range(n - 2, 0, -1))
us = []
for k in range(frames):
    m = markers[order[k % len(order)]]
    t0 = time.perf_counter()
    s.update(m, time=k * 0.01)
    us.append((time.perf_counter() - t0) * 1e6)
us.sort()
at = lambda q: us[round((len(us) - 1) * q)]
print(json.dumps({"frames": frames, "p50_us": at(0.5), "p90_us": at(0.9), "p99_us": at(0.99),
                  "p999_us": at(0.999), "max_us": at(1.0)}))
"#;

/// [`PYTHON_LATENCY`] run by `$JOINTFIT_PYTHON` (else `python3`) on the trial.
fn python_latency(
    model_path: &std::path::Path,
    trial: &Trial,
    dir: &std::path::Path,
    frames: usize,
) -> Result<Percentiles> {
    let python = std::env::var_os("JOINTFIT_PYTHON").unwrap_or_else(|| "python3".into());
    let script = dir.join("latency.py");
    std::fs::write(&script, PYTHON_LATENCY)?;
    let feed = Feed::new(trial);
    let mut text = feed.header.clone();
    for k in 0..trial.n_frames() {
        text.push_str(&feed.line(k));
    }
    let feed_path = dir.join("feed.tsv");
    std::fs::write(&feed_path, text)?;
    let out = Command::new(&python)
        .arg(&script)
        .arg(model_path)
        .arg(&feed_path)
        .arg(frames.max(1).to_string())
        .output()
        .with_context(|| format!("running {}", python.to_string_lossy()))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        bail!(
            "{} could not time jointfit.StreamingIK: {}",
            python.to_string_lossy(),
            err.lines().last().unwrap_or("").trim()
        );
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let get = |k: &str| v[k].as_f64().with_context(|| format!("no {k} from Python"));
    Ok(Percentiles {
        frames: frames.max(1),
        p50_us: get("p50_us")?,
        p90_us: get("p90_us")?,
        p99_us: get("p99_us")?,
        p999_us: get("p999_us")?,
        max_us: get("max_us")?,
    })
}

/// `jointfit stream MODEL --up y` with piped standard input and output.
fn spawn(model_path: &std::path::Path) -> Result<std::process::Child> {
    Command::new(std::env::current_exe()?)
        .args([
            "stream",
            model_path.to_str().context("a UTF-8 temporary path")?,
        ])
        .args(["--up", "y"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting jointfit stream")
}

/// Write → answer, one frame at a time.
fn pipe_latency(model_path: &std::path::Path, feed: &Feed, frames: usize) -> Result<Percentiles> {
    let mut child = spawn(model_path)?;
    let mut input = child.stdin.take().context("child stdin")?;
    let mut output = BufReader::new(child.stdout.take().context("child stdout")?);
    input.write_all(feed.header.as_bytes())?;
    let mut answer = String::new();
    read_answer(&mut output, &mut answer)?;
    let lines: Vec<String> = (0..frames.max(1)).map(|k| feed.line(k)).collect();
    let mut us = Vec::with_capacity(lines.len());
    for line in &lines {
        let t = Instant::now();
        input.write_all(line.as_bytes())?;
        input.flush()?;
        read_answer(&mut output, &mut answer)?;
        us.push(t.elapsed().as_secs_f64() * 1e6);
    }
    drop(input);
    finish(child)?;
    Ok(Percentiles::of(us))
}

/// Frames written as fast as the pipe takes them, answers read as they come.
fn throughput(
    model_path: &std::path::Path,
    feed: &Feed,
    frames: usize,
    fig: &mut StreamFigures,
) -> Result<()> {
    if frames == 0 {
        return Ok(());
    }
    let mut child = spawn(model_path)?;
    let pid = child.id();
    let mut input = std::io::BufWriter::new(child.stdin.take().context("child stdin")?);
    let mut output = BufReader::new(child.stdout.take().context("child stdout")?);
    input.write_all(feed.header.as_bytes())?;
    input.flush()?;
    let mut answer = String::new();
    read_answer(&mut output, &mut answer)?;
    // The whole feed as text first, so that writing it costs only the pipe.
    let text: Vec<String> = (0..frames).map(|k| feed.line(k)).collect();
    let start = Instant::now();
    let writer = std::thread::spawn(move || -> std::io::Result<_> {
        for line in &text {
            input.write_all(line.as_bytes())?;
        }
        input.flush()?;
        Ok(input)
    });
    for k in 0..frames {
        read_answer(&mut output, &mut answer)?;
        if answer.contains("NaN") {
            fig.unsolved_frames += 1;
        }
        if k + 1 == 1000.min(frames) {
            fig.rss_after_1000_mb = status_kb(pid, "VmRSS:")? / 1024.0;
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    fig.pipe_frames_per_second = frames as f64 / seconds;
    fig.rss_at_end_mb = status_kb(pid, "VmRSS:")? / 1024.0;
    fig.peak_rss_mb = status_kb(pid, "VmHWM:")? / 1024.0;
    let input = writer
        .join()
        .map_err(|_| anyhow::anyhow!("the feed's writer thread failed"))??;
    drop(input);
    finish(child)
}

/// One answer line into `answer`; an error when the stream ended instead.
fn read_answer(output: &mut impl BufRead, answer: &mut String) -> Result<()> {
    answer.clear();
    if output.read_line(answer)? == 0 {
        bail!("jointfit stream ended early");
    }
    Ok(())
}

/// Waits for the child; its error line when it failed.
fn finish(child: std::process::Child) -> Result<()> {
    let out = child.wait_with_output()?;
    if !out.status.success() {
        bail!(
            "jointfit stream failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

/// A `kB` field of `/proc/PID/status` (Linux).
fn status_kb(pid: u32, key: &str) -> Result<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .with_context(|| format!("reading /proc/{pid}/status"))?;
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .with_context(|| format!("no {key} in /proc/{pid}/status"))
}

/// The section's lines of the bench's text output.
pub fn print(fig: &StreamFigures) {
    let p = &fig.pipe_latency;
    println!(
        "stream, write → answer      p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs over {} frames \
         (goal p99 ≤ 1000 µs)",
        p.p50_us, p.p99_us, p.max_us, p.frames
    );
    let u = &fig.update_latency;
    println!(
        "  update() in process       p50 {:.1} µs, p99 {:.1} µs, max {:.0} µs",
        u.p50_us, u.p99_us, u.max_us
    );
    match (&fig.python_update_latency, &fig.python_note) {
        (Some(p), _) => println!(
            "  Python StreamingIK.update p50 {:.1} µs, p99 {:.1} µs, max {:.0} µs",
            p.p50_us, p.p99_us, p.max_us
        ),
        (None, Some(note)) => println!("  Python: not timed ({note})"),
        (None, None) => {}
    }
    if fig.frames > 0 {
        println!(
            "stream, {} frames piped    {:8.0} frames/s  (goal ≥ 20000; {} not solved)",
            fig.frames, fig.pipe_frames_per_second, fig.unsolved_frames
        );
        println!(
            "  child RSS                 {:.1} MB after 1000 frames, {:.1} MB after {} (peak {:.1} MB)",
            fig.rss_after_1000_mb, fig.rss_at_end_mb, fig.frames, fig.peak_rss_mb
        );
    }
}
