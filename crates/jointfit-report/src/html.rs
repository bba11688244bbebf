//! The page: one self-contained HTML file (inline CSS and SVG, system fonts, no scripts, no
//! links to anything outside the file), written so that it is also well-formed XML (every
//! element closed, attributes quoted, all text escaped), which the tests check.
//!
//! Element ids a reader (or a test) can rely on: `summary`, `fig-frame-error`,
//! `fig-marker-rms`, `fig-joint-angles`, `tbl-parameters`, `fig-convergence`, `tbl-settings`.

use std::fmt::Write;

use crate::data::{ParamRow, ReportInput};
use crate::svg::{escape, BarChart, LineChart, Scale, Series};

/// Colours (colour-blind-safe pair for baseline vs fitted).
pub const BASELINE: &str = "#d9822b";
pub const FITTED: &str = "#1f5fa8";
const BASELINE_BAR: &str = "#efbc8a";
/// Per-trial colours when several trials share a panel.
const TRIAL_COLORS: [&str; 6] = [
    "#1f5fa8", "#2a9d8f", "#8e44ad", "#c0392b", "#7f8c24", "#d35400",
];
const STAGE_COLORS: [&str; 3] = ["#8e44ad", "#1f5fa8", "#2a9d8f"];

const CSS: &str = r#"
:root { --ink:#1d232b; --muted:#5b6673; --rule:#dde2e8; --soft:#f5f7fa; --accent:#1f5fa8; }
* { box-sizing:border-box; }
html { background:#fff; }
body { margin:0; color:var(--ink); font:15px/1.55 system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue","Noto Sans","Liberation Sans",Arial,sans-serif; font-feature-settings:"tnum" 1; }
main { max-width:1120px; margin:0 auto; padding:40px 36px 64px; }
header { border-bottom:1px solid var(--rule); padding-bottom:22px; margin-bottom:8px; }
.eyebrow { text-transform:uppercase; letter-spacing:.12em; font-size:12px; color:var(--muted); margin:0 0 6px; font-weight:600; }
h1 { font-size:30px; line-height:1.2; margin:0 0 6px; font-weight:650; letter-spacing:-.01em; }
.sub { color:var(--muted); margin:0; }
h2 { font-size:20px; margin:42px 0 4px; font-weight:650; letter-spacing:-.005em; }
h2 .num { color:var(--accent); margin-right:.45em; font-variant-numeric:tabular-nums; }
h3 { font-size:15px; margin:22px 0 6px; color:var(--muted); font-weight:600; }
p.lead { color:var(--muted); margin:2px 0 14px; max-width:78ch; }
.cards { display:flex; flex-wrap:wrap; gap:14px; margin-top:20px; }
.card { flex:1 1 200px; background:var(--soft); border-radius:8px; padding:12px 16px; }
.card .k { font-size:12px; color:var(--muted); text-transform:uppercase; letter-spacing:.06em; }
.card .v { font-size:24px; font-weight:650; font-variant-numeric:tabular-nums; }
.card .v small { font-size:14px; color:var(--muted); font-weight:500; }
.card .d { font-size:13px; color:var(--muted); }
.notes { background:#fff7e6; border-left:4px solid #e0a030; padding:10px 16px; margin:20px 0 0; border-radius:4px; }
.notes p { margin:4px 0; }
figure { margin:10px 0 0; }
figcaption { color:var(--muted); font-size:13px; margin-top:4px; }
svg.chart { display:block; width:100%; height:auto; overflow:visible; }
svg .grid { stroke:#e8ecf0; stroke-width:1; }
svg .axis { stroke:#8a949e; stroke-width:1; }
svg .tick { fill:#5b6673; }
svg .label { fill:#2b333c; font-weight:600; }
svg .title { fill:#1d232b; font-weight:600; }
svg .value { fill:#5b6673; font-size:9.5px; }
svg .band { fill:#f7f9fb; }
svg text { font-family:inherit; }
.pair { display:grid; grid-template-columns:1fr 1fr; gap:20px; }
.panels { display:grid; grid-template-columns:repeat(auto-fill,minmax(320px,1fr)); gap:6px 18px; }
.key { display:flex; gap:22px; flex-wrap:wrap; font-size:13px; color:var(--muted); margin:4px 0 8px; }
.key span::before { content:""; display:inline-block; width:22px; height:0; border-top:3px solid var(--c); vertical-align:middle; margin-right:7px; }
.key span.dashed::before { border-top-style:dashed; }
.scroll { overflow-x:auto; }
table { border-collapse:collapse; width:100%; font-size:13.5px; font-variant-numeric:tabular-nums; }
th { text-align:left; font-weight:600; color:var(--muted); font-size:12px; text-transform:uppercase; letter-spacing:.04em; border-bottom:2px solid var(--rule); padding:6px 6px; }
td { border-bottom:1px solid #eef1f4; padding:5px 6px; vertical-align:middle; }
td.n, th.n { text-align:right; white-space:nowrap; }
tr.group td { background:var(--soft); font-weight:650; color:var(--ink); text-transform:capitalize; border-bottom:1px solid var(--rule); }
tr.fixed td { color:#97a0aa; }
td.name { white-space:nowrap; font-family:ui-monospace,"SFMono-Regular",Menlo,Consolas,"Liberation Mono",monospace; font-size:12.5px; }
.badge { display:inline-block; font-size:11px; padding:0 6px; border-radius:9px; background:#fdecea; color:#b03a2e; margin-left:6px; }
dl.settings { display:grid; grid-template-columns:max-content 1fr; gap:6px 22px; margin:8px 0 0; }
dl.settings dt { color:var(--muted); }
dl.settings dd { margin:0; }
code { font-family:ui-monospace,"SFMono-Regular",Menlo,Consolas,"Liberation Mono",monospace; font-size:12.5px; background:var(--soft); padding:1px 5px; border-radius:4px; word-break:break-all; }
@media (max-width:760px) { main { padding:24px 16px 40px; } .pair { grid-template-columns:1fr; } }
@media print { main { max-width:none; padding:0; } figure, svg, tr { break-inside:avoid; } .card { border:1px solid var(--rule); } }
footer { margin-top:48px; border-top:1px solid var(--rule); padding-top:12px; color:var(--muted); font-size:12.5px; }
"#;

/// The whole page.
pub fn render(input: &ReportInput) -> String {
    let mut h = String::new();
    let title = if input.title.is_empty() {
        "jointfit report".to_string()
    } else {
        input.title.clone()
    };
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"/>\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\
         <title>{}</title><style>{}</style></head><body><main>",
        escape(&title),
        CSS
    );
    header(&mut h, input, &title);
    let mut n = 0;
    let mut section = |h: &mut String, id: &str, name: &str| {
        n += 1;
        let _ = write!(
            h,
            "<section id=\"sec-{id}\"><h2><span class=\"num\">{n}</span>{}</h2>",
            escape(name)
        );
    };
    if !input.data_checks.is_empty() {
        section(&mut h, "data-checks", "Data checks");
        crate::data_checks::render(&mut h, &input.data_checks);
        h.push_str("</section>");
    }
    section(&mut h, "frame-error", "Marker error over the trial");
    frame_error(&mut h, input);
    h.push_str("</section>");
    section(&mut h, "marker-rms", "Error per marker");
    marker_rms(&mut h, input);
    h.push_str("</section>");
    section(&mut h, "joint-angles", "Joint angles");
    joint_angles(&mut h, input);
    h.push_str("</section>");
    section(&mut h, "parameters", "Joint parameters");
    parameters(&mut h, input);
    h.push_str("</section>");
    if let Some(t) = input.trust.as_ref().filter(|t| !t.is_empty()) {
        section(&mut h, "trust", "How far to trust the fit");
        crate::trust::render(&mut h, t);
        h.push_str("</section>");
    }
    section(&mut h, "convergence", "Convergence of the outer optimizer");
    convergence(&mut h, input);
    h.push_str("</section>");
    section(&mut h, "settings", "Settings");
    settings(&mut h, input);
    h.push_str("</section>");
    let version = input
        .settings
        .iter()
        .find(|(k, _)| k == "jointfit version")
        .map(|(_, v)| format!(" {v}"))
        .unwrap_or_default();
    let _ = writeln!(
        h,
        "<footer>Written by jointfit{}. Two-level optimization of joint parameters after \
         Reinbolt, Schutte, Fregly et al. (2005), J Biomech 38:621–626. This page is \
         self-contained: it loads nothing from the network.</footer></main></body></html>",
        escape(&version)
    );
    h
}

fn fmt(v: f64, decimals: usize) -> String {
    if v.is_nan() {
        return "–".to_string();
    }
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s.replace('-', "\u{2212}")
    }
}

fn header(h: &mut String, input: &ReportInput, title: &str) {
    let date = input
        .settings
        .iter()
        .find(|(k, _)| k == "date")
        .map(|(_, v)| v.as_str())
        .unwrap_or("");
    let trials: Vec<&str> = input.trials.iter().map(|t| t.name.as_str()).collect();
    let frames: usize = input.trials.iter().map(|t| t.time.len()).sum();
    let _ = write!(
        h,
        "<header id=\"summary\"><p class=\"eyebrow\">jointfit · calibration report</p><h1>{}</h1>\
         <p class=\"sub\">{} · {} frames{}</p><div class=\"cards\">",
        escape(title),
        escape(&trials.join(", ")),
        frames,
        if date.is_empty() {
            String::new()
        } else {
            format!(" · {}", escape(date))
        }
    );
    let (base, fit) = input.overall_rms_mm;
    match base {
        Some(b) => {
            let _ = write!(
                h,
                "<div class=\"card\"><div class=\"k\">RMS marker error</div><div class=\"v\">{} \
                 <small>→</small> {} <small>mm</small></div><div class=\"d\">{} → {} ({}% lower)</div></div>",
                fmt(b, 2),
                fmt(fit, 2),
                escape(&input.baseline_label),
                escape(&input.fitted_label),
                fmt(100.0 * (1.0 - fit / b), 0)
            );
        }
        None => {
            let _ = write!(
                h,
                "<div class=\"card\"><div class=\"k\">RMS marker error</div><div class=\"v\">{} <small>mm</small></div>\
                 <div class=\"d\">{}</div></div>",
                fmt(fit, 2),
                escape(&input.fitted_label)
            );
        }
    }
    let free = input
        .parameters
        .iter()
        .filter(|p| p.free.unwrap_or(false))
        .count();
    let _ = write!(
        h,
        "<div class=\"card\"><div class=\"k\">parameters</div><div class=\"v\">{}</div><div class=\"d\">{}</div></div>",
        if input.parameters.iter().any(|p| p.free.is_some()) {
            format!("{free} <small>of {}</small>", input.parameters.len())
        } else {
            input.parameters.len().to_string()
        },
        if input.parameters.iter().any(|p| p.free.is_some()) {
            "fitted"
        } else {
            "in the model"
        }
    );
    if let Some(c) = &input.convergence {
        let _ = write!(
            h,
            "<div class=\"card\"><div class=\"k\">outer optimizer</div><div class=\"v\">{} <small>iterations</small></div>\
             <div class=\"d\">{} · {} s{}</div></div>",
            c.iterations,
            escape(&c.method),
            fmt(c.seconds, 2),
            if c.converged { "" } else { " · not converged" }
        );
    }
    h.push_str("</div></header>");
    if !input.notes.is_empty() {
        h.push_str("<div class=\"notes\">");
        for n in &input.notes {
            let _ = write!(h, "<p>{}</p>", escape(n));
        }
        h.push_str("</div>");
    }
}

fn key(h: &mut String, items: &[(&str, &str, bool)]) {
    h.push_str("<div class=\"key\">");
    for (label, color, dashed) in items {
        let _ = write!(
            h,
            "<span{} style=\"--c:{}\">{}</span>",
            if *dashed { " class=\"dashed\"" } else { "" },
            escape(color),
            escape(label)
        );
    }
    h.push_str("</div>");
}

fn frame_error(h: &mut String, input: &ReportInput) {
    let with = if input.trials.iter().any(|t| t.baseline_rms_mm.is_some()) {
        "each model"
    } else {
        "the model"
    };
    let _ = write!(
        h,
        "<p class=\"lead\">Root-mean-square distance between measured and model markers in every \
         frame, after inverse kinematics with {with}. Lower is better; OpenSim's best-practice \
         target for movement trials is below 20 mm.</p><figure id=\"fig-frame-error\">"
    );
    for (i, t) in input.trials.iter().enumerate() {
        let mut c = LineChart::new(1000.0, 290.0, "time (s)", "RMS marker error (mm)");
        c.id = format!("frame-error-{i}");
        c.y_from_zero = true;
        if input.trials.len() > 1 {
            c.title = Some(t.name.clone());
        }
        if let Some(b) = &t.baseline_rms_mm {
            c.series.push(Series::line(
                &input.baseline_label,
                BASELINE,
                t.time.iter().copied().zip(b.iter().copied()).collect(),
            ));
        }
        c.series.push(Series::line(
            &input.fitted_label,
            FITTED,
            t.time
                .iter()
                .copied()
                .zip(t.fitted_rms_mm.iter().copied())
                .collect(),
        ));
        h.push_str(&c.to_svg());
        let mean = |v: &[f64]| {
            let ok: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
            ok.iter().sum::<f64>() / ok.len().max(1) as f64
        };
        let _ = write!(
            h,
            "<figcaption>{}: mean per-frame RMS {}{} mm with the {}.</figcaption>",
            escape(&t.name),
            t.baseline_rms_mm
                .as_ref()
                .map(|b| format!(
                    "{} mm with the {}, ",
                    fmt(mean(b), 2),
                    escape(&input.baseline_label)
                ))
                .unwrap_or_default(),
            fmt(mean(&t.fitted_rms_mm), 2),
            escape(&input.fitted_label)
        );
    }
    h.push_str("</figure>");
}

fn marker_rms(h: &mut String, input: &ReportInput) {
    let _ = write!(
        h,
        "<p class=\"lead\">RMS distance of each model marker over all frames of all trials. \
         Markers whose error the fit cannot reduce point to skin motion or a marker placed \
         differently than in the static trial.</p><figure id=\"fig-marker-rms\">"
    );
    let has_base = input.markers.iter().any(|m| m.baseline_mm.is_some());
    let mut groups = Vec::new();
    if has_base {
        groups.push((input.baseline_label.clone(), BASELINE_BAR.to_string()));
    }
    groups.push((input.fitted_label.clone(), FITTED.to_string()));
    let chart = BarChart {
        width: 1000.0,
        x_label: "RMS marker error (mm)".to_string(),
        categories: input.markers.iter().map(|m| m.name.clone()).collect(),
        groups,
        values: input
            .markers
            .iter()
            .map(|m| {
                let mut v = Vec::new();
                if has_base {
                    v.push(m.baseline_mm.unwrap_or(f64::NAN));
                }
                v.push(m.fitted_mm);
                v
            })
            .collect(),
        font: 12.0,
    };
    h.push_str(&chart.to_svg());
    h.push_str("</figure>");
}

fn joint_angles(h: &mut String, input: &ReportInput) {
    let several = input.trials.len() > 1;
    let _ =
        write!(
        h,
        "<p class=\"lead\">Coordinates of the {} over time from inverse kinematics{}. Angles in \
         degrees, translations in millimetres.</p><figure id=\"fig-joint-angles\">",
        escape(&input.fitted_label),
        if input.trials.iter().any(|t| t.coords.iter().any(|c| c.baseline.is_some())) {
            format!(", with the {} dashed for comparison", escape(&input.baseline_label))
        } else {
            String::new()
        }
    );
    let mut items: Vec<(String, &str, bool)> = Vec::new();
    for (i, t) in input.trials.iter().enumerate() {
        let color = if several {
            TRIAL_COLORS[i % TRIAL_COLORS.len()]
        } else {
            FITTED
        };
        let label = if several {
            format!("{}: {}", t.name, input.fitted_label)
        } else {
            input.fitted_label.clone()
        };
        items.push((label, color, false));
    }
    if input
        .trials
        .iter()
        .any(|t| t.coords.iter().any(|c| c.baseline.is_some()))
    {
        items.push((
            input.baseline_label.clone(),
            if several { "#8a949e" } else { BASELINE },
            true,
        ));
    }
    let refs: Vec<(&str, &str, bool)> =
        items.iter().map(|(a, b, c)| (a.as_str(), *b, *c)).collect();
    key(h, &refs);
    let Some(first) = input.trials.first() else {
        h.push_str("</figure>");
        return;
    };
    for root in [false, true] {
        let idx: Vec<usize> = (0..first.coords.len())
            .filter(|&c| first.coords[c].root == root)
            .collect();
        if idx.is_empty() {
            continue;
        }
        if root {
            h.push_str("<h3>Position and orientation of the root segment in the lab</h3>");
        }
        h.push_str("<div class=\"panels\">");
        for c in idx {
            let coord = &first.coords[c];
            let mut chart = LineChart::new(330.0, 200.0, "time (s)", &coord.unit);
            chart.font = 10.5;
            chart.id = format!("coord-{c}");
            chart.legend = false;
            chart.title = Some(coord.name.clone());
            for (i, t) in input.trials.iter().enumerate() {
                let Some(cs) = t.coords.get(c) else { continue };
                let color = if several {
                    TRIAL_COLORS[i % TRIAL_COLORS.len()]
                } else {
                    FITTED
                };
                if let Some(b) = &cs.baseline {
                    let mut s = Series::line(
                        &format!("{} {}", t.name, input.baseline_label),
                        if several { "#8a949e" } else { BASELINE },
                        t.time.iter().copied().zip(b.iter().copied()).collect(),
                    );
                    s.dashed = true;
                    s.width = 1.3;
                    chart.series.push(s);
                }
                chart.series.push(Series::line(
                    &format!("{} {}", t.name, input.fitted_label),
                    color,
                    t.time
                        .iter()
                        .copied()
                        .zip(cs.fitted.iter().copied())
                        .collect(),
                ));
            }
            h.push_str(&chart.to_svg());
        }
        h.push_str("</div>");
    }
    h.push_str("</figure>");
}

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

fn parameters(h: &mut String, input: &ReportInput) {
    let has_base = input.parameters.iter().any(|p| p.baseline.is_some());
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
    h.push_str("</tbody></table></div>");
}

fn convergence(h: &mut String, input: &ReportInput) {
    let Some(c) = &input.convergence else {
        h.push_str(
            "<p class=\"lead\" id=\"fig-convergence\">Not available: this report was made from a \
             fitted model file. Run <code>jointfit calibrate … --report DIR</code> to include \
             the optimizer's history.</p>",
        );
        return;
    };
    let _ = write!(
        h,
        "<p class=\"lead\">Objective e<sub>inner</sub> = Σ‖m − x‖² over all frames and markers \
         (mm², log scale) after each outer iteration of the {} method{}: {} iterations, {} \
         objective evaluations, {} s{}.</p><figure id=\"fig-convergence\">",
        escape(&c.method),
        match c.start {
            Some((best, n)) => format!(", start {} of {n} (the lowest objective)", best + 1),
            None => String::new(),
        },
        c.iterations,
        c.evaluations,
        fmt(c.seconds, 2),
        if c.converged {
            ", converged".to_string()
        } else if c.termination.is_empty() {
            ", stopped before converging".to_string()
        } else {
            format!(", stopped before converging ({})", escape(&c.termination))
        }
    );
    // Left: the objective. Right: its excess over the best value reached, which shows the
    // rate of convergence once the objective itself looks flat.
    let best = c
        .stages
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    let mut charts = [
        LineChart::new(490.0, 300.0, "outer iteration", "objective (mm²)"),
        LineChart::new(490.0, 300.0, "outer iteration", "objective − best (mm²)"),
    ];
    for (k, chart) in charts.iter_mut().enumerate() {
        chart.y_scale = Scale::Log10;
        chart.x_integer = true;
        chart.legend = k == 0;
        chart.id = format!("convergence-{k}");
        let mut offset = 0usize;
        for (i, (name, costs)) in c.stages.iter().enumerate() {
            let pts: Vec<(f64, f64)> = costs
                .iter()
                .enumerate()
                .map(|(j, v)| ((offset + j) as f64, if k == 0 { *v } else { v - best }))
                .collect();
            offset += costs.len().saturating_sub(1);
            let mut s = Series::line(name, STAGE_COLORS[i % STAGE_COLORS.len()], pts);
            s.dots = costs.len() <= 60;
            chart.series.push(s);
        }
    }
    h.push_str("<div class=\"pair\">");
    for chart in &charts {
        h.push_str(&chart.to_svg());
    }
    h.push_str("</div>");
    if let Some(last) = c.stages.last().and_then(|s| s.1.last()) {
        let first = c.stages.first().and_then(|s| s.1.first()).copied();
        let _ = write!(
            h,
            "<figcaption>{}final objective {} mm².</figcaption>",
            first
                .map(|f| format!("Starting objective {} mm²; ", fmt(f, 1)))
                .unwrap_or_default(),
            fmt(*last, 1)
        );
    }
    h.push_str("</figure>");
}

fn settings(h: &mut String, input: &ReportInput) {
    h.push_str("<dl class=\"settings\" id=\"tbl-settings\">");
    for (k, v) in &input.settings {
        let value = if k == "command line" {
            format!("<code>{}</code>", escape(v))
        } else {
            escape(v)
        };
        let _ = write!(h, "<dt>{}</dt><dd>{}</dd>", escape(k), value);
    }
    h.push_str("</dl>");
}
