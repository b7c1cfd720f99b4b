//! Tensor designs: which model runs to make (the (k+1)^d tensor Gauss grid in standard coordinates
//! ξ ∈ [-1, 1]^d) and which expansion terms to keep (full tensor or total-degree truncation).
//!
//! Conventions, used by every other file of `uq`:
//! - **Point order**: point `p` has grid multi-index `(j_1, …, j_d)` with
//!   `p = Σ_r j_r · m^{d−r}` (row-major: `ξ_1` varies slowest, `ξ_d` fastest), `m = k + 1`, and
//!   coordinates `ξ_r = nodes[j_r]` (1-D Gauss nodes, ascending).
//! - **Dense term order**: the same row-major numbering of degree multi-indices `(i_1, …, i_d)`,
//!   each `i_r ≤ k`: term `t = Σ_r i_r · m^{d−r}`, basis function `Π_r φ_{i_r}(ξ_r)`.
//! - **Kept terms**: all dense terms (tensor), or those with `Σ i_r ≤ k` (total), in increasing dense
//!   position.
//!
//! Does not: fit (see [`crate::uq::projection`]) or map to physical units (see
//! [`crate::uq::interval_map`]).

use crate::uq::basis::{Family, MAX_ORDER};
use crate::uq::error::UqError;

/// Largest number of points in a design grid or terms in a dense coefficient tensor: 2²² ≈ 4.2 M
/// (d = 8 at k = 5 is 1.7 M). Bounds the memory of fit and scan work buffers (≈ 32 MiB each).
pub const MAX_TENSOR_SIZE: usize = 1 << 22;

/// Which multi-indices a multivariate expansion keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Truncation {
    /// Full tensor: every `(i_1, …, i_d)` with each `i_r ≤ k` — `(k+1)^d` terms.
    Tensor,
    /// Total degree: `Σ_r i_r ≤ k` — `C(d+k, k)` terms (fitted on the same tensor grid).
    Total,
}

impl Truncation {
    /// The "degree" of a multi-index that the truncation limits by `k`: `max_r i_r` for tensor,
    /// `Σ_r i_r` for total.
    pub fn degree(self, multi_index: &[usize]) -> usize {
        match self {
            Truncation::Tensor => multi_index.iter().copied().max().unwrap_or(0),
            Truncation::Total => multi_index.iter().sum(),
        }
    }
}

/// `per_dim^dim` if it does not exceed `max` (and does not overflow).
pub(crate) fn checked_grid_size(
    what: &'static str,
    per_dim: usize,
    dim: usize,
    max: usize,
) -> Result<usize, UqError> {
    let too_large = UqError::GridTooLarge {
        what,
        per_dim,
        dim,
        max,
    };
    let exp = u32::try_from(dim).map_err(|_| too_large.clone())?;
    match per_dim.checked_pow(exp) {
        Some(n) if n <= max => Ok(n),
        _ => Err(too_large),
    }
}

/// Writes the row-major multi-index of `flat` (each digit < `base`) into `out` (length d).
pub(crate) fn decode_multi_index(mut flat: usize, base: usize, out: &mut [usize]) {
    for digit in out.iter_mut().rev() {
        *digit = flat % base;
        flat /= base;
    }
}

/// Calls `f(flat, multi_index)` for every row-major multi-index of `dim` digits in `0..base`, in
/// increasing `flat` order (an odometer: no division per index). Test helper.
#[cfg(test)]
pub(crate) fn for_each_multi_index(base: usize, dim: usize, mut f: impl FnMut(usize, &[usize])) {
    let mut idx = vec![0; dim];
    let total = base.pow(dim as u32);
    for flat in 0..total {
        f(flat, &idx);
        for digit in idx.iter_mut().rev() {
            *digit += 1;
            if *digit < base {
                break;
            }
            *digit = 0;
        }
    }
}

/// A tensor Gauss design of order `k` in `d` parameters: the (k+1)^d model runs and the kept terms.
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    family: Family,
    dim: usize,
    order: usize,
    truncation: Truncation,
    nodes: Vec<f64>,
    /// Nodes per dimension when they are not the family's Gauss nodes (a nested element's
    /// design, docs/method.md §12): `axis_nodes[r]` holds k + 1 distinct ascending nodes in
    /// [-1, 1]; `None` means `nodes` along every dimension.
    axis_nodes: Option<Vec<Vec<f64>>>,
    n_points: usize,
    kept: Vec<usize>,
}

impl Design {
    /// A design for `dim` parameters, polynomial `order` k per dimension (k + 1 Gauss nodes of
    /// `family` per dimension).
    ///
    /// Errors: `dim == 0`, `order > MAX_ORDER`, or `(order + 1)^dim > MAX_TENSOR_SIZE`.
    ///
    /// ```
    /// use ribbon::uq::{Design, Family, Truncation};
    /// let design = Design::new(Family::Legendre, 2, 4, Truncation::Total).unwrap();
    /// assert_eq!(design.n_points(), 25); // 5 × 5 tensor Gauss grid
    /// assert_eq!(design.n_terms(), 15); // C(2 + 4, 4)
    /// ```
    pub fn new(
        family: Family,
        dim: usize,
        order: usize,
        truncation: Truncation,
    ) -> Result<Design, UqError> {
        if dim == 0 {
            return Err(UqError::ZeroDimension);
        }
        if order > MAX_ORDER {
            return Err(UqError::OrderTooLarge {
                order,
                max: MAX_ORDER,
            });
        }
        let m = order + 1;
        let n_points = checked_grid_size("design", m, dim, MAX_TENSOR_SIZE)?;
        let nodes = family.rule(m)?.nodes().to_vec();
        let kept = match truncation {
            Truncation::Tensor => (0..n_points).collect(),
            Truncation::Total => {
                let mut idx = vec![0; dim];
                (0..n_points)
                    .filter(|&t| {
                        decode_multi_index(t, m, &mut idx);
                        idx.iter().sum::<usize>() <= order
                    })
                    .collect()
            }
        };
        Ok(Design {
            family,
            dim,
            order,
            truncation,
            nodes,
            axis_nodes: None,
            n_points,
            kept,
        })
    }

    /// A Legendre design on a tensor grid of given 1-D nodes, `axis_nodes[r]` along dimension r
    /// (each k + 1 distinct nodes in [-1, 1], ascending): the points of a nested element, some of
    /// them its parent's runs (docs/method.md §12). Its projector interpolates at these nodes.
    ///
    /// Errors: as [`Design::new`], and nodes that are not k + 1 distinct ascending values in
    /// [-1, 1] per dimension ([`UqError::BadNodes`]).
    pub fn with_axis_nodes(
        order: usize,
        truncation: Truncation,
        axis_nodes: Vec<Vec<f64>>,
    ) -> Result<Design, UqError> {
        let mut design = Design::new(Family::Legendre, axis_nodes.len(), order, truncation)?;
        for (dimension, nodes) in axis_nodes.iter().enumerate() {
            let ascending = nodes.windows(2).all(|w| w[0] < w[1]);
            let inside = nodes.iter().all(|x| (-1.0..=1.0).contains(x));
            if nodes.len() != order + 1 || !ascending || !inside {
                return Err(UqError::BadNodes {
                    dimension,
                    expected: order + 1,
                    got: nodes.len(),
                });
            }
        }
        design.axis_nodes = Some(axis_nodes);
        Ok(design)
    }

    /// The 1-D nodes along dimension `r` (ascending, k + 1): the family's Gauss nodes unless the
    /// design was made [`Design::with_axis_nodes`].
    pub fn axis_nodes(&self, r: usize) -> &[f64] {
        match &self.axis_nodes {
            Some(axes) => &axes[r],
            None => &self.nodes,
        }
    }

    /// Whether every dimension uses the family's Gauss nodes.
    pub fn has_gauss_nodes(&self) -> bool {
        self.axis_nodes.is_none()
    }

    /// Polynomial family (and so which Gauss nodes).
    pub fn family(&self) -> Family {
        self.family
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Polynomial order k per dimension.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Truncation of the expansion.
    pub fn truncation(&self) -> Truncation {
        self.truncation
    }

    /// Gauss nodes per dimension: `m = k + 1`.
    pub fn points_per_dim(&self) -> usize {
        self.order + 1
    }

    /// Number of model runs: `(k + 1)^d`.
    pub fn n_points(&self) -> usize {
        self.n_points
    }

    /// Number of kept terms (rows of a [`crate::uq::CoefficientMatrix`]).
    pub fn n_terms(&self) -> usize {
        self.kept.len()
    }

    /// Number of terms of the dense tensor: `(k + 1)^d` (= `n_points`).
    pub fn n_dense_terms(&self) -> usize {
        self.n_points
    }

    /// The family's 1-D Gauss nodes (ascending), length k + 1 (see [`Design::axis_nodes`] for a
    /// design on other nodes).
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// Dense position (row-major multi-index number, see module doc) of each kept term.
    pub fn dense_positions(&self) -> &[usize] {
        &self.kept
    }

    /// All design points in standard coordinates: `n_points × dim`, row-major, point order of the
    /// module doc. Run the model at `x = c + r ξ` (see [`crate::uq::ParameterBox`]).
    pub fn points(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.n_points * self.dim];
        let mut idx = vec![0; self.dim];
        for (p, row) in out.chunks_exact_mut(self.dim).enumerate() {
            decode_multi_index(p, self.points_per_dim(), &mut idx);
            for (r, (x, &j)) in row.iter_mut().zip(&idx).enumerate() {
                *x = self.axis_nodes(r)[j];
            }
        }
        out
    }

    /// Writes design point `p` (standard coordinates) into `xi` (length dim).
    pub fn point_into(&self, p: usize, xi: &mut [f64]) -> Result<(), UqError> {
        self.check_dim("point_into: xi", xi.len())?;
        if p >= self.n_points {
            return Err(UqError::IndexOutOfRange {
                what: "design point",
                index: p,
                len: self.n_points,
            });
        }
        let mut idx = vec![0; self.dim];
        decode_multi_index(p, self.points_per_dim(), &mut idx);
        for (r, (x, &j)) in xi.iter_mut().zip(&idx).enumerate() {
            *x = self.axis_nodes(r)[j];
        }
        Ok(())
    }

    /// Writes the degree multi-index `(i_1, …, i_d)` of kept term `term` into `out` (length dim).
    pub fn multi_index_into(&self, term: usize, out: &mut [usize]) -> Result<(), UqError> {
        self.check_dim("multi_index_into: out", out.len())?;
        let &dense = self.kept.get(term).ok_or(UqError::IndexOutOfRange {
            what: "design term",
            index: term,
            len: self.kept.len(),
        })?;
        decode_multi_index(dense, self.points_per_dim(), out);
        Ok(())
    }

    /// The kept-term number of a degree multi-index, or `None` if the truncation drops it (or a
    /// degree exceeds k, or the length is not dim).
    pub fn term_of(&self, multi_index: &[usize]) -> Option<usize> {
        if multi_index.len() != self.dim || multi_index.iter().any(|&i| i > self.order) {
            return None;
        }
        let dense = multi_index
            .iter()
            .fold(0, |acc, &i| acc * self.points_per_dim() + i);
        self.kept.binary_search(&dense).ok()
    }

    fn check_dim(&self, what: &'static str, len: usize) -> Result<(), UqError> {
        if len != self.dim {
            return Err(UqError::WrongLength {
                what,
                expected: self.dim,
                got: len,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binomial(n: usize, k: usize) -> usize {
        (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
    }

    #[test]
    fn term_counts() {
        for dim in 1..=5 {
            for order in 0..=6 {
                let tensor = Design::new(Family::Legendre, dim, order, Truncation::Tensor).unwrap();
                let total = Design::new(Family::Legendre, dim, order, Truncation::Total).unwrap();
                assert_eq!(tensor.n_terms(), (order + 1).pow(dim as u32));
                assert_eq!(total.n_terms(), binomial(dim + order, order));
                assert_eq!(total.n_points(), tensor.n_points());
            }
        }
    }

    #[test]
    fn point_order_is_row_major() {
        let design = Design::new(Family::Legendre, 2, 1, Truncation::Tensor).unwrap();
        let s = 1.0 / 3f64.sqrt();
        let expected = [-s, -s, -s, s, s, -s, s, s];
        for (a, b) in design.points().iter().zip(expected) {
            assert!((a - b).abs() < 1e-15);
        }
        let mut xi = [0.0; 2];
        design.point_into(1, &mut xi).unwrap();
        assert!((xi[0] + s).abs() < 1e-15 && (xi[1] - s).abs() < 1e-15);
        assert!(design.point_into(4, &mut xi).is_err());
    }

    #[test]
    fn multi_indices_round_trip() {
        let design = Design::new(Family::Chebyshev, 3, 3, Truncation::Total).unwrap();
        let mut idx = [0; 3];
        for term in 0..design.n_terms() {
            design.multi_index_into(term, &mut idx).unwrap();
            assert!(idx.iter().sum::<usize>() <= 3);
            assert_eq!(design.term_of(&idx), Some(term));
        }
        assert_eq!(design.term_of(&[2, 2, 0]), None);
        assert_eq!(design.term_of(&[4, 0, 0]), None);
    }

    #[test]
    fn odometer_matches_decode() {
        let mut decoded = [0; 3];
        let mut count = 0;
        for_each_multi_index(4, 3, |flat, idx| {
            decode_multi_index(flat, 4, &mut decoded);
            assert_eq!(idx, decoded);
            assert_eq!(flat, count);
            count += 1;
        });
        assert_eq!(count, 64);
    }

    #[test]
    fn refuses_bad_sizes() {
        assert_eq!(
            Design::new(Family::Legendre, 0, 2, Truncation::Tensor),
            Err(UqError::ZeroDimension)
        );
        assert!(matches!(
            Design::new(Family::Legendre, 2, MAX_ORDER + 1, Truncation::Tensor),
            Err(UqError::OrderTooLarge { .. })
        ));
        assert!(matches!(
            Design::new(Family::Legendre, 30, 4, Truncation::Total),
            Err(UqError::GridTooLarge { .. })
        ));
    }
}
