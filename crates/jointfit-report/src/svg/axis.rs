//! Axis maths: "nice" tick steps (1, 2, 5 × 10ᵏ), linear and log-10 axis ranges and their
//! tick labels (minus sign U+2212, superscript powers of ten).

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

/// Smallest and largest finite value (`(+∞, −∞)` when there is none).
pub(super) fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
