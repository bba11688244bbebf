//! Corrupted and truncated C3D files: the reader must return `Ok` or `Err`, never panic (and
//! never allocate by an unchecked size, which would abort the process).
//!
//! Mutants of several real sample files (Intel integer, DEC float, SGI/MIPS float, files that
//! need the lenient parameter parser): truncation at every 512-byte boundary and at random
//! lengths, random byte flips biased toward the header and parameter section (where one byte
//! steers the whole parse), and random 16-bit words set to extreme values.
//!
//! `JOINTFIT_C3D_FUZZ_SECS=N cargo test --release -p jointfit-io --test c3d_robustness --
//! --ignored` runs the same mutators for N seconds and prints the number of executions.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

use jointfit_io::c3d::parse_c3d;
use jointfit_testkit::data_dir;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const SAMPLES: &[&str] = &[
    "c3d_reader/btk/MyCube.c3d",
    "c3d_reader/c3dorg/sample_01/Eb015pi.c3d",
    "c3d_reader/c3dorg/sample_01/Eb015vr.c3d",
    "c3d_reader/c3dorg/sample_01/Eb015sr.c3d",
    "c3d_reader/c3dorg/sample_10/TYPE-2.C3D",
    "c3d_reader/c3dorg/sample_27/kyowadengyo.c3d",
    "c3d_reader/btk/badParameterOffset.c3d",
    "c3d_reader/ezc3d/FP_Type3.c3d",
    "c3d_reader/ezc3d/Optotrak.c3d",
];

/// Parses `bytes`; on a panic, returns the panic message.
fn survives(bytes: &[u8]) -> Result<(), String> {
    catch_unwind(AssertUnwindSafe(|| {
        if let Ok(c) = parse_c3d(bytes) {
            // Exercise the derived views too.
            let _ = c.to_trial();
            let _ = c.parameters.strings_continued("POINT", "LABELS");
        }
    }))
    .map_err(|e| {
        e.downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    })
}

/// One random mutant of `orig` (a description and the bytes).
fn mutate(orig: &[u8], rng: &mut ChaCha8Rng) -> (String, Vec<u8>) {
    let mut b = orig.to_vec();
    if b.len() < 2 {
        return ("unchanged (too short to mutate)".into(), b);
    }
    // The header and parameter section are where single bytes matter most.
    let hot = (usize::from(orig[0]).max(2) * 512 + 4096).min(orig.len());
    match rng.gen_range(0..4) {
        0 => {
            let n = rng.gen_range(0..=orig.len());
            b.truncate(n);
            (format!("truncate to {n}"), b)
        }
        1 | 2 => {
            let k = rng.gen_range(1..=8);
            let mut what = Vec::new();
            for _ in 0..k {
                let i = if rng.gen_bool(0.7) {
                    rng.gen_range(0..hot)
                } else {
                    rng.gen_range(0..b.len())
                };
                let v: u8 = rng.gen();
                what.push(format!("[{i}]={v}"));
                b[i] = v;
            }
            (format!("bytes {}", what.join(" ")), b)
        }
        _ => {
            let i = rng.gen_range(0..hot - 1);
            let v: u16 = [0, 1, 0x7fff, 0x8000, 0xffff][rng.gen_range(0..5)];
            b[i..i + 2].copy_from_slice(&v.to_le_bytes());
            (format!("word at {i} = {v:#x}"), b)
        }
    }
}

fn load(data: &Path) -> Vec<(String, Vec<u8>)> {
    SAMPLES
        .iter()
        .map(|rel| {
            let p = data.join(rel);
            (
                rel.to_string(),
                std::fs::read(&p).unwrap_or_else(|e| panic!("{rel}: {e}")),
            )
        })
        .collect()
}

#[test]
fn truncation_at_every_block_and_random_lengths_never_panics() {
    let Some(data) = data_dir() else { return };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut failures = Vec::new();
    let mut runs = 0;
    for (name, orig) in load(&data) {
        let mut cuts: Vec<usize> = (0..=orig.len()).step_by(512).collect();
        cuts.extend((0..40).map(|_| rng.gen_range(0..orig.len())));
        for n in cuts {
            runs += 1;
            if let Err(msg) = survives(&orig[..n]) {
                failures.push(format!("{name} truncated to {n}: {msg}"));
            }
        }
    }
    println!("{runs} truncated files parsed");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn random_corruption_never_panics() {
    let Some(data) = data_dir() else { return };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut failures = Vec::new();
    for (name, orig) in load(&data) {
        for _ in 0..300 {
            let (what, bytes) = mutate(&orig, &mut rng);
            if let Err(msg) = survives(&bytes) {
                failures.push(format!("{name} {what}: {msg}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Small handmade inputs: every one must be an error or a read, never a panic.
#[test]
fn tiny_and_degenerate_inputs() {
    let mut cases: Vec<Vec<u8>> = vec![vec![], vec![0; 511], vec![0; 512], vec![0xff; 2048]];
    // Parameter block 1 (the header itself), processor byte valid.
    let mut h = vec![0u8; 1024];
    h[0] = 1;
    h[3] = 84;
    cases.push(h.clone());
    // Parameter block 2, no records, data block 0.
    let mut h2 = vec![0u8; 1024];
    h2[0] = 2;
    h2[512 + 3] = 84;
    cases.push(h2.clone());
    // Huge header counts with a tiny file.
    let mut h3 = h2.clone();
    for w in [1usize, 2, 3, 4, 8, 9] {
        h3[2 * w..2 * w + 2].copy_from_slice(&0xffffu16.to_le_bytes());
    }
    cases.push(h3);
    for (i, c) in cases.iter().enumerate() {
        assert!(survives(c).is_ok(), "case {i} panicked");
    }
}

/// Long randomized run (ignored by default): see the module docs.
#[test]
#[ignore]
fn long_fuzz_session() {
    let Some(data) = data_dir() else { return };
    let secs: u64 = std::env::var("JOINTFIT_C3D_FUZZ_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    let seed: u64 = std::env::var("JOINTFIT_C3D_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(11);
    let files = load(&data);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let end = Instant::now() + Duration::from_secs(secs);
    let (mut runs, mut ok, mut bytes_total) = (0u64, 0u64, 0u64);
    let mut failures = Vec::new();
    while Instant::now() < end {
        let (name, orig) = &files[rng.gen_range(0..files.len())];
        let (what, mut bytes) = mutate(orig, &mut rng);
        // Stack a second mutation now and then.
        if rng.gen_bool(0.3) && !bytes.is_empty() {
            bytes = mutate(&bytes, &mut rng).1;
        }
        runs += 1;
        bytes_total += bytes.len() as u64;
        if parse_c3d(&bytes).is_ok() {
            ok += 1;
        }
        if let Err(msg) = survives(&bytes) {
            failures.push(format!("{name} {what}: {msg}"));
        }
    }
    println!(
        "fuzz: {runs} mutants in {secs} s (seed {seed}), {ok} parsed Ok, {} MB total, {} panics",
        bytes_total / 1_000_000,
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
