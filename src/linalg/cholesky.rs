//! In-place Cholesky factorisation `A = L Lᵀ` of small dense symmetric positive-definite matrices,
//! without allocation (nalgebra's `Cholesky` takes its matrix by value and allocates).
//!
//! The one implementation: [`factor_in_place`] and [`solve_in_place`] work on an `n × n` slice in
//! column-major order (nalgebra's storage, so `DMatrix::as_mut_slice` passes straight in) and read
//! only the lower triangle, entry `(i, k)` at `a[k·n + i]`, `i ≥ k`. The caller chooses the smallest
//! pivot it accepts; [`cholesky_factor_in_place`] is the `DMatrix` entry point with the dynamics'
//! rule (relative to the largest diagonal entry).
//!
//! Order of operations (fixed, so results are bitwise reproducible across callers): for column
//! `j`, `d = a_jj − Σ_{k<j} l_jk²` summed in increasing `k`, `l_jj = √d`, then for each `i > j`,
//! `l_ij = (a_ij − Σ_{k<j} l_ik l_jk) / l_jj`; the solve is forward then backward substitution with
//! the same increasing-index sums.

use super::return_for_fixed_size;
use nalgebra::{DMatrix, DVector};
use thiserror::Error;

/// Smallest pivot accepted by [`cholesky_factor_in_place`], relative to the largest diagonal entry:
/// below it the matrix is treated as singular (a coordinate that moves no inertia), not factorised
/// into garbage.
pub const RELATIVE_PIVOT_TOLERANCE: f64 = 1e-13;

/// `min_pivot` for callers that accept every positive pivot because they react to a failure
/// themselves (the bound optimisers shift their Hessian until it factorises).
pub const ANY_POSITIVE_PIVOT: f64 = 0.0;

/// A factorisation stopped at a pivot that was NaN or not above the caller's threshold: the matrix is
/// not positive definite to the precision asked for.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[error("Cholesky pivot {index} is {pivot:e}, not above the accepted minimum (matrix not positive definite)")]
pub struct NonPositivePivot {
    /// Row/column (0-based) whose pivot failed.
    pub index: usize,
    /// The pivot `a_jj − Σ_{k<j} l_jk²` before its square root (may be NaN).
    pub pivot: f64,
}

/// From this size on, [`factor_in_place`] computes the entries below a pivot sixteen at a time
/// (then eight, four, two, one: `factor_entries_in_blocks`) instead of four, and
/// forward substitution subtracts column by column (`forward_column_wise`). Each entry's dot
/// product is one chain of dependent subtractions; four entries at a time leave the processor
/// waiting on them, sixteen keep it busy. Before, the factorisation subtracted column by column
/// from here on too (every access contiguous, instead of a dot product per entry that strides by
/// `n`, which at n = 138 missed the cache on every term); sixteen entries read 128 contiguous
/// bytes per term and took 40–45 % less time than the column form at n = 24 … 138 (0.70 against
/// 1.52 µs at n = 24, 9.3 against 15.0 µs at n = 64, 78 against 132 µs at n = 138; the box
/// optimiser's Hessians of up to 72 free coordinates at d = 72, issue 40), and a third fewer
/// instructions. Below it the matrix sits in L1 and the four-entry form is kept as it was
/// measured for the HHT step (benches/README.md). Every form gives the same bits.
pub const COLUMN_WISE_FROM: usize = 24;

/// Factorises the symmetric `n × n` matrix `a` (column-major, `a.len() ≥ n²`; only the lower
/// triangle is read) in place: on success its lower triangle holds `L` with `A = L Lᵀ`; the strict
/// upper triangle is left as it was. A pivot that is NaN or `≤ min_pivot` stops the factorisation
/// (`a` then holds the columns finished so far) and is returned.
pub fn factor_in_place(a: &mut [f64], n: usize, min_pivot: f64) -> Result<(), NonPositivePivot> {
    return_for_fixed_size!(n, N => factor_fixed::<N>(a, min_pivot));
    if n < COLUMN_WISE_FROM {
        factor_entries_in_blocks::<4>(&mut a[..n * n], n, min_pivot)
    } else if n <= RUNNING_PIVOTS_UP_TO {
        factor_with_running_pivots(&mut a[..n * n], n, min_pivot)
    } else {
        factor_entries_in_blocks::<16>(&mut a[..n * n], n, min_pivot)
    }
}

/// Up to this size (from [`COLUMN_WISE_FROM`] on), [`factor_in_place`] keeps every later column's
/// pivot running (`factor_with_running_pivots`, in a buffer on the stack this long) instead of
/// summing each pivot when its column comes.
pub const RUNNING_PIVOTS_UP_TO: usize = 128;

/// [`factor_entries_in_blocks`] with sixteen entries at a time, each pivot `a_jj − Σ_{k<j} l_jk²`
/// kept running: once column `k` is finished, `l_jk²` is subtracted from every later pivot `j`
/// (the same subtractions in the same order `k = 0, 1, …` as the dot product, so the same bits).
/// Summed when its column comes, a pivot is one chain of `j` dependent subtractions that nothing
/// overlaps (the entries below the previous pivot fill the processor's window), and the next
/// column waits on it: about `2 n²` cycles at n = 64, more than the multiply-adds of the entries.
/// Kept running, the column waits only on its last subtraction; the box optimiser factorises
/// Hessians of up to 72 free coordinates (docs/high-dimension.md §7a).
fn factor_with_running_pivots(
    a: &mut [f64],
    n: usize,
    min_pivot: f64,
) -> Result<(), NonPositivePivot> {
    let mut running = [0.0_f64; RUNNING_PIVOTS_UP_TO];
    let pivots = &mut running[..n];
    for (j, pivot) in pivots.iter_mut().enumerate() {
        *pivot = a[j * n + j];
    }
    for j in 0..n {
        let (finished, rest) = a.split_at_mut(j * n);
        let column = &mut rest[..n];
        let diagonal = checked_root(pivots[j], j, min_pivot)?;
        column[j] = diagonal;
        column_below_pivot::<16>(finished, column, n, j, diagonal);
        for (pivot, &l) in pivots[j + 1..].iter_mut().zip(&column[j + 1..]) {
            *pivot -= l * l;
        }
    }
    Ok(())
}

/// [`factor_entry_by_entry`] or, from [`FOUR_ENTRIES_AT_A_TIME_FROM`] on,
/// [`factor_entries_in_blocks`] (four at a time), compiled for `n = N` (see
/// [`super::FIXED_SIZE_UP_TO`]).
fn factor_fixed<const N: usize>(a: &mut [f64], min_pivot: f64) -> Result<(), NonPositivePivot> {
    if N >= FOUR_ENTRIES_AT_A_TIME_FROM {
        factor_entries_in_blocks::<4>(&mut a[..N * N], N, min_pivot)
    } else {
        factor_entry_by_entry(&mut a[..N * N], N, min_pivot)
    }
}

/// From this size on, [`factor_in_place`] computes the entries below a pivot four at a time
/// (`factor_entries_in_blocks`) instead of one by one. Per factorisation inside an HHT step
/// (callgrind, benches/README.md): the quadruped's 14 × 14 matrix retired 2 895 instructions
/// instead of 4 161, but the panda's 9 × 9 571 instead of 555 and the ur5's 6 × 6 481 instead of 419
/// (small sizes are unrolled whole one entry at a time). Both forms give the same bits.
pub const FOUR_ENTRIES_AT_A_TIME_FROM: usize = 12;

/// The factorisation with a dot product per entry (`a.len() == n²`), one entry at a time. The
/// pivot is written out here rather than taken from `column_pivot`: indexed this way the compiler
/// unrolls the small sizes whole (the ur5's 6 × 6: 419 instructions; 481 through `column_pivot`).
#[inline(always)]
fn factor_entry_by_entry(a: &mut [f64], n: usize, min_pivot: f64) -> Result<(), NonPositivePivot> {
    for j in 0..n {
        let mut pivot = a[j * n + j];
        for k in 0..j {
            pivot -= a[k * n + j] * a[k * n + j];
        }
        let diagonal = checked_root(pivot, j, min_pivot)?;
        a[j * n + j] = diagonal;
        for i in j + 1..n {
            let mut value = a[j * n + i];
            for k in 0..j {
                value -= a[k * n + i] * a[k * n + j];
            }
            a[j * n + i] = value / diagonal;
        }
    }
    Ok(())
}

/// The factorisation with a dot product per entry (`a.len() == n²`), the entries below a pivot
/// computed in blocks: of `WIDEST` (16 from [`COLUMN_WISE_FROM`] on, else 4), then of eight
/// (when `WIDEST` is 16), four, two and one. The dot products of a block share the loads of
/// `l_jk` and the loop, and the compiler pairs their lanes. Each entry's terms are still
/// subtracted one by one in the order `k = 0, 1, …`, so the bits are those of
/// [`factor_entry_by_entry`].
#[inline(always)]
fn factor_entries_in_blocks<const WIDEST: usize>(
    a: &mut [f64],
    n: usize,
    min_pivot: f64,
) -> Result<(), NonPositivePivot> {
    for j in 0..n {
        let (finished, rest) = a.split_at_mut(j * n);
        let column = &mut rest[..n];
        let diagonal = column_pivot(finished, column, n, j, min_pivot)?;
        column_below_pivot::<WIDEST>(finished, column, n, j, diagonal);
    }
    Ok(())
}

/// Every entry of column `j` below its pivot `diagonal`, in blocks of `WIDEST` (16 or 4) rows,
/// then of eight (when `WIDEST` is 16), four, two and one ([`entries_below_pivot`]).
#[inline(always)]
fn column_below_pivot<const WIDEST: usize>(
    finished: &[f64],
    column: &mut [f64],
    n: usize,
    j: usize,
    diagonal: f64,
) {
    let mut i = j + 1;
    if WIDEST >= 16 {
        while i + 16 <= n {
            entries_below_pivot::<16>(finished, column, n, i, j, diagonal);
            i += 16;
        }
        if i + 8 <= n {
            entries_below_pivot::<8>(finished, column, n, i, j, diagonal);
            i += 8;
        }
    }
    while i + 4 <= n {
        entries_below_pivot::<4>(finished, column, n, i, j, diagonal);
        i += 4;
    }
    if i + 2 <= n {
        entries_below_pivot::<2>(finished, column, n, i, j, diagonal);
        i += 2;
    }
    if i < n {
        entries_below_pivot::<1>(finished, column, n, i, j, diagonal);
    }
}

/// `l_jj = √(a_jj − Σ_{k<j} l_jk²)` for column `j` (`column`, length `n`; `finished`: the `j`
/// columns before it), stored in place and returned, or the failing pivot.
#[inline(always)]
fn column_pivot(
    finished: &[f64],
    column: &mut [f64],
    n: usize,
    j: usize,
    min_pivot: f64,
) -> Result<f64, NonPositivePivot> {
    let mut pivot = column[j];
    for previous in finished.chunks_exact(n) {
        pivot -= previous[j] * previous[j];
    }
    let diagonal = checked_root(pivot, j, min_pivot)?;
    column[j] = diagonal;
    Ok(diagonal)
}

/// `√pivot` for the pivot of column `j`, or the error when it is NaN or not above `min_pivot`.
#[inline(always)]
fn checked_root(pivot: f64, j: usize, min_pivot: f64) -> Result<f64, NonPositivePivot> {
    if pivot.is_nan() || pivot <= min_pivot {
        return Err(NonPositivePivot { index: j, pivot });
    }
    Ok(pivot.sqrt())
}

/// `l_ij = (a_ij − Σ_{k<j} l_ik l_jk) / l_jj` for the `W` rows `i … i + W − 1` of column `j`
/// (`column`, `finished` as in [`column_pivot`]).
#[inline(always)]
fn entries_below_pivot<const W: usize>(
    finished: &[f64],
    column: &mut [f64],
    n: usize,
    i: usize,
    j: usize,
    diagonal: f64,
) {
    let mut values: [f64; W] = std::array::from_fn(|r| column[i + r]);
    for previous in finished.chunks_exact(n) {
        let l_jk = previous[j];
        let l_ik = &previous[i..i + W];
        for (value, &l) in values.iter_mut().zip(l_ik) {
            *value -= l * l_jk;
        }
    }
    for (entry, value) in column[i..i + W].iter_mut().zip(values) {
        *entry = value / diagonal;
    }
}

/// Solves `L Lᵀ x = b` in place (`b` of dimension `n` becomes `x`), with `L` in the lower triangle
/// of the column-major `n × n` `factor` from [`factor_in_place`]: [`forward_substitute`] then
/// [`backward_substitute`].
pub fn solve_in_place(factor: &[f64], n: usize, b: &mut [f64]) {
    return_for_fixed_size!(n, N => solve_fixed::<N>(factor, b));
    forward_any_size(&factor[..n * n], n, &mut b[..n]);
    backward(&factor[..n * n], n, &mut b[..n]);
}

/// [`forward`] and [`backward`] compiled for `n = N` (see [`super::FIXED_SIZE_UP_TO`]).
fn solve_fixed<const N: usize>(factor: &[f64], b: &mut [f64]) {
    forward(&factor[..N * N], N, &mut b[..N]);
    backward(&factor[..N * N], N, &mut b[..N]);
}

/// Solves `L y = b` in place (`b` of dimension `n` becomes `y`), `L` as in [`solve_in_place`].
pub fn forward_substitute(factor: &[f64], n: usize, b: &mut [f64]) {
    return_for_fixed_size!(n, N => forward_fixed::<N>(factor, b));
    forward_any_size(&factor[..n * n], n, &mut b[..n]);
}

/// [`forward`], or from [`COLUMN_WISE_FROM`] on [`forward_column_wise`] (same bits).
fn forward_any_size(factor: &[f64], n: usize, b: &mut [f64]) {
    if n < COLUMN_WISE_FROM {
        forward(factor, n, b);
    } else {
        forward_column_wise(factor, n, b);
    }
}

/// Solves `Lᵀ x = y` in place (`y` of dimension `n` becomes `x`), `L` as in [`solve_in_place`].
pub fn backward_substitute(factor: &[f64], n: usize, y: &mut [f64]) {
    return_for_fixed_size!(n, N => backward_fixed::<N>(factor, y));
    backward(&factor[..n * n], n, &mut y[..n]);
}

/// [`forward`] compiled for `n = N` (see [`super::FIXED_SIZE_UP_TO`]).
fn forward_fixed<const N: usize>(factor: &[f64], b: &mut [f64]) {
    forward(&factor[..N * N], N, &mut b[..N]);
}

/// [`backward`] compiled for `n = N` (see [`super::FIXED_SIZE_UP_TO`]).
fn backward_fixed<const N: usize>(factor: &[f64], y: &mut [f64]) {
    backward(&factor[..N * N], N, &mut y[..N]);
}

/// `y_i = (b_i − Σ_{k<i} l_ik y_k) / l_ii`, sums in increasing `k`.
#[inline(always)]
fn forward(factor: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut value = b[i];
        for k in 0..i {
            value -= factor[k * n + i] * b[k];
        }
        b[i] = value / factor[i * n + i];
    }
}

/// [`forward`] column by column: once `y_k` is known, `l_ik y_k` is subtracted from every later
/// entry `i` at once (column `k` of `L`, contiguous). Each entry still has its terms subtracted one
/// by one in the order `k = 0, 1, …` before its division, so the bits are [`forward`]'s; but the
/// entries no longer wait on one another's sums: the dot-product form is one chain of `n²/2`
/// dependent subtractions (at n = 72, the box optimiser's Hessians on the d = 72 study, the forward
/// half of the solve took as long as a factorisation, issue 40).
fn forward_column_wise(factor: &[f64], n: usize, b: &mut [f64]) {
    for k in 0..n {
        let column = &factor[k * n..(k + 1) * n];
        let y_k = b[k] / column[k];
        b[k] = y_k;
        for (value, &l_ik) in b[k + 1..].iter_mut().zip(&column[k + 1..]) {
            *value -= l_ik * y_k;
        }
    }
}

/// `x_i = (y_i − Σ_{k>i} l_ki x_k) / l_ii`, from the last row up, sums in increasing `k`.
#[inline(always)]
fn backward(factor: &[f64], n: usize, y: &mut [f64]) {
    for i in (0..n).rev() {
        let mut value = y[i];
        for k in i + 1..n {
            value -= factor[i * n + k] * y[k];
        }
        y[i] = value / factor[i * n + i];
    }
}

/// Factorises the square symmetric matrix `a` in place ([`factor_in_place`]), refusing pivots at or
/// below [`RELATIVE_PIVOT_TOLERANCE`] × the largest diagonal entry: on success its lower triangle
/// holds `L` (the strict upper triangle is left as it was).
pub fn cholesky_factor_in_place(a: &mut DMatrix<f64>) -> Result<(), NonPositivePivot> {
    let n = a.nrows();
    let scale = (0..n).map(|i| a[(i, i)].abs()).fold(0.0, f64::max);
    let threshold = RELATIVE_PIVOT_TOLERANCE * scale.max(f64::MIN_POSITIVE);
    factor_in_place(a.as_mut_slice(), n, threshold)
}

/// Solves `L Lᵀ x = b` in place (`b` becomes `x`), with `L` in the lower triangle of `factor`
/// ([`solve_in_place`]).
pub fn cholesky_solve_in_place(factor: &DMatrix<f64>, b: &mut DVector<f64>) {
    solve_in_place(factor.as_slice(), factor.nrows(), b.as_mut_slice());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::FIXED_SIZE_UP_TO;
    use crate::test_support::SplitMix64;

    /// The factorisation as a dot product per entry (the textbook loop order), for every `n`:
    /// [`factor_in_place`] must give these bits exactly, with its kernels of fixed size and its
    /// blocks of four and of sixteen entries.
    fn reference_factor(a: &mut [f64], n: usize) -> Result<(), usize> {
        for j in 0..n {
            let mut pivot = a[j * n + j];
            for k in 0..j {
                pivot -= a[k * n + j] * a[k * n + j];
            }
            if pivot.is_nan() || pivot <= 0.0 {
                return Err(j);
            }
            let diagonal = pivot.sqrt();
            a[j * n + j] = diagonal;
            for i in j + 1..n {
                let mut value = a[j * n + i];
                for k in 0..j {
                    value -= a[k * n + i] * a[k * n + j];
                }
                a[j * n + i] = value / diagonal;
            }
        }
        Ok(())
    }

    #[test]
    fn every_size_gives_the_textbook_bits() {
        let mut generator = SplitMix64::new(0x9e37_79b9_7f4a_7c15);
        let mut next = || generator.uniform(-0.5, 0.5);
        for n in [
            1,
            2,
            3,
            6,
            9,
            14,
            FIXED_SIZE_UP_TO,
            FIXED_SIZE_UP_TO + 1,
            COLUMN_WISE_FROM - 1,
            COLUMN_WISE_FROM,
            37,
            72,
            RUNNING_PIVOTS_UP_TO,
            138,
        ] {
            // B Bᵀ + n I: symmetric positive definite, entries of mixed signs and sizes.
            let b: Vec<f64> = (0..n * n)
                .map(|_| next() * 10f64.powi((n % 5) as i32 - 2))
                .collect();
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    let dot: f64 = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum();
                    a[j * n + i] = dot + if i == j { n as f64 } else { 0.0 };
                }
            }
            let mut expected = a.clone();
            reference_factor(&mut expected, n).unwrap();
            let mut got = a.clone();
            factor_in_place(&mut got, n, 0.0).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&expected), "n = {n}");
            // The solve: forward then backward substitution, sums in increasing index.
            let rhs: Vec<f64> = (0..n).map(|_| next()).collect();
            let mut expected_x = rhs.clone();
            for i in 0..n {
                for k in 0..i {
                    expected_x[i] -= expected[k * n + i] * expected_x[k];
                }
                expected_x[i] /= expected[i * n + i];
            }
            for i in (0..n).rev() {
                for k in i + 1..n {
                    expected_x[i] -= expected[i * n + k] * expected_x[k];
                }
                expected_x[i] /= expected[i * n + i];
            }
            let mut x = rhs;
            solve_in_place(&got, n, &mut x);
            assert_eq!(bits(&x), bits(&expected_x), "n = {n}, solve");
            // A failing pivot stops both at the same column with the same columns finished.
            if n > 2 {
                let mut broken = a.clone();
                broken[(n - 1) * n + (n - 1)] = -1.0;
                let mut expected = broken.clone();
                let mut got = broken;
                assert_eq!(reference_factor(&mut expected, n), Err(n - 1));
                assert_eq!(factor_in_place(&mut got, n, 0.0).unwrap_err().index, n - 1);
                assert_eq!(bits(&got), bits(&expected), "n = {n}, failed");
            }
        }
    }

    /// Rounding of a 3 × 3 factor/solve with entries of order one (a few ulps of 1).
    const SOLVE_TOL: f64 = 1e-14;

    /// A = L Lᵀ with L = [[2, 0, 0], [1, 2, 0], [0.3, 0.35, √(3 − 0.09 − 0.1225)]], column-major.
    fn known_spd() -> [f64; 9] {
        [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0]
    }

    #[test]
    fn slice_factor_matches_the_known_factor_and_leaves_the_upper_triangle() {
        let mut a = known_spd();
        a[3] = 99.0; // strict upper triangle (0, 1): never read, never written
        factor_in_place(&mut a, 3, 0.0).unwrap();
        let l33 = (3.0_f64 - 0.09 - 0.1225).sqrt();
        let expected_lower = [
            (0, 0, 2.0),
            (1, 0, 1.0),
            (2, 0, 0.3),
            (1, 1, 2.0),
            (2, 1, 0.35),
        ];
        for (i, k, value) in expected_lower {
            assert!(
                (a[k * 3 + i] - value).abs() < SOLVE_TOL,
                "l_{i}{k} = {}",
                a[k * 3 + i]
            );
        }
        assert!((a[8] - l33).abs() < SOLVE_TOL);
        assert_eq!(a[3], 99.0);
        assert_eq!(a[6], 0.6);
    }

    #[test]
    fn slice_solve_recovers_x_and_matches_the_dmatrix_entry_point_bit_for_bit() {
        let a = DMatrix::from_column_slice(3, 3, &known_spd());
        let x = DVector::from_row_slice(&[1.0, -2.0, 0.5]);
        let b = &a * &x;
        let mut factor = a.clone();
        cholesky_factor_in_place(&mut factor).unwrap();
        let mut solved = b.clone();
        cholesky_solve_in_place(&factor, &mut solved);
        assert!((&solved - &x).amax() < SOLVE_TOL);

        let mut slice = known_spd();
        factor_in_place(&mut slice, 3, 0.0).unwrap();
        let mut slice_b: Vec<f64> = b.iter().copied().collect();
        solve_in_place(&slice, 3, &mut slice_b);
        assert_eq!(slice.as_slice(), factor.as_slice());
        assert_eq!(slice_b.as_slice(), solved.as_slice());
    }

    #[test]
    fn non_positive_and_nan_pivots_are_named() {
        let mut singular = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let failure = cholesky_factor_in_place(&mut singular).unwrap_err();
        assert_eq!(failure.index, 1);
        assert!(failure.pivot <= RELATIVE_PIVOT_TOLERANCE);
        assert!(failure.to_string().contains("pivot 1"), "{failure}");

        let mut indefinite = [1.0, 2.0, 2.0, 1.0];
        let failure = factor_in_place(&mut indefinite, 2, 0.0).unwrap_err();
        assert_eq!(
            failure,
            NonPositivePivot {
                index: 1,
                pivot: -3.0
            }
        );

        let mut with_nan = [f64::NAN, 0.0, 0.0, 1.0];
        let failure = factor_in_place(&mut with_nan, 2, 0.0).unwrap_err();
        assert_eq!(failure.index, 0);
        assert!(failure.pivot.is_nan());
    }

    #[test]
    fn a_pivot_at_the_threshold_is_refused_and_just_above_accepted() {
        let mut at = [2.0];
        assert_eq!(factor_in_place(&mut at, 1, 2.0).unwrap_err().index, 0);
        let mut above = [2.0];
        factor_in_place(&mut above, 1, 1.999).unwrap();
        assert_eq!(above[0], 2.0_f64.sqrt());
    }
}
