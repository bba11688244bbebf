//! Repairs of a trial before any fit, each one stated: leaving markers out, exchanging two
//! labels (from a frame on), and filling short gaps.
//!
//! * **Exclude** (`--exclude-marker NAME`): the marker's column leaves the trial; a model
//!   marker of that name then counts as missing in every frame.
//! * **Swap** (`--swap-labels A,B[@F[-L]]`): the trajectories of `A` and `B` are exchanged in
//!   file frames `F..=L` (default: the whole trial), the fix for the runs of frames that
//!   [`crate::checks`] reports as swapped.
//! * **Fill** (`--fill-gaps N`): every gap of at most `N` frames with a sample on at least one
//!   side is filled (with a subject model, in its markers only: the others are not fitted).
//!   - *Rigid-body fill*, when the marker's segment (from the subject model) has at least three
//!     other markers present both in the gap frame `f` and in a reference frame `r` (the last
//!     frame before the gap and the first after it, where the marker itself is present): the
//!     least-squares rigid transform `(R, t)` taking those markers from `r` to `f` (Kabsch
//!     1976, Acta Cryst A32:922; the SVD solution of `min Σ‖R a_r + t − a_f‖²`) carries the
//!     marker, `p_f = R p_r + t`. With references on both sides the two predictions are
//!     blended linearly in time, `p_f = (1 − w) p_before + w p_after`, `w = (f − s + 1) / (L + 1)`
//!     for a gap of `L` frames starting at `s`, so the fill joins both ends.
//!   - *Cubic spline* otherwise, for gaps with samples on both sides: the cubic Hermite segment
//!     between the samples just before and just after the gap, with end slopes from central
//!     (or one-sided) differences of the neighbouring samples (the C¹ cubic interpolant of
//!     Fritsch & Carlson 1980 without their monotonicity limiter).
//!   - Gaps longer than `N`, gaps at the ends of the trial without a rigid reference, and gaps
//!     whose segment has too few markers at a trial end stay gaps.
//!
//! The actions come back as [`Action`]s whose display is one sentence for the user.

use nalgebra::Vector3;
use thiserror::Error;

use crate::model::Model;
use crate::trial::Trial;

/// Exchange the labels `a` and `b` in file frames `from..=to` (`None`: from the first / to
/// the last frame).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Swap {
    pub a: String,
    pub b: String,
    pub from: Option<i64>,
    pub to: Option<i64>,
}

/// Parses `A,B`, `A,B@F` or `A,B@F-L` (file frame numbers).
impl std::str::FromStr for Swap {
    type Err = RepairError;
    fn from_str(s: &str) -> Result<Swap, RepairError> {
        let bad = || RepairError::BadSwap(s.to_string());
        let (names, frames) = match s.split_once('@') {
            Some((n, f)) => (n, Some(f)),
            None => (s, None),
        };
        let (a, b) = names.split_once(',').ok_or_else(bad)?;
        let (a, b) = (a.trim(), b.trim());
        if a.is_empty() || b.is_empty() || a == b {
            return Err(bad());
        }
        let (from, to) = match frames {
            None => (None, None),
            Some(f) => {
                let num = |t: &str| t.trim().parse::<i64>().map_err(|_| bad());
                match f.split_once('-') {
                    Some((x, y)) => (Some(num(x)?), Some(num(y)?)),
                    None => (Some(num(f)?), None),
                }
            }
        };
        if let (Some(x), Some(y)) = (from, to) {
            if y < x {
                return Err(bad());
            }
        }
        Ok(Swap {
            a: a.to_string(),
            b: b.to_string(),
            from,
            to,
        })
    }
}

impl Swap {
    /// The option value that gives this swap back (`A,B@F`).
    pub(crate) fn to_arg(&self) -> String {
        match (self.from, self.to) {
            (None, None) => format!("{},{}", self.a, self.b),
            (Some(f), None) => format!("{},{}@{f}", self.a, self.b),
            (f, Some(l)) => format!("{},{}@{}-{l}", self.a, self.b, f.unwrap_or(0)),
        }
    }
}

/// What to repair; the default repairs nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RepairOptions {
    /// Marker labels to leave out.
    pub exclude: Vec<String>,
    /// Labels to exchange, applied in order after the exclusions.
    pub swaps: Vec<Swap>,
    /// Fill gaps of at most this many frames (0: no filling).
    pub fill_gaps: usize,
}

/// How a gap was filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FillMethod {
    Rigid,
    Spline,
}

/// One thing [`repair`] did; displays as a sentence.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Excluded {
        marker: String,
    },
    Swapped {
        swap: Swap,
        /// File frames exchanged (inclusive).
        first: i64,
        last: i64,
    },
    /// Gaps of one marker filled by one method.
    Filled {
        marker: String,
        method: FillMethod,
        gaps: usize,
        frames: usize,
    },
    /// Gaps of one marker longer than the limit, or without the samples a fill needs.
    LeftUnfilled {
        marker: String,
        gaps: usize,
        frames: usize,
    },
}

impl std::fmt::Display for Action {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Action::Excluded { marker } => write!(f, "excluded marker {marker}"),
            Action::Swapped { swap, first, last } => write!(
                f,
                "swapped labels {} and {} in frames {first}–{last}",
                swap.a, swap.b
            ),
            Action::Filled {
                marker,
                method,
                gaps,
                frames,
            } => write!(
                f,
                "filled {frames} frames of {marker} in {gaps} gap(s) by {}",
                match method {
                    FillMethod::Rigid => "rigid-body fill from its segment's other markers",
                    FillMethod::Spline => "cubic spline",
                }
            ),
            Action::LeftUnfilled {
                marker,
                gaps,
                frames,
            } => write!(
                f,
                "left {frames} frames of {marker} in {gaps} gap(s) unfilled (longer than the \
                 limit, or no samples to fill from)"
            ),
        }
    }
}

#[derive(Debug, Error, PartialEq)]
pub enum RepairError {
    #[error("--swap-labels {0:?}: expected A,B or A,B@FRAME or A,B@FIRST-LAST with two different labels")]
    BadSwap(String),
    #[error("{option} names marker {name:?}, which the trial lacks; it has: {available}")]
    UnknownMarker {
        option: &'static str,
        name: String,
        available: String,
    },
    #[error(
        "--swap-labels {arg}: frames {from}–{to} are outside the trial (frames {first}–{last})"
    )]
    OutsideTrial {
        arg: String,
        from: i64,
        to: i64,
        first: i64,
        last: i64,
    },
}

/// Applies `opts` to `trial` (exclusions, then swaps, then fills; `model` names each marker's
/// segment for the rigid fill, `None`: splines only). Returns the repaired trial and what
/// was done.
pub fn repair(
    trial: &Trial,
    model: Option<&Model>,
    opts: &RepairOptions,
) -> Result<(Trial, Vec<Action>), RepairError> {
    let mut actions = Vec::new();
    let unknown = |option: &'static str, name: &str, t: &Trial| RepairError::UnknownMarker {
        option,
        name: name.to_string(),
        available: t.labels().join(", "),
    };
    let mut out = trial.clone();
    if !opts.exclude.is_empty() {
        for name in &opts.exclude {
            if !trial.labels().contains(name) {
                return Err(unknown("--exclude-marker", name, trial));
            }
        }
        let keep: Vec<&str> = trial
            .labels()
            .iter()
            .map(String::as_str)
            .filter(|l| !opts.exclude.iter().any(|e| e == l))
            .collect();
        out = trial.select(&keep).expect("labels of the trial");
        actions.extend(
            opts.exclude
                .iter()
                .map(|m| Action::Excluded { marker: m.clone() }),
        );
    }
    for swap in &opts.swaps {
        let ia = out
            .index_of(&swap.a)
            .map_err(|_| unknown("--swap-labels", &swap.a, &out))?;
        let ib = out
            .index_of(&swap.b)
            .map_err(|_| unknown("--swap-labels", &swap.b, &out))?;
        let first = out.first_frame();
        let last = first + out.n_frames() as i64 - 1;
        let from = swap.from.unwrap_or(first).max(first);
        let to = swap.to.unwrap_or(last).min(last);
        if from > to {
            return Err(RepairError::OutsideTrial {
                arg: swap.to_arg(),
                from: swap.from.unwrap_or(first),
                to: swap.to.unwrap_or(last),
                first,
                last,
            });
        }
        let n = out.labels().len();
        let positions = out.positions_mut();
        for f in (from - first) as usize..=(to - first) as usize {
            positions.swap(f * n + ia, f * n + ib);
        }
        actions.push(Action::Swapped {
            swap: swap.clone(),
            first: from,
            last: to,
        });
    }
    if opts.fill_gaps > 0 {
        fill_gaps(&mut out, model, opts.fill_gaps, &mut actions);
    }
    Ok((out, actions))
}

/// Gaps of marker `j` as inclusive frame ranges.
fn gaps_of(t: &Trial, j: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for f in 0..t.n_frames() {
        match (t.get(f, j).is_none(), start) {
            (true, None) => start = Some(f),
            (false, Some(s)) => {
                out.push((s, f - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, t.n_frames() - 1));
    }
    out
}

fn fill_gaps(t: &mut Trial, model: Option<&Model>, max_len: usize, actions: &mut Vec<Action>) {
    // Columns of the same segment as each column (by the model's marker names).
    let segment_of: Vec<Option<usize>> = t
        .labels()
        .iter()
        .map(|l| {
            model.and_then(|m| {
                m.markers()
                    .iter()
                    .find(|mk| &mk.name == l)
                    .map(|mk| mk.segment.0)
            })
        })
        .collect();
    let original = t.clone();
    let nf = t.n_frames();
    for j in 0..t.labels().len() {
        // With a model, only its markers are filled (the others are not fitted).
        if model.is_some() && segment_of[j].is_none() {
            continue;
        }
        let mates: Vec<usize> = match segment_of[j] {
            Some(s) => (0..t.labels().len())
                .filter(|&k| k != j && segment_of[k] == Some(s))
                .collect(),
            None => Vec::new(),
        };
        let (mut rigid, mut spline, mut left) = ([0usize; 2], [0usize; 2], [0usize; 2]);
        let mut filled = original.trajectory(j);
        for (s, e) in gaps_of(&original, j) {
            let len = e - s + 1;
            let before = s.checked_sub(1);
            let after = (e + 1 < nf).then_some(e + 1);
            if len > max_len || (before.is_none() && after.is_none()) {
                left[0] += 1;
                left[1] += len;
                continue;
            }
            let by_rigid = rigid_fill(&original, j, &mates, (s, e), before, after);
            if let Some(points) = by_rigid {
                filled[s..=e].copy_from_slice(&points);
                rigid[0] += 1;
                rigid[1] += len;
            } else if let (Some(b), Some(a)) = (before, after) {
                spline_fill(&original.trajectory(j), (b, a), &mut filled[s..=e]);
                spline[0] += 1;
                spline[1] += len;
            } else {
                left[0] += 1;
                left[1] += len;
            }
        }
        t.set_trajectory(j, &filled);
        let marker = t.labels()[j].clone();
        for (method, [gaps, frames]) in [(FillMethod::Rigid, rigid), (FillMethod::Spline, spline)] {
            if gaps > 0 {
                actions.push(Action::Filled {
                    marker: marker.clone(),
                    method,
                    gaps,
                    frames,
                });
            }
        }
        if left[0] > 0 {
            actions.push(Action::LeftUnfilled {
                marker,
                gaps: left[0],
                frames: left[1],
            });
        }
    }
}

/// The gap `s..=e` of marker `j` filled by its segment `mates` carried rigidly from the frames
/// just `before` and `after` it (blended linearly when both exist; one alone only at the
/// trial's ends), or `None` when a frame of the gap cannot be carried.
fn rigid_fill(
    original: &Trial,
    j: usize,
    mates: &[usize],
    (s, e): (usize, usize),
    before: Option<usize>,
    after: Option<usize>,
) -> Option<Vec<Vector3<f64>>> {
    let len = e - s + 1;
    (s..=e)
        .map(|f| {
            let from = |r: usize| rigid_carry(original, j, mates, r, f);
            match (before.and_then(from), after.and_then(from)) {
                (Some(a), Some(b)) => {
                    let w = (f - s + 1) as f64 / (len + 1) as f64;
                    Some(a * (1.0 - w) + b * w)
                }
                (Some(a), None) if after.is_none() => Some(a),
                (None, Some(b)) if before.is_none() => Some(b),
                _ => None,
            }
        })
        .collect()
}

/// The gap between the present frames `b` and `a` of trajectory `traj` filled (`gap`: frames
/// `b + 1 ..= a − 1`) by the cubic Hermite spline through both ends with the slopes there.
fn spline_fill(traj: &[Vector3<f64>], (b, a): (usize, usize), gap: &mut [Vector3<f64>]) {
    let nf = traj.len();
    let slope = |i: usize, prev: Option<usize>, next: Option<usize>| {
        let present = |k: Option<usize>| k.filter(|&k| traj[k].x.is_finite());
        match (present(prev), present(next)) {
            (Some(p), Some(n)) => (traj[n] - traj[p]) / (n - p) as f64,
            (Some(p), None) => (traj[i] - traj[p]) / (i - p) as f64,
            (None, Some(n)) => (traj[n] - traj[i]) / (n - i) as f64,
            (None, None) => Vector3::zeros(),
        }
    };
    // Slopes per frame at the two ends; the gap spans h = a − b frames.
    let m0 = slope(b, b.checked_sub(1), None);
    let m1 = slope(a, None, (a + 1 < nf).then_some(a + 1));
    let h = (a - b) as f64;
    let (p0, p1) = (traj[b], traj[a]);
    for (k, slot) in gap.iter_mut().enumerate() {
        let f = b + 1 + k;
        let u = (f - b) as f64 / h;
        let (u2, u3) = (u * u, u * u * u);
        *slot = p0 * (2.0 * u3 - 3.0 * u2 + 1.0)
            + m0 * (h * (u3 - 2.0 * u2 + u))
            + p1 * (-2.0 * u3 + 3.0 * u2)
            + m1 * (h * (u3 - u2));
    }
}

/// Marker `j` of reference frame `r` carried into frame `f` by the least-squares rigid
/// transform of its segment mates present in both frames (at least three), or `None`.
fn rigid_carry(t: &Trial, j: usize, mates: &[usize], r: usize, f: usize) -> Option<Vector3<f64>> {
    let pj = t.get(r, j)?;
    let (from, to): (Vec<_>, Vec<_>) = mates
        .iter()
        .filter_map(|&k| Some((t.get(r, k)?, t.get(f, k)?)))
        .unzip();
    if from.len() < 3 {
        return None;
    }
    let pose = crate::spatial::rigid_fit(&from, &to);
    let p = pose.rot * pj + pose.trans;
    p.x.is_finite().then_some(p)
}

#[cfg(test)]
mod tests;
