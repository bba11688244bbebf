//! The marker targets of a calibration's frames, read from the trials where they lie.
//!
//! Frame `f` of a [`super::Problem`] is frame `k` of trial `t`; its target for model marker
//! `j` is the trial's sample in the column that feeds `j` ([`crate::ik::MarkerMap`]), or
//! missing (NaN) when the trial lacks that marker or the sample is gross
//! ([`crate::ik::is_gross`]: dropped once for both levels). The targets are not copied: a
//! copy of every frame's targets would cost as much memory as the trials themselves (24 bytes
//! per marker and frame), while a frame's targets are gathered again in a few nanoseconds per
//! marker when a pass over the frames needs them. Each fitted frame costs 8 bytes here.

use nalgebra::Vector3;

use crate::ik::is_gross;
use crate::trial::Trial;

/// One trial and which of its columns feeds each model marker.
#[derive(Debug, Clone)]
struct Source<'t> {
    trial: &'t Trial,
    /// `columns[j]`: the trial column of model marker `j` (`None`: absent in every frame).
    columns: Vec<Option<usize>>,
    /// Whether some sample of a mapped column is gross (else the reads skip the test).
    gross: bool,
}

/// The fitted frames' targets per model marker, borrowed from the trials.
#[derive(Debug, Clone)]
pub(crate) struct Targets<'t> {
    sources: Vec<Source<'t>>,
    /// Per fitted frame: (source, frame of that trial).
    frames: Vec<(u32, u32)>,
    n_markers: usize,
}

impl<'t> Targets<'t> {
    /// No frames yet; `n_markers` model markers.
    pub(crate) fn new(n_markers: usize) -> Self {
        Targets {
            sources: Vec::new(),
            frames: Vec::new(),
            n_markers,
        }
    }

    /// Adds a trial whose model marker `j` is read from column `columns[j]`; returns its
    /// index for [`Targets::push`].
    pub(crate) fn add_trial(&mut self, trial: &'t Trial, columns: Vec<Option<usize>>) -> usize {
        debug_assert_eq!(columns.len(), self.n_markers);
        let gross = (0..trial.n_frames()).any(|f| {
            let row = trial.frame(f);
            columns
                .iter()
                .flatten()
                .any(|&c| !row[c].x.is_nan() && is_gross(&row[c]))
        });
        self.sources.push(Source {
            trial,
            columns,
            gross,
        });
        self.sources.len() - 1
    }

    /// Appends frame `frame` of trial `source` as the next fitted frame.
    pub(crate) fn push(&mut self, source: usize, frame: usize) {
        let narrow = |v: usize| u32::try_from(v).expect("fewer than 2³² trials and frames");
        self.frames.push((narrow(source), narrow(frame)));
    }

    /// Fitted frames.
    pub(crate) fn len(&self) -> usize {
        self.frames.len()
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Model markers per frame.
    pub(crate) fn n_markers(&self) -> usize {
        self.n_markers
    }

    /// Frame `f`'s targets, one per model marker (NaN where missing), into `out`; returns
    /// them.
    pub(crate) fn fill<'a>(&self, f: usize, out: &'a mut Vec<Vector3<f64>>) -> &'a [Vector3<f64>] {
        let (s, k) = self.frames[f];
        self.fill_from(s as usize, k as usize, out)
    }

    /// Frame `frame` of trial `source`'s targets (whether or not it is a fitted frame).
    pub(crate) fn fill_from<'a>(
        &self,
        source: usize,
        frame: usize,
        out: &'a mut Vec<Vector3<f64>>,
    ) -> &'a [Vector3<f64>] {
        let src = &self.sources[source];
        let row = src.trial.frame(frame);
        let missing = Vector3::from_element(f64::NAN);
        out.clear();
        out.extend(src.columns.iter().map(|c| match c {
            Some(c) if !(src.gross && is_gross(&row[*c])) => row[*c],
            _ => missing,
        }));
        out
    }

    /// Frame `f`'s targets in a new vector ([`Targets::fill`] without an allocation to
    /// reuse).
    pub(crate) fn get(&self, f: usize) -> Vec<Vector3<f64>> {
        let mut out = Vec::with_capacity(self.n_markers);
        self.fill(f, &mut out);
        out
    }

    /// Every frame's targets in order, each in a new vector.
    pub(crate) fn iter(&self) -> impl Iterator<Item = Vec<Vector3<f64>>> + '_ {
        (0..self.len()).map(|f| self.get(f))
    }

    /// The targets of the frames `frames` (indices into these), in that order.
    pub(crate) fn select(&self, frames: impl IntoIterator<Item = usize>) -> Self {
        Targets {
            sources: self.sources.clone(),
            frames: frames.into_iter().map(|f| self.frames[f]).collect(),
            n_markers: self.n_markers,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::MarkerMap;
    use crate::model::lower_limb::{lower_limb, Side};
    use crate::model::Model;

    /// What `Problem::new` copied before the targets were read in place: the model-ordered
    /// targets of [`MarkerMap::targets`] with gross samples set missing.
    fn copied(map: &MarkerMap, trial: &Trial, f: usize) -> Vec<Vector3<f64>> {
        let mut out = Vec::new();
        map.targets(trial, f, &mut out);
        for t in out.iter_mut().filter(|t| !t.x.is_nan() && is_gross(t)) {
            *t = Vector3::from_element(f64::NAN);
        }
        out
    }

    fn same(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (0..3).all(|k| x[k] == y[k] || (x[k].is_nan() && y[k].is_nan())))
    }

    #[test]
    fn reads_what_the_copy_held_with_absent_gross_and_missing_samples() {
        let model = Model::compile(&lower_limb(Side::Right)).unwrap();
        // The trial lacks the model's second marker, has an extra column and lists the
        // others in reverse order.
        let mut labels: Vec<String> = model
            .markers()
            .iter()
            .skip(2)
            .map(|m| m.name.clone())
            .rev()
            .collect();
        labels.insert(1, "EXTRA".into());
        labels.push(model.markers()[0].name.clone());
        let n = labels.len();
        let frames = 6;
        let mut positions: Vec<Vector3<f64>> = (0..frames * n)
            .map(|i| Vector3::new(0.001 * i as f64, 1.0 - 0.002 * i as f64, 0.3))
            .collect();
        positions[n + 3] = Vector3::new(1e9, 0.0, 0.0); // gross
        positions[2 * n + 4] = Vector3::from_element(f64::NAN); // a gap
        let trial = Trial::new(labels, 100.0, 1, positions).unwrap();
        let clean = Trial::new(
            trial.labels().to_vec(),
            100.0,
            1,
            (0..frames * n)
                .map(|i| Vector3::repeat(0.01 * i as f64))
                .collect(),
        )
        .unwrap();
        let mut targets = Targets::new(model.markers().len());
        for t in [&trial, &clean] {
            let (map, absent) = MarkerMap::allowing_absent(&model, t.labels());
            assert_eq!(absent, vec![model.markers()[1].name.clone()]);
            let s = targets.add_trial(t, map.columns);
            for f in (0..frames).rev() {
                targets.push(s, f);
            }
        }
        assert!(targets.sources[0].gross && !targets.sources[1].gross);
        let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
        let mut buf = Vec::new();
        for (i, (t, f)) in [&trial, &clean]
            .iter()
            .flat_map(|t| (0..frames).rev().map(move |f| (*t, f)))
            .enumerate()
        {
            let want = copied(&map, t, f);
            assert!(same(targets.fill(i, &mut buf), &want), "frame {i}");
            assert!(same(&targets.get(i), &want));
        }
        let picked = targets.select([7, 1]);
        assert_eq!(picked.len(), 2);
        assert!(same(&picked.get(0), &copied(&map, &clean, 4)));
        assert!(same(&picked.get(1), &copied(&map, &trial, 4)));
    }
}
