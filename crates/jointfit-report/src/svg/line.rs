//! Line charts with one x axis and a linear or log-10 y axis; non-finite values break the
//! line, long series are decimated to their visual envelope.

use std::fmt::Write;

use super::axis::{format_tick, linear_ticks, log_axis_ticks, log_ticks, min_max, nice_step};
use super::escape;

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
        let fr = self.frame();
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg class="chart" viewBox="0 0 {w} {h}" width="{w}" height="{h}" role="img" font-size="{f}">"#,
            w = self.width,
            h = self.height,
            f = self.font
        );
        self.title_element(&mut s, &fr);
        self.grid_and_axes(&mut s, &fr);
        self.data(&mut s, &fr);
        if self.legend && !self.series.is_empty() {
            self.legend_row(&mut s, &fr);
        }
        s.push_str("</svg>");
        s
    }

    /// The x axis: its range and ticks (integer ticks from zero for iteration counts;
    /// exactly the data range with ticks inside it for time axes) and the tick spacing.
    fn x_axis(&self, all: &[(f64, f64)]) -> (f64, f64, Vec<f64>, f64) {
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
        (x_lo, x_hi, xticks, x_step)
    }

    /// The value axis in axis units (log10 of the value on a log axis): its range, tick
    /// positions and tick labels.
    fn y_axis(&self, all: &[(f64, f64)]) -> (f64, f64, Vec<f64>, Vec<String>) {
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
        }
    }

    /// Both axes and the plot area's place, from the finite points of every series.
    fn frame(&self) -> Frame {
        let f = self.font;
        let all: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        let (x_lo, x_hi, xticks, x_step) = self.x_axis(&all);
        let (y_lo, y_hi, yticks, ylabels) = self.y_axis(&all);
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
        Frame {
            f,
            left,
            top,
            pw: self.width - left - right,
            ph: self.height - top - bottom,
            x_lo,
            x_hi,
            xticks,
            x_step,
            y_lo,
            y_hi,
            yticks,
            ylabels,
            scale: self.y_scale,
        }
    }

    /// The chart's `<title>` (and the drawn title of a small panel).
    fn title_element(&self, s: &mut String, fr: &Frame) {
        let f = fr.f;
        if let Some(t) = &self.title {
            let _ = write!(
                s,
                r#"<title>{}</title><text class="title" x="{:.1}" y="{:.1}" font-size="{:.1}">{}</text>"#,
                escape(t),
                fr.left,
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
    }

    /// Grid lines with their tick labels, the left and bottom axes and their labels.
    fn grid_and_axes(&self, s: &mut String, fr: &Frame) {
        let (f, left, top, pw, ph) = (fr.f, fr.left, fr.top, fr.pw, fr.ph);
        for (v, l) in fr.yticks.iter().zip(&fr.ylabels) {
            let y = fr.sy(*v);
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
        for v in &fr.xticks {
            let x = fr.sx(*v);
            let _ = write!(
                s,
                r#"<line class="grid" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}"/><line class="axis" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}"/><text class="tick" x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                top,
                top + ph,
                top + ph,
                top + ph + 4.0,
                top + ph + 1.3 * f + 3.0,
                escape(&format_tick(*v, fr.x_step))
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
    }

    /// Each series as a path (broken at gaps, dots where asked), clipped to the plot area;
    /// the clip path is named by the chart's id, else by a fingerprint of what `s` holds.
    fn data(&self, s: &mut String, fr: &Frame) {
        let clip = if self.id.is_empty() {
            format!("clip-{:x}", fingerprint(s, &self.series))
        } else {
            format!("clip-{}", self.id)
        };
        let _ = write!(
            s,
            r#"<clipPath id="{clip}"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/></clipPath><g clip-path="url(#{clip})">"#,
            fr.left,
            fr.top - 2.0,
            fr.pw + 2.0,
            fr.ph + 4.0
        );
        for ser in &self.series {
            let mut d = String::new();
            let mut pen_down = false;
            for &(x, y) in &decimate(&ser.points, MAX_DRAWN_POINTS) {
                if !fr.drawable(x, y) {
                    pen_down = false;
                    continue;
                }
                let _ = write!(
                    d,
                    "{}{:.1},{:.1}",
                    if pen_down { "L" } else { "M" },
                    fr.sx(x),
                    fr.sy(fr.to_axis(y))
                );
                pen_down = true;
            }
            let _ = write!(
                s,
                r#"<path d="{d}" fill="none" stroke="{}" stroke-width="{}" stroke-linejoin="round" stroke-linecap="round"{}><title>{}</title></path>"#,
                escape(&ser.color),
                ser.width,
                dash(ser),
                escape(&ser.label)
            );
            if ser.dots {
                for &(x, y) in ser.points.iter().filter(|&&(x, y)| fr.drawable(x, y)) {
                    let _ = write!(
                        s,
                        r#"<circle cx="{:.1}" cy="{:.1}" r="2.6" fill="{}"/>"#,
                        fr.sx(x),
                        fr.sy(fr.to_axis(y)),
                        escape(&ser.color)
                    );
                }
            }
        }
        s.push_str("</g>");
    }

    /// The legend: one row above the plot area, right-aligned, so that it never hides data.
    fn legend_row(&self, s: &mut String, fr: &Frame) {
        let f = fr.f;
        let widths: Vec<f64> = self
            .series
            .iter()
            .map(|x| 34.0 + x.label.chars().count() as f64 * f * 0.56)
            .collect();
        let mut x0 = fr.left + fr.pw - widths.iter().sum::<f64>();
        let y = fr.top - 0.75 * f;
        for (ser, w) in self.series.iter().zip(&widths) {
            let _ = write!(
                s,
                r#"<line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="{}" stroke-width="{}"{}/><text x="{:.1}" y="{:.1}">{}</text>"#,
                x0,
                x0 + 20.0,
                escape(&ser.color),
                ser.width.max(2.2),
                dash(ser),
                x0 + 25.0,
                y + 0.35 * f,
                escape(&ser.label)
            );
            x0 += w;
        }
    }
}

/// The dash attribute of a dashed series (empty for a solid one).
fn dash(ser: &Series) -> &'static str {
    if ser.dashed {
        r#" stroke-dasharray="5 4""#
    } else {
        ""
    }
}

/// The plot area of a [`LineChart`] (px) and its two axes.
struct Frame {
    f: f64,
    left: f64,
    top: f64,
    /// Plot width and height.
    pw: f64,
    ph: f64,
    x_lo: f64,
    x_hi: f64,
    xticks: Vec<f64>,
    x_step: f64,
    /// The value axis in axis units (log10 of the value on a log axis).
    y_lo: f64,
    y_hi: f64,
    yticks: Vec<f64>,
    ylabels: Vec<String>,
    scale: Scale,
}

impl Frame {
    fn sx(&self, x: f64) -> f64 {
        self.left + (x - self.x_lo) / (self.x_hi - self.x_lo).max(1e-300) * self.pw
    }

    fn sy(&self, v: f64) -> f64 {
        self.top + self.ph - (v - self.y_lo) / (self.y_hi - self.y_lo).max(1e-300) * self.ph
    }

    fn to_axis(&self, y: f64) -> f64 {
        match self.scale {
            Scale::Linear => y,
            Scale::Log10 => y.log10(),
        }
    }

    /// A point that can be drawn: finite, and positive on a log axis.
    fn drawable(&self, x: f64, y: f64) -> bool {
        x.is_finite() && y.is_finite() && (self.scale == Scale::Linear || y > 0.0)
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
    use crate::svg::axis::log_axis_ticks;

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
}
