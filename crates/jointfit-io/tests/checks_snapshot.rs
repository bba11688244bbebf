//! The data checks (`jointfit::checks::check_trial`) on real trials (opencap_expert1 walking1
//! and DJ1 against the subject model personalized from static1), as read and with defects
//! planted in them (two labels swapped over a range of frames, a marker missing in two runs,
//! a one-frame jump, a marker displaced for the whole trial), compared finding by finding
//! (kind, severity, message with its numbers, fix, order) with a snapshot of the findings
//! written by the straightforward implementation before it was made faster
//! (`checks_snapshot.txt`). Regenerate only on purpose: `JOINTFIT_WRITE_SNAPSHOT=1`.

use std::fmt::Write;
use std::path::Path;

use jointfit::checks::{check_trial, marker_span, CheckKind};
use jointfit::ik::MarkerMap;
use jointfit::model::lower_limb::Side;
use jointfit::model::Model;
use jointfit::spatial::UpAxis;
use jointfit::trial::Trial;
use jointfit_io::trial_file::{load_trial, LoadOptions};
use jointfit_landmarks::markerset::MarkerSet;
use jointfit_landmarks::{personalize, PersonalizeOptions};
use nalgebra::Vector3;

fn load(path: &Path) -> Trial {
    let options = LoadOptions {
        up: UpAxis::Y,
        filter_hz: None,
    };
    load_trial(path, &options).unwrap().0
}

fn render(name: &str, model: &Model, trial: &Trial, out: &mut String) {
    let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
    writeln!(out, "== {name}").unwrap();
    // The moved-marker check (`jointfit::checks::offsets`, after IK) is not part of the
    // snapshot: it is tested in jointfit-cli's `offsets` test.
    for f in check_trial(model, trial, &map)
        .into_iter()
        .filter(|f| f.kind != CheckKind::Offset)
    {
        writeln!(
            out,
            "{:?} {:?} {} | {:?}",
            f.kind, f.severity, f.message, f.fix
        )
        .unwrap();
    }
}

/// `trial` with defects planted in the markers of the model's segment with the most markers.
fn planted(model: &Model, trial: &Trial) -> Trial {
    let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
    let mut per_segment: Vec<Vec<usize>> = vec![Vec::new(); model.segments().len()];
    for (j, m) in model.markers().iter().enumerate() {
        if let Some(c) = map.columns[j] {
            per_segment[m.segment.0].push(c);
        }
    }
    let cols = per_segment.iter().max_by_key(|s| s.len()).unwrap().clone();
    assert!(cols.len() >= 3, "a segment with three markers");
    let other = per_segment
        .iter()
        .filter(|s| !s.is_empty() && **s != cols)
        .max_by_key(|s| s.len())
        .unwrap()
        .clone();
    let (n, m) = (trial.n_frames(), trial.labels().len());
    let mut pos = trial.positions().to_vec();
    // Labels of two markers exchanged in frames 40–89.
    for f in 40..90.min(n) {
        pos.swap(f * m + cols[0], f * m + cols[1]);
    }
    // A marker missing in frames 10–19 and 120–122.
    for f in (10..20).chain(120..123).filter(|&f| f < n) {
        pos[f * m + cols[2]] = Vector3::repeat(f64::NAN);
    }
    // A one-frame jump of 1 m at frame 30.
    pos[30 * m + other[0]] += Vector3::new(1.0, 0.0, 0.0);
    // A marker 3 cm off its place in every frame (the cluster check).
    for f in 0..n {
        pos[f * m + other[other.len() - 1]] += Vector3::new(0.0, 0.03, 0.0);
    }
    let labels = trial.labels().to_vec();
    Trial::new(labels, trial.rate(), trial.first_frame(), pos)
        .and_then(|t| t.with_times(trial.times().map(<[f64]>::to_vec)))
        .unwrap()
}

#[test]
fn findings_on_real_trials_match_the_snapshot() {
    let Some(dir) = jointfit_testkit::data_file("opencap_expert1") else {
        return;
    };
    let stat = load(&dir.join("static1.trc"));
    let set = MarkerSet::preset("opencap").unwrap();
    let subject = personalize(&stat, &set, Side::Right, &PersonalizeOptions::default()).unwrap();
    let model = Model::compile(&subject.spec).unwrap();
    let mut out = String::new();
    for name in ["walking1", "DJ1"] {
        let trial = load(&dir.join(format!("{name}.trc")));
        render(name, &model, &trial, &mut out);
        render(
            &format!("{name} planted"),
            &model,
            &planted(&model, &trial),
            &mut out,
        );
    }
    let snap = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/checks_snapshot.txt");
    if std::env::var_os("JOINTFIT_WRITE_SNAPSHOT").is_some() {
        std::fs::write(&snap, &out).unwrap();
    }
    let want = std::fs::read_to_string(&snap).unwrap();
    for (i, (got, want)) in out.lines().zip(want.lines()).enumerate() {
        assert_eq!(got, want, "line {} of the findings", i + 1);
    }
    assert_eq!(out.lines().count(), want.lines().count(), "number of lines");
}

/// The span of the units check, all pairs in every looked-at frame, sorted for the median.
fn span_reference(trial: &Trial) -> Option<f64> {
    let n = trial.n_frames();
    let step = n.div_ceil(200).max(1);
    let mut spans: Vec<f64> = (0..n)
        .step_by(step)
        .filter_map(|f| {
            let present: Vec<&Vector3<f64>> =
                trial.frame(f).iter().filter(|p| p.x.is_finite()).collect();
            let mut best: Option<f64> = None;
            for (i, a) in present.iter().enumerate() {
                for b in &present[i + 1..] {
                    let d = (*a - *b).norm();
                    best = Some(best.map_or(d, |m: f64| m.max(d)));
                }
            }
            best
        })
        .collect();
    spans.sort_by(f64::total_cmp);
    spans.get(spans.len() / 2).copied()
}

#[test]
fn the_span_is_the_all_pairs_span_bit_for_bit() {
    let Some(dir) = jointfit_testkit::data_file("opencap_expert1") else {
        return;
    };
    for name in ["static1", "walking1", "DJ1", "squats1"] {
        let trial = load(&dir.join(format!("{name}.trc")));
        let (got, want) = (marker_span(&trial), span_reference(&trial));
        assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "{name}");
        assert!(got.is_some());
    }
}
