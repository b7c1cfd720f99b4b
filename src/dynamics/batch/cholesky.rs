//! In-place Cholesky factorisation `M = L Lᵀ` and solve per sample: the scalar
//! [`crate::dynamics::cholesky_factor_in_place`] and [`crate::dynamics::cholesky_solve_in_place`]
//! lane by lane, with the same pivot test (`RELATIVE_PIVOT_TOLERANCE` of `src/linalg/cholesky.rs` times the
//! largest diagonal entry) per lane.

use super::lanes::Lanes;
use super::state::BatchVectors;
use super::{Isa, IsaKind};
use crate::linalg::cholesky::{NonPositivePivot, RELATIVE_PIVOT_TOLERANCE};
use crate::linalg::return_for_fixed_size;

/// Factorises every sample's `n × n` symmetric matrix in `matrices` (column-major, `dim n²`) in
/// place: the lower triangle becomes `L` (the strict upper triangle is kept).
///
/// `failures` (length ≥ `matrices.size`) is overwritten: `None` for a sample whose matrix was
/// factorised, `Some(NonPositivePivot { index: j, pivot })` for one whose pivot `j` was NaN or not above the threshold —
/// exactly the scalar function's `Err`. A failed sample's matrix is left unspecified (the scalar
/// function stops there; its lane goes on computing with the bad pivot). Returns whether every
/// sample succeeded. Allocates nothing.
pub fn cholesky_factor<const W: usize>(
    isa: Isa,
    matrices: &mut BatchVectors<W>,
    n: usize,
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    match isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2.
            unsafe { factor_avx2(matrices, n, failures) }
        }
        _ => factor(matrices, n, failures),
    }
}

/// [`cholesky_factor`] with the smallest pivot each sample accepts given: `min_pivots[sample]`
/// (length ≥ `matrices.size`) instead of the relative rule, so that a caller with another rule (the
/// integrator's Newton matrix: `SINGULAR_PIVOT_RELATIVE` times the largest entry) gets exactly its
/// own scalar factorisation's verdict. The factors have the bits of
/// [`crate::linalg::cholesky::factor_in_place`] on each sample's matrix.
pub fn cholesky_factor_with_min_pivots<const W: usize>(
    isa: Isa,
    matrices: &mut BatchVectors<W>,
    n: usize,
    min_pivots: &[f64],
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    match isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: as in `cholesky_factor`.
            unsafe { factor_with_min_pivots_avx2(matrices, n, min_pivots, failures) }
        }
        _ => factor_with_min_pivots(matrices, n, min_pivots, failures),
    }
}

/// Solves `L Lᵀ x = b` for every sample in place (`b` becomes `x`, `dim n`), with `L` in the lower
/// triangle of `factors` ([`cholesky_factor`]). Allocates nothing.
pub fn cholesky_solve<const W: usize>(
    isa: Isa,
    factors: &BatchVectors<W>,
    n: usize,
    b: &mut BatchVectors<W>,
) {
    match isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: as in `cholesky_factor`.
            unsafe { solve_avx2(factors, n, b) }
        }
        _ => solve(factors, n, b),
    }
}

#[inline(always)]
fn factor<const W: usize>(
    matrices: &mut BatchVectors<W>,
    n: usize,
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    factor_chunks(matrices, n, failures, |_, a| {
        // Column-major: entry (row, column) at `row + column · n`.
        let mut scale = [0.0; W];
        for i in 0..n {
            for (s, x) in scale.iter_mut().zip(a[i + i * n].0) {
                *s = f64::max(*s, x.abs());
            }
        }
        let mut threshold = [0.0; W];
        for (t, s) in threshold.iter_mut().zip(scale) {
            *t = RELATIVE_PIVOT_TOLERANCE * s.max(f64::MIN_POSITIVE);
        }
        threshold
    })
}

#[inline(always)]
fn factor_with_min_pivots<const W: usize>(
    matrices: &mut BatchVectors<W>,
    n: usize,
    min_pivots: &[f64],
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    factor_chunks(matrices, n, failures, |c, _| {
        let mut threshold = [0.0; W];
        for (lane, t) in threshold.iter_mut().enumerate() {
            *t = min_pivots.get(c * W + lane).copied().unwrap_or(0.0);
        }
        threshold
    })
}

/// Every chunk `c` factorised ([`factor_chunk`]) with the smallest pivots `threshold(c, its
/// entries)`; `failures` overwritten as [`cholesky_factor`] says. Returns whether every sample
/// succeeded.
#[inline(always)]
fn factor_chunks<const W: usize>(
    matrices: &mut BatchVectors<W>,
    n: usize,
    failures: &mut [Option<NonPositivePivot>],
    threshold: impl Fn(usize, &[Lanes<W>]) -> [f64; W],
) -> bool {
    failures.iter_mut().for_each(|f| *f = None);
    let size = matrices.size;
    for (c, a) in matrices.chunks.chunks_exact_mut(n * n).enumerate() {
        let threshold = threshold(c, a);
        factor_chunk_sized(a, n, c, threshold, size, failures);
    }
    failures[..size].iter().all(Option::is_none)
}

/// [`factor_chunk`] compiled for `n` itself up to `linalg::FIXED_SIZE_UP_TO` (the loop bounds
/// known: unrolled, no index checks; the same operations in the same order).
#[inline(always)]
fn factor_chunk_sized<const W: usize>(
    a: &mut [Lanes<W>],
    n: usize,
    c: usize,
    threshold: [f64; W],
    size: usize,
    failures: &mut [Option<NonPositivePivot>],
) {
    return_for_fixed_size!(n, N => factor_chunk(&mut a[..N * N], N, c, threshold, size, failures));
    factor_chunk(a, n, c, threshold, size, failures)
}

/// The factorisation of chunk `c` (`a`: its `n²` entries), lane `l` refusing pivots that are NaN
/// or not above `threshold[l]`: the scalar factorisation's operations, in its order, lane by lane.
#[inline(always)]
fn factor_chunk<const W: usize>(
    a: &mut [Lanes<W>],
    n: usize,
    c: usize,
    threshold: [f64; W],
    size: usize,
    failures: &mut [Option<NonPositivePivot>],
) {
    for j in 0..n {
        let mut pivot = a[j + j * n];
        for k in 0..j {
            pivot = pivot - a[j + k * n] * a[j + k * n];
        }
        let mut diagonal = [0.0; W];
        for (lane, d) in diagonal.iter_mut().enumerate() {
            let p = pivot.0[lane];
            let sample = c * W + lane;
            if (p.is_nan() || p <= threshold[lane]) && sample < size && failures[sample].is_none() {
                failures[sample] = Some(NonPositivePivot { index: j, pivot: p });
            }
            *d = p.sqrt();
        }
        let diagonal = Lanes(diagonal);
        a[j + j * n] = diagonal;
        for i in j + 1..n {
            let mut value = a[i + j * n];
            for k in 0..j {
                value = value - a[i + k * n] * a[j + k * n];
            }
            let mut quotient = value.0;
            for (q, d) in quotient.iter_mut().zip(diagonal.0) {
                *q /= d;
            }
            a[i + j * n] = Lanes(quotient);
        }
    }
}

/// Every chunk's systems solved ([`solve_chunk_sized`]).
#[inline(always)]
fn solve<const W: usize>(factors: &BatchVectors<W>, n: usize, b: &mut BatchVectors<W>) {
    for (l, x) in factors
        .chunks
        .chunks_exact(n * n)
        .zip(b.chunks.chunks_exact_mut(n))
    {
        solve_chunk_sized(l, n, x);
    }
}

/// [`solve_chunk`] compiled for `n` itself up to `linalg::FIXED_SIZE_UP_TO`, as
/// [`factor_chunk_sized`].
#[inline(always)]
fn solve_chunk_sized<const W: usize>(l: &[Lanes<W>], n: usize, x: &mut [Lanes<W>]) {
    return_for_fixed_size!(n, N => solve_chunk(&l[..N * N], N, &mut x[..N]));
    solve_chunk(l, n, x)
}

/// `L Lᵀ x = b` for one chunk (`l`: its `n²` factor entries, `x`: its right-hand sides, becoming
/// the solutions): the scalar solve's forward and backward substitutions, lane by lane.
#[inline(always)]
fn solve_chunk<const W: usize>(l: &[Lanes<W>], n: usize, x: &mut [Lanes<W>]) {
    for i in 0..n {
        let mut value = x[i];
        for k in 0..i {
            value = value - l[i + k * n] * x[k];
        }
        x[i] = divide(value, l[i + i * n]);
    }
    for i in (0..n).rev() {
        let mut value = x[i];
        for k in i + 1..n {
            value = value - l[k + i * n] * x[k];
        }
        x[i] = divide(value, l[i + i * n]);
    }
}

#[inline(always)]
fn divide<const W: usize>(numerator: Lanes<W>, denominator: Lanes<W>) -> Lanes<W> {
    let mut out = numerator.0;
    for (o, d) in out.iter_mut().zip(denominator.0) {
        *o /= d;
    }
    Lanes(out)
}

/// [`factor`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn factor_avx2<const W: usize>(
    matrices: &mut BatchVectors<W>,
    n: usize,
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    factor(matrices, n, failures)
}

/// [`factor_with_min_pivots`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn factor_with_min_pivots_avx2<const W: usize>(
    matrices: &mut BatchVectors<W>,
    n: usize,
    min_pivots: &[f64],
    failures: &mut [Option<NonPositivePivot>],
) -> bool {
    factor_with_min_pivots(matrices, n, min_pivots, failures)
}

/// [`solve`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn solve_avx2<const W: usize>(factors: &BatchVectors<W>, n: usize, b: &mut BatchVectors<W>) {
    solve(factors, n, b)
}
