//! Small SVG charts written by hand: line charts (linear or log-10 value axis) and grouped
//! horizontal bar charts, with ticks at "nice" values (1, 2, 5 × 10ᵏ), grid lines, axis labels
//! and legends.
//!
//! The output is inline SVG for an HTML page: no `xmlns`, no scripts, no external fonts or
//! images; colours and fonts come from attributes and from the page's CSS classes `grid`, `axis`,
//! `tick`, `label`, `title`, `band` and `value` (see [`crate::html`]). All text goes through
//! [`escape`].
//!
//! * [`axis`] holds tick steps, axis ranges and tick labels;
//! * [`line`] holds [`LineChart`] and [`decimate`];
//! * [`bar`] holds [`BarChart`].

pub mod axis;
pub mod bar;
pub mod line;

pub use axis::{format_tick, linear_ticks, log_axis_ticks, log_ticks, nice_step, power_of_ten};
pub use bar::BarChart;
pub use jointfit_io::xml::escape;
pub use line::{decimate, LineChart, Scale, Series, MAX_DRAWN_POINTS};
