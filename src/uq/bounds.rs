//! Bound types shared by every bounding method, and the interval-arithmetic bounds of a surrogate
//! (docs/method.md §3a, §4): `[y] = c_0 + Σ_{i≠0} c_i Π_r R(φ_{i_r})` with crude or exact ranges `R`.
//!
//! Labels (docs/method.md §3): a bound's [`BoundKind`] states its relation to the **surrogate's** range;
//! no method here is a rigorous enclosure of the true model, since truncation and aliasing error
//! are ignored. The [`ErrorEstimate`] beside each bound is how large that ignored error may be.
//! Interval arithmetic here is in ordinary floating point (no directed rounding): enclosure holds
//! up to ~1e-16 relative rounding.
//!
//! Does not: scan (see [`crate::uq::Scanner`]) or use finite differences (see
//! [`crate::uq::taylor`]).

use crate::uq::basis::Family;
use crate::uq::error::UqError;
pub use crate::uq::surrogate::ErrorEstimate;
use crate::uq::surrogate::Surrogate;

/// How a bound relates to the range it estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BoundKind {
    /// Contains the surrogate's range (interval arithmetic, Chebyshev inclusion): an overestimate.
    Outer,
    /// Attained values of the surrogate (scanning): contained in its range, an underestimate.
    Inner,
    /// Neither: the exact range of a linearisation (first-order Taylor). It may be too wide where
    /// the response is flat and too narrow where it curves; no containment either way.
    Approximate,
}

/// A lower and upper bound of one output, labelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// Lower bound, in the output's unit.
    pub lower: f64,
    /// Upper bound, in the output's unit.
    pub upper: f64,
    /// Outer, inner or approximate (relative to the surrogate; see module doc).
    pub kind: BoundKind,
    /// Error estimate beside the bound.
    pub error: ErrorEstimate,
}

impl Bound {
    /// `upper − lower`.
    pub fn width(&self) -> f64 {
        self.upper - self.lower
    }
}

/// Which enclosure `R(φ_n)` of a basis function's range interval arithmetic uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RangeMode {
    /// `[-1, 1]` for every n ≥ 1: the bound is `c_0 ± Σ_{i≠0} |c_i|`.
    Crude,
    /// The exact range: Legendre `[-1, 1]` for odd n and `[min P_n, 1]` for even n ≥ 2; Chebyshev
    /// `[-1, 1]` (so crude = exact for Chebyshev).
    Exact,
}

/// Interval product `[a_lo, a_hi] · [b_lo, b_hi]`.
fn interval_mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let p = [a.0 * b.0, a.0 * b.1, a.1 * b.0, a.1 * b.1];
    (
        p.iter().copied().fold(f64::INFINITY, f64::min),
        p.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// `Σ_t c_t · (prefix · Π_r R(φ_{t_r}))` over a dense sub-tensor `block` whose leading factors
/// multiply to the interval `prefix`; recursive over leading digits (one interval product per
/// term at most, no per-term decode).
fn interval_sum(block: &[f64], ranges: &[(f64, f64)], prefix: (f64, f64)) -> (f64, f64) {
    let m = ranges.len();
    if block.len() == m {
        let (mut lower, mut upper) = (0.0, 0.0);
        for (&c, &range) in block.iter().zip(ranges) {
            let (lo, hi) = interval_mul(prefix, range);
            let (a, b) = (c * lo, c * hi);
            lower += a.min(b);
            upper += a.max(b);
        }
        return (lower, upper);
    }
    let len = block.len() / m;
    block
        .chunks_exact(len)
        .zip(ranges)
        .map(|(sub, &range)| interval_sum(sub, ranges, interval_mul(prefix, range)))
        .fold((0.0, 0.0), |acc, t| (acc.0 + t.0, acc.1 + t.1))
}

/// Interval arithmetic over the surrogate: substitute `ξ_r → [-1, 1]` term by term,
/// `[y] = c_0 + Σ_{i≠0} c_i Π_r R(φ_{i_r})`. Each product term is bounded exactly (distinct
/// variables); the overestimation comes from the sum (dependency effect). Kind: [`BoundKind::Outer`].
///
/// ```
/// use ribbon::uq::{interval_bound, Design, Family, RangeMode, Surrogate, Truncation};
/// // ξ + ξ² = 1/3 + P_1 + 2/3 P_2 (range [−0.25, 2]), docs/method.md §3:
/// let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor)?;
/// let s = Surrogate::from_terms(&design, &[1.0 / 3.0, 1.0, 2.0 / 3.0])?;
/// let crude = interval_bound(&s, RangeMode::Crude)?;
/// assert!((crude.lower + 4.0 / 3.0).abs() < 1e-15 && (crude.upper - 2.0).abs() < 1e-15);
/// let exact = interval_bound(&s, RangeMode::Exact)?;
/// assert!((exact.lower + 1.0).abs() < 1e-15 && (exact.upper - 2.0).abs() < 1e-15);
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
pub fn interval_bound(surrogate: &Surrogate, mode: RangeMode) -> Result<Bound, UqError> {
    let (family, k) = (surrogate.family(), surrogate.order());
    let m = k + 1;
    let ranges = (0..m)
        .map(|n| match (mode, n) {
            (_, 0) => Ok((1.0, 1.0)),
            (RangeMode::Crude, _) => Ok((-1.0, 1.0)),
            (RangeMode::Exact, _) => family.exact_range(n),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (lower, upper) = interval_sum(surrogate.dense_coefficients(), &ranges, (1.0, 1.0));
    Ok(Bound {
        lower,
        upper,
        kind: BoundKind::Outer,
        error: surrogate.error_estimate(),
    })
}

/// The Chebyshev inclusion function (Wu et al. 2013, docs/method.md §4): `c_0 ± Σ_{i≠0} |c_i|` of a
/// Chebyshev surrogate (the same as [`interval_bound`] with either range mode, since the range of
/// every `T_n`, n ≥ 1, is exactly [-1, 1]). Kind: [`BoundKind::Outer`].
///
/// ```
/// use ribbon::uq::{chebyshev_inclusion, Design, Family, Surrogate, Truncation};
/// // ξ + ξ² = 1/2 + T_1 + 1/2 T_2
/// let design = Design::new(Family::Chebyshev, 1, 2, Truncation::Tensor)?;
/// let s = Surrogate::from_terms(&design, &[0.5, 1.0, 0.5])?;
/// let b = chebyshev_inclusion(&s)?;
/// assert_eq!((b.lower, b.upper), (-1.0, 2.0));
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
///
/// Errors: [`UqError::WrongFamily`] for a Legendre surrogate.
pub fn chebyshev_inclusion(surrogate: &Surrogate) -> Result<Bound, UqError> {
    if surrogate.family() != Family::Chebyshev {
        return Err(UqError::WrongFamily {
            what: "the Chebyshev inclusion function",
            expected: Family::Chebyshev,
            got: surrogate.family(),
        });
    }
    interval_bound(surrogate, RangeMode::Crude)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uq::design::{Design, Truncation};

    #[test]
    fn interval_products_are_exact() {
        // 2 P_2(ξ1) P_2(ξ2): each P_2 ∈ [−½, 1] ⇒ product ∈ [−½, 1] ⇒ term ∈ [−1, 2].
        let design = Design::new(Family::Legendre, 2, 2, Truncation::Tensor).unwrap();
        let mut coef = vec![0.0; 9];
        coef[8] = 2.0;
        let s = Surrogate::from_terms(&design, &coef).unwrap();
        let b = interval_bound(&s, RangeMode::Exact).unwrap();
        assert_eq!((b.lower, b.upper), (-1.0, 2.0));
        let crude = interval_bound(&s, RangeMode::Crude).unwrap();
        assert_eq!((crude.lower, crude.upper), (-2.0, 2.0));
        // −3 P_1(ξ1) P_2(ξ2): P_1 P_2 ∈ [−1, 1] ⇒ [−3, 3].
        coef[8] = 0.0;
        coef[5] = -3.0;
        let s = Surrogate::from_terms(&design, &coef).unwrap();
        let b = interval_bound(&s, RangeMode::Exact).unwrap();
        assert_eq!((b.lower, b.upper), (-3.0, 3.0));
        assert_eq!(b.kind, BoundKind::Outer);
    }

    #[test]
    fn chebyshev_inclusion_refuses_legendre() {
        let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor).unwrap();
        let s = Surrogate::from_terms(&design, &[0.0, 1.0, 0.0]).unwrap();
        assert!(matches!(
            chebyshev_inclusion(&s),
            Err(UqError::WrongFamily { .. })
        ));
    }
}
