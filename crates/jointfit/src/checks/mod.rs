//! Data checks before any fit: what in a trial would silently bend the fitted joints.
//!
//! * **Scale** ([`check_scale`]): the markers of a standing or moving person span about
//!   0.3–2.5 m. The median over frames of the largest distance between two present markers
//!   outside [`PLAUSIBLE_SPAN`] (0.05–6 m, room for partial marker sets and stray markers)
//!   means the declared units are wrong (millimetre data declared `m` span about 1000 m); the
//!   finding names the likely factor and the fix. Against a subject model, the median ratio
//!   of same-segment marker distances in the trial to the model's outside [1/3, 3] is the
//!   same error (a factor 10 that a partial marker set's span would hide), said once instead
//!   of as a moved marker per pair.
//! * Against a subject model ([`check_trial`]), for markers on one segment, whose distances
//!   the rigid model fixes (`‖local_a − local_b‖`, measured on the static trial):
//!   - **cluster**: the median distance of a pair over the trial differs from the model's by
//!     more than [`CLUSTER_TOLERANCE`]: a marker was re-attached or the cluster slipped;
//!   - **swap**: in a frame, exchanging the labels of two markers of a segment fits the model's
//!     distances to the segment's other markers far better than the labels as written;
//!     reported as runs of frames. Only pairs the distances can tell apart are tested: the
//!     two markers' model distances to the other markers must differ by at least
//!     [`SWAP_MIN_ASYMMETRY`] on average (a pair placed symmetrically, e.g. both ASIS with
//!     only a sacral marker besides them, is a mirror image that no distance tells from its
//!     swap, and soft-tissue motion would be read as swaps). One swap corrupts the other
//!     pairs' references, so in a frame where several pairs read as swaps they are taken
//!     strongest first (smallest ratio of the exchanged to the written misfit), and a later
//!     pair is kept only when it shares no marker with a kept one and still reads as a swap
//!     against the markers no kept swap moved;
//!   - **jump**: a marker moves faster than [`JUMP_SPEED`] between consecutive frames;
//!   - **gaps**: frames in which a model marker is missing, with the longest run (one finding
//!     for the markers missing in exactly the same frames);
//!   - **offset**: after inverse kinematics, markers that sit at the same wrong place of their
//!     segment in every frame, e.g. a whole cluster moved ([`crate::checks::offsets`]).
//!
//! Nothing here changes the data; the findings are for the user (and the report). A finding
//! that a repair of [`crate::repair`] addresses carries the option that applies it
//! ([`Finding::fix`]): `--swap-labels A,B@F` for a swap, `--fill-gaps N` for gaps of at most
//! half a second, `--exclude-marker` for a cluster whose distance changed.

use nalgebra::Vector3;

use crate::ik::MarkerMap;
use crate::model::Model;
use crate::trial::Trial;

pub mod offsets;
mod segment;

/// Distance change within a segment's cluster above which a pair is reported (m).
pub(crate) const CLUSTER_TOLERANCE: f64 = 0.01;
/// The least mean difference (m) between two markers' model distances to their segment's
/// other markers for a swap of the two to be tested: a real swap then changes those
/// distances by twice this at least, beyond the skin motion of a gait trial (≈ 10–15 mm).
pub(crate) const SWAP_MIN_ASYMMETRY: f64 = 0.02;
/// Marker speed above which a frame-to-frame displacement is a jump (m/s); the fastest body
/// markers (the foot in sprinting) stay below 20 m/s.
pub(crate) const JUMP_SPEED: f64 = 30.0;
/// Spans of a trial's markers that pass the units check (m).
pub const PLAUSIBLE_SPAN: [f64; 2] = [0.05, 6.0];

/// How serious a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// Worth a look; the fit can go on.
    Warning,
    /// The data cannot be fitted as they are.
    Error,
}

/// What a finding is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CheckKind {
    Scale,
    Cluster,
    Swap,
    Jump,
    Gaps,
    /// Markers that sit at the same wrong place of their segment in every frame
    /// ([`crate::checks::offsets`]).
    Offset,
}

/// The kind's name in JSON and messages: `scale`, `cluster`, `swap`, `jump`, `gaps`, `offset`.
impl std::fmt::Display for CheckKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl CheckKind {
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            CheckKind::Scale => "scale",
            CheckKind::Cluster => "cluster",
            CheckKind::Swap => "swap",
            CheckKind::Jump => "jump",
            CheckKind::Gaps => "gaps",
            CheckKind::Offset => "offset",
        }
    }
}

/// One finding: a sentence naming the markers, frames and sizes involved.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    pub kind: CheckKind,
    pub severity: Severity,
    pub message: String,
    /// The command-line option that repairs it ([`crate::repair`]), if one does.
    pub fix: Option<String>,
}

/// The median over frames of the largest distance between two present markers (m); `None`
/// when no frame has two markers. At most 200 frames, evenly spaced, are looked at.
pub fn marker_span(trial: &Trial) -> Option<f64> {
    let n = trial.n_frames();
    let step = n.div_ceil(200).max(1);
    // Present markers with their distance from the frame's centroid, farthest first.
    let mut present: Vec<(f64, Vector3<f64>)> = Vec::with_capacity(trial.labels().len());
    let mut spans: Vec<f64> = Vec::with_capacity(n.div_ceil(step));
    for f in (0..n).step_by(step) {
        present.clear();
        present.extend(
            trial
                .frame(f)
                .iter()
                .filter(|p| p.x.is_finite())
                .map(|p| (0.0, *p)),
        );
        let centroid =
            present.iter().map(|(_, p)| p).sum::<Vector3<f64>>() / present.len().max(1) as f64;
        for (r, p) in present.iter_mut() {
            *r = (*p - centroid).norm();
        }
        present.sort_by(|a, b| b.0.total_cmp(&a.0));
        // The largest squared distance; its square root is the largest distance (the norm
        // is the square root of the squared norm, and the root is monotonic). A pair whose
        // bound ‖a − c‖ + ‖b − c‖ (triangle inequality) is clearly below the best so far
        // cannot be the largest and is skipped; the margin covers rounding in the bound.
        let mut best: Option<f64> = None;
        for (i, (ra, a)) in present.iter().enumerate() {
            for (rb, b) in &present[i + 1..] {
                if let Some(m) = best {
                    let bound = ra + rb;
                    if bound * bound * (1.0 + 1e-9) < m {
                        break;
                    }
                }
                let d2 = (a - b).norm_squared();
                best = Some(best.map_or(d2, |m: f64| m.max(d2)));
            }
        }
        if let Some(d2) = best {
            spans.push(d2.sqrt());
        }
    }
    if spans.is_empty() {
        return None;
    }
    let mid = spans.len() / 2;
    Some(*spans.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// The units check (see the module docs): an error when the markers' span is outside
/// [`PLAUSIBLE_SPAN`], naming the likely factor.
pub fn check_scale(trial: &Trial) -> Option<Finding> {
    let span = marker_span(trial)?;
    if (PLAUSIBLE_SPAN[0]..=PLAUSIBLE_SPAN[1]).contains(&span) {
        return None;
    }
    // The power of ten that brings the span nearest to 1 m.
    let hint = units_hint(span.log10().round() as i32);
    let [lo, hi] = PLAUSIBLE_SPAN;
    Some(Finding {
        kind: CheckKind::Scale,
        severity: Severity::Error,
        message: format!(
            "the markers span {span:.3} m (this check accepts {lo}–{hi} m): this looks like \
             {hint} (TRC: the Units value on line 3; C3D: the POINT:UNITS parameter)"
        ),
        fix: None,
    })
}

/// What a length `10^power` times too large says about the declared units.
fn units_hint(power: i32) -> &'static str {
    match power {
        3 => "millimetre data read as metres: declare the units as mm",
        2 => "centimetre data read as metres: declare the units as cm",
        1 => "millimetre data read as centimetres: declare the units as mm",
        -1 => "centimetre data read as millimetres: declare the units as cm",
        -2 => "metre data read as centimetres: declare the units as m",
        -3 => "metre data read as millimetres: declare the units as m",
        _ => "the units or the data are wrong",
    }
}

/// Shortest model distance of a marker pair that enters the model-based units check (m).
pub(crate) const MIN_PAIR_DISTANCE: f64 = 0.03;

/// Every check of the module docs for `trial` against the subject `model` (markers matched
/// by `map`). Frame numbers in messages are the file's.
pub fn check_trial(model: &Model, trial: &Trial, map: &MarkerMap) -> Vec<Finding> {
    let mut out = check_trial_before_ik(model, trial, map);
    // Wrong units move every cluster: the units finding says it once.
    if out
        .iter()
        .any(|f| f.kind == CheckKind::Scale && f.severity == Severity::Error)
    {
        return out;
    }
    out.extend(crate::checks::offsets::check_offsets(
        model, trial, map, None,
    ));
    out
}

/// The checks of [`check_trial`] that need no inverse kinematics (all but the moved-cluster
/// check of [`crate::checks::offsets`], which [`check_trial`] appends last): a front end that
/// runs the IK anyway appends [`crate::checks::offsets::check_offsets`] with its fit to these and
/// gets what [`check_trial`] gives without a second IK (`workflow::ik::ik_checked`).
///
/// The units check, each segment's cluster and swap checks and each marker's jump and gap
/// scans are independent; they run as parallel tasks (rayon) and their findings are joined
/// in the fixed order units, segments, markers, so the result is the same on any number of
/// threads.
pub fn check_trial_before_ik(model: &Model, trial: &Trial, map: &MarkerMap) -> Vec<Finding> {
    use rayon::prelude::*;
    let reference = crate::checks::offsets::reference_name(model);
    // Marker pairs of one segment with the model's distance.
    let mut segments: Vec<Vec<usize>> = vec![Vec::new(); model.segments().len()];
    for (j, m) in model.markers().iter().enumerate() {
        if map.columns[j].is_some() {
            segments[m.segment.0].push(j);
        }
    }
    let ctx = Ctx { model, trial, map };
    let (scale, (per_segment, per_marker)) = rayon::join(
        || check_scale(trial),
        || {
            rayon::join(
                || {
                    segments
                        .par_iter()
                        .filter(|m| m.len() >= 2)
                        .map(|markers| ctx.segment_findings(markers, &reference))
                        .collect::<Vec<_>>()
                },
                || {
                    (0..model.markers().len())
                        .into_par_iter()
                        .filter(|&j| map.columns[j].is_some())
                        .map(|j| (j, ctx.jumps(j), ctx.gaps(j)))
                        .collect::<Vec<_>>()
                },
            )
        },
    );
    let mut out: Vec<Finding> = scale.into_iter().collect();
    // Units wrong by a power of ten move every marker pair of every segment: one finding
    // that says so instead of a "marker moved" line per pair.
    if out.is_empty() {
        out.extend(ctx.model_scale(&segments, &reference));
    }
    // With wrong units every distance and speed is off too: the units finding alone.
    if !out.is_empty() {
        return out;
    }
    out.extend(per_segment.into_iter().flatten());
    // Jumps per model marker; gaps per model marker, one finding for the markers that are
    // missing in exactly the same frames (a subject walking out of the capture volume).
    // (gap runs, marker names, index in `out` where the group's finding goes)
    type GapGroup = (Vec<(usize, usize)>, Vec<String>, usize);
    let mut gap_groups: Vec<GapGroup> = Vec::new();
    for (j, jump, gaps) in per_marker {
        out.extend(jump);
        if !gaps.is_empty() {
            let name = model.markers()[j].name.clone();
            match gap_groups.iter_mut().find(|(g, _, _)| *g == gaps) {
                Some((_, names, _)) => names.push(name),
                None => {
                    // A placeholder keeps the findings in marker order.
                    gap_groups.push((gaps, vec![name], out.len()));
                    out.push(Finding {
                        kind: CheckKind::Gaps,
                        severity: Severity::Warning,
                        message: String::new(),
                        fix: None,
                    });
                }
            }
        }
    }
    let (first, n) = (trial.first_frame(), trial.n_frames());
    for (gaps, names, at) in gap_groups {
        let missing: usize = gaps.iter().map(|(s, e)| e - s + 1).sum();
        let (s, e) = *gaps.iter().max_by_key(|(s, e)| e - s).expect("non-empty");
        let who = match names.len() {
            1 => format!("{} is", names[0]),
            k => format!("{k} markers ({}) are each", names.join(", ")),
        };
        out[at] = Finding {
            kind: CheckKind::Gaps,
            severity: Severity::Warning,
            message: format!(
                "{who} missing in {missing} of {n} frames ({} gaps; longest frames {}–{})",
                gaps.len(),
                first + s as i64,
                first + e as i64
            ),
            fix: (((e - s + 1) as f64) <= 0.5 * trial.rate())
                .then(|| format!("--fill-gaps {}", e - s + 1)),
        };
    }
    out
}

/// What the checks of one trial against one model read.
#[derive(Clone, Copy)]
struct Ctx<'a> {
    model: &'a Model,
    trial: &'a Trial,
    map: &'a MarkerMap,
}

impl Ctx<'_> {
    /// Model marker `j` in frame `f`, when present.
    fn pos(&self, f: usize, j: usize) -> Option<Vector3<f64>> {
        self.map.columns[j]
            .map(|c| self.trial.frame(f)[c])
            .filter(|p| p.x.is_finite())
    }

    /// The units check against the model: the median, over marker pairs of one segment at
    /// least [`MIN_PAIR_DISTANCE`] apart in the model, of the ratio of the pair's distance in
    /// the trial (median over frames) to the model's. A ratio outside [1/3, 3] cannot be a
    /// different subject or a moved marker; it is the units (a factor 10, 100 or 1000).
    fn model_scale(&self, segments: &[Vec<usize>], reference: &str) -> Option<Finding> {
        let n = self.trial.n_frames();
        let step = (n / 64).max(1);
        let mut ratios = Vec::new();
        for markers in segments.iter().filter(|m| m.len() >= 2) {
            for (i, &a) in markers.iter().enumerate() {
                for &b in &markers[i + 1..] {
                    let r = (self.model.markers()[a].local - self.model.markers()[b].local).norm();
                    if r < MIN_PAIR_DISTANCE {
                        continue;
                    }
                    let mut d: Vec<f64> = (0..n)
                        .step_by(step)
                        .filter_map(|f| Some((self.pos(f, a)? - self.pos(f, b)?).norm()))
                        .collect();
                    if d.is_empty() {
                        continue;
                    }
                    let mid = d.len() / 2;
                    ratios.push(*d.select_nth_unstable_by(mid, f64::total_cmp).1 / r);
                }
            }
        }
        if ratios.len() < 2 {
            return None;
        }
        let mid = ratios.len() / 2;
        let ratio = *ratios.select_nth_unstable_by(mid, f64::total_cmp).1;
        if (1.0 / 3.0..=3.0).contains(&ratio) || !ratio.is_finite() || ratio <= 0.0 {
            return None;
        }
        Some(Finding {
            kind: CheckKind::Scale,
            severity: Severity::Error,
            message: format!(
                "marker distances within segments are {ratio:.3} times those of {reference} \
                 (median over {} marker pairs): this looks like {} (TRC: the Units value on \
                 line 3; C3D: the POINT:UNITS parameter)",
                ratios.len(),
                units_hint(ratio.log10().round() as i32)
            ),
            fix: None,
        })
    }

    fn name(&self, j: usize) -> &str {
        self.model.markers()[j].name.as_str()
    }

    /// The jump finding of model marker `j` (one pass: the number of jumps and the first).
    fn jumps(&self, j: usize) -> Option<Finding> {
        let n = self.trial.n_frames();
        let max_step = JUMP_SPEED / self.trial.rate();
        let (mut count, mut first_jump) = (0usize, None);
        let mut prev = if n > 0 { self.pos(0, j) } else { None };
        for f in 1..n {
            let here = self.pos(f, j);
            if let (Some(p0), Some(p1)) = (prev, here) {
                if (p1 - p0).norm() > max_step {
                    count += 1;
                    first_jump.get_or_insert(f);
                }
            }
            prev = here;
        }
        first_jump.map(|f| Finding {
            kind: CheckKind::Jump,
            severity: Severity::Warning,
            message: format!(
                "{} jumps faster than {JUMP_SPEED} m/s in {} frames (first: frame {})",
                self.name(j),
                count,
                self.trial.first_frame() + f as i64
            ),
            fix: None,
        })
    }

    /// The runs of frames in which model marker `j` is missing.
    fn gaps(&self, j: usize) -> Vec<(usize, usize)> {
        runs((0..self.trial.n_frames()).map(|f| self.pos(f, j).is_none()))
    }
}

/// Runs of `true` as inclusive `(start, end)` indices.
fn runs(flags: impl Iterator<Item = bool>) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    let mut open: Option<usize> = None;
    let mut last = 0;
    for (i, on) in flags.enumerate() {
        last = i;
        match (on, open) {
            (true, None) => open = Some(i),
            (false, Some(s)) => {
                out.push((s, i - 1));
                open = None;
            }
            _ => {}
        }
    }
    if let Some(s) = open {
        out.push((s, last));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::runs;

    #[test]
    fn runs_are_inclusive_ranges() {
        let f = [false, true, true, false, true];
        assert_eq!(runs(f.into_iter()), vec![(1, 2), (4, 4)]);
        assert!(runs([false, false].into_iter()).is_empty());
    }
}
