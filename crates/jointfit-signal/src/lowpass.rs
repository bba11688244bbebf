//! The filter as the user specifies it: cutoff, order and what the order means (see the
//! [crate docs](crate) for the two conventions and Winter's correction).

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

#[cfg(test)]
use super::sosfiltfilt;
use super::{butter_lowpass, check_cutoff, check_rate, SignalError, Sos, MAX_DESIGN_ORDER};

/// What [`LowPass::order`] counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OrderConvention {
    /// `order` is the order of the zero-phase result: a Butterworth design of order `order/2`
    /// is run forward and backward (`order` must be even). "Fourth order" = a second-order
    /// design run both ways; the biomechanics habit after Winter.
    #[default]
    Effective,
    /// `order` is the order of the design that is run forward and backward, so the zero-phase
    /// result has order `2·order`: `scipy.signal.sosfiltfilt(butter(order, …))`.
    Design,
}

/// What [`filter_trial`](super::filter_trial) does with a gap-free stretch that is too short for
/// scipy's default padding (`3·ntaps` samples).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShortStretches {
    /// Filter it with the padding reduced to `len − 1` samples (the most scipy's `padlen`
    /// allows) as long as that is at least `ntaps`; leave shorter stretches raw.
    #[default]
    ReducePadding,
    /// Leave it raw.
    LeaveRaw,
}

/// A zero-phase Butterworth low-pass for marker trajectories.
///
/// The default is the paper's filter under the effective-order reading: cutoff 6 Hz, order 4
/// counted as the order of the zero-phase result (a second-order design run forward and
/// backward), no cutoff correction, short stretches filtered with reduced padding.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LowPass {
    /// Cutoff frequency in Hz: −3 dB point of the design (−6 dB of the zero-phase result), or,
    /// with `winter_correction`, −3 dB point of the zero-phase result.
    pub cutoff_hz: f64,
    /// Filter order, counted as `convention` says.
    pub order: usize,
    /// Whether `order` is the effective order of the zero-phase result or the design order.
    pub convention: OrderConvention,
    /// Raise the design cutoff so that the forward–backward result is −3 dB at `cutoff_hz`.
    pub winter_correction: bool,
    /// Treatment of gap-free stretches too short for the default padding.
    pub short_stretches: ShortStretches,
}

impl Default for LowPass {
    fn default() -> Self {
        Self {
            cutoff_hz: 6.0,
            order: 4,
            convention: OrderConvention::Effective,
            winter_correction: false,
            short_stretches: ShortStretches::ReducePadding,
        }
    }
}

/// Winter's correction factor `C = (2^(1/passes) − 1)^(1/(2·design_order))`: a design with
/// pre-warped cutoff `tan(π f_c/f_s)/C`, run `passes` times, is −3 dB at `f_c`.
pub(crate) fn winter_correction_factor(design_order: usize, passes: usize) -> f64 {
    (2f64.powf(1.0 / passes as f64) - 1.0).powf(1.0 / (2.0 * design_order as f64))
}

impl LowPass {
    /// The order of the Butterworth design that is run forward and backward.
    ///
    /// # Errors
    /// [`SignalError::OddEffectiveOrder`] for an odd order under
    /// [`OrderConvention::Effective`]; [`SignalError::BadDesignOrder`] when the design order is
    /// 0 or above [`MAX_DESIGN_ORDER`].
    pub(crate) fn design_order(&self) -> Result<usize, SignalError> {
        let n = match self.convention {
            OrderConvention::Effective if self.order % 2 == 1 => {
                return Err(SignalError::OddEffectiveOrder(self.order))
            }
            OrderConvention::Effective => self.order / 2,
            OrderConvention::Design => self.order,
        };
        if (1..=MAX_DESIGN_ORDER).contains(&n) {
            Ok(n)
        } else {
            Err(SignalError::BadDesignOrder {
                order: n,
                max: MAX_DESIGN_ORDER,
            })
        }
    }

    #[cfg(test)]
    /// The order of the zero-phase result (twice the design order).
    pub(crate) fn effective_order(&self) -> Result<usize, SignalError> {
        Ok(2 * self.design_order()?)
    }

    /// The cutoff of the design in Hz: `cutoff_hz`, or with Winter's correction
    /// `(f_s/π)·atan(tan(π f_c/f_s)/C)`.
    ///
    /// # Errors
    /// [`SignalError::BadRate`], [`SignalError::BadCutoff`] (cutoff not in `(0, f_s/2)`, before
    /// or after the correction), and the errors of [`LowPass::design_order`].
    pub(crate) fn design_cutoff_hz(&self, rate_hz: f64) -> Result<f64, SignalError> {
        check_rate(rate_hz)?;
        check_cutoff(self.cutoff_hz, rate_hz)?;
        let n = self.design_order()?;
        if !self.winter_correction {
            return Ok(self.cutoff_hz);
        }
        let c = winter_correction_factor(n, 2);
        let f = rate_hz / PI * ((PI * self.cutoff_hz / rate_hz).tan() / c).atan();
        check_cutoff(f, rate_hz)?;
        Ok(f)
    }

    /// The Butterworth design (one pass) for sampling rate `rate_hz`.
    ///
    /// # Errors
    /// As [`LowPass::design_cutoff_hz`].
    pub fn design(&self, rate_hz: f64) -> Result<Sos, SignalError> {
        let cutoff = self.design_cutoff_hz(rate_hz)?;
        butter_lowpass(self.design_order()?, cutoff, rate_hz)
    }

    #[cfg(test)]
    /// Filters one gap-free signal sampled at `rate_hz` forward and backward with scipy's
    /// default padding (see [`sosfiltfilt`]).
    ///
    /// # Errors
    /// As [`LowPass::design`] and [`sosfiltfilt`].
    pub(crate) fn apply(&self, x: &[f64], rate_hz: f64) -> Result<Vec<f64>, SignalError> {
        sosfiltfilt(&self.design(rate_hz)?, x)
    }

    /// The padding [`filter_trial`](super::filter_trial) uses for a stretch of `len` samples
    /// filtered with `sos`, or `None` when the stretch is left raw.
    pub(crate) fn padlen_for(&self, sos: &Sos, len: usize) -> Option<usize> {
        let default = sos.default_padlen();
        if len > default {
            return Some(default);
        }
        match self.short_stretches {
            ShortStretches::LeaveRaw => None,
            ShortStretches::ReducePadding => {
                let reduced = len.checked_sub(1)?;
                (reduced >= sos.ntaps()).then_some(reduced)
            }
        }
    }
}
