//! Marker trajectories: named markers × frames, SI units, missing samples as NaN.
//!
//! A [`Trial`] is what every reader produces and every solver consumes. Positions are in
//! metres in the laboratory frame as recorded; [`Trial::rotate`] maps a lab whose vertical is
//! Z (or −Z) onto the model's Y-up convention (docs/architecture.md §6: x anterior, y superior,
//! z to the right).
//!
//! A sample is *missing* when any of its three coordinates is NaN; readers turn every
//! format's own gap marker (negative C3D residual, exact (0,0,0), blank or NaN TRC cells)
//! into NaN so that no downstream code has to know about them.

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

/// Errors raised when building or querying a [`Trial`].
#[derive(Debug, Error, PartialEq)]
pub enum TrialError {
    #[error("trial has {labels} marker labels but {columns} marker columns per frame")]
    ShapeMismatch { labels: usize, columns: usize },
    #[error("marker label {0:?} appears twice")]
    DuplicateLabel(String),
    #[error("sampling rate must be positive and finite, got {0}")]
    BadRate(f64),
    #[error("marker {name:?} not found; the trial has: {available}")]
    UnknownMarker { name: String, available: String },
    #[error("{times} time stamps for {frames} frames")]
    TimesLength { times: usize, frames: usize },
    #[error("time stamp of frame {frame} is {time} s; time stamps must be finite and increase")]
    BadTimes { frame: usize, time: f64 },
}

/// Marker trajectories of one trial.
#[derive(Debug, Clone, PartialEq)]
pub struct Trial {
    /// Marker labels, one per column, unique.
    labels: Vec<String>,
    /// Sampling rate in Hz.
    rate: f64,
    /// Number of the first frame as the source file counts it (C3D's first frame, TRC's
    /// first Frame# value); frame `i` of this trial is source frame `first_frame + i`.
    first_frame: i64,
    /// Positions, frame-major: `positions[frame * n_markers + marker]`, metres, lab frame;
    /// NaN in every coordinate where the sample is missing.
    positions: Vec<Vector3<f64>>,
    /// The source file's own time stamps (s), one per frame, finite and strictly increasing
    /// (a TRC's Time column); `None`: frame `i` is at `i / rate` (C3D, synthetic trials).
    times: Option<Vec<f64>>,
}

impl Trial {
    /// Builds a trial from frame-major positions (`positions.len() == frames * labels.len()`).
    /// Any sample with a non-finite coordinate is normalised to all-NaN (missing).
    pub fn new(
        labels: Vec<String>,
        rate: f64,
        first_frame: i64,
        mut positions: Vec<Vector3<f64>>,
    ) -> Result<Self, TrialError> {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(TrialError::BadRate(rate));
        }
        let n = labels.len();
        if (n == 0 && !positions.is_empty()) || (n > 0 && !positions.len().is_multiple_of(n)) {
            return Err(TrialError::ShapeMismatch {
                labels: n,
                columns: positions.len(),
            });
        }
        let mut seen = std::collections::HashSet::new();
        for l in &labels {
            if !seen.insert(l.as_str()) {
                return Err(TrialError::DuplicateLabel(l.clone()));
            }
        }
        for p in &mut positions {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                *p = Vector3::repeat(f64::NAN);
            }
        }
        Ok(Self {
            labels,
            rate,
            first_frame,
            positions,
            times: None,
        })
    }

    /// The same trial with the source file's time stamps (`None`: `i / rate`). They must be
    /// one per frame, finite and strictly increasing.
    pub fn with_times(mut self, times: Option<Vec<f64>>) -> Result<Self, TrialError> {
        if let Some(t) = &times {
            if t.len() != self.n_frames() {
                return Err(TrialError::TimesLength {
                    times: t.len(),
                    frames: self.n_frames(),
                });
            }
            for (i, &v) in t.iter().enumerate() {
                if !v.is_finite() || (i > 0 && v <= t[i - 1]) {
                    return Err(TrialError::BadTimes { frame: i, time: v });
                }
            }
        }
        self.times = times;
        Ok(self)
    }

    /// The source file's time stamps, when it had them (see [`Trial::time`]).
    pub fn times(&self) -> Option<&[f64]> {
        self.times.as_deref()
    }

    pub fn labels(&self) -> &[String] {
        &self.labels
    }
    pub fn rate(&self) -> f64 {
        self.rate
    }
    pub fn first_frame(&self) -> i64 {
        self.first_frame
    }
    pub fn n_frames(&self) -> usize {
        if self.labels.is_empty() {
            0
        } else {
            self.positions.len() / self.labels.len()
        }
    }
    /// Time of frame `i` in seconds: the source file's own time stamp when it had one (a
    /// TRC's Time column, which OpenSim copies into its results), else `i / rate`, counted
    /// from the trial's first frame.
    pub fn time(&self, frame: usize) -> f64 {
        match &self.times {
            Some(t) => t[frame],
            None => frame as f64 / self.rate,
        }
    }

    /// Column index of a marker by label.
    pub fn index_of(&self, name: &str) -> Result<usize, TrialError> {
        self.labels
            .iter()
            .position(|l| l == name)
            .ok_or_else(|| TrialError::UnknownMarker {
                name: name.to_string(),
                available: self.labels.join(", "),
            })
    }

    /// Position of `marker` in `frame` (metres), `None` when missing.
    pub fn get(&self, frame: usize, marker: usize) -> Option<Vector3<f64>> {
        let p = self.positions[frame * self.labels.len() + marker];
        if p.x.is_nan() {
            None
        } else {
            Some(p)
        }
    }

    /// All markers of one frame (NaN where missing).
    pub fn frame(&self, frame: usize) -> &[Vector3<f64>] {
        let n = self.labels.len();
        &self.positions[frame * n..(frame + 1) * n]
    }

    /// Frame-major positions (NaN where missing).
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions
    }
    pub(crate) fn positions_mut(&mut self) -> &mut [Vector3<f64>] {
        &mut self.positions
    }

    /// The trajectory of one marker, one entry per frame (NaN where missing).
    pub fn trajectory(&self, marker: usize) -> Vec<Vector3<f64>> {
        (0..self.n_frames())
            .map(|f| self.positions[f * self.labels.len() + marker])
            .collect()
    }

    /// Overwrites the trajectory of one marker (`values.len() == n_frames`).
    pub fn set_trajectory(&mut self, marker: usize, values: &[Vector3<f64>]) {
        let n = self.labels.len();
        for (f, v) in values.iter().enumerate() {
            self.positions[f * n + marker] = *v;
        }
    }

    /// A new trial with only the named markers, in the order given.
    pub fn select(&self, names: &[&str]) -> Result<Trial, TrialError> {
        let idx: Vec<usize> = names
            .iter()
            .map(|n| self.index_of(n))
            .collect::<Result<_, _>>()?;
        let mut positions = Vec::with_capacity(idx.len() * self.n_frames());
        for f in 0..self.n_frames() {
            let row = self.frame(f);
            positions.extend(idx.iter().map(|&i| row[i]));
        }
        Trial::new(
            names.iter().map(|s| s.to_string()).collect(),
            self.rate,
            self.first_frame,
            positions,
        )?
        .with_times(self.times.clone())
    }

    /// A new trial with frames `start..end` (clamped to the trial).
    pub fn slice_frames(&self, start: usize, end: usize) -> Trial {
        let end = end.min(self.n_frames());
        let start = start.min(end);
        let n = self.labels.len();
        Trial {
            labels: self.labels.clone(),
            rate: self.rate,
            first_frame: self.first_frame + start as i64,
            positions: self.positions[start * n..end * n].to_vec(),
            times: self.times.as_ref().map(|t| t[start..end].to_vec()),
        }
    }

    /// Rotates every sample by `r` (lab → model frame). Missing samples stay missing.
    pub fn rotate(&mut self, r: &Matrix3<f64>) {
        for p in &mut self.positions {
            if !p.x.is_nan() {
                *p = r * *p;
            }
        }
    }

    /// Fraction of missing samples of one marker (0 to 1) and its longest gap in frames.
    pub fn gap_stats(&self, marker: usize) -> (f64, usize) {
        let nf = self.n_frames();
        let (mut missing, mut run, mut longest) = (0usize, 0usize, 0usize);
        for f in 0..nf {
            if self.get(f, marker).is_none() {
                missing += 1;
                run += 1;
                longest = longest.max(run);
            } else {
                run = 0;
            }
        }
        let frac = if nf == 0 {
            0.0
        } else {
            missing as f64 / nf as f64
        };
        (frac, longest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::{up_axis_rotation, UpAxis};

    fn small() -> Trial {
        let nan = Vector3::repeat(f64::NAN);
        Trial::new(
            vec!["A".into(), "B".into()],
            100.0,
            1,
            vec![
                Vector3::new(1.0, 2.0, 3.0),
                nan,
                Vector3::new(1.0, 2.0, f64::INFINITY),
                Vector3::new(0.5, 0.5, 0.5),
                Vector3::new(1.0, 0.0, 0.0),
                nan,
            ],
        )
        .unwrap()
    }

    #[test]
    fn shape_and_missing() {
        let t = small();
        assert_eq!(t.n_frames(), 3);
        assert!(t.get(0, 1).is_none());
        assert!(t.get(1, 0).is_none(), "infinite coordinate is missing");
        assert_eq!(t.gap_stats(1), (2.0 / 3.0, 1));
        assert_eq!(t.gap_stats(0), (1.0 / 3.0, 1));
    }

    #[test]
    fn select_and_errors() {
        let t = small();
        let s = t.select(&["B"]).unwrap();
        assert_eq!(s.labels().len(), 1);
        assert_eq!(s.get(1, 0), Some(Vector3::new(0.5, 0.5, 0.5)));
        let e = t.select(&["C"]).unwrap_err();
        assert_eq!(e.to_string(), "marker \"C\" not found; the trial has: A, B");
        assert!(matches!(
            Trial::new(vec!["A".into(), "A".into()], 1.0, 0, vec![]),
            Err(TrialError::DuplicateLabel(_))
        ));
        assert!(matches!(
            Trial::new(vec!["A".into()], 0.0, 0, vec![]),
            Err(TrialError::BadRate(_))
        ));
    }

    #[test]
    fn z_up_maps_to_y_up() {
        let r = up_axis_rotation(UpAxis::Z);
        let up = r * Vector3::new(0.0, 0.0, 1.0);
        assert_eq!(up, Vector3::new(0.0, 1.0, 0.0));
        assert!((r.determinant() - 1.0).abs() < 1e-15);
        let r = up_axis_rotation(UpAxis::NegZ);
        assert_eq!(
            r * Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(0.0, 1.0, 0.0)
        );
        assert!((r.determinant() - 1.0).abs() < 1e-15);
        for up in UpAxis::ALL {
            let r = up_axis_rotation(up);
            assert_eq!(r * up.direction(), Vector3::y(), "{up}");
            assert!((r.determinant() - 1.0).abs() < 1e-15);
            assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-15);
            assert_eq!(up.to_string().parse::<UpAxis>(), Ok(up));
        }
        assert_eq!("+Z".parse::<UpAxis>(), Ok(UpAxis::Z));
        assert!("up".parse::<UpAxis>().is_err());
    }
}
