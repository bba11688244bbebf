//! Forward–backward (zero-phase) application of a [`Sos`] cascade with scipy's edge handling:
//! odd extension and steady-state initial conditions (see the
//! [crate docs](crate)).

use super::{SignalError, Sos};

/// Section states (transposed direct form II, `[z0, z1]` per section) in which the cascade is
/// stationary under a constant unit input: `scipy.signal.sosfilt_zi`. Multiply by the input
/// level to start a pass in steady state.
pub(crate) fn sosfilt_zi(sos: &Sos) -> Vec<[f64; 2]> {
    let mut scale = 1.0;
    sos.sections()
        .iter()
        .map(|s| {
            let (b, a) = (s.b, s.a);
            // Stationary state of one section under unit input: solve (I − Aᵀ) z = B with the
            // companion matrix A of [1, a1, a2], i.e. [[1 + a1, −1], [a2, 1]] z = B.
            let big_b = [b[1] - a[1] * b[0], b[2] - a[2] * b[0]];
            let z0 = (big_b[0] + big_b[1]) / (1.0 + a[1] + a[2]);
            let z1 = big_b[1] - a[2] * z0;
            let zi = [scale * z0, scale * z1];
            scale *= s.dc_gain();
            zi
        })
        .collect()
}

/// One step of the cascade in transposed direct form II (the arithmetic of scipy's `sosfilt`).
#[inline]
fn step(sos: &Sos, state: &mut [[f64; 2]], mut x: f64) -> f64 {
    for (s, z) in sos.sections().iter().zip(state.iter_mut()) {
        let y = s.b[0] * x + z[0];
        z[0] = s.b[1] * x - s.a[1] * y + z[1];
        z[1] = s.b[2] * x - s.a[2] * y;
        x = y;
    }
    x
}

/// Runs the cascade over `x` in place (one causal pass, `scipy.signal.sosfilt`), starting from
/// `state` (one `[z0, z1]` per section) and leaving the final state in it.
///
/// # Panics
/// If `state` does not have one entry per section.
pub(crate) fn sosfilt_in_place(sos: &Sos, x: &mut [f64], state: &mut [[f64; 2]]) {
    assert_eq!(state.len(), sos.sections().len(), "one state per section");
    for v in x.iter_mut() {
        *v = step(sos, state, *v);
    }
}

/// `x` extended by `padlen` samples at each end by point reflection about the end samples
/// (scipy's `odd_ext`): `x[−j] = 2x[0] − x[j]`, `x[n−1+j] = 2x[n−1] − x[n−1−j]`.
///
/// # Errors
/// [`SignalError::TooShort`] unless `x.len() > padlen`.
pub(crate) fn odd_extend(x: &[f64], padlen: usize) -> Result<Vec<f64>, SignalError> {
    let n = x.len();
    if n <= padlen {
        return Err(SignalError::TooShort { len: n, padlen });
    }
    let mut ext = Vec::with_capacity(n + 2 * padlen);
    let (first, last) = (x[0], x[n - 1]);
    ext.extend((1..=padlen).rev().map(|j| 2.0 * first - x[j]));
    ext.extend_from_slice(x);
    ext.extend((1..=padlen).map(|j| 2.0 * last - x[n - 1 - j]));
    Ok(ext)
}

/// Zero-phase filtering with scipy's default padding: `scipy.signal.sosfiltfilt(sos, x)`.
///
/// # Errors
/// [`SignalError::TooShort`] unless `x.len() > sos.default_padlen()`;
/// [`SignalError::NonFinite`] if any sample is NaN or infinite.
pub fn sosfiltfilt(sos: &Sos, x: &[f64]) -> Result<Vec<f64>, SignalError> {
    sosfiltfilt_padlen(sos, x, sos.default_padlen())
}

/// Zero-phase filtering with `padlen` samples of odd extension at each end:
/// `scipy.signal.sosfiltfilt(sos, x, padlen=padlen)`. `padlen = 0` filters without extension.
///
/// # Errors
/// [`SignalError::TooShort`] unless `x.len() > padlen`;
/// [`SignalError::NonFinite`] if any sample is NaN or infinite.
pub(crate) fn sosfiltfilt_padlen(
    sos: &Sos,
    x: &[f64],
    padlen: usize,
) -> Result<Vec<f64>, SignalError> {
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SignalError::NonFinite { index, value });
    }
    let mut ext = odd_extend(x, padlen)?;
    let zi = sosfilt_zi(sos);
    let start =
        |level: f64| -> Vec<[f64; 2]> { zi.iter().map(|z| [z[0] * level, z[1] * level]).collect() };

    let mut state = start(ext[0]);
    sosfilt_in_place(sos, &mut ext, &mut state);

    let mut state = start(ext[ext.len() - 1]);
    for v in ext.iter_mut().rev() {
        *v = step(sos, &mut state, *v);
    }

    ext.truncate(padlen + x.len());
    ext.drain(..padlen);
    Ok(ext)
}
