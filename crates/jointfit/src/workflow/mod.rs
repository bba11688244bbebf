//! The jobs of the program, on models and trials already in memory: calibrate a model
//! ([`calibration::calibrate`]), predict what a trial can determine ([`predict::predict`]),
//! inverse kinematics of a trial ([`ik::ik_trial`]), carry parameters from one model to another
//! ([`ik::transfer_params`]).
//!
//! This is the one place that drives the solvers of [`crate::calibrate`] and [`crate::ik`]:
//! the command line, the experiments and any other front end (a Python binding, a batch
//! runner) call these functions and keep only file input/output and printing. Nothing here
//! reads files or prints; progress goes to an [`Observer`] (pass `&mut NoObserver` for
//! none), timing is left to the caller.
//!
//! A calibration (Reinbolt et al. 2005, J Biomech 38:621–626,
//! doi:10.1016/j.jbiomech.2004.03.031) minimises `e_inner(p) = Σ_i min_{q_i} Σ_j w_ij
//! ‖m_ij − x_j(p, q_i)‖²` over the free parameters `p` with one of three outer methods
//! ([`Method`]); with `starts > 1` it is repeated from seeded starts moved by up to
//! `restart_m` / `restart_rad` ([`restart_point`]) and the lowest objective wins; an
//! uncertainty analysis ([`crate::calibrate::uncertainty`]) may follow, and with
//! `fix_unidentifiable` the parameters the trials cannot determine are held at their start
//! and the rest refitted.

pub mod calibration;
#[cfg(test)]
use calibration::calibrate;
use calibration::Calibration;
#[cfg(test)]
use ik::ik_trial;
pub mod conflict;
pub mod envelope;
mod global;
pub mod ik;
pub(crate) mod map;
pub mod marker_policy;
pub(crate) mod marker_rigid;
pub mod marker_rms;
pub(crate) mod motion_range;
pub use motion_range::HeldJoint;
pub mod predict;
mod probes;
pub mod redundant;
pub mod refine;
mod starts;
mod summary;
pub mod verdict;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::calibrate::uncertainty::UncertaintyOptions;
use crate::calibrate::CalibError;

use crate::solver::{NoObserver, Observer, Termination};
pub use starts::perturb;
#[cfg(test)]
use starts::restart_point;
pub use summary::GlobalSearch;

/// Errors of the workflow.
#[derive(Debug, Error, PartialEq)]
pub enum WorkflowError {
    #[error(transparent)]
    Calib(#[from] CalibError),
    #[error(transparent)]
    Ik(#[from] crate::ik::IkError),
    #[error(
        "no parameter of {groups} can be determined from these trials within the thresholds; \
         nothing left to fit"
    )]
    NothingIdentifiable { groups: String },
    #[error("no frame could be solved{detail}")]
    NoFrameSolved { detail: String },
    #[error("{source_model}: has no parameter {name:?} of the subject model")]
    MissingParameter { source_model: String, name: String },
    #[error(
        "marker refinement needs the parameter priors: without one, a marker position trades \
         off exactly with the joint its segment hangs from (the fit was asked to use none)"
    )]
    RefineNeedsPriors,
    #[error("marker refinement: {0}")]
    Refine(String),
    /// A trial does not belong with the model ([`verdict::check_inputs`]); `trial` indexes
    /// the calibration's trials, and a front end names its file.
    #[error("trial {}: {cause}", trial + 1)]
    Mismatch { trial: usize, cause: String },
}

/// The outer optimizer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Joint sparse Levenberg–Marquardt over every frame's coordinates and the parameters
    /// ([`crate::calibrate::joint`]); the fast default.
    Joint,
    /// Two-level Gauss-Newton on the reduced (variable-projection) Jacobian
    /// ([`crate::calibrate::varpro`]).
    Gradient,
    /// Particle swarm (Schutte et al. 2005, [`crate::calibrate::pso`]), then polished by the
    /// joint solver.
    Pso,
}

impl Method {
    /// Every method, in the order of the command line's choices.
    pub(crate) const ALL: [Method; 3] = [Method::Joint, Method::Gradient, Method::Pso];

    /// The lower-case name (`joint`, `gradient`, `pso`), as on the command line and in JSON
    /// (what [`std::fmt::Display`] writes and [`std::str::FromStr`] reads).
    pub(crate) fn name(self) -> &'static str {
        match self {
            Method::Joint => "joint",
            Method::Gradient => "gradient",
            Method::Pso => "pso",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Method, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown method {s:?}; choose joint, gradient or pso"))
    }
}

/// How a calibration is run.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    pub method: Method,
    /// Seed of every random choice: the particle swarm, the extra starts and (when the
    /// uncertainty options do not set their own) the bootstrap.
    pub seed: u64,
    /// Number of starts (≥ 1). Start 0 is the given start; start `k` moves every free
    /// parameter by up to `restart_m` metres / `restart_rad` radians ([`restart_point`]).
    /// The particle swarm, global by itself, always uses one.
    pub starts: usize,
    pub restart_m: f64,
    pub restart_rad: f64,
    /// Extra starts of the global phase of a single-start joint fit ([`global`]): each runs
    /// `probe_iterations` iterations, the most promising are finished. 0: one local fit from
    /// the given start (the paper's protocol).
    pub probes: usize,
    pub probe_iterations: usize,
    /// The probes run on every k-th frame, k the smallest that leaves at most this many.
    pub probe_frames: usize,
    /// Uncertainty and identifiability of the fitted parameters; `None`: not analysed.
    pub uncertainty: Option<UncertaintyOptions>,
    /// Refit with the parameters the trials cannot determine (within the thresholds of
    /// `uncertainty`) held at their starting values; needs `uncertainty`.
    pub fix_unidentifiable: bool,
    /// Use the parameter priors of the model file (`prior_sd`/`prior_mean`, written by
    /// `personalize`): a maximum a posteriori fit ([`map::map_problem_with`]). `false`, or a model
    /// without priors: the paper's unregularized least squares.
    pub priors: bool,
    /// Marker noise σ (m) that weighs the priors against the markers; `None`: estimated from
    /// the residuals ([`map`]).
    pub marker_noise: Option<f64>,
    /// Refine the tracking markers' positions in their segments with this prior SD (m) per
    /// axis ([`crate::model::refine`]); honoured by [`refine::calibrate_refined`], which
    /// returns the refined model ([`calibrate`] fits the markers as the model gives them).
    /// `None`: markers as given.
    pub refine_markers: Option<f64>,
    /// Iteration limit of the outer solver (the joint or two-level solve and the polish
    /// after the swarm; the swarm keeps its own budget); `None`: the solver's default (200).
    /// A fit that reaches it ends [`Termination::IterationLimit`].
    pub max_iterations: Option<usize>,
    /// With a prior: bound the hip centre medial to the ASIS ([`envelope`]), honoured by
    /// [`refine::calibrate_refined`].
    pub anatomical_envelope: bool,
    /// With a prior: refine the markers the data checks find displaced since the static
    /// trial, leave out broken ones ([`marker_policy`]), honoured by
    /// [`refine::calibrate_refined`].
    pub marker_policy: bool,
    /// Markers the marker policy leaves as they are.
    pub keep_markers: Vec<String>,
    /// With a prior: test each joint's prior against the trial and widen the prior of a joint
    /// the trial disagrees with ([`conflict`]), honoured by [`refine::calibrate_refined`].
    pub prior_conflict: bool,
    /// Refuse trials whose marker placement does not match the model's
    /// ([`verdict::check_inputs`]: [`WorkflowError::Mismatch`]); off, the fit runs and the
    /// mismatch makes its verdict a `reject`.
    pub refuse_mismatch: bool,
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            method: Method::Joint,
            seed: 1,
            starts: 1,
            restart_m: 20.0 * crate::model::spec::M_PER_MM,
            restart_rad: 10f64.to_radians(),
            probes: 5,
            probe_iterations: 6,
            probe_frames: 25,
            uncertainty: None,
            fix_unidentifiable: false,
            priors: true,
            marker_noise: None,
            refine_markers: None,
            max_iterations: None,
            anatomical_envelope: true,
            marker_policy: true,
            keep_markers: Vec::new(),
            prior_conflict: true,
            refuse_mismatch: true,
        }
    }
}

impl FitSettings {
    /// Starts actually run: `starts` (at least one), one for the particle swarm.
    pub(crate) fn effective_starts(&self) -> usize {
        if self.method == Method::Pso {
            1
        } else {
            self.starts.max(1)
        }
    }

    /// Extra starts of the global phase actually run: `probes` for a single-start joint fit,
    /// else none (several full starts are their own global phase; the swarm is global).
    pub(crate) fn effective_probes(&self) -> usize {
        if self.method == Method::Joint && self.starts <= 1 {
            self.probes
        } else {
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
            assert_eq!(
                serde_json::to_string(&m).unwrap(),
                format!("\"{}\"", m.name())
            );
        }
        assert!("newton".parse::<Method>().is_err());
    }

    #[test]
    fn swarm_runs_one_start() {
        let s = FitSettings {
            method: Method::Pso,
            starts: 5,
            ..FitSettings::default()
        };
        assert_eq!(s.effective_starts(), 1);
        let s = FitSettings {
            starts: 0,
            ..FitSettings::default()
        };
        assert_eq!(s.effective_starts(), 1);
    }

    /// The uncertainty analysis of the command line's defaults: intervals flagged wider than
    /// 5 mm or 5°, no bootstrap, seed 1 (what the workflow tests analyse with).
    pub(crate) fn five_mm_five_deg() -> UncertaintyOptions {
        UncertaintyOptions {
            threshold_m: 0.005,
            threshold_rad: 5f64.to_radians(),
            bootstrap_replicates: 0,
            seed: 1,
            ..UncertaintyOptions::default()
        }
    }
}

#[cfg(test)]
mod conflict_tests;
#[cfg(test)]
mod motion_range_tests;
#[cfg(test)]
mod policy_tests;
#[cfg(test)]
mod refine_tests;
#[cfg(test)]
pub(crate) mod synthetic_tests;
