//! Univariate orthogonal bases on ξ ∈ [-1, 1]: Legendre `P_n` and Chebyshev (first kind) `T_n`.
//! Values of all degrees 0..=k at one point (and their first two derivatives) by the three-term
//! recurrences, and the exact range of each basis function on [-1, 1] for interval arithmetic.
//!
//! Does not: evaluate multivariate expansions (see `tensor_contraction.rs` and
//! [`crate::uq::surrogate`]).

use std::sync::OnceLock;

use crate::uq::error::UqError;
pub use crate::uq::family::Family;
use crate::uq::quadrature::{self, GaussRule};

/// Largest polynomial order per dimension: a fit of order k uses k + 1 Gauss points.
pub const MAX_ORDER: usize = quadrature::MAX_POINTS - 1;

/// Bisection on `P_n'` stops when the bracket is this narrow. `P_n` is stationary there, so the
/// error in `min P_n` is O(width²): far below 1e-16.
const CRITICAL_POINT_BRACKET: f64 = 1e-14;

impl Family {
    /// Fills `out[n]` with the n-th basis function at `xi`, for n = 0..out.len().
    pub fn values(self, xi: f64, out: &mut [f64]) {
        match self {
            Family::Legendre => legendre_values(xi, out),
            Family::Chebyshev => chebyshev_values(xi, out),
        }
    }

    /// Fills values, first and second derivatives (d/dξ) of degrees 0..len at `xi`; the three
    /// slices must have the same length.
    pub fn values_and_derivatives(self, xi: f64, v: &mut [f64], d1: &mut [f64], d2: &mut [f64]) {
        match self {
            Family::Legendre => legendre_values_and_derivatives(xi, v, d1, d2),
            Family::Chebyshev => chebyshev_values_and_derivatives(xi, v, d1, d2),
        }
    }

    /// The Gauss rule whose discrete orthogonality makes this family's projection exact:
    /// Gauss–Legendre or Gauss–Chebyshev with `points` nodes (ascending).
    pub fn rule(self, points: usize) -> Result<GaussRule, UqError> {
        match self {
            Family::Legendre => quadrature::gauss_legendre(points),
            Family::Chebyshev => quadrature::gauss_chebyshev(points),
        }
    }

    /// Exact range `(min, max)` of the degree-`n` basis function on [-1, 1].
    ///
    /// Legendre: `(1, 1)` for n = 0, `(−1, 1)` for odd n, `(min P_n, 1)` for even n ≥ 2 (see
    /// [`legendre_min`]). Chebyshev: `(1, 1)` for n = 0, `(−1, 1)` otherwise.
    pub fn exact_range(self, n: usize) -> Result<(f64, f64), UqError> {
        if n == 0 {
            return Ok((1.0, 1.0));
        }
        match self {
            Family::Chebyshev => Ok((-1.0, 1.0)),
            Family::Legendre => Ok((legendre_min(n)?, 1.0)),
        }
    }
}

/// `out[n] = P_n(xi)` for n = 0..out.len().
///
/// ```
/// let mut p = [0.0; 3];
/// ribbon::uq::basis::legendre_values(0.5, &mut p);
/// assert_eq!(p, [1.0, 0.5, -0.125]); // P_2(½) = (3·¼ − 1)/2
/// ```
pub fn legendre_values(xi: f64, out: &mut [f64]) {
    let k = out.len();
    if k == 0 {
        return;
    }
    out[0] = 1.0;
    if k == 1 {
        return;
    }
    out[1] = xi;
    for n in 1..k - 1 {
        let nf = n as f64;
        out[n + 1] = ((2.0 * nf + 1.0) * xi * out[n] - nf * out[n - 1]) / (nf + 1.0);
    }
}

/// `out[n] = T_n(xi)` for n = 0..out.len().
///
/// ```
/// let mut t = [0.0; 4];
/// ribbon::uq::basis::chebyshev_values(0.5, &mut t);
/// assert_eq!(t, [1.0, 0.5, -0.5, -1.0]); // cos(nπ/3)
/// ```
pub fn chebyshev_values(xi: f64, out: &mut [f64]) {
    let k = out.len();
    if k == 0 {
        return;
    }
    out[0] = 1.0;
    if k == 1 {
        return;
    }
    out[1] = xi;
    for n in 1..k - 1 {
        out[n + 1] = 2.0 * xi * out[n] - out[n - 1];
    }
}

/// Legendre values and derivatives. Derivative recurrences (valid at ±1, no division):
/// `P'_{n+1} = P'_{n−1} + (2n+1) P_n`, `P''_{n+1} = P''_{n−1} + (2n+1) P'_n`.
fn legendre_values_and_derivatives(xi: f64, v: &mut [f64], d1: &mut [f64], d2: &mut [f64]) {
    legendre_values(xi, v);
    let k = v.len();
    if k == 0 {
        return;
    }
    d1[0] = 0.0;
    d2[0] = 0.0;
    if k == 1 {
        return;
    }
    d1[1] = 1.0;
    d2[1] = 0.0;
    for n in 1..k - 1 {
        let c = (2 * n + 1) as f64;
        d1[n + 1] = d1[n - 1] + c * v[n];
        d2[n + 1] = d2[n - 1] + c * d1[n];
    }
}

/// Chebyshev values and derivatives, differentiating `T_{n+1} = 2ξ T_n − T_{n−1}`:
/// `T'_{n+1} = 2 T_n + 2ξ T'_n − T'_{n−1}`, `T''_{n+1} = 4 T'_n + 2ξ T''_n − T''_{n−1}`.
fn chebyshev_values_and_derivatives(xi: f64, v: &mut [f64], d1: &mut [f64], d2: &mut [f64]) {
    chebyshev_values(xi, v);
    let k = v.len();
    if k == 0 {
        return;
    }
    d1[0] = 0.0;
    d2[0] = 0.0;
    if k == 1 {
        return;
    }
    d1[1] = 1.0;
    d2[1] = 0.0;
    for n in 1..k - 1 {
        d1[n + 1] = 2.0 * v[n] + 2.0 * xi * d1[n] - d1[n - 1];
        d2[n + 1] = 4.0 * d1[n] + 2.0 * xi * d2[n] - d2[n - 1];
    }
}

/// `min_{ξ ∈ [-1,1]} P_n(ξ)` for n = 0..=[`MAX_ORDER`], computed once.
///
/// Odd n: −1 (at ξ = −1); n = 0: 1. Even n ≥ 2: the smallest value of `P_n` at the n − 1 roots of
/// `P_n'`, each found by bisection between consecutive roots of `P_n` (Rolle: exactly one root of
/// `P_n'` lies between two consecutive roots of `P_n`), accurate to ~1e-16.
///
/// ```
/// use ribbon::uq::basis::legendre_min;
/// assert!((legendre_min(2).unwrap() + 0.5).abs() < 1e-15);
/// assert!((legendre_min(4).unwrap() + 3.0 / 7.0).abs() < 1e-15);
/// assert!((legendre_min(6).unwrap() + 0.41475046038).abs() < 1e-11);
/// ```
pub fn legendre_min(n: usize) -> Result<f64, UqError> {
    if n > MAX_ORDER {
        return Err(UqError::OrderTooLarge {
            order: n,
            max: MAX_ORDER,
        });
    }
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    Ok(TABLE.get_or_init(|| (0..=MAX_ORDER).map(compute_legendre_min).collect())[n])
}

fn compute_legendre_min(n: usize) -> f64 {
    if n == 0 {
        return 1.0;
    }
    if n % 2 == 1 {
        return -1.0;
    }
    let mut v = vec![0.0; n + 1];
    let mut d1 = vec![0.0; n + 1];
    let mut d2 = vec![0.0; n + 1];
    let mut eval = |x: f64| {
        legendre_values_and_derivatives(x, &mut v, &mut d1, &mut d2);
        (v[n], d1[n])
    };
    // n ≤ MAX_ORDER < MAX_POINTS, so the rule exists; the roots of P_n bracket those of P_n'.
    let roots = match quadrature::gauss_legendre(n) {
        Ok(rule) => rule.nodes().to_vec(),
        Err(_) => unreachable!("n <= MAX_ORDER is a valid rule size"),
    };
    let mut min = 1.0_f64;
    for pair in roots.windows(2) {
        let (mut a, mut b) = (pair[0], pair[1]);
        let sign_a = eval(a).1.signum();
        while b - a > CRITICAL_POINT_BRACKET {
            let mid = 0.5 * (a + b);
            if eval(mid).1.signum() == sign_a {
                a = mid;
            } else {
                b = mid;
            }
        }
        min = min.min(eval(0.5 * (a + b)).0);
    }
    min
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/method.md gives min P_n to 11 decimals.
    const TABLE_TOL: f64 = 1e-11;
    /// Recurrence values are exact to a few ulp for the small degrees tested.
    const RECURRENCE_TOL: f64 = 1e-14;

    #[test]
    fn legendre_min_matches_method_table() {
        let table = [
            (2, -0.5),
            (4, -3.0 / 7.0),
            (6, -0.41475046038),
            (8, -0.40969044627),
            (10, -0.40727622900),
        ];
        for (n, expected) in table {
            let got = legendre_min(n).unwrap();
            assert!((got - expected).abs() < TABLE_TOL, "P_{n}: {got}");
        }
        for n in [3, 5, 7, 9] {
            assert_eq!(legendre_min(n).unwrap(), -1.0);
        }
        assert!((legendre_min(2).unwrap() + 0.5).abs() < 1e-15);
        assert!((legendre_min(4).unwrap() + 3.0 / 7.0).abs() < 1e-15);
    }

    #[test]
    fn legendre_min_agrees_with_dense_sampling() {
        let mut v = vec![0.0; MAX_ORDER + 1];
        for n in (2..=MAX_ORDER).step_by(2) {
            let dense = (0..=200_000)
                .map(|i| {
                    legendre_values(-1.0 + 2.0 * i as f64 / 200_000.0, &mut v[..=n]);
                    v[n]
                })
                .fold(f64::INFINITY, f64::min);
            let exact = legendre_min(n).unwrap();
            // Dense sampling can only be ≥ the true minimum; spacing 1e-5 ⇒ error ≲ n⁴·1e-10.
            assert!(exact <= dense + 1e-15, "n = {n}");
            assert!(dense - exact < 1e-6, "n = {n}: {dense} vs {exact}");
        }
        assert_eq!(
            legendre_min(MAX_ORDER + 1),
            Err(UqError::OrderTooLarge {
                order: MAX_ORDER + 1,
                max: MAX_ORDER
            })
        );
    }

    #[test]
    fn closed_forms_and_endpoint_values() {
        let mut p = [0.0; 5];
        let mut t = [0.0; 5];
        for &x in &[-1.0, -0.3, 0.0, 0.7, 1.0] {
            legendre_values(x, &mut p);
            chebyshev_values(x, &mut t);
            let p4 = (35.0 * x.powi(4) - 30.0 * x * x + 3.0) / 8.0;
            assert!((p[4] - p4).abs() < RECURRENCE_TOL);
            let t4 = 8.0 * x.powi(4) - 8.0 * x * x + 1.0;
            assert!((t[4] - t4).abs() < RECURRENCE_TOL);
        }
        legendre_values(-1.0, &mut p);
        assert_eq!(p, [1.0, -1.0, 1.0, -1.0, 1.0]);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        const H: f64 = 1e-5;
        // Central differences: error O(H²)·|f'''| ≈ 1e-10 · 10⁴ for degree 8, plus rounding 1e-16/H.
        const FD_TOL: f64 = 1e-5;
        for family in [Family::Legendre, Family::Chebyshev] {
            let k = 9;
            let (mut v, mut d1, mut d2) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
            let (mut vp, mut vm) = (vec![0.0; k], vec![0.0; k]);
            let (mut d1p, mut d1m, mut scratch) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
            for &x in &[-1.0 + H, -0.4, 0.1, 0.9, 1.0 - H] {
                family.values_and_derivatives(x, &mut v, &mut d1, &mut d2);
                family.values_and_derivatives(x + H, &mut vp, &mut d1p, &mut scratch);
                family.values_and_derivatives(x - H, &mut vm, &mut d1m, &mut scratch);
                for n in 0..k {
                    let fd1 = (vp[n] - vm[n]) / (2.0 * H);
                    let fd2 = (d1p[n] - d1m[n]) / (2.0 * H);
                    assert!((fd1 - d1[n]).abs() < FD_TOL, "{family:?} n={n} x={x}");
                    assert!((fd2 - d2[n]).abs() < FD_TOL * 10.0, "{family:?} n={n}");
                }
            }
            // Endpoint identities: P_n'(1) = n(n+1)/2, T_n'(1) = n².
            family.values_and_derivatives(1.0, &mut v, &mut d1, &mut d2);
            for (n, &slope) in d1.iter().enumerate() {
                let nf = n as f64;
                let expected = match family {
                    Family::Legendre => nf * (nf + 1.0) / 2.0,
                    Family::Chebyshev => nf * nf,
                };
                assert!((slope - expected).abs() < RECURRENCE_TOL * 100.0);
            }
        }
    }

    #[test]
    fn exact_ranges() {
        assert_eq!(Family::Legendre.exact_range(0).unwrap(), (1.0, 1.0));
        assert_eq!(Family::Legendre.exact_range(3).unwrap(), (-1.0, 1.0));
        assert_eq!(Family::Legendre.exact_range(2).unwrap(), (-0.5, 1.0));
        assert_eq!(Family::Chebyshev.exact_range(2).unwrap(), (-1.0, 1.0));
    }
}
