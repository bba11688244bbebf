//! Low-pass filtering of marker trajectories: Butterworth design and zero-phase application.
//!
//! Reinbolt et al. (2005, doi:10.1016/j.jbiomech.2004.03.031) filtered their marker data with a
//! "fourth-order, zero phase-shift, low pass Butterworth filter with a cutoff frequency of 6 Hz".
//! This crate provides that filter, matching `scipy.signal` to rounding error, and applies it to
//! a [`Trial`](jointfit::trial::Trial) with gaps ([`filter_trial`]).
//!
//! # Design ([`butter_lowpass`])
//!
//! An order-`N` digital Butterworth low-pass with cutoff `f_c` at sampling rate `f_s`, designed
//! as `scipy.signal.butter(N, f_c/(f_s/2), output='sos')` does it:
//!
//! 1. Analog prototype with unit cutoff: no zeros, poles `s_m = −exp(iπm/(2N))` for
//!    `m = −N+1, −N+3, …, N−1` (the left half of the unit circle), gain 1.
//! 2. Pre-warping, so that the digital cutoff lands exactly on `f_c`: with scipy's normalised
//!    sampling rate 2 (Nyquist = 1) and `W_n = f_c/(f_s/2)`, the analog cutoff is
//!    `Ω_c = 2·2·tan(π W_n / 2) = 4·tan(π f_c / f_s)`; poles become `Ω_c s_m`, the gain `Ω_c^N`.
//! 3. Bilinear transform `z = (4 + s)/(4 − s)`: poles `p_m = (4 + Ω_c s_m)/(4 − Ω_c s_m)`, all
//!    `N` zeros at `z = −1` (the zeros at infinity), gain `k = Ω_c^N / Π_m (4 − Ω_c s_m)`.
//!
//! The result satisfies, at digital frequency `f`,
//!
//! ```text
//! |H(f)|² = 1 / (1 + (tan(π f / f_s) / tan(π f_c / f_s))^(2N))
//! ```
//!
//! so `|H(0)| = 1`, `|H(f_c)|² = 1/2` (−3 dB) and `H(f_s/2) = 0`.
//!
//! The transfer function is stored as a cascade of second-order sections ([`Sos`]),
//! `H(z) = Π_j (b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²)`, built as `scipy.signal.zpk2sos`
//! with its default `pairing='nearest'` builds it: the pole closest to the unit circle goes to
//! the last section together with its conjugate (or, if real, the next real pole) and the two
//! zeros nearest to it; repeat towards the first section; the gain `k` multiplies the first
//! section's numerator. An odd order gets an extra pole and zero at the origin so that every
//! section is second order. Matching scipy's order of sections is what makes the coefficients
//! comparable one by one (to ~1e-15); the filtered output does not depend on it beyond rounding.
//!
//! # Zero-phase application ([`sosfiltfilt`])
//!
//! The cascade runs forward over the signal and then backward over the result. In the frequency
//! domain this multiplies the spectrum by `H(f)·conj(H(f)) = |H(f)|²`: real, so no phase shift,
//! and the magnitude response is squared. A design of order `N` run both ways therefore has the
//! stop-band slope of an order-`2N` filter (−12N dB per octave) and gain `1/2` (−6 dB) at the
//! design cutoff.
//!
//! Edges are handled exactly as `scipy.signal.sosfiltfilt` does with its defaults:
//!
//! - *Odd extension*: `padlen` samples are added at each end by point reflection about the end
//!   sample, `x[−j] = 2x[0] − x[j]` and `x[n−1+j] = 2x[n−1] − x[n−1−j]` for `j = 1..=padlen`.
//!   The default is `padlen = 3·ntaps` with `ntaps = 2·S + 1 − min(#{b2 = 0}, #{a2 = 0})` over
//!   the `S` sections, which is `3(N + 1)` for a Butterworth design of order `N`. The signal must
//!   be longer than `padlen` ([`sosfiltfilt_padlen`] takes another `padlen`, like scipy's
//!   `padlen=` argument).
//! - *Initial conditions* (`scipy.signal.sosfilt_zi`): each pass starts with every section in
//!   the steady state it would reach under a constant input equal to the first sample of that
//!   pass. For one section in transposed direct form II with state `(z0, z1)`, a constant input
//!   `u` with output `y = H_j(1)·u` is stationary when `z0 = y − b0 u`, `z1 = b2 u − a2 y`;
//!   scipy obtains the same by solving `(I − Aᵀ) z = b[1:] − a[1:]·b0` with the companion matrix
//!   `A` of the denominator, which for a second-order section gives
//!   `z0 = (B0 + B1)/(1 + a1 + a2)`, `z1 = B1 − a2 z0` with `B = (b1 − a1 b0, b2 − a2 b0)`.
//!   Section `j` sees the input scaled by the DC gains of the sections before it, so its state is
//!   scaled by `Π_{i<j} H_i(1)`.
//!
//! # Which "fourth order"? ([`LowPass`], [`OrderConvention`])
//!
//! Because the double pass doubles the order, "a fourth-order zero phase-shift Butterworth" has
//! two readings, and the paper does not say which one it means:
//!
//! - [`OrderConvention::Effective`] (**the default**): `order` is the order of the zero-phase
//!   result, so a design of order `order/2` is run forward and backward. "Fourth order" is a
//!   second-order design run both ways: 24 dB/octave, −6 dB at the cutoff.
//! - [`OrderConvention::Design`]: `order` is the order of the design that is run both ways, as in
//!   `scipy.signal.sosfiltfilt(butter(4, …))` or MATLAB's `filtfilt(butter(4, …))`: effective
//!   order 8, 48 dB/octave, still −6 dB at the cutoff.
//!
//! We default to the effective-order reading because that is the usual sense of the phrase in
//! the biomechanics literature the paper belongs to: Winter's textbook (Biomechanics and Motor
//! Control of Human Movement) builds the zero-lag filter from a second-order Butterworth passed
//! forward and then backward and treats the result as a fourth-order zero-lag filter, and
//! "fourth-order zero-lag Butterworth" is commonly used in that sense in gait analysis. It is
//! also the milder of the two readings (less overshoot near sharp features). It remains an
//! interpretation: for the other reading set `convention: OrderConvention::Design` (with
//! `order: 4`), which reproduces `sosfiltfilt(butter(4, 6/(f_s/2), output='sos'), x)` to
//! rounding error.
//!
//! ## Winter's cutoff correction (optional, off by default)
//!
//! Since each pass attenuates the cutoff frequency by −3 dB, the double pass leaves `f_c` at
//! −6 dB. Winter's correction raises the design cutoff to `f_d` so that the *combined* response
//! is −3 dB (gain `1/√2`) at the requested `f_c`. With `P = 2` passes of an order-`N` design
//! with cutoff `f_d`, the combined power gain `|H(f_c)|^(2P)` must be `1/2`:
//!
//! ```text
//! (1 + r^(2N))^P = 2,   r = tan(π f_c / f_s) / tan(π f_d / f_s)
//! ⇒ tan(π f_d / f_s) = tan(π f_c / f_s) / C,   C = (2^(1/P) − 1)^(1/(2N))
//! ```
//!
//! `C = (√2 − 1)^(1/4) ≈ 0.802` for a second-order design (Winter's value), `≈ 0.896` for a
//! fourth-order one. Well below Nyquist this is the familiar `f_d ≈ f_c / C`; we apply it in
//! the pre-warped domain (as Robertson & Dowling 2003, J Electromyogr Kinesiol 13:569–573, do),
//! where it is exact for the digital filter. Enable it with `winter_correction: true`. The
//! paper does not mention a correction, so it is off by default.
//!
//! # Gaps ([`filter_trial`])
//!
//! A missing sample (NaN) cannot pass through a recursive filter without spoiling everything
//! after it, and filling gaps is not this module's business. [`filter_trial`] therefore cuts
//! every marker's trajectory into gap-free *stretches* and filters each coordinate of each
//! stretch on its own, as `sosfiltfilt` would filter that stretch alone. Gaps stay missing.
//! A stretch of `L` samples is handled by the [`ShortStretches`] policy in [`LowPass`]:
//!
//! - `L > 3·ntaps` (scipy's default padding fits): filtered exactly as `sosfiltfilt` does.
//! - otherwise, with [`ShortStretches::ReducePadding`] (the default): filtered with
//!   `padlen = L − 1` (the longest padding scipy accepts) as long as that is at least `ntaps`,
//!   i.e. `L ≥ ntaps + 1` (4 samples for the default filter, whose design has order 2, ntaps 3,
//!   default padlen 9); shorter stretches are left raw. With [`ShortStretches::LeaveRaw`],
//!   every stretch that scipy's default padding does not fit is left raw.
//!
//! Raw stretches keep their measured values. The [`FilterReport`] lists, per marker, the
//! filtered stretches with the padding used, the stretches left raw, and the largest
//! displacement (in metres) that filtering caused, so that callers can warn when filtering moves
//! a marker by more than a couple of centimetres (a sign of a wrong cutoff or a bad marker).

mod butterworth;
mod filtfilt;
mod lowpass;
mod trial_filter;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_scipy;

pub use butterworth::Sos;
pub(crate) use butterworth::{butter_lowpass, MAX_DESIGN_ORDER};
pub use filtfilt::sosfiltfilt;
pub(crate) use filtfilt::sosfiltfilt_padlen;
#[cfg(test)]
use filtfilt::{odd_extend, sosfilt_in_place, sosfilt_zi};
#[cfg(test)]
use lowpass::winter_correction_factor;
pub use lowpass::{LowPass, OrderConvention, ShortStretches};
pub use trial_filter::{filter_trial, FilterReport, FilteredStretch, MarkerFilterReport};

use thiserror::Error;

/// Errors of filter design and application.
#[derive(Debug, Error, PartialEq)]
pub enum SignalError {
    #[error("sampling rate must be positive and finite, got {0} Hz")]
    BadRate(f64),
    #[error(
        "cutoff frequency must be positive and below the Nyquist frequency ({nyquist_hz} Hz \
         at {rate_hz} Hz sampling), got {cutoff_hz} Hz"
    )]
    BadCutoff {
        cutoff_hz: f64,
        rate_hz: f64,
        nyquist_hz: f64,
    },
    #[error("Butterworth design order must be between 1 and {max}, got {order}")]
    BadDesignOrder { order: usize, max: usize },
    #[error(
        "effective order {0} is odd; a zero-phase filter from a design run forward and backward \
         has an even effective order (use OrderConvention::Design for an odd design order)"
    )]
    OddEffectiveOrder(usize),
    #[error(
        "signal has {len} samples but zero-phase filtering with padding {padlen} needs more \
         than {padlen}"
    )]
    TooShort { len: usize, padlen: usize },
    #[error("sample {index} is not finite ({value}); split the signal at gaps before filtering")]
    NonFinite { index: usize, value: f64 },
}

/// Checks a sampling rate (Hz).
fn check_rate(rate_hz: f64) -> Result<(), SignalError> {
    if rate_hz.is_finite() && rate_hz > 0.0 {
        Ok(())
    } else {
        Err(SignalError::BadRate(rate_hz))
    }
}

/// Checks a cutoff frequency (Hz) against a (valid) sampling rate: `0 < f_c < f_s/2`.
fn check_cutoff(cutoff_hz: f64, rate_hz: f64) -> Result<(), SignalError> {
    let nyquist_hz = rate_hz / 2.0;
    if cutoff_hz.is_finite() && cutoff_hz > 0.0 && cutoff_hz < nyquist_hz {
        Ok(())
    } else {
        Err(SignalError::BadCutoff {
            cutoff_hz,
            rate_hz,
            nyquist_hz,
        })
    }
}
