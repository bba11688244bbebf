//! The fit's unknowns laid out in one vector, the problem's data, and its starting point.
//!
//! `θ = (g, u, δ, q_1 … q_F)`: first the fitted factors `g` (groups in order, one each or
//! three with `per_axis`), then the log overall size `u` (with the anthropometric prior
//! only), then the offset `δ_j` (three, m, in its body) of each marker not held at its
//! scaled generic place, then the coordinates `q_f` of each frame. The shared unknowns
//! `(g, u, δ)` come before every frame's, the split the Schur elimination uses
//! (`crate::normal`).
//!
//! Starting point: every factor 1, or the stature ratio `H/H_generic` when a stature is given
//! (and `u` its log), every offset 0, and each frame's pose by inverse kinematics on the
//! model at that starting size (jointfit's IK seed, then its per-frame solver).

use nalgebra::Vector3;

use super::options::{ScaleError, ScaleOptions};
use crate::basis::{factors_of, BasisData, FactorBasis, FramePoints};
use crate::geometry::{scaled_spec, ScaleFactors};
use crate::normal::Step;
use jointfit::ik::lm::IkWorkspace;
use jointfit::ik::IkOptions;
use jointfit::model::spec::ModelSpec;
use jointfit::model::Model;

/// Where each unknown sits in `θ` (module docs).
pub(super) struct Layout {
    /// Per group: first unknown and count (1 or 3); the factors come first, `0..k`.
    pub(super) groups: Vec<(usize, usize)>,
    /// Number of factor unknowns.
    pub(super) k: usize,
    /// The log overall size `u`, with the anthropometric prior.
    pub(super) size: Option<usize>,
    /// Per model marker: first unknown of its δ, if free.
    pub(super) delta: Vec<Option<usize>>,
    /// Per frame: first unknown of its q; the shared unknowns are `0..q[0]`.
    pub(super) q: Vec<usize>,
    /// Number of unknowns.
    pub(super) n: usize,
}

/// The problem: the generic model, the targets, the options, the layout of `θ` and the basis
/// that gives the markers at any `θ` (`crate::basis`).
pub(super) struct Problem<'a> {
    pub(super) spec: &'a ModelSpec,
    pub(super) opts: &'a ScaleOptions,
    /// `targets[f][j]`: the measured position (m, world) of model marker `j` in frame `f`.
    pub(super) targets: &'a [Vec<Vector3<f64>>],
    pub(super) lay: Layout,
    /// Coordinates per frame.
    pub(super) n_q: usize,
    /// The starting θ; its coordinates anchor the weak pose rows.
    pub(super) start: Vec<f64>,
    /// Per model marker: the SD of its offset prior (m).
    pub(super) msd: Vec<f64>,
    /// Per model marker: the weight of its data rows in the static frame
    /// (`ScaleOptions::marker_weights`).
    pub(super) weight: Vec<f64>,
    pub(super) basis: FactorBasis,
}

impl Problem<'_> {
    /// Every body's factors at `th`.
    pub(super) fn factors(&self, th: &[f64]) -> ScaleFactors {
        factors_of(
            &self.opts.groups,
            &th[..self.lay.k],
            &self.opts.fixed_factors,
        )
    }

    /// The scaled model with the markers moved by their offsets.
    pub(super) fn model(&self, th: &[f64]) -> Result<Model, ScaleError> {
        let mut spec = scaled_spec(self.spec, &self.factors(th));
        for (m, d) in spec.markers.iter_mut().zip(&self.lay.delta) {
            if let Some(at) = d {
                for k in 0..3 {
                    m.position[k] += th[at + k];
                }
            }
        }
        Ok(Model::compile(&spec)?)
    }

    /// Per model marker: its offset δ (zero when held).
    pub(super) fn deltas(&self, th: &[f64]) -> Vec<Vector3<f64>> {
        let at = |d: &Option<usize>| {
            d.map_or(Vector3::zeros(), |a| {
                Vector3::new(th[a], th[a + 1], th[a + 2])
            })
        };
        self.lay.delta.iter().map(at).collect()
    }

    /// The coordinates of frame `f`.
    pub(super) fn coords<'t>(&self, th: &'t [f64], f: usize) -> &'t [f64] {
        &th[self.lay.q[f]..self.lay.q[f] + self.n_q]
    }

    /// Marker positions of frame `f` (with the Jacobians when `jac`).
    pub(super) fn points(
        &self,
        th: &[f64],
        f: usize,
        jac: bool,
        ws: &mut BasisData,
    ) -> FramePoints {
        let g = &th[..self.lay.k];
        self.basis
            .points(g, &self.deltas(th), self.coords(th, f), jac, ws)
    }

    /// `th` moved by a step.
    pub(super) fn moved(&self, th: &[f64], step: &Step) -> Vec<f64> {
        let mut out = th.to_vec();
        for (x, d) in out.iter_mut().zip(step.shared.iter()) {
            *x += d;
        }
        for (&at, dq) in self.lay.q.iter().zip(&step.frames) {
            for (x, d) in out[at..at + self.n_q].iter_mut().zip(dq.iter()) {
                *x += d;
            }
        }
        out
    }
}

/// Every group's bodies exist, and none is in two groups or in one and held.
fn check_groups(spec: &ModelSpec, opts: &ScaleOptions) -> Result<(), ScaleError> {
    let mut seen = std::collections::HashSet::new();
    for g in &opts.groups {
        for b in &g.bodies {
            if !spec.segments.iter().any(|s| s.name == *b) {
                return Err(ScaleError::UnknownBody(g.name.clone(), b.clone()));
            }
            if !seen.insert(b.clone()) || opts.fixed_factors.contains_key(b) {
                return Err(ScaleError::TwiceGrouped(b.clone()));
            }
        }
    }
    Ok(())
}

/// The layout of `θ` (module docs) for `frames` frames of `n_q` coordinates.
fn layout(
    spec: &ModelSpec,
    opts: &ScaleOptions,
    n_q: usize,
    frames: usize,
) -> Result<Layout, ScaleError> {
    check_groups(spec, opts)?;
    let mut n = 0;
    let mut groups = Vec::new();
    for g in &opts.groups {
        groups.push((n, g.n_factors()));
        n += g.n_factors();
    }
    let k = n;
    let size = opts.prior.map(|_| {
        n += 1;
        n - 1
    });
    let mut delta = Vec::new();
    for m in &spec.markers {
        if opts.fixed_markers.contains(&m.name) {
            delta.push(None);
        } else {
            delta.push(Some(n));
            n += 3;
        }
    }
    let q = (0..frames).map(|f| n + f * n_q).collect();
    n += frames * n_q;
    Ok(Layout {
        groups,
        k,
        size,
        delta,
        q,
        n,
    })
}

/// There is a frame, and every frame has at least four markers with data.
fn check_present(targets: &[Vec<Vector3<f64>>]) -> Result<(), ScaleError> {
    if targets.is_empty() {
        return Err(ScaleError::TooFewMarkers {
            frame: 0,
            present: 0,
        });
    }
    for (f, t) in targets.iter().enumerate() {
        let present = t.iter().filter(|m| m.x.is_finite()).count();
        if present < 4 {
            return Err(ScaleError::TooFewMarkers { frame: f, present });
        }
    }
    Ok(())
}

/// The starting shared unknowns: factors 1 or the stature ratio, `u` its log, offsets 0
/// (the coordinates are zero until [`initial_poses`] fills them).
fn starting_size(lay: &Layout, opts: &ScaleOptions) -> Vec<f64> {
    let mut th = vec![0.0; lay.n];
    let size = opts
        .prior
        .and_then(|p| p.stature)
        .map_or(1.0, |(ratio, _)| ratio);
    th[..lay.k].fill(size);
    if let Some(u) = lay.size {
        th[u] = size.ln();
    }
    th
}

/// Each frame's pose by inverse kinematics on the model at `th`'s factors and offsets.
fn initial_poses(pb: &Problem, th: &mut [f64]) -> Result<(), ScaleError> {
    let m0 = pb.model(th)?;
    let ik = IkOptions::default();
    let mut ws = IkWorkspace::new(&m0);
    let p0 = m0.nominal_params();
    for (f, t) in pb.targets.iter().enumerate() {
        let mut q = ws.seed(&m0, &p0, t, &ik);
        ws.solve(&m0, &p0, t, &mut q, &ik);
        let at = pb.lay.q[f];
        th[at..at + pb.n_q].copy_from_slice(&q);
    }
    Ok(())
}

/// The problem at its starting point (module docs), with `weight` the markers' static
/// weights (`fit::markers`).
pub(super) fn start<'a>(
    spec: &'a ModelSpec,
    targets: &'a [Vec<Vector3<f64>>],
    opts: &'a ScaleOptions,
    weight: Vec<f64>,
) -> Result<(Problem<'a>, Vec<f64>), ScaleError> {
    check_present(targets)?;
    let basis = FactorBasis::new(spec, &opts.groups, &opts.fixed_factors)?;
    let n_q = basis.base().coordinates().len();
    let lay = layout(spec, opts, n_q, targets.len())?;
    let mut th = starting_size(&lay, opts);
    let mut pb = Problem {
        spec,
        opts,
        targets,
        lay,
        n_q,
        start: Vec::new(),
        msd: vec![opts.marker_sd; spec.markers.len()],
        weight,
        basis,
    };
    initial_poses(&pb, &mut th)?;
    pb.start = th.clone();
    Ok((pb, th))
}
