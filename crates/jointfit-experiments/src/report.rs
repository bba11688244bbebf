//! Tables 1 and 2 of Reinbolt et al. 2005 next to ours: the run's results as data
//! (serialisable to JSON) and their Markdown and CSV renderings.

use jointfit::model::{Model, Unit};
use serde::Serialize;

use crate::paper::{TABLE1, TABLE1_COLUMNS, TABLE1_REDUCTION_PERCENT, TABLE2};
use crate::protocol::{ExperimentalResult, SyntheticResult};

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
    (u.display_suffix(), u.display_scale())
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

fn num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() < 0.1 || v.abs() >= 1e4 {
        format!("{v:.2e}")
    } else {
        format!("{v:.2}")
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or("n/a".into(), num)
}

fn spread(s: Option<Spread>) -> String {
    match s {
        None => "n/a".into(),
        Some(s) if s.n == 1 => num(s.mean),
        Some(s) => format!(
            "{} ± {} [{}–{}]",
            num(s.mean),
            num(s.std),
            num(s.min),
            num(s.max)
        ),
    }
}

fn table(header: &[String], rows: &[Vec<String>]) -> String {
    let mut out = format!("| {} |\n", header.join(" | "));
    out += &format!("|{}\n", "---|".repeat(header.len()));
    for r in rows {
        out += &format!("| {} |\n", r.join(" | "));
    }
    out
}

impl Report {
    /// Table 1 as Markdown: our value and the paper's, per column.
    pub fn table1_markdown(&self) -> String {
        let mut out = String::new();
        if !self.synthetic.is_empty() {
            let mut header = vec!["data".to_string(), "RMS error".to_string()];
            for c in &self.synthetic {
                header.push(format!("{} — ours", c.label));
                header.push(format!("{} — paper", TABLE1_COLUMNS[c.paper_column]));
            }
            let mut rows = Vec::new();
            type Getter = fn(&SyntheticResult) -> Option<f64>;
            let noiseless: [(&str, Getter, usize); 3] = [
                ("marker distances (mm)", |r| Some(r.marker_rms_mm), 0),
                ("orientation parameters (deg)", |r| r.orientation_rms_deg, 1),
                ("position parameters (mm)", |r| r.position_rms_mm, 2),
            ];
            for (q, get, paper_row) in noiseless {
                let mut row = vec!["synthetic without noise".into(), q.into()];
                for c in &self.synthetic {
                    row.push(opt(get(&c.noiseless)));
                    row.push(opt(TABLE1[paper_row].values[c.paper_column]));
                }
                rows.push(row);
            }
            type ColumnGetter = fn(&SyntheticColumn) -> Option<Spread>;
            let noisy: [(&str, ColumnGetter, usize); 3] = [
                ("marker distances (mm)", SyntheticColumn::noisy_marker, 3),
                (
                    "orientation parameters (deg)",
                    SyntheticColumn::noisy_orientation,
                    4,
                ),
                (
                    "position parameters (mm)",
                    SyntheticColumn::noisy_position,
                    5,
                ),
            ];
            for (q, get, paper_row) in noisy {
                let mut row = vec!["synthetic with noise".into(), q.into()];
                for c in &self.synthetic {
                    row.push(spread(get(c)));
                    row.push(opt(TABLE1[paper_row].values[c.paper_column]));
                }
                rows.push(row);
            }
            let mut row = vec![
                "synthetic with noise".into(),
                "injected noise, 3-D RMS (mm)".into(),
            ];
            for c in &self.synthetic {
                row.push(spread(c.noise_3d()));
                row.push("—".into());
            }
            rows.push(row);
            let mut row = vec![
                "synthetic with noise".into(),
                "seeds with fitted cost < cost at truth".into(),
            ];
            for c in &self.synthetic {
                row.push(format!("{}/{}", c.below_truth(), c.noisy.len()));
                row.push("—".into());
            }
            rows.push(row);
            out += &table(&header, &rows);
            out += "\nNoisy cells: mean ± sample std [min–max] over the seeds.\n\n";
        }
        if !self.experimental.is_empty() {
            let mut header = vec!["data".to_string(), "RMS marker distance (mm)".to_string()];
            for c in &self.experimental {
                header.push(format!("{} — ours", c.label));
                header.push(format!("{} — paper", TABLE1_COLUMNS[c.paper_column]));
            }
            let mut rows = vec![
                vec!["experimental".into(), "two-level optimization".into()],
                vec!["experimental".into(), "anatomical landmarks".into()],
                vec!["experimental".into(), "reduction (%)".into()],
            ];
            for c in &self.experimental {
                let r = &c.result;
                rows[0].push(num(r.fitted_rms_mm));
                rows[0].push(opt(TABLE1[6].values[c.paper_column]));
                rows[1].push(num(r.landmark_rms_mm));
                rows[1].push(opt(TABLE1[7].values[c.paper_column]));
                rows[2].push(format!("{:.0}", r.reduction_percent));
                rows[2].push(format!("{:.0}", TABLE1_REDUCTION_PERCENT[c.paper_column]));
            }
            out += &table(&header, &rows);
            out += "\n";
            for c in &self.experimental {
                out += &format!(
                    "- {}: {} — {} ({} frames, fitted {}; {:.2} s)\n",
                    c.label,
                    c.dataset,
                    c.trials.join(" + "),
                    c.result.frames,
                    c.result.groups.join(","),
                    c.result.seconds
                );
            }
            out += "\n";
        }
        out
    }

    /// Table 2 per subject as Markdown, the paper's three columns first.
    pub fn table2_markdown(&self) -> String {
        let mut out = String::new();
        for t in &self.table2 {
            out += &format!("#### {}\n\n", t.subject);
            let mut header: Vec<String> = [
                "joint",
                "parameter",
                "segment",
                "unit",
                "paper: landmarks",
                "paper: single joint",
                "paper: full leg",
            ]
            .iter()
            .map(|s| s.to_string())
            .collect();
            header.extend(t.methods.iter().map(|m| format!("ours: {m}")));
            let rows: Vec<Vec<String>> = t
                .rows
                .iter()
                .map(|(name, unit, vals)| {
                    let paper = TABLE2.iter().find(|r| r.0 == name);
                    let mut row = match paper {
                        Some(p) => vec![
                            p.1.to_string(),
                            format!("{} (`{name}`)", p.2),
                            p.3.to_string(),
                            unit.clone(),
                            format!("{:.2}", p.4),
                            format!("{:.2}", p.5),
                            format!("{:.2}", p.6),
                        ],
                        None => vec![
                            String::new(),
                            format!("`{name}`"),
                            String::new(),
                            unit.clone(),
                            "—".into(),
                            "—".into(),
                            "—".into(),
                        ],
                    };
                    row.extend(
                        vals.iter()
                            .map(|v| v.map_or("—".into(), |v| format!("{v:.2}"))),
                    );
                    row
                })
                .collect();
            out += &table(&header, &rows);
            for unit in ["deg", "mm"] {
                let d = t.rms_difference(unit);
                let parts: Vec<String> = t.methods[1..]
                    .iter()
                    .zip(d)
                    .filter_map(|(m, v)| Some(format!("{m} {:.1} {unit}", v?)))
                    .collect();
                if !parts.is_empty() {
                    out += &format!(
                        "\nRMS difference from our landmark values ({unit}): {}.",
                        parts.join(", ")
                    );
                }
            }
            out += " Paper: single joints about 7° and 15 mm, full leg 14° and 23 mm.\n";
            for n in &t.notes {
                out += &format!("\n- {n}");
            }
            out += "\n\n";
        }
        out
    }

    /// The whole report as Markdown.
    pub fn markdown(&self) -> String {
        let mut out = format!("# {}\n\n", self.title);
        out += &format!(
            "Reproduction of Reinbolt et al. 2005 (J Biomech 38:621–626, \
             doi:10.1016/j.jbiomech.2004.03.031) by jointfit {}{}.\n\nCommand: `{}`  \nRun time: {:.1} s\n\n",
            self.version,
            self.git.as_ref().map_or(String::new(), |g| format!(" ({g})")),
            self.command,
            self.seconds
        );
        if !self.synthetic.is_empty() || !self.experimental.is_empty() {
            out += "## Table 1: RMS errors\n\n";
            out += &self.table1_markdown();
        }
        if !self.table2.is_empty() {
            out += "## Table 2: joint parameters (mm, deg)\n\n";
            out += &self.table2_markdown();
        }
        if !self.notes.is_empty() {
            out += "## Notes\n\n";
            for n in &self.notes {
                out += &format!("- {n}\n");
            }
            out += "\n";
        }
        out += "## Settings\n\n```json\n";
        out += &serde_json::to_string_pretty(&self.settings).unwrap_or_default();
        out += "\n```\n";
        out
    }

    /// Long-format CSV: `table,data,column,quantity,statistic,ours,paper`.
    pub fn csv(&self) -> String {
        let mut out = String::from("table,data,column,quantity,statistic,ours,paper\n");
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
        for c in &self.synthetic {
            let pc = c.paper_column;
            let r = &c.noiseless;
            for (q, v, pr) in [
                ("marker_mm", Some(r.marker_rms_mm), 0),
                ("orientation_deg", r.orientation_rms_deg, 1),
                ("position_mm", r.position_rms_mm, 2),
            ] {
                out += &format!(
                    "1,synthetic without noise,{},{q},value,{},{}\n",
                    c.label,
                    f(v),
                    f(TABLE1[pr].values[pc])
                );
            }
            for (q, s, pr) in [
                ("marker_mm", c.noisy_marker(), 3),
                ("orientation_deg", c.noisy_orientation(), 4),
                ("position_mm", c.noisy_position(), 5),
            ] {
                if let Some(s) = s {
                    for (stat, v) in [
                        ("mean", s.mean),
                        ("std", s.std),
                        ("min", s.min),
                        ("max", s.max),
                    ] {
                        let paper = if stat == "mean" {
                            f(TABLE1[pr].values[pc])
                        } else {
                            String::new()
                        };
                        out += &format!(
                            "1,synthetic with noise,{},{q},{stat},{v},{paper}\n",
                            c.label
                        );
                    }
                }
            }
        }
        for c in &self.experimental {
            let pc = c.paper_column;
            let r = &c.result;
            out += &format!(
                "1,experimental,{},marker_mm,two-level,{},{}\n",
                c.label,
                r.fitted_rms_mm,
                f(TABLE1[6].values[pc])
            );
            out += &format!(
                "1,experimental,{},marker_mm,landmarks,{},{}\n",
                c.label,
                r.landmark_rms_mm,
                f(TABLE1[7].values[pc])
            );
        }
        for t in &self.table2 {
            for (name, unit, vals) in &t.rows {
                let paper = TABLE2.iter().find(|r| r.0 == name);
                for (m, v) in t.methods.iter().zip(vals) {
                    let pv = paper.and_then(|p| match m.as_str() {
                        "anatomical landmarks" => Some(p.4),
                        "single joint" => Some(p.5),
                        m if m.starts_with("full leg") => Some(p.6),
                        _ => None,
                    });
                    out += &format!(
                        "2,{},{name},{unit},{m},{},{}\n",
                        t.subject.replace(',', ";"),
                        f(*v),
                        f(pv)
                    );
                }
            }
        }
        out
    }
}

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
