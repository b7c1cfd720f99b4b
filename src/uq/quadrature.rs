//! Gauss quadrature rules on [-1, 1]: Gauss–Legendre (weight 1) and Gauss–Chebyshev of the first
//! kind (weight 1/√(1−ξ²)), for 1 to [`MAX_POINTS`] points, nodes in ascending order.
//!
//! Does not: build tensor grids (see [`crate::uq::design`]) or fit anything.

use crate::uq::error::UqError;

/// Largest number of points per rule. The Newton iteration below is accurate to ~1e-15 well past
/// this, but 40 is the range the tests cover (every monomial up to degree 79 integrated exactly).
pub const MAX_POINTS: usize = 40;

/// Newton on a Legendre root stops once a correction is below this (a few ulp of a root in [-1, 1]).
const NEWTON_STEP_TOL: f64 = 4.0 * f64::EPSILON;

/// Safety cap on Newton iterations; from the initial guess below 4–6 iterations suffice for m ≤ 40.
const NEWTON_MAX_ITERATIONS: usize = 100;

/// A quadrature rule on [-1, 1]: `∫ w(ξ) f(ξ) dξ ≈ Σ_j weights[j] · f(nodes[j])`.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussRule {
    nodes: Vec<f64>,
    weights: Vec<f64>,
}

impl GaussRule {
    /// Nodes in ascending order (length = number of points). Symmetric: `nodes[m−1−j] = −nodes[j]`
    /// exactly, and the middle node of an odd rule is exactly 0.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// Weights, one per node (same order).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Always false: a rule has at least one point.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// `Σ_j weights[j] · f(nodes[j])`.
    pub fn integrate(&self, f: impl Fn(f64) -> f64) -> f64 {
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(|(&x, &w)| w * f(x))
            .sum()
    }
}

fn check_points(points: usize) -> Result<(), UqError> {
    if points == 0 {
        return Err(UqError::NoPoints);
    }
    if points > MAX_POINTS {
        return Err(UqError::TooManyPoints {
            points,
            max: MAX_POINTS,
        });
    }
    Ok(())
}

/// `(P_m(x), P_m'(x))` by the three-term recurrence; valid for |x| < 1.
fn legendre_and_derivative(m: usize, x: f64) -> (f64, f64) {
    let (mut p_prev, mut p) = (1.0, x);
    for n in 1..m {
        let nf = n as f64;
        let p_next = ((2.0 * nf + 1.0) * x * p - nf * p_prev) / (nf + 1.0);
        p_prev = p;
        p = p_next;
    }
    // (1 − x²) P_m' = m (P_{m−1} − x P_m)
    let dp = m as f64 * (p_prev - x * p) / (1.0 - x * x);
    (p, dp)
}

/// Gauss–Legendre rule with `points` nodes: exact for polynomials of degree ≤ 2·points − 1 with
/// weight 1 on [-1, 1].
///
/// Nodes are the roots of `P_m`, found by Newton on the three-term recurrence from the guess
/// `cos(π (j − ¼) / (m + ½))`; weights `w_j = 2 / ((1 − ξ_j²) P_m'(ξ_j)²)` (docs/method.md §2).
/// Accurate to ~1e-15 for every `points ≤ MAX_POINTS`.
///
/// ```
/// use ribbon::uq::quadrature::gauss_legendre;
/// let rule = gauss_legendre(3).unwrap();
/// let expected_nodes = [-0.7745966692414834, 0.0, 0.7745966692414834]; // ±√(3/5), 0
/// let expected_weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
/// for j in 0..3 {
///     assert!((rule.nodes()[j] - expected_nodes[j]).abs() < 1e-15);
///     assert!((rule.weights()[j] - expected_weights[j]).abs() < 1e-15);
/// }
/// // exact for degree ≤ 5: ∫ ξ⁴ dξ = 2/5
/// assert!((rule.integrate(|x| x.powi(4)) - 0.4).abs() < 1e-15);
/// ```
pub fn gauss_legendre(points: usize) -> Result<GaussRule, UqError> {
    check_points(points)?;
    let m = points;
    let mut nodes = vec![0.0; m];
    let mut weights = vec![0.0; m];
    // Roots come in ± pairs: compute the positive ones (j = 0 is the largest) and mirror them.
    for j in 0..m / 2 {
        let mut x = (std::f64::consts::PI * (j as f64 + 0.75) / (m as f64 + 0.5)).cos();
        for _ in 0..NEWTON_MAX_ITERATIONS {
            let (p, dp) = legendre_and_derivative(m, x);
            let step = p / dp;
            x -= step;
            if step.abs() <= NEWTON_STEP_TOL {
                break;
            }
        }
        let (_, dp) = legendre_and_derivative(m, x);
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[m - 1 - j] = x;
        nodes[j] = -x;
        weights[m - 1 - j] = w;
        weights[j] = w;
    }
    if m % 2 == 1 {
        // Middle root is exactly 0; P_m'(0) from the recurrence (|x| < 1 so the formula holds).
        let (_, dp) = legendre_and_derivative(m, 0.0);
        nodes[m / 2] = 0.0;
        weights[m / 2] = 2.0 / (dp * dp);
    }
    Ok(GaussRule { nodes, weights })
}

/// Gauss–Chebyshev rule (first kind) with `points` nodes: exact for `∫ f(ξ)/√(1−ξ²) dξ` when `f`
/// has degree ≤ 2·points − 1.
///
/// docs/method.md §4 numbers the nodes `x_j = cos θ_j`, `θ_j = (2j − 1)π/(2m)`, j = 1..m, which runs
/// from +1 down to −1; here they are returned **ascending** (`nodes[j] = cos θ_{m−j}`, 0-based `j`)
/// like every rule in this module. All weights are `π/m`.
///
/// ```
/// use ribbon::uq::quadrature::gauss_chebyshev;
/// let rule = gauss_chebyshev(3).unwrap();
/// let expected = [-0.8660254037844387, 0.0, 0.8660254037844387]; // ±cos(π/6), 0
/// for j in 0..3 {
///     assert!((rule.nodes()[j] - expected[j]).abs() < 1e-15);
///     assert!((rule.weights()[j] - std::f64::consts::PI / 3.0).abs() < 1e-15);
/// }
/// // ∫ ξ² / √(1−ξ²) dξ = π/2
/// assert!((rule.integrate(|x| x * x) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// ```
pub fn gauss_chebyshev(points: usize) -> Result<GaussRule, UqError> {
    check_points(points)?;
    let m = points;
    let mut nodes = vec![0.0; m];
    for j in 0..m / 2 {
        let theta = std::f64::consts::PI * (2 * j + 1) as f64 / (2 * m) as f64;
        let x = theta.cos();
        nodes[m - 1 - j] = x;
        nodes[j] = -x;
    }
    // For odd m the middle node cos(π/2) is exactly 0 (already set).
    let weights = vec![std::f64::consts::PI / m as f64; m];
    Ok(GaussRule { nodes, weights })
}

/// The angles `θ` with `nodes[j] = cos θ[j]` of [`gauss_chebyshev`]`(points)`, same (ascending-node)
/// order: `θ[j] = (2(m − 1 − j) + 1) π / (2m)`. Used to evaluate `T_i(x_j) = cos(i θ_j)` exactly.
pub fn chebyshev_angles(points: usize) -> Result<Vec<f64>, UqError> {
    check_points(points)?;
    let m = points;
    Ok((0..m)
        .map(|j| std::f64::consts::PI * (2 * (m - 1 - j) + 1) as f64 / (2 * m) as f64)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrals of monomials up to degree 79 are O(1); the rules reproduce them to a few ulp each,
    /// summed over up to 40 nodes.
    const QUADRATURE_TOL: f64 = 1e-13;

    #[test]
    fn legendre_integrates_monomials_exactly_up_to_degree_2m_minus_1() {
        for m in 1..=MAX_POINTS {
            let rule = gauss_legendre(m).unwrap();
            for p in 0..2 * m {
                let exact = if p % 2 == 1 {
                    0.0
                } else {
                    2.0 / (p as f64 + 1.0)
                };
                let got = rule.integrate(|x| x.powi(p as i32));
                assert!(
                    (got - exact).abs() < QUADRATURE_TOL,
                    "m = {m}, degree {p}: {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn legendre_weights_sum_to_two_and_nodes_ascend() {
        for m in 1..=MAX_POINTS {
            let rule = gauss_legendre(m).unwrap();
            let sum: f64 = rule.weights().iter().sum();
            assert!((sum - 2.0).abs() < QUADRATURE_TOL, "m = {m}: {sum}");
            assert!(rule.nodes().windows(2).all(|w| w[0] < w[1]), "m = {m}");
            assert!(rule.weights().iter().all(|&w| w > 0.0));
        }
    }

    #[test]
    fn legendre_nodes_are_roots() {
        for m in 1..=MAX_POINTS {
            let rule = gauss_legendre(m).unwrap();
            for &x in rule.nodes() {
                let (p, dp) = legendre_and_derivative(m, x);
                // |P_m| near a root ≈ |P_m'| · |δx|: require |δx| ≲ 1e-15.
                assert!((p / dp).abs() < 1e-15, "m = {m}, x = {x}");
            }
        }
    }

    #[test]
    fn chebyshev_integrates_monomials_exactly_up_to_degree_2m_minus_1() {
        for m in 1..=MAX_POINTS {
            let rule = gauss_chebyshev(m).unwrap();
            // I_p = ∫ ξ^p / √(1−ξ²) dξ: I_0 = π, I_p = I_{p−2} (p − 1)/p, odd p: 0.
            let mut even = std::f64::consts::PI;
            for p in 0..2 * m {
                let exact = if p % 2 == 1 {
                    0.0
                } else {
                    if p > 0 {
                        even *= (p as f64 - 1.0) / p as f64;
                    }
                    even
                };
                let got = rule.integrate(|x| x.powi(p as i32));
                assert!(
                    (got - exact).abs() < QUADRATURE_TOL,
                    "m = {m}, degree {p}: {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn chebyshev_angles_match_nodes() {
        for m in 1..=MAX_POINTS {
            let rule = gauss_chebyshev(m).unwrap();
            let theta = chebyshev_angles(m).unwrap();
            for (x, t) in rule.nodes().iter().zip(&theta) {
                assert!((x - t.cos()).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn refuses_zero_and_too_many_points() {
        assert_eq!(gauss_legendre(0), Err(UqError::NoPoints));
        assert_eq!(
            gauss_chebyshev(MAX_POINTS + 1),
            Err(UqError::TooManyPoints {
                points: MAX_POINTS + 1,
                max: MAX_POINTS
            })
        );
    }
}
