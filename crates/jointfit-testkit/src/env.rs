//! Where the real data and the Python oracles are: `$JOINTFIT_DATA` and `$JOINTFIT_PYTHON`.
//! In CI (`CI` set) a missing resource is a test failure; elsewhere the test prints a
//! `skipped:` notice and passes.
//!
//! These live in the core crate (`jointfit::testing`, hidden from its docs) because the core's
//! own unit tests need them too; this module is the name every other crate's tests use.

pub use jointfit::testing::{data_dir, data_file, data_files, in_ci, python};
