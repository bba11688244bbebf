//! Why no frame of a calibration's trials can be fitted, when every frame leaves some
//! coordinate undetermined by its markers ([`crate::ik::solvable`]): the coordinate found most
//! often, the segment it moves, and how often each marker of that segment and the segments
//! below it was present. The plain causes (no model marker in a trial, every marker missing
//! in every frame) are told before a fit by the front ends; this is the one left, too few
//! markers on a segment.

use crate::model::{Model, SegmentId};

/// Tally of the frames a calibration skipped, by the coordinate that left them undetermined.
pub(super) struct Unfittable {
    /// Frames skipped per coordinate (index in `q`).
    by_coordinate: Vec<usize>,
    /// Frames in which each model marker was present (not missing, not gross).
    present: Vec<usize>,
    frames: usize,
}

impl Unfittable {
    pub(super) fn new(model: &Model) -> Self {
        Unfittable {
            by_coordinate: vec![0; model.coordinates().len()],
            present: vec![0; model.markers().len()],
            frames: 0,
        }
    }

    /// Counts one frame: its targets (NaN where missing) and the coordinate it left
    /// undetermined, if any.
    pub(super) fn count(
        &mut self,
        targets: &[nalgebra::Vector3<f64>],
        undetermined: Option<usize>,
    ) {
        self.frames += 1;
        for (n, t) in self.present.iter_mut().zip(targets) {
            if !t.x.is_nan() {
                *n += 1;
            }
        }
        if let Some(c) = undetermined {
            self.by_coordinate[c] += 1;
        }
    }

    /// The cause in words: `: <coordinate> is undetermined in K of N frames: segment <s> and
    /// the segments below it carry markers A (in every frame), B (never), …`; empty when no
    /// frame was counted.
    pub(super) fn describe(&self, model: &Model) -> String {
        let Some((coord, &k)) = self
            .by_coordinate
            .iter()
            .enumerate()
            .max_by_key(|&(i, &k)| (k, std::cmp::Reverse(i)))
            .filter(|(_, &k)| k > 0)
        else {
            return String::new();
        };
        let c = &model.coordinates()[coord];
        let segment = model.joints()[c.joint].child;
        let markers: Vec<String> = model
            .markers()
            .iter()
            .enumerate()
            .filter(|(_, m)| below(model, m.segment, segment))
            .map(|(j, m)| format!("{} ({})", m.name, self.share(self.present[j])))
            .collect();
        let carried = if markers.is_empty() {
            "no marker".to_string()
        } else {
            format!("the markers {}", markers.join(", "))
        };
        format!(
            ": {} is undetermined in {k} of {} frames (segment {} and the segments below it \
             carry {carried})",
            c.name,
            self.frames,
            model.segments()[segment.0].name,
        )
    }

    fn share(&self, n: usize) -> String {
        match n {
            0 => "never present".to_string(),
            n if n == self.frames => "in every frame".to_string(),
            n => format!("in {n} of {} frames", self.frames),
        }
    }
}

/// Whether segment `s` is `top` or lies below it in the tree.
fn below(model: &Model, s: SegmentId, top: SegmentId) -> bool {
    let mut s = Some(s);
    while let Some(id) = s {
        if id == top {
            return true;
        }
        s = model.segments()[id.0].parent;
    }
    false
}
