//! Sparse interpolation on nested Leja points over a downward-closed set Λ
//! (docs/high-dimension.md §3): one design point per term, and the exact linear map from the values
//! there to the Legendre coefficients of the interpolant in `span{P_α : α ∈ Λ}`.
//!
//! Points: term α gives the point `(z_{α_1}, …, z_{α_d})`, `z` the Leja sequence
//! ([`crate::uq::leja_points`], `z_0 = 0`): point 0 is the centre, point `1 + r` moves dimension r
//! to +1, and so on, in the set's canonical order.
//!
//! The map: with Newton polynomials `ω_m(x) = Π_{l<m}(x − z_l)`, the 1-D Vandermonde
//! `V₁[p, n] = P_n(z_p)` factors as `W₁ Sᵀ` with `W₁[p, m] = ω_m(z_p)` lower triangular and
//! `Sᵀ` upper triangular (`P_n = Σ_{m≤n} S[n, m] ω_m`). Because Λ is downward closed, the
//! d-dimensional Vandermonde restricted to Λ factors the same way into restrictions of Kronecker
//! products, and so do the inverses:
//!
//! ```text
//! c = U⁻¹ W⁻¹ y,   W⁻¹[α, p] = Π_r W₁⁻¹[α_r, p_r]  (p ≤ α),   U⁻¹[β, α] = Π_r T[α_r, β_r]  (β ≤ α)
//! ```
//!
//! where `T[m, n]` is the coefficient of `P_n` in `ω_m` (so `T = S⁻¹`). `W⁻¹ y` are the
//! hierarchical surpluses; `U⁻¹` converts the Newton form to Legendre coefficients. Both factors
//! are sparse (row α has `Π_r (α_r + 1)` entries), exact up to rounding, and built without any
//! dense factorisation: `|Λ| = 1891` (total degree 2, d = 60) takes milliseconds.
//!
//! Does not: run models, or choose Λ (see [`crate::uq::MultiIndexSet`]).

use std::sync::{Arc, OnceLock};

use crate::uq::basis::legendre_values;
use crate::uq::error::UqError;
use crate::uq::leja::{leja_points, MAX_LEJA_POINTS};
use crate::uq::linear_fit::{LinearFit, SparseRows};
use crate::uq::multi_index::{Factor, MultiIndexSet};

/// A sparse interpolation grid on Leja points for a downward-closed set.
///
/// ```
/// use std::sync::Arc;
/// use ribbon::uq::{MultiIndexSet, SparseGrid};
/// // Total degree 2 in d = 2: 6 terms, 6 points; y = ξ1 ξ2 = P_1(ξ1) P_1(ξ2).
/// let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(2, 2)?))?;
/// assert_eq!(grid.n_points(), 6);
/// let values: Vec<f64> = grid.points().chunks_exact(2).map(|x| x[0] * x[1]).collect();
/// let coef = grid.fit().fit(&values, 1)?;
/// let t = grid.set().index_of_dense(&[1, 1]).unwrap();
/// assert!((coef[t] - 1.0).abs() < 1e-14);
/// assert!(coef.iter().enumerate().all(|(i, c)| i == t || c.abs() < 1e-14));
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
#[derive(Debug)]
pub struct SparseGrid {
    set: Arc<MultiIndexSet>,
    /// `n × d` row-major standard coordinates, point t for term t.
    points: Vec<f64>,
    fit: LinearFit,
    condition: OnceLock<f64>,
}

impl SparseGrid {
    /// Builds the points and the fitting map of `set` (which is downward closed by construction
    /// of [`MultiIndexSet`]).
    ///
    /// Errors: a degree beyond the Leja table (`max_degree() ≥` [`MAX_LEJA_POINTS`]).
    pub fn new(set: Arc<MultiIndexSet>) -> Result<SparseGrid, UqError> {
        let (d, n) = (set.dim(), set.len());
        let k = set.max_degree();
        if k + 1 > MAX_LEJA_POINTS {
            return Err(UqError::OrderTooLarge {
                order: k,
                max: MAX_LEJA_POINTS - 1,
            });
        }
        let z = leja_points(k + 1)?;
        let mut points = vec![0.0; n * d];
        for (t, x) in points.chunks_exact_mut(d).enumerate() {
            for f in set.term(t) {
                x[f.dim as usize] = z[f.degree as usize];
            }
        }
        let w_inv = newton_inverse(z);
        let t_coef = newton_in_legendre(z);
        let (lower, upper) = factors(&set, &w_inv, &t_coef);
        let fit = LinearFit::triangular(n, lower, upper);
        Ok(SparseGrid {
            set,
            points,
            fit,
            condition: OnceLock::new(),
        })
    }

    /// The index set (shared with the surrogates fitted on this grid).
    pub fn set(&self) -> &Arc<MultiIndexSet> {
        &self.set
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.set.dim()
    }

    /// Number of points = number of terms |Λ|.
    pub fn n_points(&self) -> usize {
        self.set.len()
    }

    /// The points, `n_points × d` row-major, in ξ ∈ [−1, 1]^d; point t belongs to term t and
    /// point 0 is the centre.
    pub fn points(&self) -> &[f64] {
        &self.points
    }

    /// Point t (length d).
    pub fn point(&self, t: usize) -> &[f64] {
        let d = self.dim();
        &self.points[t * d..(t + 1) * d]
    }

    /// The fitting map: values at [`SparseGrid::points`] → Legendre coefficients in the set's
    /// order. Interpolation: it reproduces every polynomial in `span{P_α : α ∈ Λ}`.
    pub fn fit(&self) -> &LinearFit {
        &self.fit
    }

    /// ∞-norm condition number `κ_∞ = ‖Ṽ‖_∞ ‖Ṽ⁻¹‖_∞` of the generalized Vandermonde
    /// `Ṽ[p, α] = Π_r √(2α_r + 1) P_{α_r}(ξ_{p,r})` (orthonormal Legendre basis, docs/high-dimension.md
    /// §3). Computed on the first call (cost `O(|Λ| · Σ_α |supp α|)` plus one fit of the identity:
    /// ~10 ms at |Λ| = 1891), then cached.
    pub fn condition_number(&self) -> f64 {
        *self.condition.get_or_init(|| self.compute_condition())
    }

    fn compute_condition(&self) -> f64 {
        let set = &self.set;
        let (d, n) = (set.dim(), set.len());
        let k = set.max_degree();
        let z = leja_points(k + 1).unwrap_or(&[]);
        // table[j * (k+1) + b] = P_b(z_j).
        let mut table = vec![0.0; (k + 1) * (k + 1)];
        for (j, row) in table.chunks_exact_mut(k + 1).enumerate() {
            legendre_values(z[j], row);
        }
        let scale: Vec<f64> = (0..n)
            .map(|t| {
                set.term(t)
                    .iter()
                    .map(|f| (2.0 * f.degree as f64 + 1.0).sqrt())
                    .product()
            })
            .collect();
        // ‖Ṽ‖_∞ = max_p Σ_α s_α |Π_r P_{α_r}(z_{p_r})|; dims outside supp α give P_0 = 1.
        let mut degree_of_point = vec![0usize; d];
        let mut v_norm = 0.0_f64;
        for p in 0..n {
            for f in set.term(p) {
                degree_of_point[f.dim as usize] = f.degree as usize;
            }
            let row: f64 = (0..n)
                .map(|a| {
                    let v: f64 = set
                        .term(a)
                        .iter()
                        .map(|f| {
                            table[degree_of_point[f.dim as usize] * (k + 1) + f.degree as usize]
                        })
                        .product();
                    (v * scale[a]).abs()
                })
                .sum();
            v_norm = v_norm.max(row);
            for f in set.term(p) {
                degree_of_point[f.dim as usize] = 0;
            }
        }
        // Ṽ⁻¹ = D⁻¹ V⁻¹: row α of the fitting map divided by s_α.
        let inv_norm = self
            .fit
            .abs_row_sums()
            .iter()
            .zip(&scale)
            .map(|(s, sc)| s / sc)
            .fold(0.0, f64::max);
        v_norm * inv_norm
    }
}

/// `W₁⁻¹` for `W₁[p, m] = ω_m(z_p)` (lower triangular, unit first column), `(k+1)²` row-major.
fn newton_inverse(z: &[f64]) -> Vec<f64> {
    let m = z.len();
    let mut w = vec![0.0; m * m];
    for p in 0..m {
        let mut omega = 1.0;
        for j in 0..=p {
            w[p * m + j] = omega;
            omega *= z[p] - z[j];
        }
    }
    // Forward substitution, one column of the identity at a time.
    let mut inv = vec![0.0; m * m];
    for col in 0..m {
        for row in col..m {
            let mut s = if row == col { 1.0 } else { 0.0 };
            for j in col..row {
                s -= w[row * m + j] * inv[j * m + col];
            }
            inv[row * m + col] = s / w[row * m + row];
        }
    }
    inv
}

/// `T[m, n]`: the Legendre coefficients of `ω_m`, from `ω_{m+1} = (x − z_m) ω_m` and
/// `x P_n = ((n+1) P_{n+1} + n P_{n−1}) / (2n+1)`; `(k+1)²` row-major, zero for n > m.
fn newton_in_legendre(z: &[f64]) -> Vec<f64> {
    let m = z.len();
    let mut t = vec![0.0; m * m];
    t[0] = 1.0;
    for row in 0..m.saturating_sub(1) {
        let (cur, next) = t.split_at_mut((row + 1) * m);
        let cur = &cur[row * m..];
        let next = &mut next[..m];
        for n in 0..=row {
            let c = cur[n];
            if c == 0.0 {
                continue;
            }
            let nf = n as f64;
            next[n + 1] += c * (nf + 1.0) / (2.0 * nf + 1.0);
            if n > 0 {
                next[n - 1] += c * nf / (2.0 * nf + 1.0);
            }
            next[n] -= z[row] * c;
        }
    }
    t
}

/// The two sparse factors of the module doc.
fn factors(set: &MultiIndexSet, w_inv: &[f64], t_coef: &[f64]) -> (SparseRows, SparseRows) {
    let n = set.len();
    let m = ((w_inv.len() as f64).sqrt().round()) as usize;
    let mut lower = SparseRows {
        starts: Vec::with_capacity(n + 1),
        cols: Vec::new(),
        vals: Vec::new(),
    };
    lower.starts.push(0);
    let mut upper_rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    let mut digits: Vec<usize> = Vec::new();
    let mut sub: Vec<Factor> = Vec::new();
    let mut row: Vec<(u32, f64)> = Vec::new();
    for alpha in 0..n {
        let term = set.term(alpha);
        digits.clear();
        digits.resize(term.len(), 0);
        row.clear();
        // Odometer over every γ ≤ α (on the support of α).
        loop {
            sub.clear();
            let (mut w, mut u) = (1.0, 1.0);
            for (f, &g) in term.iter().zip(&digits) {
                let a = f.degree as usize;
                w *= w_inv[a * m + g];
                u *= t_coef[a * m + g];
                if g > 0 {
                    sub.push(Factor {
                        dim: f.dim,
                        degree: g as u32,
                    });
                }
            }
            // Downward closed: every γ ≤ α is in the set.
            let gamma = set
                .index_of(&sub)
                .unwrap_or_else(|| unreachable!("a MultiIndexSet is downward closed"));
            if w != 0.0 {
                row.push((gamma as u32, w));
            }
            if u != 0.0 {
                upper_rows[gamma].push((alpha as u32, u));
            }
            // Next γ.
            let mut i = 0;
            loop {
                if i == term.len() {
                    break;
                }
                if digits[i] < term[i].degree as usize {
                    digits[i] += 1;
                    break;
                }
                digits[i] = 0;
                i += 1;
            }
            if i == term.len() {
                break;
            }
        }
        row.sort_by_key(|&(p, _)| p);
        for &(p, v) in &row {
            lower.cols.push(p);
            lower.vals.push(v);
        }
        lower.starts.push(lower.cols.len());
    }
    let mut upper = SparseRows {
        starts: Vec::with_capacity(n + 1),
        cols: Vec::new(),
        vals: Vec::new(),
    };
    upper.starts.push(0);
    for r in upper_rows {
        // Pushed in increasing α: already sorted, diagonal first.
        for (a, v) in r {
            upper.cols.push(a);
            upper.vals.push(v);
        }
        upper.starts.push(upper.cols.len());
    }
    (lower, upper)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// Interpolation reproduces span{P_α} exactly; in floating point the triangular factors of
    /// degree ≤ 6 lose a few hundred ulp at most relative to Σ|c|.
    const REPRODUCTION_TOL: f64 = 1e-12;

    /// Σ_α c_α Π_r P_{α_r}(x_r) by brute force (dense degree vectors).
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

    fn check_reproduction(set: MultiIndexSet, seed: u64, n_outputs: usize) -> f64 {
        let set = Arc::new(set);
        let grid = SparseGrid::new(set.clone()).unwrap();
        let (n, d) = (set.len(), set.dim());
        assert_eq!(grid.n_points(), n);
        assert!(grid.point(0).iter().all(|&x| x == 0.0));
        let mut rng = SplitMix64::new(seed);
        let coef: Vec<f64> = (0..n * n_outputs).map(|_| rng.uniform(-1.0, 1.0)).collect();
        // values[p, o] from coefficient column o (coef is n_terms × n_outputs).
        let mut values = vec![0.0; n * n_outputs];
        let mut column = vec![0.0; n];
        for o in 0..n_outputs {
            for t in 0..n {
                column[t] = coef[t * n_outputs + o];
            }
            for p in 0..n {
                values[p * n_outputs + o] = eval(&set, &column, &grid.points()[p * d..(p + 1) * d]);
            }
        }
        let fitted = grid.fit().fit(&values, n_outputs).unwrap();
        fitted
            .iter()
            .zip(&coef)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn reproduces_random_polynomials_in_3_10_and_60_dimensions() {
        let cases = [
            (MultiIndexSet::total_degree(3, 6).unwrap(), 3),
            (MultiIndexSet::total_degree(10, 3).unwrap(), 2),
            (MultiIndexSet::total_degree(60, 2).unwrap(), 2),
            (
                MultiIndexSet::anisotropic(
                    &[6, 4, 2, 1, 1, 1, 1, 1, 1, 1]
                        .iter()
                        .chain(&[1; 50])
                        .copied()
                        .collect::<Vec<_>>(),
                    6,
                    2,
                )
                .unwrap(),
                1,
            ),
            (MultiIndexSet::anisotropic(&[4, 4, 4, 4], 16, 4).unwrap(), 1),
        ];
        for (i, (set, outputs)) in cases.into_iter().enumerate() {
            let (d, len) = (set.dim(), set.len());
            let err = check_reproduction(set, 100 + i as u64, outputs);
            eprintln!("sparse grid d = {d}, |Λ| = {len}: max coefficient error {err:.2e}");
            assert!(err < REPRODUCTION_TOL, "case {i}: {err}");
        }
    }

    #[test]
    fn one_dimensional_high_degree() {
        // Degree 20 in 1-D: interpolation on 21 Leja points, coefficients back to 1e-12·scale.
        let err = check_reproduction(MultiIndexSet::total_degree(1, 20).unwrap(), 9, 1);
        assert!(err < 1e-11, "{err}");
    }

    #[test]
    fn one_dimensional_factors_are_inverse_of_vandermonde() {
        let z = leja_points(8).unwrap();
        let w_inv = newton_inverse(z);
        let t = newton_in_legendre(z);
        // V₁⁻¹ = Tᵀ W₁⁻¹ must invert V₁[p, n] = P_n(z_p).
        let m = z.len();
        let mut v = vec![0.0; m * m];
        for p in 0..m {
            legendre_values(z[p], &mut v[p * m..(p + 1) * m]);
        }
        for i in 0..m {
            for j in 0..m {
                // (Tᵀ W⁻¹ V)[i, j] = Σ_a Σ_p T[a, i] W⁻¹[a, p] V[p, j]
                let mut s = 0.0;
                for a in 0..m {
                    for p in 0..m {
                        s += t[a * m + i] * w_inv[a * m + p] * v[p * m + j];
                    }
                }
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((s - want).abs() < 1e-13, "({i}, {j}): {s}");
            }
        }
    }

    #[test]
    fn condition_numbers_and_points() {
        let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(2, 1).unwrap())).unwrap();
        assert_eq!(grid.points(), &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        // Ṽ = [[1, 0, 0], [1, √3, 0], [1, 0, √3]]: ‖Ṽ‖_∞ = 1 + √3;
        // Ṽ⁻¹ rows: [1, 0, 0], [−1/√3, 1/√3, 0], …: ‖Ṽ⁻¹‖_∞ = 2/√3.
        let want = (1.0 + 3f64.sqrt()) * 2.0 / 3f64.sqrt();
        assert!((grid.condition_number() - want).abs() < 1e-13);
        for (d, k) in [(60, 2), (10, 3), (3, 6)] {
            let grid =
                SparseGrid::new(Arc::new(MultiIndexSet::total_degree(d, k).unwrap())).unwrap();
            let kappa = grid.condition_number();
            eprintln!("sparse grid d = {d}, k = {k}: κ_∞ = {kappa:.3e}");
            assert!(kappa.is_finite() && kappa >= 1.0);
        }
    }
}
