//! Tables 1 and 2 of Reinbolt et al. 2005 next to ours: the run's results as data
//! (serialisable to JSON) and their Markdown and CSV renderings.

use jointfit::model::spec::Unit;
use jointfit::model::Model;
use serde::Serialize;

use crate::paper::{TABLE1, TABLE1_COLUMNS, TABLE1_REDUCTION_PERCENT, TABLE2};
use crate::protocol::{ExperimentalResult, SyntheticResult};

mod columns;
mod render;

pub use columns::{run_synthetic_column, run_synthetic_column_observed, ColumnSpec};

/// Mean, sample standard deviation, min and max of some values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    pub n: usize,
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    pub fn of(v: &[f64]) -> Option<Spread> {
        if v.is_empty() {
            return None;
        }
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        Some(Spread {
            n,
            mean,
            std: var.sqrt(),
            min: v.iter().cloned().fold(f64::INFINITY, f64::min),
            max: v.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
        })
    }
}

/// One synthetic column of Table 1 (a joint or the full leg, one motion).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SyntheticColumn {
    pub label: String,
    /// Index into the paper's columns it compares with.
    pub paper_column: usize,
    pub groups: Vec<String>,
    pub motion: String,
    pub frames: usize,
    pub rate_hz: f64,
    pub noiseless: SyntheticResult,
    pub noisy: Vec<SyntheticResult>,
}

impl SyntheticColumn {
    fn spread(&self, f: impl Fn(&SyntheticResult) -> Option<f64>) -> Option<Spread> {
        Spread::of(&self.noisy.iter().filter_map(f).collect::<Vec<_>>())
    }
    pub fn noisy_marker(&self) -> Option<Spread> {
        self.spread(|r| Some(r.marker_rms_mm))
    }
    pub fn noisy_orientation(&self) -> Option<Spread> {
        self.spread(|r| r.orientation_rms_deg)
    }
    pub fn noisy_position(&self) -> Option<Spread> {
        self.spread(|r| r.position_rms_mm)
    }
    pub fn noise_3d(&self) -> Option<Spread> {
        self.spread(|r| Some(r.noise_rms_3d_mm))
    }
    /// Seeds whose fitted cost is below the cost at the true parameters.
    pub fn below_truth(&self) -> usize {
        self.noisy
            .iter()
            .filter(|r| r.cost_fit < r.cost_truth)
            .count()
    }
}

/// One experimental column of Table 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExperimentalColumn {
    pub label: String,
    pub paper_column: usize,
    pub dataset: String,
    pub trials: Vec<String>,
    pub result: ExperimentalResult,
}

/// One subject's Table 2: parameter values (mm, deg) per method.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table2 {
    pub subject: String,
    /// Method names, e.g. "anatomical landmarks", "single joint", "full leg".
    pub methods: Vec<String>,
    /// (parameter, unit, value per method); `None` where a method did not fit the subject.
    pub rows: Vec<(String, String, Vec<Option<f64>>)>,
    pub notes: Vec<String>,
}

impl Table2 {
    /// Builds the table from full parameter vectors (SI) per method.
    pub fn new(subject: &str, model: &Model, methods: &[(&str, Option<&[f64]>)]) -> Table2 {
        let rows = model
            .parameters()
            .iter()
            .enumerate()
            .map(|(i, par)| {
                let (unit, k) = unit_of(par.unit);
                let v = methods.iter().map(|(_, p)| p.map(|p| p[i] * k)).collect();
                (par.name.clone(), unit.to_string(), v)
            })
            .collect();
        Table2 {
            subject: subject.to_string(),
            methods: methods.iter().map(|(m, _)| m.to_string()).collect(),
            rows,
            notes: Vec::new(),
        }
    }

    /// RMS difference from the first method over the rows of one unit, per other method.
    pub fn rms_difference(&self, unit: &str) -> Vec<Option<f64>> {
        (1..self.methods.len())
            .map(|m| {
                let d: Vec<f64> = self
                    .rows
                    .iter()
                    .filter(|r| r.1 == unit)
                    .filter_map(|r| Some(r.2[m]? - r.2[0]?))
                    .collect();
                (!d.is_empty())
                    .then(|| (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt())
            })
            .collect()
    }
}

fn unit_of(u: Unit) -> (&'static str, f64) {
    (crate::units::suffix(u), crate::units::scale(u))
}

/// Everything one `reproduce` run produced, with what produced it.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub title: String,
    pub command: String,
    pub version: String,
    pub git: Option<String>,
    pub settings: serde_json::Value,
    pub synthetic: Vec<SyntheticColumn>,
    pub experimental: Vec<ExperimentalColumn>,
    pub table2: Vec<Table2>,
    pub notes: Vec<String>,
    pub seconds: f64,
}
