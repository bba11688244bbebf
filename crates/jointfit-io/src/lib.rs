//! File formats for jointfit: motion capture in (C3D, TRC), results out (OpenSim .mot/.sto).
//!
//! Every reader returns a [`jointfit::trial::Trial`] in SI units with gaps as NaN, and every
//! error names the file and, where it applies, the line, frame or marker. Every writer goes
//! through [`atomic::write_atomic`], so a crash never leaves a half-written file behind.
//!
//! - [`c3d`]: C3D files (all three processor formats), checked against ezc3d and the `c3d`
//!   Python package on every sample file (`tests/c3d_vs_python.rs`).
//! - [`osim`]: OpenSim 4 model export, checked against OpenSim 4.6 (`tests/it/osim.rs`).

pub mod atomic;
pub mod c3d;
pub mod content_hash;
pub mod csv;
pub mod limits;
pub mod message;
pub mod osim;
pub mod osim_read;
pub mod osim_scale;
pub mod osim_setup;
pub mod staging;
pub mod sto;
pub mod trc;
pub mod vsk;

pub mod model_file;
mod text;
pub mod trial_file;
pub mod xml;
