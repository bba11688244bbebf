//! Small SVG charts written by hand: line charts (linear or log-10 value axis) and grouped
//! horizontal bar charts, with ticks at "nice" values (1, 2, 5 × 10ᵏ), grid lines, axis labels
//! and legends.
//!
//! The output is inline SVG for an HTML page: no `xmlns`, no scripts, no external fonts or
//! images; colours and fonts come from attributes and from the page's CSS classes `grid`, `axis`,
//! `tick`, `label`, `title`, `band` and `value` (see [`crate::html`]). All text goes through
//! [`escape`].

use std::fmt::Write;

/// Escapes text for HTML/SVG text content and double-quoted attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            // Control characters other than tab/newline are not allowed in XML text.
            c if c.is_control() && c != '\n' && c != '\t' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

/// A step of 1, 2 or 5 × 10ᵏ giving about `target` intervals over `span` (> 0).
pub fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f < 1.5 {
        1.0
    } else if f < 3.0 {
        2.0
    } else if f < 7.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Axis range widened to multiples of a nice step, and the ticks inside it.
///
/// A degenerate or empty range (`lo == hi`, or non-finite) becomes a unit-wide range around
/// the value (or `[0, 1]`).
pub fn linear_ticks(lo: f64, hi: f64, target: usize) -> (f64, f64, Vec<f64>) {
    let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() {
        (lo.min(hi), lo.max(hi))
    } else {
        (0.0, 1.0)
    };
    if hi - lo < 1e-12 * (1.0 + lo.abs().max(hi.abs())) {
        let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        lo -= pad;
        hi += pad;
    }
    let step = nice_step(hi - lo, target);
    let a = (lo / step + 1e-9).floor() * step;
    let b = (hi / step - 1e-9).ceil() * step;
    let n = ((b - a) / step).round() as usize;
    let ticks = (0..=n).map(|i| a + i as f64 * step).collect();
    (a, b, ticks)
}

/// Decade range (as exponents) covering the positive values `lo..hi`, and tick values.
pub fn log_ticks(lo: f64, hi: f64) -> (i32, i32, Vec<f64>) {
    let (lo, hi) = if lo > 0.0 && hi.is_finite() && hi >= lo {
        (lo, hi)
    } else {
        (1.0, 10.0)
    };
    let a = lo.log10().floor() as i32;
    let mut b = hi.log10().ceil() as i32;
    if b <= a {
        b = a + 1;
    }
    let ticks = (a..=b).map(|e| 10f64.powi(e)).collect();
    (a, b, ticks)
}

/// A tick label with as many decimals as the step needs (no "-0").
pub fn format_tick(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let s = format!("{:.*}", decimals, v);
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s.replace('-', "\u{2212}")
    }
}

/// `10` with a superscript exponent, e.g. `10⁻³`.
pub fn power_of_ten(e: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("10");
    if e < 0 {
        s.push('⁻');
    }
    for d in e.unsigned_abs().to_string().chars() {
        s.push(SUP[d.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// Tick positions (log10 of the value) and labels for the decades `a..=b`: every decade (or
/// every few when there are many), plus 2 and 5 in between when the range spans at most two
/// decades. Labels are plain numbers between 0.001 and 100 000, powers of ten otherwise.
pub fn log_axis_ticks(a: i32, b: i32) -> (Vec<f64>, Vec<String>) {
    let plain = a >= -3 && b <= 5;
    let label = |m: f64, e: i32| {
        if plain {
            let v = m * 10f64.powi(e);
            format_tick(v, 10f64.powi(e.min(0)))
        } else if m == 1.0 {
            power_of_ten(e)
        } else {
            format!("{m}·{}", power_of_ten(e))
        }
    };
    let mut pos = Vec::new();
    let mut labels = Vec::new();
    if b - a <= 2 {
        for e in a..=b {
            for m in [1.0, 2.0, 5.0] {
                let p = (m * 10f64.powi(e)).log10();
                if p <= b as f64 + 1e-9 {
                    pos.push(p);
                    labels.push(label(m, e));
                }
            }
        }
    } else {
        let every = ((b - a) as f64 / 6.0).ceil().max(1.0) as i32;
        for e in (a..=b).filter(|e| (e - a) % every == 0) {
            pos.push(e as f64);
            labels.push(label(1.0, e));
        }
    }
    (pos, labels)
}

/// How a series is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    /// CSS colour.
    pub color: String,
    pub width: f64,
    pub dashed: bool,
    /// Draw a dot at every point (for short series such as optimizer iterations).
    pub dots: bool,
    /// Points `(x, y)`; a non-finite `y` breaks the line (a gap).
    pub points: Vec<(f64, f64)>,
}

impl Series {
    pub fn line(label: &str, color: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.to_string(),
            color: color.to_string(),
            width: 1.8,
            dashed: false,
            dots: false,
            points,
        }
    }
}

/// Linear or logarithmic value axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    Log10,
}

/// A line chart with one x axis and one y axis.
#[derive(Debug, Clone)]
pub struct LineChart {
    pub width: f64,
    pub height: f64,
    /// Drawn above the plot area (small panels); `None` for charts captioned by the page.
    pub title: Option<String>,
    pub x_label: String,
    pub y_label: String,
    pub y_scale: Scale,
    /// Include zero in the (linear) y range.
    pub y_from_zero: bool,
    /// Only integer x ticks (iteration counts).
    pub x_integer: bool,
    pub series: Vec<Series>,
    pub legend: bool,
    /// Font size of tick labels (px); axis labels are one pixel larger.
    pub font: f64,
    /// Unique among the charts of a page (names the clip path); derived from the content
    /// when empty.
    pub id: String,
}

impl LineChart {
    pub fn new(width: f64, height: f64, x_label: &str, y_label: &str) -> LineChart {
        LineChart {
            width,
            height,
            title: None,
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            y_scale: Scale::Linear,
            y_from_zero: false,
            x_integer: false,
            series: Vec::new(),
            legend: true,
            font: 12.0,
            id: String::new(),
        }
    }

    /// The chart as an `<svg>` element.
    pub fn to_svg(&self) -> String {
        let f = self.font;
        let finite = |s: &Series| {
            s.points
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect::<Vec<_>>()
        };
        let all: Vec<(f64, f64)> = self.series.iter().flat_map(finite).collect();
        let (x_lo, x_hi) = min_max(all.iter().map(|p| p.0));
        let (x_lo, x_hi, mut xticks) = if self.x_integer {
            let (a, b, t) = linear_ticks(x_lo, x_hi, 6);
            let step = nice_step(b - a, 6).max(1.0);
            let t = t
                .into_iter()
                .filter(|v| (v / step).fract().abs() < 1e-9 && *v >= 0.0)
                .collect();
            (a.max(0.0), b, t)
        } else {
            // Time axes: exactly the data range, ticks inside it.
            let (a, b, t) = linear_ticks(x_lo, x_hi, 6);
            let inside: Vec<f64> = t
                .into_iter()
                .filter(|v| *v >= x_lo - 1e-9 && *v <= x_hi + 1e-9)
                .collect();
            if x_hi - x_lo > 1e-12 && inside.len() >= 2 {
                (x_lo, x_hi, inside)
            } else {
                let t = linear_ticks(a, b, 6).2;
                (a, b, t)
            }
        };
        if xticks.is_empty() {
            xticks.push(x_lo);
        }
        let x_step = if xticks.len() > 1 {
            xticks[1] - xticks[0]
        } else {
            1.0
        };
        // Value axis.
        let ys = all.iter().map(|p| p.1);
        let (ylo, yhi) = match self.y_scale {
            Scale::Linear => {
                let (a, b) = min_max(ys);
                if self.y_from_zero {
                    (a.min(0.0), b.max(0.0))
                } else {
                    (a, b)
                }
            }
            Scale::Log10 => min_max(ys.filter(|v| *v > 0.0)),
        };
        let target = if self.height < 200.0 { 4 } else { 5 };
        let (y_axis_lo, y_axis_hi, yticks, ylabels): (f64, f64, Vec<f64>, Vec<String>) =
            match self.y_scale {
                Scale::Linear => {
                    let (a, b, t) = linear_ticks(ylo, yhi, target);
                    let step = if t.len() > 1 { t[1] - t[0] } else { 1.0 };
                    let labels = t.iter().map(|v| format_tick(*v, step)).collect();
                    (a, b, t, labels)
                }
                Scale::Log10 => {
                    let (a, b, _) = log_ticks(ylo, yhi);
                    let (pos, labels) = log_axis_ticks(a, b);
                    (a as f64, b as f64, pos, labels)
                }
            };
        let ylabel_width =
            ylabels.iter().map(|l| l.chars().count()).max().unwrap_or(1) as f64 * f * 0.6;
        let left = (ylabel_width + 2.2 * f + 8.0).max(40.0);
        let top = if self.title.is_some() {
            2.2 * f
        } else {
            0.9 * f
        };
        let bottom = 3.3 * f;
        let right = 0.9 * f + 6.0;
        let pw = self.width - left - right;
        let ph = self.height - top - bottom;
        let sx = |x: f64| left + (x - x_lo) / (x_hi - x_lo).max(1e-300) * pw;
        let to_axis = |y: f64| match self.y_scale {
            Scale::Linear => y,
            Scale::Log10 => y.log10(),
        };
        let sy = |v: f64| top + ph - (v - y_axis_lo) / (y_axis_hi - y_axis_lo).max(1e-300) * ph;
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg class="chart" viewBox="0 0 {w} {h}" width="{w}" height="{h}" role="img" font-size="{f}">"#,
            w = self.width,
            h = self.height
        );
        if let Some(t) = &self.title {
            let _ = write!(
                s,
                r#"<title>{}</title><text class="title" x="{:.1}" y="{:.1}" font-size="{:.1}">{}</text>"#,
                escape(t),
                left,
                1.3 * f,
                f + 1.0,
                escape(t)
            );
        } else if !self.y_label.is_empty() {
            let _ = write!(
                s,
                "<title>{} against {}</title>",
                escape(&self.y_label),
                escape(&self.x_label)
            );
        }
        // Grid and tick labels.
        for (v, l) in yticks.iter().zip(&ylabels) {
            let y = sy(*v);
            let _ = write!(
                s,
                r#"<line class="grid" x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}"/><text class="tick" x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                left,
                left + pw,
                left - 5.0,
                y + 0.35 * f,
                escape(l)
            );
        }
        for v in &xticks {
            let x = sx(*v);
            let _ = write!(
                s,
                r#"<line class="grid" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}"/><line class="axis" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}"/><text class="tick" x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                top,
                top + ph,
                top + ph,
                top + ph + 4.0,
                top + ph + 1.3 * f + 3.0,
                escape(&format_tick(*v, x_step))
            );
        }
        // Axes (left and bottom).
        let _ = write!(
            s,
            r#"<path class="axis" d="M{:.1},{:.1}V{:.1}H{:.1}" fill="none"/>"#,
            left,
            top,
            top + ph,
            left + pw
        );
        let _ = write!(
            s,
            r#"<text class="label" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="{:.1}">{}</text>"#,
            left + pw / 2.0,
            self.height - 0.45 * f,
            f + 1.0,
            escape(&self.x_label)
        );
        let _ = write!(
            s,
            r#"<text class="label" transform="translate({:.1},{:.1}) rotate(-90)" text-anchor="middle" font-size="{:.1}">{}</text>"#,
            1.1 * f,
            top + ph / 2.0,
            f + 1.0,
            escape(&self.y_label)
        );
        // Data, clipped to the plot area.
        let clip = if self.id.is_empty() {
            format!("clip-{:x}", fingerprint(&s, &self.series))
        } else {
            format!("clip-{}", self.id)
        };
        let _ = write!(
            s,
            r#"<clipPath id="{clip}"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/></clipPath><g clip-path="url(#{clip})">"#,
            left,
            top - 2.0,
            pw + 2.0,
            ph + 4.0
        );
        for ser in &self.series {
            let mut d = String::new();
            let mut pen_down = false;
            for &(x, y) in &decimate(&ser.points, MAX_DRAWN_POINTS) {
                let ok =
                    x.is_finite() && y.is_finite() && (self.y_scale == Scale::Linear || y > 0.0);
                if !ok {
                    pen_down = false;
                    continue;
                }
                let _ = write!(
                    d,
                    "{}{:.1},{:.1}",
                    if pen_down { "L" } else { "M" },
                    sx(x),
                    sy(to_axis(y))
                );
                pen_down = true;
            }
            let _ = write!(
                s,
                r#"<path d="{d}" fill="none" stroke="{}" stroke-width="{}" stroke-linejoin="round" stroke-linecap="round"{}><title>{}</title></path>"#,
                escape(&ser.color),
                ser.width,
                if ser.dashed {
                    r#" stroke-dasharray="5 4""#
                } else {
                    ""
                },
                escape(&ser.label)
            );
            if ser.dots {
                for &(x, y) in &ser.points {
                    if x.is_finite() && y.is_finite() && (self.y_scale == Scale::Linear || y > 0.0)
                    {
                        let _ = write!(
                            s,
                            r#"<circle cx="{:.1}" cy="{:.1}" r="2.6" fill="{}"/>"#,
                            sx(x),
                            sy(to_axis(y)),
                            escape(&ser.color)
                        );
                    }
                }
            }
        }
        s.push_str("</g>");
        if self.legend && !self.series.is_empty() {
            // One row above the plot area, right-aligned, so that it never hides data.
            let widths: Vec<f64> = self
                .series
                .iter()
                .map(|x| 34.0 + x.label.chars().count() as f64 * f * 0.56)
                .collect();
            let mut x0 = left + pw - widths.iter().sum::<f64>();
            let y = top - 0.75 * f;
            for (ser, w) in self.series.iter().zip(&widths) {
                let _ = write!(
                    s,
                    r#"<line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="{}" stroke-width="{}"{}/><text x="{:.1}" y="{:.1}">{}</text>"#,
                    x0,
                    x0 + 20.0,
                    escape(&ser.color),
                    ser.width.max(2.2),
                    if ser.dashed {
                        r#" stroke-dasharray="5 4""#
                    } else {
                        ""
                    },
                    x0 + 25.0,
                    y + 0.35 * f,
                    escape(&ser.label)
                );
                x0 += w;
            }
        }
        s.push_str("</svg>");
        s
    }
}

/// A grouped horizontal bar chart: one row per category, one bar per group.
#[derive(Debug, Clone)]
pub struct BarChart {
    pub width: f64,
    pub x_label: String,
    pub categories: Vec<String>,
    /// Per group: label and CSS colour.
    pub groups: Vec<(String, String)>,
    /// `values[category][group]`; NaN draws no bar and writes "n/a".
    pub values: Vec<Vec<f64>>,
    pub font: f64,
}

impl BarChart {
    pub fn to_svg(&self) -> String {
        let f = self.font;
        let ng = self.groups.len().max(1);
        let bar = 9.0;
        let row = ng as f64 * bar + 8.0;
        let label_w = self
            .categories
            .iter()
            .map(|c| c.chars().count())
            .max()
            .unwrap_or(4) as f64
            * f
            * 0.58;
        let left = label_w + 14.0;
        let right = 4.0 * f;
        let top = 1.8 * f + 6.0;
        let bottom = 3.2 * f;
        let ph = self.categories.len() as f64 * row;
        let height = top + ph + bottom;
        let pw = self.width - left - right;
        let hi = self
            .values
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let (_, x_hi, ticks) = linear_ticks(0.0, hi.max(1e-9), 6);
        let step = if ticks.len() > 1 {
            ticks[1] - ticks[0]
        } else {
            1.0
        };
        let sx = |v: f64| left + v / x_hi * pw;
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg class="chart" viewBox="0 0 {w} {h:.1}" width="{w}" height="{h:.1}" role="img" font-size="{f}"><title>{}</title>"#,
            escape(&self.x_label),
            w = self.width,
            h = height
        );
        // Legend on top.
        let mut lx = left;
        for (label, color) in &self.groups {
            let _ = write!(
                s,
                r#"<rect x="{lx:.1}" y="{:.1}" width="12" height="{bar}" fill="{}"/><text x="{:.1}" y="{:.1}">{}</text>"#,
                1.0 * f - bar / 2.0 + 1.0,
                escape(color),
                lx + 17.0,
                1.0 * f + 0.35 * f + 1.0,
                escape(label)
            );
            lx += 30.0 + label.chars().count() as f64 * f * 0.56;
        }
        for v in &ticks {
            let x = sx(*v);
            let _ = write!(
                s,
                r#"<line class="grid" x1="{x:.1}" y1="{top:.1}" x2="{x:.1}" y2="{:.1}"/><text class="tick" x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                top + ph,
                top + ph + 1.3 * f + 3.0,
                escape(&format_tick(*v, step))
            );
        }
        for (c, name) in self.categories.iter().enumerate() {
            let y0 = top + c as f64 * row + 4.0;
            if c % 2 == 1 {
                let _ = write!(
                    s,
                    r#"<rect class="band" x="0" y="{:.1}" width="{:.1}" height="{row:.1}"/>"#,
                    y0 - 4.0,
                    left + pw
                );
            }
            let _ = write!(
                s,
                r#"<text class="tick" x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                left - 6.0,
                y0 + ng as f64 * bar / 2.0 + 0.35 * f,
                escape(name)
            );
            for (g, (label, color)) in self.groups.iter().enumerate() {
                let v = self.values.get(c).and_then(|r| r.get(g)).copied();
                let y = y0 + g as f64 * bar;
                match v {
                    Some(v) if v.is_finite() => {
                        let _ = write!(
                            s,
                            r#"<rect x="{left:.1}" y="{y:.1}" width="{:.1}" height="{:.1}" fill="{}"><title>{}: {} {:.2}</title></rect><text class="value" x="{:.1}" y="{:.1}">{:.1}</text>"#,
                            (sx(v) - left).max(0.5),
                            bar - 1.0,
                            escape(color),
                            escape(name),
                            escape(label),
                            v,
                            sx(v) + 3.0,
                            y + bar - 1.5,
                            v
                        );
                    }
                    _ => {
                        let _ = write!(
                            s,
                            r#"<text class="value" x="{:.1}" y="{:.1}">n/a</text>"#,
                            left + 3.0,
                            y + bar - 1.5
                        );
                    }
                }
            }
        }
        let _ = write!(
            s,
            r#"<path class="axis" d="M{left:.1},{top:.1}V{:.1}H{:.1}" fill="none"/><text class="label" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="{:.1}">{}</text></svg>"#,
            top + ph,
            left + pw,
            left + pw / 2.0,
            height - 0.45 * f,
            f + 1.0,
            escape(&self.x_label)
        );
        s
    }
}

/// Series longer than this are drawn through [`decimate`] (a few pixels per point at most).
pub const MAX_DRAWN_POINTS: usize = 2000;

/// At most about `max` points that keep the visual envelope of `points`: consecutive
/// buckets each keep their first point, minimum and maximum (in x order), and a bucket with a
/// gap (non-finite y) keeps the gap so that lines still break there.
pub fn decimate(points: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max || max < 6 {
        return points.to_vec();
    }
    let buckets = max / 3;
    let size = points.len().div_ceil(buckets);
    let mut out = Vec::with_capacity(3 * buckets + 1);
    for chunk in points.chunks(size) {
        let mut keep: Vec<usize> = vec![0];
        let finite = |i: &usize| chunk[*i].1.is_finite();
        let idx: Vec<usize> = (0..chunk.len()).filter(finite).collect();
        if let (Some(lo), Some(hi)) = (
            idx.iter()
                .min_by(|a, b| chunk[**a].1.total_cmp(&chunk[**b].1)),
            idx.iter()
                .max_by(|a, b| chunk[**a].1.total_cmp(&chunk[**b].1)),
        ) {
            keep.extend([*lo, *hi]);
        }
        if let Some(gap) = (0..chunk.len()).find(|i| !chunk[*i].1.is_finite()) {
            keep.push(gap);
        }
        keep.sort_unstable();
        keep.dedup();
        out.extend(keep.into_iter().map(|i| chunk[i]));
    }
    if let Some(last) = points.last() {
        if out.last() != Some(last) {
            out.push(*last);
        }
    }
    out
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        })
}

/// A short id that differs between charts of one page (clip paths need unique ids).
fn fingerprint(prefix: &str, series: &[Series]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    prefix.hash(&mut h);
    for s in series {
        s.label.hash(&mut h);
        s.points.len().hash(&mut h);
        for (x, y) in s.points.iter().take(64) {
            x.to_bits().hash(&mut h);
            y.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(
            escape(r#"<a href="x">R&L's</a>"#),
            "&lt;a href=&quot;x&quot;&gt;R&amp;L&#39;s&lt;/a&gt;"
        );
        assert_eq!(escape("a\u{1}b"), "a\u{fffd}b");
    }

    #[test]
    fn ticks_are_nice_and_cover_the_range() {
        let (a, b, t) = linear_ticks(0.13, 9.7, 5);
        assert_eq!((a, b), (0.0, 10.0));
        assert_eq!(t, vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let (a, b, t) = linear_ticks(-47.0, 61.0, 5);
        assert!(a <= -47.0 && b >= 61.0);
        assert!(
            t.windows(2).all(|w| (w[1] - w[0] - 20.0).abs() < 1e-9),
            "{t:?}"
        );
        let (a, b, _) = linear_ticks(3.0, 3.0, 5);
        assert!(a < 3.0 && b > 3.0);
        let (a, b, t) = log_ticks(2e-4, 0.3);
        assert_eq!((a, b), (-4, 0));
        assert_eq!(t.len(), 5);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(format_tick(0.5, 0.1), "0.5");
        assert_eq!(format_tick(-0.0, 0.1), "0.0");
        assert_eq!(format_tick(-20.0, 10.0), "\u{2212}20");
        assert_eq!(format_tick(1.25, 0.05), "1.25");
        assert_eq!(power_of_ten(-12), "10⁻¹²");
        assert_eq!(power_of_ten(3), "10³");
    }

    #[test]
    fn line_chart_breaks_at_gaps_and_escapes_labels() {
        let mut c = LineChart::new(400.0, 250.0, "time (s)", "error <mm>");
        c.series.push(Series::line(
            "a&b",
            "#123456",
            vec![(0.0, 1.0), (1.0, f64::NAN), (2.0, 3.0), (3.0, 4.0)],
        ));
        let svg = c.to_svg();
        assert!(svg.contains("error &lt;mm&gt;"));
        assert!(svg.contains("a&amp;b"));
        assert!(!svg.contains("a&b"));
        // Two sub-paths: one starting at the first point, one at the third.
        let path = svg.split(r##"stroke="#123456""##).next().unwrap();
        let d = path.rsplit("d=\"").next().unwrap();
        assert_eq!(d.matches('M').count(), 2, "{d}");
    }

    #[test]
    fn decimation_keeps_envelope_and_gaps() {
        let pts: Vec<(f64, f64)> = (0..100_000)
            .map(|i| {
                let x = i as f64 * 1e-3;
                let y = if (50_000..50_010).contains(&i) {
                    f64::NAN
                } else {
                    (x * 3.0).sin() + if i == 77_777 { 5.0 } else { 0.0 }
                };
                (x, y)
            })
            .collect();
        let d = decimate(&pts, 2000);
        assert!(d.len() <= 2100, "{}", d.len());
        assert!(d.iter().any(|p| p.1 == pts[77_777].1), "spike lost");
        assert!(d.iter().any(|p| p.1.is_nan()), "gap lost");
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0), "x order");
        assert_eq!(d.first(), pts.first());
        assert_eq!(d.last(), pts.last());
        let short = vec![(0.0, 1.0), (1.0, 2.0)];
        assert_eq!(decimate(&short, 2000), short);
    }

    #[test]
    fn log_chart_skips_non_positive_values() {
        let mut c = LineChart::new(400.0, 250.0, "iteration", "cost");
        c.y_scale = Scale::Log10;
        c.x_integer = true;
        c.series.push(Series::line(
            "cost",
            "blue",
            vec![(0.0, 1.0), (1.0, 0.0), (2.0, 1e-3)],
        ));
        let svg = c.to_svg();
        // Three decades, plain labels.
        assert!(svg.contains(">0.001<"), "{svg}");
        assert!(svg.contains(">1<"), "{svg}");
        let (pos, labels) = log_axis_ticks(4, 5);
        assert_eq!(labels, ["10000", "20000", "50000", "100000"]);
        assert!((pos[1] - 20000f64.log10()).abs() < 1e-12);
        let (_, labels) = log_axis_ticks(-9, 1);
        assert_eq!(labels, ["10⁻⁹", "10⁻⁷", "10⁻⁵", "10⁻³", "10⁻¹", "10¹"]);
        let (_, labels) = log_axis_ticks(-8, -7);
        assert_eq!(labels[1], "2·10⁻⁸");
    }

    #[test]
    fn bar_chart_has_a_row_per_category() {
        let b = BarChart {
            width: 600.0,
            x_label: "RMS (mm)".into(),
            categories: vec!["R.ASIS".into(), "<toe>".into()],
            groups: vec![("a".into(), "red".into()), ("b".into(), "blue".into())],
            values: vec![vec![3.0, 2.0], vec![f64::NAN, 1.0]],
            font: 12.0,
        };
        let svg = b.to_svg();
        assert!(svg.contains("&lt;toe&gt;"));
        assert_eq!(svg.matches("<rect x=").count() - 2, 3, "{svg}");
        assert!(svg.contains("n/a"));
    }
}
