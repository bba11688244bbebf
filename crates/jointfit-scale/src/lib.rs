//! Scaling a generic model to a subject: OpenSim's geometric scaling rules
//! ([`geometry`]), and the fit of per-body scale factors, marker offsets and the static pose
//! ([`fit`]) with its groups, static targets and plausibility checks ([`groups`]). The maths
//! and the priors are in `docs/scaling.md`.

mod basis;
pub mod fit;
pub mod geometry;
pub mod groups;
mod normal;
