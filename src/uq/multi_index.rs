//! Downward-closed sets of multi-indices α ∈ ℕ^d, stored sparsely: the index set Λ of a sparse
//! polynomial expansion `Σ_{α∈Λ} c_α Π_r P_{α_r}(ξ_r)` (docs/high-dimension.md §1).
//!
//! Storage: each term keeps only its non-zero `(dimension, degree)` pairs ([`Factor`]s), sorted by
//! dimension, so a term of d = 100 with two active dimensions costs two pairs. Terms are kept in
//! one **canonical order**, used by every file that reads a set (sparse grids, regression,
//! surrogates): graded lexicographic ("grlex" with `ξ_1 > ξ_2 > … > ξ_d`), i.e.
//!
//! 1. by total degree `|α| = Σ_r α_r`, ascending;
//! 2. within one total degree, α before β when at the first dimension r where they differ,
//!    `α_r > β_r`.
//!
//! So term 0 is the constant, terms 1..=d are `P_1(ξ_1), …, P_1(ξ_d)`, and degree 2 starts
//! `P_2(ξ_1), P_1(ξ_1)P_1(ξ_2), …, P_1(ξ_1)P_1(ξ_d), P_2(ξ_2), …`. The order is graded, so every
//! proper predecessor `β ≤ α` (componentwise) comes before α: triangular solves over a
//! downward-closed set can run in term order.
//!
//! Does not: evaluate polynomials (see [`crate::uq::sparse_surrogate`]) or choose points (see
//! [`crate::uq::sparse_grid`], [`crate::uq::regression`]).

use std::collections::HashMap;

use crate::uq::error::UqError;

mod row_lists;

pub(crate) use row_lists::RowLists;

/// Largest number of terms a set may hold: 2²² ≈ 4.2 M (total degree 3 at d = 100 is 176 851).
/// Bounds the memory of sets and of every matrix built over them.
pub const MAX_TERMS: usize = 1 << 22;

/// One factor `P_degree(ξ_dim)` of a product basis function: a non-zero entry of a multi-index.
/// `dim` is 0-based (dimension r = `dim + 1` in the docs' 1-based notation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Factor {
    /// Dimension (0-based), `< set.dim()`.
    pub dim: u32,
    /// Degree in that dimension, ≥ 1.
    pub degree: u32,
}

impl Factor {
    /// The factor `P_degree(ξ_dim)`.
    pub fn new(dim: usize, degree: usize) -> Factor {
        Factor {
            dim: dim as u32,
            degree: degree as u32,
        }
    }
}

/// A downward-closed set of multi-indices in canonical (graded lexicographic) order.
///
/// ```
/// use ribbon::uq::MultiIndexSet;
/// // Total degree 2 in d = 60: C(62, 2) = 1891 terms.
/// let set = MultiIndexSet::total_degree(60, 2)?;
/// assert_eq!(set.len(), 1891);
/// // Terms 1..=60 are ξ1..ξ60, term 61 is P_2(ξ1), term 62 is P_1(ξ1) P_1(ξ2).
/// assert_eq!(set.to_dense(61)[..2], [2, 0]);
/// assert_eq!(set.to_dense(62), [1, 1].into_iter().chain([0; 58]).collect::<Vec<_>>());
/// assert_eq!(set.index_of_dense(&set.to_dense(62)), Some(62));
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MultiIndexSet {
    dim: usize,
    /// Term t's factors are `factors[offsets[t]..offsets[t + 1]]`, sorted by dimension.
    offsets: Vec<usize>,
    factors: Vec<Factor>,
    /// Highest degree present per dimension.
    max_degree: Vec<usize>,
    /// First term of each total degree: terms of degree n are `degree_starts[n]..degree_starts[n+1]`.
    degree_starts: Vec<usize>,
    lookup: HashMap<Box<[Factor]>, usize>,
    /// Per factor, `dim · (max_degree() + 1) + degree`: its entry in a `d × (k+1)` table of basis
    /// values (what evaluation reads).
    table_index: Vec<u32>,
    /// Per factor, its dimension (`factors[i].dim`): a term's dimensions as one slice.
    factor_dims: Vec<u32>,
    /// The terms grouped by support size, with their table indices and dimensions at hand.
    plan: EvalPlan,
}

/// A term with one factor: `P_degree(ξ_dim)`, table entry `index`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Single {
    pub(crate) term: u32,
    pub(crate) index: u32,
    pub(crate) dim: u32,
}

/// A term with two factors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pair {
    pub(crate) term: u32,
    pub(crate) index_a: u32,
    pub(crate) dim_a: u32,
    pub(crate) index_b: u32,
    pub(crate) dim_b: u32,
}

/// Evaluation order of a set's non-constant terms: single-factor and two-factor terms in flat
/// lists (no per-term slice lookups), the rest as [`GeneralTerm`]s. Two-factor terms of degree one in
/// both dimensions (`P_1(ξ_r) P_1(ξ_s) = ξ_r ξ_s`, the bilinear part, whose Hessian is constant)
/// are kept apart from the other two-factor terms.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct EvalPlan {
    pub(crate) singles: Vec<Single>,
    pub(crate) bilinear: Vec<Pair>,
    pub(crate) pairs: Vec<Pair>,
    pub(crate) general: Vec<GeneralTerm>,
    /// The same terms by the Hessian rows they add to.
    pub(crate) rows: RowLists,
}

/// A term of three or more factors in a plan, with its table indices and dimensions kept in the
/// entry when it has at most [`GeneralTerm::INLINE`] factors (every general term of a design of
/// total degree 4 or less): evaluation then reads them without the set's offsets. Before (issue
/// 40), the gradient and the Hessian looked both up through the offsets per term; with them here
/// the box search of the README's d = 32 scaling row (296 three-factor terms) takes about 6 %
/// fewer instructions (callgrind, one thread).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct GeneralTerm {
    /// The term's index in the set.
    pub(crate) term: u32,
    /// Its number of factors.
    len: u32,
    /// Its first (up to) four table indices.
    index: [u32; GeneralTerm::INLINE],
    /// Its first (up to) four factors' dimensions.
    dims: [u32; GeneralTerm::INLINE],
}

impl GeneralTerm {
    /// How many factors a term's entry holds.
    pub(crate) const INLINE: usize = 4;

    /// Term `term` of `factors` with table indices `index` (the same length).
    fn new(term: u32, factors: &[Factor], index: &[u32]) -> GeneralTerm {
        let mut entry = GeneralTerm {
            term,
            len: factors.len() as u32,
            ..GeneralTerm::default()
        };
        for ((slot, dim), (f, &i)) in entry
            .index
            .iter_mut()
            .zip(&mut entry.dims)
            .zip(factors.iter().zip(index))
        {
            *slot = i;
            *dim = f.dim;
        }
        entry
    }

    /// The term's table indices (`set` its set: read from there beyond [`Self::INLINE`]).
    #[inline(always)]
    pub(crate) fn indices<'a>(&'a self, set: &'a MultiIndexSet) -> &'a [u32] {
        self.inline_or(&self.index, || set.table_indices(self.term as usize))
    }

    /// The term's factors' dimensions, in the term's order (as [`Self::indices`]).
    #[inline(always)]
    pub(crate) fn dims<'a>(&'a self, set: &'a MultiIndexSet) -> &'a [u32] {
        self.inline_or(&self.dims, || set.factor_dims(self.term as usize))
    }

    /// The first `len` entries of `inline` when the term fits the entry, else what `in_set`
    /// reads from the set.
    #[inline(always)]
    fn inline_or<'a>(
        &self,
        inline: &'a [u32; GeneralTerm::INLINE],
        in_set: impl FnOnce() -> &'a [u32],
    ) -> &'a [u32] {
        let len = self.len as usize;
        if len <= Self::INLINE {
            &inline[..len]
        } else {
            in_set()
        }
    }
}

impl EvalPlan {
    /// Overwrites `out` with this plan restricted to the terms `keep` accepts, every list in
    /// the same order (a surrogate evaluated through `out` sums the kept terms as through this
    /// plan, and skips the others).
    pub(crate) fn kept_into(&self, keep: impl Fn(u32) -> bool, out: &mut EvalPlan) {
        out.singles.clear();
        out.singles
            .extend(self.singles.iter().filter(|s| keep(s.term)).copied());
        out.bilinear.clear();
        out.bilinear
            .extend(self.bilinear.iter().filter(|p| keep(p.term)).copied());
        out.pairs.clear();
        out.pairs
            .extend(self.pairs.iter().filter(|p| keep(p.term)).copied());
        out.general.clear();
        out.general
            .extend(self.general.iter().filter(|g| keep(g.term)).copied());
        self.rows.kept_into(&keep, &mut out.rows);
    }

    /// The number of non-constant terms the plan evaluates.
    pub(crate) fn terms(&self) -> usize {
        self.singles.len() + self.bilinear.len() + self.pairs.len() + self.general.len()
    }
}

impl MultiIndexSet {
    /// All α with `|α| ≤ order`: `C(dim + order, order)` terms.
    ///
    /// Errors: `dim == 0`; more than [`MAX_TERMS`] terms.
    pub fn total_degree(dim: usize, order: usize) -> Result<MultiIndexSet, UqError> {
        MultiIndexSet::anisotropic(&vec![order; dim], order, dim)
    }

    /// All α with `α_r ≤ max_degree_per_dim[r]` for every r, `|α| ≤ total`, and at most
    /// `max_interaction` non-zero entries (`max_interaction = 1`: no interaction terms). The
    /// constraints are monotone, so the set is always downward closed. `dim` is
    /// `max_degree_per_dim.len()`.
    ///
    /// ```
    /// use ribbon::uq::MultiIndexSet;
    /// // Dimension 1 to degree 4, the other 59 to degree 1, pairs at most, total ≤ 4:
    /// // 1 + (4 + 59) pure terms + interactions: ξ_1^a ξ_s (a ≤ 3) 3·59, ξ_r ξ_s among the 59: 1711.
    /// let mut max = vec![1; 60];
    /// max[0] = 4;
    /// let set = MultiIndexSet::anisotropic(&max, 4, 2)?;
    /// assert_eq!(set.len(), 1 + 63 + 3 * 59 + 59 * 58 / 2);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    ///
    /// Errors: an empty `max_degree_per_dim`; more than [`MAX_TERMS`] terms.
    pub fn anisotropic(
        max_degree_per_dim: &[usize],
        total: usize,
        max_interaction: usize,
    ) -> Result<MultiIndexSet, UqError> {
        let dim = max_degree_per_dim.len();
        if dim == 0 {
            return Err(UqError::ZeroDimension);
        }
        let caps: Vec<usize> = max_degree_per_dim.iter().map(|&m| m.min(total)).collect();
        // suffix[r] = Σ_{s ≥ r} caps[s]: the most degree dimensions r.. can still absorb.
        let mut suffix = vec![0; dim + 1];
        for r in (0..dim).rev() {
            suffix[r] = suffix[r + 1] + caps[r];
        }
        let mut builder = Builder::new(dim);
        let mut stack = Vec::with_capacity(dim.min(total.max(1)));
        for degree in 0..=total.min(suffix[0]) {
            builder.start_degree();
            let mut e = Enumeration {
                caps: &caps,
                suffix: &suffix,
                max_interaction,
                builder: &mut builder,
                stack: &mut stack,
            };
            e.run(0, degree)?;
        }
        Ok(builder.finish())
    }

    /// A set from explicit terms, each given as its non-zero `(dimension, degree)` pairs in any
    /// order (pairs with degree 0 are ignored); the terms are put in canonical order. The zero
    /// multi-index must be among them (as an empty list).
    ///
    /// Errors: a dimension `≥ dim` or repeated within a term ([`UqError::InvalidMultiIndex`]), a
    /// repeated term ([`UqError::InvalidMultiIndex`]), a set that is not downward closed
    /// ([`UqError::NotDownwardClosed`], naming a term and its missing predecessor), no terms, more
    /// than [`MAX_TERMS`].
    ///
    /// ```
    /// use ribbon::uq::{MultiIndexSet, UqError};
    /// let ok = MultiIndexSet::from_terms(3, &[vec![], vec![(2, 1)], vec![(2, 2)]])?;
    /// assert_eq!(ok.len(), 3);
    /// // ξ_3² without ξ_3 is not downward closed.
    /// let bad = MultiIndexSet::from_terms(3, &[vec![], vec![(2, 2)]]);
    /// assert!(matches!(bad, Err(UqError::NotDownwardClosed { .. })));
    /// # Ok::<(), UqError>(())
    /// ```
    pub fn from_terms(dim: usize, terms: &[Vec<(usize, usize)>]) -> Result<MultiIndexSet, UqError> {
        if dim == 0 {
            return Err(UqError::ZeroDimension);
        }
        if terms.is_empty() {
            return Err(UqError::Empty {
                what: "multi-index set terms",
            });
        }
        if terms.len() > MAX_TERMS {
            return Err(UqError::TooManyTerms {
                terms: terms.len(),
                max: MAX_TERMS,
            });
        }
        let mut sorted: Vec<Vec<Factor>> = Vec::with_capacity(terms.len());
        for (t, term) in terms.iter().enumerate() {
            let mut factors: Vec<Factor> = term
                .iter()
                .filter(|&&(_, degree)| degree > 0)
                .map(|&(r, degree)| Factor::new(r, degree))
                .collect();
            factors.sort();
            if let Some(f) = factors.iter().find(|f| f.dim as usize >= dim) {
                return Err(UqError::InvalidMultiIndex {
                    term: t,
                    reason: format!(
                        "dimension {} is out of range (the set has {dim} dimensions, 0-based)",
                        f.dim
                    ),
                });
            }
            if let Some(w) = factors.windows(2).find(|w| w[0].dim == w[1].dim) {
                return Err(UqError::InvalidMultiIndex {
                    term: t,
                    reason: format!("dimension {} appears twice", w[0].dim),
                });
            }
            sorted.push(factors);
        }
        sorted.sort_by(|a, b| canonical_cmp(a, b));
        let mut builder = Builder::new(dim);
        let mut previous_degree = None;
        for (i, factors) in sorted.iter().enumerate() {
            if i > 0 && sorted[i - 1] == *factors {
                return Err(UqError::InvalidMultiIndex {
                    term: i,
                    reason: format!("the term {} is given twice", format_factors(factors)),
                });
            }
            let degree = total_of(factors);
            while previous_degree.is_none_or(|p| p < degree) {
                builder.start_degree();
                previous_degree = Some(previous_degree.map_or(0, |p| p + 1));
            }
            builder.push(factors)?;
        }
        let set = builder.finish();
        set.check_downward_closed()?;
        Ok(set)
    }

    /// Verifies that every predecessor `α − e_r` (r in the support of α) is in the set (enough by
    /// induction: then every `β ≤ α` is).
    fn check_downward_closed(&self) -> Result<(), UqError> {
        if self.is_empty() || !self.term(0).is_empty() {
            return Err(UqError::NotDownwardClosed {
                term: self
                    .len()
                    .checked_sub(1)
                    .map_or_else(String::new, |t| format_factors(self.term(t))),
                missing: "the constant term (zero multi-index)".to_string(),
            });
        }
        let mut scratch = Vec::new();
        for t in 0..self.len() {
            let term = self.term(t);
            for i in 0..term.len() {
                scratch.clear();
                scratch.extend_from_slice(term);
                if scratch[i].degree == 1 {
                    scratch.remove(i);
                } else {
                    scratch[i].degree -= 1;
                }
                if self.index_of(&scratch).is_none() {
                    return Err(UqError::NotDownwardClosed {
                        term: format_factors(term),
                        missing: format_factors(&scratch),
                    });
                }
            }
        }
        Ok(())
    }

    /// Number of dimensions d.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of terms |Λ| (≥ 1: the constant is always there).
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Always false: a set holds at least the constant term.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Term t's non-zero factors, sorted by dimension (empty for the constant, t = 0).
    ///
    /// Panics if `t >= len()`.
    pub fn term(&self, t: usize) -> &[Factor] {
        &self.factors[self.offsets[t]..self.offsets[t + 1]]
    }

    /// Total degree `|α|` of term t.
    pub fn total_degree_of(&self, t: usize) -> usize {
        total_of(self.term(t))
    }

    /// Highest total degree present.
    pub fn max_total_degree(&self) -> usize {
        self.degree_starts.len() - 2
    }

    /// The terms of total degree n, as a range of term indices (empty past the highest degree).
    pub fn terms_of_total_degree(&self, n: usize) -> std::ops::Range<usize> {
        if n + 1 >= self.degree_starts.len() {
            return self.len()..self.len();
        }
        self.degree_starts[n]..self.degree_starts[n + 1]
    }

    /// Highest degree present in each dimension (length d).
    pub fn max_degree_per_dim(&self) -> &[usize] {
        &self.max_degree
    }

    /// Highest degree present in any dimension.
    pub fn max_degree(&self) -> usize {
        self.max_degree.iter().copied().max().unwrap_or(0)
    }

    /// Term index of the multi-index with these factors (sorted by dimension, degrees ≥ 1), if in
    /// the set.
    pub fn index_of(&self, factors: &[Factor]) -> Option<usize> {
        self.lookup.get(factors).copied()
    }

    /// Term index of a dense multi-index `(α_1, …, α_d)`; `None` if absent or of the wrong length.
    pub fn index_of_dense(&self, alpha: &[usize]) -> Option<usize> {
        if alpha.len() != self.dim {
            return None;
        }
        let factors: Vec<Factor> = alpha
            .iter()
            .enumerate()
            .filter(|&(_, &a)| a > 0)
            .map(|(r, &a)| Factor::new(r, a))
            .collect();
        self.index_of(&factors)
    }

    /// Term t as a dense multi-index of length d (allocates; for tests and reports).
    pub fn to_dense(&self, t: usize) -> Vec<usize> {
        let mut alpha = vec![0; self.dim];
        for f in self.term(t) {
            alpha[f.dim as usize] = f.degree as usize;
        }
        alpha
    }

    /// Total number of stored factors (Σ over terms of the support size).
    pub fn n_factors(&self) -> usize {
        self.factors.len()
    }

    /// Term t's factors as indices into a row-major `d × (max_degree() + 1)` table of per-dimension
    /// basis values (`dim · (k+1) + degree`).
    pub(crate) fn table_indices(&self, t: usize) -> &[u32] {
        &self.table_index[self.offsets[t]..self.offsets[t + 1]]
    }

    /// Term t's factors' dimensions, in the term's order.
    pub(crate) fn factor_dims(&self, t: usize) -> &[u32] {
        &self.factor_dims[self.offsets[t]..self.offsets[t + 1]]
    }

    /// The terms grouped by support size (constant excluded).
    pub(crate) fn plan(&self) -> &EvalPlan {
        &self.plan
    }
}

/// Builds a set term by term in canonical order.
struct Builder {
    dim: usize,
    offsets: Vec<usize>,
    factors: Vec<Factor>,
    max_degree: Vec<usize>,
    degree_starts: Vec<usize>,
    lookup: HashMap<Box<[Factor]>, usize>,
}

impl Builder {
    fn new(dim: usize) -> Builder {
        Builder {
            dim,
            offsets: vec![0],
            factors: Vec::new(),
            max_degree: vec![0; dim],
            degree_starts: Vec::new(),
            lookup: HashMap::new(),
        }
    }

    /// Marks the start of the next total degree.
    fn start_degree(&mut self) {
        self.degree_starts.push(self.offsets.len() - 1);
    }

    fn push(&mut self, factors: &[Factor]) -> Result<(), UqError> {
        let t = self.offsets.len() - 1;
        if t >= MAX_TERMS {
            return Err(UqError::TooManyTerms {
                terms: t + 1,
                max: MAX_TERMS,
            });
        }
        self.factors.extend_from_slice(factors);
        self.offsets.push(self.factors.len());
        for f in factors {
            let m = &mut self.max_degree[f.dim as usize];
            *m = (*m).max(f.degree as usize);
        }
        self.lookup.insert(factors.into(), t);
        Ok(())
    }

    fn finish(mut self) -> MultiIndexSet {
        let n = self.offsets.len() - 1;
        // Drop trailing empty degrees (a cap below `total`), then close the ranges.
        while self.degree_starts.len() > 1 && *self.degree_starts.last().unwrap_or(&0) == n {
            self.degree_starts.pop();
        }
        self.degree_starts.push(n);
        let stride = self.max_degree.iter().copied().max().unwrap_or(0) + 1;
        let table_index = self
            .factors
            .iter()
            .map(|f| (f.dim as usize * stride + f.degree as usize) as u32)
            .collect::<Vec<u32>>();
        let mut plan = EvalPlan::default();
        for t in 1..n {
            let range = self.offsets[t]..self.offsets[t + 1];
            let (f, idx) = (&self.factors[range.clone()], &table_index[range]);
            match f.len() {
                1 => plan.singles.push(Single {
                    term: t as u32,
                    index: idx[0],
                    dim: f[0].dim,
                }),
                2 => {
                    let pair = Pair {
                        term: t as u32,
                        index_a: idx[0],
                        dim_a: f[0].dim,
                        index_b: idx[1],
                        dim_b: f[1].dim,
                    };
                    if f[0].degree == 1 && f[1].degree == 1 {
                        plan.bilinear.push(pair);
                    } else {
                        plan.pairs.push(pair);
                    }
                }
                _ => plan.general.push(GeneralTerm::new(t as u32, f, idx)),
            }
        }
        let factor_dims: Vec<u32> = self.factors.iter().map(|f| f.dim).collect();
        plan.rows = RowLists::of(&plan, self.dim, |t| {
            &factor_dims[self.offsets[t]..self.offsets[t + 1]]
        });
        MultiIndexSet {
            dim: self.dim,
            offsets: self.offsets,
            factors: self.factors,
            max_degree: self.max_degree,
            degree_starts: self.degree_starts,
            lookup: self.lookup,
            table_index,
            factor_dims,
            plan,
        }
    }
}

/// Depth-first enumeration of the multi-indices of one exact total degree, in canonical order
/// (larger degree in an earlier dimension first).
struct Enumeration<'a> {
    caps: &'a [usize],
    suffix: &'a [usize],
    max_interaction: usize,
    builder: &'a mut Builder,
    stack: &'a mut Vec<Factor>,
}

impl Enumeration<'_> {
    fn run(&mut self, r: usize, remaining: usize) -> Result<(), UqError> {
        if remaining == 0 {
            let stack = std::mem::take(self.stack);
            let result = self.builder.push(&stack);
            *self.stack = stack;
            return result;
        }
        if r == self.caps.len()
            || self.suffix[r] < remaining
            || self.stack.len() >= self.max_interaction
        {
            return Ok(());
        }
        for a in (1..=self.caps[r].min(remaining)).rev() {
            self.stack.push(Factor::new(r, a));
            self.run(r + 1, remaining - a)?;
            self.stack.pop();
        }
        // α_r = 0: skip ahead.
        self.run(r + 1, remaining)
    }
}

fn total_of(factors: &[Factor]) -> usize {
    factors.iter().map(|f| f.degree as usize).sum()
}

/// Canonical order on sparse terms (module doc): total degree, then the first differing dimension
/// with the larger degree first.
fn canonical_cmp(a: &[Factor], b: &[Factor]) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    match total_of(a).cmp(&total_of(b)) {
        Ordering::Equal => {}
        other => return other,
    }
    // Walk both sparse lists as dense vectors: the first dimension where the degrees differ.
    let (mut i, mut j) = (0, 0);
    loop {
        match (a.get(i), b.get(j)) {
            (None, None) => return Ordering::Equal,
            // Equal totals and one exhausted means the other has only zeros left: equal.
            (Some(_), None) | (None, Some(_)) => return Ordering::Equal,
            (Some(fa), Some(fb)) => {
                if fa.dim == fb.dim {
                    if fa.degree != fb.degree {
                        return fb.degree.cmp(&fa.degree);
                    }
                    i += 1;
                    j += 1;
                } else if fa.dim < fb.dim {
                    // a has a positive degree where b has 0: a first.
                    return Ordering::Less;
                } else {
                    return Ordering::Greater;
                }
            }
        }
    }
}

/// `ξ1^2·ξ4` style text of a term (1-based dimensions), `1` for the constant.
pub(crate) fn format_factors(factors: &[Factor]) -> String {
    if factors.is_empty() {
        return "1 (the constant)".to_string();
    }
    factors
        .iter()
        .map(|f| {
            if f.degree == 1 {
                format!("ξ{}", f.dim + 1)
            } else {
                format!("ξ{}^{}", f.dim + 1, f.degree)
            }
        })
        .collect::<Vec<_>>()
        .join("·")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binomial(n: usize, k: usize) -> usize {
        (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
    }

    /// Brute force over the dense box: every α with α_r ≤ cap_r, filtered, in canonical order.
    fn brute_force(caps: &[usize], total: usize, max_interaction: usize) -> Vec<Vec<usize>> {
        let d = caps.len();
        let mut out = Vec::new();
        let mut alpha = vec![0; d];
        loop {
            let sum: usize = alpha.iter().sum();
            let nnz = alpha.iter().filter(|&&a| a > 0).count();
            if sum <= total && nnz <= max_interaction {
                out.push(alpha.clone());
            }
            let mut r = d;
            loop {
                if r == 0 {
                    out.sort_by(|a, b| {
                        let sa: usize = a.iter().sum();
                        let sb: usize = b.iter().sum();
                        sa.cmp(&sb).then_with(|| b.cmp(a))
                    });
                    return out;
                }
                r -= 1;
                if alpha[r] < caps[r] {
                    alpha[r] += 1;
                    break;
                }
                alpha[r] = 0;
            }
        }
    }

    #[test]
    fn total_degree_counts_match_binomials() {
        for (d, k) in [
            (1, 0),
            (1, 5),
            (2, 3),
            (3, 4),
            (10, 2),
            (10, 3),
            (60, 2),
            (100, 2),
        ] {
            let set = MultiIndexSet::total_degree(d, k).unwrap();
            assert_eq!(set.len(), binomial(d + k, k), "d={d} k={k}");
            assert_eq!(set.max_total_degree(), k);
            for n in 0..=k {
                // Terms of exact degree n: C(d + n − 1, n).
                let range = set.terms_of_total_degree(n);
                let expected = if n == 0 { 1 } else { binomial(d + n - 1, n) };
                assert_eq!(range.len(), expected, "d={d} n={n}");
                assert!(range.clone().all(|t| set.total_degree_of(t) == n));
            }
        }
        // d = 100, k = 3: C(103, 3) = 176 851 terms, cheap.
        let big = MultiIndexSet::total_degree(100, 3).unwrap();
        assert_eq!(big.len(), 176_851);
        assert_eq!(big.index_of_dense(&big.to_dense(123_456)), Some(123_456));
    }

    #[test]
    fn canonical_order_and_lookup() {
        let set = MultiIndexSet::total_degree(3, 2).unwrap();
        let dense: Vec<Vec<usize>> = (0..set.len()).map(|t| set.to_dense(t)).collect();
        let expected: Vec<Vec<usize>> = vec![
            vec![0, 0, 0],
            vec![1, 0, 0],
            vec![0, 1, 0],
            vec![0, 0, 1],
            vec![2, 0, 0],
            vec![1, 1, 0],
            vec![1, 0, 1],
            vec![0, 2, 0],
            vec![0, 1, 1],
            vec![0, 0, 2],
        ];
        assert_eq!(dense, expected);
        for (t, alpha) in expected.iter().enumerate() {
            assert_eq!(set.index_of_dense(alpha), Some(t));
        }
        assert_eq!(set.index_of_dense(&[1, 1, 1]), None);
        assert_eq!(set.index_of_dense(&[1, 1]), None);
        assert_eq!(set.term(5), &[Factor::new(0, 1), Factor::new(1, 1)]);
        assert_eq!(set.max_degree_per_dim(), &[2, 2, 2]);
    }

    #[test]
    fn anisotropic_matches_brute_force() {
        for (caps, total, inter) in [
            (vec![3, 1, 2, 0], 4, 2),
            (vec![4, 4, 1, 1, 1], 5, 3),
            (vec![2, 2, 2], 6, 3),
            (vec![2, 2, 2], 6, 1),
            (vec![5, 0, 3], 3, 2),
        ] {
            let set = MultiIndexSet::anisotropic(&caps, total, inter).unwrap();
            let want = brute_force(&caps, total, inter);
            let got: Vec<Vec<usize>> = (0..set.len()).map(|t| set.to_dense(t)).collect();
            assert_eq!(got, want, "caps {caps:?} total {total} inter {inter}");
            // The checked constructor accepts it back (it is downward closed).
            let terms: Vec<Vec<(usize, usize)>> = (0..set.len())
                .rev()
                .map(|t| {
                    set.term(t)
                        .iter()
                        .map(|f| (f.dim as usize, f.degree as usize))
                        .collect()
                })
                .collect();
            assert_eq!(MultiIndexSet::from_terms(caps.len(), &terms).unwrap(), set);
        }
        // Closed form: caps k on the first a dims, 1 elsewhere, no interactions: 1 + a·k + (d − a).
        let mut caps = vec![1; 50];
        caps[..5].fill(4);
        let set = MultiIndexSet::anisotropic(&caps, 4, 1).unwrap();
        assert_eq!(set.len(), 1 + 5 * 4 + 45);
        // Pairs only, total 2, d = 60: 1 + 60 + 60 + C(60, 2) = C(62, 2).
        let pairs = MultiIndexSet::anisotropic(&[2; 60], 2, 2).unwrap();
        assert_eq!(pairs.len(), binomial(62, 2));
    }

    #[test]
    fn from_terms_refuses_bad_sets() {
        let missing = MultiIndexSet::from_terms(2, &[vec![], vec![(0, 1)], vec![(0, 1), (1, 1)]]);
        match missing {
            Err(UqError::NotDownwardClosed { term, missing }) => {
                assert_eq!(term, "ξ1·ξ2");
                assert_eq!(missing, "ξ2");
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            MultiIndexSet::from_terms(2, &[vec![(0, 1)]]),
            Err(UqError::NotDownwardClosed { .. })
        ));
        assert!(matches!(
            MultiIndexSet::from_terms(2, &[vec![], vec![(2, 1)]]),
            Err(UqError::InvalidMultiIndex { .. })
        ));
        assert!(matches!(
            MultiIndexSet::from_terms(2, &[vec![], vec![(0, 1), (0, 2)]]),
            Err(UqError::InvalidMultiIndex { .. })
        ));
        assert!(matches!(
            MultiIndexSet::from_terms(2, &[vec![], vec![(1, 1)], vec![(1, 1), (0, 0)]]),
            Err(UqError::InvalidMultiIndex { .. })
        ));
        assert!(MultiIndexSet::from_terms(0, &[vec![]]).is_err());
        assert!(MultiIndexSet::from_terms(2, &[]).is_err());
        assert!(MultiIndexSet::anisotropic(&[], 2, 2).is_err());
    }

    #[test]
    fn degenerate_sets() {
        let constant = MultiIndexSet::total_degree(5, 0).unwrap();
        assert_eq!(constant.len(), 1);
        assert_eq!(constant.max_total_degree(), 0);
        assert!(constant.term(0).is_empty());
        // Caps all zero with a positive total: only the constant, degree ranges closed.
        let capped = MultiIndexSet::anisotropic(&[0, 0], 3, 2).unwrap();
        assert_eq!(capped.len(), 1);
        assert_eq!(capped.max_total_degree(), 0);
        assert!(capped.terms_of_total_degree(2).is_empty());
    }
}
