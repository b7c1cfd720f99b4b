//! The comparison error of docs/method.md §4 between an envelope and a reference envelope over time:
//!
//! `e(t) = max(|lower − lower_ref|, |upper − upper_ref|) / max(w_ref(t), 1e-3 · max_t w_ref)`,
//! `w_ref = upper_ref − lower_ref`, reported as max and mean over time (per output).
//!
//! Does not: decide which envelope is the reference, or interpolate between time grids (both
//! series must share the record times).

use crate::uq::error::UqError;

/// Fraction of the largest reference width below which the denominator is floored, so that times
/// where the reference has zero width (t = 0 of a fixed initial state) stay meaningful
/// (docs/method.md §4).
pub const WIDTH_FLOOR_FRACTION: f64 = 1e-3;

/// Error of one output's envelope against the reference, over time.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeError {
    /// `e(t)` at every record time (dimensionless; 0.01 = 1 % of the reference width).
    pub per_time: Vec<f64>,
    /// `max_t e(t)`.
    pub max: f64,
    /// `mean_t e(t)`.
    pub mean: f64,
    /// First time index where the maximum occurs.
    pub argmax: usize,
    /// `max_t max(|lower − lower_ref|, |upper − upper_ref|)`, in the output's unit.
    pub max_abs: f64,
    /// The largest share of the reference's range the envelope misses, `max_t max(lower −
    /// lower_ref, upper_ref − upper, 0)` over the same denominator as `e(t)`: against a reference
    /// made of true runs (an inner bound) this is the part of the error that is certainly wrong,
    /// where `e(t)` also counts an envelope wider than runs the reference happened to make.
    pub max_missed: f64,
}

/// Computes [`EnvelopeError`] from four equally long time series.
///
/// ```
/// use ribbon::uq::envelope_error;
/// // reference widths 0, 2, 4 (floor 4e-3); deviations 0, 0.25, 0.5.
/// let (lower, upper) = ([0.0, -1.25, -2.0], [0.0, 1.0, 2.5]);
/// let (lower_ref, upper_ref) = ([0.0, -1.0, -2.0], [0.0, 1.0, 2.0]);
/// let e = envelope_error(&lower, &upper, &lower_ref, &upper_ref)?;
/// assert_eq!(e.per_time, vec![0.0, 0.125, 0.125]);
/// assert_eq!((e.max, e.argmax, e.max_abs), (0.125, 1, 0.5));
/// // Only the upper side at t = 2 is wider; the lower side at t = 1 is wider too: nothing missed.
/// assert_eq!(e.max_missed, 0.0);
/// assert!((e.mean - 0.25 / 3.0).abs() < 1e-15);
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
///
/// Errors: series of different lengths or empty; a non-finite entry; a reference with
/// `upper < lower` at some time; a reference of zero width at every time
/// ([`UqError::ZeroReferenceWidth`]: the relative error is undefined — compare absolute errors).
pub fn envelope_error(
    lower: &[f64],
    upper: &[f64],
    lower_ref: &[f64],
    upper_ref: &[f64],
) -> Result<EnvelopeError, UqError> {
    let n = lower.len();
    if n == 0 {
        return Err(UqError::Empty {
            what: "envelope_error: series",
        });
    }
    for (what, s) in [
        ("envelope_error: upper", upper),
        ("envelope_error: lower_ref", lower_ref),
        ("envelope_error: upper_ref", upper_ref),
    ] {
        if s.len() != n {
            return Err(UqError::WrongLength {
                what,
                expected: n,
                got: s.len(),
            });
        }
    }
    for (what, s) in [
        ("envelope_error: lower", lower),
        ("envelope_error: upper", upper),
        ("envelope_error: lower_ref", lower_ref),
        ("envelope_error: upper_ref", upper_ref),
    ] {
        if let Some(index) = s.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what,
                index,
                value: s[index],
            });
        }
    }
    let mut max_width: f64 = 0.0;
    for (index, (&lo, &hi)) in lower_ref.iter().zip(upper_ref).enumerate() {
        if hi < lo {
            return Err(UqError::InvertedReference {
                index,
                lower: lo,
                upper: hi,
            });
        }
        max_width = max_width.max(hi - lo);
    }
    if max_width == 0.0 {
        return Err(UqError::ZeroReferenceWidth);
    }
    let floor = WIDTH_FLOOR_FRACTION * max_width;
    let mut per_time = Vec::with_capacity(n);
    let mut max_abs: f64 = 0.0;
    let mut max_missed: f64 = 0.0;
    for t in 0..n {
        let deviation = (lower[t] - lower_ref[t])
            .abs()
            .max((upper[t] - upper_ref[t]).abs());
        max_abs = max_abs.max(deviation);
        let denominator = (upper_ref[t] - lower_ref[t]).max(floor);
        per_time.push(deviation / denominator);
        let missed = (lower[t] - lower_ref[t])
            .max(upper_ref[t] - upper[t])
            .max(0.0);
        max_missed = max_missed.max(missed / denominator);
    }
    let (argmax, max) =
        per_time
            .iter()
            .copied()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (t, e)| {
                if e > best.1 {
                    (t, e)
                } else {
                    best
                }
            });
    let mean = per_time.iter().sum::<f64>() / n as f64;
    Ok(EnvelopeError {
        per_time,
        max,
        mean,
        argmax,
        max_abs,
        max_missed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_applies_at_zero_width() {
        // t = 0: reference width 0, floor 1e-3 · 2 = 2e-3; deviation 1e-3 ⇒ e = 0.5.
        let e = envelope_error(&[0.001, -1.0], &[0.0, 1.0], &[0.0, -1.0], &[0.0, 1.0]).unwrap();
        assert!((e.per_time[0] - 0.5).abs() < 1e-15);
        assert_eq!(e.per_time[1], 0.0);
        assert_eq!(e.argmax, 0);
        assert!((e.max_abs - 0.001).abs() < 1e-18);
    }

    #[test]
    fn refuses_bad_series() {
        assert!(matches!(
            envelope_error(&[0.0], &[0.0], &[0.0], &[0.0]),
            Err(UqError::ZeroReferenceWidth)
        ));
        assert!(matches!(
            envelope_error(&[0.0], &[0.0], &[1.0], &[0.0]),
            Err(UqError::InvertedReference { index: 0, .. })
        ));
        assert!(matches!(
            envelope_error(&[0.0, 1.0], &[0.0], &[0.0], &[1.0]),
            Err(UqError::WrongLength { .. })
        ));
        assert!(matches!(
            envelope_error(&[], &[], &[], &[]),
            Err(UqError::Empty { .. })
        ));
        assert!(matches!(
            envelope_error(&[0.0], &[f64::NAN], &[0.0], &[1.0]),
            Err(UqError::NonFinite { .. })
        ));
    }
}
