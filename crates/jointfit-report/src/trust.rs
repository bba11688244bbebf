//! The report's section on how far to trust a fit: where each parameter's information came
//! from (the share of its posterior information that the trial supplied, with the words
//! "determined by the trial", "partly determined", "held by the prior"; see
//! `jointfit::calibrate::prior::data_share`) and the anatomical plausibility checks
//! (`jointfit::plausibility`) with how far outside a failed one is.
//!
//! Element ids: `trust-summary`, `tbl-information`, `tbl-plausibility`.

use std::fmt::Write;

use jointfit::workflow::calibration::Calibration;

use crate::svg::escape;

/// One anatomical check, in display units.
#[derive(Debug, Clone, PartialEq)]
pub struct TrustCheck {
    pub check: String,
    pub parameters: Vec<String>,
    pub value: f64,
    pub limit: f64,
    pub unit: String,
    pub ok: bool,
}

/// What the section shows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trust {
    /// Marker noise σ (mm) that weighed the prior, and whether it was estimated; `None`: no
    /// prior (the paper's unregularized fit).
    pub noise_mm: Option<f64>,
    pub noise_estimated: bool,
    /// The short summary (one line per class, then which trial would help).
    pub summary: Vec<String>,
    /// Per parameter with a prior: name, share of information from the trial (0–1), class.
    pub shares: Vec<(String, f64, String)>,
    pub checks: Vec<TrustCheck>,
}

impl Trust {
    /// From a calibration's rows and checks.
    pub fn from_calibration(cal: &Calibration) -> Trust {
        let rows: Vec<_> = cal
            .parameters
            .iter()
            .map(|p| (p.group.clone(), p.name.clone(), p.source))
            .collect();
        Trust {
            noise_mm: cal.prior_noise.map(jointfit_app::present::mm),
            noise_estimated: cal.prior_noise_estimated,
            summary: if cal.prior_noise.is_some() {
                jointfit_app::present::information_summary(&rows)
            } else {
                Vec::new()
            },
            shares: cal
                .parameters
                .iter()
                .filter_map(|p| Some((p.name.clone(), p.data_share?, p.source?.to_string())))
                .collect(),
            checks: cal
                .plausibility
                .iter()
                .map(|c| TrustCheck {
                    check: c.check.clone(),
                    parameters: c.parameters.clone(),
                    value: c.value,
                    limit: c.limit,
                    unit: c.unit.to_string(),
                    ok: c.ok,
                })
                .collect(),
        }
    }

    /// Whether there is anything to show.
    pub fn is_empty(&self) -> bool {
        self.shares.is_empty() && self.checks.is_empty()
    }
}

/// Writes the section's body.
pub fn render(h: &mut String, t: &Trust) {
    match t.noise_mm {
        Some(s) => {
            let _ = write!(
                h,
                "<p class=\"lead\">Maximum a posteriori fit: each parameter was pulled toward \
                 its landmark (or functional) estimate with that method's published accuracy, \
                 weighed against the markers with a marker noise of σ = {s:.2} mm ({}).</p>",
                if t.noise_estimated {
                    "estimated from the residuals, inflated for their correlation over time"
                } else {
                    "given"
                }
            );
        }
        None => h.push_str(
            "<p class=\"lead\">Unregularized fit (no prior): every parameter is the trial's \
             alone.</p>",
        ),
    }
    if !t.summary.is_empty() {
        h.push_str("<ul id=\"trust-summary\">");
        for line in &t.summary {
            let _ = write!(h, "<li>{}</li>", escape(line));
        }
        h.push_str("</ul>");
    }
    if !t.shares.is_empty() {
        h.push_str(
            "<div class=\"scroll\"><table id=\"tbl-information\"><thead><tr><th>parameter</th>\
             <th class=\"n\">information from the trial</th><th>so the value is</th></tr>\
             </thead><tbody>",
        );
        for (name, share, words) in &t.shares {
            let _ = write!(
                h,
                "<tr><td>{}</td><td class=\"n\">{:.0} %</td><td>{}</td></tr>",
                escape(name),
                100.0 * share,
                escape(words)
            );
        }
        h.push_str("</tbody></table></div>");
    }
    if !t.checks.is_empty() {
        let failed = t.checks.iter().filter(|c| !c.ok).count();
        let _ = write!(
            h,
            "<p class=\"lead\">Anatomical checks: {}.</p>",
            if failed == 0 {
                "every fitted joint lies inside its envelope".to_string()
            } else {
                format!("<b>{failed} of {} outside the envelope</b>", t.checks.len())
            }
        );
        h.push_str(
            "<div class=\"scroll\"><table id=\"tbl-plausibility\"><thead><tr><th>check</th>\
             <th>parameters</th><th class=\"n\">value</th><th class=\"n\">limit</th>\
             <th class=\"n\">outside by</th></tr></thead><tbody>",
        );
        for c in &t.checks {
            let u = escape(&c.unit);
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td class=\"n\">{:.1} {u}</td>\
                 <td class=\"n\">{:.1} {u}</td><td class=\"n\">{}</td></tr>",
                escape(&c.check),
                escape(&c.parameters.join(", ")),
                c.value,
                c.limit,
                if c.ok {
                    "-".to_string()
                } else {
                    format!("<b>{:.1} {u}</b>", c.value - c.limit)
                }
            );
        }
        h.push_str("</tbody></table></div>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn section_names_the_class_and_how_far_outside() {
        let t = Trust {
            noise_mm: Some(8.5),
            noise_estimated: true,
            summary: vec!["held by the prior: hip (all 6)".into()],
            shares: vec![(
                "hip_pelvis_lateral".into(),
                0.12,
                "held by the prior".into(),
            )],
            checks: vec![TrustCheck {
                check: "hip centre lateral offset (≤ 0.9 × half the inter-ASIS width)".into(),
                parameters: vec!["hip_pelvis_lateral".into()],
                value: 119.9,
                limit: 114.3,
                unit: "mm".into(),
                ok: false,
            }],
        };
        let mut h = String::from("<div>");
        render(&mut h, &t);
        h.push_str("</div>");
        for needle in [
            "σ = 8.50 mm",
            "held by the prior: hip (all 6)",
            "12 %",
            "1 of 1 outside",
            "<b>5.6 mm</b>",
            "hip_pelvis_lateral",
        ] {
            assert!(h.contains(needle), "{needle}: {h}");
        }
        let root = crate::check::parse(&h).unwrap();
        assert!(root.by_id("tbl-plausibility").is_some());
        assert!(root.by_id("tbl-information").is_some());
    }
}
