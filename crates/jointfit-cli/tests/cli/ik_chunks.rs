//! Whole-trial IK in parallel chunks (`jointfit::ik::trial_fit::solve_trial`: two from 128 frames
//! on) against the same trial solved as one chunk: every frame's coordinates agree within the
//! solver's tolerance, on OpenCap's walking1 with its landmark model, as read and with gaps
//! cut across the chunk boundary (frames no marker set can solve, so the chunks restart from
//! seeds), and the chunked result has the same bits on one and two threads. The one-chunk
//! solve is the trial fed frame by frame to `jointfit::ik::stream::StreamingIk`, which gives
//! the one-chunk trial loop bit for bit (the core's stream tests).

use jointfit::ik::stream::StreamingIk;
use jointfit::ik::trial_fit::solve_trial;
use jointfit::ik::trial_fit::TrialFit;
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::model::Model;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_testkit::scratch;

/// Largest coordinate difference allowed between the chunked and the one-chunk solve (rad
/// or m): ten times the step tolerance of `IkOptions` (1e-8), 6e-6 degrees.
const TOLERANCE: f64 = 1e-7;

fn on_threads(threads: usize, f: impl FnOnce() -> TrialFit + Send) -> TrialFit {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Every frame of `trial` in order through one stream (at the model's nominal parameters):
/// the trial as one chunk.
fn one_chunk(model: &Model, trial: &Trial, opts: &IkOptions) -> TrialFit {
    let mut s = StreamingIk::new(model, trial.labels(), UpAxis::Y, *opts).unwrap();
    assert!(s.last().held.is_empty(), "the stream holds no coordinate");
    let mut out = TrialFit {
        coords: Vec::new(),
        frames: Vec::new(),
        errors: Vec::new(),
    };
    for f in 0..trial.n_frames() {
        let frame = s.update(trial.time(f), trial.frame(f)).unwrap();
        out.coords.push(frame.coords.to_vec());
        out.frames.push(frame.fit.unwrap().clone());
        out.errors.push(frame.errors.to_vec());
    }
    out
}

/// Solves `trial` in its chunks and as one; asserts the chunked solve has two or more chunks,
/// the same solved frames, coordinates within [`TOLERANCE`], and the same bits on one and
/// two threads. Returns the largest difference.
fn chunked_equals_one_chunk(model: &Model, trial: &Trial) -> f64 {
    let p = model.nominal_params();
    let opts = IkOptions::default();
    let map = MarkerMap::allowing_absent(model, trial.labels()).0;
    let n = trial.n_frames();
    assert!(n >= 128, "{n} frames: fewer than two chunks");
    let one = one_chunk(model, trial, &opts);
    let chunked = on_threads(2, || solve_trial(model, &p, trial, &map, &opts).unwrap());
    let serial = on_threads(1, || solve_trial(model, &p, trial, &map, &opts).unwrap());
    let bits = |fit: &TrialFit| {
        fit.coords
            .iter()
            .flatten()
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&chunked), bits(&serial));
    let mut worst = 0.0f64;
    for f in 0..n {
        assert_eq!(
            one.frames[f].solved(),
            chunked.frames[f].solved(),
            "frame {f}: {:?} vs {:?}",
            one.frames[f].status,
            chunked.frames[f].status
        );
        if !one.frames[f].solved() {
            continue;
        }
        for (a, b) in one.coords[f].iter().zip(&chunked.coords[f]) {
            worst = worst.max((a - b).abs());
            assert!((a - b).abs() < TOLERANCE, "frame {f}: {a} vs {b}");
        }
    }
    worst
}

#[test]
fn chunked_ik_equals_one_chunk_on_walking1() {
    let tmp = scratch("ik-chunks");
    let Some((subject, walk)) = super::opencap_subject(tmp.path(), "subject.toml") else {
        return;
    };
    let model = jointfit_io::model_file::load_model(subject.to_str().unwrap()).unwrap();
    let trial = jointfit_io::trc::read_trc(&walk).unwrap();
    assert_eq!(trial.n_frames(), 143);
    let worst = chunked_equals_one_chunk(&model, &trial);
    eprintln!("walking1: largest difference {worst:.2e}");

    // Gaps: the right shank's markers missing in frames 66–76 (across the boundary at 71:
    // those frames cannot be solved, and each chunk restarts from a seed after them), one
    // thigh marker in frames 0–20 and one foot marker in frames 60–100.
    let mut gappy = trial.clone();
    let names: Vec<String> = model.markers().iter().map(|m| m.name.clone()).collect();
    let segment_of = |name: &str| {
        let j = model.markers().iter().position(|m| m.name == name).unwrap();
        model.segments()[model.markers()[j].segment.0].name.clone()
    };
    let mut cut = |name: &str, frames: std::ops::Range<usize>| {
        let k = gappy.index_of(name).unwrap();
        let mut t = gappy.trajectory(k);
        for f in frames {
            t[f] = nalgebra::Vector3::repeat(f64::NAN);
        }
        gappy.set_trajectory(k, &t);
    };
    let mut by_segment: std::collections::BTreeMap<String, Vec<&String>> = Default::default();
    for name in names.iter().filter(|n| trial.labels().contains(n)) {
        by_segment.entry(segment_of(name)).or_default().push(name);
    }
    let shank = by_segment
        .iter()
        .find(|(s, _)| s.contains("shank") || s.contains("tibia"))
        .map(|(_, v)| v.clone())
        .expect("a shank segment");
    for name in &shank {
        cut(name, 66..77);
    }
    let thigh = by_segment
        .iter()
        .find(|(s, _)| s.contains("thigh") || s.contains("femur"))
        .map(|(_, v)| v[0].clone())
        .expect("a thigh segment");
    cut(&thigh, 0..21);
    let foot = by_segment
        .iter()
        .find(|(s, _)| s.contains("foot") || s.contains("calc"))
        .map(|(_, v)| v[0].clone())
        .expect("a foot segment");
    cut(&foot, 60..101);
    let worst = chunked_equals_one_chunk(&model, &gappy);
    eprintln!("walking1 with gaps: largest difference {worst:.2e}");
}
