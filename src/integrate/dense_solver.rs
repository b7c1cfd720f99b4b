//! Small dense factorisations done in place in preallocated storage, so that a time step allocates
//! nothing (nalgebra's `LU::new` / `Cholesky::new` take their matrix by value).
//!
//! Sizes here are `nv + m ≤ ~50`: a plain right-looking LU with partial pivoting and a plain
//! Cholesky (the crate's ones, [`crate::linalg::lu`] and [`crate::linalg::cholesky`]) are as fast
//! as anything for these sizes and keep the workspace explicit.

use nalgebra::{DMatrix, DVector};

use crate::linalg::{cholesky, lu};

/// A pivot smaller than this fraction of the matrix's largest entry means "singular to working
/// precision". A matrix that close to singular (condition ≳ 1e13) leaves no correct digits at the
/// Newton tolerances we use, and dependent constraint rows give pivots at the 1e-16 rounding level,
/// well below it.
pub const SINGULAR_PIVOT_RELATIVE: f64 = 1e-13;

/// Where a factorisation broke down.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Breakdown {
    /// Elimination step (row) at which the pivot was too small.
    pub index: usize,
    /// |pivot| / max |entry| (for Cholesky: the diagonal before its square root, relative).
    pub pivot_relative: f64,
}

/// Which factorisation a [`DenseSolver`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FactorKind {
    /// LU with partial pivoting: general square matrices (saddle-point systems with constraints).
    Lu,
    /// Cholesky `L Lᵀ`: symmetric positive definite matrices (the Newton matrix of a tree).
    Cholesky,
}

/// An `n × n` factorisation held in preallocated storage.
#[derive(Debug, Clone)]
pub(crate) struct DenseSolver {
    factors: DMatrix<f64>,
    pivots: Vec<usize>,
    kind: FactorKind,
}

impl DenseSolver {
    /// Storage for `n × n` systems (the only allocation).
    pub fn new(n: usize, kind: FactorKind) -> Self {
        Self {
            factors: DMatrix::zeros(n, n),
            pivots: vec![0; n],
            kind,
        }
    }

    /// The dimension `n` of the systems it solves.
    pub fn dimension(&self) -> usize {
        self.factors.nrows()
    }

    /// Factorises `a` (dimension `n × n`; only the lower triangle is read for Cholesky), overwriting
    /// the stored factors. Allocation-free.
    pub fn factor(&mut self, a: &DMatrix<f64>) -> Result<(), Breakdown> {
        assert_eq!(
            self.factors.shape(),
            a.shape(),
            "DenseSolver::factor: the matrix has the solver's dimension"
        );
        self.factors.as_mut_slice().copy_from_slice(a.as_slice());
        let scale = max_abs(a.as_slice());
        if scale == 0.0 && !a.is_empty() {
            return Err(Breakdown {
                index: 0,
                pivot_relative: 0.0,
            });
        }
        match self.kind {
            FactorKind::Lu => self.factor_lu(scale),
            FactorKind::Cholesky => self.factor_cholesky(scale),
        }
    }

    fn factor_lu(&mut self, scale: f64) -> Result<(), Breakdown> {
        let n = self.factors.nrows();
        lu::factor_in_place(
            self.factors.as_mut_slice(),
            n,
            &mut self.pivots,
            SINGULAR_PIVOT_RELATIVE * scale,
        )
        .map_err(|failure| Breakdown {
            index: failure.index,
            pivot_relative: failure.magnitude / scale,
        })
    }

    fn factor_cholesky(&mut self, scale: f64) -> Result<(), Breakdown> {
        let n = self.factors.nrows();
        cholesky::factor_in_place(
            self.factors.as_mut_slice(),
            n,
            SINGULAR_PIVOT_RELATIVE * scale,
        )
        .map_err(|failure| Breakdown {
            index: failure.index,
            pivot_relative: failure.pivot / scale,
        })
    }

    /// Solves `A x = b` in place (`b` of dimension `n`, overwritten with `x`) with the last successful
    /// factorisation. Allocation-free.
    pub fn solve_in_place(&self, b: &mut DVector<f64>) {
        let a = &self.factors;
        let n = a.nrows();
        match self.kind {
            FactorKind::Lu => lu::solve_in_place(a.as_slice(), n, &self.pivots, b.as_mut_slice()),
            FactorKind::Cholesky => cholesky::solve_in_place(a.as_slice(), n, b.as_mut_slice()),
        }
    }
}

/// Index of the first non-finite entry (column-major for matrices), if any. The common case, every
/// entry finite, is one pass with no early exit (which the compiler vectorises); the index is
/// searched for only when there is one.
pub(crate) fn first_non_finite(x: &[f64]) -> Option<usize> {
    let all_finite = x.iter().fold(true, |finite, v| finite & v.is_finite());
    if all_finite {
        None
    } else {
        x.iter().position(|v| !v.is_finite())
    }
}

/// `max |x_i|` over the entries that are not NaN (0 for none): the same value as folding with
/// `f64::max`, which skips NaN, but in four independent accumulators (a maximum is exact, so the
/// order does not matter) rather than one chain of dependent comparisons.
fn max_abs(x: &[f64]) -> f64 {
    let magnitude = |v: f64| {
        let a = v.abs();
        if a.is_nan() {
            0.0
        } else {
            a
        }
    };
    let mut lanes = [0.0_f64; 4];
    let mut chunks = x.chunks_exact(4);
    for chunk in &mut chunks {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            let a = magnitude(*v);
            if a > *lane {
                *lane = a;
            }
        }
    }
    for v in chunks.remainder() {
        let a = magnitude(*v);
        if a > lanes[0] {
            lanes[0] = a;
        }
    }
    lanes.iter().fold(0.0, |acc: f64, lane| acc.max(*lane))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Agreement of an in-place solve with nalgebra's own LU on a well-conditioned matrix.
    const SOLVE_TOL: f64 = 1e-12;

    /// `max_abs` equals the `f64::max` fold it replaced, bit for bit, NaN and infinities included,
    /// for every length around the four accumulators' chunk.
    #[test]
    fn max_abs_equals_the_sequential_fold() {
        let values = [
            0.5,
            -3.25,
            f64::NAN,
            1e-300,
            -0.0,
            7.0,
            f64::INFINITY,
            -1e308,
            2.0,
            -7.5,
            f64::NAN,
        ];
        for len in 0..=values.len() {
            for start in 0..(values.len() - len).min(3) + 1 {
                let x = &values[start..start + len];
                let sequential = x.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
                assert_eq!(max_abs(x).to_bits(), sequential.to_bits(), "{x:?}");
            }
        }
        assert_eq!(max_abs(&[f64::NAN, f64::NAN]), 0.0);
        let finite = [1.0, -9.5, 3.0, 2.0, 0.1];
        assert_eq!(max_abs(&finite), 9.5);
        assert_eq!(first_non_finite(&finite), None);
        assert_eq!(
            first_non_finite(&[1.0, 2.0, f64::NEG_INFINITY, f64::NAN]),
            Some(2)
        );
    }

    #[test]
    fn lu_and_cholesky_solve_small_systems() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let b = DVector::from_column_slice(&[1.0, -2.0, 0.5]);
        let expected = a.clone().lu().solve(&b).expect("invertible");
        for kind in [FactorKind::Lu, FactorKind::Cholesky] {
            let mut s = DenseSolver::new(3, kind);
            s.factor(&a).expect("regular");
            let mut x = b.clone();
            s.solve_in_place(&mut x);
            assert!((x - &expected).amax() < SOLVE_TOL, "{kind:?}");
        }
        // A saddle-point matrix needs the pivoting.
        let k = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 1.0, 0.0, 2.0, 1.0, 1.0, 1.0, 0.0]);
        let mut s = DenseSolver::new(3, FactorKind::Lu);
        s.factor(&k).expect("regular");
        let mut x = b.clone();
        s.solve_in_place(&mut x);
        assert!((&k * x - &b).amax() < SOLVE_TOL);
    }

    #[test]
    fn singular_matrices_are_reported() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        let mut s = DenseSolver::new(2, FactorKind::Lu);
        let e = s.factor(&a).unwrap_err();
        assert_eq!(e.index, 1);
        let mut c = DenseSolver::new(2, FactorKind::Cholesky);
        assert!(c.factor(&a).is_err());
    }
}
