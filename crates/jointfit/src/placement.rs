//! Do a subject model and a trial carry the same marker placement?
//!
//! A subject model fixes the distance between any two markers of one rigid segment
//! (`d⁰ = ‖local_a − local_b‖`, measured on the static trial the model was built from). A
//! motion trial of the same session shows the same distances up to soft-tissue motion
//! (thigh markers move 5–15 mm against the bone in gait: Leardini et al. 2005, Gait Posture
//! 21:212–225). For every such pair the trial's distance `d` is the median over frames
//! (at most 200, evenly spaced), and three things are read off:
//!
//! * **units**: the median ratio `d / d⁰` over every pair. Far from 1 (outside
//!   [`UNIT_RATIO`]) the two files are in different units or of different things;
//! * **build**: per segment with at least [`MIN_PAIRS`] pairs, the median ratio `s`. A
//!   different person (or the same person's static trial of another session, with the
//!   markers placed again) changes a segment's marker distances together: `|s − 1|` above
//!   [`BUILD_RATIO`] with a median distance change above [`BUILD_CHANGE`] on a segment, while
//!   the median ratio over every pair is off 1 by more than [`BUILD_OVERALL`] (one
//!   re-attached marker of a three-marker cluster moves its segment's median, not the whole
//!   body's);
//! * **markers**: per marker, the median over its segment partners of `|d − d⁰|`. One
//!   re-attached marker is ordinary (the marker policy of a calibration refines it); many
//!   markers off by more than [`DISPLACED`] mean the labels do not name the same markers in
//!   the two files (a wrong marker map, swapped labels, auto-labelled trajectories).
//!
//! [`compare`] measures; [`Placement::mismatch`] turns the measurement into a one-line cause
//! when the model and the trial do not belong together. Nothing here prints or changes data.

use nalgebra::Vector3;

use crate::ik::MarkerMap;
use crate::model::Model;
use crate::trial::Trial;

/// The median pair ratio outside which the two files are in different units or describe
/// different things.
pub(crate) const UNIT_RATIO: [f64; 2] = [0.6, 1.6];
/// A segment's median distance ratio further than this from 1 is another build.
pub(crate) const BUILD_RATIO: f64 = 0.08;
/// ... when its median distance change is also above this (m) ...
pub(crate) const BUILD_CHANGE: f64 = 0.012;
/// ... and the median ratio over every pair is further than this from 1.
pub(crate) const BUILD_OVERALL: f64 = 0.025;
/// A marker whose median distance change to its segment partners is above this is displaced
/// (m): twice the soft-tissue motion of a thigh marker in gait.
pub(crate) const DISPLACED: f64 = 0.03;
/// A marker displaced by more than this (m) was not re-attached: its label names another
/// marker (a re-attached marker lands within a few centimetres of where it was).
pub(crate) const GROSS: f64 = 0.08;
/// Least number of pairs of a segment for its build ratio.
pub(crate) const MIN_PAIRS: usize = 3;
/// Pairs shorter than this in the model do not enter ratios (m): their ratio is mostly noise.
pub(crate) const MIN_PAIR_LENGTH: f64 = 0.04;

/// One pair of markers of one segment.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct Pair {
    pub a: String,
    pub b: String,
    /// The model's distance (m).
    pub model: f64,
    /// The trial's median distance (m).
    pub trial: f64,
}

/// One segment's markers.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct SegmentPlacement {
    pub segment: String,
    pub pairs: Vec<Pair>,
    /// Median of `d / d⁰` over the pairs at least [`MIN_PAIR_LENGTH`] long (NaN without any).
    pub ratio: f64,
    /// Median of `d − d⁰` (m, signed: positive when the trial's markers are further apart).
    pub change: f64,
}

/// One marker's distance change to its segment partners.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct MarkerPlacement {
    pub marker: String,
    pub segment: String,
    /// Median over its partners of `|d − d⁰|` (m).
    pub change: f64,
}

/// What [`compare`] measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub(crate) struct Placement {
    /// Median ratio over every pair (NaN without any).
    pub ratio: f64,
    pub segments: Vec<SegmentPlacement>,
    pub markers: Vec<MarkerPlacement>,
}

/// Why a model and a trial do not belong together.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub(crate) enum Mismatch {
    /// The trial's marker distances are `ratio` times the model's everywhere.
    Units { ratio: f64 },
    /// Segments whose markers are further apart (or closer) as a whole: another build.
    Build { segments: Vec<(String, f64, usize)> },
    /// Markers whose distances to their segment partners changed beyond soft-tissue motion.
    Markers { markers: Vec<(String, f64)> },
}

impl Mismatch {
    /// The cause in words (no file name; the caller prefixes it).
    pub(crate) fn cause(&self) -> String {
        match self {
            Mismatch::Units { ratio } => format!(
                "its markers are {ratio:.3} times as far apart as the model's: the two are in \
                 different units, or not of the same marker set"
            ),
            Mismatch::Build { segments } => {
                let (seg, change, pairs) = &segments[0];
                let more = match segments.len() {
                    1 => String::new(),
                    k => format!(
                        " (and {} more segment{})",
                        k - 1,
                        if k > 2 { "s" } else { "" }
                    ),
                };
                format!(
                    "not the same marker placement as the model: {seg} markers {:.0} mm {} \
                     apart (median of {pairs} pairs){more}; build the model from this \
                     session's static trial",
                    change.abs() * 1e3,
                    if *change > 0.0 { "further" } else { "less far" }
                )
            }
            Mismatch::Markers { markers } => {
                let list: Vec<String> = markers
                    .iter()
                    .take(4)
                    .map(|(m, d)| format!("{m} {:.0} mm", d * 1e3))
                    .collect();
                let count = match markers.len() {
                    1 => "1 marker sits".to_string(),
                    k => format!("{k} markers sit"),
                };
                format!(
                    "{count} elsewhere on their segments than in the model ({}{}): the labels \
                     do not name the same markers in the two files (a wrong marker map, swapped \
                     or automatic labels)",
                    list.join(", "),
                    if markers.len() > 4 { ", …" } else { "" }
                )
            }
        }
    }
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The trial's median distance of model markers `a` and `b` over at most 200 evenly spaced
/// frames (NaN when never both present).
fn trial_distance(trial: &Trial, map: &MarkerMap, a: usize, b: usize) -> f64 {
    let (Some(ca), Some(cb)) = (map.columns[a], map.columns[b]) else {
        return f64::NAN;
    };
    let n = trial.n_frames();
    let step = n.div_ceil(200).max(1);
    let mut d: Vec<f64> = (0..n)
        .step_by(step)
        .map(|f| {
            let (p, q): (Vector3<f64>, Vector3<f64>) = (trial.frame(f)[ca], trial.frame(f)[cb]);
            (p - q).norm()
        })
        .filter(|x| x.is_finite())
        .collect();
    median(&mut d)
}

/// Measures the model's marker distances per segment against `trial`'s (markers matched by
/// `map`; absent ones are skipped).
pub(crate) fn compare(model: &Model, trial: &Trial, map: &MarkerMap) -> Placement {
    let mut segments = Vec::new();
    let mut per_marker: Vec<Vec<f64>> = vec![Vec::new(); model.markers().len()];
    let mut all_ratios = Vec::new();
    for (s, seg) in model.segments().iter().enumerate() {
        let on: Vec<usize> = (0..model.markers().len())
            .filter(|&j| model.markers()[j].segment.0 == s && map.columns[j].is_some())
            .collect();
        let mut pairs = Vec::new();
        let (mut ratios, mut changes) = (Vec::new(), Vec::new());
        for (i, &a) in on.iter().enumerate() {
            for &b in &on[i + 1..] {
                let d0 = (model.markers()[a].local - model.markers()[b].local).norm();
                let d = trial_distance(trial, map, a, b);
                if !d.is_finite() {
                    continue;
                }
                per_marker[a].push((d - d0).abs());
                per_marker[b].push((d - d0).abs());
                if d0 >= MIN_PAIR_LENGTH {
                    ratios.push(d / d0);
                    changes.push(d - d0);
                }
                pairs.push(Pair {
                    a: model.markers()[a].name.clone(),
                    b: model.markers()[b].name.clone(),
                    model: d0,
                    trial: d,
                });
            }
        }
        if pairs.is_empty() {
            continue;
        }
        all_ratios.extend_from_slice(&ratios);
        segments.push(SegmentPlacement {
            segment: seg.name.clone(),
            pairs,
            ratio: median(&mut ratios),
            change: median(&mut changes),
        });
    }
    let markers = per_marker
        .iter_mut()
        .enumerate()
        .filter(|(_, v)| !v.is_empty())
        .map(|(j, v)| MarkerPlacement {
            marker: model.markers()[j].name.clone(),
            segment: model.segments()[model.markers()[j].segment.0].name.clone(),
            change: median(v),
        })
        .collect();
    Placement {
        ratio: median(&mut all_ratios),
        segments,
        markers,
    }
}

impl Placement {
    /// The segments whose markers changed together beyond [`BUILD_RATIO`] and
    /// [`BUILD_CHANGE`]: (segment, median change (m), pairs), largest change first.
    pub(crate) fn rebuilt_segments(&self) -> Vec<(String, f64, usize)> {
        let mut out: Vec<(String, f64, usize)> = self
            .segments
            .iter()
            .filter(|s| {
                let long = s
                    .pairs
                    .iter()
                    .filter(|p| p.model >= MIN_PAIR_LENGTH)
                    .count();
                long >= MIN_PAIRS
                    && (s.ratio - 1.0).abs() > BUILD_RATIO
                    && s.change.abs() > BUILD_CHANGE
            })
            .map(|s| {
                let long = s
                    .pairs
                    .iter()
                    .filter(|p| p.model >= MIN_PAIR_LENGTH)
                    .count();
                (s.segment.clone(), s.change, long)
            })
            .collect();
        out.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        out
    }

    /// The markers displaced by more than [`DISPLACED`], largest first.
    pub(crate) fn displaced(&self) -> Vec<(String, f64)> {
        let mut out: Vec<(String, f64)> = self
            .markers
            .iter()
            .filter(|m| m.change > DISPLACED)
            .map(|m| (m.marker.clone(), m.change))
            .collect();
        out.sort_by(|a, b| b.1.total_cmp(&a.1));
        out
    }

    /// Whether the model and the trial do not belong together (see the module docs): units
    /// first, then markers whose labels name other markers (one displaced beyond [`GROSS`],
    /// or more displaced markers than one re-attachment explains: at least three and at
    /// least a quarter of the compared markers), then a segment rebuilt.
    pub(crate) fn mismatch(&self) -> Option<Mismatch> {
        if self.ratio.is_finite() && !(UNIT_RATIO[0]..=UNIT_RATIO[1]).contains(&self.ratio) {
            return Some(Mismatch::Units { ratio: self.ratio });
        }
        let displaced = self.displaced();
        let gross = displaced.first().is_some_and(|(_, d)| *d > GROSS);
        if gross || (displaced.len() >= 3 && 4 * displaced.len() >= self.markers.len()) {
            return Some(Mismatch::Markers { markers: displaced });
        }
        let rebuilt = self.rebuilt_segments();
        if !rebuilt.is_empty() && (self.ratio - 1.0).abs() > BUILD_OVERALL {
            return Some(Mismatch::Build { segments: rebuilt });
        }
        None
    }
}

/// A trial made from the model itself matches; a trial of another build (marker positions
/// scaled on two segments), labels exchanged between segments, another unit, and a marker
/// moved far are each told apart, with the known size of the change.
#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::workflow::synthetic_tests::synthetic;
    use nalgebra::Vector3;

    fn leg() -> Model {
        Model::compile(&lower_limb(Side::Right)).unwrap()
    }

    /// The trial of `model_made` at its nominal parameters, compared with `model`.
    fn placement_of(model: &Model, trial: &Trial) -> Placement {
        let (map, _) = MarkerMap::allowing_absent(model, trial.labels());
        compare(model, trial, &map)
    }

    fn trial_of(model: &Model) -> Trial {
        synthetic(model, &model.nominal_params(), 80, 0.0)
    }

    #[test]
    fn the_models_own_trial_matches_exactly() {
        let model = leg();
        let p = placement_of(&model, &trial_of(&model));
        assert!((p.ratio - 1.0).abs() < 1e-9, "{}", p.ratio);
        for s in &p.segments {
            assert!((s.ratio - 1.0).abs() < 1e-9 || s.ratio.is_nan(), "{s:?}");
            assert!(s.change.abs() < 1e-9 || s.change.is_nan(), "{s:?}");
        }
        assert!(p.markers.iter().all(|m| m.change < 1e-9));
        assert_eq!(p.mismatch(), None);
    }

    /// Another person: the thigh's and shank's markers 15 % further apart (local positions
    /// scaled about the segment origin, which scales every distance within the segment by
    /// exactly 1.15).
    #[test]
    fn another_build_is_named_with_its_segment_and_size() {
        let model = leg();
        let mut spec = model.spec().clone();
        for m in spec.markers.iter_mut() {
            if m.segment == "thigh" || m.segment == "shank" {
                m.position = m.position.map(|x| 1.15 * x);
            }
        }
        let other = Model::compile(&spec).unwrap();
        let p = placement_of(&model, &trial_of(&other));
        for s in p
            .segments
            .iter()
            .filter(|s| s.segment == "thigh" || s.segment == "shank")
        {
            assert!((s.ratio - 1.15).abs() < 1e-9, "{s:?}");
        }
        match p.mismatch() {
            Some(Mismatch::Build { segments }) => {
                let names: Vec<&str> = segments.iter().map(|s| s.0.as_str()).collect();
                assert!(
                    names.contains(&"thigh") && names.contains(&"shank"),
                    "{names:?}"
                );
            }
            other => panic!("expected another build, got {other:?}"),
        }
        // The same change on one segment only, small enough to be soft tissue (2 %): accepted.
        let mut spec = model.spec().clone();
        for m in spec.markers.iter_mut().filter(|m| m.segment == "thigh") {
            m.position = m.position.map(|x| 1.02 * x);
        }
        let close = Model::compile(&spec).unwrap();
        assert_eq!(placement_of(&model, &trial_of(&close)).mismatch(), None);
    }

    /// A thigh and a shank marker with each other's labels: both named, the gross one first.
    #[test]
    fn labels_exchanged_between_segments_are_a_marker_mismatch() {
        let model = leg();
        let trial = trial_of(&model);
        let mut labels = trial.labels().to_vec();
        let a = labels.iter().position(|l| l == "RTHI").unwrap();
        let b = labels.iter().position(|l| l == "RTIB").unwrap();
        labels.swap(a, b);
        let swapped = Trial::new(labels, trial.rate(), 1, trial.positions().to_vec()).unwrap();
        match placement_of(&model, &swapped).mismatch() {
            Some(Mismatch::Markers { markers }) => {
                let names: Vec<&str> = markers.iter().map(|m| m.0.as_str()).collect();
                assert!(
                    names.contains(&"RTHI") && names.contains(&"RTIB"),
                    "{names:?}"
                );
                assert!(markers[0].1 > GROSS);
            }
            other => panic!("expected a marker mismatch, got {other:?}"),
        }
    }

    /// Centimetres read as millimetres: every distance ×0.1, named as units.
    #[test]
    fn another_unit_is_a_units_mismatch_with_its_factor() {
        let model = leg();
        let trial = trial_of(&model);
        let scaled: Vec<Vector3<f64>> = trial.positions().iter().map(|p| p * 0.1).collect();
        let cm = Trial::new(trial.labels().to_vec(), trial.rate(), 1, scaled).unwrap();
        match placement_of(&model, &cm).mismatch() {
            Some(Mismatch::Units { ratio }) => assert!((ratio - 0.1).abs() < 1e-9, "{ratio}"),
            other => panic!("expected units, got {other:?}"),
        }
    }

    /// One marker re-attached 20 mm away is ordinary (the calibration's marker policy handles
    /// it); moved 150 mm, its label names another place. The marker moves in its segment, away
    /// from the centroid of the segment's other markers.
    #[test]
    fn one_marker_moved_far_is_a_mismatch_and_a_re_attached_one_is_not() {
        let model = leg();
        let moved = |by: f64| {
            let mut spec = model.spec().clone();
            let k = spec.markers.iter().position(|m| m.name == "RTHA").unwrap();
            let others: Vec<Vector3<f64>> = spec
                .markers
                .iter()
                .filter(|m| m.segment == "thigh" && m.name != "RTHA")
                .map(|m| Vector3::from(m.position))
                .collect();
            let centroid = others.iter().sum::<Vector3<f64>>() / others.len() as f64;
            let at = Vector3::from(spec.markers[k].position);
            let to = at + by * (at - centroid).normalize();
            spec.markers[k].position = [to.x, to.y, to.z];
            trial_of(&Model::compile(&spec).unwrap())
        };
        assert_eq!(placement_of(&model, &moved(0.02)).mismatch(), None);
        match placement_of(&model, &moved(0.15)).mismatch() {
            Some(Mismatch::Markers { markers }) => assert_eq!(markers[0].0, "RTHA"),
            other => panic!("expected a marker mismatch, got {other:?}"),
        }
    }
}
