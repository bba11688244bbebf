//! jointfit: patient-specific joint parameters of multi-joint kinematic models.
//!
//! The method is the two-level optimization of Reinbolt, Schutte, Fregly, Koh, Haftka,
//! George & Mitchell (2005), "Determination of patient-specific multi-joint kinematic models
//! through two-level optimization", J Biomech 38:621–626, doi:10.1016/j.jbiomech.2004.03.031.
//! See `docs/architecture.md` in the repository for the layers, the data flow, the model, the
//! frames and the conventions.
//!
//! This crate has no file formats and never prints: readers and writers live in
//! `jointfit-io`, the command line in `jointfit-cli`. Two capabilities are layered on it as
//! their own crates: low-pass filtering of trials (`jointfit-signal`) and a subject's model
//! from a static trial (`jointfit-landmarks`).

pub mod calibrate;
pub mod checks;
pub mod ik;
pub mod kinematics;
pub(crate) mod linalg;
pub mod model;
pub(crate) mod placement;
pub mod plausibility;
pub mod repair;
pub mod solver;
pub mod spatial;
pub mod trial;
pub mod vertical;
pub mod workflow;
