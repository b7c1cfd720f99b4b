//! The common fitting interface of sparse grids and regression: a linear map from model values at
//! the design points to expansion coefficients, applied to many outputs at once
//! (docs/high-dimension.md §5).
//!
//! Layouts (row-major, as a batch of runs produces them):
//! - **values**: `n_points × n_outputs`, `values[p · n_outputs + o]` = output o of run p;
//! - **coefficients**: `n_terms × n_outputs`, `out[t · n_outputs + o]` = coefficient of term t
//!   (canonical order of the [`crate::uq::MultiIndexSet`]) for output o.
//!
//! "Outputs" are any columns: a caller may pass every output of every record time of a block at
//! once, which makes the dense product more efficient (longer rows).
//!
//! Two representations, both applied without allocating on our side:
//! - **dense** (regression): `out = C · values`, one matrix product (`C` is `n_terms × n_points`),
//!   through nalgebra's `gemm`, which calls the `matrixmultiply` kernels once every dimension
//!   exceeds 5 (those keep packing buffers in a thread-local cache or allocate them per call);
//! - **sparse triangular factors** (sparse grids, docs/high-dimension.md §3): `out = U⁻¹ (W⁻¹ values)`
//!   where `W⁻¹` is lower and `U⁻¹` upper triangular in the set's order; the second product runs in
//!   place in `out`, so no scratch is needed.
//!
//! Both are deterministic (single-threaded, fixed summation order).

use nalgebra::{DMatrix, DMatrixView, DMatrixViewMut};

use crate::isa::{Isa, IsaKind};
use crate::uq::error::UqError;

/// A sparse matrix in compressed-row form: row i's entries are `cols/vals[starts[i]..starts[i+1]]`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SparseRows {
    pub(crate) starts: Vec<usize>,
    pub(crate) cols: Vec<u32>,
    pub(crate) vals: Vec<f64>,
}

impl SparseRows {
    pub(crate) fn n_rows(&self) -> usize {
        self.starts.len() - 1
    }

    pub(crate) fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let range = self.starts[i]..self.starts[i + 1];
        (&self.cols[range.clone()], &self.vals[range])
    }

    pub(crate) fn nnz(&self) -> usize {
        self.vals.len()
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Map {
    /// `Cᵀ` (n_points × n_terms), column-major as nalgebra stores it: column t holds term t's
    /// weights of every point, contiguous.
    Dense(DMatrix<f64>),
    /// `C = upper · lower`: `lower` maps points → terms (row α: points p ≤ α), `upper` maps terms →
    /// terms (row β: terms α ≥ β, all at indices ≥ β).
    Triangular {
        lower: SparseRows,
        upper: SparseRows,
    },
}

/// A linear map from values at `n_points` design points to `n_terms` expansion coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    n_points: usize,
    n_terms: usize,
    map: Map,
}

impl LinearFit {
    /// From the transpose `Cᵀ` (`n_points × n_terms`) of a dense map.
    pub(crate) fn dense_transposed(transposed: DMatrix<f64>) -> LinearFit {
        LinearFit {
            n_points: transposed.nrows(),
            n_terms: transposed.ncols(),
            map: Map::Dense(transposed),
        }
    }

    /// From triangular factors (module doc); `upper` must only reference columns ≥ its row.
    pub(crate) fn triangular(n_points: usize, lower: SparseRows, upper: SparseRows) -> LinearFit {
        debug_assert!((0..upper.n_rows()).all(|b| upper.row(b).0.iter().all(|&a| a as usize >= b)));
        LinearFit {
            n_points,
            n_terms: upper.n_rows(),
            map: Map::Triangular { lower, upper },
        }
    }

    /// Number of design points (model runs) the map reads.
    pub fn n_points(&self) -> usize {
        self.n_points
    }

    /// Number of expansion terms it produces.
    pub fn n_terms(&self) -> usize {
        self.n_terms
    }

    /// Stored non-zeros: `n_terms · n_points` (dense) or the two factors' entries (sparse). The
    /// cost of a fit is about `2 · stored_entries · n_outputs` flops.
    pub fn stored_entries(&self) -> usize {
        match &self.map {
            Map::Dense(m) => m.len(),
            Map::Triangular { lower, upper } => lower.nnz() + upper.nnz(),
        }
    }

    /// Overwrites `out` (`n_terms × n_outputs`, row-major) with the coefficients of every output
    /// of `values` (`n_points × n_outputs`, row-major). Allocates nothing on our side (module doc).
    ///
    /// Errors: `n_outputs == 0`, a length that disagrees, a non-finite value (its flat index).
    pub fn fit_into(
        &self,
        values: &[f64],
        n_outputs: usize,
        out: &mut [f64],
    ) -> Result<(), UqError> {
        if n_outputs == 0 {
            return Err(UqError::Empty {
                what: "fit: outputs",
            });
        }
        if values.len() != self.n_points * n_outputs {
            return Err(UqError::WrongLength {
                what: "fit: values (n_points × n_outputs)",
                expected: self.n_points * n_outputs,
                got: values.len(),
            });
        }
        if out.len() != self.n_terms * n_outputs {
            return Err(UqError::WrongLength {
                what: "fit: out (n_terms × n_outputs)",
                expected: self.n_terms * n_outputs,
                got: out.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what: "fit: values",
                index,
                value: values[index],
            });
        }
        match &self.map {
            Map::Dense(ct) => {
                // Row-major (n × o) is column-major (o × n): outᵀ = valuesᵀ · Cᵀ.
                let values_t = DMatrixView::from_slice(values, n_outputs, self.n_points);
                let mut out_t = DMatrixViewMut::from_slice(out, n_outputs, self.n_terms);
                out_t.gemm(1.0, &values_t, ct, 0.0);
            }
            Map::Triangular { lower, upper } => {
                apply_triangular(
                    lower,
                    upper,
                    |j| &values[j * n_outputs..(j + 1) * n_outputs],
                    n_outputs,
                    out,
                );
            }
        }
        Ok(())
    }

    /// As [`LinearFit::fit_into`] with the values given row by row: `rows[p]` holds point p's
    /// values of every column (all of the same length `width`), so that a caller whose runs are
    /// stored apart fits every column at once without gathering them (one multi-right-hand-side
    /// application of the map: e.g. every output at every record time of a design). Each column's
    /// coefficients are those [`LinearFit::fit_into`] gives that column alone, to the bit.
    ///
    /// Errors: no rows or `width == 0`, a count or length that disagrees, a non-finite value (its
    /// flat index `p · width + column`).
    pub fn fit_rows_into(&self, rows: &[&[f64]], out: &mut [f64]) -> Result<(), UqError> {
        let width = rows.first().map_or(0, |row| row.len());
        if width == 0 {
            return Err(UqError::Empty {
                what: "fit: columns",
            });
        }
        if rows.len() != self.n_points {
            return Err(UqError::WrongLength {
                what: "fit: rows (one per point)",
                expected: self.n_points,
                got: rows.len(),
            });
        }
        if let Some(row) = rows.iter().find(|row| row.len() != width) {
            return Err(UqError::WrongLength {
                what: "fit: row (as long as the first)",
                expected: width,
                got: row.len(),
            });
        }
        if out.len() != self.n_terms * width {
            return Err(UqError::WrongLength {
                what: "fit: out (n_terms × columns)",
                expected: self.n_terms * width,
                got: out.len(),
            });
        }
        for (p, row) in rows.iter().enumerate() {
            if let Some(column) = row.iter().position(|v| !v.is_finite()) {
                return Err(UqError::NonFinite {
                    what: "fit: values",
                    index: p * width + column,
                    value: row[column],
                });
            }
        }
        match &self.map {
            Map::Dense(_) => {
                let gathered: Vec<f64> = rows.iter().flat_map(|row| row.iter().copied()).collect();
                self.fit_into(&gathered, width, out)?;
            }
            Map::Triangular { lower, upper } => {
                apply_triangular(lower, upper, |j| rows[j], width, out);
            }
        }
        Ok(())
    }

    /// As [`LinearFit::fit_into`], into a new vector.
    pub fn fit(&self, values: &[f64], n_outputs: usize) -> Result<Vec<f64>, UqError> {
        let mut out = vec![0.0; self.n_terms * n_outputs];
        self.fit_into(values, n_outputs, &mut out)?;
        Ok(out)
    }

    /// The map as a dense `n_terms × n_points` matrix, row-major (allocates `n_terms · n_points`;
    /// for tests and diagnostics).
    pub fn to_dense(&self) -> Vec<f64> {
        match &self.map {
            Map::Dense(ct) => {
                // Column t of Cᵀ is row t of C.
                ct.as_slice().to_vec()
            }
            Map::Triangular { .. } => {
                // Fit the identity: column p of C is the fit of the unit vector e_p.
                let n = self.n_points;
                let mut identity = vec![0.0; n * n];
                for p in 0..n {
                    identity[p * n + p] = 1.0;
                }
                let mut out = vec![0.0; self.n_terms * n];
                // The identity is finite and sized to match: this cannot fail.
                if self.fit_into(&identity, n, &mut out).is_err() {
                    unreachable!("identity fit has consistent sizes");
                }
                out
            }
        }
    }

    /// The triangular map's two factors; a dense map has none (an error).
    fn factors(&self) -> Result<(&SparseRows, &SparseRows), UqError> {
        match &self.map {
            Map::Triangular { lower, upper } => Ok((lower, upper)),
            Map::Dense(_) => Err(UqError::Empty {
                what: "fit: factors of a dense map",
            }),
        }
    }

    /// The two steps of [`LinearFit::fit_rows_into`] apart, for a caller that keeps the first
    /// step's rows from one fit to the next (the adaptive design's stages: a sparse grid's first
    /// factor gives each point its hierarchical surplus, which depends only on that point's term
    /// and the points below it, so a grown set's old points keep theirs; `crate::uq::sparse_grid`).
    /// Step 1: rows `terms` of the first factor applied to the points' rows,
    /// `out[k, :] = Σ_p lower[terms[k], p] · x_row(p)`, `out` row-major `terms.len() × width`;
    /// each row the bits [`LinearFit::fit_rows_into`] computes it with.
    ///
    /// Errors: a dense map (it has no factors), a term past the last, a length that disagrees.
    pub(crate) fn first_factor_rows_into<'x>(
        &self,
        terms: &[usize],
        x_row: impl Fn(usize) -> &'x [f64],
        width: usize,
        out: &mut [f64],
    ) -> Result<(), UqError> {
        let (lower, _) = self.factors()?;
        if let Some(&term) = terms.iter().find(|&&t| t >= self.n_terms) {
            return Err(UqError::WrongLength {
                what: "fit: a term of the first factor",
                expected: self.n_terms,
                got: term,
            });
        }
        if out.len() != terms.len() * width {
            return Err(UqError::WrongLength {
                what: "fit: out (terms × columns)",
                expected: terms.len() * width,
                got: out.len(),
            });
        }
        dispatch_row_updates(
            #[inline(always)]
            || apply_sparse_rows(lower, |k| terms[k], &x_row, width, out),
        );
        Ok(())
    }

    /// Step 2 of [`LinearFit::first_factor_rows_into`]: the second factor applied to every
    /// term's row of step 1 (`y_row(t)`, each `width` long), `out` row-major `n_terms × width`:
    /// the coefficients, the bits [`LinearFit::fit_rows_into`] gives.
    ///
    /// Errors: a dense map, a length that disagrees.
    pub(crate) fn second_factor_into<'y>(
        &self,
        y_row: impl Fn(usize) -> &'y [f64],
        width: usize,
        out: &mut [f64],
    ) -> Result<(), UqError> {
        let (_, upper) = self.factors()?;
        if out.len() != self.n_terms * width {
            return Err(UqError::WrongLength {
                what: "fit: out (n_terms × columns)",
                expected: self.n_terms * width,
                got: out.len(),
            });
        }
        dispatch_row_updates(
            #[inline(always)]
            || apply_upper_from(upper, &y_row, width, out),
        );
        Ok(())
    }

    /// Row sums `Σ_p |C[t, p]|` per term (the ∞-norm of the map is their maximum), computed in
    /// blocks of points so the memory stays `n_terms × BLOCK`.
    pub(crate) fn abs_row_sums(&self) -> Vec<f64> {
        const BLOCK: usize = 256;
        let mut sums = vec![0.0; self.n_terms];
        match &self.map {
            Map::Dense(ct) => {
                for (t, column) in ct.column_iter().enumerate() {
                    sums[t] = column.iter().map(|v| v.abs()).sum();
                }
            }
            Map::Triangular { lower, upper } => {
                let n = self.n_points;
                let mut unit = vec![0.0; n * BLOCK];
                let mut out = vec![0.0; self.n_terms * BLOCK];
                for p0 in (0..n).step_by(BLOCK) {
                    let b = BLOCK.min(n - p0);
                    let unit = &mut unit[..n * b];
                    unit.fill(0.0);
                    for j in 0..b {
                        unit[(p0 + j) * b + j] = 1.0;
                    }
                    let out = &mut out[..self.n_terms * b];
                    apply_triangular(lower, upper, |j| &unit[j * b..(j + 1) * b], b, out);
                    for (t, row) in out.chunks_exact(b).enumerate() {
                        sums[t] += row.iter().map(|v| v.abs()).sum::<f64>();
                    }
                }
            }
        }
        sums
    }
}

/// `out = upper · (lower · x)` (module doc) for `width` columns, row j of `x` given by
/// `x_row(j)`: [`apply_sparse_rows`] then [`apply_upper_in_place`], with AVX2 when the CPU has
/// it. Both are row updates `y ← y + v·x` over the columns, element by element: four lanes per
/// instruction instead of SSE2's two give the same bits (neither contracts into FMA;
/// docs/batch.md §3), and the adaptive design's fits of 16 records at once (144 columns on the
/// ur5) are almost all such updates.
fn apply_triangular<'x>(
    lower: &SparseRows,
    upper: &SparseRows,
    x_row: impl Fn(usize) -> &'x [f64],
    width: usize,
    out: &mut [f64],
) {
    dispatch_row_updates(
        #[inline(always)]
        || {
            apply_sparse_rows(lower, |i| i, &x_row, width, out);
            apply_upper_in_place(upper, width, out);
        },
    );
}

/// Runs `updates` (loops of row updates, inlined into it) compiled for AVX2 when the CPU has it
/// ([`apply_triangular`]: the same bits), else as they are.
#[inline(always)]
fn dispatch_row_updates(updates: impl FnOnce()) {
    match Isa::best().kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2
            // (`Isa::avx2`), which is all `run_with_avx2` requires.
            unsafe { run_with_avx2(updates) }
        }
        _ => updates(),
    }
}

/// `updates` compiled for AVX2 (the loops inlined into it, which the compiler widens to four
/// lanes).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_with_avx2(updates: impl FnOnce()) {
    updates()
}

/// `out[k, :] = Σ_j a[row_of(k), j] · x[j, :]` for sparse `a`, row j of `x` given by `x_row(j)`
/// (each `width` long), row-major blocks of `width` columns.
#[inline(always)]
fn apply_sparse_rows<'x>(
    a: &SparseRows,
    row_of: impl Fn(usize) -> usize,
    x_row: impl Fn(usize) -> &'x [f64],
    width: usize,
    out: &mut [f64],
) {
    for (k, dst) in out.chunks_exact_mut(width).enumerate() {
        dst.fill(0.0);
        let (cols, vals) = a.row(row_of(k));
        for (&j, &v) in cols.iter().zip(vals) {
            for (d, &s) in dst.iter_mut().zip(x_row(j as usize)) {
                *d += v * s;
            }
        }
    }
}

/// `y[i, :] = Σ_{j ≥ i} u[i, j] · y[j, :]` in place, rows in increasing order: row i reads only
/// rows j ≥ i, which are not yet overwritten (the diagonal entry is read before the write).
#[inline(always)]
fn apply_upper_in_place(u: &SparseRows, width: usize, y: &mut [f64]) {
    for i in 0..u.n_rows() {
        let (cols, vals) = u.row(i);
        // The diagonal (if present) is the first entry: columns are sorted ascending.
        let (head, tail) = y.split_at_mut((i + 1) * width);
        let row = &mut head[i * width..];
        let diag = if cols.first() == Some(&(i as u32)) {
            vals[0]
        } else {
            0.0
        };
        row.iter_mut().for_each(|v| *v *= diag);
        for (&j, &v) in cols.iter().zip(vals) {
            let j = j as usize;
            if j == i {
                continue;
            }
            let src = &tail[(j - i - 1) * width..(j - i) * width];
            for (d, &s) in row.iter_mut().zip(src) {
                *d += v * s;
            }
        }
    }
}

/// [`apply_upper_in_place`] from rows kept elsewhere (`y_row(j)`) into `out`: the same
/// operations in the same order (the diagonal's product first, then the other entries'), so the
/// same bits.
#[inline(always)]
fn apply_upper_from<'y>(
    u: &SparseRows,
    y_row: impl Fn(usize) -> &'y [f64],
    width: usize,
    out: &mut [f64],
) {
    for (i, row) in out.chunks_exact_mut(width).enumerate() {
        let (cols, vals) = u.row(i);
        let diag = if cols.first() == Some(&(i as u32)) {
            vals[0]
        } else {
            0.0
        };
        for (d, &s) in row.iter_mut().zip(y_row(i)) {
            *d = s * diag;
        }
        for (&j, &v) in cols.iter().zip(vals) {
            let j = j as usize;
            if j == i {
                continue;
            }
            for (d, &s) in row.iter_mut().zip(y_row(j)) {
                *d += v * s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// The fit's row updates give the same bits with AVX2 (when this CPU has it) as with the
    /// baseline instruction set, at widths with and without a partial vector.
    #[test]
    fn the_triangular_fit_gives_the_same_bits_with_any_instruction_set() {
        use crate::uq::{MultiIndexSet, SparseGrid};
        use std::sync::Arc;
        let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(5, 4).unwrap())).unwrap();
        let Map::Triangular { lower, upper } = &grid.fit().map else {
            panic!("a sparse grid's fit has triangular factors")
        };
        let n = grid.n_points();
        let mut rng = SplitMix64::new(57);
        for width in [1, 3, 9, 144] {
            let x: Vec<f64> = (0..n * width).map(|_| rng.uniform(-3.0, 3.0)).collect();
            let x_row = |j: usize| &x[j * width..(j + 1) * width];
            let mut dispatched = vec![0.0; upper.n_rows() * width];
            apply_triangular(lower, upper, x_row, width, &mut dispatched);
            let mut baseline = vec![0.0; upper.n_rows() * width];
            apply_sparse_rows(lower, |i| i, x_row, width, &mut baseline);
            apply_upper_in_place(upper, width, &mut baseline);
            let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<u64>>();
            assert_eq!(bits(&dispatched), bits(&baseline), "width {width}");
        }
    }

    /// The fit in two steps gives the bits of the fit in one, and a point's row of the first
    /// step is the same in a grown set's grid (the adaptive design's stages keep it): a set, a
    /// larger downward-closed set containing it, runs stored in the order their terms came.
    #[test]
    fn the_two_factor_steps_give_the_fit_and_a_grown_set_keeps_its_first_rows() {
        use crate::uq::{MultiIndexSet, SparseGrid};
        use std::sync::Arc;
        let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<u64>>();
        let small = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(4, 2).unwrap())).unwrap();
        let grown = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(4, 4).unwrap())).unwrap();
        let width = 11;
        let mut rng = SplitMix64::new(58);
        // Runs in the order their terms came: the small set's, then the rest of the grown one's.
        let mut run_terms: Vec<Vec<crate::uq::Factor>> = (0..small.n_points())
            .map(|t| small.set().term(t).to_vec())
            .collect();
        for t in 0..grown.n_points() {
            let term = grown.set().term(t);
            if small.set().index_of(term).is_none() {
                run_terms.push(term.to_vec());
            }
        }
        let runs: Vec<Vec<f64>> = run_terms
            .iter()
            .map(|_| (0..width).map(|_| rng.uniform(-3.0, 3.0)).collect())
            .collect();
        let mut first_rows: Vec<Vec<f64>> = Vec::new();
        for grid in [&small, &grown] {
            let fit = grid.fit();
            let n = grid.n_points();
            // Grid point t's run.
            let run_of: Vec<usize> = (0..n)
                .map(|t| {
                    let term = grid.set().term(t);
                    run_terms.iter().position(|r| r.as_slice() == term).unwrap()
                })
                .collect();
            let x_row = |p: usize| runs[run_of[p]].as_slice();
            let every: Vec<usize> = (0..n).collect();
            let mut first = vec![0.0; n * width];
            fit.first_factor_rows_into(&every, x_row, width, &mut first)
                .unwrap();
            let mut two_steps = vec![0.0; n * width];
            fit.second_factor_into(
                |t| &first[t * width..(t + 1) * width],
                width,
                &mut two_steps,
            )
            .unwrap();
            let rows: Vec<&[f64]> = (0..n).map(x_row).collect();
            let mut one_step = vec![0.0; fit.n_terms() * width];
            fit.fit_rows_into(&rows, &mut one_step).unwrap();
            assert_eq!(bits(&two_steps), bits(&one_step), "{n} points");
            // The first step's row of each run, by run.
            let mut by_run = vec![Vec::new(); n];
            for (t, row) in first.chunks_exact(width).enumerate() {
                by_run[run_of[t]] = row.to_vec();
            }
            // Selected rows alone are the same rows.
            let some: Vec<usize> = (0..n).step_by(3).collect();
            let mut selected = vec![0.0; some.len() * width];
            fit.first_factor_rows_into(&some, x_row, width, &mut selected)
                .unwrap();
            for (k, &t) in some.iter().enumerate() {
                assert_eq!(
                    bits(&selected[k * width..(k + 1) * width]),
                    bits(&first[t * width..(t + 1) * width])
                );
            }
            first_rows.push(by_run.concat());
        }
        let kept = small.n_points() * width;
        assert_eq!(bits(&first_rows[1][..kept]), bits(&first_rows[0]));
        // A dense map has no factors; a term past the last is an error.
        let dense = LinearFit::dense_transposed(nalgebra::DMatrix::identity(2, 2));
        assert!(dense
            .first_factor_rows_into(&[0], |_| &runs[0][..1], 1, &mut [0.0])
            .is_err());
        let fit = small.fit();
        assert!(fit
            .first_factor_rows_into(&[small.n_points()], |_| &runs[0][..1], 1, &mut [0.0])
            .is_err());
    }

    #[test]
    fn fitting_rows_at_once_gives_each_column_to_the_bit() {
        use crate::uq::{MultiIndexSet, SparseGrid};
        use std::sync::Arc;
        let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(6, 3).unwrap())).unwrap();
        let fit = grid.fit();
        let (n, width) = (fit.n_points(), 37);
        let mut rng = SplitMix64::new(41);
        let stored: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..width).map(|_| rng.uniform(-3.0, 3.0)).collect())
            .collect();
        let rows: Vec<&[f64]> = stored.iter().map(Vec::as_slice).collect();
        let mut all = vec![0.0; fit.n_terms() * width];
        fit.fit_rows_into(&rows, &mut all).unwrap();
        for column in [0, 1, 17, width - 1] {
            let alone: Vec<f64> = stored.iter().map(|row| row[column]).collect();
            let want = fit.fit(&alone, 1).unwrap();
            for (t, &w) in want.iter().enumerate() {
                assert_eq!(all[t * width + column].to_bits(), w.to_bits(), "term {t}");
            }
        }
        // Bad input is refused, naming what.
        assert!(fit.fit_rows_into(&rows[1..], &mut all).is_err());
        let mut short = stored[3].clone();
        short.pop();
        let mut bad = rows.clone();
        bad[3] = &short;
        assert!(fit.fit_rows_into(&bad, &mut all).is_err());
        let mut nan = stored[2].clone();
        nan[5] = f64::NAN;
        let mut bad = rows.clone();
        bad[2] = &nan;
        assert!(matches!(
            fit.fit_rows_into(&bad, &mut all),
            Err(UqError::NonFinite { index, .. }) if index == 2 * width + 5
        ));
    }

    #[test]
    fn dense_fit_is_a_matrix_product() {
        let mut rng = SplitMix64::new(3);
        for (terms, points, outputs) in [(7, 9, 1), (7, 9, 3), (20, 31, 12), (3, 3, 40)] {
            let c = DMatrix::from_fn(terms, points, |_, _| rng.uniform(-1.0, 1.0));
            let fit = LinearFit::dense_transposed(c.transpose());
            let values: Vec<f64> = (0..points * outputs)
                .map(|_| rng.uniform(-1.0, 1.0))
                .collect();
            let out = fit.fit(&values, outputs).unwrap();
            for t in 0..terms {
                for o in 0..outputs {
                    let want: f64 = (0..points)
                        .map(|p| c[(t, p)] * values[p * outputs + o])
                        .sum();
                    assert!((out[t * outputs + o] - want).abs() < 1e-13);
                }
            }
            let dense = fit.to_dense();
            assert_eq!(dense[points + 2], c[(1, 2)]);
            let sums = fit.abs_row_sums();
            assert!((sums[0] - c.row(0).iter().map(|v| v.abs()).sum::<f64>()).abs() < 1e-14);
        }
    }

    #[test]
    fn triangular_fit_matches_its_dense_product() {
        // lower: 4 terms × 4 points; upper: 4 × 4 upper triangular with a missing diagonal.
        let lower = SparseRows {
            starts: vec![0, 1, 3, 5, 7],
            cols: vec![0, 0, 1, 0, 2, 1, 3],
            vals: vec![1.0, -1.0, 2.0, 0.5, 0.25, 3.0, -2.0],
        };
        let upper = SparseRows {
            starts: vec![0, 3, 4, 6, 7],
            cols: vec![0, 2, 3, 1, 2, 3, 3],
            vals: vec![1.0, 0.5, -0.5, 2.0, 1.5, 4.0, 0.75],
        };
        let fit = LinearFit::triangular(4, lower.clone(), upper.clone());
        let dense = |a: &SparseRows, n: usize| {
            let mut m = DMatrix::zeros(a.n_rows(), n);
            for i in 0..a.n_rows() {
                let (cols, vals) = a.row(i);
                for (&j, &v) in cols.iter().zip(vals) {
                    m[(i, j as usize)] = v;
                }
            }
            m
        };
        let c = dense(&upper, 4) * dense(&lower, 4);
        let got = fit.to_dense();
        for t in 0..4 {
            for p in 0..4 {
                assert!((got[t * 4 + p] - c[(t, p)]).abs() < 1e-15, "({t}, {p})");
            }
        }
        for (t, sum) in fit.abs_row_sums().iter().enumerate() {
            assert!((sum - c.row(t).iter().map(|v| v.abs()).sum::<f64>()).abs() < 1e-14);
        }
        assert_eq!(fit.stored_entries(), 14);
    }

    #[test]
    fn refuses_bad_input() {
        let fit = LinearFit::dense_transposed(DMatrix::identity(3, 2));
        let mut out = vec![0.0; 4];
        assert!(fit.fit_into(&[0.0; 6], 0, &mut out).is_err());
        assert!(fit.fit_into(&[0.0; 5], 2, &mut out).is_err());
        assert!(fit.fit_into(&[0.0; 6], 2, &mut out[..3]).is_err());
        let mut values = [0.0; 6];
        values[4] = f64::NAN;
        assert!(matches!(
            fit.fit_into(&values, 2, &mut out),
            Err(UqError::NonFinite { index: 4, .. })
        ));
    }
}
