//! The evaluation plan: how forward kinematics walks the compiled steps fast.
//!
//! Runs of steps that do not read a coordinate (constants and parameters) form *blocks*.
//! A block's composed transform depends on `p` only, so [`crate::kinematics::KinData`] caches
//! it per parameter vector: inverse kinematics, which evaluates thousands of frames with the
//! same `p`, pays for the offset frames' sines and cosines once.
//!
//! Jacobian columns are listed per segment in chain order. The first step that writes a column
//! for a marker assigns it, later ones (a parameter read by two scalars) add to it, so the
//! structurally zero entries are never touched and the matrices need no clearing.

use std::ops::Range;

use super::compiled::{Source, Step};

#[derive(Debug, Clone)]
pub(crate) enum Item {
    /// Steps without coordinates, composed once per parameter vector.
    Block { id: usize, steps: Range<usize> },
    /// A step that reads a coordinate.
    Coord(usize),
}

/// One Jacobian column contribution of a chain step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct JCol {
    pub step: usize,
    pub col: usize,
    pub scale: f64,
    pub rotation: bool,
    /// First contribution to `col` along this chain: assign instead of add.
    pub first: bool,
}

#[derive(Debug, Clone)]
pub(crate) struct Plan {
    pub items: Vec<Vec<Item>>,
    pub n_blocks: usize,
    pub cols_q: Vec<Vec<JCol>>,
    pub cols_p: Vec<Vec<JCol>>,
    pub markers_by_segment: Vec<Vec<usize>>,
}

impl Plan {
    pub(crate) fn new(
        steps: &[Step],
        step_ranges: &[Range<usize>],
        parents: &[Option<usize>],
        marker_segments: &[usize],
    ) -> Plan {
        let mut items = Vec::with_capacity(step_ranges.len());
        let mut n_blocks = 0;
        for range in step_ranges {
            let mut seg_items = Vec::new();
            let mut k = range.start;
            while k < range.end {
                if steps[k].source.is_coordinate() {
                    seg_items.push(Item::Coord(k));
                    k += 1;
                    continue;
                }
                let start = k;
                while k < range.end && !steps[k].source.is_coordinate() {
                    k += 1;
                }
                seg_items.push(Item::Block {
                    id: n_blocks,
                    steps: start..k,
                });
                n_blocks += 1;
            }
            items.push(seg_items);
        }

        let mut cols_q: Vec<Vec<JCol>> = Vec::with_capacity(step_ranges.len());
        let mut cols_p: Vec<Vec<JCol>> = Vec::with_capacity(step_ranges.len());
        for (s, range) in step_ranges.iter().enumerate() {
            let (mut q, mut p) = match parents[s] {
                Some(parent) => (cols_q[parent].clone(), cols_p[parent].clone()),
                None => (Vec::new(), Vec::new()),
            };
            for k in range.clone() {
                let rotation = steps[k].motion.is_rotation();
                let (list, col, scale) = match steps[k].source {
                    Source::Const(_) => continue,
                    Source::Coord { index, scale } => (&mut q, index, scale),
                    // The derivative σ·scale is folded into the step axis at evaluation.
                    Source::Func { index, .. } => (&mut q, index, 1.0),
                    Source::Param { index, scale } => (&mut p, index, scale),
                };
                let first = !list.iter().any(|c: &JCol| c.col == col);
                list.push(JCol {
                    step: k,
                    col,
                    scale,
                    rotation,
                    first,
                });
            }
            cols_q.push(q);
            cols_p.push(p);
        }

        let mut markers_by_segment = vec![Vec::new(); step_ranges.len()];
        for (m, &s) in marker_segments.iter().enumerate() {
            markers_by_segment[s].push(m);
        }
        Plan {
            items,
            n_blocks,
            cols_q,
            cols_p,
            markers_by_segment,
        }
    }
}
