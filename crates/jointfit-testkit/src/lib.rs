//! Test support shared by every jointfit crate's tests (dev-only, never published).
//!
//! * [`env`]: where the real data and the Python oracles are; in CI (`CI` set) a missing
//!   resource is a failure, elsewhere the test prints `skipped:` and passes.
//! * [`script`]: runs a script of `scripts/` with the oracle interpreter (OpenSim, scipy, …)
//!   and reads its `@@` result lines.
//! * [`scratch`]: temporary directories that are removed when the test ends, passed or failed.
//! * [`models`]: small sample models covering every joint kind (like Pinocchio's
//!   `buildModels`), next to the built-in legs of [`jointfit::model::lower_limb`].
//! * [`osim_text`]: which lines a personalized `.osim` write-back changed.
//! * [`synth`]: the one synthetic-trial generator: markers of a model along a motion, with
//!   known truth and seeded noise.

pub mod env;
pub mod models;
pub mod osim_text;
pub mod scratch;
pub mod script;
pub mod synth;

pub use env::{data_dir, data_file, data_files, in_ci, python};
pub use scratch::{entries, scratch, snapshot, ScratchDir};
