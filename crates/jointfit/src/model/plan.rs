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
    /// Per segment, the coordinate columns of the steps from the root to it (root first);
    /// empty for a segment without markers that has a parent (nothing reads it).
    pub cols_q: Vec<Vec<JCol>>,
    /// As `cols_q`, for parameter columns.
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

        let mut markers_by_segment = vec![Vec::new(); step_ranges.len()];
        for (m, &s) in marker_segments.iter().enumerate() {
            markers_by_segment[s].push(m);
        }
        // Only segments that carry markers need their chain's columns; a chain walked once
        // per such segment keeps a long serial chain with markers near its tip linear in the
        // number of segments (copying every ancestor's list into every segment is quadratic).
        let mut cols_q: Vec<Vec<JCol>> = vec![Vec::new(); step_ranges.len()];
        let mut cols_p: Vec<Vec<JCol>> = vec![Vec::new(); step_ranges.len()];
        let mut seen_q = std::collections::HashSet::new();
        let mut seen_p = std::collections::HashSet::new();
        for s in 0..step_ranges.len() {
            if markers_by_segment[s].is_empty() && parents[s].is_some() {
                continue;
            }
            let mut chain = vec![s];
            while let Some(parent) = parents[*chain.last().unwrap_or(&s)] {
                chain.push(parent);
            }
            let (mut q, mut p) = (Vec::new(), Vec::new());
            seen_q.clear();
            seen_p.clear();
            for &seg in chain.iter().rev() {
                for k in step_ranges[seg].clone() {
                    let rotation = steps[k].motion.is_rotation();
                    let (list, seen, col, scale) = match steps[k].source {
                        Source::Const(_) => continue,
                        Source::Coord { index, scale } => (&mut q, &mut seen_q, index, scale),
                        // The derivative σ·scale is folded into the step axis at evaluation.
                        Source::Func { index, .. } => (&mut q, &mut seen_q, index, 1.0),
                        Source::Param { index, scale } => (&mut p, &mut seen_p, index, scale),
                    };
                    let first = seen.insert(col);
                    list.push(JCol {
                        step: k,
                        col,
                        scale,
                        rotation,
                        first,
                    });
                }
            }
            cols_q[s] = q;
            cols_p[s] = p;
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

#[cfg(test)]
mod tests {
    use crate::model::spec::ModelSpec;
    use crate::model::Model;

    /// A serial chain of `n` pin joints, each 1 cm from its parent, with one marker on the
    /// last segment.
    fn chain(n: usize) -> ModelSpec {
        let mut t = String::from("name = \"chain\"\n");
        for i in 0..n {
            t += &format!("[[segments]]\nname = \"s{i}\"\n");
        }
        for i in 0..n {
            let parent = if i == 0 {
                "ground".to_string()
            } else {
                format!("s{}", i - 1)
            };
            t += &format!(
                "[[joints]]\nname = \"j{i}\"\nparent = \"{parent}\"\nchild = \"s{i}\"\n\
                 [joints.kind]\ntype = \"pin\"\naxis = \"z\"\n\
                 [[joints.coordinates]]\nname = \"q{i}\"\nrange = [-1.0, 1.0]\n\
                 [joints.parent_offset]\nty = 0.01\n"
            );
        }
        t += &format!(
            "[[markers]]\nname = \"tip\"\nsegment = \"s{}\"\nposition = [0.0, 0.01, 0.0]\n",
            n - 1
        );
        ModelSpec::from_toml(&t).unwrap()
    }

    /// The plan of a long chain with one marker holds one column per coordinate, not one per
    /// (segment, ancestor) pair; the tip marker's Jacobian still has every coordinate.
    #[test]
    fn a_long_chain_plans_linearly() {
        let n = 3000;
        let model = Model::compile(&chain(n)).unwrap();
        let stored: usize = model.plan.cols_q.iter().map(Vec::len).sum();
        // The tip's chain (n columns) and the root's own column (kept for seeding).
        assert_eq!(stored, n + 1, "columns stored for a chain of {n}");
        let tip = &model.plan.cols_q[n - 1];
        assert!(tip.iter().enumerate().all(|(i, c)| c.col == i && c.first));
    }
}
