//! The joint-parameter table (`tbl-parameters`): landmark and fitted values, change,
//! interval, bounds, and a gauge of where each value sits inside its bounds.

use std::fmt::Write;

use super::{fmt, BASELINE, FITTED};
use crate::data::{ParamRow, ReportInput};
use crate::svg::escape;

/// A small gauge: the bounds as a bar, the baseline as a tick, the fitted value as a dot, the
/// interval as a thick segment.
fn gauge(p: &ParamRow) -> String {
    let (w, hgt) = (104.0, 14.0);
    let span = (p.upper - p.lower).max(1e-12);
    let x = |v: f64| 4.0 + (v.clamp(p.lower, p.upper) - p.lower) / span * (w - 8.0);
    let mut s = format!(
        "<svg viewBox=\"0 0 {w} {hgt}\" width=\"{w}\" height=\"{hgt}\" role=\"img\"><title>position within bounds</title>\
         <line x1=\"4\" y1=\"7\" x2=\"{:.1}\" y2=\"7\" stroke=\"#dde2e8\" stroke-width=\"4\" stroke-linecap=\"round\"/>",
        w - 4.0
    );
    if let Some(iv) = &p.interval {
        let _ = write!(
            s,
            "<line x1=\"{:.1}\" y1=\"7\" x2=\"{:.1}\" y2=\"7\" stroke=\"{FITTED}\" stroke-opacity=\".35\" stroke-width=\"8\"/>",
            x(iv.lower),
            x(iv.upper)
        );
    }
    if let Some(b) = p.baseline {
        let _ = write!(
            s,
            "<line x1=\"{0:.1}\" y1=\"1\" x2=\"{0:.1}\" y2=\"13\" stroke=\"{BASELINE}\" stroke-width=\"2\"/>",
            x(b)
        );
    }
    let _ = write!(
        s,
        "<circle cx=\"{:.1}\" cy=\"7\" r=\"3.6\" fill=\"{FITTED}\"/></svg>",
        x(p.fitted)
    );
    s
}

/// A fitted (not fixed) parameter within 0.1 % of its range from a bound.
fn at_bound(p: &ParamRow) -> bool {
    let tol = 1e-3 * (p.upper - p.lower).abs();
    p.free != Some(false)
        && ((p.fitted - p.lower).abs() <= tol || (p.upper - p.fitted).abs() <= tol)
}

pub(super) fn parameters(h: &mut String, input: &ReportInput) {
    let has_base = input.parameters.iter().any(|p| p.baseline.is_some());
    lead(h, input, has_base);
    table_head(h, input, has_base);
    let cols = if has_base { 8 } else { 6 };
    let mut group: Option<&str> = None;
    for p in &input.parameters {
        if group != Some(p.group.as_str()) {
            group = Some(p.group.as_str());
            let _ = write!(
                h,
                "<tr class=\"group\"><td colspan=\"{cols}\">{}</td></tr>",
                escape(&p.group)
            );
        }
        row(h, p, has_base);
    }
    h.push_str("</tbody></table></div>");
}

/// The paragraphs above the table: how to read the gauge, and which parameters ended at a
/// bound.
fn lead(h: &mut String, input: &ReportInput, has_base: bool) {
    let bound: Vec<&str> = input
        .parameters
        .iter()
        .filter(|p| at_bound(p))
        .map(|p| p.name.as_str())
        .collect();
    let has_interval = input.parameters.iter().any(|p| p.interval.is_some());
    let _ = write!(
        h,
        "<p class=\"lead\">Joint parameters in millimetres and degrees. The gauge spans each \
         parameter's bounds: {}the dot is the fitted value{}. {}</p>",
        if has_base {
            format!("the orange tick is the {}, ", escape(&input.baseline_label))
        } else {
            String::new()
        },
        if has_interval {
            ", the shaded band its confidence interval"
        } else {
            ""
        },
        if has_interval {
            ""
        } else {
            "Confidence intervals are shown when uncertainty estimates are available."
        }
    );
    if !bound.is_empty() {
        let _ =
            write!(
            h,
            "<p class=\"lead\"><b>{} at a bound</b> ({}): the fit would have moved {} further; \
             {} set by the bound, not by the data.</p>",
            if bound.len() == 1 {
                "One parameter ended".to_string()
            } else {
                format!("{} parameters ended", bound.len())
            },
            escape(&bound.join(", ")),
            if bound.len() == 1 { "it" } else { "them" },
            if bound.len() == 1 { "its value is" } else { "their values are" }
        );
    }
}

/// The table's opening and header row.
fn table_head(h: &mut String, input: &ReportInput, has_base: bool) {
    let _ = write!(
        h,
        "<div class=\"scroll\"><table id=\"tbl-parameters\"><thead><tr><th>parameter</th><th>unit</th>{}<th class=\"n\">{}</th>{}\
         <th class=\"n\">{}</th><th class=\"n\">bounds</th><th>position in bounds</th></tr></thead><tbody>",
        if has_base {
            format!("<th class=\"n\">{}</th>", escape(&input.baseline_label))
        } else {
            String::new()
        },
        escape(&input.fitted_label),
        if has_base { "<th class=\"n\">change</th>" } else { "" },
        match input.parameters.iter().find_map(|p| p.interval) {
            Some(iv) => format!("{}% interval", fmt(100.0 * iv.level, 0)),
            None => "interval".to_string(),
        }
    );
}

/// One parameter's row: name (and badges), unit, baseline, fitted value, change, interval,
/// bounds and gauge.
fn row(h: &mut String, p: &ParamRow, has_base: bool) {
    let fixed = p.free == Some(false);
    let at_bound = at_bound(p);
    let _ = write!(
        h,
        "<tr{}><td class=\"name\">{}{}{}</td><td>{}</td>",
        if fixed { " class=\"fixed\"" } else { "" },
        escape(&p.name),
        if fixed {
            " <span class=\"badge\" style=\"background:#eef1f4;color:#7a8590\">fixed</span>"
        } else {
            ""
        },
        if at_bound {
            "<span class=\"badge\">at bound</span>"
        } else {
            ""
        },
        escape(&p.unit)
    );
    if has_base {
        let _ = write!(
            h,
            "<td class=\"n\">{}</td>",
            p.baseline.map(|b| fmt(b, 2)).unwrap_or_else(|| "–".into())
        );
    }
    let _ = write!(h, "<td class=\"n\"><b>{}</b></td>", fmt(p.fitted, 2));
    if has_base {
        let _ = write!(
            h,
            "<td class=\"n\">{}</td>",
            p.baseline
                .map(|b| {
                    let d = p.fitted - b;
                    if d.abs() < 0.005 {
                        "0".to_string()
                    } else {
                        format!("{}{}", if d > 0.0 { "+" } else { "" }, fmt(d, 2))
                    }
                })
                .unwrap_or_else(|| "–".into())
        );
    }
    let _ = write!(
        h,
        "<td class=\"n\">{}</td><td class=\"n\">{} … {}</td><td>{}</td></tr>",
        match &p.interval {
            Some(iv) => format!(
                "<span title=\"{}% interval {} … {}; standard error {}\">±{}</span>",
                fmt(100.0 * iv.level, 0),
                fmt(iv.lower, 2),
                fmt(iv.upper, 2),
                fmt(iv.se, 2),
                fmt(0.5 * (iv.upper - iv.lower), 2)
            ),
            None => "–".to_string(),
        },
        fmt(p.lower, 1),
        fmt(p.upper, 1),
        gauge(p)
    );
}
