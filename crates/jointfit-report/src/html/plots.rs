//! The figures over the trial: RMS marker error per frame, RMS per marker, and every
//! coordinate over time (element ids `fig-frame-error`, `fig-marker-rms`, `fig-joint-angles`).

use std::fmt::Write;

use super::{fmt, BASELINE, BASELINE_BAR, FITTED, TRIAL_COLORS};
use crate::data::ReportInput;
use crate::svg::{escape, BarChart, LineChart, Series};

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

pub(super) fn frame_error(h: &mut String, input: &ReportInput) {
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

pub(super) fn marker_rms(h: &mut String, input: &ReportInput) {
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

pub(super) fn joint_angles(h: &mut String, input: &ReportInput) {
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
