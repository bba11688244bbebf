//! Where a marker sits relative to the rest of its segment's cluster, frame by frame: the
//! leave-one-out test of the marker policy ([`super::marker_policy`]).
//!
//! For marker `j` of segment `s` with at least [`MIN_OTHERS`] other markers of `s` present,
//! the rigid transform `(R_i, t_i)` that best maps the others' static-trial (model) positions
//! `l_k` onto their measured positions `m_ik` in frame `i` (least squares, Kabsch 1976 by
//! SVD with the reflection removed, Arun et al. 1987) predicts where `j` should be; the
//! residual in the segment frame
//!
//! ```text
//! r_ij = R_iᵀ (m_ij − t_i) − l_j
//! ```
//!
//! has over the frames a mean `μ_j` and a spread `σ_j`. Unlike the residual after inverse
//! kinematics ([`crate::checks::offsets`]) it does not depend on the joint parameters at all:
//! a joint placed wrong by the landmark method leaves it at zero, while a marker that sits
//! elsewhere on its segment than in the static trial shows its full displacement (the IK
//! spreads part of it over the segment's other markers and absorbs part into the
//! coordinates). Skin motion of the cluster gives a mean of the order of its spread.

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::checks::offsets::frames_looked_at;
use crate::model::Model;
use crate::spatial::rigid_fit;
use crate::trial::Trial;

/// Other markers of the segment a frame needs for the leave-one-out transform.
pub(crate) const MIN_OTHERS: usize = 3;

/// The leave-one-out statistic of one model marker over a trial.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RigidOffset {
    pub marker: usize,
    /// `μ_j` in the segment frame (m).
    pub mean: Vector3<f64>,
    /// RMS distance of `r_ij` from `μ_j` (m).
    pub spread: f64,
    pub frames: usize,
}

impl RigidOffset {
    pub(crate) fn size(&self) -> f64 {
        self.mean.norm()
    }
    pub(crate) fn ratio(&self) -> f64 {
        if self.spread > 0.0 {
            self.size() / self.spread
        } else {
            f64::INFINITY
        }
    }
}

/// The leave-one-out statistic of marker `j` against the markers `others` (model indices,
/// with their trial columns `col`) over frames `frames`, `None` without a frame in which `j`
/// and [`MIN_OTHERS`] of the others are present. With `with_self`, the transform is fitted to
/// the others and `j` together (every marker's share of the misfit).
fn statistic(
    model: &Model,
    trial: &Trial,
    col: &[Option<usize>],
    j: usize,
    others: &[usize],
    frames: std::ops::Range<usize>,
    with_self: bool,
) -> Option<RigidOffset> {
    let cj = col[j]?;
    let mj = &model.markers()[j];
    let mut rs: Vec<Vector3<f64>> = Vec::new();
    for f in frames {
        let Some(xf) = trial.get(f, cj) else { continue };
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for &k in others {
            if let Some(x) = col[k].and_then(|c| trial.get(f, c)) {
                a.push(model.markers()[k].local);
                b.push(x);
            }
        }
        if a.len() < MIN_OTHERS {
            continue;
        }
        if with_self {
            a.push(mj.local);
            b.push(xf);
        }
        let pose = rigid_fit(&a, &b);
        rs.push(pose.rot.transpose() * (xf - pose.trans) - mj.local);
    }
    if rs.is_empty() {
        return None;
    }
    let n = rs.len() as f64;
    let mean = rs.iter().sum::<Vector3<f64>>() / n;
    let spread = (rs.iter().map(|r| (r - mean).norm_squared()).sum::<f64>() / n).sqrt();
    Some(RigidOffset {
        marker: j,
        mean,
        spread,
        frames: rs.len(),
    })
}

/// The markers of `model` that `steady` calls displaced by the leave-one-out statistic over
/// the frames [`frames_looked_at`] picks, with that statistic. Segment by segment, greedily:
/// among the markers whose statistic (against the segment's markers not yet flagged) passes
/// `steady`, the one with the largest mean residual of a transform fitted to all of them is
/// flagged (a displaced marker pulls the leave-one-out transforms of the others, so their
/// statistics can pass too; it keeps the largest share of the misfit itself), then the rest
/// are tested again without it, while [`MIN_OTHERS`] others remain.
pub(crate) fn rigid_displaced(
    model: &Model,
    trial: &Trial,
    steady: impl Fn(&RigidOffset) -> bool + Sync,
) -> Vec<RigidOffset> {
    let col: Vec<Option<usize>> = model
        .markers()
        .iter()
        .map(|m| trial.index_of(&m.name).ok())
        .collect();
    let (start, end) = frames_looked_at(trial.n_frames());
    let mut out = Vec::new();
    for s in 0..model.segments().len() {
        let mut set: Vec<usize> = (0..model.markers().len())
            .filter(|&k| {
                let m = &model.markers()[k];
                m.segment.0 == s && m.weight > 0.0 && col[k].is_some()
            })
            .collect();
        while set.len() > MIN_OTHERS {
            let others =
                |j: usize| -> Vec<usize> { set.iter().copied().filter(|&k| k != j).collect() };
            // Each candidate with its share, computed once and in parallel (collected in
            // the set's order, so the pick is that of a sequential pass: the last of equal
            // maxima).
            let candidates: Vec<(RigidOffset, f64)> = set
                .par_iter()
                .filter_map(|&j| statistic(model, trial, &col, j, &others(j), start..end, false))
                .filter(|o| steady(o))
                .map(|o| {
                    let share = statistic(
                        model,
                        trial,
                        &col,
                        o.marker,
                        &others(o.marker),
                        start..end,
                        true,
                    )
                    .map_or(0.0, |x| x.size());
                    (o, share)
                })
                .collect();
            let pick = candidates
                .into_iter()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(o, _)| o);
            let Some(pick) = pick else { break };
            set.retain(|&k| k != pick.marker);
            out.push(pick);
        }
    }
    out
}
