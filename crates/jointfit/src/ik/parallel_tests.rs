//! The trial loop in parallel chunks: the same bits on any number of threads, exact on
//! noiseless data across chunk boundaries, and wrong local minima re-solved from the
//! neighbours (`crate::ik::repair`).

use crate::ik::trial_fit::chunk_ranges;
use crate::ik::trial_fit::solve_trial;
use crate::ik::trial_fit::TrialFit;
use crate::ik::{warm_started_coords, FrameStatus, IkOptions, MarkerMap};
use crate::kinematics::synth;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;

use super::tests::{motion, synthetic_trial};

fn on_threads(threads: usize, f: impl FnOnce() -> TrialFit + Send) -> TrialFit {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn bits(fit: &TrialFit) -> Vec<u64> {
    fit.coords
        .iter()
        .chain(&fit.errors)
        .flatten()
        .map(|v| v.to_bits())
        .collect()
}

#[test]
fn chunks_cover_the_trial_in_order_whatever_the_threads() {
    for n in [0, 1, 143, 1023, 1024, 5000, 10_000, 1_000_000] {
        let chunks = chunk_ranges(n, false);
        assert_eq!(chunks.first().map_or(0, |c| c.start), 0, "{n}");
        assert_eq!(chunks.last().map_or(0, |c| c.end), n, "{n}");
        for w in chunks.windows(2) {
            assert_eq!(w[0].end, w[1].start, "{n}");
        }
        assert!(chunks.len() <= 32);
        if n >= 1024 {
            assert!(chunks.iter().all(|c| c.len() >= 512), "{n}");
        } else {
            assert!(chunks.len() <= 1, "{n}");
        }
        assert_eq!(chunk_ranges(n, true).len(), 1);
    }
}

/// Noisy markers (white, 2 mm), 1600 frames: 3 chunks. One thread and three threads give
/// identical bits; the chunked result equals the single-chunk one (holding undetermined
/// coordinates solves the trial as one chunk and changes nothing else here) to 1e-7, ten
/// times the step tolerance.
#[test]
fn same_bits_on_one_and_three_threads() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let s = synth::synthetic_trial(
        &model,
        &p,
        1600,
        100.0,
        |f| motion(&model, f, 0.4),
        synth::Noise::White { sd: 0.002 },
        11,
    );
    let map = MarkerMap::by_name(&model, s.trial.labels()).unwrap();
    let opts = IkOptions::default();
    let one = on_threads(1, || {
        solve_trial(&model, &p, &s.trial, &map, &opts).unwrap()
    });
    let three = on_threads(3, || {
        solve_trial(&model, &p, &s.trial, &map, &opts).unwrap()
    });
    assert_eq!(bits(&one), bits(&three));
    assert_eq!(one.frames, three.frames);
    let serial_opts = IkOptions {
        hold_undetermined: true,
        ..opts
    };
    let serial = solve_trial(&model, &p, &s.trial, &map, &serial_opts).unwrap();
    assert!(one.frames.iter().all(|f| f.solved()));
    for f in 0..1600 {
        for (a, b) in one.coords[f].iter().zip(&serial.coords[f]) {
            assert!((a - b).abs() < 1e-7, "frame {f}: {a} vs {b}");
        }
    }
}

/// Noiseless markers: every frame exact, the seeded chunk starts included.
#[test]
fn exact_across_chunk_boundaries() {
    let model = Model::compile(&lower_limb(Side::Left)).unwrap();
    let p = model.nominal_params();
    let (trial, truth) = synthetic_trial(&model, &p, 1100, 2.0);
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let fit = solve_trial(&model, &p, &trial, &map, &IkOptions::default()).unwrap();
    assert_eq!(chunk_ranges(1100, false).len(), 2);
    for (f, q) in truth.iter().enumerate() {
        assert_eq!(fit.frames[f].status, FrameStatus::Converged, "frame {f}");
        for (a, b) in fit.coords[f].iter().zip(q) {
            assert!((a - b).abs() < 1e-7, "frame {f}: {a} vs {b}");
        }
    }
}

/// The calibration's starting coordinates: two noiseless trials back to back (each seeded at
/// its first frame), 1100 frames in 2 chunks: exact, and the same bits on one and three
/// threads.
#[test]
fn warm_started_coords_are_exact_and_thread_independent() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let (a, truth_a) = synthetic_trial(&model, &p, 700, 0.0);
    let (b, truth_b) = synthetic_trial(&model, &p, 400, 3.0);
    let mut frames = Vec::new();
    for t in [&a, &b] {
        let map = MarkerMap::by_name(&model, t.labels()).unwrap();
        for f in 0..t.n_frames() {
            let mut targets = Vec::new();
            map.targets(t, f, &mut targets);
            frames.push(targets);
        }
    }
    let opts = IkOptions::default();
    let run = || warm_started_coords(&model, &p, &frames, |f| f == 700, &opts);
    let pool = |k: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .unwrap()
    };
    let one = pool(1).install(run);
    let three = pool(3).install(run);
    let flat = |q: &Vec<Vec<f64>>| q.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(flat(&one), flat(&three));
    for (f, truth) in truth_a.iter().chain(&truth_b).enumerate() {
        for (x, y) in one[f].iter().zip(truth) {
            assert!((x - y).abs() < 1e-7, "frame {f}: {x} vs {y}");
        }
    }
}
