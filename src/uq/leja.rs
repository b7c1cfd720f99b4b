//! The nested 1-D point sequence of sparse grids: a Leja sequence on [−1, 1]
//! (docs/high-dimension.md §2).
//!
//! Rule: `ξ_0 = 0` (the centre, so the first design point of every sparse grid is the nominal
//! point), then for n ≥ 1 `ξ_n = argmax_{x ∈ [−1, 1]} Π_{j<n} |x − ξ_j|`; a tie (equal maxima up to
//! [`TIE_REL_TOL`], which happens exactly when the product is symmetric) goes to the larger x.
//! The first values: `0, 1, −1, 1/√3, −0.6587066, 0.8392542, −0.8700071, −0.3056133, …` (tests
//! pin them). Every prefix
//! `ξ_0..ξ_k` is unisolvent for degree k, and each degree adds one point: a sparse grid on a
//! downward-closed set Λ has exactly |Λ| points.
//!
//! The maximiser: the product `ω_n(x) = Π_{j<n}(x − ξ_j)` has a simple root at each node and one
//! critical point between consecutive nodes (Rolle, degree count); there `ω_n'/ω_n = Σ_j 1/(x − ξ_j)`
//! is strictly decreasing, so bisection on its sign finds the critical point to the last bit. The
//! ends ±1 are nodes from n = 3 on, so the maximum is at one of these critical points.
//!
//! Does not: build multi-dimensional grids (see [`crate::uq::sparse_grid`]).

use std::sync::OnceLock;

use crate::uq::error::UqError;

/// Number of Leja points available (degrees 0..=63). A sparse grid of degree k in one dimension
/// uses k + 1 of them.
pub const MAX_LEJA_POINTS: usize = 64;

/// Two candidate maxima of `|ω_n|` within this relative distance are a tie (symmetric products
/// give ties that rounding splits at the 1e-16 level; genuine near-ties this close do not occur
/// among the first 64 points — the closest is ~1e-3, checked in the tests).
pub const TIE_REL_TOL: f64 = 1e-10;

/// Bisection of a bracket of width ≤ 2 halves 64 times: below the spacing of doubles near ±1.
const BISECTION_STEPS: usize = 64;

/// The first `n` Leja points (module doc), computed once.
///
/// ```
/// let p = ribbon::uq::leja_points(4)?;
/// assert_eq!(&p[..3], &[0.0, 1.0, -1.0]);
/// assert!((p[3] - 1.0 / 3f64.sqrt()).abs() < 1e-15);
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
///
/// Errors: `n > MAX_LEJA_POINTS` ([`UqError::TooManyPoints`]).
pub fn leja_points(n: usize) -> Result<&'static [f64], UqError> {
    if n > MAX_LEJA_POINTS {
        return Err(UqError::TooManyPoints {
            points: n,
            max: MAX_LEJA_POINTS,
        });
    }
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    Ok(&TABLE.get_or_init(|| compute(MAX_LEJA_POINTS))[..n])
}

/// `log |ω(x)| = Σ_j log |x − ξ_j|` (logs: the product spans many decades for n ≈ 60).
fn log_abs_product(x: f64, nodes: &[f64]) -> f64 {
    nodes.iter().map(|&z| (x - z).abs().ln()).sum()
}

fn compute(count: usize) -> Vec<f64> {
    let mut points = vec![0.0];
    if count > 1 {
        // |x| is maximal at both ends: tie → the larger, +1. Then |x(x − 1)| forces −1.
        points.push(1.0);
    }
    if count > 2 {
        points.push(-1.0);
    }
    let mut sorted = points.clone();
    while points.len() < count {
        sorted.sort_by(f64::total_cmp);
        let mut best: Option<(f64, f64)> = None; // (log|ω|, x)
        for gap in sorted.windows(2) {
            let x = critical_point(gap[0], gap[1], &points);
            let value = log_abs_product(x, &points);
            best = match best {
                None => Some((value, x)),
                Some((v, bx)) => {
                    // Logs: a relative tie of |ω| is an absolute tie of log|ω|.
                    if (value - v).abs() <= TIE_REL_TOL {
                        Some((v.max(value), bx.max(x)))
                    } else if value > v {
                        Some((value, x))
                    } else {
                        Some((v, bx))
                    }
                }
            };
        }
        let x = best.map_or(0.0, |(_, x)| x);
        points.push(x);
        sorted.push(x);
    }
    points
}

/// The root of `Σ_j 1/(x − ξ_j)` strictly between the consecutive nodes `lo < hi` (it is +∞ just
/// right of `lo` and −∞ just left of `hi`, decreasing in between).
fn critical_point(lo: f64, hi: f64, nodes: &[f64]) -> f64 {
    let (mut a, mut b) = (lo, hi);
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            break;
        }
        let s: f64 = nodes.iter().map(|&z| 1.0 / (mid - z)).sum();
        if s > 0.0 {
            a = mid;
        } else {
            b = mid;
        }
    }
    0.5 * (a + b)
}

/// The Lebesgue constant of interpolation at `nodes` on [−1, 1] — the largest sum of the Lagrange
/// basis polynomials' magnitudes, the factor by which interpolation can exceed the best
/// polynomial approximation's error (plus one) — sampled at `samples` equally spaced points.
pub fn lebesgue_constant(nodes: &[f64], samples: usize) -> f64 {
    let last = samples.max(2) - 1;
    (0..=last)
        .map(|i| {
            let x = -1.0 + 2.0 * i as f64 / last as f64;
            (0..nodes.len())
                .map(|j| {
                    nodes
                        .iter()
                        .enumerate()
                        .filter(|&(m, _)| m != j)
                        .map(|(_, &z)| (x - z) / (nodes[j] - z))
                        .product::<f64>()
                        .abs()
                })
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uq::basis::legendre_values;

    /// Bisection to the last bit; the product at a critical point is stationary.
    const POINT_TOL: f64 = 1e-14;

    #[test]
    fn first_points_are_exact() {
        let p = leja_points(MAX_LEJA_POINTS).unwrap();
        assert_eq!(&p[..3], &[0.0, 1.0, -1.0]);
        // |x(x² − 1)| is maximal at ±1/√3 (a tie): the larger.
        assert!((p[3] - 1.0 / 3f64.sqrt()).abs() < POINT_TOL);
        // The next ones have no closed form; pinned to 9 digits (each maximises the product on a
        // fine grid, see below).
        for (got, want) in
            p[4..8]
                .iter()
                .zip([-0.658706594, 0.839254174, -0.870007150, -0.305613329])
        {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        // All distinct, all in [−1, 1].
        let mut sorted = p.to_vec();
        sorted.sort_by(f64::total_cmp);
        assert!(sorted.windows(2).all(|w| w[1] > w[0]));
        assert!(sorted[0] == -1.0 && sorted[MAX_LEJA_POINTS - 1] == 1.0);
        assert!(leja_points(MAX_LEJA_POINTS + 1).is_err());
    }

    #[test]
    fn each_point_maximises_the_product_on_a_fine_grid() {
        let p = leja_points(24).unwrap();
        for n in 3..24 {
            let grid_max = (0..=200_000)
                .map(|i| log_abs_product(-1.0 + 2.0 * i as f64 / 200_000.0, &p[..n]))
                .fold(f64::NEG_INFINITY, f64::max);
            let at_point = log_abs_product(p[n], &p[..n]);
            // The chosen point is at least as good as any grid point (up to rounding).
            assert!(
                at_point >= grid_max - 1e-12,
                "n={n}: {at_point} < {grid_max}"
            );
        }
    }

    #[test]
    fn ties_are_resolved_and_no_near_ties_hide() {
        // The runner-up maximum at every step is either a tie (symmetric product) or clearly
        // smaller: no decision rests on rounding.
        let p = leja_points(MAX_LEJA_POINTS).unwrap();
        let mut closest = f64::INFINITY;
        for n in 3..MAX_LEJA_POINTS {
            let mut sorted = p[..n].to_vec();
            sorted.sort_by(f64::total_cmp);
            let mut values: Vec<f64> = sorted
                .windows(2)
                .map(|g| log_abs_product(critical_point(g[0], g[1], &p[..n]), &p[..n]))
                .collect();
            values.sort_by(|a, b| b.total_cmp(a));
            let gap = values[0] - values[1];
            if gap > TIE_REL_TOL {
                closest = closest.min(gap);
            }
        }
        assert!(closest > 1e-4, "closest non-tie {closest}");
    }

    #[test]
    fn lebesgue_constants_grow_slowly() {
        // Lebesgue constant of interpolation at the first n points, on a fine grid: documented in
        // docs/high-dimension.md §2 (n = 3: 1.25, 5: 1.72, 10: 4.49, 15: 4.62, 20: 8.75, 21: 4.17).
        let p = leja_points(21).unwrap();
        let lebesgue = |n: usize| lebesgue_constant(&p[..n], 20_001);
        let l: Vec<f64> = [3, 5, 10, 15, 20, 21]
            .iter()
            .map(|&n| lebesgue(n))
            .collect();
        eprintln!("Leja Lebesgue constants n = 3, 5, 10, 15, 20, 21: {l:?}");
        assert!(l.iter().all(|&v| v >= 1.0));
        assert!(l[5] < 30.0, "{l:?}");
        // Interpolation is exact for polynomials: P_4 through 5 points.
        let mut pv = [0.0; 5];
        let x = 0.3;
        let value: f64 = (0..5)
            .map(|j| {
                legendre_values(p[j], &mut pv);
                let basis: f64 = (0..5)
                    .filter(|&m| m != j)
                    .map(|m| (x - p[m]) / (p[j] - p[m]))
                    .product();
                pv[4] * basis
            })
            .sum();
        legendre_values(x, &mut pv);
        assert!((value - pv[4]).abs() < 1e-14);
    }
}
