//! Integration tests of the core library (one test binary for the crate).

mod calibrate;
mod ik;
mod kinematics;
mod landmarks;
mod models;
mod uncertainty;
