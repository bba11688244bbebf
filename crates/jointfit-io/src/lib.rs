//! File formats for jointfit: motion capture in (C3D, TRC), results out (OpenSim .mot/.sto).
//!
//! Every reader returns a [`jointfit::trial::Trial`] in SI units with gaps as NaN, and every
//! error names the file and, where it applies, the line, frame or marker.

pub mod c3d;
