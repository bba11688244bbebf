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

/// Writes the corpus into `s.dir/in` and returns (trial-like files, model-like files).
fn corpus(s: &Scratch) -> (Vec<String>, Vec<String>) {
    let input = s.dir.join("in");
    std::fs::create_dir_all(input.join("sub")).unwrap();
    let good_trc = std::fs::read_to_string(s.dir.join("t.trc")).unwrap();
    let good_toml = std::fs::read_to_string(s.dir.join("m.toml")).unwrap();
    let w = |name: &str, bytes: &[u8]| std::fs::write(input.join(name), bytes).unwrap();
    w("t.trc", good_trc.as_bytes());
    w("m.toml", good_toml.as_bytes());
    w("trunc.trc", &good_trc.as_bytes()[..good_trc.len() * 2 / 5]);
    w("empty.trc", b"");
    let map_data = |f: &dyn Fn(&str) -> String| -> String {
        good_trc
            .lines()
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
    };
    w("huge.trc", map_data(&|_| "1e300".into()).as_bytes());
    w("nan.trc", map_data(&|_| "NaN".into()).as_bytes());
    w("blank.trc", map_data(&|_| String::new()).as_bytes());
    let mut lines: Vec<String> = good_trc.lines().map(str::to_string).collect();
    lines[2] = lines[2].replacen("10", "1e300", 2);
    w("rate.trc", lines.join("\n").as_bytes());
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let junk: Vec<u8> = (0..2048).map(|_| rng.gen()).collect();
    w("junk.c3d", &junk);
    w("empty.c3d", b"");
    let mut header = vec![0u8; 1536];
    header[0] = 2;
    header[1] = 0x50;
    w("header.c3d", &header);
    w("bad.toml", b"name = \"x\"\n[[bad\n");
    w(
        "nan.toml",
        good_toml
            .replacen("nominal = ", "nominal = nan #", 1)
            .as_bytes(),
    );
    w(
        "long.toml",
        format!("name = \"{}\"\n", "y".repeat(200_000)).as_bytes(),
    );
    // A model without markers.
    let mut bare = jointfit::model::ModelSpec::from_toml(&good_toml).unwrap();
    bare.markers.clear();
    w("bare.toml", bare.to_toml().as_bytes());
    // Units off by a tenth and by ten (coordinates scaled, units line unchanged).
    w("tenth.trc", map_data(&|c| scale_number(c, 0.1)).as_bytes());
    w("ten.trc", map_data(&|c| scale_number(c, 10.0)).as_bytes());
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(input.join("t.trc"), input.join("link.trc")).unwrap();
        std::fs::hard_link(input.join("t.trc"), input.join("hard.trc")).unwrap();
    }
    let p = |n: &str| input.join(n).to_str().unwrap().to_string();
    let trials = [
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
    ]
    .iter()
    .map(|n| p(n))
    .collect();
    let mut models: Vec<String> = [
        "m.toml",
        "m.toml",
        "m.toml",
        "bad.toml",
        "nan.toml",
        "long.toml",
        "bare.toml",
    ]
    .iter()
    .map(|n| p(n))
    .collect();
    models.push("lower-limb-right".into());
    models.push("no-such-model".into());
    (trials, models)
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

    fn command(&mut self) -> Vec<String> {
        let s = |x: &str| x.to_string();
        self.used.clear();
        let which = self.rng.gen_range(0..12);
        let mut a: Vec<String> = match which {
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
            9 => {
                // Sizes past their limits only: a valid size is a legitimately long bench.
                let opt = ["--io-frames", "--long-frames", "--rss-frames", "--fit-only"]
                    .choose(&mut self.rng)
                    .unwrap()
                    .to_string();
                let v = ["100000000", "1e9", "-1", "18446744073709551616", "abc"]
                    .choose(&mut self.rng)
                    .unwrap()
                    .to_string();
                vec![s("bench"), opt, v]
            }
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
        };
        // Options, each sometimes, with odd values.
        let numeric: &[&str] = match which {
            2 => &["--filter", "--decimals"],
            3 => &["--filter"],
            4 => &["--filter", "--noise-mm", "--threshold-mm"],
            5 => &["--frames", "--rate", "--perturb-mm", "--white-mm"],
            7 => &["--filter", "--bootstrap", "--threshold-deg"],
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
        if which == 3 && self.maybe(0.5) {
            a.push(s("--errors"));
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
            a.push(s("--force"));
        }
        if which == 7 && self.maybe(0.2) {
            a.push(s("--report"));
            a.push(self.out.join("crep").display().to_string());
        }
        if matches!(which, 0 | 1 | 3 | 4 | 5 | 7) && self.maybe(0.3) {
            a.push(s("--json"));
        }
        if matches!(which, 2 | 3 | 4 | 7 | 8 | 11) && self.maybe(0.2) {
            a.push(s("--up"));
            a.push(
                ["y", "z", "-z", "x"]
                    .choose(&mut self.rng)
                    .unwrap()
                    .to_string(),
            );
        }
        if which == 2 && self.maybe(0.3) {
            a.push(s("--units"));
            a.push(
                ["mm", "cm", "m", "km"]
                    .choose(&mut self.rng)
                    .unwrap()
                    .to_string(),
            );
        }
        if which == 2 && self.maybe(0.2) {
            a.push(s("--markers"));
            a.push(
                ["RASI,LASI", "NOPE", "", "RASI,RASI"]
                    .choose(&mut self.rng)
                    .unwrap()
                    .to_string(),
            );
        }
        a
    }
}

#[derive(Default, Debug)]
struct Counts {
    runs: usize,
    ok: usize,
    errors: usize,
    usage: usize,
    other: usize,
}

#[test]
fn fuzz_the_command_line() {
    let runs: usize = std::env::var("JOINTFIT_FUZZ_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(RUNS);
    let seed: u64 = std::env::var("JOINTFIT_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SEED);
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
        let mut child = Command::new(env!("CARGO_BIN_EXE_jointfit"))
            .args(&args)
            .env("JOINTFIT_PROGRESS", "quiet")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
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
        let mut err = String::new();
        use std::io::Read;
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        counts.runs += 1;
        let code = status.code();
        assert_ne!(code, Some(101), "panic: jointfit {args:?}: {err}");
        assert!(!err.contains("panicked"), "panic: jointfit {args:?}: {err}");
        assert!(
            code.is_some(),
            "killed by a signal: jointfit {args:?}: {err}"
        );
        assert!(
            jointfit_testkit::snapshot(&input) == inputs_before,
            "input changed: jointfit {args:?}: {err}"
        );
        let left = jointfit_testkit::snapshot(&out);
        let inputs_now = jointfit_testkit::snapshot(&input);
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
        match code {
            Some(0) => counts.ok += 1,
            Some(c) => {
                assert!(
                    left.is_empty(),
                    "failed (status {c}) but wrote {:?}: jointfit {args:?}: {err}",
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
                match c {
                    1 => counts.errors += 1,
                    2 => counts.usage += 1,
                    _ => counts.other += 1,
                }
            }
            None => unreachable!(),
        }
    }
    println!(
        "fuzz (seed {seed}): {} runs in {:.1} s: {} succeeded, {} errors (status 1), {} usage \
         errors (status 2), {} other statuses; no panic, hang, changed input, temporary file \
         or partial output",
        counts.runs,
        clock.elapsed().as_secs_f64(),
        counts.ok,
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
