//! What every iterative solver of the crate shares: how a solve ended ([`Termination`]) and
//! who may watch it ([`Observer`]).
//!
//! The observer follows the pattern of argmin's observers (`argmin::core::observers`): the
//! solver calls it with its state and the observer cannot change the result. A workflow
//! (see [`crate::workflow`]) names the stages (`stage_started` / `stage_ended`); a solver
//! reports its iterations (`iteration`); long jobs made of many solves report `progress`.
//! [`NoObserver`] does nothing; pass `&mut NoObserver` when nobody watches.

use serde::{Deserialize, Serialize};

/// Why an iterative solve stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The convergence test passed: a negligible step, or a negligible decrease of the
    /// objective (the particle swarm: its best value stopped improving over its window).
    Converged,
    /// No step along the damped direction lowered the objective, even at the largest
    /// damping: the solver could go no further, which is not a verified minimum.
    Stalled,
    /// The iteration budget ran out first; the result is the best point found.
    IterationLimit,
}

impl Termination {
    /// `true` only for [`Termination::Converged`].
    pub(crate) fn converged(self) -> bool {
        self == Termination::Converged
    }

    /// Lower-case words for text output: `converged`, `stalled`, `iteration limit`.
    fn describe(self) -> &'static str {
        match self {
            Termination::Converged => "converged",
            Termination::Stalled => "stalled",
            Termination::IterationLimit => "iteration limit",
        }
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.describe())
    }
}

/// Watches a solve or a workflow. Every method has an empty default.
pub trait Observer {
    /// A named stage begins (e.g. "particle swarm"); `budget` is its iteration limit when
    /// the stage usually runs to it (for a progress bar with an end), else `None`.
    fn stage_started(&mut self, _stage: &str, _budget: Option<usize>) {}
    /// After outer iteration `iteration` (1-based) of the current stage, with the objective
    /// reached (for the calibration solvers `e_inner`, m²).
    fn iteration(&mut self, _iteration: usize, _objective: f64) {}
    /// The current stage ended.
    fn stage_ended(&mut self, _termination: Termination) {}
    /// `done` of `total` units of a long job (starts of a multi-start fit, trials, ...).
    fn progress(&mut self, _done: usize, _total: usize) {}
}

/// The observer that watches nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoObserver;

impl Observer for NoObserver {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_converged_counts_as_converged() {
        assert!(Termination::Converged.converged());
        assert!(!Termination::Stalled.converged());
        assert!(!Termination::IterationLimit.converged());
        assert_eq!(
            serde_json::to_string(&Termination::IterationLimit).unwrap(),
            "\"iteration_limit\""
        );
        assert_eq!(Termination::Stalled.to_string(), "stalled");
    }
}
