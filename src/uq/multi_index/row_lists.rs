//! The terms of an [`EvalPlan`] grouped by the Hessian rows they add to, for building the
//! Hessian block of a few free dimensions without walking every term
//! (`SparseSurrogate::free_hessian_at_loaded`): a term adds to the rows of the dimensions it
//! contains, so the block of the free dimensions needs only the terms that contain one of them.
//! On the README's scaling rows 41–64 % of the terms contain a free dimension of the box
//! optimiser's iteration, 1.8 to 4.4 free dimensions at its last (issue 40).
//!
//! Each list keeps the plan's order, so an entry of the block sums the same terms in the same
//! order, to the same bits, as the walk over every term.
//!
//! Does not: evaluate anything (`SparseSurrogate`), or order the terms (`MultiIndexSet`).

use super::{EvalPlan, GeneralTerm, Pair, Single};

/// Per dimension r, the plan's terms that add to row r of the Hessian (compressed rows:
/// dimension r's entries are `offsets[r]..offsets[r + 1]` of each list).
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct RowLists {
    /// Bilinear terms under their earlier dimension only: each adds one constant to the upper
    /// entry of its two dimensions, which no other bilinear term adds to.
    bilinear: Vec<Pair>,
    bilinear_offsets: Vec<usize>,
    singles: Vec<Single>,
    single_offsets: Vec<usize>,
    /// Two-factor terms under both of their dimensions.
    pairs: Vec<Pair>,
    pair_offsets: Vec<usize>,
    /// Terms of three or more factors under each of their dimensions: (the term's plan entry,
    /// the factor's place in the term).
    general: Vec<GeneralRow>,
    general_offsets: Vec<usize>,
}

/// A term of three or more factors seen from one of its dimensions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GeneralRow {
    /// The term's plan entry (its index in the set, table indices and dimensions).
    pub(crate) general: GeneralTerm,
    /// Which of the term's factors (0-based, in the term's order) has this row's dimension.
    pub(crate) factor: u32,
}

/// `entries` (dimension, item) grouped by dimension, each dimension's items in the order given:
/// the grouped items and the offsets of each dimension's run (length `dim + 1`).
fn grouped<T: Copy>(
    dim: usize,
    entries: impl Iterator<Item = (u32, T)> + Clone,
) -> (Vec<T>, Vec<usize>) {
    let mut offsets = vec![0usize; dim + 1];
    for (r, _) in entries.clone() {
        offsets[r as usize + 1] += 1;
    }
    for r in 0..dim {
        offsets[r + 1] += offsets[r];
    }
    let mut next = offsets.clone();
    let mut out: Vec<Option<T>> = vec![None; offsets[dim]];
    for (r, item) in entries {
        out[next[r as usize]] = Some(item);
        next[r as usize] += 1;
    }
    (out.into_iter().flatten().collect(), offsets)
}

/// The items of each row (`items[offsets[r]..offsets[r + 1]]`) that `keep` accepts, in order,
/// into `out_items` with their offsets into `out_offsets` (both overwritten).
fn kept_rows<T: Copy>(
    items: &[T],
    offsets: &[usize],
    keep: impl Fn(&T) -> bool,
    out_items: &mut Vec<T>,
    out_offsets: &mut Vec<usize>,
) {
    out_items.clear();
    out_offsets.clear();
    out_offsets.push(0);
    for row in offsets.windows(2) {
        out_items.extend(
            items[row[0]..row[1]]
                .iter()
                .copied()
                .filter(|item| keep(item)),
        );
        out_offsets.push(out_items.len());
    }
}

impl RowLists {
    /// The lists of `plan` for a set of dimension `dim`; `term_dims(t)` the dimensions of term
    /// t's factors, in the term's order.
    pub(crate) fn of<'a>(
        plan: &EvalPlan,
        dim: usize,
        term_dims: impl Fn(usize) -> &'a [u32],
    ) -> RowLists {
        let (bilinear, bilinear_offsets) =
            grouped(dim, plan.bilinear.iter().map(|p| (p.dim_a, *p)));
        let (singles, single_offsets) = grouped(dim, plan.singles.iter().map(|s| (s.dim, *s)));
        let (pairs, pair_offsets) = grouped(
            dim,
            plan.pairs
                .iter()
                .flat_map(|p| [(p.dim_a, *p), (p.dim_b, *p)]),
        );
        let (general, general_offsets) = grouped(
            dim,
            plan.general.iter().flat_map(|&general| {
                term_dims(general.term as usize)
                    .iter()
                    .enumerate()
                    .map(move |(e, &dim)| {
                        (
                            dim,
                            GeneralRow {
                                general,
                                factor: e as u32,
                            },
                        )
                    })
            }),
        );
        RowLists {
            bilinear,
            bilinear_offsets,
            singles,
            single_offsets,
            pairs,
            pair_offsets,
            general,
            general_offsets,
        }
    }

    /// The bilinear terms whose earlier dimension is r.
    pub(crate) fn bilinear_from(&self, r: usize) -> &[Pair] {
        &self.bilinear[self.bilinear_offsets[r]..self.bilinear_offsets[r + 1]]
    }

    /// The single-factor terms of dimension r.
    pub(crate) fn singles(&self, r: usize) -> &[Single] {
        &self.singles[self.single_offsets[r]..self.single_offsets[r + 1]]
    }

    /// The (non-bilinear) two-factor terms containing dimension r.
    pub(crate) fn pairs(&self, r: usize) -> &[Pair] {
        &self.pairs[self.pair_offsets[r]..self.pair_offsets[r + 1]]
    }

    /// The terms of three or more factors containing dimension r.
    pub(crate) fn general(&self, r: usize) -> &[GeneralRow] {
        &self.general[self.general_offsets[r]..self.general_offsets[r + 1]]
    }

    /// Overwrites `out` with these lists restricted to the terms `keep` accepts (each row in
    /// the same order, so a block built from `out` sums the kept terms as this one does).
    pub(crate) fn kept_into(&self, keep: impl Fn(u32) -> bool, out: &mut RowLists) {
        kept_rows(
            &self.bilinear,
            &self.bilinear_offsets,
            |p| keep(p.term),
            &mut out.bilinear,
            &mut out.bilinear_offsets,
        );
        kept_rows(
            &self.singles,
            &self.single_offsets,
            |s| keep(s.term),
            &mut out.singles,
            &mut out.single_offsets,
        );
        kept_rows(
            &self.pairs,
            &self.pair_offsets,
            |p| keep(p.term),
            &mut out.pairs,
            &mut out.pair_offsets,
        );
        kept_rows(
            &self.general,
            &self.general_offsets,
            |g| keep(g.general.term),
            &mut out.general,
            &mut out.general_offsets,
        );
    }

    /// How many list entries the rows `free` hold in all: the work of a block built from them.
    pub(crate) fn entries_of(&self, free: &[usize]) -> usize {
        free.iter()
            .map(|&r| {
                self.single_offsets[r + 1] - self.single_offsets[r] + self.pair_offsets[r + 1]
                    - self.pair_offsets[r]
                    + self.general_offsets[r + 1]
                    - self.general_offsets[r]
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::super::MultiIndexSet;

    /// Each row lists exactly the plan's terms that contain its dimension, in the plan's order
    /// (what makes a block built from the rows sum like the walk over every term).
    #[test]
    fn each_row_lists_the_terms_of_its_dimension_in_the_plans_order() {
        let set = MultiIndexSet::anisotropic(&[3, 1, 2, 1, 1, 2], 5, 4).unwrap();
        let plan = set.plan();
        let rows = &plan.rows;
        for r in 0..set.dim() as u32 {
            let bilinear: Vec<u32> = plan
                .bilinear
                .iter()
                .filter(|p| p.dim_a == r)
                .map(|p| p.term)
                .collect();
            assert_eq!(
                rows.bilinear_from(r as usize)
                    .iter()
                    .map(|p| p.term)
                    .collect::<Vec<_>>(),
                bilinear
            );
            let singles: Vec<u32> = plan
                .singles
                .iter()
                .filter(|s| s.dim == r)
                .map(|s| s.term)
                .collect();
            assert_eq!(
                rows.singles(r as usize)
                    .iter()
                    .map(|s| s.term)
                    .collect::<Vec<_>>(),
                singles
            );
            let pairs: Vec<u32> = plan
                .pairs
                .iter()
                .filter(|p| p.dim_a == r || p.dim_b == r)
                .map(|p| p.term)
                .collect();
            assert_eq!(
                rows.pairs(r as usize)
                    .iter()
                    .map(|p| p.term)
                    .collect::<Vec<_>>(),
                pairs
            );
            let general: Vec<(u32, u32)> = plan
                .general
                .iter()
                .filter_map(|g| {
                    let e = set.term(g.term as usize).iter().position(|f| f.dim == r)?;
                    Some((g.term, e as u32))
                })
                .collect();
            let listed: Vec<(u32, u32)> = rows
                .general(r as usize)
                .iter()
                .map(|g| (g.general.term, g.factor))
                .collect();
            assert_eq!(listed, general);
            assert!(
                !general.is_empty(),
                "dimension {r} is in terms of three or more factors"
            );
        }
        let every: Vec<usize> = (0..set.dim()).collect();
        assert_eq!(
            rows.entries_of(&every),
            plan.singles.len()
                + 2 * plan.pairs.len()
                + plan
                    .general
                    .iter()
                    .map(|g| set.term(g.term as usize).len())
                    .sum::<usize>()
        );
    }
}
