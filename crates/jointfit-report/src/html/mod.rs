//! The page: one self-contained HTML file (inline CSS and SVG, system fonts, no scripts, no
//! links to anything outside the file), written so that it is also well-formed XML (every
//! element closed, attributes quoted, all text escaped), which the tests check.
//!
//! Element ids a reader (or a test) can rely on: `summary`, `fig-frame-error`,
//! `fig-marker-rms`, `fig-joint-angles`, `tbl-parameters`, `fig-convergence`, `tbl-settings`,
//! and with a scaling record `tbl-scale-factors`, `tbl-marker-offsets` (`html/scaling.rs`).
//!
//! This file holds the page frame (style sheet, header cards, section order, footer), the
//! convergence figure and the settings list; the figures over the trial are in `html/plots.rs`, the
//! parameter table in `html/params.rs`.

use std::fmt::Write;

use crate::data::ReportInput;
use crate::svg::{escape, LineChart, Scale, Series};

mod params;
mod plots;
mod scaling;

use params::parameters;
use plots::{frame_error, joint_angles, marker_rms};

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
.verdict { border-left:4px solid #2e7d32; padding:6px 14px; margin:14px 0; background:#f3f8f3; }
.verdict-caution { border-color:#b26a00; background:#fff7e8; }
.verdict-reject { border-color:#b00020; background:#fdecee; }
.verdict ul { margin:4px 0 0 0; padding-left:20px; }
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
    if let Some(v) = &input.verdict {
        verdict(&mut h, v);
    }
    let mut n = 0;
    let mut section = |h: &mut String, id: &str, name: &str| {
        n += 1;
        let _ = write!(
            h,
            "<section id=\"sec-{id}\"><h2><span class=\"num\">{n}</span>{}</h2>",
            escape(name)
        );
    };
    if let Some(rec) = &input.scaling {
        section(&mut h, "scaling", "Scaling from the generic model");
        scaling::render(&mut h, rec);
        h.push_str("</section>");
    }
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

/// The verdict, first after the header: its level and the reasons (`id="verdict"`).
fn verdict(h: &mut String, v: &jointfit::workflow::verdict::Verdict) {
    let _ = write!(
        h,
        "<div id=\"verdict\" class=\"verdict verdict-{l}\"><p><strong>verdict: {l}</strong>{}</p>",
        if v.reasons.is_empty() {
            " — nothing found that argues against the result"
        } else {
            ""
        },
        l = v.level
    );
    if !v.reasons.is_empty() {
        h.push_str("<ul>");
        for r in &v.reasons {
            let _ = write!(h, "<li>{}</li>", escape(r));
        }
        h.push_str("</ul>");
    }
    h.push_str("</div>");
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
