//! One output's sparse Legendre surrogate `y(ξ) ≈ Σ_{α∈Λ} c_α Π_r P_{α_r}(ξ_r)` over a shared
//! [`MultiIndexSet`] (docs/high-dimension.md §6): evaluation with gradient and Hessian, the
//! constant and linear parts, the top-order error estimate, and variance-based (Sobol')
//! sensitivity indices, which follow from the coefficients by orthogonality.
//!
//! Evaluation first fills a `d × (k+1)` table of `P_n(ξ_r)` (and derivatives) in a
//! [`SurrogateWorkspace`], then sums one product of table entries per term: `O(d·k + Σ|supp α|)`
//! per point, no allocation once the workspace has the set's size. The bilinear part
//! `Σ c_rs ξ_r ξ_s` (terms `P_1(ξ_r) P_1(ξ_s)`) is kept as a dense symmetric matrix `Q` when it
//! fills enough of it ([`DENSE_BILINEAR_FILL`]): its gradient `Q ξ` and value `½ ξ·(Q ξ)` are
//! then contiguous dot products, and its Hessian is `Q` itself, copied rather than
//! summed term by term (the d = 72 all-values ur5 study's surrogates have 2 418 such terms of
//! 2 726, issue 40).
//!
//! A surrogate may leave its smallest terms out ([`SparseSurrogate::smallest_terms_into`],
//! [`SparseSurrogate::drop_terms`]): their coefficients become zero and evaluation skips them,
//! which the box search uses (docs/high-dimension.md §7a).
//!
//! Does not: fit (see [`crate::uq::LinearFit`]) or bound (see [`crate::uq::box_optimize`]).

use std::sync::Arc;

use crate::isa::{Isa, IsaKind};
use crate::uq::basis::Family;
use crate::uq::bounds::ErrorEstimate;
use crate::uq::error::UqError;
use crate::uq::multi_index::{EvalPlan, MultiIndexSet};
use crate::uq::sobol_indices::SobolIndices;

mod general_terms;

/// The bilinear part is kept dense when it has at least `d² / DENSE_BILINEAR_FILL` terms and at
/// least half of all terms ([`SparseSurrogate::has_dense_bilinear_part`]): a dense row costs d
/// contiguous multiply-adds that vectorise four at a time, a sparse term two gathered products
/// for the gradient and one more for the value, so dense wins once about one entry in eight is
/// present; and when most terms are of other kinds they dominate the cost, the dense matrix saves
/// little and the sums keep their term-by-term order (and bits).
pub const DENSE_BILINEAR_FILL: usize = 8;

/// How many binades [`SparseSurrogate::smallest_terms_into`] sorts magnitudes into: one per
/// binary exponent of an f64 (zeros and subnormals in the first).
const BINADES: usize = 2048;

/// The binade of a magnitude `m ≥ 0`: its biased binary exponent (0 for zeros and subnormals,
/// 2047 for infinities and NaN), increasing with `m`.
fn binade(m: f64) -> usize {
    ((m.to_bits() >> 52) & 0x7ff) as usize
}

/// Work buffers for evaluating sparse surrogates: per-dimension tables of `P_n`, `P_n'`, `P_n''`.
/// Grows to the largest set it is used with; reuse it across calls and surrogates.
#[derive(Debug, Clone, Default)]
pub struct SurrogateWorkspace {
    values: Vec<f64>,
    first: Vec<f64>,
    second: Vec<f64>,
    /// `Q ξ` of a dense bilinear part, when only the value is asked for.
    bilinear_rows: Vec<f64>,
    /// The point the tables were last loaded at with derivatives (the *base*, see
    /// [`SparseSurrogate::value_moved_unchecked`]); kept only for a dense bilinear part.
    base_point: Vec<f64>,
    /// `Q ξ` at the base point (dense bilinear part only).
    base_rows: Vec<f64>,
    /// `½ ξ·(Q ξ)` at the base point (dense bilinear part only).
    base_bilinear_value: f64,
    /// `ξ − base`, length d (scratch).
    moved_offsets: Vec<f64>,
    /// Per dimension, its row and column in the Hessian block being built, or [`NOT_IN_BLOCK`]
    /// ([`SparseSurrogate::free_hessian_at_loaded`]).
    block_slots: Vec<u32>,
}

/// The [`SurrogateWorkspace::block_slots`] entry of a dimension outside the Hessian block.
const NOT_IN_BLOCK: u32 = u32::MAX;

impl SurrogateWorkspace {
    /// An empty workspace (sized on first use).
    pub fn new() -> SurrogateWorkspace {
        SurrogateWorkspace::default()
    }

    /// Refills the value tables at `xi` for the coordinates `moved` only (no derivatives): the
    /// others keep what the last load put there. The same values as [`Self::load`] gives
    /// (`Family::values_and_derivatives` computes the values as `Family::values` does).
    fn reload_moved(&mut self, set: &MultiIndexSet, xi: &[f64], moved: &[usize]) {
        let stride = set.max_degree() + 1;
        let per_dim = set.max_degree_per_dim();
        for &r in moved {
            let start = r * stride;
            Family::Legendre.values(xi[r], &mut self.values[start..start + per_dim[r] + 1]);
        }
    }

    /// Fills the tables at `xi` for `set` (`derivatives`: also P' and P'').
    fn load(&mut self, set: &MultiIndexSet, xi: &[f64], derivatives: bool) {
        let stride = set.max_degree() + 1;
        let len = set.dim() * stride;
        if self.values.len() < len {
            self.values.resize(len, 0.0);
            self.first.resize(len, 0.0);
            self.second.resize(len, 0.0);
        }
        for ((r, &x), &k) in xi.iter().enumerate().zip(set.max_degree_per_dim()) {
            let range = r * stride..r * stride + k + 1;
            if derivatives {
                Family::Legendre.values_and_derivatives(
                    x,
                    &mut self.values[range.clone()],
                    &mut self.first[range.clone()],
                    &mut self.second[range],
                );
            } else {
                Family::Legendre.values(x, &mut self.values[range]);
            }
        }
    }
}

/// A sparse Legendre surrogate of one output.
///
/// ```
/// use std::sync::Arc;
/// use ribbon::uq::{MultiIndexSet, SparseSurrogate, SurrogateWorkspace};
/// // ξ1 + ξ1² = 1/3 + P_1(ξ1) + 2/3 P_2(ξ1), as a total-degree-2 surrogate in d = 2.
/// let set = Arc::new(MultiIndexSet::total_degree(2, 2)?);
/// let mut c = vec![0.0; set.len()];
/// c[0] = 1.0 / 3.0;
/// c[set.index_of_dense(&[1, 0]).unwrap()] = 1.0;
/// c[set.index_of_dense(&[2, 0]).unwrap()] = 2.0 / 3.0;
/// let s = SparseSurrogate::new(set, c)?;
/// let mut ws = SurrogateWorkspace::new();
/// assert!((s.eval(&[-0.5, 0.9], &mut ws)? + 0.25).abs() < 1e-15);
/// let mut grad = [0.0; 2];
/// s.gradient(&[-0.5, 0.9], &mut grad, &mut ws)?;
/// assert!(grad[0].abs() < 1e-15 && grad[1] == 0.0); // 1 + 2ξ1 = 0
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SparseSurrogate {
    set: Arc<MultiIndexSet>,
    coefficients: Vec<f64>,
    /// The bilinear part as a dense symmetric `d × d` matrix with a zero diagonal (module doc),
    /// or empty when the set has too few bilinear terms for it.
    bilinear: Vec<f64>,
    /// The plan of a surrogate with dropped terms: the set's without them (unused when none
    /// are dropped: the set's plan is evaluated then).
    kept: EvalPlan,
    /// The terms left out ([`SparseSurrogate::drop_terms`]), ascending.
    dropped: Vec<u32>,
}

impl SparseSurrogate {
    /// From coefficients in the set's canonical order (length |Λ|).
    ///
    /// Errors: wrong length, a non-finite coefficient.
    pub fn new(
        set: Arc<MultiIndexSet>,
        coefficients: Vec<f64>,
    ) -> Result<SparseSurrogate, UqError> {
        let mut s = SparseSurrogate::zeros(set);
        s.set_coefficients(&coefficients)?;
        Ok(s)
    }

    /// The zero surrogate over `set`.
    pub fn zeros(set: Arc<MultiIndexSet>) -> SparseSurrogate {
        let n = set.len();
        let d = set.dim();
        let bilinear = set.plan().bilinear.len();
        let dense = bilinear * DENSE_BILINEAR_FILL >= d * d && 2 * bilinear >= n;
        SparseSurrogate {
            set,
            coefficients: vec![0.0; n],
            bilinear: if dense { vec![0.0; d * d] } else { Vec::new() },
            kept: EvalPlan::default(),
            dropped: Vec::new(),
        }
    }

    /// The terms evaluated: the set's plan, or the kept terms of a pruned surrogate.
    fn plan(&self) -> &EvalPlan {
        if self.dropped.is_empty() {
            self.set.plan()
        } else {
            &self.kept
        }
    }

    /// How many terms an evaluation sums (the constant included): the set's size, or fewer
    /// for a pruned surrogate — the measure of what a surrogate value costs.
    pub fn evaluated_terms(&self) -> usize {
        self.plan().terms() + 1
    }

    /// Terms (ascending indices) whose coefficients are the smallest in magnitude and sum to at
    /// most `budget`, into `out` (overwritten): candidates for [`SparseSurrogate::drop_terms`].
    /// They are whole binades of magnitudes (`[2^e, 2^(e+1))`), from the smallest up, as long
    /// as their sum fits: no sort of the terms, and within a factor two of the magnitude a
    /// sorted choice would stop at. The constant and the linear terms `P_1(ξ_r)` are never among
    /// them (they cost little, and the box optimiser starts from the vertex their signs give).
    /// Which terms they are depends on the coefficients' values alone (summed in term order),
    /// so the result is the same on every machine.
    ///
    /// ```
    /// use std::sync::Arc;
    /// use ribbon::uq::{MultiIndexSet, SparseSurrogate, SurrogateWorkspace};
    /// let set = Arc::new(MultiIndexSet::total_degree(2, 2)?);
    /// let mut c = vec![0.0; set.len()];
    /// c[set.index_of_dense(&[1, 0]).unwrap()] = 1.0;
    /// c[set.index_of_dense(&[1, 1]).unwrap()] = 1e-9;
    /// c[set.index_of_dense(&[0, 2]).unwrap()] = 2e-9;
    /// c[set.index_of_dense(&[2, 0]).unwrap()] = 0.5;
    /// let full = SparseSurrogate::new(set.clone(), c)?;
    /// let mut small = Vec::new();
    /// // 1e-9 fits the budget, 1e-9 + 2e-9 does not; the linear ξ2 stays although it is zero.
    /// full.smallest_terms_into(1.5e-9, &mut small);
    /// let mut pruned = full.clone();
    /// pruned.drop_terms(&small)?;
    /// assert_eq!(pruned.dropped_terms(), [set.index_of_dense(&[1, 1]).unwrap() as u32]);
    /// assert_eq!(pruned.evaluated_terms(), 5); // the constant, ξ1, ξ2, P_2(ξ1), P_2(ξ2)
    /// let mut ws = SurrogateWorkspace::new();
    /// let x = [0.3, -1.0];
    /// assert!((full.eval(&x, &mut ws)? - pruned.eval(&x, &mut ws)?).abs() <= 1.5e-9);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    pub fn smallest_terms_into(&self, budget: f64, out: &mut Vec<u32>) {
        // The linear terms, as `linear_part` reads them.
        let linear = self.set.terms_of_total_degree(1);
        let droppable = |t: usize| !linear.contains(&t);
        // The magnitudes summed per binade (by their binary exponent, subnormals and zeros in
        // binade 0), in term order: no sort of the terms.
        let mut per_binade = [0.0_f64; BINADES];
        for t in 1..self.coefficients.len() {
            if droppable(t) {
                let m = self.coefficients[t].abs();
                per_binade[binade(m)] += m;
            }
        }
        // Whole binades from the smallest up while their sum fits; every term below the first
        // that does not fit goes.
        let budget = budget.max(0.0);
        let mut spent = 0.0;
        let mut first_kept = BINADES;
        for (b, &sum) in per_binade.iter().enumerate() {
            if spent + sum > budget {
                first_kept = b;
                break;
            }
            spent += sum;
        }
        out.clear();
        out.extend(
            (1..self.coefficients.len())
                .filter(|&t| droppable(t) && binade(self.coefficients[t].abs()) < first_kept)
                .map(|t| t as u32),
        );
    }

    /// Leaves the terms `dropped` (ascending term indices, none the constant) out of this
    /// surrogate: their coefficients are zero, now and after every later
    /// [`SparseSurrogate::set_coefficients`] or [`SparseSurrogate::set_from_fit`], and evaluation
    /// skips them, so each costs nothing. A surrogate whose dropped coefficients sum to at most
    /// `m` in magnitude differs from the one with them by at most `m` anywhere in the box
    /// (`|P_n| ≤ 1` there; docs/high-dimension.md §7a). An empty list restores every term.
    ///
    /// Errors: an index out of range, the constant, or not ascending.
    pub fn drop_terms(&mut self, dropped: &[u32]) -> Result<(), UqError> {
        let n = self.coefficients.len();
        if let Some(i) = (0..dropped.len()).find(|&i| {
            dropped[i] == 0 || dropped[i] as usize >= n || (i > 0 && dropped[i - 1] >= dropped[i])
        }) {
            return Err(UqError::IndexOutOfRange {
                what: "sparse surrogate: dropped terms (ascending, not the constant)",
                index: dropped[i] as usize,
                len: n,
            });
        }
        self.dropped.clear();
        self.dropped.extend_from_slice(dropped);
        if dropped.is_empty() {
            self.kept = EvalPlan::default();
        } else {
            let mut is_dropped = vec![false; n];
            for &t in dropped {
                is_dropped[t as usize] = true;
            }
            self.set
                .plan()
                .kept_into(|t| !is_dropped[t as usize], &mut self.kept);
        }
        self.zero_dropped();
        Ok(())
    }

    /// The terms left out ([`SparseSurrogate::drop_terms`]; empty when none).
    pub fn dropped_terms(&self) -> &[u32] {
        &self.dropped
    }

    /// Zeroes the dropped terms' coefficients and refreshes the dense bilinear part.
    fn zero_dropped(&mut self) {
        for &t in &self.dropped {
            self.coefficients[t as usize] = 0.0;
        }
        self.refresh_bilinear();
    }

    /// Whether the bilinear part is kept as a dense matrix ([`DENSE_BILINEAR_FILL`]).
    pub fn has_dense_bilinear_part(&self) -> bool {
        !self.bilinear.is_empty()
    }

    /// Writes the bilinear coefficients into the dense matrix (when there is one).
    fn refresh_bilinear(&mut self) {
        if self.bilinear.is_empty() {
            return;
        }
        let d = self.set.dim();
        for p in &self.set.plan().bilinear {
            let (a, b) = (p.dim_a as usize, p.dim_b as usize);
            let c = self.coefficients[p.term as usize];
            self.bilinear[a * d + b] = c;
            self.bilinear[b * d + a] = c;
        }
    }

    /// Overwrites the coefficients (length |Λ|, canonical order).
    ///
    /// Errors: wrong length, a non-finite coefficient.
    pub fn set_coefficients(&mut self, coefficients: &[f64]) -> Result<(), UqError> {
        if coefficients.len() != self.set.len() {
            return Err(UqError::WrongLength {
                what: "sparse surrogate coefficients",
                expected: self.set.len(),
                got: coefficients.len(),
            });
        }
        if let Some(index) = coefficients.iter().position(|c| !c.is_finite()) {
            return Err(UqError::NonFinite {
                what: "sparse surrogate coefficients",
                index,
                value: coefficients[index],
            });
        }
        self.coefficients.copy_from_slice(coefficients);
        self.zero_dropped();
        Ok(())
    }

    /// Overwrites the coefficients with column `output` of a fit's output
    /// (`|Λ| × n_outputs` row-major, as [`crate::uq::LinearFit::fit_into`] writes it).
    ///
    /// Errors: `output ≥ n_outputs`, a length that disagrees, a non-finite coefficient.
    pub fn set_from_fit(
        &mut self,
        coefficients: &[f64],
        n_outputs: usize,
        output: usize,
    ) -> Result<(), UqError> {
        if output >= n_outputs {
            return Err(UqError::IndexOutOfRange {
                what: "sparse surrogate: fit output",
                index: output,
                len: n_outputs,
            });
        }
        if coefficients.len() != self.set.len() * n_outputs {
            return Err(UqError::WrongLength {
                what: "sparse surrogate: fit coefficients (n_terms × n_outputs)",
                expected: self.set.len() * n_outputs,
                got: coefficients.len(),
            });
        }
        for (t, c) in self.coefficients.iter_mut().enumerate() {
            *c = coefficients[t * n_outputs + output];
        }
        if let Some(index) = self.coefficients.iter().position(|c| !c.is_finite()) {
            return Err(UqError::NonFinite {
                what: "sparse surrogate: fit coefficients",
                index: index * n_outputs + output,
                value: self.coefficients[index],
            });
        }
        self.zero_dropped();
        Ok(())
    }

    /// The index set.
    pub fn set(&self) -> &Arc<MultiIndexSet> {
        &self.set
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.set.dim()
    }

    /// Coefficients in canonical order.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    fn check_xi(&self, xi: &[f64]) -> Result<(), UqError> {
        if xi.len() != self.dim() {
            return Err(UqError::WrongLength {
                what: "sparse surrogate: xi",
                expected: self.dim(),
                got: xi.len(),
            });
        }
        Ok(())
    }

    /// The value at `xi` (length d).
    ///
    /// Errors: wrong length of `xi`.
    pub fn eval(&self, xi: &[f64], ws: &mut SurrogateWorkspace) -> Result<f64, UqError> {
        self.check_xi(xi)?;
        Ok(self.value_unchecked(xi, ws))
    }

    pub(crate) fn value_unchecked(&self, xi: &[f64], ws: &mut SurrogateWorkspace) -> f64 {
        ws.load(&self.set, xi, false);
        let bilinear_value = if self.bilinear.is_empty() {
            0.0
        } else {
            let rows = &mut ws.bilinear_rows;
            rows.resize(xi.len(), 0.0);
            matrix_vector_into(&self.bilinear, xi, rows);
            0.5 * dot(rows, xi)
        };
        self.value_from_tables(bilinear_value, ws)
    }

    /// The value at `xi`, a point that differs from the *base* — the point of the last
    /// [`SparseSurrogate::derivatives_unchecked`] with `ws` — only in the coordinates `moved`;
    /// the caller guarantees that every load into `ws` since then was such a point (the box
    /// optimiser's trial points of one iteration move only its free coordinates). Only the moved
    /// coordinates' tables are refilled; the sums run as in [`SparseSurrogate::value_unchecked`]
    /// (the same bits), except a dense bilinear part: `½ ξ·Qξ = ½ b·Qb + Δ·(Qb) + ½ Δ·QΔ` with
    /// `Δ = ξ − b`, `Δ·QΔ` from the moved rows only: `|moved| × d` products instead of d²
    /// (issue 40: the d = 72 study's trial points move 21 of 72 coordinates on average),
    /// equal to the full product up to rounding.
    pub(crate) fn value_moved_unchecked(
        &self,
        xi: &[f64],
        moved: &[usize],
        ws: &mut SurrogateWorkspace,
    ) -> f64 {
        ws.reload_moved(&self.set, xi, moved);
        let bilinear_value = if self.bilinear.is_empty() {
            0.0
        } else {
            // Δ over all d coordinates (0 where nothing moved), so that each moved row's
            // product is one contiguous dot product.
            ws.moved_offsets.clear();
            ws.moved_offsets
                .extend(xi.iter().zip(&ws.base_point).map(|(x, b)| x - b));
            debug_assert!(ws
                .moved_offsets
                .iter()
                .enumerate()
                .all(|(r, &offset)| offset == 0.0 || moved.contains(&r)));
            let d = xi.len();
            let (mut linear, mut quadratic) = (0.0, 0.0);
            for &r in moved {
                let offset = ws.moved_offsets[r];
                if offset == 0.0 {
                    continue;
                }
                linear += offset * ws.base_rows[r];
                quadratic += offset * dot(&self.bilinear[r * d..(r + 1) * d], &ws.moved_offsets);
            }
            ws.base_bilinear_value + linear + 0.5 * quadratic
        };
        self.value_from_tables(bilinear_value, ws)
    }

    /// The value from the value tables `ws` holds, with the dense bilinear part's value given
    /// (0 without one).
    fn value_from_tables(&self, bilinear_value: f64, ws: &SurrogateWorkspace) -> f64 {
        let v = &ws.values;
        let c = &self.coefficients;
        let plan = self.plan();
        let mut sum = c[0];
        for s in &plan.singles {
            sum += c[s.term as usize] * v[s.index as usize];
        }
        if self.bilinear.is_empty() {
            for p in &plan.bilinear {
                sum += c[p.term as usize] * v[p.index_a as usize] * v[p.index_b as usize];
            }
        } else {
            sum += bilinear_value;
        }
        for p in &plan.pairs {
            sum += c[p.term as usize] * v[p.index_a as usize] * v[p.index_b as usize];
        }
        for general in &plan.general {
            let product = general_terms::product(general.indices(&self.set), v);
            sum += c[general.term as usize] * product;
        }
        sum
    }

    /// The value at `xi`, and the gradient `∂y/∂ξ_r` into `grad` (length d, overwritten).
    ///
    /// Errors: wrong length of `xi` or `grad`.
    pub fn gradient(
        &self,
        xi: &[f64],
        grad: &mut [f64],
        ws: &mut SurrogateWorkspace,
    ) -> Result<f64, UqError> {
        self.check_xi(xi)?;
        if grad.len() != self.dim() {
            return Err(UqError::WrongLength {
                what: "sparse surrogate: gradient",
                expected: self.dim(),
                got: grad.len(),
            });
        }
        Ok(self.derivatives_unchecked(xi, grad, ws))
    }

    /// The value at `xi`, the gradient into `grad` (length d) and the Hessian into `hess`
    /// (d × d row-major, symmetric), both overwritten.
    ///
    /// Errors: wrong length of `xi`, `grad` or `hess`.
    pub fn hessian(
        &self,
        xi: &[f64],
        grad: &mut [f64],
        hess: &mut [f64],
        ws: &mut SurrogateWorkspace,
    ) -> Result<f64, UqError> {
        self.check_xi(xi)?;
        let d = self.dim();
        if grad.len() != d || hess.len() != d * d {
            return Err(UqError::WrongLength {
                what: "sparse surrogate: gradient (d) and Hessian (d × d)",
                expected: d + d * d,
                got: grad.len() + hess.len(),
            });
        }
        let value = self.derivatives_unchecked(xi, grad, ws);
        let every_dimension: Vec<usize> = (0..d).collect();
        self.free_hessian_at_loaded(&every_dimension, hess, ws);
        Ok(value)
    }

    /// Value and gradient; lengths already checked.
    pub(crate) fn derivatives_unchecked(
        &self,
        xi: &[f64],
        grad: &mut [f64],
        ws: &mut SurrogateWorkspace,
    ) -> f64 {
        ws.load(&self.set, xi, true);
        if !self.bilinear.is_empty() {
            // The base of later `value_moved_unchecked` calls.
            ws.base_rows.resize(xi.len(), 0.0);
            matrix_vector_into(&self.bilinear, xi, &mut ws.base_rows);
            ws.base_bilinear_value = 0.5 * dot(&ws.base_rows, xi);
            ws.base_point.clear();
            ws.base_point.extend_from_slice(xi);
        }
        self.value_and_gradient_from_tables(grad, ws)
    }

    /// The block of the Hessian on the dimensions `free` (ascending) into `block` (the first
    /// `nf × nf` entries, row-major, symmetric; entry `(a, b)` is `∂²y/∂ξ_{free[a]}∂ξ_{free[b]}`)
    /// at the point of the last [`SparseSurrogate::derivatives_unchecked`] with `ws`, without
    /// loading the tables again. The caller guarantees that nothing loaded another point into
    /// `ws` since: the box optimiser asks for the Hessian apart, only where a Newton step
    /// follows, right after the gradient at the same point (loading the tables again there cost
    /// a second Legendre table per iteration, issue 40).
    ///
    /// Every entry is summed as in the whole Hessian (the same terms in the same order, the same
    /// bits); the terms and entries outside the block are skipped. The box optimiser reads only
    /// the block of its free coordinates, on average 21 of 72 on the d = 72 all-values ur5 study
    /// and 10 of 32 on the d = 32 scaling row, where building and mirroring the whole d × d
    /// Hessian (and copying the dense bilinear part into it) was a fifth of the search (issue 40).
    /// A small block takes only the terms containing a free dimension (`RowLists`: 41–64 % of
    /// the terms on the scaling rows; the d = 32 row's Hessians −38 % of instructions).
    pub(crate) fn free_hessian_at_loaded(
        &self,
        free: &[usize],
        block: &mut [f64],
        ws: &mut SurrogateWorkspace,
    ) {
        let d = self.dim();
        ws.block_slots.clear();
        ws.block_slots.resize(d, NOT_IN_BLOCK);
        for (a, &r) in free.iter().enumerate() {
            debug_assert!(a == 0 || free[a - 1] < r, "free dimensions ascending");
            ws.block_slots[r] = a as u32;
        }
        self.hessian_block_from_tables(free, &mut block[..free.len() * free.len()], ws);
    }

    /// Value and gradient from the tables `ws` holds (loaded with derivatives).
    fn value_and_gradient_from_tables(&self, grad: &mut [f64], ws: &SurrogateWorkspace) -> f64 {
        let (v, g) = (&ws.values, &ws.first);
        let c = &self.coefficients;
        let plan = self.plan();
        // The same order of sums as `value_unchecked`, so that both give the same value.
        let mut bilinear_value = 0.0;
        if self.bilinear.is_empty() {
            grad.fill(0.0);
        } else {
            grad.copy_from_slice(&ws.base_rows);
            bilinear_value = ws.base_bilinear_value;
        }
        let mut sum = c[0];
        for s in &plan.singles {
            let (ct, i, r) = (c[s.term as usize], s.index as usize, s.dim as usize);
            sum += ct * v[i];
            grad[r] += ct * g[i];
        }
        if self.bilinear.is_empty() {
            for p in &plan.bilinear {
                let ct = c[p.term as usize];
                let (va, vb) = (v[p.index_a as usize], v[p.index_b as usize]);
                sum += ct * va * vb;
                grad[p.dim_a as usize] += ct * vb;
                grad[p.dim_b as usize] += ct * va;
            }
        } else {
            sum += bilinear_value;
        }
        for p in &plan.pairs {
            let ct = c[p.term as usize];
            let (ia, ib) = (p.index_a as usize, p.index_b as usize);
            let (ra, rb) = (p.dim_a as usize, p.dim_b as usize);
            sum += ct * v[ia] * v[ib];
            grad[ra] += ct * g[ia] * v[ib];
            grad[rb] += ct * v[ia] * g[ib];
        }
        for general in &plan.general {
            let ct = c[general.term as usize];
            let (idx, dims) = (general.indices(&self.set), general.dims(&self.set));
            sum += ct * general_terms::product_adding_gradient(ct, idx, dims, v, g, grad);
        }
        sum
    }

    /// The Hessian block of the dimensions `free` (ascending, their slots in
    /// `ws.block_slots`) from the tables `ws` holds (loaded with derivatives): the upper triangle
    /// term by term (factors are sorted by dimension, so a term's entries in the block are upper
    /// too), mirrored below at the end.
    fn hessian_block_from_tables(
        &self,
        free: &[usize],
        block: &mut [f64],
        ws: &SurrogateWorkspace,
    ) {
        let (d, nf) = (self.dim(), free.len());
        let (v, g, h) = (&ws.values, &ws.first, &ws.second);
        let slots = &ws.block_slots;
        let place = |r: usize| {
            let slot = slots[r];
            (slot != NOT_IN_BLOCK).then_some(slot as usize)
        };
        let c = &self.coefficients;
        let plan = self.plan();
        if self.bilinear.is_empty() {
            block.fill(0.0);
            // From the rows of the free dimensions (each bilinear term under its earlier
            // dimension): an entry gets at most one bilinear term, so the order is free. Before
            // (issue 40), every bilinear term was tested, about 270 per block on the README's
            // d = 32 scaling row for 10 free dimensions of 32: 2.4 % of the box search's
            // instructions there.
            for (a, &r) in free.iter().enumerate() {
                for p in plan.rows.bilinear_from(r) {
                    if let Some(b) = place(p.dim_b as usize) {
                        block[a * nf + b] += c[p.term as usize];
                    }
                }
            }
        } else {
            for (row, &r) in block.chunks_exact_mut(nf).zip(free) {
                let bilinear_row = &self.bilinear[r * d..(r + 1) * d];
                for (entry, &q) in row.iter_mut().zip(free) {
                    *entry = bilinear_row[q];
                }
            }
        }
        // The rows of the free dimensions when they hold fewer terms than the walk over every
        // term visits (a pair whose dimensions are both free is in two rows, a general term in
        // the rows of each of its dimensions); the same bits either way.
        if plan.rows.entries_of(free) < plan.singles.len() + plan.pairs.len() + plan.general.len() {
            self.add_hessian_rows(free, block, ws);
        } else {
            for s in &plan.singles {
                if let Some(a) = place(s.dim as usize) {
                    block[a * nf + a] += c[s.term as usize] * h[s.index as usize];
                }
            }
            for p in &plan.pairs {
                let (pa, pb) = (place(p.dim_a as usize), place(p.dim_b as usize));
                if pa.is_none() && pb.is_none() {
                    continue;
                }
                let ct = c[p.term as usize];
                let (ia, ib) = (p.index_a as usize, p.index_b as usize);
                if let Some(a) = pa {
                    block[a * nf + a] += ct * h[ia] * v[ib];
                }
                if let Some(b) = pb {
                    block[b * nf + b] += ct * v[ia] * h[ib];
                }
                if let (Some(a), Some(b)) = (pa, pb) {
                    block[a * nf + b] += ct * g[ia] * g[ib];
                }
            }
            for general in &plan.general {
                let (idx, dims) = (general.indices(&self.set), general.dims(&self.set));
                let ct = c[general.term as usize];
                general_terms::add_hessian(ct, idx, dims, v, g, h, block, nf, place);
            }
        }
        // The bilinear part is symmetric already; every entry the terms added to is upper.
        for a in 0..nf {
            for b in a + 1..nf {
                block[b * nf + a] = block[a * nf + b];
            }
        }
    }

    /// The singles', pairs' and general terms' part of [`Self::hessian_block_from_tables`] from
    /// the terms of the free dimensions' rows only (`RowLists`): row by row, each row's terms
    /// in the plan's order, so that every entry sums the same terms in the same order as the walk
    /// over every term (the same bits) — a term adds to the rows of its free dimensions, and a
    /// pair's or a general term's upper entries belong to the row of its earlier dimension.
    fn add_hessian_rows(&self, free: &[usize], block: &mut [f64], ws: &SurrogateWorkspace) {
        let nf = free.len();
        let (v, g, h) = (&ws.values, &ws.first, &ws.second);
        let slots = &ws.block_slots;
        let place = |r: usize| {
            let slot = slots[r];
            (slot != NOT_IN_BLOCK).then_some(slot as usize)
        };
        let c = &self.coefficients;
        let rows = &self.plan().rows;
        for (a, &r) in free.iter().enumerate() {
            for s in rows.singles(r) {
                block[a * nf + a] += c[s.term as usize] * h[s.index as usize];
            }
        }
        for (a, &r) in free.iter().enumerate() {
            for p in rows.pairs(r) {
                let ct = c[p.term as usize];
                let (ia, ib) = (p.index_a as usize, p.index_b as usize);
                if p.dim_a as usize == r {
                    block[a * nf + a] += ct * h[ia] * v[ib];
                    if let Some(b) = place(p.dim_b as usize) {
                        block[a * nf + b] += ct * g[ia] * g[ib];
                    }
                } else {
                    block[a * nf + a] += ct * v[ia] * h[ib];
                }
            }
        }
        for &r in free {
            for row in rows.general(r) {
                let general = &row.general;
                general_terms::add_hessian_row(
                    c[general.term as usize],
                    general.indices(&self.set),
                    general.dims(&self.set),
                    (v, g, h),
                    row.factor as usize,
                    block,
                    nf,
                    place,
                );
            }
        }
    }

    /// The constant coefficient `c_0` (the mean of the surrogate under uniform ξ).
    pub fn constant(&self) -> f64 {
        self.coefficients[0]
    }

    /// The linear part: `out[r]` = coefficient of `P_1(ξ_r)` (0 if the set has no such term).
    ///
    /// Errors: `out.len() != d`.
    pub fn linear_part(&self, out: &mut [f64]) -> Result<(), UqError> {
        if out.len() != self.dim() {
            return Err(UqError::WrongLength {
                what: "sparse surrogate: linear part",
                expected: self.dim(),
                got: out.len(),
            });
        }
        out.fill(0.0);
        for t in self.set.terms_of_total_degree(1) {
            out[self.set.term(t)[0].dim as usize] = self.coefficients[t];
        }
        Ok(())
    }

    /// Top-order magnitude: `Σ |c_α|` over the terms of the highest total degree present in the
    /// set (docs/high-dimension.md §6). For a total-degree set this is the dense surrogate's
    /// measure; for an anisotropic set only the dimensions that reach that degree contribute, so
    /// it says nothing about truncation in dimensions kept at low order.
    pub fn top_order_magnitude(&self) -> f64 {
        self.set
            .terms_of_total_degree(self.set.max_total_degree())
            .map(|t| self.coefficients[t].abs())
            .sum()
    }

    /// The error estimate beside every bound of this surrogate ([`ErrorEstimate`], no misfit).
    pub fn error_estimate(&self) -> ErrorEstimate {
        ErrorEstimate {
            top_order: self.top_order_magnitude(),
            misfit: None,
        }
    }

    /// `c_α² Π_r 1/(2α_r+1)`: term t's share of the variance (`‖P_n‖² = 1/(2n+1)` under the
    /// uniform probability on [−1, 1]).
    #[inline]
    fn term_variance(&self, t: usize) -> f64 {
        let c = self.coefficients[t];
        self.set
            .term(t)
            .iter()
            .fold(c * c, |acc, f| acc / (2.0 * f.degree as f64 + 1.0))
    }

    /// Variance of the surrogate under uniform ξ: `Σ_{α≠0} c_α² Π_r 1/(2α_r+1)`.
    pub fn variance(&self) -> f64 {
        (1..self.set.len()).map(|t| self.term_variance(t)).sum()
    }

    /// Main and total Sobol' indices per dimension (docs/sobol-indices.md §2). A constant
    /// surrogate (variance 0, or a spread of rounding size:
    /// [`crate::uq::sobol_indices::NEGLIGIBLE_RELATIVE_SPREAD`]) has every index 0.
    pub fn sobol_indices(&self) -> SobolIndices {
        let mut out = SobolIndices::zeros(self.dim());
        self.sobol_indices_into(&mut out);
        out
    }

    /// As [`SparseSurrogate::sobol_indices`], overwriting `out` (resized to d) to reuse its
    /// allocation.
    pub fn sobol_indices_into(&self, out: &mut SobolIndices) {
        out.reset(self.dim());
        for t in 1..self.set.len() {
            let term = self.set.term(t);
            let single = (term.len() == 1).then(|| term[0].dim as usize);
            out.add_term(
                self.term_variance(t),
                single,
                term.iter().map(|f| f.dim as usize),
            );
        }
        out.normalise(self.coefficients[0]);
    }

    /// Largest `|y − surrogate(ξ)|` over model runs: `points` `n × d` row-major, `values` the n
    /// model values.
    ///
    /// Errors: lengths that disagree, no points, non-finite values.
    pub fn misfit(
        &self,
        points: &[f64],
        values: &[f64],
        ws: &mut SurrogateWorkspace,
    ) -> Result<f64, UqError> {
        if values.is_empty() {
            return Err(UqError::Empty {
                what: "misfit: values",
            });
        }
        if points.len() != values.len() * self.dim() {
            return Err(UqError::WrongLength {
                what: "misfit: points (n × d)",
                expected: values.len() * self.dim(),
                got: points.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what: "misfit: values",
                index,
                value: values[index],
            });
        }
        Ok(points
            .chunks_exact(self.dim())
            .zip(values)
            .map(|(xi, y)| (y - self.value_unchecked(xi, ws)).abs())
            .fold(0.0, f64::max))
    }
}

/// `a · b` over equal lengths, in four interleaved partial sums (so that it vectorises).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let (a_rest, b_rest) = (a4.remainder(), b4.remainder());
    for (x, y) in a4.zip(b4) {
        for l in 0..4 {
            lanes[l] += x[l] * y[l];
        }
    }
    let tail: f64 = a_rest.iter().zip(b_rest).map(|(x, y)| x * y).sum();
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// `out = q x` for a `d × d` row-major `q` (d = `x.len()` = `out.len()`), row by row with
/// [`dot`]; with AVX2 when the CPU has it (4 lanes per instruction instead of SSE2's 2; the same
/// bits, as neither contracts into FMA: docs/batch.md §3).
fn matrix_vector_into(q: &[f64], x: &[f64], out: &mut [f64]) {
    match Isa::best().kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2
            // (`Isa::avx2`), which is all `matrix_vector_avx2` requires.
            unsafe { matrix_vector_avx2(q, x, out) }
        }
        _ => matrix_vector_rows(q, x, out),
    }
}

#[inline(always)]
fn matrix_vector_rows(q: &[f64], x: &[f64], out: &mut [f64]) {
    for (row, o) in q.chunks_exact(x.len()).zip(out.iter_mut()) {
        *o = dot(row, x);
    }
}

/// [`matrix_vector_rows`] with AVX2 vectors: lane l of the accumulator sums the products of
/// entries `4i + l` as [`dot`]'s partial sum l does, and the lanes and the tail are added in
/// `dot`'s order, so the result is the same to the bit. (The compiler does not widen `dot`'s
/// loop past SSE2's two lanes by itself.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn matrix_vector_avx2(q: &[f64], x: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    let d = x.len();
    let whole = d - d % 4;
    let (x4, x_rest) = x.split_at(whole);
    for (row, o) in q.chunks_exact(d).zip(out.iter_mut()) {
        let (row4, row_rest) = row.split_at(whole);
        let mut acc = _mm256_setzero_pd();
        for (a, b) in row4.chunks_exact(4).zip(x4.chunks_exact(4)) {
            // SAFETY: each chunk holds four f64, what one unaligned 256-bit load reads.
            let (va, vb) = unsafe { (_mm256_loadu_pd(a.as_ptr()), _mm256_loadu_pd(b.as_ptr())) };
            acc = _mm256_add_pd(acc, _mm256_mul_pd(va, vb));
        }
        let mut lanes = [0.0; 4];
        // SAFETY: `lanes` holds four f64, what one unaligned 256-bit store writes.
        unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), acc) };
        let tail: f64 = row_rest.iter().zip(x_rest).map(|(a, b)| a * b).sum();
        *o = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::basis::legendre_values;

    const TOL: f64 = 1e-13;

    fn random_surrogate(set: MultiIndexSet, seed: u64) -> SparseSurrogate {
        let mut rng = SplitMix64::new(seed);
        let c = (0..set.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        SparseSurrogate::new(Arc::new(set), c).unwrap()
    }

    fn brute_force(s: &SparseSurrogate, x: &[f64]) -> f64 {
        let k = s.set().max_degree();
        let mut p = vec![0.0; k + 1];
        (0..s.set().len())
            .map(|t| {
                s.coefficients()[t]
                    * s.set()
                        .to_dense(t)
                        .iter()
                        .zip(x)
                        .map(|(&a, &xr)| {
                            legendre_values(xr, &mut p);
                            p[a]
                        })
                        .product::<f64>()
            })
            .sum()
    }

    /// Two sets with terms of every kind: the first with a sparse bilinear part and terms of up
    /// to three factors, the second with a dense bilinear part (45 of 66 terms) and other pairs
    /// beside it.
    fn sparse_and_dense_sets() -> [MultiIndexSet; 2] {
        let mut caps = vec![1; 12];
        caps[0] = 4;
        caps[3] = 3;
        let mut dense_caps = vec![1; 10];
        dense_caps[0] = 2;
        [
            MultiIndexSet::anisotropic(&caps, 5, 3).unwrap(),
            MultiIndexSet::anisotropic(&dense_caps, 4, 2).unwrap(),
        ]
    }

    #[test]
    fn value_gradient_hessian_match_brute_force_and_differences() {
        const H: f64 = 1e-5;
        const FD_TOL: f64 = 1e-6;
        let [sparse, dense] = sparse_and_dense_sets();
        // The last with terms of five factors, whose table indices and dimensions are read
        // through the set (three and four from the plan's `GeneralTerm` entries).
        let sets = [
            MultiIndexSet::total_degree(4, 4).unwrap(),
            sparse,
            dense,
            MultiIndexSet::anisotropic(&[2; 7], 6, 5).unwrap(),
        ];
        let mut ws = SurrogateWorkspace::new();
        let mut rng = SplitMix64::new(1);
        for (i, set) in sets.into_iter().enumerate() {
            let s = random_surrogate(set, 10 + i as u64);
            assert_eq!(s.has_dense_bilinear_part(), i == 2, "set {i}");
            let d = s.dim();
            let x: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let v = s.eval(&x, &mut ws).unwrap();
            assert!((v - brute_force(&s, &x)).abs() < TOL);
            let (mut g, mut h) = (vec![0.0; d], vec![0.0; d * d]);
            let v2 = s.hessian(&x, &mut g, &mut h, &mut ws).unwrap();
            assert!((v - v2).abs() < TOL);
            let mut g_only = vec![0.0; d];
            s.gradient(&x, &mut g_only, &mut ws).unwrap();
            assert_eq!(g, g_only);
            for r in 0..d {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[r] += H;
                xm[r] -= H;
                let fd = (brute_force(&s, &xp) - brute_force(&s, &xm)) / (2.0 * H);
                assert!((fd - g[r]).abs() < FD_TOL, "set {i} grad {r}");
                let (mut gp, mut gm) = (vec![0.0; d], vec![0.0; d]);
                s.gradient(&xp, &mut gp, &mut ws).unwrap();
                s.gradient(&xm, &mut gm, &mut ws).unwrap();
                for q in 0..d {
                    let fd = (gp[q] - gm[q]) / (2.0 * H);
                    assert!((fd - h[r * d + q]).abs() < FD_TOL, "set {i} hess {r} {q}");
                }
            }
        }
        let s = random_surrogate(MultiIndexSet::total_degree(2, 1).unwrap(), 0);
        assert!(s.eval(&[0.0], &mut ws).is_err());
        assert!(s.gradient(&[0.0, 0.0], &mut [0.0], &mut ws).is_err());
    }

    /// A trial point that moves only some coordinates from the base (the point of the last
    /// evaluation with derivatives): the same bits as a full evaluation without a dense
    /// bilinear part, the same value to rounding with one, including after other trials.
    #[test]
    fn values_of_moved_points_match_full_evaluations() {
        let sets = sparse_and_dense_sets();
        let (mut ws, mut full_ws) = (SurrogateWorkspace::new(), SurrogateWorkspace::new());
        let mut rng = SplitMix64::new(7);
        for (i, set) in sets.into_iter().enumerate() {
            let s = random_surrogate(set, 20 + i as u64);
            let d = s.dim();
            let base: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut grad = vec![0.0; d];
            s.derivatives_unchecked(&base, &mut grad, &mut ws);
            let moved: Vec<usize> = (0..d).filter(|r| r % 3 != 1).collect();
            for _ in 0..5 {
                let mut trial = base.clone();
                for &r in &moved {
                    // Some moved coordinates stay (a zero offset), some reach a face.
                    trial[r] = match rng.uniform(0.0, 3.0) as usize {
                        0 => base[r],
                        1 => 1.0,
                        _ => rng.uniform(-1.0, 1.0),
                    };
                }
                let moved_value = s.value_moved_unchecked(&trial, &moved, &mut ws);
                let full = s.value_unchecked(&trial, &mut full_ws);
                if s.has_dense_bilinear_part() {
                    assert!((moved_value - full).abs() < TOL, "set {i}");
                } else {
                    assert_eq!(moved_value.to_bits(), full.to_bits(), "set {i}");
                }
                assert!(
                    (moved_value - brute_force(&s, &trial)).abs() < TOL,
                    "set {i}"
                );
            }
        }
    }

    /// The Hessian block of some dimensions holds the whole Hessian's entries of those
    /// dimensions, bit for bit, with and without a dense bilinear part, whatever block came before.
    #[test]
    fn hessian_blocks_are_the_whole_hessians_entries() {
        let [sparse, dense] = sparse_and_dense_sets();
        // Terms of up to five factors: the gathered three- and four-factor paths and the general
        // one.
        let wide = MultiIndexSet::anisotropic(&[2; 7], 6, 5).unwrap();
        let mut ws = SurrogateWorkspace::new();
        let mut rng = SplitMix64::new(5);
        // A small block is built from the free dimensions' rows (`RowLists`), the whole Hessian
        // by the walk over every term: the same bits either way.
        for (i, set) in [sparse, dense, wide].into_iter().enumerate() {
            let s = random_surrogate(set, 30 + i as u64);
            let d = s.dim();
            let x: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let (mut grad, mut whole) = (vec![0.0; d], vec![0.0; d * d]);
            s.hessian(&x, &mut grad, &mut whole, &mut ws).unwrap();
            for free in [
                (0..d).filter(|r| r % 3 != 1).collect::<Vec<usize>>(),
                vec![0, d - 1],
                vec![2],
                (0..d).collect(),
            ] {
                s.derivatives_unchecked(&x, &mut grad, &mut ws);
                let nf = free.len();
                let mut block = vec![f64::NAN; d * d];
                s.free_hessian_at_loaded(&free, &mut block, &mut ws);
                for (a, &r) in free.iter().enumerate() {
                    for (b, &q) in free.iter().enumerate() {
                        assert_eq!(
                            block[a * nf + b].to_bits(),
                            whole[r * d + q].to_bits(),
                            "set {i}, free {free:?}, ({r}, {q})"
                        );
                    }
                }
                assert!(block[nf * nf..].iter().all(|v| v.is_nan()), "set {i}");
            }
        }
    }

    /// A surrogate with terms dropped evaluates (value, gradient, Hessian, Hessian blocks, moved
    /// points) to the same bits as the same surrogate with those coefficients zero and every term
    /// walked, keeps them dropped when its coefficients are set again, and stays within the
    /// dropped magnitudes of the surrogate with them.
    #[test]
    fn dropped_terms_are_skipped_to_the_same_bits_as_zero_coefficients() {
        let [sparse, dense] = sparse_and_dense_sets();
        let wide = MultiIndexSet::anisotropic(&[2; 7], 6, 5).unwrap();
        let (mut ws, mut reference_ws) = (SurrogateWorkspace::new(), SurrogateWorkspace::new());
        let mut rng = SplitMix64::new(9);
        let linear = |set: &MultiIndexSet, t: u32| {
            let term = set.term(t as usize);
            term.len() == 1 && term[0].degree == 1
        };
        for (i, set) in [sparse, dense, wide].into_iter().enumerate() {
            let set = Arc::new(set);
            let d = set.dim();
            // Magnitudes over twelve decades, so that a budget drops terms of every kind.
            let c: Vec<f64> = (0..set.len())
                .map(|_| rng.uniform(-1.0, 1.0) * 10f64.powf(rng.uniform(-12.0, 0.0)))
                .collect();
            let full = SparseSurrogate::new(Arc::clone(&set), c.clone()).unwrap();
            let budget = 1e-3;
            let mut dropped = Vec::new();
            full.smallest_terms_into(budget, &mut dropped);
            let mass: f64 = dropped.iter().map(|&t| c[t as usize].abs()).sum();
            assert!(mass <= budget, "set {i}: {mass}");
            assert!(dropped.len() > set.len() / 4, "set {i}: {}", dropped.len());
            assert!(dropped.windows(2).all(|w| w[0] < w[1]));
            assert!(dropped.iter().all(|&t| t != 0 && !linear(&set, t)));
            // Every other term but the constant and the linear ones is larger than every
            // dropped one.
            let largest_dropped = dropped
                .iter()
                .map(|&t| c[t as usize].abs())
                .fold(0.0, f64::max);
            assert!((1..set.len() as u32)
                .filter(|t| !linear(&set, *t) && dropped.binary_search(t).is_err())
                .all(|t| c[t as usize].abs() > largest_dropped));

            let mut pruned = SparseSurrogate::zeros(Arc::clone(&set));
            pruned.drop_terms(&dropped).unwrap();
            pruned.set_coefficients(&c).unwrap();
            let mut zeroed = c.clone();
            for &t in &dropped {
                zeroed[t as usize] = 0.0;
            }
            assert_eq!(pruned.coefficients(), &zeroed[..], "set {i}");
            assert_eq!(pruned.evaluated_terms(), set.len() - dropped.len());
            assert_eq!(pruned.dropped_terms(), &dropped[..]);
            let reference = SparseSurrogate::new(Arc::clone(&set), zeroed).unwrap();
            assert_eq!(pruned.has_dense_bilinear_part(), i == 1);
            for _ in 0..3 {
                let x: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let (mut g, mut h) = (vec![0.0; d], vec![0.0; d * d]);
                let (mut g_ref, mut h_ref) = (vec![0.0; d], vec![0.0; d * d]);
                let v = pruned.hessian(&x, &mut g, &mut h, &mut ws).unwrap();
                let v_ref = reference
                    .hessian(&x, &mut g_ref, &mut h_ref, &mut reference_ws)
                    .unwrap();
                assert_eq!(v.to_bits(), v_ref.to_bits(), "set {i}");
                assert_eq!(g, g_ref, "set {i}");
                assert_eq!(h, h_ref, "set {i}");
                let v_full = full.eval(&x, &mut reference_ws).unwrap();
                assert!((v - v_full).abs() <= mass + TOL, "set {i}");
                // A block of a few free dimensions (built from the kept rows) and a moved point.
                let free: Vec<usize> = (0..d).filter(|r| r % 4 == 1).collect();
                let nf = free.len();
                pruned.derivatives_unchecked(&x, &mut g, &mut ws);
                let mut block = vec![0.0; nf * nf];
                pruned.free_hessian_at_loaded(&free, &mut block, &mut ws);
                for (a, &r) in free.iter().enumerate() {
                    for (b, &q) in free.iter().enumerate() {
                        assert_eq!(block[a * nf + b].to_bits(), h_ref[r * d + q].to_bits());
                    }
                }
                let mut trial = x.clone();
                for &r in &free {
                    trial[r] = rng.uniform(-1.0, 1.0);
                }
                let moved = pruned.value_moved_unchecked(&trial, &free, &mut ws);
                let moved_ref = reference.eval(&trial, &mut reference_ws).unwrap();
                if pruned.has_dense_bilinear_part() {
                    assert!((moved - moved_ref).abs() < TOL, "set {i}");
                } else {
                    assert_eq!(moved.to_bits(), moved_ref.to_bits(), "set {i}");
                }
            }
            // No term dropped: every term evaluated again.
            pruned.drop_terms(&[]).unwrap();
            pruned.set_coefficients(&c).unwrap();
            assert_eq!(pruned, full);
        }
        let mut s = random_surrogate(MultiIndexSet::total_degree(3, 2).unwrap(), 1);
        for bad in [&[0u32][..], &[3, 2], &[4, 4], &[10]] {
            assert!(s.drop_terms(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn the_dense_bilinear_products_give_the_same_bits_with_any_instruction_set() {
        let mut rng = SplitMix64::new(3);
        for d in [1, 3, 4, 7, 72] {
            let q: Vec<f64> = (0..d * d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let x: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let (mut fast, mut plain) = (vec![0.0; d], vec![0.0; d]);
            matrix_vector_into(&q, &x, &mut fast);
            matrix_vector_rows(&q, &x, &mut plain);
            for r in 0..d {
                assert_eq!(fast[r].to_bits(), plain[r].to_bits(), "d = {d}, row {r}");
                let exact: f64 = (0..d).map(|s| q[r * d + s] * x[s]).sum();
                assert!((plain[r] - exact).abs() < 1e-14 * d as f64);
            }
        }
    }

    #[test]
    fn parts_and_sobol_indices() {
        // y = 2 + 3 P_1(ξ1) + P_2(ξ2) + 4 P_1(ξ1) P_1(ξ3) in d = 3, total degree 2.
        let set = Arc::new(MultiIndexSet::total_degree(3, 2).unwrap());
        let mut c = vec![0.0; set.len()];
        c[0] = 2.0;
        c[set.index_of_dense(&[1, 0, 0]).unwrap()] = 3.0;
        c[set.index_of_dense(&[0, 2, 0]).unwrap()] = 1.0;
        c[set.index_of_dense(&[1, 0, 1]).unwrap()] = 4.0;
        let s = SparseSurrogate::new(set.clone(), c).unwrap();
        assert_eq!(s.constant(), 2.0);
        let mut lin = [0.0; 3];
        s.linear_part(&mut lin).unwrap();
        assert_eq!(lin, [3.0, 0.0, 0.0]);
        assert_eq!(s.top_order_magnitude(), 5.0);
        // Variances: 9/3 = 3, 1/5, 16/9.
        let want = 3.0 + 0.2 + 16.0 / 9.0;
        assert!((s.variance() - want).abs() < TOL);
        let idx = s.sobol_indices();
        assert!((idx.main[0] - 3.0 / want).abs() < TOL);
        assert!((idx.main[1] - 0.2 / want).abs() < TOL);
        assert_eq!(idx.main[2], 0.0);
        assert!((idx.total[0] - (3.0 + 16.0 / 9.0) / want).abs() < TOL);
        assert!((idx.total[2] - 16.0 / 9.0 / want).abs() < TOL);
        assert!((idx.variance - want).abs() < TOL);
        // Monte Carlo check of the variance: uniform samples.
        let mut rng = SplitMix64::new(2);
        let mut ws = SurrogateWorkspace::new();
        let n = 200_000;
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for _ in 0..n {
            let x = [
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            ];
            let y = s.eval(&x, &mut ws).unwrap();
            sum += y;
            sum_sq += y * y;
        }
        let mean = sum / n as f64;
        let var = sum_sq / n as f64 - mean * mean;
        assert!(
            (mean - 2.0).abs() < 0.02 && (var - want).abs() < 0.05 * want,
            "{mean} {var}"
        );
        // Fit-layout column extraction.
        let mut t = SparseSurrogate::zeros(set.clone());
        let two: Vec<f64> = s.coefficients().iter().flat_map(|&c| [c, -c]).collect();
        t.set_from_fit(&two, 2, 1).unwrap();
        assert_eq!(t.coefficients()[0], -2.0);
        assert!(t.set_from_fit(&two, 2, 2).is_err());
        assert!(t.set_coefficients(&[1.0]).is_err());
        let misfit = s
            .misfit(&[0.0, 0.0, 0.0], &[2.0 - 0.5 + 0.25], &mut ws)
            .unwrap();
        assert!((misfit - 0.25).abs() < TOL);
    }
}
