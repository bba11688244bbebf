//! What a report shows, in display units (mm, degrees, seconds): plain numbers and names,
//! so that any command (calibrate, report, reproduce) can fill it.
//!
//! [`crate::analyze::analyze`] fills the marker errors and joint angles from models and
//! trials; the caller adds parameters, convergence and settings.

/// Everything the page shows.
#[derive(Debug, Clone, Default)]
pub struct ReportInput {
    /// Page title (e.g. the fitted model's name).
    pub title: String,
    /// Name of the baseline model in legends, e.g. "landmark model".
    pub baseline_label: String,
    /// Name of the fitted model in legends, e.g. "fitted model".
    pub fitted_label: String,
    pub trials: Vec<TrialSeries>,
    /// Per model marker: RMS distance over every trial (mm).
    pub markers: Vec<MarkerRms>,
    /// RMS marker distance over every present sample (mm): baseline (if any), fitted.
    pub overall_rms_mm: (Option<f64>, f64),
    pub parameters: Vec<ParamRow>,
    /// Outer-optimizer convergence, when the report comes from a calibration.
    pub convergence: Option<Convergence>,
    /// Settings that produced the result, in display order (key, value).
    pub settings: Vec<(String, String)>,
    /// Notes shown above the figures (warnings, e.g. frames that could not be solved).
    pub notes: Vec<String>,
    /// Where the information came from and the anatomical checks (a calibration).
    pub trust: Option<crate::trust::Trust>,
    /// Per trial: how it was read, repairs and data-check findings (section "Data checks",
    /// [`crate::data_checks`]; omitted when empty).
    pub data_checks: Vec<crate::data_checks::TrialChecks>,
    /// The verdict on a calibration (`ok`, `caution`, `reject` and why), shown at the top.
    pub verdict: Option<jointfit::workflow::verdict::Verdict>,
    /// How the model was scaled from a generic one (section "Scaling"; `jointfit scale`'s
    /// record beside the model).
    pub scaling: Option<jointfit_io::osim_scale::record::ScaleRecord>,
}

impl ReportInput {
    /// Attaches an uncertainty interval to the parameter called `name`; false when the table
    /// has no such parameter.
    pub fn set_interval(&mut self, name: &str, interval: Interval) -> bool {
        match self.parameters.iter_mut().find(|p| p.name == name) {
            Some(p) => {
                p.interval = Some(interval);
                true
            }
            None => false,
        }
    }
}

/// One trial's per-frame results.
#[derive(Debug, Clone, Default)]
pub struct TrialSeries {
    /// File name shown in captions and legends.
    pub name: String,
    /// Time of every frame (s).
    pub time: Vec<f64>,
    /// RMS marker distance per frame with the baseline model (mm; NaN where not solved).
    pub baseline_rms_mm: Option<Vec<f64>>,
    /// RMS marker distance per frame with the fitted model (mm; NaN where not solved).
    pub fitted_rms_mm: Vec<f64>,
    /// Coordinates of the fitted model over the trial, in model order.
    pub coords: Vec<CoordSeries>,
    /// Frames not solved with the fitted model.
    pub unsolved_frames: usize,
}

/// One coordinate over a trial.
#[derive(Debug, Clone, Default)]
pub struct CoordSeries {
    pub name: String,
    /// The joint it belongs to.
    pub joint: String,
    /// True for a joint to ground (the root segment's position and orientation in the lab).
    pub root: bool,
    /// "deg" for angles, "mm" for translations.
    pub unit: String,
    /// Fitted model, per frame (NaN where not solved).
    pub fitted: Vec<f64>,
    /// Baseline model, per frame, when a baseline is given.
    pub baseline: Option<Vec<f64>>,
}

/// Per-marker RMS (mm).
#[derive(Debug, Clone, Default)]
pub struct MarkerRms {
    pub name: String,
    pub baseline_mm: Option<f64>,
    pub fitted_mm: f64,
}

/// One joint parameter, in display units ("mm" or "deg").
#[derive(Debug, Clone, Default)]
pub struct ParamRow {
    pub name: String,
    pub group: String,
    pub unit: String,
    /// Baseline (nominal / landmark) value.
    pub baseline: Option<f64>,
    pub fitted: f64,
    pub lower: f64,
    pub upper: f64,
    /// Whether the calibration was free to change it (`None`: not known).
    pub free: Option<bool>,
    /// Uncertainty of the fitted value, when available.
    pub interval: Option<Interval>,
}

/// Standard error and confidence interval of a fitted parameter (display units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Interval {
    pub se: f64,
    pub lower: f64,
    pub upper: f64,
    /// Coverage of `[lower, upper]`, e.g. 0.95.
    pub level: f64,
}

/// Outer-optimizer progress.
#[derive(Debug, Clone, Default)]
pub struct Convergence {
    pub method: String,
    /// Stages (e.g. "particle swarm", "joint LM polish"), each with the objective
    /// `e_inner` (mm²) after every iteration; the first value is the starting cost.
    pub stages: Vec<(String, Vec<f64>)>,
    pub iterations: usize,
    pub evaluations: usize,
    pub converged: bool,
    pub seconds: f64,
    /// With several starts: (the start shown, 0-based; how many starts ran).
    pub start: Option<(usize, usize)>,
    /// How the optimizer stopped (`converged`, `stalled`, `iteration limit`); empty: unknown.
    pub termination: String,
}
