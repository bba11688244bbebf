//! Integration tests of the core library (one test binary for the crate).

mod checks;
mod ik;
mod models;
mod offsets;
