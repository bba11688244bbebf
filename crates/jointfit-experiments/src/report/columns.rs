//! Running one synthetic column of Table 1 (the noiseless case and the skin-noise seeds).

use jointfit::model::Model;

use super::SyntheticColumn;

/// What one synthetic column of Table 1 runs: a motion and the parameter groups fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSpec {
    pub label: String,
    /// Index into the paper's Table 1 columns.
    pub paper_column: usize,
    pub groups: Vec<String>,
    /// Description of the motion.
    pub motion: String,
    /// Coordinates per frame (model order).
    pub coords: Vec<Vec<f64>>,
    pub rate: f64,
}

/// Runs a synthetic column: the noiseless case (seed `first_seed`) and `seeds` skin-noise
/// cases (seeds `first_seed ..`), each from the truth perturbed by up to `perturb_mm` /
/// `perturb_deg` on the fitted parameters ([`crate::protocol::synthetic_case`]).
#[allow(clippy::too_many_arguments)]
pub fn run_synthetic_column(
    model: &Model,
    truth: &[f64],
    spec: &ColumnSpec,
    perturb_mm: f64,
    perturb_deg: f64,
    settings: &jointfit::workflow::FitSettings,
    first_seed: u64,
    seeds: usize,
) -> Result<SyntheticColumn, jointfit::workflow::WorkflowError> {
    run_synthetic_column_observed(
        model,
        truth,
        spec,
        perturb_mm,
        perturb_deg,
        settings,
        first_seed,
        seeds,
        &mut |_| {},
    )
}

/// [`run_synthetic_column`], calling `case_done(k)` after each of its `1 + seeds` cases
/// (progress reporting).
#[allow(clippy::too_many_arguments)]
pub fn run_synthetic_column_observed(
    model: &Model,
    truth: &[f64],
    spec: &ColumnSpec,
    perturb_mm: f64,
    perturb_deg: f64,
    settings: &jointfit::workflow::FitSettings,
    first_seed: u64,
    seeds: usize,
    case_done: &mut dyn FnMut(usize),
) -> Result<SyntheticColumn, jointfit::workflow::WorkflowError> {
    use crate::protocol::{synthetic_case, SyntheticSetup};
    use crate::synth::Noise;
    let groups: Vec<&str> = spec.groups.iter().map(|g| g.as_str()).collect();
    let setup = SyntheticSetup {
        groups: &groups,
        coords: &spec.coords,
        rate: spec.rate,
        perturb_mm,
        perturb_deg,
    };
    let noiseless = synthetic_case(model, truth, &setup, &Noise::none(), settings, first_seed)?;
    case_done(0);
    let noisy = (0..seeds as u64)
        .map(|k| {
            let seed = first_seed + k;
            let case = synthetic_case(model, truth, &setup, &Noise::skin(seed), settings, seed);
            case_done(1 + k as usize);
            case
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(SyntheticColumn {
        label: spec.label.clone(),
        paper_column: spec.paper_column,
        groups: spec.groups.clone(),
        motion: spec.motion.clone(),
        frames: spec.coords.len(),
        rate_hz: spec.rate,
        noiseless,
        noisy,
    })
}
