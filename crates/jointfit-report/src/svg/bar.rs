//! Grouped horizontal bar charts: one row per category, one bar per group.

use std::fmt::Write;

use super::axis::{format_tick, linear_ticks};
use super::escape;

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

/// Where things go on a [`BarChart`] (px).
struct Layout {
    font: f64,
    /// Height of one bar.
    bar: f64,
    /// Height of one category (its bars and a gap).
    row: f64,
    left: f64,
    top: f64,
    /// Plot width and height.
    pw: f64,
    ph: f64,
    height: f64,
    /// The value at the right end of the axis, the ticks and their spacing.
    x_hi: f64,
    ticks: Vec<f64>,
    step: f64,
}

impl Layout {
    fn x(&self, v: f64) -> f64 {
        self.left + v / self.x_hi * self.pw
    }
}

impl BarChart {
    pub fn to_svg(&self) -> String {
        let l = self.layout();
        let f = l.font;
        let mut s = String::new();
        let _ = write!(
            s,
            r#"<svg class="chart" viewBox="0 0 {w} {h:.1}" width="{w}" height="{h:.1}" role="img" font-size="{f}"><title>{}</title>"#,
            escape(&self.x_label),
            w = self.width,
            h = l.height
        );
        self.legend(&mut s, &l);
        grid(&mut s, &l);
        for (c, name) in self.categories.iter().enumerate() {
            self.category(&mut s, &l, c, name);
        }
        let (left, top, pw) = (l.left, l.top, l.pw);
        let _ = write!(
            s,
            r#"<path class="axis" d="M{left:.1},{top:.1}V{:.1}H{:.1}" fill="none"/><text class="label" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="{:.1}">{}</text></svg>"#,
            top + l.ph,
            left + pw,
            left + pw / 2.0,
            l.height - 0.45 * f,
            f + 1.0,
            escape(&self.x_label)
        );
        s
    }

    /// Margins from the font and the longest category label; the axis from the largest value.
    fn layout(&self) -> Layout {
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
        Layout {
            font: f,
            bar,
            row,
            left,
            top,
            pw: self.width - left - right,
            ph,
            height: top + ph + bottom,
            x_hi,
            ticks,
            step,
        }
    }

    /// The legend on top: a swatch and the label of each group.
    fn legend(&self, s: &mut String, l: &Layout) {
        let (f, bar) = (l.font, l.bar);
        let mut lx = l.left;
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
    }

    /// One category: its band (every other row), its label and one bar per group ("n/a"
    /// where the value is missing).
    fn category(&self, s: &mut String, l: &Layout, c: usize, name: &str) {
        let (f, bar, row, left) = (l.font, l.bar, l.row, l.left);
        let ng = self.groups.len().max(1);
        let y0 = l.top + c as f64 * row + 4.0;
        if c % 2 == 1 {
            let _ = write!(
                s,
                r#"<rect class="band" x="0" y="{:.1}" width="{:.1}" height="{row:.1}"/>"#,
                y0 - 4.0,
                left + l.pw
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
                        (l.x(v) - left).max(0.5),
                        bar - 1.0,
                        escape(color),
                        escape(name),
                        escape(label),
                        v,
                        l.x(v) + 3.0,
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
}

/// The vertical grid lines and their tick labels.
fn grid(s: &mut String, l: &Layout) {
    let (f, top, ph) = (l.font, l.top, l.ph);
    for v in &l.ticks {
        let x = l.x(*v);
        let _ = write!(
            s,
            r#"<line class="grid" x1="{x:.1}" y1="{top:.1}" x2="{x:.1}" y2="{:.1}"/><text class="tick" x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
            top + ph,
            top + ph + 1.3 * f + 3.0,
            escape(&format_tick(*v, l.step))
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
