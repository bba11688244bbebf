//! Markdown and CSV renderings of a [`Report`]: Table 1 and Table 2, ours next to the
//! paper's.

use super::*;

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
            out += &self.table1_synthetic();
        }
        if !self.experimental.is_empty() {
            out += &self.table1_experimental();
        }
        out
    }

    /// Table 1's synthetic rows: without noise, with noise (spread over the seeds), the
    /// injected noise and how often the fit ended below the cost at the truth.
    fn table1_synthetic(&self) -> String {
        let mut out = String::new();
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
        out
    }

    /// Table 1's experimental rows and a line per data set.
    fn table1_experimental(&self) -> String {
        let mut out = String::new();
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
