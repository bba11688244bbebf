//! Synthetic experiments: motions driven through a model, skin-artifact noise, and the
//! perturbed "true" parameters the paper's synthetic tests recover (Reinbolt et al. 2005 §2).

pub mod paper;
pub mod protocol;
pub mod report;
pub mod subject;
pub mod synth;
pub mod units;
