//! Digital Butterworth low-pass design as second-order sections (see the
//! [crate docs](crate) for the math).

use std::f64::consts::PI;

use nalgebra::Complex;

use super::{check_cutoff, check_rate, SignalError};

/// Highest design order [`butter_lowpass`] accepts. Far above anything used on marker data;
/// the bound keeps the overall gain `k ~ (π f_c/f_s)^N` well away from underflow.
pub(crate) const MAX_DESIGN_ORDER: usize = 32;

/// One second-order section `(b0 + b1 z⁻¹ + b2 z⁻²) / (a0 + a1 z⁻¹ + a2 z⁻²)` with `a0 = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Section {
    /// Numerator coefficients `[b0, b1, b2]`.
    pub b: [f64; 3],
    /// Denominator coefficients `[a0, a1, a2]`, `a0 = 1`.
    pub a: [f64; 3],
}

impl Section {
    #[cfg(test)]
    /// The section as a row of scipy's `sos` array: `[b0, b1, b2, a0, a1, a2]`.
    pub(crate) fn to_row(self) -> [f64; 6] {
        let (b, a) = (self.b, self.a);
        [b[0], b[1], b[2], a[0], a[1], a[2]]
    }

    /// Gain at zero frequency, `H(z = 1) = Σb / Σa`.
    pub(crate) fn dc_gain(&self) -> f64 {
        self.b.iter().sum::<f64>() / self.a.iter().sum::<f64>()
    }

    #[cfg(test)]
    /// Response at `z⁻¹ = w`.
    fn response_at(&self, w: Complex<f64>) -> Complex<f64> {
        let num = w * (w * self.b[2] + self.b[1]) + self.b[0];
        let den = w * (w * self.a[2] + self.a[1]) + self.a[0];
        num / den
    }
}

/// A cascade of second-order sections, applied first to last (scipy's `sos` array).
#[derive(Debug, Clone, PartialEq)]
pub struct Sos {
    /// At least one section.
    sections: Vec<Section>,
}

impl Sos {
    pub(crate) fn sections(&self) -> &[Section] {
        &self.sections
    }

    #[cfg(test)]
    /// The sections as rows of scipy's `sos` array, shape (sections, 6).
    pub(crate) fn to_rows(&self) -> Vec<[f64; 6]> {
        self.sections.iter().map(|s| s.to_row()).collect()
    }

    /// scipy's `ntaps` for padding: `2·S + 1` less the number of sections that are really first
    /// order (counted as `min(#{b2 = 0}, #{a2 = 0})`). `N + 1` for a Butterworth design of
    /// order `N`.
    pub(crate) fn ntaps(&self) -> usize {
        let b2_zero = self.sections.iter().filter(|s| s.b[2] == 0.0).count();
        let a2_zero = self.sections.iter().filter(|s| s.a[2] == 0.0).count();
        2 * self.sections.len() + 1 - b2_zero.min(a2_zero)
    }

    /// scipy's default pad length for `sosfiltfilt`: `3·ntaps` samples at each end.
    pub(crate) fn default_padlen(&self) -> usize {
        3 * self.ntaps()
    }

    #[cfg(test)]
    /// Complex frequency response of one pass at `freq_hz` for sampling rate `rate_hz`.
    pub(crate) fn response(&self, freq_hz: f64, rate_hz: f64) -> Complex<f64> {
        let omega = 2.0 * PI * freq_hz / rate_hz;
        let w = Complex::new(omega.cos(), -omega.sin()); // z⁻¹ on the unit circle
        self.sections
            .iter()
            .fold(Complex::new(1.0, 0.0), |h, s| h * s.response_at(w))
    }

    #[cfg(test)]
    /// Magnitude `|H(f)|` of one pass. The forward–backward filter has gain `|H(f)|²`.
    pub(crate) fn gain(&self, freq_hz: f64, rate_hz: f64) -> f64 {
        self.response(freq_hz, rate_hz).norm()
    }

    #[cfg(test)]
    /// Gain at zero frequency (1 for a low-pass, up to rounding).
    pub(crate) fn dc_gain(&self) -> f64 {
        self.sections.iter().map(Section::dc_gain).product()
    }
}

/// Digital Butterworth low-pass of order `order` with cutoff `cutoff_hz` (−3 dB) at sampling rate
/// `rate_hz`, as second-order sections: `scipy.signal.butter(order, cutoff_hz/(rate_hz/2),
/// output='sos')`.
///
/// # Errors
/// [`SignalError::BadRate`] unless `rate_hz` is positive and finite;
/// [`SignalError::BadCutoff`] unless `0 < cutoff_hz < rate_hz/2`;
/// [`SignalError::BadDesignOrder`] unless `1 ≤ order ≤ MAX_DESIGN_ORDER`.
pub(crate) fn butter_lowpass(
    order: usize,
    cutoff_hz: f64,
    rate_hz: f64,
) -> Result<Sos, SignalError> {
    check_rate(rate_hz)?;
    check_cutoff(cutoff_hz, rate_hz)?;
    if !(1..=MAX_DESIGN_ORDER).contains(&order) {
        return Err(SignalError::BadDesignOrder {
            order,
            max: MAX_DESIGN_ORDER,
        });
    }
    // scipy works with the sampling rate normalised to 2 (Nyquist 1): `wn` is the cutoff as a
    // fraction of Nyquist, `warped` the pre-warped analog cutoff (rad/s at that rate).
    let wn = cutoff_hz / (rate_hz / 2.0);
    let fs = 2.0;
    let warped = 2.0 * fs * (PI * wn / fs).tan();
    let fs2 = 2.0 * fs;

    let n = order as f64;
    let mut poles = Vec::with_capacity(order);
    let mut den = Complex::new(1.0, 0.0); // Π (fs2 − s) over the scaled analog poles
    for j in 0..order {
        let m = -n + 1.0 + 2.0 * j as f64;
        let theta = PI * m / (2.0 * n);
        let s = Complex::new(-theta.cos(), -theta.sin()) * warped;
        den *= Complex::new(fs2, 0.0) - s;
        poles.push(div(Complex::new(fs2, 0.0) + s, Complex::new(fs2, 0.0) - s));
    }
    let gain = warped.powf(n) * div(Complex::new(1.0, 0.0), den).re;
    let zeros = vec![-1.0; order];
    Ok(Sos {
        sections: sections_nearest(zeros, poles, gain),
    })
}

/// Complex division by Smith's method (what numpy uses), so that the poles agree with scipy's
/// to the last bit or so.
fn div(x: Complex<f64>, y: Complex<f64>) -> Complex<f64> {
    if y.re.abs() >= y.im.abs() {
        let r = y.im / y.re;
        let d = 1.0 / (y.re + y.im * r);
        Complex::new((x.re + x.im * r) * d, (x.im - x.re * r) * d)
    } else {
        let r = y.re / y.im;
        let d = 1.0 / (y.im + y.re * r);
        Complex::new((x.re * r + x.im) * d, (x.im * r - x.re) * d)
    }
}

/// Pairs poles and real zeros into second-order sections the way `scipy.signal.zpk2sos` does
/// with `pairing='nearest'`, and puts `gain` into the first section's numerator.
///
/// `poles` come in conjugate pairs plus real poles; `zeros` are real and as many as the poles.
/// scipy's two special cases (a lone real pole; a complex pole that must take a complex zero)
/// cannot occur here: after the padding of an odd count with a pole and a zero at the origin
/// there is an even number of real poles, and there are no complex zeros.
fn sections_nearest(mut zeros: Vec<f64>, poles: Vec<Complex<f64>>, gain: f64) -> Vec<Section> {
    debug_assert_eq!(zeros.len(), poles.len());
    let mut poles = poles;
    if poles.len() % 2 == 1 {
        poles.push(Complex::new(0.0, 0.0));
        zeros.push(0.0);
    }
    let n_sections = poles.len() / 2;

    // Like scipy's `_cplxreal`: one pole of each conjugate pair (positive imaginary part), sorted
    // by real part then |imaginary part|, followed by the real poles sorted by value.
    let tol = 100.0 * f64::EPSILON;
    let is_real = |c: &Complex<f64>| c.im.abs() <= tol * c.norm();
    let mut upper: Vec<Complex<f64>> = poles
        .iter()
        .filter(|c| !is_real(c) && c.im > 0.0)
        .copied()
        .collect();
    upper.sort_by(|x, y| {
        x.re.total_cmp(&y.re)
            .then(x.im.abs().total_cmp(&y.im.abs()))
    });
    let mut reals: Vec<f64> = poles.iter().filter(|c| is_real(c)).map(|c| c.re).collect();
    reals.sort_by(f64::total_cmp);
    let mut p: Vec<Complex<f64>> = upper;
    p.extend(reals.iter().map(|&r| Complex::new(r, 0.0)));
    zeros.sort_by(f64::total_cmp);

    // "Worst" pole: closest to the unit circle (first one on ties, like numpy's argmin).
    let worst = |candidates: &mut dyn Iterator<Item = (usize, &Complex<f64>)>| -> usize {
        let mut best = (usize::MAX, f64::INFINITY);
        for (i, c) in candidates {
            let d = (1.0 - c.norm()).abs();
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    };
    let nearest_zero = |zeros: &[f64], to: Complex<f64>| -> usize {
        let mut best = (0, f64::INFINITY);
        for (i, &z) in zeros.iter().enumerate() {
            let d = (Complex::new(z, 0.0) - to).norm();
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    };

    let mut sections = vec![
        Section {
            b: [0.0; 3],
            a: [1.0, 0.0, 0.0],
        };
        n_sections
    ];
    // Fill from the last section backwards, so that the poles nearest the unit circle come last.
    for si in (0..n_sections).rev() {
        let p1 = p.remove(worst(&mut p.iter().enumerate()));
        let p2 = if p1.im == 0.0 {
            let i2 = worst(&mut p.iter().enumerate().filter(|(_, c)| c.im == 0.0));
            p.remove(i2)
        } else {
            p1.conj()
        };
        let z1 = zeros.remove(nearest_zero(&zeros, p1));
        let z2 = zeros.remove(nearest_zero(&zeros, p1));
        // (1 − z1 z⁻¹)(1 − z2 z⁻¹) and (1 − p1 z⁻¹)(1 − p2 z⁻¹), real by construction.
        let a1 = -p1 + -p2;
        let a2 = p1 * p2;
        sections[si] = Section {
            b: [1.0, -z1 + -z2, z1 * z2],
            a: [1.0, a1.re, a2.re],
        };
    }
    debug_assert!(p.is_empty() && zeros.is_empty());
    for b in &mut sections[0].b {
        *b *= gain;
    }
    sections
}
