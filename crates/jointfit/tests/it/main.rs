//! Integration tests of the core library (one test binary for the crate).

mod calibrate;
mod calibrate_clamped;
mod checks;
mod ik;
mod ik_clamped;
mod ik_parallel;
mod ik_robust;
mod ik_stream;
mod kinematics;
mod models;
mod offsets;
mod placement;
mod posterior;
mod priors;
mod secant;
mod status;
mod uncertainty;
