//! Variance-based (Sobol') sensitivity indices of a polynomial surrogate under uniform ξ on
//! [−1, 1]^d, read off its Legendre coefficients (docs/sobol-indices.md §1–§3), and a Saltelli /
//! Jansen Monte Carlo estimator to check them against (§4).
//!
//! Orthogonality does the work: with `‖P_n‖² = 1/(2n+1)` under the uniform probability, a
//! Legendre expansion's variance is `D = Σ_{α≠0} c_α² Π_r 1/(2α_r+1)`, every term belongs to
//! exactly one ANOVA component (the set of dimensions where `α_r > 0`), so the main index of ξ_j
//! sums the terms in ξ_j alone and the total index every term involving ξ_j. The indices are exact
//! for the surrogate; how well they describe the model is the surrogate's accuracy.
//!
//! A Chebyshev surrogate is first rewritten in the Legendre basis, one dimension at a time (an
//! exact change of basis: `T_n = Σ_{m≤n} a_nm P_m`), so both families give indices under the same
//! uniform measure.
//!
//! Does not: fit (see [`crate::uq::Projector`], [`crate::uq::LinearFit`]); name dimensions (see
//! [`crate::analysis::SobolSeries`]).

use crate::uq::basis::Family;
use crate::uq::error::UqError;
use crate::uq::quadrature::gauss_legendre;
use crate::uq::sobol_design::{sobol_design, SOBOL_MAX_DIM};

/// The standard deviation, as a share of the mean's magnitude, at or below which a surrogate's
/// variance counts as none (docs/sobol-indices.md §2). Values that agree to the last bits — an
/// output the parameters cannot move yet, such as a joint at its initial position, whose runs
/// differ only by rounding — are fitted to coefficients of rounding size (a least-squares fit of
/// exactly constant data leaves about `ε |mean| √|Λ|` in the other coefficients: 1e-14 of the mean
/// at a few thousand terms); dividing them by their own sum would rank rounding errors, as one
/// index of 1.000. A parameter that truly moves an output moves it by far more than this share:
/// at the first record after t = 0 (10 ms) the narrowest envelope of the ur5 all-values study is
/// 6.3e-5 of its output's magnitude, of the README's d = 8 scaling box 3.0e-6.
pub const NEGLIGIBLE_RELATIVE_SPREAD: f64 = 1e-10;

/// Variance-based sensitivity of a surrogate under uniform ξ (docs/sobol-indices.md §1).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SobolIndices {
    /// Total variance `D = Σ_{α≠0} c_α² Π_r 1/(2α_r+1)`, in the output's unit squared.
    pub variance: f64,
    /// Main (first-order) index per dimension: the share of D from terms in ξ_r alone.
    pub main: Vec<f64>,
    /// Total index per dimension: the share of D from every term involving ξ_r.
    pub total: Vec<f64>,
}

impl SobolIndices {
    /// All indices and the variance 0, for `dim` dimensions.
    pub fn zeros(dim: usize) -> SobolIndices {
        SobolIndices {
            variance: 0.0,
            main: vec![0.0; dim],
            total: vec![0.0; dim],
        }
    }

    /// Number of dimensions d.
    pub fn dim(&self) -> usize {
        self.main.len()
    }

    /// Sets every index and the variance to 0 for `dim` dimensions (reusing the allocation).
    pub(crate) fn reset(&mut self, dim: usize) {
        self.variance = 0.0;
        self.main.clear();
        self.main.resize(dim, 0.0);
        self.total.clear();
        self.total.resize(dim, 0.0);
    }

    /// Adds one non-constant term of variance `v` whose factors are in `dims` (each dimension
    /// once; `single` is `Some(r)` when the term involves ξ_r alone).
    #[inline]
    pub(crate) fn add_term(
        &mut self,
        v: f64,
        single: Option<usize>,
        dims: impl Iterator<Item = usize>,
    ) {
        self.variance += v;
        if let Some(r) = single {
            self.main[r] += v;
        }
        for r in dims {
            self.total[r] += v;
        }
    }

    /// Divides the accumulated partial variances by the variance. A constant surrogate (variance
    /// 0), or one whose standard deviation is at most [`NEGLIGIBLE_RELATIVE_SPREAD`] of its mean
    /// `mean`'s magnitude, has variance 0 and every index 0.
    pub(crate) fn normalise(&mut self, mean: f64) {
        let variance = self.variance;
        if variance.sqrt() <= NEGLIGIBLE_RELATIVE_SPREAD * mean.abs() {
            self.variance = 0.0;
            self.main.iter_mut().for_each(|s| *s = 0.0);
            self.total.iter_mut().for_each(|s| *s = 0.0);
        } else if variance > 0.0 {
            self.main.iter_mut().for_each(|s| *s /= variance);
            self.total.iter_mut().for_each(|s| *s /= variance);
        }
    }
}

/// `1/(2n+1)`: the squared norm of `P_n` under the uniform probability on [−1, 1].
#[inline]
fn legendre_norm_squared(n: usize) -> f64 {
    1.0 / (2.0 * n as f64 + 1.0)
}

/// Sobol' indices of a dense tensor surrogate (`(order+1)^dim` coefficients, row-major multi-index
/// order with ξ_1 slowest, as [`crate::uq::Surrogate::dense_coefficients`]) of `family`, into `out`
/// (overwritten). Cost `O((k+1)^d · d)`, plus `O(d (k+1)^{d+1})` to rewrite a Chebyshev surrogate
/// in the Legendre basis.
///
/// Errors: `dense.len() != (order+1)^dim` ([`UqError::WrongLength`]); an order beyond the
/// quadrature's range for the Chebyshev change of basis.
pub fn tensor_sobol_indices_into(
    family: Family,
    dim: usize,
    order: usize,
    dense: &[f64],
    out: &mut SobolIndices,
) -> Result<(), UqError> {
    let m = order + 1;
    let expected = m.checked_pow(dim as u32).unwrap_or(usize::MAX);
    if dense.len() != expected {
        return Err(UqError::WrongLength {
            what: "Sobol' indices: dense coefficients ((k+1)^d)",
            expected,
            got: dense.len(),
        });
    }
    let converted;
    let legendre: &[f64] = match family {
        Family::Legendre => dense,
        Family::Chebyshev => {
            converted = chebyshev_to_legendre(dim, order, dense)?;
            &converted
        }
    };
    out.reset(dim);
    let mut digits = vec![0usize; dim];
    for (t, &c) in legendre.iter().enumerate() {
        if t > 0 {
            // Odometer: the last digit runs fastest.
            for digit in digits.iter_mut().rev() {
                *digit += 1;
                if *digit < m {
                    break;
                }
                *digit = 0;
            }
        }
        if t == 0 || c == 0.0 {
            continue;
        }
        let mut v = c * c;
        let mut support = 0;
        let mut last = 0;
        for (r, &i) in digits.iter().enumerate() {
            if i > 0 {
                v *= legendre_norm_squared(i);
                support += 1;
                last = r;
            }
        }
        let single = (support == 1).then_some(last);
        out.add_term(
            v,
            single,
            digits
                .iter()
                .enumerate()
                .filter(|(_, &i)| i > 0)
                .map(|(r, _)| r),
        );
    }
    out.normalise(legendre[0]);
    Ok(())
}

/// `a[n][m]` (row-major `(k+1) × (k+1)`): the coefficient of `P_m` in `T_n`,
/// `a_nm = (2m+1)/2 ∫ T_n P_m dξ`, by Gauss–Legendre with k+1 nodes (exact: degree ≤ 2k).
pub fn chebyshev_in_legendre(order: usize) -> Result<Vec<f64>, UqError> {
    let m = order + 1;
    let rule = gauss_legendre(m)?;
    let mut a = vec![0.0; m * m];
    let mut t = vec![0.0; m];
    let mut p = vec![0.0; m];
    for (&x, &w) in rule.nodes().iter().zip(rule.weights()) {
        Family::Chebyshev.values(x, &mut t);
        Family::Legendre.values(x, &mut p);
        for n in 0..m {
            for (k, &pk) in p.iter().enumerate() {
                a[n * m + k] += w * t[n] * pk;
            }
        }
    }
    for n in 0..m {
        for k in 0..m {
            a[n * m + k] *= (2.0 * k as f64 + 1.0) / 2.0;
        }
    }
    Ok(a)
}

/// The dense Chebyshev tensor rewritten in the Legendre basis: the 1-D change of basis applied
/// along each dimension in turn.
pub(crate) fn chebyshev_to_legendre(
    dim: usize,
    order: usize,
    dense: &[f64],
) -> Result<Vec<f64>, UqError> {
    let m = order + 1;
    let a = chebyshev_in_legendre(order)?;
    let mut current = dense.to_vec();
    let mut next = vec![0.0; dense.len()];
    for r in 0..dim {
        // Dimension r: `outer` blocks of `m × inner` entries, digit r varying with stride `inner`.
        let inner = m.pow((dim - 1 - r) as u32);
        next.fill(0.0);
        for (block_in, block_out) in current
            .chunks_exact(m * inner)
            .zip(next.chunks_exact_mut(m * inner))
        {
            for n in 0..m {
                let source = &block_in[n * inner..(n + 1) * inner];
                for k in 0..=n {
                    let coefficient = a[n * m + k];
                    if coefficient == 0.0 {
                        continue;
                    }
                    for (o, s) in block_out[k * inner..(k + 1) * inner].iter_mut().zip(source) {
                        *o += coefficient * s;
                    }
                }
            }
        }
        std::mem::swap(&mut current, &mut next);
    }
    Ok(current)
}

/// Monte Carlo estimate of the main and total Sobol' indices of `f` on [−1, 1]^dim
/// (docs/sobol-indices.md §4), from `n` pairs of points `A`, `B` (the two halves of an
/// Owen-scrambled Sobol' design in 2d dimensions, seeded with `seed`) and the `d` mixed points
/// `A_B^(j)` (A with its j-th coordinate from B): `n (d + 2)` evaluations of `f`.
///
/// Main: Saltelli et al. (2010), `V_j ≈ (1/n) Σ f(B) (f(A_B^(j)) − f(A))`. Total: Jansen (1999),
/// `T_j ≈ (1/2n) Σ (f(A) − f(A_B^(j)))²`. Both divided by the variance of the `2n` values
/// `f(A)`, `f(B)`. Values are centred on their mean first (the estimators are shift-invariant in
/// expectation; centring removes the shift's noise).
///
/// A check, not a method: its error falls like `n^{-1/2}` (faster on smooth `f`, the points being
/// quasi-random).
///
/// Errors: `dim == 0`, `n == 0`, `2 dim` beyond the Sobol' generator ([`UqError::DesignTooLarge`]),
/// a non-finite value of `f` ([`UqError::NonFinite`], its evaluation index).
pub fn sobol_indices_monte_carlo(
    dim: usize,
    n: usize,
    seed: u32,
    mut f: impl FnMut(&[f64]) -> f64,
) -> Result<SobolIndices, UqError> {
    if dim == 0 {
        return Err(UqError::ZeroDimension);
    }
    if n == 0 {
        return Err(UqError::Empty {
            what: "Monte Carlo Sobol' indices: samples",
        });
    }
    if 2 * dim > SOBOL_MAX_DIM {
        return Err(UqError::DesignTooLarge {
            what: "Monte Carlo Sobol' indices: dimensions (2d of the Sobol' generator)",
            got: dim,
            max: SOBOL_MAX_DIM / 2,
        });
    }
    // Row 0 of the design is the centre; the n rows after it are Sobol' points.
    let design = sobol_design(2 * dim, n + 1, seed, &[])?;
    let rows: Vec<&[f64]> = design.chunks_exact(2 * dim).skip(1).collect();
    let mut evaluations = 0usize;
    let mut checked = |x: &[f64]| -> Result<f64, UqError> {
        let value = f(x);
        evaluations += 1;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(UqError::NonFinite {
                what: "Monte Carlo Sobol' indices: a value of f",
                index: evaluations - 1,
                value,
            })
        }
    };
    let mut fa = Vec::with_capacity(n);
    let mut fb = Vec::with_capacity(n);
    for row in &rows {
        fa.push(checked(&row[..dim])?);
        fb.push(checked(&row[dim..])?);
    }
    let mean = (fa.iter().sum::<f64>() + fb.iter().sum::<f64>()) / (2 * n) as f64;
    fa.iter_mut().for_each(|v| *v -= mean);
    fb.iter_mut().for_each(|v| *v -= mean);
    let variance = (fa.iter().map(|v| v * v).sum::<f64>() + fb.iter().map(|v| v * v).sum::<f64>())
        / (2 * n) as f64;
    let mut out = SobolIndices::zeros(dim);
    out.variance = variance;
    let mut mixed = vec![0.0; dim];
    for (i, row) in rows.iter().enumerate() {
        for j in 0..dim {
            mixed.copy_from_slice(&row[..dim]);
            mixed[j] = row[dim + j];
            let fab = checked(&mixed)? - mean;
            out.main[j] += fb[i] * (fab - fa[i]);
            out.total[j] += (fa[i] - fab) * (fa[i] - fab);
        }
    }
    for j in 0..dim {
        out.main[j] /= n as f64;
        out.total[j] /= 2.0 * n as f64;
    }
    out.normalise(mean);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::design::{Design, Truncation};
    use crate::uq::projection::Projector;
    use crate::uq::surrogate::Surrogate;
    use std::f64::consts::PI;

    /// Exact arithmetic up to rounding: indices of polynomials the surrogate holds exactly.
    const EXACT_TOL: f64 = 1e-13;
    /// Agreement asked of the Monte Carlo estimate (the "within 1 %": 0.01 on the index
    /// scale [0, 1]).
    const MONTE_CARLO_TOL: f64 = 0.01;
    /// Monte Carlo pairs: 2^15 quasi-random points (with d + 2 evaluations each).
    const MONTE_CARLO_SAMPLES: usize = 1 << 15;

    /// Fits `f` (on ξ ∈ [−1,1]^d) with a tensor surrogate of `family` and order k.
    fn fit(family: Family, dim: usize, order: usize, f: impl Fn(&[f64]) -> f64) -> Surrogate {
        let design = Design::new(family, dim, order, Truncation::Tensor).unwrap();
        let projector = Projector::new(design.clone()).unwrap();
        let values: Vec<f64> = design.points().chunks_exact(dim).map(&f).collect();
        let matrix = projector.fit(&values, 1).unwrap();
        Surrogate::from_matrix(&design, &matrix, 0).unwrap()
    }

    /// A test function on ξ.
    type TestFunction = dyn Fn(&[f64]) -> f64;

    /// Ishigami (1990) with a = 7, b = 0.1 on x = πξ.
    fn ishigami(xi: &[f64]) -> f64 {
        let (a, b) = (7.0, 0.1);
        let x: Vec<f64> = xi.iter().map(|v| PI * v).collect();
        x[0].sin() + a * x[1].sin().powi(2) + b * x[2].powi(4) * x[0].sin()
    }

    /// Closed form of Ishigami's indices (Sobol' & Levitan 1999; Saltelli et al. 2008 §4.1):
    /// `V_1 = (1 + bπ⁴/5)²/2`, `V_2 = a²/8`, `V_13 = 8 b² π⁸ / 225`, `V_3 = V_12 = V_23 = V_123 = 0`.
    fn ishigami_exact() -> SobolIndices {
        let (a, b) = (7.0_f64, 0.1_f64);
        let pi4 = PI.powi(4);
        let v1 = (1.0 + b * pi4 / 5.0).powi(2) / 2.0;
        let v2 = a * a / 8.0;
        let v13 = 8.0 * b * b * pi4 * pi4 / 225.0;
        let v = v1 + v2 + v13;
        SobolIndices {
            variance: v,
            main: vec![v1 / v, v2 / v, 0.0],
            total: vec![(v1 + v13) / v, v2 / v, v13 / v],
        }
    }

    /// A smooth cousin of Sobol's g-function (1993): `Π (2ξ_j² + ½ + a_j)/(1 + a_j)` with the
    /// importance falling as a_j grows (a_j = 0, 1, 4.5, 9), every interaction present.
    fn product_of_quadratics(xi: &[f64]) -> f64 {
        let a = [0.0, 1.0, 4.5, 9.0];
        xi.iter()
            .zip(a)
            .map(|(x, aj)| (2.0 * x * x + 0.5 + aj) / (1.0 + aj))
            .product()
    }

    fn assert_close(got: &SobolIndices, want: &SobolIndices, tol: f64, what: &str) {
        for j in 0..want.dim() {
            assert!(
                (got.main[j] - want.main[j]).abs() <= tol
                    && (got.total[j] - want.total[j]).abs() <= tol,
                "{what}: dimension {j}: main {} vs {}, total {} vs {}",
                got.main[j],
                want.main[j],
                got.total[j],
                want.total[j]
            );
        }
    }

    fn assert_consistent(s: &SobolIndices, what: &str) {
        let sum: f64 = s.main.iter().sum();
        assert!(sum <= 1.0 + EXACT_TOL, "{what}: Σ main {sum} > 1");
        for j in 0..s.dim() {
            assert!(
                s.main[j] >= 0.0
                    && s.total[j] >= s.main[j] - EXACT_TOL
                    && s.total[j] <= 1.0 + EXACT_TOL,
                "{what}: dimension {j}: main {} total {}",
                s.main[j],
                s.total[j]
            );
        }
    }

    #[test]
    fn values_that_differ_only_by_rounding_have_no_indices() {
        // A joint at its initial position, fitted from runs that agree to the last bits (the
        // xarm6 gripper's drive joint at t = 0 gave one total index of 1.000 before the floor).
        let mean = 0.070_833_333_333_333_25;
        let mut rng = SplitMix64::new(7);
        let noisy = |_: &[f64]| mean * (1.0 + 2.0 * f64::EPSILON * rng.uniform(-1.0, 1.0));
        let noisy = std::cell::RefCell::new(noisy);
        for family in [Family::Legendre, Family::Chebyshev] {
            let s = fit(family, 3, 2, |x| (noisy.borrow_mut())(x))
                .sobol_indices()
                .unwrap();
            assert_eq!(s.variance, 0.0, "{family:?}");
            assert!(s.main.iter().chain(&s.total).all(|&i| i == 0.0), "{s:?}");
        }
        // A spread just above the floor is apportioned: ξ_2 alone moves it.
        let small = 1e-9 * mean;
        let s = fit(Family::Legendre, 3, 2, |x| mean + small * x[1])
            .sobol_indices()
            .unwrap();
        assert!(s.variance > 0.0);
        assert!(
            (s.main[1] - 1.0).abs() < 1e-6 && (s.total[1] - 1.0).abs() < 1e-6,
            "{s:?}"
        );
    }

    #[test]
    fn linear_function_has_equal_main_and_total_indices() {
        // y = 1 + 2ξ1 − 3ξ2 + 0.5ξ3: V_j = a_j²/3, no interaction.
        let a = [2.0, -3.0, 0.5];
        let f = |x: &[f64]| 1.0 + a[0] * x[0] + a[1] * x[1] + a[2] * x[2];
        let v: f64 = a.iter().map(|c| c * c / 3.0).sum();
        let want = SobolIndices {
            variance: v,
            main: a.iter().map(|c| c * c / 3.0 / v).collect(),
            total: a.iter().map(|c| c * c / 3.0 / v).collect(),
        };
        for family in [Family::Legendre, Family::Chebyshev] {
            let s = fit(family, 3, 2, f).sobol_indices().unwrap();
            assert!((s.variance - v).abs() < EXACT_TOL * v, "{family:?}");
            assert_close(&s, &want, EXACT_TOL, &format!("linear {family:?}"));
            assert_consistent(&s, "linear");
            let sum: f64 = s.main.iter().sum();
            assert!((sum - 1.0).abs() < EXACT_TOL);
        }
    }

    #[test]
    fn product_function_matches_its_closed_form() {
        // y = Π (1 + c_j ξ_j): V_j = c_j²/3, D = Π(1 + V_j) − 1, S_j = V_j/D,
        // T_j = V_j Π_{k≠j}(1 + V_k) / D.
        let c = [1.0, 0.5, 0.25, 2.0];
        let f = |x: &[f64]| x.iter().zip(c).map(|(x, c)| 1.0 + c * x).product::<f64>();
        let vj: Vec<f64> = c.iter().map(|c| c * c / 3.0).collect();
        let d = vj.iter().map(|v| 1.0 + v).product::<f64>() - 1.0;
        let want = SobolIndices {
            variance: d,
            main: vj.iter().map(|v| v / d).collect(),
            total: (0..4)
                .map(|j| {
                    vj[j]
                        * (0..4)
                            .filter(|&k| k != j)
                            .map(|k| 1.0 + vj[k])
                            .product::<f64>()
                        / d
                })
                .collect(),
        };
        for family in [Family::Legendre, Family::Chebyshev] {
            let s = fit(family, 4, 1, f).sobol_indices().unwrap();
            assert!((s.variance - d).abs() < EXACT_TOL * d);
            assert_close(&s, &want, EXACT_TOL, &format!("product {family:?}"));
            assert_consistent(&s, "product");
            let sum: f64 = s.main.iter().sum();
            assert!(sum < 1.0 - 0.1, "interactions must leave Σ main < 1: {sum}");
        }
    }

    #[test]
    fn ishigami_surrogate_recovers_the_known_indices() {
        // Order 16: sin(πξ) and sin²(πξ) are resolved to ~1e-7 (the Legendre coefficients of an
        // entire function decay faster than geometrically).
        let want = ishigami_exact();
        for family in [Family::Legendre, Family::Chebyshev] {
            let s = fit(family, 3, 16, ishigami).sobol_indices().unwrap();
            assert!(
                (s.variance - want.variance).abs() < 1e-6 * want.variance,
                "{family:?}: D {} vs {}",
                s.variance,
                want.variance
            );
            assert_close(&s, &want, 1e-6, &format!("Ishigami {family:?}"));
            assert_consistent(&s, "Ishigami");
        }
        // The published values, to their four digits.
        assert!((want.main[0] - 0.3139).abs() < 1e-4);
        assert!((want.main[1] - 0.4424).abs() < 1e-4);
        assert!((want.total[0] - 0.5576).abs() < 1e-4);
        assert!((want.total[2] - 0.2437).abs() < 1e-4);
    }

    #[test]
    fn monte_carlo_agrees_with_the_coefficients_on_three_functions() {
        let linear = |x: &[f64]| 1.0 + 2.0 * x[0] - 3.0 * x[1] + 0.5 * x[2] + 0.2 * x[0] * x[1];
        let cases: [(&str, usize, usize, &TestFunction); 3] = [
            ("Ishigami", 3, 16, &ishigami),
            ("linear with an interaction", 3, 2, &linear),
            ("product of quadratics", 4, 2, &product_of_quadratics),
        ];
        for (name, dim, order, f) in cases {
            let surrogate = fit(Family::Legendre, dim, order, f);
            let exact = surrogate.sobol_indices().unwrap();
            let estimate = sobol_indices_monte_carlo(dim, MONTE_CARLO_SAMPLES, 7, |x| {
                surrogate.eval(x).unwrap()
            })
            .unwrap();
            let worst = (0..dim)
                .map(|j| {
                    (estimate.main[j] - exact.main[j])
                        .abs()
                        .max((estimate.total[j] - exact.total[j]).abs())
                })
                .fold(0.0, f64::max);
            println!(
                "{name}: largest |Monte Carlo − exact| over main and total indices {worst:.2e}"
            );
            assert_close(&estimate, &exact, MONTE_CARLO_TOL, name);
            assert!(
                (estimate.variance - exact.variance).abs() < MONTE_CARLO_TOL * exact.variance,
                "{name}: variance {} vs {}",
                estimate.variance,
                exact.variance
            );
        }
    }

    #[test]
    fn random_surrogates_keep_the_index_inequalities() {
        let mut rng = SplitMix64::new(11);
        for (dim, order, truncation) in [
            (1, 5, Truncation::Tensor),
            (2, 4, Truncation::Total),
            (3, 3, Truncation::Tensor),
            (5, 2, Truncation::Total),
        ] {
            for family in [Family::Legendre, Family::Chebyshev] {
                let design = Design::new(family, dim, order, truncation).unwrap();
                let coefficients: Vec<f64> = (0..design.n_terms())
                    .map(|_| rng.uniform(-1.0, 1.0))
                    .collect();
                let s = Surrogate::from_terms(&design, &coefficients)
                    .unwrap()
                    .sobol_indices()
                    .unwrap();
                assert!(s.variance > 0.0);
                assert_consistent(&s, &format!("d {dim} k {order} {family:?}"));
            }
        }
        // A constant has variance 0 and every index 0.
        let design = Design::new(Family::Legendre, 2, 2, Truncation::Tensor).unwrap();
        let mut c = vec![0.0; design.n_terms()];
        c[0] = 3.0;
        let s = Surrogate::from_terms(&design, &c)
            .unwrap()
            .sobol_indices()
            .unwrap();
        assert_eq!(s, SobolIndices::zeros(2));
    }

    #[test]
    fn chebyshev_change_of_basis_is_exact() {
        // T_2 = 2ξ² − 1 = (4/3) P_2 − 1/3; T_3 = 4ξ³ − 3ξ = (8/5) P_3 − (3/5) P_1.
        let a = chebyshev_in_legendre(3).unwrap();
        let row = |n: usize| &a[n * 4..(n + 1) * 4];
        let close = |got: &[f64], want: [f64; 4]| {
            got.iter().zip(want).all(|(g, w)| (g - w).abs() < EXACT_TOL)
        };
        assert!(close(row(0), [1.0, 0.0, 0.0, 0.0]));
        assert!(close(row(1), [0.0, 1.0, 0.0, 0.0]));
        assert!(
            close(row(2), [-1.0 / 3.0, 0.0, 4.0 / 3.0, 0.0]),
            "{:?}",
            row(2)
        );
        assert!(close(row(3), [0.0, -0.6, 0.0, 1.6]), "{:?}", row(3));
    }

    #[test]
    fn bad_input_is_refused() {
        let mut out = SobolIndices::zeros(2);
        assert!(tensor_sobol_indices_into(Family::Legendre, 2, 2, &[0.0; 8], &mut out).is_err());
        assert!(sobol_indices_monte_carlo(0, 8, 0, |_| 0.0).is_err());
        assert!(sobol_indices_monte_carlo(2, 0, 0, |_| 0.0).is_err());
        assert!(sobol_indices_monte_carlo(SOBOL_MAX_DIM, 8, 0, |_| 0.0).is_err());
        assert!(matches!(
            sobol_indices_monte_carlo(2, 8, 0, |x| if x[0] > 0.0 { f64::NAN } else { 0.0 }),
            Err(UqError::NonFinite { .. })
        ));
    }
}
