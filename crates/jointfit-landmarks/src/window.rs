//! The stable window of a static trial: consecutive frames with every needed marker present,
//! of a given length, with the least marker motion.
//!
//! Motion of a window = Σ over the needed markers of the mean squared distance of the marker
//! from its own mean over the window (m²); the report gives `sqrt(motion / n_markers)`, the
//! RMS distance of a marker from its window mean.

use nalgebra::Vector3;

use super::LandmarkError;
use jointfit::trial::Trial;

/// Which frames of the static trial were averaged.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticWindow {
    /// First frame of the window (0-based index into the trial).
    pub first: usize,
    /// Number of frames averaged.
    pub len: usize,
    /// Frames of the trial in which every needed marker is present.
    pub complete_frames: usize,
    pub total_frames: usize,
    /// Sampling rate of the trial (Hz).
    pub rate: f64,
    /// RMS distance of a needed marker from its mean over the window (m).
    pub motion_rms: f64,
}

impl StaticWindow {
    /// One past the last frame of the window.
    pub fn end(&self) -> usize {
        self.first + self.len
    }
    /// Duration of the window (s): its frame count over the rate.
    pub fn seconds(&self) -> f64 {
        self.len as f64 / self.rate
    }
}

/// Chooses the window (see the module docs). `columns` are the needed markers' columns and
/// `names` their labels (for errors); `wanted` is the window length in frames (≥ 1), shortened
/// to the longest run of complete frames when no run is that long.
pub(crate) fn select_window(
    trial: &Trial,
    columns: &[usize],
    names: &[String],
    wanted: usize,
) -> Result<StaticWindow, LandmarkError> {
    let nf = trial.n_frames();
    let complete: Vec<bool> = (0..nf)
        .map(|f| columns.iter().all(|&c| trial.get(f, c).is_some()))
        .collect();
    let n_complete = complete.iter().filter(|&&c| c).count();
    if n_complete == 0 {
        let mut never = Vec::new();
        let mut gaps = Vec::new();
        for (&c, name) in columns.iter().zip(names) {
            let present = (0..nf).filter(|&f| trial.get(f, c).is_some()).count();
            if present == 0 {
                never.push(name.clone());
            } else if present < nf {
                gaps.push(format!("{name} ({present} of {nf})"));
            }
        }
        return Err(LandmarkError::NoCompleteFrame {
            frames: nf,
            never_present: never,
            partly_present: gaps,
        });
    }
    // Runs of complete frames: (start, length).
    let mut runs = Vec::new();
    let mut f = 0;
    while f < nf {
        if complete[f] {
            let s = f;
            while f < nf && complete[f] {
                f += 1;
            }
            runs.push((s, f - s));
        } else {
            f += 1;
        }
    }
    let longest = runs.iter().map(|r| r.1).max().unwrap_or(0);
    let len = wanted.clamp(1, longest);

    // Prefix sums of positions centred on each marker's mean over complete frames (keeps the
    // sums small, so the variance subtraction loses no precision).
    let mut centre = vec![Vector3::zeros(); columns.len()];
    for (k, &c) in columns.iter().enumerate() {
        let mut s = Vector3::zeros();
        for f in (0..nf).filter(|&f| complete[f]) {
            s += trial.get(f, c).expect("complete frame");
        }
        centre[k] = s / n_complete as f64;
    }
    let mut best: Option<(f64, usize)> = None;
    for &(start, run_len) in &runs {
        if run_len < len {
            continue;
        }
        // s1[i], s2[i]: sums over frames start..start+i of (x − centre) and |x − centre|².
        let mut s1 = vec![vec![Vector3::zeros(); columns.len()]; run_len + 1];
        let mut s2 = vec![0.0; run_len + 1];
        for i in 0..run_len {
            let mut acc2 = s2[i];
            for (k, &c) in columns.iter().enumerate() {
                let d = trial.get(start + i, c).expect("complete frame") - centre[k];
                s1[i + 1][k] = s1[i][k] + d;
                acc2 += d.norm_squared();
            }
            s2[i + 1] = acc2;
        }
        let n = len as f64;
        for i in 0..=run_len - len {
            let sum2 = s2[i + len] - s2[i];
            let mean_sq: f64 = (0..columns.len())
                .map(|k| ((s1[i + len][k] - s1[i][k]) / n).norm_squared())
                .sum();
            let motion = (sum2 / n - mean_sq).max(0.0);
            if best.is_none_or(|(b, _)| motion < b) {
                best = Some((motion, start + i));
            }
        }
    }
    let (_, first) = best.expect("the longest run holds a window");
    let mut w = StaticWindow {
        first,
        len,
        complete_frames: n_complete,
        total_frames: nf,
        rate: trial.rate(),
        motion_rms: 0.0,
    };
    // The reported motion, two-pass (the prefix sums above only rank the windows).
    w.motion_rms = motion_rms(trial, columns, &w);
    Ok(w)
}

/// RMS distance of a marker from its mean over the window (every sample present).
fn motion_rms(trial: &Trial, columns: &[usize], w: &StaticWindow) -> f64 {
    let means = window_means(trial, columns, w);
    let mut sum2 = 0.0;
    for f in w.first..w.end() {
        for (k, &c) in columns.iter().enumerate() {
            sum2 += (trial.get(f, c).expect("complete frame") - means[k]).norm_squared();
        }
    }
    (sum2 / (w.len * columns.len()) as f64).sqrt()
}

/// A window chosen elsewhere (the common window of both legs) for these columns: every
/// sample must be present; the counts and the motion are recomputed for these columns.
pub(crate) fn check_window(
    trial: &Trial,
    columns: &[usize],
    names: &[String],
    w: &StaticWindow,
) -> Result<StaticWindow, LandmarkError> {
    let nf = trial.n_frames();
    if w.len == 0 || w.end() > nf {
        return Err(LandmarkError::Internal(format!(
            "static window {}–{} outside the trial's {nf} frames",
            w.first,
            w.end()
        )));
    }
    for f in w.first..w.end() {
        for (&c, name) in columns.iter().zip(names) {
            if trial.get(f, c).is_none() {
                return Err(LandmarkError::Internal(format!(
                    "marker {name:?} is missing in frame {f} of the static window"
                )));
            }
        }
    }
    let mut out = StaticWindow {
        complete_frames: (0..nf)
            .filter(|&f| columns.iter().all(|&c| trial.get(f, c).is_some()))
            .count(),
        total_frames: nf,
        rate: trial.rate(),
        motion_rms: 0.0,
        ..w.clone()
    };
    out.motion_rms = motion_rms(trial, columns, &out);
    Ok(out)
}

/// Mean position of each column over the window (every sample present by construction).
pub(crate) fn window_means(
    trial: &Trial,
    columns: &[usize],
    w: &StaticWindow,
) -> Vec<Vector3<f64>> {
    columns
        .iter()
        .map(|&c| {
            let s: Vector3<f64> = (w.first..w.end())
                .map(|f| trial.get(f, c).expect("window frames are complete"))
                .sum();
            s / w.len as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trial(frames: &[[Option<f64>; 2]]) -> Trial {
        let mut pos = Vec::new();
        for row in frames {
            for v in row {
                pos.push(match v {
                    Some(x) => Vector3::new(*x, 0.0, 0.0),
                    None => Vector3::repeat(f64::NAN),
                });
            }
        }
        Trial::new(vec!["a".into(), "b".into()], 10.0, 1, pos).unwrap()
    }

    #[test]
    fn picks_the_quietest_complete_window() {
        let s = Some;
        let t = trial(&[
            [s(0.0), s(0.0)],
            [s(0.5), s(0.0)],
            [s(1.0), None],
            [s(1.0), s(2.0)],
            [s(1.0), s(2.0)],
            [s(1.0), s(2.0)],
            [s(3.0), s(2.0)],
        ]);
        let names = vec!["a".to_string(), "b".to_string()];
        let w = select_window(&t, &[0, 1], &names, 3).unwrap();
        assert_eq!((w.first, w.len, w.complete_frames), (3, 3, 6));
        assert_eq!(w.motion_rms, 0.0);
        let m = window_means(&t, &[0, 1], &w);
        assert_eq!(m[1].x, 2.0);
        // Longer than any complete run: shortened to the longest run (frames 3..7).
        let w = select_window(&t, &[0, 1], &names, 10).unwrap();
        assert_eq!((w.first, w.len), (3, 4));
        assert!((w.motion_rms - (0.75f64 / 2.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_given_window_is_checked_and_its_motion_recomputed() {
        let s = Some;
        let t = trial(&[
            [s(0.0), s(5.0)],
            [s(1.0), None],
            [s(1.0), s(5.0)],
            [s(3.0), s(5.0)],
        ]);
        let names = vec!["a".to_string(), "b".to_string()];
        let both = select_window(&t, &[0, 1], &names, 2).unwrap();
        assert_eq!(both.first, 2);
        // Marker a alone over the window chosen for a and b: |3 − 1| / 2 from the mean.
        let a = check_window(&t, &[0], &names[..1], &both).unwrap();
        assert_eq!((a.first, a.len, a.complete_frames), (2, 2, 4));
        assert!((a.motion_rms - 1.0).abs() < 1e-12);
        let gap = StaticWindow { first: 0, ..both };
        let e = check_window(&t, &[0, 1], &names, &gap)
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"b\" is missing in frame 1"), "{e}");
    }

    #[test]
    fn no_complete_frame_names_the_markers() {
        let t = trial(&[[Some(0.0), None], [None, None]]);
        let names = vec!["a".to_string(), "b".to_string()];
        let e = select_window(&t, &[0, 1], &names, 1)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "no frame of the static trial (2 frames) has every needed marker; never present: \
             [\"b\"]; with gaps: [\"a (1 of 2)\"]"
        );
    }
}
