//! Zero-phase filtering of a whole [`Trial`], stretch by stretch between gaps (see the
//! [crate docs](crate) for the short-stretch policy).

use std::ops::Range;

use nalgebra::Vector3;
use serde::Serialize;

use super::{sosfiltfilt_padlen, LowPass, SignalError};
use jointfit::trial::Trial;

/// A gap-free stretch that was filtered.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FilteredStretch {
    /// Frames of the stretch, as indices into the trial (source frame = `first_frame + i`).
    pub frames: Range<usize>,
    /// Samples of odd extension used at each end; less than
    /// [`FilterReport::default_padlen`] when the stretch was too short for the default.
    pub padlen: usize,
}

/// What filtering did to one marker.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerFilterReport {
    /// Marker label.
    pub label: String,
    /// Gap-free stretches that were filtered, in frame order.
    pub filtered: Vec<FilteredStretch>,
    /// Gap-free stretches left unfiltered (too short), as frame index ranges, in frame order.
    pub raw: Vec<Range<usize>>,
    /// Largest distance between a filtered and a measured position, metres (0 when nothing was
    /// filtered).
    pub max_displacement_m: f64,
    /// Frame index where that largest displacement occurred (`None` when nothing was filtered).
    pub max_displacement_frame: Option<usize>,
}

/// What [`filter_trial`] did, per marker, and the filter it used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilterReport {
    /// Order of the Butterworth design run forward and backward.
    pub design_order: usize,
    /// Cutoff of that design in Hz (after Winter's correction when requested).
    pub design_cutoff_hz: f64,
    /// scipy's default padding for this design (`3·ntaps`); longer stretches used it.
    pub default_padlen: usize,
    /// Shortest padding used for a short stretch (`ntaps`); see [`LowPass::padlen_for`].
    pub min_padlen: usize,
    /// One entry per marker, in the trial's marker order.
    pub markers: Vec<MarkerFilterReport>,
}

impl FilterReport {
    /// Markers whose filtered positions moved by more than `threshold_m` metres somewhere.
    pub fn moved_more_than(&self, threshold_m: f64) -> impl Iterator<Item = &MarkerFilterReport> {
        self.markers
            .iter()
            .filter(move |m| m.max_displacement_m > threshold_m)
    }

    #[cfg(test)]
    /// Largest displacement over all markers, metres.
    pub(crate) fn max_displacement_m(&self) -> f64 {
        self.markers
            .iter()
            .map(|m| m.max_displacement_m)
            .fold(0.0, f64::max)
    }

    #[cfg(test)]
    /// Number of stretches left raw over all markers.
    pub(crate) fn raw_stretch_count(&self) -> usize {
        self.markers.iter().map(|m| m.raw.len()).sum()
    }
}

/// Maximal runs of frames where `present` is true.
fn stretches(present: &[bool]) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &p) in present.iter().enumerate() {
        match (p, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push(s..i);
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push(s..present.len());
    }
    out
}

/// Filters every marker coordinate of `trial` with `filter`, each gap-free stretch on its own.
///
/// Returns the filtered trial (same markers, frames and rate; missing samples stay missing, as
/// NaN in all three coordinates; stretches too short to filter keep their measured values) and
/// a report of what was filtered, what was left raw and how far filtering moved each marker.
///
/// # Errors
/// The design errors of [`LowPass::design`] (cutoff not below the trial's Nyquist frequency,
/// odd effective order, …). Nothing depends on the data.
pub fn filter_trial(trial: &Trial, filter: &LowPass) -> Result<(Trial, FilterReport), SignalError> {
    let rate = trial.rate();
    let sos = filter.design(rate)?;
    let mut report = FilterReport {
        design_order: filter.design_order()?,
        design_cutoff_hz: filter.design_cutoff_hz(rate)?,
        default_padlen: sos.default_padlen(),
        min_padlen: sos.ntaps(),
        markers: Vec::with_capacity(trial.labels().len()),
    };

    let mut out = trial.clone();
    let mut coord = Vec::new();
    for (marker, label) in trial.labels().iter().enumerate() {
        let raw = trial.trajectory(marker);
        let present: Vec<bool> = raw
            .iter()
            .map(|p| p.iter().all(|c| c.is_finite()))
            .collect();
        let mut filtered: Vec<Vector3<f64>> = raw
            .iter()
            .zip(&present)
            .map(|(p, &ok)| if ok { *p } else { Vector3::repeat(f64::NAN) })
            .collect();
        let mut m = MarkerFilterReport {
            label: label.clone(),
            filtered: Vec::new(),
            raw: Vec::new(),
            max_displacement_m: 0.0,
            max_displacement_frame: None,
        };
        for frames in stretches(&present) {
            let Some(padlen) = filter.padlen_for(&sos, frames.len()) else {
                m.raw.push(frames);
                continue;
            };
            for axis in 0..3 {
                coord.clear();
                coord.extend(raw[frames.clone()].iter().map(|p| p[axis]));
                let y = sosfiltfilt_padlen(&sos, &coord, padlen)
                    .expect("stretches are finite and longer than their padding");
                for (f, v) in frames.clone().zip(y) {
                    filtered[f][axis] = v;
                }
            }
            for f in frames.clone() {
                let d = (filtered[f] - raw[f]).norm();
                if m.max_displacement_frame.is_none() || d > m.max_displacement_m {
                    m.max_displacement_m = d;
                    m.max_displacement_frame = Some(f);
                }
            }
            m.filtered.push(FilteredStretch { frames, padlen });
        }
        out.set_trajectory(marker, &filtered);
        report.markers.push(m);
    }
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::stretches;

    #[test]
    fn stretches_between_gaps() {
        let t = true;
        let f = false;
        assert!(stretches(&[]).is_empty());
        assert!(stretches(&[f, f]).is_empty());
        assert_eq!(stretches(&[t, t, t]), vec![0..3]);
        assert_eq!(stretches(&[f, t, t, f, t, f, f, t]), vec![1..3, 4..5, 7..8]);
    }
}
