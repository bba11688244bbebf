//! What the global phase reports ([`super::global`]): its summary in the calibration record
//! and the warning when its finished starts disagree.

use serde::Serialize;

/// Two finished starts reached the same optimum when their objectives differ by less than
/// this (relative).
pub(crate) const SAME_OPTIMUM: f64 = 1e-6;

/// What the global phase did (`jointfit calibrate --json`: `global`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GlobalSearch {
    /// Starts probed (the given one included).
    pub starts: usize,
    /// Iterations of each probe.
    pub probe_iterations: usize,
    /// Frames the probes ran on (every k-th frame of the trials).
    pub probe_frames: usize,
    /// Objective of every start after its probe (m², on the probes' frames), in start order.
    pub probe_objective: Vec<f64>,
    /// The starts continued to convergence on every frame, best probe first
    /// ([`super::global`]'s module docs).
    pub finished: Vec<usize>,
    /// Their final objectives (m²).
    pub finished_objective: Vec<f64>,
    /// Whether every finished start reached the same optimum.
    pub agree: bool,
}

/// The warning of a global phase whose finished starts disagree (`None`: they agree).
pub(crate) fn warning(g: &GlobalSearch) -> Option<String> {
    if g.agree || g.finished.len() < 2 {
        return None;
    }
    let list: Vec<String> = g
        .finished
        .iter()
        .zip(&g.finished_objective)
        .map(|(k, &c)| format!("start {k}: {:.1} mm²", super::calibration::mm2(c)))
        .collect();
    Some(format!(
        "the fit is not known to be the global optimum: the {} most promising of {} starts \
         ended at different optima ({}); the lowest is kept. More starts (more probes of the \
         global phase, or several full starts) may find a lower one",
        g.finished.len(),
        g.starts,
        list.join(", ")
    ))
}
