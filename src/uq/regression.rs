//! Least-squares fits of a sparse Legendre expansion on a given point set
//! (docs/high-dimension.md §4): the fitting map by Householder QR (never the normal equations), the
//! oversampling ratio, the condition number of the regression matrix, the hat-matrix diagonal and
//! the leave-one-out error it gives for free.
//!
//! The regression matrix uses the orthonormal Legendre basis `ψ_α = Π_r √(2α_r+1) P_{α_r}`:
//! `A[p, α] = ψ_α(ξ_p)`. For uniformly spread points `AᵀA / n → I`, so its condition number
//! measures the design, not the basis scaling; the coefficients returned are those of the plain
//! `P_α` (the surrogates' basis), `c_α = √(…) · c̃_α`.
//!
//! Does not: choose points (see [`mod@crate::uq::sobol_design`]) or terms (see
//! [`crate::uq::MultiIndexSet`]).

use std::sync::Arc;

use nalgebra::{DMatrix, DMatrixView, DMatrixViewMut};

use crate::uq::basis::legendre_values;
use crate::uq::error::UqError;
use crate::uq::householder::{form_q, qr_in_place, right_solve_upper_transposed};
use crate::uq::linear_fit::LinearFit;
use crate::uq::multi_index::MultiIndexSet;

/// Below this oversampling `n / |Λ|` the fit is accepted but flagged
/// ([`Regression::low_oversampling`]): with fewer than two points per term, least squares on random
/// or quasi-random points is often ill-conditioned (docs/high-dimension.md §4).
pub const MIN_GOOD_OVERSAMPLING: f64 = 2.0;

/// A diagonal entry of R below this fraction of the largest one means the regression matrix is
/// numerically rank deficient (κ ≥ 1e10: coefficients would carry no correct digit from data with
/// 1e-6 relative noise, a typical integrator tolerance). Refused.
pub const RANK_TOL: f64 = 1e-10;

/// Leverages `h_p ≥ 1 − LEVERAGE_TOL` make the leave-one-out residual `r_p / (1 − h_p)` undefined
/// (the point alone fixes a direction of the fit); such points report an infinite LOO error.
pub const LEVERAGE_TOL: f64 = 1e-10;

/// Lanczos steps used for each extreme eigenvalue of `RᵀR` in the condition number: extreme Ritz
/// values converge fastest; 40 steps give ≲ 1e-3 relative on the test matrices.
const LANCZOS_STEPS: usize = 40;

/// The leave-one-out error of one output, in the output's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LooError {
    /// `√(Σ_p e_p² / n)`, `e_p = r_p / (1 − h_p)` the residual at point p of the fit without p.
    pub rms: f64,
    /// `max_p |e_p|`.
    pub max: f64,
}

/// A least-squares fit of a set Λ on n ≥ |Λ| points.
///
/// ```
/// use std::sync::Arc;
/// use ribbon::uq::{sobol_design, MultiIndexSet, Regression};
/// // Total degree 2 in d = 5 (21 terms) on 64 points; y = 1 + ξ1 ξ5 is in the span.
/// let set = Arc::new(MultiIndexSet::total_degree(5, 2)?);
/// let fit = Regression::new(set.clone(), sobol_design(5, 64, 0, &[])?)?;
/// assert!(!fit.low_oversampling() && fit.condition_number() < 10.0);
/// let values: Vec<f64> = fit.points().chunks_exact(5).map(|x| 1.0 + x[0] * x[4]).collect();
/// let coef = fit.fit().fit(&values, 1)?;
/// assert!((coef[0] - 1.0).abs() < 1e-12);
/// assert!((coef[set.index_of_dense(&[1, 0, 0, 0, 1]).unwrap()] - 1.0).abs() < 1e-12);
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
#[derive(Debug)]
pub struct Regression {
    set: Arc<MultiIndexSet>,
    points: Vec<f64>,
    fit: LinearFit,
    /// `P_α(ξ_p)` transposed: m × n, column p = every basis function at point p.
    basis_t: DMatrix<f64>,
    leverage: Vec<f64>,
    condition: f64,
}

impl Regression {
    /// Builds the fitting map of `set` on `points` (`n × d` row-major, in [−1, 1]^d).
    ///
    /// Cost (measured on this machine, one core): |Λ| = 1891 terms on n = 3800 points takes
    /// 4.4–6.5 s (QR, thin Q, pseudo-inverse: ~60 GFlop in matrix products); |Λ| = 496 on 1000
    /// points 0.18 s. Memory: three n × |Λ| matrices at the peak (~170 MB for the large case).
    ///
    /// Errors: points not a multiple of d, a non-finite or out-of-box coordinate, fewer points
    /// than terms ([`UqError::TooFewPoints`]), a rank-deficient matrix ([`UqError::RankDeficient`]).
    pub fn new(set: Arc<MultiIndexSet>, points: Vec<f64>) -> Result<Regression, UqError> {
        let (d, m) = (set.dim(), set.len());
        if !points.len().is_multiple_of(d) {
            return Err(UqError::WrongLength {
                what: "regression points (n × d)",
                expected: (points.len() / d + 1) * d,
                got: points.len(),
            });
        }
        let n = points.len() / d;
        if let Some(index) = points.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what: "regression points",
                index,
                value: points[index],
            });
        }
        if let Some(index) = points.iter().position(|v| v.abs() > 1.0) {
            return Err(UqError::InvalidInterval {
                index,
                lo: points[index],
                hi: points[index],
            });
        }
        if n < m {
            return Err(UqError::TooFewPoints {
                points: n,
                terms: m,
            });
        }
        let scale: Vec<f64> = (0..m)
            .map(|t| {
                set.term(t)
                    .iter()
                    .map(|f| (2.0 * f.degree as f64 + 1.0).sqrt())
                    .product()
            })
            .collect();
        let basis_t = basis_matrix_t(&set, &points);
        // A (n × m) in the orthonormal basis.
        let mut a = DMatrix::from_fn(n, m, |p, t| basis_t[(t, p)] * scale[t]);
        let tau = qr_in_place(&mut a);
        let largest = (0..m).map(|i| a[(i, i)].abs()).fold(0.0, f64::max);
        // `is_nan` too: a NaN pivot is as unusable as a tiny one.
        if let Some(column) = (0..m).find(|&i| {
            let pivot = a[(i, i)].abs();
            pivot.is_nan() || pivot <= RANK_TOL * largest
        }) {
            return Err(UqError::RankDeficient {
                column,
                pivot: a[(column, column)].abs(),
                largest,
            });
        }
        let mut q = form_q(&a, &tau);
        let leverage: Vec<f64> = (0..n)
            .map(|p| q.row(p).iter().map(|v| v * v).sum())
            .collect();
        let condition = condition_number(&a);
        // Yᵀ = R⁻¹ Q₁ᵀ = Ã⁺; the plain-basis map is diag(s) Ã⁺, i.e. column t of Y times s_t.
        right_solve_upper_transposed(&a, &mut q);
        drop(a);
        for (t, mut column) in q.column_iter_mut().enumerate() {
            column *= scale[t];
        }
        Ok(Regression {
            set,
            points,
            fit: LinearFit::dense_transposed(q),
            basis_t,
            leverage,
            condition,
        })
    }

    /// The index set.
    pub fn set(&self) -> &Arc<MultiIndexSet> {
        &self.set
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.set.dim()
    }

    /// Number of points n.
    pub fn n_points(&self) -> usize {
        self.leverage.len()
    }

    /// The points, `n × d` row-major.
    pub fn points(&self) -> &[f64] {
        &self.points
    }

    /// The fitting map (least squares): values at the points → Legendre coefficients in the set's
    /// order.
    pub fn fit(&self) -> &LinearFit {
        &self.fit
    }

    /// `n / |Λ|` (≥ 1).
    pub fn oversampling(&self) -> f64 {
        self.n_points() as f64 / self.set.len() as f64
    }

    /// True when `n / |Λ| <` [`MIN_GOOD_OVERSAMPLING`]: the fit was made, but the caller should
    /// say that it is weakly determined.
    pub fn low_oversampling(&self) -> bool {
        self.oversampling() < MIN_GOOD_OVERSAMPLING
    }

    /// 2-norm condition number `σ_max / σ_min` of the regression matrix in the orthonormal basis
    /// (module doc), from Lanczos on `RᵀR` and `(RᵀR)⁻¹`: the Ritz values are inner estimates of the
    /// extreme eigenvalues, so this is a lower bound, ≲ 1e-3 relative below the true value in tests.
    pub fn condition_number(&self) -> f64 {
        self.condition
    }

    /// Diagonal of the hat matrix `H = A (AᵀA)⁻¹ Aᵀ` (length n, each in [0, 1], summing to |Λ|):
    /// how much point p's own value decides the fit there.
    pub fn leverage(&self) -> &[f64] {
        &self.leverage
    }

    /// Leave-one-out errors of every output, from the residuals `r = y − A c` and the leverages:
    /// `e_p = r_p / (1 − h_p)` is exactly the error at point p of the least-squares fit made
    /// without p (docs/high-dimension.md §4). `values` is `n × n_outputs`, `coefficients`
    /// `|Λ| × n_outputs` (as [`LinearFit::fit_into`] wrote them), both row-major. Allocates the
    /// `n × n_outputs` residuals.
    ///
    /// Errors: lengths that disagree, `n_outputs == 0`.
    pub fn leave_one_out(
        &self,
        values: &[f64],
        coefficients: &[f64],
        n_outputs: usize,
    ) -> Result<Vec<LooError>, UqError> {
        let (n, m) = (self.n_points(), self.set.len());
        if n_outputs == 0 {
            return Err(UqError::Empty {
                what: "leave-one-out: outputs",
            });
        }
        if values.len() != n * n_outputs {
            return Err(UqError::WrongLength {
                what: "leave-one-out: values (n_points × n_outputs)",
                expected: n * n_outputs,
                got: values.len(),
            });
        }
        if coefficients.len() != m * n_outputs {
            return Err(UqError::WrongLength {
                what: "leave-one-out: coefficients (n_terms × n_outputs)",
                expected: m * n_outputs,
                got: coefficients.len(),
            });
        }
        // Row-major (p, o) is column-major (o, p): residualᵀ = valuesᵀ − coefᵀ · Aᵀ.
        let mut residual = values.to_vec();
        {
            let coef_t = DMatrixView::from_slice(coefficients, n_outputs, m);
            let mut res_t = DMatrixViewMut::from_slice(&mut residual, n_outputs, n);
            res_t.gemm(-1.0, &coef_t, &self.basis_t, 1.0);
        }
        let mut out = vec![LooError { rms: 0.0, max: 0.0 }; n_outputs];
        for (row, &h) in residual.chunks_exact(n_outputs).zip(&self.leverage) {
            let free = 1.0 - h;
            for (e, &r) in out.iter_mut().zip(row) {
                let loo = if free > LEVERAGE_TOL {
                    (r / free).abs()
                } else {
                    f64::INFINITY
                };
                e.rms += loo * loo;
                e.max = e.max.max(loo);
            }
        }
        for e in &mut out {
            e.rms = (e.rms / n as f64).sqrt();
        }
        Ok(out)
    }
}

/// `P_α(ξ_p)` for every term and point, m × n (column p contiguous).
fn basis_matrix_t(set: &MultiIndexSet, points: &[f64]) -> DMatrix<f64> {
    let (d, m) = (set.dim(), set.len());
    let n = points.len() / d;
    let k = set.max_degree();
    let mut table = vec![0.0; d * (k + 1)];
    let mut out = DMatrix::zeros(m, n);
    for (p, x) in points.chunks_exact(d).enumerate() {
        for (r, &xr) in x.iter().enumerate() {
            legendre_values(xr, &mut table[r * (k + 1)..(r + 1) * (k + 1)]);
        }
        for (t, v) in out.column_mut(p).iter_mut().enumerate() {
            *v = set
                .term(t)
                .iter()
                .map(|f| table[f.dim as usize * (k + 1) + f.degree as usize])
                .product();
        }
    }
    out
}

/// `σ_max(R) / σ_min(R)` for the upper triangle R (m × m) of `factored`, by Lanczos on `RᵀR`
/// and on `(RᵀR)⁻¹` (triangular solves).
fn condition_number(factored: &DMatrix<f64>) -> f64 {
    let m = factored.ncols();
    let r = factored.rows(0, m).upper_triangle();
    let rt = r.transpose();
    let largest = lanczos_max(m, |x, y| {
        let tmp = &r * x;
        y.gemv(1.0, &rt, &tmp, 0.0);
    });
    let inverse_largest = lanczos_max(m, |x, y| {
        // y = R⁻¹ R⁻ᵀ x.
        let mut tmp = x.clone();
        if !rt.solve_lower_triangular_mut(&mut tmp) || !r.solve_upper_triangular_mut(&mut tmp) {
            tmp.fill(f64::INFINITY);
        }
        y.copy_from(&tmp);
    });
    (largest * inverse_largest).sqrt()
}

/// Largest eigenvalue of a symmetric positive (semi)definite operator of size m, by `LANCZOS_STEPS`
/// steps of Lanczos with full reorthogonalisation from a fixed start vector.
fn lanczos_max(
    m: usize,
    apply: impl Fn(&nalgebra::DVector<f64>, &mut nalgebra::DVector<f64>),
) -> f64 {
    use nalgebra::DVector;
    let steps = LANCZOS_STEPS.min(m);
    // A deterministic start with every component non-zero.
    let mut q = DVector::from_fn(m, |i, _| 1.0 + 0.5 * ((i as f64) * 0.618_034).sin());
    q /= q.norm();
    let mut basis: Vec<DVector<f64>> = Vec::with_capacity(steps);
    let mut alpha = Vec::with_capacity(steps);
    let mut beta: Vec<f64> = Vec::with_capacity(steps);
    let mut w = DVector::zeros(m);
    for _ in 0..steps {
        apply(&q, &mut w);
        let a = q.dot(&w);
        alpha.push(a);
        basis.push(q.clone());
        for b in &basis {
            let c = b.dot(&w);
            w.axpy(-c, b, 1.0);
        }
        let norm = w.norm();
        if norm.is_nan() || norm <= 1e-14 * a.abs() {
            break;
        }
        beta.push(norm);
        q = &w / norm;
    }
    let k = alpha.len();
    let mut t = DMatrix::zeros(k, k);
    for i in 0..k {
        t[(i, i)] = alpha[i];
        if i + 1 < k {
            t[(i, i + 1)] = beta[i];
            t[(i + 1, i)] = beta[i];
        }
    }
    t.symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::sobol_design::sobol_design;

    /// Least squares reproduces polynomials in the span exactly; rounding scales with κ ≈ 2–5.
    const REPRODUCTION_TOL: f64 = 1e-11;

    fn eval(set: &MultiIndexSet, coef: &[f64], x: &[f64]) -> f64 {
        let k = set.max_degree();
        let mut p = vec![0.0; k + 1];
        let table: Vec<Vec<f64>> = x
            .iter()
            .map(|&xr| {
                legendre_values(xr, &mut p);
                p.clone()
            })
            .collect();
        (0..set.len())
            .map(|t| {
                coef[t]
                    * set
                        .term(t)
                        .iter()
                        .map(|f| table[f.dim as usize][f.degree as usize])
                        .product::<f64>()
            })
            .sum()
    }

    #[test]
    fn reproduces_polynomials_in_the_span() {
        let mut rng = SplitMix64::new(5);
        for (d, k, n) in [(3, 4, 80), (10, 2, 140), (60, 1, 130), (20, 2, 500)] {
            let set = Arc::new(MultiIndexSet::total_degree(d, k).unwrap());
            let points = sobol_design(d, n, 3, &[]).unwrap();
            let fit = Regression::new(set.clone(), points).unwrap();
            let n_out = 3;
            let coef: Vec<f64> = (0..set.len() * n_out)
                .map(|_| rng.uniform(-1.0, 1.0))
                .collect();
            let mut values = vec![0.0; n * n_out];
            let mut column = vec![0.0; set.len()];
            for o in 0..n_out {
                for t in 0..set.len() {
                    column[t] = coef[t * n_out + o];
                }
                for (p, x) in fit.points().chunks_exact(d).enumerate() {
                    values[p * n_out + o] = eval(&set, &column, x);
                }
            }
            let got = fit.fit().fit(&values, n_out).unwrap();
            let err = got
                .iter()
                .zip(&coef)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "regression d = {d}, k = {k}, n = {n}, |Λ| = {}: κ = {:.3}, error {err:.1e}",
                set.len(),
                fit.condition_number()
            );
            assert!(err < REPRODUCTION_TOL, "d={d}: {err}");
            // Exact data: LOO residuals vanish.
            let loo = fit.leave_one_out(&values, &got, n_out).unwrap();
            assert!(loo.iter().all(|e| e.max < 1e-9), "{loo:?}");
            let h: f64 = fit.leverage().iter().sum();
            assert!((h - set.len() as f64).abs() < 1e-8, "trace of H = |Λ|");
        }
    }

    #[test]
    fn leave_one_out_equals_refitting_without_the_point() {
        // y = ξ1³ + ξ2 is not in total degree 2: the LOO residual at p must equal the error at p
        // of the fit made without p.
        let d = 2;
        let set = Arc::new(MultiIndexSet::total_degree(d, 2).unwrap());
        let points = sobol_design(d, 20, 9, &[]).unwrap();
        let f = |x: &[f64]| x[0].powi(3) + x[1];
        let values: Vec<f64> = points.chunks_exact(d).map(f).collect();
        let full = Regression::new(set.clone(), points.clone()).unwrap();
        let coef = full.fit().fit(&values, 1).unwrap();
        let loo = full.leave_one_out(&values, &coef, 1).unwrap()[0];
        let mut sum_sq = 0.0;
        let mut max = 0.0_f64;
        for p in 0..20 {
            let mut pts = points.clone();
            pts.drain(p * d..(p + 1) * d);
            let mut vals = values.clone();
            vals.remove(p);
            let without = Regression::new(set.clone(), pts).unwrap();
            let c = without.fit().fit(&vals, 1).unwrap();
            let e = (f(&points[p * d..(p + 1) * d]) - eval(&set, &c, &points[p * d..(p + 1) * d]))
                .abs();
            sum_sq += e * e;
            max = max.max(e);
        }
        assert!((loo.max - max).abs() < 1e-10 * max, "{} vs {max}", loo.max);
        assert!((loo.rms - (sum_sq / 20.0).sqrt()).abs() < 1e-10 * max);
    }

    #[test]
    fn condition_number_matches_svd() {
        for (d, k, n) in [(2, 3, 12), (4, 2, 40), (6, 2, 60), (8, 3, 400)] {
            let set = Arc::new(MultiIndexSet::total_degree(d, k).unwrap());
            let points = sobol_design(d, n, 1, &[]).unwrap();
            let fit = Regression::new(set.clone(), points.clone()).unwrap();
            let basis = basis_matrix_t(&set, &points);
            let a = DMatrix::from_fn(n, set.len(), |p, t| {
                basis[(t, p)]
                    * set
                        .term(t)
                        .iter()
                        .map(|f| (2.0 * f.degree as f64 + 1.0).sqrt())
                        .product::<f64>()
            });
            let sv = a.singular_values();
            let exact = sv.max() / sv.min();
            let got = fit.condition_number();
            assert!(got <= exact * (1.0 + 1e-12), "{got} > {exact}");
            assert!(got >= exact * (1.0 - 1e-3), "d={d}: {got} vs {exact}");
            assert_eq!(fit.low_oversampling(), n < 2 * set.len());
        }
    }

    #[test]
    fn refuses_bad_designs() {
        let set = Arc::new(MultiIndexSet::total_degree(2, 2).unwrap());
        assert!(matches!(
            Regression::new(set.clone(), sobol_design(2, 5, 0, &[]).unwrap()),
            Err(UqError::TooFewPoints {
                points: 5,
                terms: 6
            })
        ));
        // Six points on the line ξ2 = 0 cannot determine ξ2 terms.
        let line: Vec<f64> = (0..6).flat_map(|i| [-1.0 + 0.4 * i as f64, 0.0]).collect();
        assert!(matches!(
            Regression::new(set.clone(), line),
            Err(UqError::RankDeficient { .. })
        ));
        assert!(Regression::new(set.clone(), vec![0.0; 13]).is_err());
        assert!(Regression::new(set.clone(), vec![2.0; 14]).is_err());
        let exact = Regression::new(set, sobol_design(2, 6, 0, &[]).unwrap()).unwrap();
        assert!(exact.low_oversampling());
        assert_eq!(exact.oversampling(), 1.0);
    }
}
