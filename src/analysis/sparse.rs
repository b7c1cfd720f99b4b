//! The designs that grow polynomially in d (docs/high-dimension.md, docs/method.md §10): a
//! downward-closed set of Legendre terms, the points where the model runs, and the linear map from
//! the values there to the coefficients.
//!
//! - `sparse`: interpolation on the nested Leja sparse grid of the set (one run per term);
//! - `regression`: least squares on a scrambled Sobol' design with twice as many runs as terms
//!   ([`REGRESSION_OVERSAMPLING`]), the centre included.
//!
//! Sets: total degree k in every parameter, or the screened set of [`AutoDesign::Screened`] built
//! from a ranking of the parameters.

use super::auto::{AutoDesign, BASE_ORDER};
use crate::uq::{sobol_design, LinearFit, MultiIndexSet, Regression, SparseGrid, UqError};
use std::collections::HashSet;
use std::sync::Arc;

/// Runs per term of a regression design: the least oversampling at which least squares on random
/// or low-discrepancy points is stable (Cohen, Davenport & Leviatan 2013; docs/high-dimension.md).
pub const REGRESSION_OVERSAMPLING: usize = 2;

/// Seed of the regression design's Sobol' scrambling (fixed: studies repeat).
pub const REGRESSION_SEED: u32 = 0x5eed;

/// A sparse design, ready to fit.
#[derive(Debug)]
pub enum SparseDesign {
    /// Interpolation on the Leja sparse grid of the set.
    Grid(SparseGrid),
    /// Least squares on Sobol' points.
    Regression(Regression),
}

impl SparseDesign {
    /// Interpolation on total degree `order` in all `dim` parameters.
    pub fn total_degree(dim: usize, order: usize) -> Result<SparseDesign, UqError> {
        let set = Arc::new(MultiIndexSet::total_degree(dim, order)?);
        Ok(SparseDesign::Grid(SparseGrid::new(set)?))
    }

    /// Least squares on total degree `order` with [`REGRESSION_OVERSAMPLING`] runs per term.
    pub fn regression(dim: usize, order: usize) -> Result<SparseDesign, UqError> {
        let set = Arc::new(MultiIndexSet::total_degree(dim, order)?);
        let points = sobol_design(
            dim,
            REGRESSION_OVERSAMPLING * set.len(),
            REGRESSION_SEED,
            &[],
        )?;
        Ok(SparseDesign::Regression(Regression::new(set, points)?))
    }

    /// Interpolation on a screened set (see [`AutoDesign::Screened`]); `ranking` lists the
    /// parameters from the most important.
    pub fn screened(
        dim: usize,
        design: &AutoDesign,
        ranking: &[usize],
    ) -> Result<SparseDesign, UqError> {
        let AutoDesign::Screened { order, top, pairs } = *design else {
            return SparseDesign::total_degree(dim, BASE_ORDER);
        };
        let set = Arc::new(screened_set(dim, order, top, pairs, ranking)?);
        Ok(SparseDesign::Grid(SparseGrid::new(set)?))
    }

    /// The design's name in summaries: `sparse` or `regression`.
    pub fn name(&self) -> &'static str {
        match self {
            SparseDesign::Grid(_) => "sparse",
            SparseDesign::Regression(_) => "regression",
        }
    }

    /// The term set.
    pub fn set(&self) -> &Arc<MultiIndexSet> {
        match self {
            SparseDesign::Grid(g) => g.set(),
            SparseDesign::Regression(r) => r.set(),
        }
    }

    /// The points, row-major `n × d`.
    pub fn points(&self) -> &[f64] {
        match self {
            SparseDesign::Grid(g) => g.points(),
            SparseDesign::Regression(r) => r.points(),
        }
    }

    /// Number of runs.
    pub fn n_points(&self) -> usize {
        match self {
            SparseDesign::Grid(g) => g.n_points(),
            SparseDesign::Regression(r) => r.n_points(),
        }
    }

    /// Values (`n_points × outputs`) → coefficients (`terms × outputs`).
    pub fn fit(&self) -> &LinearFit {
        match self {
            SparseDesign::Grid(g) => g.fit(),
            SparseDesign::Regression(r) => r.fit(),
        }
    }

    /// The condition number of the design's basis matrix (κ∞ for the grid, κ₂ for regression;
    /// orthonormal Legendre basis).
    pub fn condition_number(&self) -> f64 {
        match self {
            SparseDesign::Grid(g) => g.condition_number(),
            SparseDesign::Regression(r) => r.condition_number(),
        }
    }
}

/// The screened set: constant, degrees 1..=BASE_ORDER of every parameter, the pairwise products
/// among the first `pairs` of `ranking`, and total degree `order` among its first `top`.
pub fn screened_set(
    dim: usize,
    order: usize,
    top: usize,
    pairs: usize,
    ranking: &[usize],
) -> Result<MultiIndexSet, UqError> {
    let mut terms: Vec<Vec<(usize, usize)>> = vec![Vec::new()];
    let mut seen: HashSet<Vec<(usize, usize)>> = HashSet::new();
    seen.insert(Vec::new());
    let mut push = |mut term: Vec<(usize, usize)>, terms: &mut Vec<Vec<(usize, usize)>>| {
        term.sort_unstable();
        if seen.insert(term.clone()) {
            terms.push(term);
        }
    };
    for r in 0..dim {
        for degree in 1..=BASE_ORDER {
            push(vec![(r, degree)], &mut terms);
        }
    }
    let pairs: Vec<usize> = ranking.iter().copied().take(pairs).collect();
    for (i, &a) in pairs.iter().enumerate() {
        for &b in &pairs[i + 1..] {
            push(vec![(a, 1), (b, 1)], &mut terms);
        }
    }
    let top: Vec<usize> = ranking.iter().copied().take(top).collect();
    if !top.is_empty() {
        let local = MultiIndexSet::total_degree(top.len(), order)?;
        for t in 0..local.len() {
            let term: Vec<(usize, usize)> = local
                .term(t)
                .iter()
                .map(|f| (top[f.dim as usize], f.degree as usize))
                .collect();
            push(term, &mut terms);
        }
    }
    MultiIndexSet::from_terms(dim, &terms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::auto::screened_terms;

    #[test]
    fn the_screened_set_has_the_closed_form_size_and_follows_the_ranking() {
        let ranking: Vec<usize> = (0..12).rev().collect();
        for (top, pairs) in [(0, 12), (3, 12), (5, 7), (12, 12), (2, 0)] {
            let set = screened_set(12, 4, top, pairs, &ranking).unwrap();
            assert_eq!(
                set.len(),
                screened_terms(12, 4, top, pairs),
                "top {top} pairs {pairs}"
            );
        }
        let set = screened_set(12, 4, 2, 0, &ranking).unwrap();
        // The two most important (11 and 10) reach degree 4 together; the least does not.
        assert!(set
            .index_of_dense(&[0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 2])
            .is_some());
        assert!(set
            .index_of_dense(&[3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0])
            .is_none());
        // Without pairs there is no product of two parameters outside the top.
        assert!(set
            .index_of_dense(&[1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0])
            .is_none());
    }

    #[test]
    fn designs_have_one_run_per_term_or_twice_as_many() {
        let grid = SparseDesign::total_degree(6, 4).unwrap();
        assert_eq!(grid.n_points(), 210);
        assert_eq!(grid.points().len(), 210 * 6);
        let regression = SparseDesign::regression(3, 2).unwrap();
        assert_eq!(regression.n_points(), 20);
        assert_eq!(regression.name(), "regression");
    }
}
