//! Why personalization refused a static trial, a marker set or an option
//! ([`LandmarkError`]).

use thiserror::Error;

use super::functional;
use jointfit::model::ModelError;

/// Why a static trial or a marker set was refused. Messages name the markers involved.
#[derive(Debug, Error, PartialEq)]
pub enum LandmarkError {
    #[error("marker set {source_name}: {detail}")]
    MarkerSetSyntax { source_name: String, detail: String },
    #[error("unknown marker-set preset {name:?}; presets: {available}")]
    UnknownPreset { name: String, available: String },
    #[error("marker set {set:?}: {detail}")]
    InvalidMarkerSet { set: String, detail: String },
    #[error("marker set {set:?} has no [{side}] leg")]
    NoSuchLeg { set: String, side: &'static str },
    #[error(
        "the static trial lacks {} marker(s) that marker set {set:?} expects for the {side} \
         leg: {}; the trial has: {available}",
        missing.len(),
        missing.join(", ")
    )]
    MissingMarkers {
        set: String,
        side: &'static str,
        /// `role "label"` for each missing label.
        missing: Vec<String>,
        available: String,
    },
    #[error(
        "no frame of the static trial ({frames} frames) has every needed marker; never \
         present: {never_present:?}; with gaps: {partly_present:?}"
    )]
    NoCompleteFrame {
        frames: usize,
        never_present: Vec<String>,
        partly_present: Vec<String>,
    },
    #[error(
        "{segment} tracking markers {markers:?} lie within {spread_mm:.1} mm of one line \
         (at least {min_mm:.1} mm needed): their rigid fit cannot find the rotation about \
         that line; add a marker off the line or list another one"
    )]
    Collinear {
        segment: String,
        markers: Vec<String>,
        spread_mm: f64,
        min_mm: f64,
    },
    #[error("{why} needs the subject's {what}, which was not given")]
    MissingMeasurement { what: String, why: String },
    #[error("{segment} frame: {detail}")]
    Degenerate { segment: String, detail: String },
    #[error("{0}")]
    Implausible(String),
    #[error("invalid option: {0}")]
    InvalidOption(String),
    #[error("the personalized model does not compile: {0}")]
    Model(ModelError),
    #[error("functional {joint} trial: {error}")]
    Functional {
        joint: &'static str,
        error: functional::FunctionalError,
    },
    #[error("internal error (a bug): {0}")]
    Internal(String),
}
