//! The outer level: joint parameters that make model markers match measured markers.
//!
//! Reinbolt et al. 2005, Eqs. (1)–(2):
//!
//! `e_inner(p) = Σ_i min_{q_i} Σ_j w_ij ‖m_ij − x_j(p, q_i)‖²`,  `p* = argmin_p e_inner(p)`,
//!
//! over a chosen subset of the parameters (the rest stay fixed), on the frames of one or more
//! trials (parameters shared, coordinates per frame). The free parameters are scaled to
//! `s ∈ [−1, 1]` inside their bounds, `p = lo + (s + 1)(hi − lo)/2`, as the paper did to help
//! its optimizers.
//!
//! Three outer solvers, all on the same objective:
//!
//! * [`joint`]: one Levenberg–Marquardt over every frame's `q_i` and `s` together. Its normal
//!   matrix has block-arrow structure (per-frame `n_q × n_q` blocks `U_i`, coupling blocks
//!   `W_i`, a parameter block `V`); the Schur complement `S = V − Σ W_iᵀ U_i⁻¹ W_i` reduces each
//!   step to one small solve in `s`. At a stationary point of the joint problem every `q_i` is
//!   an inner optimum, so it shares the two-level formulation's optima. The fast default.
//! * [`varpro`]: the two-level method with an exact gradient. After solving every frame's inner
//!   problem, the envelope theorem gives `∇_p e = −2 Σ_i J_p,iᵀ W r_i`, and the reduced
//!   (variable-projection) Jacobian `(I − J_q (J_qᵀWJ_q)⁻¹ J_qᵀW) J_p` gives a Gauss-Newton
//!   matrix equal to the undamped Schur complement above.
//! * [`pso`]: the particle swarm of Schutte et al. 2005 (global, derivative-free), each cost
//!   evaluation a full set of inner solves.
//!
//! With a [`prior::Prior`] attached ([`Problem::prior`]), all three minimize the maximum a
//! posteriori objective `e_inner(p) + σ² Σ_k ((p_k − μ_k)/s_k)²` instead (see [`prior`]).

pub(crate) mod joint;
mod kernel;
mod kernel_twist;
pub mod prior;
pub(crate) mod pso;
mod schur;
mod targets;
pub mod uncertainty;
mod unfittable;
pub(crate) mod varpro;

use rayon::prelude::*;
use thiserror::Error;

use crate::ik::lm::solve_frame;
use crate::ik::lm::IkWorkspace;
use crate::ik::trial_fit::trial_chunk_ranges;
use crate::ik::{seed_frame, undetermined_coordinate, FrameStatus, IkOptions, MarkerMap};
use crate::kinematics::{forward_kinematics, KinData, Want};
use crate::model::{Model, ParamId};
pub(crate) use crate::solver::Termination;
use crate::trial::Trial;
use nalgebra::Vector3;
pub(crate) use targets::Targets;

#[derive(Debug, Error, PartialEq)]
pub enum CalibError {
    #[error(transparent)]
    Ik(#[from] crate::ik::IkError),
    #[error("no parameter is free: choose at least one group or parameter")]
    NothingFree,
    #[error("unknown parameter group {group:?}; the groups are: {available}")]
    UnknownGroup { group: String, available: String },
    /// `detail` names the coordinate the markers left undetermined and the markers of its
    /// segment, with how often each was present.
    #[error("no frame has enough markers to fit{detail}")]
    NoFrames { detail: String },
    #[error("parameter vector has {got} values, the model has {expected}")]
    ParamLength { got: usize, expected: usize },
}

/// Parameters selected by group names (`hip`, `knee`, `ankle`, or `all`). On a bilateral
/// model, whose groups carry the side suffix (`hip_r`, `hip_l`), a name without the suffix
/// selects both sides' groups: `hip` is `hip_r` and `hip_l`.
pub fn params_for_groups(model: &Model, groups: &[&str]) -> Result<Vec<ParamId>, CalibError> {
    let mut out: Vec<ParamId> = Vec::new();
    for g in groups {
        let ids = if *g == "all" {
            (0..model.parameters().len()).map(ParamId).collect()
        } else {
            let mut ids = model.params_in_group(g);
            if ids.is_empty() {
                for s in ["_r", "_l"] {
                    ids.extend(model.params_in_group(&format!("{g}{s}")));
                }
            }
            if ids.is_empty() {
                return Err(CalibError::UnknownGroup {
                    group: g.to_string(),
                    available: group_choices(model),
                });
            }
            ids
        };
        for id in ids {
            if !out.contains(&id) {
                out.push(id);
            }
        }
    }
    out.sort();
    if out.is_empty() {
        return Err(CalibError::NothingFree);
    }
    Ok(out)
}

/// What [`params_for_groups`] accepts on `model`, for its error: `all`, the side-less names
/// that select both sides (`hip`, `knee`, `ankle`), then the model's own groups.
fn group_choices(model: &Model) -> String {
    let groups = model.groups();
    let mut names: Vec<String> = vec!["all".into()];
    for g in &groups {
        let bare = g
            .strip_suffix("_r")
            .or_else(|| g.strip_suffix("_l"))
            .unwrap_or(g);
        if !names.iter().any(|n| n == bare) {
            names.push(bare.to_string());
        }
    }
    for g in groups {
        if !names.contains(&g) {
            names.push(g);
        }
    }
    names.join(", ")
}

/// Step tolerance (rad, m) of the starting coordinates ([`Problem::initial_coords`]). A
/// coordinate 1e-5 rad off moves a marker half a metre from its joint by 5 µm, far below
/// skin-marker noise, and the solvers that go on from these points remove such an error in
/// their first step. Against the `ik` command's 1e-8, the command's fit takes 3.6 %, 3.0 % and
/// 2.4 % fewer instructions on opencap walking1, gait2392 walk1 and Hamner running (callgrind,
/// one thread); 1e-4 costs more joint iterations than it saves on gait2392.
pub(crate) const START_STEP_TOLERANCE: f64 = 1e-5;

/// Frames per partial sum of [`Problem::inner`] (fixed: it sets the order of the sum).
pub(crate) const INNER_CHUNK: usize = 256;

/// About this many frames per parallel task of [`Problem::inner`] (any value gives the same
/// result; small enough that a 143-frame trial is split between the threads).
pub(crate) const INNER_TASK: usize = 16;

/// Frames per parallel task of [`Problem::inner`] on `n` frames: at most [`INNER_TASK`], the
/// length that cuts `n` into `2⌈n / 2·INNER_TASK⌉` tasks of nearly equal length, so that two
/// threads split a short trial evenly (143 frames: 10 tasks of at most 15 frames, 5 : 5, where
/// tasks of 16 were 9, 5 : 4). The count is even for every trial of up to 224 frames; longer
/// ones have enough tasks (15 or more) for two threads to share them evenly anyway.
pub(crate) fn inner_task_len(n: usize) -> usize {
    let tasks = 2 * n.div_ceil(2 * INNER_TASK);
    n.div_ceil(tasks.max(1)).max(1)
}

/// One calibration problem: model, free parameters, the frames to fit (their targets read
/// from the trials in place, which therefore live as long as the problem).
#[derive(Debug, Clone)]
pub(crate) struct Problem<'m> {
    pub model: &'m Model,
    /// Indices of the free parameters.
    pub free: Vec<usize>,
    /// Full parameter vector; fixed parameters keep these values.
    pub base: Vec<f64>,
    /// Per fitted frame: target positions per model marker (NaN when missing), gathered from
    /// the trials on demand ([`Targets::fill`]).
    pub frames: Targets<'m>,
    /// Per fitted frame: (trial index, frame index in that trial).
    pub origin: Vec<(usize, usize)>,
    /// Frames left out because their markers left a coordinate undetermined: (trial, frame).
    pub skipped: Vec<(usize, usize)>,
    pub ik: IkOptions,
    /// Gaussian prior on the free parameters (None: the paper's unregularized fit).
    pub prior: Option<prior::Prior>,
}

impl<'m> Problem<'m> {
    /// Builds a problem from trials; frames whose present markers leave a coordinate
    /// undetermined ([`crate::ik::solvable`]) are skipped.
    pub(crate) fn new(
        model: &'m Model,
        base: Vec<f64>,
        free: &[ParamId],
        trials: &[&'m Trial],
    ) -> Result<Self, CalibError> {
        if base.len() != model.parameters().len() {
            return Err(CalibError::ParamLength {
                got: base.len(),
                expected: model.parameters().len(),
            });
        }
        if free.is_empty() {
            return Err(CalibError::NothingFree);
        }
        // The outer level differentiates through the inner solutions (envelope theorem), so
        // they are solved tighter than plain IK needs.
        // The outer gradient counts every present marker, so no marker is rejected inside
        // the inner level; gross samples are dropped here, once, for both levels.
        let ik = IkOptions {
            step_tolerance: 1e-11,
            outlier_distance: f64::INFINITY,
            ..IkOptions::default()
        };
        let mut ws = IkWorkspace::new(model);
        let mut frames = Targets::new(model.markers().len());
        let mut origin = Vec::new();
        let mut skipped = Vec::new();
        let mut targets = Vec::new();
        let mut unfittable = unfittable::Unfittable::new(model);
        for (t, trial) in trials.iter().enumerate() {
            // A model marker the trial lacks altogether (excluded by the user, or never
            // recorded in this session) is missing in every frame, as in IK; the per-frame
            // test below still decides which frames its absence leaves undetermined.
            let (map, _absent) = MarkerMap::allowing_absent(model, trial.labels());
            let source = frames.add_trial(trial, map.columns);
            for f in 0..trial.n_frames() {
                // Gross samples read as missing ([`Targets`]).
                let targets = frames.fill_from(source, f, &mut targets);
                let undetermined = undetermined_coordinate(model, &base, targets, &ik, &mut ws);
                unfittable.count(targets, undetermined);
                if undetermined.is_none() {
                    frames.push(source, f);
                    origin.push((t, f));
                } else {
                    skipped.push((t, f));
                }
            }
        }
        if frames.is_empty() {
            return Err(CalibError::NoFrames {
                detail: unfittable.describe(model),
            });
        }
        Ok(Problem {
            model,
            free: free.iter().map(|id| id.0).collect(),
            base,
            frames,
            origin,
            skipped,
            ik,
            prior: None,
        })
    }

    pub(crate) fn n_free(&self) -> usize {
        self.free.len()
    }

    /// Half-width of free parameter `k`'s bounds: `∂p/∂s`.
    pub(crate) fn half_range(&self, k: usize) -> f64 {
        let par = &self.model.parameters()[self.free[k]];
        0.5 * (par.upper - par.lower)
    }

    /// Scaled coordinates `s ∈ [−1, 1]` of the free parameters of `p`.
    pub(crate) fn to_scaled(&self, p: &[f64]) -> Vec<f64> {
        self.free
            .iter()
            .map(|&i| {
                let par = &self.model.parameters()[i];
                2.0 * (p[i] - par.lower) / (par.upper - par.lower) - 1.0
            })
            .collect()
    }

    /// The full parameter vector for scaled free parameters `s`.
    pub(crate) fn to_params(&self, s: &[f64]) -> Vec<f64> {
        let mut p = self.base.clone();
        for (k, &i) in self.free.iter().enumerate() {
            let par = &self.model.parameters()[i];
            p[i] = par.lower + (s[k] + 1.0) * 0.5 * (par.upper - par.lower);
        }
        p
    }

    /// Solves every frame's inner problem at `p`, warm-starting from `qs` (updated in place).
    /// Returns `e_inner(p)`, the summed weighted squared marker error (m²), plus the prior
    /// term [`Problem::prior_cost`] when a prior is attached.
    ///
    /// Each frame's solve depends only on its own targets and start, so the frames are solved
    /// in parallel tasks of [`inner_task_len`] frames (a trial of a few hundred frames keeps
    /// every thread busy) and each frame's cost is kept; the costs are then summed as a fixed
    /// tree, in frame order within chunks of [`INNER_CHUNK`] and the chunk sums in chunk
    /// order, so the result is the same bit for bit on any number of threads. `ws` serves a
    /// problem of a single task (no thread is started).
    pub(crate) fn inner(&self, p: &[f64], qs: &mut [Vec<f64>], ws: &mut IkWorkspace) -> f64 {
        let task = inner_task_len(qs.len());
        let solve_task =
            |t: usize, qs: &mut [Vec<f64>], costs: &mut [f64], ws: &mut IkWorkspace| {
                let mut buf = Vec::with_capacity(self.frames.n_markers());
                for (i, (q, c)) in qs.iter_mut().zip(costs.iter_mut()).enumerate() {
                    let targets = self.frames.fill(t * task + i, &mut buf);
                    let fit = solve_frame(self.model, p, targets, q, &self.ik, ws);
                    debug_assert!(fit.status != FrameStatus::Converged || fit.cost.is_finite());
                    *c = fit.cost;
                }
            };
        let mut costs = vec![0.0; qs.len()];
        if qs.len() <= INNER_TASK {
            solve_task(0, qs, &mut costs, ws);
        } else {
            qs.par_chunks_mut(task)
                .zip(costs.par_chunks_mut(task))
                .enumerate()
                .for_each_init(
                    || IkWorkspace::new(self.model),
                    |ws, (t, (qs, costs))| solve_task(t, qs, costs, ws),
                );
        }
        let total: f64 = costs
            .chunks(INNER_CHUNK)
            .map(|chunk| chunk.iter().fold(0.0, |total, &c| total + c))
            .sum();
        total + self.prior_cost(p)
    }

    /// Starting coordinates for every frame at `p`: seeded IK, warm-started within each trial
    /// from the frame before, in the fixed parallel chunks of [`trial_chunk_ranges`] (each
    /// chunk's first frame seeded too), so the result does not depend on the number of
    /// threads. The loop of `crate::ik::warm_started_coords`, on targets gathered from the
    /// trials; like the `ik` command (and unlike that function's `crate::ik::trial_fit::chunk_ranges`),
    /// a problem of 128 to 1023 frames is cut into two chunks, so that a gait trial's seeded
    /// IK runs on two cores (`notebook/performance.md`: the cost is one more seed).
    ///
    /// These are starting points, solved to [`START_STEP_TOLERANCE`], not to the inner level's
    /// 1e-11: [`Problem::inner`] and the joint solver go on from them, and the joint solver's
    /// first Gauss–Newton step takes a coordinate error of that size to its square.
    pub(crate) fn initial_coords(&self, p: &[f64]) -> Vec<Vec<f64>> {
        self.initial_coords_near(p, &|_| None)
    }

    /// [`Problem::initial_coords`], frame `f` starting from `near(f)` where that is given
    /// (another inverse kinematics of the same frame at `p`, e.g. the marker policy's robust
    /// one) instead of from the frame before or a seed.
    pub(crate) fn initial_coords_near<'g>(
        &self,
        p: &[f64],
        near: &(dyn Fn(usize) -> Option<&'g [f64]> + Sync),
    ) -> Vec<Vec<f64>> {
        let loose = self.start_ik();
        let origin = &self.origin;
        // The coordinates are allocated here, on the calling thread, and the chunks fill
        // them: vectors allocated on the worker threads would be freed into the workers'
        // allocation arenas, where the calling thread's later copies (every iteration's
        // trial point) cannot reuse them (about 130 MB more resident memory at 1 M frames).
        let mut out = vec![vec![0.0; self.model.coordinates().len()]; self.frames.len()];
        let mut pieces = Vec::new();
        let mut rest: &mut [Vec<f64>] = &mut out;
        for range in trial_chunk_ranges(self.frames.len(), false) {
            let (piece, tail) = std::mem::take(&mut rest).split_at_mut(range.len());
            pieces.push((range, piece));
            rest = tail;
        }
        pieces.into_par_iter().for_each(|(range, piece)| {
            let mut ws = IkWorkspace::new(self.model);
            let mut buf = Vec::with_capacity(self.frames.n_markers());
            let first = range.start;
            for (i, f) in range.enumerate() {
                let targets = self.frames.fill(f, &mut buf);
                let (done, todo) = piece.split_at_mut(i);
                let q = &mut todo[0];
                if let Some(g) = near(f) {
                    q.copy_from_slice(g);
                } else if f > first && origin[f - 1].0 == origin[f].0 {
                    q.copy_from_slice(&done[i - 1]);
                } else {
                    q.copy_from_slice(&seed_frame(self.model, p, targets, &loose, &mut ws));
                }
                solve_frame(self.model, p, targets, q, &loose, &mut ws);
            }
        });
        out
    }

    /// The inner level's IK options at [`START_STEP_TOLERANCE`]: those of
    /// [`Problem::initial_coords`].
    pub(crate) fn start_ik(&self) -> IkOptions {
        IkOptions {
            step_tolerance: START_STEP_TOLERANCE,
            ..self.ik
        }
    }

    /// RMS marker distance over every present marker sample for `p` and coordinates `qs` (m).
    pub(crate) fn marker_rms(&self, p: &[f64], qs: &[Vec<f64>]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        self.visit_marker_errors(p, qs, |_, e| {
            let v = e.norm();
            if !v.is_nan() {
                s += v * v;
                n += 1;
            }
        });
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    }

    /// The objective's marker term `Σ w_j ‖x_j − m_j‖²` at `p` and coordinates `qs` (m²),
    /// over every present marker sample.
    pub(crate) fn marker_cost(&self, p: &[f64], qs: &[Vec<f64>]) -> f64 {
        let markers = self.model.markers();
        let mut s = 0.0;
        self.visit_marker_errors(p, qs, |j, e| {
            let v = e.norm_squared();
            if !v.is_nan() && markers[j].weight > 0.0 {
                s += markers[j].weight * v;
            }
        });
        s
    }

    /// Calls `visit(marker, target − model marker)` for every frame and model marker, in
    /// frame order then marker order (NaN for a missing marker), at `p` and coordinates `qs`.
    /// The forward kinematics run in parallel over blocks of [`ERROR_BLOCK`] frames and the
    /// visits follow in order on the calling thread, so any sum the caller forms has the
    /// same bits on any number of threads (and as a serial loop).
    pub(crate) fn visit_marker_errors(
        &self,
        p: &[f64],
        qs: &[Vec<f64>],
        mut visit: impl FnMut(usize, &Vector3<f64>),
    ) {
        const TASK: usize = 16;
        let nm = self.model.markers().len();
        let mut errors: Vec<Vector3<f64>> = Vec::new();
        for first in (0..qs.len()).step_by(ERROR_BLOCK) {
            let last = (first + ERROR_BLOCK).min(qs.len());
            errors.resize((last - first) * nm, Vector3::zeros());
            errors.par_chunks_mut(TASK * nm).enumerate().for_each_init(
                || (KinData::new(self.model), Vec::new()),
                |(kin, buf), (t, out)| {
                    for (i, e) in out.chunks_mut(nm).enumerate() {
                        let f = first + t * TASK + i;
                        let targets = self.frames.fill(f, buf);
                        forward_kinematics(self.model, p, &qs[f], Want::Positions, kin);
                        for (j, e) in e.iter_mut().enumerate() {
                            *e = targets[j] - kin.markers[j];
                        }
                    }
                },
            );
            for (k, e) in errors.iter().enumerate() {
                visit(k % nm, e);
            }
        }
    }
}

/// Frames per block of [`Problem::visit_marker_errors`] (bounds its memory on long trials).
pub(crate) const ERROR_BLOCK: usize = 4096;

/// The result of an outer solve.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Scaled free parameters.
    pub s: Vec<f64>,
    /// Full parameter vector.
    pub p: Vec<f64>,
    /// Coordinates per fitted frame.
    pub coords: Vec<Vec<f64>>,
    /// Final objective `e_inner` (m²).
    pub cost: f64,
    /// Outer iterations.
    pub iterations: usize,
    /// Objective evaluations (each a full pass over the frames).
    pub evaluations: usize,
    /// Best objective after each outer iteration.
    pub history: Vec<f64>,
    /// Why the solver stopped.
    pub termination: Termination,
}

impl Fit {
    /// Whether the solver's convergence test passed (not stalled, not out of iterations).
    pub(crate) fn converged(&self) -> bool {
        self.termination.converged()
    }
}

#[cfg(test)]
#[path = "problem_tests.rs"]
mod tests;

#[cfg(test)]
mod clamped_tests;
#[cfg(test)]
mod joint_secant_tests;
#[cfg(test)]
mod prior_tests;
#[cfg(test)]
mod solvers_tests;
