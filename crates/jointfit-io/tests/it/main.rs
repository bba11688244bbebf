//! Integration tests of jointfit-io against the real files in `$JOINTFIT_DATA` and against
//! OpenSim (through `$JOINTFIT_PYTHON`). Without them the tests print `skipped:` and pass,
//! except in CI, where they fail.

mod oracle;
mod osim;
mod osim_joint_model;
mod osim_joint_types;
mod osim_names;
mod osim_read;
mod osim_scale;
mod osim_values;
mod sto;
mod sto_edges;
mod trc_fast;
mod trc_field;
mod trc_files;
mod trc_format;
mod trc_opensim;
mod trc_times;
mod vertical;
