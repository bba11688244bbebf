//! A bounded fuzz harness of the command line: random commands over a corpus of good and
//! corrupted files, odd numbers and aliased output paths (fixed seed, [`RUNS`] runs, stopped
//! early after [`BUDGET_SECONDS`]). Every run must: not panic, end within
//! [`RUN_TIMEOUT_SECONDS`], leave the input files byte for byte as they were, leave no
//! temporary file, write nothing when it fails, and fail with exactly one error line.
//! `JOINTFIT_FUZZ_RUNS` and `JOINTFIT_FUZZ_SEED` override the run count and the seed.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::reliability::Scratch;

const RUNS: usize = 1000;
const BUDGET_SECONDS: u64 = 60;
const RUN_TIMEOUT_SECONDS: u64 = 60;
const SEED: u64 = 16;

const NUMBERS: &[&str] = &[
    "6",
    "0",
    "-6",
    "-0",
    "NaN",
    "inf",
    "-inf",
    "1e-7",
    "1e300",
    "18446744073709551615",
    "4294967296",
    "100000000",
    "3.5",
    "",
    "abc",
    "1e20",
    "2",
];

/// Writes the corpus into `s.dir/in` (and files too large to compare, into `s.dir/big`)
/// and returns (trial-like files, model-like files).
fn corpus(s: &Scratch) -> (Vec<String>, Vec<String>) {
    let input = s.dir.join("in");
    std::fs::create_dir_all(input.join("sub")).unwrap();
    let good_trc = std::fs::read_to_string(s.dir.join("t.trc")).unwrap();
    let good_toml = std::fs::read_to_string(s.dir.join("m.toml")).unwrap();
    let w = |name: &str, bytes: &[u8]| std::fs::write(input.join(name), bytes).unwrap();
    write_bad_trials(&w, &good_trc);
    write_bad_c3ds(&w);
    write_bad_models(&w, &good_toml);
    write_bad_osims(s, &w);
    let big = write_oversized(s);
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(input.join("t.trc"), input.join("link.trc")).unwrap();
        std::fs::hard_link(input.join("t.trc"), input.join("hard.trc")).unwrap();
    }
    let p = |n: &str| input.join(n).to_str().unwrap().to_string();
    let mut trials: Vec<String> = TRIALS.iter().map(|n| p(n)).collect();
    let mut models: Vec<String> = MODELS.iter().map(|n| p(n)).collect();
    trials.extend(big.iter().filter(|b| !b.ends_with(".osim")).cloned());
    models.extend(big.iter().filter(|b| b.ends_with(".osim")).cloned());
    models.push("lower-limb-right".into());
    models.push("no-such-model".into());
    (trials, models)
}

/// Trial-like files of the corpus (`t.trc` three times: most commands should get a good one).
const TRIALS: &[&str] = &[
    "t.trc",
    "t.trc",
    "t.trc",
    "trunc.trc",
    "empty.trc",
    "huge.trc",
    "nan.trc",
    "blank.trc",
    "rate.trc",
    "junk.c3d",
    "empty.c3d",
    "header.c3d",
    "link.trc",
    "hard.trc",
    "missing.trc",
    "sub/../t.trc",
    "tenth.trc",
    "ten.trc",
    "one.trc",
    "still.trc",
    "lower.trc",
];

/// Model-like files of the corpus.
const MODELS: &[&str] = &[
    "m.toml",
    "m.toml",
    "m.toml",
    "bad.toml",
    "nan.toml",
    "long.toml",
    "bare.toml",
    "tiny_prior.toml",
    "m.osim",
    "split.osim",
    "version.osim",
];

/// `good` with every data cell mapped by `f` (the five header lines, frame and time kept).
fn map_cells(good: &str, f: &dyn Fn(&str) -> String) -> String {
    good.lines()
        .enumerate()
        .map(|(i, l)| {
            if i < 5 {
                l.to_string()
            } else {
                l.split('\t')
                    .enumerate()
                    .map(|(k, c)| if k < 2 { c.to_string() } else { f(c) })
                    .collect::<Vec<_>>()
                    .join("\t")
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// TRC files: cut, empty, absurd numbers, wrong units, one frame, a still trial, labels in
/// the wrong case.
fn write_bad_trials(w: &dyn Fn(&str, &[u8]), good: &str) {
    w("t.trc", good.as_bytes());
    w("trunc.trc", &good.as_bytes()[..good.len() * 2 / 5]);
    w("empty.trc", b"");
    w("huge.trc", map_cells(good, &|_| "1e300".into()).as_bytes());
    w("nan.trc", map_cells(good, &|_| "NaN".into()).as_bytes());
    w("blank.trc", map_cells(good, &|_| String::new()).as_bytes());
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
    lines[2] = lines[2].replacen("10", "1e300", 2);
    w("rate.trc", lines.join("\n").as_bytes());
    // Units off by a tenth and by ten (coordinates scaled, units line unchanged).
    w(
        "tenth.trc",
        map_cells(good, &|c| scale_number(c, 0.1)).as_bytes(),
    );
    w(
        "ten.trc",
        map_cells(good, &|c| scale_number(c, 10.0)).as_bytes(),
    );
    // One frame; the same frame twenty times; labels in lower case.
    let lines: Vec<&str> = good.lines().collect();
    let mut head: Vec<String> = lines[..5].iter().map(|l| l.to_string()).collect();
    let first = lines[5..].iter().find(|l| !l.trim().is_empty()).unwrap();
    let mut counts: Vec<String> = head[2].split('\t').map(str::to_string).collect();
    for n in [1usize, 20] {
        counts[2] = n.to_string();
        counts[7] = n.to_string();
        head[2] = counts.join("\t");
        let rows: Vec<String> = (1..=n)
            .map(|f| {
                let mut c: Vec<String> = first.split('\t').map(str::to_string).collect();
                c[0] = f.to_string();
                c[1] = format!("{:.6}", (f - 1) as f64 / 10.0);
                c.join("\t")
            })
            .collect();
        let name = if n == 1 { "one.trc" } else { "still.trc" };
        w(
            name,
            format!("{}\n{}\n", head.join("\n"), rows.join("\n")).as_bytes(),
        );
    }
    let mut lower: Vec<String> = good.lines().map(str::to_string).collect();
    lower[3] = lower[3]
        .to_ascii_lowercase()
        .replace("frame#", "Frame#")
        .replace("time", "Time");
    w("lower.trc", lower.join("\n").as_bytes());
}

/// C3D files: random bytes, empty, a header with nothing after it.
fn write_bad_c3ds(w: &dyn Fn(&str, &[u8])) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let junk: Vec<u8> = (0..2048).map(|_| rng.gen()).collect();
    w("junk.c3d", &junk);
    w("empty.c3d", b"");
    let mut header = vec![0u8; 1536];
    header[0] = 2;
    header[1] = 0x50;
    w("header.c3d", &header);
}

/// Model files: broken TOML, a NaN nominal, a huge name, no markers, a prior SD of 1e-203 m.
fn write_bad_models(w: &dyn Fn(&str, &[u8]), good: &str) {
    w("m.toml", good.as_bytes());
    w("bad.toml", b"name = \"x\"\n[[bad\n");
    w(
        "nan.toml",
        good.replacen("nominal = ", "nominal = nan #", 1).as_bytes(),
    );
    w(
        "long.toml",
        format!("name = \"{}\"\n", "y".repeat(200_000)).as_bytes(),
    );
    let mut bare = jointfit::model::spec::ModelSpec::from_toml(good).unwrap();
    bare.markers.clear();
    w("bare.toml", bare.to_toml().as_bytes());
    let mut tiny = jointfit::model::spec::ModelSpec::from_toml(good).unwrap();
    tiny.parameters[0].prior_sd = Some(1e-203);
    tiny.parameters[0].prior_mean = Some(tiny.parameters[0].nominal);
    w("tiny_prior.toml", tiny.to_toml().as_bytes());
}

/// `.osim` files: the model exported, one whose marker location a comment splits, one with a
/// `Version` past any integer.
fn write_bad_osims(s: &Scratch, w: &dyn Fn(&str, &[u8])) {
    let osim = s.dir.join("m.osim");
    let (ok, _, err) = super::jointfit(&[
        "export",
        "osim",
        &s.p("m.toml"),
        "-o",
        osim.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&osim).unwrap();
    w("m.osim", text.as_bytes());
    let start = text.find("<location>").unwrap() + "<location>".len();
    let gap = start + text[start..].find(' ').unwrap();
    let split = format!("{}<!-- c -->{}", &text[..gap], &text[gap..]);
    w("split.osim", split.as_bytes());
    let version = with_version(&text, "99999999999999999999");
    w("version.osim", version.as_bytes());
}

/// `text` with its `Version="…"` attribute set to `v`.
fn with_version(text: &str, v: &str) -> String {
    let key = "Version=\"";
    let a = text.find(key).unwrap() + key.len();
    let b = a + text[a..].find('"').unwrap();
    format!("{}{v}{}", &text[..a], &text[b..])
}

/// Inputs past the size limits, outside the directory the harness compares run by run:
/// sparse 2 GiB files and `/dev/zero` behind input names. Returns their paths.
fn write_oversized(s: &Scratch) -> Vec<String> {
    let big = s.dir.join("big");
    std::fs::create_dir_all(&big).unwrap();
    let mut paths = Vec::new();
    for name in ["big.trc", "big.c3d", "big.osim"] {
        let f = std::fs::File::create(big.join(name)).unwrap();
        f.set_len(2 << 30).unwrap();
        paths.push(big.join(name).display().to_string());
    }
    #[cfg(unix)]
    {
        let zero = big.join("zero.osim");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        paths.push(zero.display().to_string());
    }
    paths
}

/// A data cell times `factor` (other text as it is).
fn scale_number(c: &str, factor: f64) -> String {
    c.parse::<f64>()
        .map_or_else(|_| c.to_string(), |v| format!("{}", v * factor))
}

struct Gen<'a> {
    rng: ChaCha8Rng,
    /// The input files of the command being built: the only corpus files an output may name.
    used: Vec<String>,
    trials: &'a [String],
    models: &'a [String],
    out: &'a Path,
}

impl Gen<'_> {
    /// An input of the command being built.
    fn pick(&mut self, v: &[String]) -> String {
        let p = v.choose(&mut self.rng).unwrap().clone();
        self.used.push(p.clone());
        p
    }

    fn number(&mut self) -> String {
        NUMBERS.choose(&mut self.rng).unwrap().to_string()
    }

    /// An output path: usually new, sometimes one of this command's inputs (as given or
    /// spelled another way: symlink, hard link, `sub/..`), a missing directory or the output
    /// directory itself. Never another corpus file: overwriting a file that is not an input
    /// is allowed.
    fn output(&mut self, ext: &str) -> String {
        let k: u32 = self.rng.gen_range(0..10);
        // Existing files only (never a bare name, which would land in the working directory,
        // nor a missing one, which would land among the inputs).
        let existing: Vec<String> = self
            .used
            .iter()
            .filter(|p| Path::new(p).is_absolute() && Path::new(p).is_file())
            .cloned()
            .collect();
        let family = ["/t.trc", "/link.trc", "/hard.trc"];
        let aliases: Vec<String> = if existing
            .iter()
            .any(|p| family.iter().any(|f| p.ends_with(f)))
        {
            self.trials
                .iter()
                .filter(|p| family.iter().any(|f| p.ends_with(f)))
                .cloned()
                .collect()
        } else {
            Vec::new()
        };
        match k {
            0 | 1 if !existing.is_empty() => {
                if k == 1 && !aliases.is_empty() {
                    aliases.choose(&mut self.rng).unwrap().clone()
                } else {
                    existing.choose(&mut self.rng).unwrap().clone()
                }
            }
            2 => self
                .out
                .join("nodir")
                .join(format!("x.{ext}"))
                .display()
                .to_string(),
            3 => self.out.display().to_string(),
            4 => self.out.join("same.out").display().to_string(),
            _ => self
                .out
                .join(format!("o{}.{ext}", self.rng.gen_range(0..3)))
                .display()
                .to_string(),
        }
    }

    fn maybe(&mut self, p: f64) -> bool {
        self.rng.gen_bool(p)
    }

    /// A random command: a subcommand with its inputs and outputs, then options.
    fn command(&mut self) -> Vec<String> {
        self.used.clear();
        let which = self.rng.gen_range(0..12);
        let mut a = self.subcommand(which);
        self.numeric_options(which, &mut a);
        self.output_options(which, &mut a);
        self.marker_options(which, &mut a);
        self.format_options(which, &mut a);
        a
    }

    /// The subcommand `which` with its inputs and outputs.
    fn subcommand(&mut self, which: u32) -> Vec<String> {
        let s = |x: &str| x.to_string();
        match which {
            0 => vec![s("model"), s("show"), self.pick(self.models)],
            1 => vec![s("inspect"), self.pick(self.trials)],
            2 => vec![s("convert"), self.pick(self.trials), self.output("trc")],
            3 => vec![
                s("ik"),
                self.pick(self.models),
                self.pick(self.trials),
                s("-o"),
                self.output("mot"),
            ],
            4 => vec![
                s("check"),
                self.pick(self.models),
                self.pick(self.trials),
                s("--joints"),
                s("hip"),
            ],
            5 => vec![
                s("synth"),
                self.pick(self.models),
                s("--motion"),
                s("hip"),
                s("-o"),
                self.output("trc"),
                s("--truth"),
                self.output("toml"),
            ],
            6 => vec![
                s("export"),
                s("osim"),
                self.pick(self.models),
                s("-o"),
                self.output("osim"),
            ],
            7 => vec![
                s("calibrate"),
                self.pick(self.models),
                self.pick(self.trials),
                s("--joints"),
                s("hip"),
                s("-o"),
                self.output("toml"),
            ],
            8 => vec![
                s("personalize"),
                s("--static"),
                self.pick(self.trials),
                s("--markers"),
                s("gait2392"),
                s("--side"),
                s("right"),
                s("-o"),
                self.output("toml"),
            ],
            9 => self.bench_past_limits(),
            10 => {
                // Small frame counts only: a valid large one is a legitimately long run.
                let frames = ["2", "5", "0", "-1", "abc", "100001", "1e3"];
                vec![
                    s("demo"),
                    s("--frames"),
                    frames.choose(&mut self.rng).unwrap().to_string(),
                ]
            }
            _ => vec![
                s("report"),
                self.pick(self.models),
                self.pick(self.trials),
                s("-o"),
                self.out.join("rep").display().to_string(),
            ],
        }
    }

    /// `bench` with a size past its limit (a valid size is a legitimately long bench).
    fn bench_past_limits(&mut self) -> Vec<String> {
        let opt = ["--io-frames", "--long-frames", "--rss-frames", "--fit-only"]
            .choose(&mut self.rng)
            .unwrap()
            .to_string();
        let v = ["100000000", "1e9", "-1", "18446744073709551616", "abc"]
            .choose(&mut self.rng)
            .unwrap()
            .to_string();
        vec!["bench".into(), opt, v]
    }

    /// Numeric options of the subcommand, each sometimes, with odd values.
    fn numeric_options(&mut self, which: u32, a: &mut Vec<String>) {
        let numeric: &[&str] = match which {
            2 => &["--filter", "--decimals"],
            3 => &["--filter"],
            4 => &["--filter", "--noise-mm", "--threshold-mm"],
            5 => &["--frames", "--rate", "--perturb-mm", "--white-mm"],
            7 => &[
                "--filter",
                "--bootstrap",
                "--threshold-deg",
                "--marker-prior-sd-mm",
            ],
            8 => &["--window"],
            10 => &["--noise-mm"],
            _ => &[],
        };
        for opt in numeric {
            if self.maybe(0.3) {
                a.push(opt.to_string());
                a.push(self.number());
            }
        }
        if which == 7 && self.maybe(0.2) {
            a.push("--prior-sd".into());
            let v = [
                "hip=1e-200mm",
                "knee=5deg",
                "hip=0mm",
                "hip=NaNmm",
                "nope=5mm",
            ];
            a.push(v.choose(&mut self.rng).unwrap().to_string());
        }
    }

    /// Second outputs, `--force`, `--report`.
    fn output_options(&mut self, which: u32, a: &mut Vec<String>) {
        if which == 3 && self.maybe(0.5) {
            a.push("--errors".into());
            a.push(self.output("csv"));
        }
        if which == 5 && self.maybe(0.2) {
            let t = self.pick(self.trials);
            let i = a.iter().position(|x| x == "hip").unwrap();
            a[i] = format!("gait:{t}");
        }
        // --force may replace only the model: with an output aliasing a trial it must refuse.
        // (Not with the model itself as the output, which --force rightly replaces.)
        if which == 7 && !self.models.contains(&a[6]) && self.maybe(0.3) {
            a.push("--force".into());
        }
        if which == 7 && self.maybe(0.2) {
            a.push("--report".into());
            a.push(self.out.join("crep").display().to_string());
        }
    }

    /// Marker selections, kept markers and label swaps, valid or not.
    fn marker_options(&mut self, which: u32, a: &mut Vec<String>) {
        if which == 2 && self.maybe(0.2) {
            a.push("--markers".into());
            let v = ["RASI,LASI", "NOPE", "", "RASI,RASI"];
            a.push(v.choose(&mut self.rng).unwrap().to_string());
        }
        if which == 7 && self.maybe(0.2) {
            a.push("--keep-markers".into());
            let v = ["RASI", "nope", "RASI,nope", ""];
            a.push(v.choose(&mut self.rng).unwrap().to_string());
        }
        if matches!(which, 3 | 7) && self.maybe(0.2) {
            let v = [
                "RKNE,RANK",
                "RANK,RKNE",
                "RANK,RHEE",
                "RKNE,RANK@5",
                "RKNE,RANK@3-9",
            ];
            for _ in 0..self.rng.gen_range(1..=2) {
                a.push("--swap-labels".into());
                a.push(v.choose(&mut self.rng).unwrap().to_string());
            }
        }
    }

    /// `--json`, `--up`, `--units`.
    fn format_options(&mut self, which: u32, a: &mut Vec<String>) {
        if matches!(which, 0 | 1 | 3 | 4 | 5 | 7) && self.maybe(0.3) {
            a.push("--json".into());
        }
        if matches!(which, 2 | 3 | 4 | 7 | 8 | 11) && self.maybe(0.2) {
            a.push("--up".into());
            let v = ["y", "z", "-z", "x"];
            a.push(v.choose(&mut self.rng).unwrap().to_string());
        }
        if which == 2 && self.maybe(0.3) {
            a.push("--units".into());
            let v = ["mm", "cm", "m", "km"];
            a.push(v.choose(&mut self.rng).unwrap().to_string());
        }
    }

    /// The progress interval for a run: usually unset, sometimes one a run must warn about
    /// once.
    fn progress_seconds(&mut self) -> Option<&'static str> {
        self.maybe(0.1).then(|| {
            *["NaN", "-1", "0", "1e300", "2"]
                .choose(&mut self.rng)
                .unwrap()
        })
    }
}

#[derive(Default, Debug)]
struct Counts {
    runs: usize,
    ok: usize,
    errors: usize,
    usage: usize,
    other: usize,
    /// Refusals whose error is one line naming its cause (all of them: anything else fails).
    clear_refusals: usize,
}

impl Counts {
    fn record(&mut self, code: i32) {
        self.runs += 1;
        match code {
            0 => self.ok += 1,
            1 => self.errors += 1,
            2 => self.usage += 1,
            _ => self.other += 1,
        }
        if code != 0 {
            self.clear_refusals += 1;
        }
    }
}

/// How one run ended.
struct Outcome {
    code: i32,
    stderr: String,
}

/// Runs `jointfit args` (with the progress interval `progress`, if any) and waits at most
/// [`RUN_TIMEOUT_SECONDS`]; a hang or a death by signal fails the test.
fn run_one(args: &[String], progress: Option<&str>) -> Outcome {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_jointfit"));
    cmd.args(args)
        .env(
            "JOINTFIT_PROGRESS",
            if progress.is_some() { "log" } else { "quiet" },
        )
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if let Some(p) = progress {
        cmd.env("JOINTFIT_PROGRESS_SECONDS", p);
    }
    let mut child = cmd.spawn().unwrap();
    // Drain stderr while the child runs (a chatty run must not block on a full pipe).
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut err = String::new();
        use std::io::Read;
        let _ = pipe.read_to_string(&mut err);
        err
    });
    let deadline = Instant::now() + Duration::from_secs(RUN_TIMEOUT_SECONDS);
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("hang: jointfit {args:?} ran over {RUN_TIMEOUT_SECONDS} s");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = reader.join().unwrap();
    let code = status.code();
    assert!(
        code.is_some(),
        "killed by a signal: jointfit {args:?}: {stderr}"
    );
    Outcome {
        code: code.unwrap(),
        stderr,
    }
}

/// What every run must satisfy: no panic, inputs unchanged, no temporary file, nothing
/// written on failure, one error line of bounded length, at most one progress warning.
fn check_outcome(
    args: &[String],
    o: &Outcome,
    input: &Path,
    out: &Path,
    inputs_before: &[(String, Vec<u8>)],
) {
    let err = &o.stderr;
    assert_ne!(o.code, 101, "panic: jointfit {args:?}: {err}");
    assert!(!err.contains("panicked"), "panic: jointfit {args:?}: {err}");
    let inputs_now = jointfit_testkit::snapshot(input);
    assert!(
        inputs_now == inputs_before,
        "input changed: jointfit {args:?}: {err}"
    );
    let left = jointfit_testkit::snapshot(out);
    let temps: Vec<&String> = left
        .iter()
        .chain(inputs_now.iter())
        .map(|(n, _)| n)
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(
        temps.is_empty(),
        "temporary files {temps:?}: jointfit {args:?}"
    );
    let warnings = err
        .lines()
        .filter(|l| l.contains("JOINTFIT_PROGRESS_SECONDS"))
        .count();
    assert!(
        warnings <= 1,
        "progress warned {warnings} times: {args:?}: {err}"
    );
    if o.code == 0 {
        return;
    }
    assert!(
        left.is_empty(),
        "failed (status {}) but wrote {:?}: jointfit {args:?}: {err}",
        o.code,
        left.iter().map(|(n, _)| n).collect::<Vec<_>>()
    );
    let error_lines = err
        .lines()
        .filter(|l| l.starts_with("jointfit: error: "))
        .count();
    assert_eq!(error_lines, 1, "jointfit {args:?}: {err}");
    assert!(
        err.lines().all(|l| l.len() < 1500),
        "a long line: jointfit {args:?}"
    );
}

/// `JOINTFIT_FUZZ_RUNS` / `JOINTFIT_FUZZ_SEED`, else [`RUNS`] / [`SEED`].
fn runs_and_seed() -> (usize, u64) {
    let env = |k: &str| std::env::var(k).ok();
    (
        env("JOINTFIT_FUZZ_RUNS")
            .and_then(|v| v.parse().ok())
            .unwrap_or(RUNS),
        env("JOINTFIT_FUZZ_SEED")
            .and_then(|v| v.parse().ok())
            .unwrap_or(SEED),
    )
}

#[test]
fn fuzz_the_command_line() {
    let (runs, seed) = runs_and_seed();
    let s = Scratch::new("fuzz");
    let (trials, models) = corpus(&s);
    let out = s.dir.join("out");
    let input = s.dir.join("in");
    let mut g = Gen {
        rng: ChaCha8Rng::seed_from_u64(seed),
        used: Vec::new(),
        trials: &trials,
        models: &models,
        out: &out,
    };
    let inputs_before = jointfit_testkit::snapshot(&input);
    let clock = Instant::now();
    let mut counts = Counts::default();
    for _ in 0..runs {
        if clock.elapsed() > Duration::from_secs(BUDGET_SECONDS) {
            break;
        }
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&out).unwrap();
        let args = g.command();
        let progress = g.progress_seconds();
        let outcome = run_one(&args, progress);
        check_outcome(&args, &outcome, &input, &out, &inputs_before);
        counts.record(outcome.code);
    }
    println!(
        "fuzz (seed {seed}): {} inputs tried in {:.1} s: {} succeeded, {} refused with a \
         one-line error ({} errors with status 1, {} usage errors with status 2, {} other \
         statuses); panics 0; no hang, changed input, temporary file or partial output",
        counts.runs,
        clock.elapsed().as_secs_f64(),
        counts.ok,
        counts.clear_refusals,
        counts.errors,
        counts.usage,
        counts.other
    );
    assert!(counts.runs >= 20, "too few runs in the budget: {counts:?}");
    assert!(
        counts.ok > 0 && counts.errors > 0 && counts.usage > 0,
        "{counts:?}"
    );
}
