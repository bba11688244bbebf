//! Scaling a generic model to a subject: OpenSim's geometric scaling rules
//! ([`geometry`]) and the fit of per-body scale factors, marker offsets and the static pose
//! ([`fit`]). The maths and the priors are in `docs/scaling.md`.

pub mod geometry;

pub use geometry::{scaled_spec, ScaleFactors};
