//! What the fit is asked: the groups of bodies that share factors, the priors, the markers'
//! weights and the iteration budget; and the errors that refuse a problem.

use crate::geometry::ScaleFactors;
use jointfit::model::ModelError;

/// Bodies that share scale factors.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleGroup {
    pub name: String,
    pub bodies: Vec<String>,
    /// Three factors (x, y, z of the bodies' frames) instead of one.
    pub per_axis: bool,
}

impl ScaleGroup {
    /// How many fitted factors the group has: three with `per_axis`, else one.
    pub(crate) fn n_factors(&self) -> usize {
        if self.per_axis {
            3
        } else {
            1
        }
    }
}

/// The anthropometric prior (`fit::residuals`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizePrior {
    /// Spread of a segment's factor about the overall size (log units, ≈ relative).
    pub proportion_sd: f64,
    /// Subject stature over the generic model's stature, with its spread (log units).
    pub stature: Option<(f64, f64)>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaleOptions {
    pub groups: Vec<ScaleGroup>,
    /// Markers kept at their scaled generic place (OpenSim's `fixed`).
    pub fixed_markers: Vec<String>,
    /// Prior SD of a marker's offset from its scaled generic place (m).
    pub marker_sd: f64,
    /// Assumed SD of a marker sample about the model (m).
    pub noise_sd: f64,
    /// `None`: the pure fit (no anthropometric prior).
    pub prior: Option<SizePrior>,
    /// Levenberg–Marquardt iterations per robust round (a safeguard: the fit normally stops
    /// by its convergence test well before).
    pub max_iterations: usize,
    /// Widen the offset prior of markers the data move far (tracking markers;
    /// `fit::markers`).
    pub robust: bool,
    /// Bodies held at given factors (OpenSim's manual scales), in no group.
    pub fixed_factors: ScaleFactors,
    /// Weights `w_j` of markers' data rows in the static frame (frame 0:
    /// `√w_j (x_j − m_0j)/σ_d`; 0 leaves the marker's static data out), as OpenSim's marker
    /// placer weighs the static pose; unnamed: 1. They describe the static pose only: the
    /// motion frames weigh every marker 1 (`fit::markers`).
    pub marker_weights: Vec<(String, f64)>,
}

impl ScaleOptions {
    pub fn new(groups: Vec<ScaleGroup>) -> Self {
        ScaleOptions {
            groups,
            fixed_markers: Vec::new(),
            marker_sd: 0.01,
            noise_sd: 0.005,
            prior: Some(SizePrior {
                proportion_sd: 0.05,
                stature: None,
            }),
            max_iterations: 200,
            robust: true,
            marker_weights: Vec::new(),
            fixed_factors: ScaleFactors::new(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScaleError {
    #[error("the scaled model does not compile: {0}")]
    Model(#[from] ModelError),
    #[error("frame {frame}: {present} model markers have data, at least 4 are needed")]
    TooFewMarkers { frame: usize, present: usize },
    #[error("group {0:?} names body {1:?}, which the model does not have")]
    UnknownBody(String, String),
    #[error("body {0:?} is in two scale groups (or in one and held at given factors)")]
    TwiceGrouped(String),
    #[error(
        "the normal equations are singular: the data and priors leave the factors undetermined"
    )]
    Singular,
}
