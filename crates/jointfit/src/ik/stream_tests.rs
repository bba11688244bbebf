//! Streaming inverse kinematics (`crate::ik::stream::StreamingIk`) against the trial loop on the
//! same frames: bit for bit the one-chunk solve (gaps, a gross error, a non-finite sample,
//! held coordinates), within ten step tolerances of the chunked `solve_trial`, samples rotated
//! from the laboratory's vertical as a trial's reader rotates them, and bad frames refused
//! without disturbing the stream.

use crate::ik::stream::StreamingIk;
use crate::ik::trial_fit::solve_trial;
use crate::ik::trial_fit::solve_trial_in_chunks;
use crate::ik::trial_fit::trial_chunk_ranges;
use crate::ik::trial_fit::TrialFit;
use crate::ik::{FrameStatus, IkError, IkOptions, MarkerMap};
use crate::kinematics::synth;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;
use crate::spatial::up_axis_rotation;
use crate::spatial::UpAxis;
use crate::trial::Trial;
use nalgebra::Vector3;

use super::tests::motion;

/// Largest coordinate difference allowed between a frame solved from another start and the
/// stream's (rad or m): ten times the step tolerance of `IkOptions` (1e-8).
const TOLERANCE: f64 = 1e-7;

/// A noisy synthetic walk (white noise, 2 mm) of `frames` frames at 100 Hz.
fn noisy_walk(model: &Model, p: &[f64], frames: usize) -> Trial {
    synth::synthetic_trial(
        model,
        p,
        frames,
        100.0,
        |f| motion(model, f, 0.4),
        synth::Noise::White { sd: 0.002 },
        5,
    )
    .trial
}

/// Every frame of `trial` through a stream on the model's own labels (Y up).
fn streamed(model: &Model, p: &[f64], trial: &Trial, opts: &IkOptions) -> TrialFit {
    let mut s =
        StreamingIk::with_params(model.clone(), p.to_vec(), trial.labels(), UpAxis::Y, *opts)
            .unwrap();
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

fn bits(rows: &[Vec<f64>]) -> Vec<u64> {
    rows.iter().flatten().map(|v| v.to_bits()).collect()
}

fn set(
    trial: &mut Trial,
    label: &str,
    frames: std::ops::Range<usize>,
    v: impl Fn(Vector3<f64>) -> Vector3<f64>,
) {
    let k = trial.index_of(label).unwrap();
    let mut t = trial.trajectory(k);
    for f in frames {
        t[f] = v(t[f]);
    }
    trial.set_trajectory(k, &t);
}

/// Every marker of the foot missing over `frames`.
fn blank_foot(model: &Model, trial: &mut Trial, frames: std::ops::Range<usize>) {
    for m in model.markers() {
        if model.segments()[m.segment.0].name == "foot" {
            set(trial, &m.name, frames.clone(), |_| {
                Vector3::repeat(f64::NAN)
            });
        }
    }
}

/// Gaps that leave the foot unsolvable (frames 40–44), a marker 30 cm off (a gross error,
/// rejected) and a non-finite sample (missing, as a reader gives it): the stream gives the one-chunk trial loop's bits, its
/// statuses and its rejections, frame by frame.
#[test]
fn stream_equals_the_one_chunk_trial_loop_bit_for_bit() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let mut trial = noisy_walk(&model, &p, 120);
    blank_foot(&model, &mut trial, 40..45);
    let second = model.markers()[1].name.clone();
    set(&mut trial, &second, 70..71, |m| {
        m + Vector3::new(0.3, 0.0, 0.0)
    });
    let third = model.markers()[2].name.clone();
    set(&mut trial, &third, 90..91, |m| {
        Vector3::new(m.x, f64::INFINITY, m.z)
    });
    // As a file's reader gives it: a sample with a non-finite coordinate is missing.
    let trial = Trial::new(
        trial.labels().to_vec(),
        trial.rate(),
        0,
        (0..trial.n_frames())
            .flat_map(|f| trial.frame(f).to_vec())
            .collect(),
    )
    .unwrap();
    let opts = IkOptions::default();
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let n = trial.n_frames();
    let batch = solve_trial_in_chunks(
        &model,
        &p,
        &trial,
        &map,
        &opts,
        std::slice::from_ref(&(0..n)),
    )
    .unwrap();
    let stream = streamed(&model, &p, &trial, &opts);
    // (Debug text: an unsolved frame's cost is NaN, which `==` never equals.)
    assert_eq!(
        format!("{:?}", stream.frames),
        format!("{:?}", batch.frames)
    );
    assert_eq!(bits(&stream.coords), bits(&batch.coords));
    assert_eq!(bits(&stream.errors), bits(&batch.errors));
    // The cases this test is about did happen.
    assert!((40..45).all(|f| matches!(stream.frames[f].status, FrameStatus::Undetermined { .. })));
    assert!(stream.frames[46].solved());
    assert_eq!(stream.frames[70].rejected, vec![1]);
    assert!(stream.frames[90].solved() && stream.errors[90][2].is_nan());
    assert!(stream.frames[90].rejected.is_empty());
}

/// With `hold_undetermined` the trial loop is one chunk: the stream equals `solve_trial`
/// itself, held coordinates included.
#[test]
fn stream_equals_solve_trial_holding_undetermined_coordinates() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let mut trial = noisy_walk(&model, &p, 200);
    blank_foot(&model, &mut trial, 150..160);
    let opts = IkOptions {
        hold_undetermined: true,
        ..IkOptions::default()
    };
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let batch = solve_trial(&model, &p, &trial, &map, &opts).unwrap();
    let stream = streamed(&model, &p, &trial, &opts);
    assert_eq!(
        format!("{:?}", stream.frames),
        format!("{:?}", batch.frames)
    );
    assert_eq!(bits(&stream.coords), bits(&batch.coords));
    assert!((150..160).all(|f| stream.frames[f].solved() && !stream.frames[f].held.is_empty()));
}

/// 1600 frames: `solve_trial` cuts them into three chunks and seeds each. Frames of the
/// first chunk have the stream's bits; every frame agrees within [`TOLERANCE`].
#[test]
fn stream_agrees_with_the_chunked_trial_loop_within_tolerance() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let trial = noisy_walk(&model, &p, 1600);
    let chunks = trial_chunk_ranges(trial.n_frames(), false);
    assert_eq!(chunks.len(), 3);
    let opts = IkOptions::default();
    let map = MarkerMap::by_name(&model, trial.labels()).unwrap();
    let batch = solve_trial(&model, &p, &trial, &map, &opts).unwrap();
    let stream = streamed(&model, &p, &trial, &opts);
    assert_eq!(
        bits(&stream.coords[chunks[0].clone()]),
        bits(&batch.coords[chunks[0].clone()])
    );
    let mut worst = 0.0f64;
    for f in 0..trial.n_frames() {
        assert!(stream.frames[f].solved() && batch.frames[f].solved(), "{f}");
        for (a, b) in stream.coords[f].iter().zip(&batch.coords[f]) {
            worst = worst.max((a - b).abs());
        }
    }
    eprintln!("stream vs chunked solve_trial: largest difference {worst:.2e}");
    assert!(worst < TOLERANCE, "{worst}");
}

/// Samples in a Z-up laboratory, rotated by the stream, give the bits of the trial rotated
/// as a file's reader rotates it (`Trial::rotate`).
#[test]
fn stream_rotates_from_the_laboratory_vertical() {
    let model = Model::compile(&lower_limb(Side::Left)).unwrap();
    let p = model.nominal_params();
    let trial = noisy_walk(&model, &p, 60);
    // The same markers as a Z-up laboratory records them.
    let mut lab = trial.clone();
    lab.rotate(&up_axis_rotation(UpAxis::Z).transpose());
    let mut back = lab.clone();
    back.rotate(&up_axis_rotation(UpAxis::Z));
    let opts = IkOptions::default();
    let map = MarkerMap::by_name(&model, back.labels()).unwrap();
    let batch = solve_trial_in_chunks(
        &model,
        &p,
        &back,
        &map,
        &opts,
        std::slice::from_ref(&(0..60)),
    )
    .unwrap();
    let mut s =
        StreamingIk::with_params(model.clone(), p.clone(), lab.labels(), UpAxis::Z, opts).unwrap();
    assert_streams_as_batch(&batch.coords, |f| {
        s.update(lab.time(f), lab.frame(f)).unwrap().coords.to_vec()
    });
}

/// Feed labels in another order, with extra labels and a model marker missing: the stream
/// pairs them by name as the trial loop does.
#[test]
fn stream_pairs_labels_by_name() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let trial = noisy_walk(&model, &p, 30);
    let absent = model.markers()[3].name.clone();
    let mut labels: Vec<String> = trial
        .labels()
        .iter()
        .rev()
        .filter(|l| **l != absent)
        .cloned()
        .collect();
    labels.insert(2, "EXTRA".to_string());
    let feed = |f: usize| -> Vec<Vector3<f64>> {
        labels
            .iter()
            .map(|l| match trial.index_of(l).ok() {
                Some(k) => trial.frame(f)[k],
                None => Vector3::new(5.0, 5.0, 5.0),
            })
            .collect()
    };
    let reordered = Trial::new(
        labels.clone(),
        trial.rate(),
        0,
        (0..30).flat_map(feed).collect(),
    )
    .unwrap();
    let opts = IkOptions::default();
    let (map, missing) = MarkerMap::allowing_absent(&model, reordered.labels());
    assert_eq!(missing, vec![absent.clone()]);
    let batch = solve_trial_in_chunks(
        &model,
        &p,
        &reordered,
        &map,
        &opts,
        std::slice::from_ref(&(0..30)),
    )
    .unwrap();
    let mut s = StreamingIk::new(&model, &labels, UpAxis::Y, opts).unwrap();
    assert_eq!(s.last().absent, &[absent]);
    assert!(s.last().held.is_empty());
    assert_streams_as_batch(&batch.coords, |f| {
        s.update(f as f64 / 100.0, &feed(f))
            .unwrap()
            .coords
            .to_vec()
    });
}

/// A frame with the wrong number of samples, or a time that does not increase, is refused
/// and leaves the stream as it was: the next good frame gives the same bits as without it.
#[test]
fn bad_frames_are_refused_without_disturbing_the_stream() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let trial = noisy_walk(&model, &p, 20);
    let opts = IkOptions::default();
    let clean = streamed(&model, &p, &trial, &opts);
    let mut s = StreamingIk::with_params(model.clone(), p.clone(), trial.labels(), UpAxis::Y, opts)
        .unwrap();
    for f in 0..20 {
        if f == 10 {
            let short = &trial.frame(f)[1..];
            assert_eq!(
                s.update(trial.time(f), short),
                Err(IkError::MarkerCount {
                    got: short.len(),
                    expected: short.len() + 1
                })
            );
            assert!(matches!(
                s.update(trial.time(f - 1), trial.frame(f)),
                Err(IkError::TimeNotIncreasing { .. })
            ));
            assert!(matches!(
                s.update(f64::NAN, trial.frame(f)),
                Err(IkError::TimeNotFinite(_))
            ));
        }
        let q = s.update(trial.time(f), trial.frame(f)).unwrap();
        assert_eq!(
            bits(&[q.coords.to_vec()]),
            bits(&clean.coords[f..f + 1]),
            "frame {f}"
        );
    }
    // After a reset the next frame is seeded, as a first frame is.
    s.reset();
    let again = s
        .update(trial.time(0), trial.frame(0))
        .unwrap()
        .coords
        .to_vec();
    assert_eq!(bits(&[again]), bits(&clean.coords[0..1]));
    // Feeds the model cannot use.
    let e = |labels: &[&str]| {
        let labels: Vec<String> = labels.iter().map(|s| s.to_string()).collect();
        StreamingIk::new(&model, &labels, UpAxis::Y, opts).unwrap_err()
    };
    assert_eq!(e(&[]), IkError::NoLabels);
    assert_eq!(e(&["A", "B", "A"]), IkError::DuplicateLabel("A".into()));
    assert!(matches!(e(&["A", "B"]), IkError::NoCommonMarker { .. }));
}

/// Each frame the stream answers (`update(f)`, in order) has the bits of the batch's frame.
fn assert_streams_as_batch(batch: &[Vec<f64>], mut update: impl FnMut(usize) -> Vec<f64>) {
    for (f, want) in batch.iter().enumerate() {
        let q = update(f);
        assert_eq!(bits(&[q]), bits(std::slice::from_ref(want)), "frame {f}");
    }
}
