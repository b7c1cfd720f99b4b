//! In-place LU factorisation with partial pivoting, `P A = L U`, of small dense square matrices, and
//! its solve, without allocation: the integrator's saddle-point Newton matrices (a tree's rows and
//! the constraint rows), which are not positive definite.
//!
//! Storage as in [`super::cholesky`]: an `n × n` slice in column-major order, entry `(i, j)` at
//! `a[j·n + i]`; `L` (unit diagonal, not stored) below the diagonal, `U` on and above it.
//!
//! Order of operations (fixed, so results are bitwise reproducible): for column `k`, the pivot is
//! the first entry of largest magnitude on or below the diagonal; whole rows are swapped; the
//! column below the pivot is multiplied by `1 / u_kk`; then for each later column `j` with
//! `u_kj ≠ 0`, `a_ij −= l_ik u_kj` for `i > k` in increasing `i`. The solve applies the row swaps in
//! order, then forward substitution by columns (skipping zero entries of the right-hand side) and
//! backward substitution by columns, dividing by `u_jj` first.

use super::return_for_fixed_size;
use thiserror::Error;

/// A factorisation stopped at a column whose largest candidate pivot was NaN or not above the
/// caller's threshold: the matrix is singular to the precision asked for.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[error("LU pivot {index} has magnitude {magnitude:e}, not above the accepted minimum (matrix singular)")]
pub struct SmallPivot {
    /// Column (0-based) whose pivot failed.
    pub index: usize,
    /// The largest magnitude found in that column on or below the diagonal (may be NaN).
    pub magnitude: f64,
}

/// Factorises the square `n × n` matrix `a` (column-major, `a.len() ≥ n²`) in place, writing the
/// row swapped with row `k` at step `k` into `pivots[k]` (`pivots.len() ≥ n`). A pivot magnitude
/// that is NaN or `≤ min_pivot` stops the factorisation and is returned (`a` and `pivots` then
/// hold the steps finished so far).
pub fn factor_in_place(
    a: &mut [f64],
    n: usize,
    pivots: &mut [usize],
    min_pivot: f64,
) -> Result<(), SmallPivot> {
    return_for_fixed_size!(n, N => factor_fixed::<N>(a, pivots, min_pivot));
    factor(&mut a[..n * n], n, &mut pivots[..n], min_pivot)
}

/// [`factor`] compiled for `n = N` (see [`super::FIXED_SIZE_UP_TO`]).
fn factor_fixed<const N: usize>(
    a: &mut [f64],
    pivots: &mut [usize],
    min_pivot: f64,
) -> Result<(), SmallPivot> {
    factor(&mut a[..N * N], N, &mut pivots[..N], min_pivot)
}

/// The right-looking elimination (`a.len() == n²`, `pivots.len() == n`).
#[inline(always)]
fn factor(a: &mut [f64], n: usize, pivots: &mut [usize], min_pivot: f64) -> Result<(), SmallPivot> {
    for k in 0..n {
        let mut pivot_row = k;
        let mut best = a[k * n + k].abs();
        for i in k + 1..n {
            let magnitude = a[k * n + i].abs();
            if magnitude > best {
                best = magnitude;
                pivot_row = i;
            }
        }
        if best.is_nan() || best <= min_pivot {
            return Err(SmallPivot {
                index: k,
                magnitude: best,
            });
        }
        pivots[k] = pivot_row;
        if pivot_row != k {
            for column in 0..n {
                a.swap(column * n + k, column * n + pivot_row);
            }
        }
        let inverse = 1.0 / a[k * n + k];
        for i in k + 1..n {
            a[k * n + i] *= inverse;
        }
        for j in k + 1..n {
            let u_kj = a[j * n + k];
            if u_kj != 0.0 {
                for i in k + 1..n {
                    let l_ik = a[k * n + i];
                    a[j * n + i] -= l_ik * u_kj;
                }
            }
        }
    }
    Ok(())
}

/// Solves `A x = b` in place (`b` of dimension `n` becomes `x`) with the factors and row swaps of
/// [`factor_in_place`].
pub fn solve_in_place(factor: &[f64], n: usize, pivots: &[usize], b: &mut [f64]) {
    return_for_fixed_size!(n, N => solve_fixed::<N>(factor, pivots, b));
    substitute(&factor[..n * n], n, &pivots[..n], &mut b[..n]);
}

/// [`substitute`] compiled for `n = N` (see [`super::FIXED_SIZE_UP_TO`]).
fn solve_fixed<const N: usize>(factor: &[f64], pivots: &[usize], b: &mut [f64]) {
    substitute(&factor[..N * N], N, &pivots[..N], &mut b[..N]);
}

/// The row swaps, then `L y = P b` (unit diagonal) and `U x = y`, both by columns.
#[inline(always)]
fn substitute(a: &[f64], n: usize, pivots: &[usize], b: &mut [f64]) {
    for (k, &pivot_row) in pivots.iter().enumerate() {
        if pivot_row != k {
            b.swap(k, pivot_row);
        }
    }
    for j in 0..n {
        let b_j = b[j];
        if b_j != 0.0 {
            for i in j + 1..n {
                b[i] -= a[j * n + i] * b_j;
            }
        }
    }
    for j in (0..n).rev() {
        b[j] /= a[j * n + j];
        let b_j = b[j];
        if b_j != 0.0 {
            for i in 0..j {
                b[i] -= a[j * n + i] * b_j;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::FIXED_SIZE_UP_TO;
    use crate::test_support::SplitMix64;
    use nalgebra::{DMatrix, DVector};

    /// Agreement of the solve with nalgebra's own LU on well-conditioned matrices of order one.
    const SOLVE_TOL: f64 = 1e-11;

    /// A deterministic stream in `[-0.5, 0.5)`.
    fn stream(seed: u64) -> impl FnMut() -> f64 {
        let mut generator = SplitMix64::new(seed);
        move || generator.uniform(-0.5, 0.5)
    }

    /// The elimination written the textbook way on a `DMatrix` (the loops `DenseSolver` had):
    /// every size's kernel must give its bits.
    fn reference(a: &mut DMatrix<f64>, pivots: &mut [usize]) {
        let n = a.nrows();
        for k in 0..n {
            let mut p = k;
            let mut best = a[(k, k)].abs();
            for i in k + 1..n {
                if a[(i, k)].abs() > best {
                    best = a[(i, k)].abs();
                    p = i;
                }
            }
            pivots[k] = p;
            if p != k {
                a.swap_rows(k, p);
            }
            let inverse = 1.0 / a[(k, k)];
            for i in k + 1..n {
                a[(i, k)] *= inverse;
            }
            for j in k + 1..n {
                let akj = a[(k, j)];
                if akj != 0.0 {
                    for i in k + 1..n {
                        let lik = a[(i, k)];
                        a[(i, j)] -= lik * akj;
                    }
                }
            }
        }
    }

    /// A saddle-point matrix `[[0, B], [Bᵀ, A]]` with `m` rows of `B` and `A` (`n × n`) diagonally
    /// dominant: the zero block on the diagonal forces row swaps.
    fn saddle_point(n: usize, m: usize, next: &mut impl FnMut() -> f64) -> DMatrix<f64> {
        let size = n + m;
        let mut k = DMatrix::zeros(size, size);
        for i in 0..n {
            for j in 0..n {
                k[(m + i, m + j)] = next() + if i == j { n as f64 } else { 0.0 };
            }
        }
        for r in 0..m {
            for j in 0..n {
                let b = next();
                k[(r, m + j)] = b;
                k[(m + j, r)] = b;
            }
        }
        k
    }

    #[test]
    fn every_size_gives_the_textbook_bits_and_solves() {
        let mut next = stream(0x2545_f491_4f6c_dd1d);
        for size in (1..=FIXED_SIZE_UP_TO + 3).chain([40]) {
            let m = (size / 4).min(3);
            let k = saddle_point(size - m, m, &mut next);
            let mut expected = k.clone();
            let mut expected_pivots = vec![0; size];
            reference(&mut expected, &mut expected_pivots);
            let mut got = k.clone();
            let mut pivots = vec![0; size];
            factor_in_place(got.as_mut_slice(), size, &mut pivots, 0.0).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(got.as_slice()),
                bits(expected.as_slice()),
                "n = {size}"
            );
            assert_eq!(pivots, expected_pivots, "n = {size}");
            if m > 0 {
                assert!(
                    pivots.iter().enumerate().any(|(k, &p)| p != k),
                    "n = {size}"
                );
            }

            let b = DVector::from_fn(size, |_, _| next());
            let mut x = b.clone();
            solve_in_place(got.as_slice(), size, &pivots, x.as_mut_slice());
            let expected_x = k.clone().lu().solve(&b).expect("regular");
            assert!((&x - &expected_x).amax() < SOLVE_TOL, "n = {size}");
            assert!((&k * &x - &b).amax() < SOLVE_TOL, "n = {size}");
        }
    }

    #[test]
    fn a_singular_column_is_named_with_its_largest_candidate() {
        // Second column a multiple of the first: after one step its candidates are zero.
        let mut a = [1.0, 2.0, 2.0, 4.0];
        let mut pivots = [0; 2];
        let failure = factor_in_place(&mut a, 2, &mut pivots, 1e-12).unwrap_err();
        assert_eq!(failure.index, 1);
        assert_eq!(failure.magnitude, 0.0);
        assert!(failure.to_string().contains("pivot 1"), "{failure}");

        // A NaN first candidate is never beaten (no comparison with NaN is true): named at once.
        let mut with_nan = [f64::NAN, 1.0, 1.0, 1.0];
        let failure = factor_in_place(&mut with_nan, 2, &mut pivots, 0.0).unwrap_err();
        assert_eq!(failure.index, 0);
        assert!(failure.magnitude.is_nan());
    }
}
