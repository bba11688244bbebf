//! Times the TRC reader and the `.mot` writer on a long trial (a development aid; the
//! figures of record come from `jointfit bench`).
//!
//! `cargo run --release -p jointfit-io --example io_timing -- SOURCE.trc FRAMES RUNS [MARKERS]`
//! repeats SOURCE to FRAMES frames, writes it as `bench_perf::ik_io` does, then reads it RUNS
//! times (all columns, and only the first MARKERS labels when given), formats a 13-column
//! table of FRAMES rows and writes it to disk (joined then written, and chunk by chunk with
//! `write_sto_to`, each synced); prints the minimum of each.

use std::time::Instant;

use jointfit::trial::Trial;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let source = std::path::Path::new(&args[1]);
    let frames: usize = args[2].parse().unwrap();
    let runs: usize = args[3].parse().unwrap();
    let keep: Option<usize> = args.get(4).map(|s| s.parse().unwrap());
    let trial = jointfit_io::trc::read_trc(source).unwrap();
    let n = trial.n_frames();
    let positions: Vec<_> = (0..frames)
        .flat_map(|f| trial.frame(f % n).iter().copied())
        .collect();
    let long = Trial::new(trial.labels().to_vec(), trial.rate(), 1, positions).unwrap();
    // IO_TIMING_TRC: a long file written before, read as it is (for profilers).
    let given = std::env::var_os("IO_TIMING_TRC").map(std::path::PathBuf::from);
    let path = given.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("io-timing-{}.trc", std::process::id()))
    });
    if !path.exists() {
        let text = jointfit_io::trc::format_trc(&long, "long.trc", &Default::default()).unwrap();
        std::fs::write(&path, &text).unwrap();
    }
    println!("{} markers", trial.labels().len());
    // Minimum wall time, and minimum CPU time of the process (all threads): less noisy on
    // a loaded machine.
    let min_of = |f: &dyn Fn() -> usize| {
        let mut best = f64::INFINITY;
        let mut best_cpu = f64::INFINITY;
        let mut check = 0;
        for _ in 0..runs {
            let c = cpu_seconds();
            let t = Instant::now();
            check = f();
            best = best.min(t.elapsed().as_secs_f64());
            best_cpu = best_cpu.min(cpu_seconds() - c);
        }
        (format!("{best:.4} s wall, {best_cpu:.4} s CPU"), check)
    };
    let (t, c) = min_of(&|| std::fs::read(&path).unwrap().len());
    println!("fs::read          {t} ({c})");
    let (t, c) = min_of(&|| jointfit_io::trc::read_trc(&path).unwrap().labels().len());
    println!("read_trc all      {t} ({c} markers)");
    if let Some(k) = keep {
        let labels: Vec<String> = trial.labels()[..k].to_vec();
        let (t, c) = min_of(&|| {
            jointfit_io::trc::read_trc_selected(
                &path,
                Some(&|l: &str| labels.iter().any(|x| x == l)),
            )
            .unwrap()
            .trial
            .labels()
            .len()
        });
        println!("read_trc selected {t} ({c} markers)");
    }
    let cols: Vec<String> = (0..12).map(|k| format!("q{k}")).collect();
    let refs: Vec<&str> = cols.iter().map(String::as_str).collect();
    let mut table = jointfit_io::sto::Table::new("Coordinates", &refs, true);
    for f in 0..frames {
        let mut row = vec![f as f64 / 100.0];
        row.extend((0..12).map(|k| ((f * 12 + k) as f64 * 0.013).sin() * 57.29577951308232));
        table.rows.push(row);
    }
    let (t, c) = min_of(&|| jointfit_io::sto::format_sto(&table).unwrap().len());
    println!("format_sto        {t} ({c} bytes)");
    // The `.mot` to disk: joined then written (before) against written chunk by chunk.
    let mot = path.with_extension("mot");
    let (t, _) = min_of(&|| {
        let text = jointfit_io::sto::format_sto(&table).unwrap();
        let mut f = std::fs::File::create(&mot).unwrap();
        std::io::Write::write_all(&mut f, text.as_bytes()).unwrap();
        f.sync_all().unwrap();
        0
    });
    println!("format + write    {t}");
    let (t, _) = min_of(&|| {
        let mut f = std::fs::File::create(&mot).unwrap();
        jointfit_io::sto::write_sto_to(&mut f, &table, &mot).unwrap();
        f.sync_all().unwrap();
        0
    });
    println!("write_sto_to      {t}");
    let _ = std::fs::remove_file(&mot);
    if given.is_none() {
        let _ = std::fs::remove_file(&path);
    }
}

/// CPU time of this process, all threads (s; 0 where not measured).
#[cfg(unix)]
fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

#[cfg(not(unix))]
fn cpu_seconds() -> f64 {
    0.0
}
