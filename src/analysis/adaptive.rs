//! The dimension-adaptive sparse design (docs/method.md §11): which Legendre terms to add next,
//! judged by the coefficients the model runs have produced so far.
//!
//! ```text
//! old = {0}, active = {e_j}: run their Leja points
//! repeat: fit on old ∪ active ⇒ indicator of each active term = the larger of its own largest
//!         normalised coefficient and LOOK_AHEAD × its backward neighbours' own coefficients
//!         move the largest active terms to old; their admissible forward neighbours become active
//!         (run their points) — until the budget is spent or every indicator is below tolerance
//! ```
//!
//! This is the greedy algorithm of Gerstner & Griebel (Computing 2003) on nested Leja points
//! (Narayan & Jakeman, SISC 2014): one new run per new term, the set always downward closed, so
//! the interpolant on `old ∪ active` is always defined. Interactions are discovered, not assumed:
//! a separable response never expands a product term whose coefficient is zero.
//!
//! Two rules guard against coefficients that vanish by symmetry, which a purely greedy refinement
//! never looks behind:
//! - **Admissibility.** A forward neighbour is run at once when every backward neighbour is in `old`,
//!   as in Gerstner & Griebel. A new interaction `e_a + e_k` from an expanded linear term `e_a`
//!   whose partner `e_k` is only *evaluated* (not expanded) becomes a **pending** candidate with the
//!   indicator [`LOOK_AHEAD`] × the own coefficient of `e_a`: it competes with the measured terms
//!   and is run when it ranks high enough. A parameter whose own slope and curvature vanish at the
//!   centre (a mass whose centre-of-mass offset has nominal zero) is then still paired with the
//!   important ones first, and the product's own coefficient decides; interactions between two
//!   unimportant parameters are never tried.
//! - **Look-ahead along powers.** An active term inherits [`LOOK_AHEAD`] times the own coefficient
//!   of its backward neighbour *with the same support* (`ξ_a^2` from `ξ_a`, `ξ_a^2 ξ_b` from
//!   `ξ_a ξ_b`), so the even terms of an odd response are refined through. Products inherit
//!   nothing from their factors, and nothing cascades through terms that carry no signal.
//!
//! **Several rounds per stage.** Every run of points is a stage (a lock-step phase over the whole
//! horizon, and on a cluster a scheduling round trip: docs/distributed.md §7), so the study proposes
//! [`ADAPTIVE_ROUNDS_PER_STAGE`] rounds ([`ADAPTIVE_FIRST_STAGE_ROUNDS`] after round 0) before it
//! runs anything: the first from the measured
//! indicators, each later one after [`AdaptiveSet::predict_unmeasured`] has given the terms not yet
//! run the indicator the look-ahead rule would give them (their power parents' own coefficients,
//! measured or themselves predicted, times [`LOOK_AHEAD`]; a new product predicts nothing). Every
//! proposed term passes the same admissibility rule, so the set stays downward closed and every run
//! of the stage is fitted: no run is wasted, and the budget is the same. The next fit measures them
//! all and replaces every prediction.
//!
//! Nothing here runs the model; the study runs the points this returns and hands back the
//! coefficients.

use crate::uq::{leja_points, MultiIndexSet, UqError};
use std::collections::{HashMap, HashSet};

/// A term: its non-zero `(dimension, degree)` pairs, sorted by dimension.
pub type Term = Vec<(usize, usize)>;

/// Highest degree the adaptive design gives one parameter: Leja interpolation of degree 12 in one
/// variable already resolves responses no smooth mechanism needs more for, and it bounds the
/// design's condition number.
pub const ADAPTIVE_MAX_DEGREE: usize = 12;

/// Stop refining when every active term's normalised coefficient is below this: a term that moves
/// an output by less than 10⁻⁴ of its spread is below what any envelope is read to.
pub const ADAPTIVE_TOLERANCE: f64 = 1e-4;

/// Fraction of a parent's own coefficient an active term inherits as its indicator (see the module
/// documentation): large enough that a child of any significant term is explored, small enough that
/// signal-free terms are explored last.
pub const LOOK_AHEAD: f64 = 0.1;

/// Each round adds at least this fraction of the points run so far (and at least
/// [`ADAPTIVE_MIN_BATCH`] points): rounds are lock-step phases over the whole horizon, so they
/// should be few; growth by a quarter reaches 3000 runs from 121 in ~14 rounds.
pub const ADAPTIVE_BATCH_FRACTION: f64 = 0.25;

/// Smallest batch of new points per round.
pub const ADAPTIVE_MIN_BATCH: usize = 8;

/// Rounds proposed per stage (module documentation). Each stage then grows the design about
/// `1.25³ ≈ 2`-fold while the first of its rounds still ranks candidates by measured coefficients
/// alone (only the terms of the stage's earlier rounds are predicted). Measured on the ur5
/// (docs/distributed.md §7): at d = 72 the envelopes stay within 3.6·10⁻⁴ of a width of one round
/// per stage's, at d = 19 within 7·10⁻⁵; where the budget stops the design they move within the
/// surrogate's own error (d = 64: up to 4.3·10⁻³), and four rounds in every stage moved d = 72 by
/// 3·10⁻³.
pub const ADAPTIVE_ROUNDS_PER_STAGE: usize = 3;

/// Rounds proposed by the first stage after round 0: its rounds are the smallest
/// ([`ADAPTIVE_MIN_BATCH`] or a quarter of `d + 1` terms each), so one more of them costs the
/// fewest predicted runs, and it brings the 73-run start at d = 72 to the 3000-run budget in 6
/// stages instead of 7.
pub const ADAPTIVE_FIRST_STAGE_ROUNDS: usize = 4;

/// The state of the greedy refinement.
#[derive(Clone, Debug)]
pub struct AdaptiveSet {
    dim: usize,
    /// Accepted terms.
    old: HashSet<Term>,
    /// Evaluated but not yet expanded, with their indicator (`None` until measured).
    active: Vec<(Term, Option<f64>)>,
    /// Not evaluated, with the indicator they inherit (see the module documentation).
    pending: Vec<(Term, f64)>,
    /// Every evaluated term, in the order its point was run.
    evaluated: Vec<Term>,
    /// Term → index into `evaluated`.
    row_of: HashMap<Term, usize>,
    /// The own indicator (normalised coefficient) measured for each term.
    own: HashMap<Term, f64>,
    /// The own indicator predicted for each term proposed but not yet measured
    /// ([`AdaptiveSet::predict_unmeasured`]); emptied by every measurement.
    predicted: HashMap<Term, f64>,
}

impl AdaptiveSet {
    /// The start: old = {0}, active = {e_j for every j}. Returns the set; its points to run are
    /// [`AdaptiveSet::points`] of [`AdaptiveSet::evaluated`] (the constant's point is the centre).
    pub fn new(dim: usize) -> AdaptiveSet {
        let mut set = AdaptiveSet {
            dim,
            old: HashSet::new(),
            active: Vec::new(),
            pending: Vec::new(),
            evaluated: Vec::new(),
            row_of: HashMap::new(),
            own: HashMap::new(),
            predicted: HashMap::new(),
        };
        set.old.insert(Vec::new());
        set.push_evaluated(Vec::new());
        for j in 0..dim {
            set.push_evaluated(vec![(j, 1)]);
            set.active.push((vec![(j, 1)], None));
        }
        set
    }

    fn push_evaluated(&mut self, term: Term) {
        self.row_of.insert(term.clone(), self.evaluated.len());
        self.evaluated.push(term);
    }

    /// Number of terms (= points run).
    pub fn len(&self) -> usize {
        self.evaluated.len()
    }

    /// Whether no term was evaluated (never: the constant always is).
    pub fn is_empty(&self) -> bool {
        self.evaluated.is_empty()
    }

    /// Every evaluated term, in the order its point was run (the storage order of the values).
    pub fn evaluated(&self) -> &[Term] {
        &self.evaluated
    }

    /// The row of `term` in [`AdaptiveSet::evaluated`].
    pub fn row_of(&self, term: &[(usize, usize)]) -> Option<usize> {
        self.row_of.get(term).copied()
    }

    /// The Leja points of `terms`, row-major `n × d`.
    pub fn points(&self, terms: &[Term]) -> Result<Vec<f64>, UqError> {
        let max_degree = terms
            .iter()
            .flat_map(|t| t.iter().map(|&(_, k)| k))
            .max()
            .unwrap_or(0);
        let z = leja_points(max_degree + 1)?;
        let mut out = vec![0.0; terms.len() * self.dim];
        for (p, term) in terms.iter().enumerate() {
            for &(j, k) in term {
                out[p * self.dim + j] = z[k];
            }
        }
        Ok(out)
    }

    /// The evaluated set (old ∪ active, downward closed) as a [`MultiIndexSet`].
    pub fn multi_index_set(&self) -> Result<MultiIndexSet, UqError> {
        self.multi_index_set_of(self.evaluated.len())
    }

    /// The set of the first `runs` evaluated terms (those run before a later stage, which form a
    /// downward-closed set of their own) as a [`MultiIndexSet`].
    pub fn multi_index_set_of(&self, runs: usize) -> Result<MultiIndexSet, UqError> {
        MultiIndexSet::from_terms(self.dim, &self.evaluated[..runs.min(self.evaluated.len())])
    }

    /// Records the indicator of every active term: `indicator(term)` is its own largest normalised
    /// coefficient over outputs and records; the indicator kept is the larger of that and
    /// [`LOOK_AHEAD`] times its backward neighbours' own coefficients.
    pub fn measure(&mut self, indicator: impl Fn(&[(usize, usize)]) -> f64) {
        self.predicted.clear();
        for (term, _) in &self.active {
            let own = indicator(term);
            self.own
                .insert(term.clone(), if own.is_finite() { own } else { 0.0 });
        }
        for (term, eta) in &mut self.active {
            let own = self.own.get(term).copied().unwrap_or(0.0);
            // Backward neighbours with the same support: lowering a degree ≥ 2.
            let inherited = term
                .iter()
                .filter(|&&(_, degree)| degree >= 2)
                .map(|&(j, _)| self.own.get(&lower(term, j)).copied().unwrap_or(0.0))
                .fold(0.0, f64::max);
            *eta = Some(own.max(LOOK_AHEAD * inherited));
        }
    }

    /// Gives every active term without an indicator (proposed by a round of this stage, not yet
    /// run) the one the look-ahead rule predicts: [`LOOK_AHEAD`] times the largest own coefficient
    /// of its backward neighbours with the same support, measured or themselves predicted (a
    /// chain `ξ_a², ξ_a³, …` inherits through its predicted links); 0 for a new product, whose
    /// coefficient nothing predicts. Measured terms keep their indicators; the next
    /// [`AdaptiveSet::measure`] replaces every prediction.
    pub fn predict_unmeasured(&mut self) {
        // `active` holds terms in the order they were proposed, a parent before its children.
        for a in 0..self.active.len() {
            if self.active[a].1.is_some() {
                continue;
            }
            let term = &self.active[a].0;
            let inherited = term
                .iter()
                .filter(|&&(_, degree)| degree >= 2)
                .map(|&(j, _)| {
                    let parent = lower(term, j);
                    self.own
                        .get(&parent)
                        .or_else(|| self.predicted.get(&parent))
                        .copied()
                        .unwrap_or(0.0)
                })
                .fold(0.0, f64::max);
            let eta = LOOK_AHEAD * inherited;
            self.predicted.insert(term.clone(), eta);
            self.active[a].1 = Some(eta);
        }
    }

    /// The largest indicator of the active and pending terms (0 when there is none).
    pub fn largest_indicator(&self) -> f64 {
        self.active
            .iter()
            .filter_map(|(_, eta)| *eta)
            .chain(self.pending.iter().map(|(_, eta)| *eta))
            .fold(0.0, f64::max)
    }

    /// Expands the most important active terms and runs the most important pending ones until at
    /// least `batch` new terms (or every admissible one, or `budget` in all) are added; returns the
    /// new terms, whose points the caller runs. Terms with an indicator below `tolerance` are left.
    /// Returns an empty list when nothing is left to do.
    pub fn refine(&mut self, batch: usize, budget: usize, tolerance: f64) -> Vec<Term> {
        // Candidates: (indicator, is pending, index), the largest first; ties by term.
        let mut order: Vec<(f64, bool, usize)> = self
            .active
            .iter()
            .enumerate()
            .map(|(a, (_, eta))| (eta.unwrap_or(0.0), false, a))
            .chain(
                self.pending
                    .iter()
                    .enumerate()
                    .map(|(p, (_, eta))| (*eta, true, p)),
            )
            .collect();
        // Compared in place (cloning both terms at every comparison was most of a stage's
        // proposal at d = 64, with thousands of candidates).
        let term_of = |&(_, pending, i): &(f64, bool, usize)| -> &Term {
            if pending {
                &self.pending[i].0
            } else {
                &self.active[i].0
            }
        };
        order.sort_by(|x, y| y.0.total_cmp(&x.0).then_with(|| term_of(x).cmp(term_of(y))));
        let room = budget.saturating_sub(self.len());
        let limit = batch.min(room);
        let mut new_terms: Vec<Term> = Vec::new();
        let mut expanded: Vec<usize> = Vec::new();
        let mut taken: Vec<usize> = Vec::new();
        let mut new_pending: Vec<(Term, f64)> = Vec::new();
        for candidate in &order {
            let (eta, pending, i) = *candidate;
            if new_terms.len() >= limit || eta < tolerance {
                break;
            }
            if pending {
                taken.push(i);
                let term = self.pending[i].0.clone();
                if !self.row_of.contains_key(&term) && !new_terms.contains(&term) {
                    new_terms.push(term);
                }
                continue;
            }
            let term = self.active[i].0.clone();
            self.old.insert(term.clone());
            expanded.push(i);
            let own = self.own.get(&term).copied().unwrap_or(0.0);
            for k in 0..self.dim {
                let forward = raise(&term, k);
                if forward
                    .iter()
                    .any(|&(_, degree)| degree > ADAPTIVE_MAX_DEGREE)
                    || self.row_of.contains_key(&forward)
                    || new_terms.contains(&forward)
                {
                    continue;
                }
                if self.admissible(&forward) {
                    if new_terms.len() < room {
                        new_terms.push(forward);
                    }
                } else if self.pairs_with_evaluated(&term, k) {
                    new_pending.push((forward, LOOK_AHEAD * own));
                }
            }
        }
        expanded.sort_unstable_by(|a, b| b.cmp(a));
        for a in expanded {
            self.active.swap_remove(a);
        }
        taken.sort_unstable_by(|a, b| b.cmp(a));
        for p in taken {
            self.pending.swap_remove(p);
        }
        self.pending.extend(new_pending);
        // Pending terms that became evaluated (through an expansion) are no longer pending.
        let evaluated_now: HashSet<&Term> = new_terms.iter().collect();
        self.pending
            .retain(|(term, _)| !evaluated_now.contains(term) && !self.row_of.contains_key(term));
        self.pending.sort_by(|a, b| a.0.cmp(&b.0));
        self.pending.dedup_by(|a, b| {
            if a.0 == b.0 {
                b.1 = b.1.max(a.1);
                true
            } else {
                false
            }
        });
        for term in &new_terms {
            self.push_evaluated(term.clone());
            self.active.push((term.clone(), None));
        }
        new_terms
    }

    /// Whether every backward neighbour of `forward` is in `old` (Gerstner & Griebel).
    fn admissible(&self, forward: &[(usize, usize)]) -> bool {
        forward
            .iter()
            .all(|&(j, _)| self.old.contains(&lower(forward, j)))
    }

    /// Whether `from + e_k` is a new interaction of a linear term with an evaluated parameter `k`
    /// (a pending candidate).
    fn pairs_with_evaluated(&self, from: &[(usize, usize)], k: usize) -> bool {
        from.len() == 1
            && from[0].1 == 1
            && from[0].0 != k
            && self.row_of.contains_key(&vec![(k, 1)])
    }
}

/// `term + e_k`.
fn raise(term: &[(usize, usize)], k: usize) -> Term {
    let mut out: Term = term.to_vec();
    match out.iter_mut().find(|(j, _)| *j == k) {
        Some((_, degree)) => *degree += 1,
        None => {
            out.push((k, 1));
            out.sort_unstable();
        }
    }
    out
}

/// `term − e_j` (term has a non-zero degree in j).
fn lower(term: &[(usize, usize)], j: usize) -> Term {
    term.iter()
        .filter_map(|&(i, degree)| match (i == j, degree) {
            (true, 1) => None,
            (true, degree) => Some((i, degree - 1)),
            (false, degree) => Some((i, degree)),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uq::SparseGrid;
    use std::sync::Arc;

    /// Runs the adaptive loop on `f` with a budget, one round per fit; returns the final set.
    fn adapt(dim: usize, f: impl Fn(&[f64]) -> f64, budget: usize) -> AdaptiveSet {
        adapt_in_stages(dim, f, budget, 1).0
    }

    #[test]
    fn a_separable_function_gets_no_product_terms_and_high_degree_where_needed() {
        // Dimension 0 needs degree ~8, dimension 2 is linear, the others do nothing.
        let f = |x: &[f64]| (2.0 * x[0]).sin() + 0.5 * x[2];
        let set = adapt(6, f, 200);
        let terms = set.evaluated();
        // Products may be tried once (both parents carry signal) but never refined further.
        assert!(
            terms
                .iter()
                .all(|t| t.len() <= 1 || t.iter().all(|&(_, k)| k == 1)),
            "an interaction was refined: {terms:?}"
        );
        let degree0 = terms
            .iter()
            .filter(|t| t.first().is_some_and(|&(j, _)| j == 0))
            .count();
        assert!(degree0 >= 7, "dimension 0 refined to degree {degree0}");
        // Dead dimensions stay at their first term.
        for j in [1, 3, 4, 5] {
            assert!(!terms.contains(&vec![(j, 3)]), "dimension {j} was refined");
        }
        assert!(set.len() < 60, "{} terms for a 1-D problem", set.len());
    }

    #[test]
    fn an_interaction_is_found_and_the_set_stays_downward_closed() {
        // x3 has no effect of its own at the centre (a mass whose offset has nominal zero), only
        // through x1: the product must still be found.
        let f = |x: &[f64]| x[1] * x[3] + 0.3 * x[1] + 0.1 * x[0];
        let set = adapt(5, f, 100);
        assert!(
            set.row_of(&[(1, 1), (3, 1)]).is_some(),
            "{:?}",
            set.evaluated()
        );
        set.multi_index_set().expect("downward closed");
    }

    #[test]
    fn the_budget_is_never_exceeded() {
        let f = |x: &[f64]| x.iter().map(|v| (3.0 * v).cos()).product::<f64>();
        let set = adapt(8, f, 50);
        assert!(set.len() <= 50, "{}", set.len());
    }

    /// The adaptive loop with `per_stage` rounds proposed per fit (the study's stages), on `f`;
    /// returns the final set and the number of fits (stages).
    fn adapt_in_stages(
        dim: usize,
        f: impl Fn(&[f64]) -> f64,
        budget: usize,
        per_stage: usize,
    ) -> (AdaptiveSet, usize) {
        let mut set = AdaptiveSet::new(dim);
        let mut stages = 0;
        loop {
            stages += 1;
            let mi = set.multi_index_set().expect("downward closed");
            let grid = SparseGrid::new(Arc::new(mi)).unwrap();
            let values: Vec<f64> = grid.points().chunks(dim).map(&f).collect();
            let coefficients = grid.fit().fit(&values, 1).unwrap();
            let scale = values
                .iter()
                .fold(0.0_f64, |a, v| a.max(v.abs()))
                .max(1e-300);
            let mi = grid.set().clone();
            set.measure(|term| {
                let dense: Vec<usize> = (0..dim)
                    .map(|j| term.iter().find(|(i, _)| *i == j).map_or(0, |t| t.1))
                    .collect();
                mi.index_of_dense(&dense)
                    .map_or(0.0, |t| coefficients[t].abs() / scale)
            });
            let mut proposed = 0;
            for round in 0..per_stage {
                if round > 0 {
                    set.predict_unmeasured();
                }
                let batch =
                    ADAPTIVE_MIN_BATCH.max((ADAPTIVE_BATCH_FRACTION * set.len() as f64) as usize);
                let terms = set.refine(batch, budget, ADAPTIVE_TOLERANCE);
                if terms.is_empty() {
                    break;
                }
                proposed += terms.len();
            }
            if proposed == 0 {
                return (set, stages);
            }
        }
    }

    #[test]
    fn predicted_indicators_follow_powers_and_leave_new_products_at_zero() {
        let mut set = AdaptiveSet::new(3);
        // e_0 strong, e_1 weaker, e_2 silent.
        set.measure(|term| match term {
            [(0, 1)] => 0.5,
            [(1, 1)] => 0.2,
            _ => 0.0,
        });
        let first = set.refine(8, 100, ADAPTIVE_TOLERANCE);
        assert!(first.contains(&vec![(0, 2)]) && first.contains(&vec![(0, 1), (1, 1)]));
        set.predict_unmeasured();
        let eta = |set: &AdaptiveSet, term: &[(usize, usize)]| {
            set.active
                .iter()
                .find(|(t, _)| t == term)
                .and_then(|(_, eta)| *eta)
        };
        assert_eq!(eta(&set, &[(0, 2)]), Some(LOOK_AHEAD * 0.5));
        assert_eq!(eta(&set, &[(1, 2)]), Some(LOOK_AHEAD * 0.2));
        assert_eq!(eta(&set, &[(0, 1), (1, 1)]), Some(0.0));
        // A predicted power's child inherits through the prediction: ξ_0³ from ξ_0².
        let second = set.refine(8, 100, ADAPTIVE_TOLERANCE);
        assert!(second.contains(&vec![(0, 3)]), "{second:?}");
        set.predict_unmeasured();
        assert_eq!(eta(&set, &[(0, 3)]), Some(LOOK_AHEAD * LOOK_AHEAD * 0.5));
        // A measurement replaces every prediction.
        set.measure(|_| 0.0);
        assert_eq!(eta(&set, &[(0, 3)]), Some(0.0));
        assert!(set.predicted.is_empty());
    }

    #[test]
    fn several_rounds_per_stage_keep_the_set_closed_and_take_fewer_stages() {
        let f = |x: &[f64]| (2.0 * x[0]).sin() + 0.5 * x[2] + 0.3 * x[1] * (1.0 + x[3]);
        let (one, stages_one) = adapt_in_stages(6, f, 200, 1);
        let (three, stages_three) = adapt_in_stages(6, f, 200, ADAPTIVE_ROUNDS_PER_STAGE);
        three.multi_index_set().expect("downward closed");
        assert!(three.len() <= 200, "{}", three.len());
        assert!(
            stages_three * 4 <= stages_one * 3,
            "{stages_three} stages of {ADAPTIVE_ROUNDS_PER_STAGE} rounds against {stages_one} of one"
        );
        // The same terms that matter are found.
        for term in [vec![(0, 7)], vec![(1, 1), (3, 1)]] {
            assert!(one.row_of(&term).is_some(), "one round: {term:?}");
            assert!(three.row_of(&term).is_some(), "three rounds: {term:?}");
        }
        assert!(
            three.len() <= one.len() + one.len() / 10,
            "{} terms against {}",
            three.len(),
            one.len()
        );
    }

    #[test]
    fn raise_and_lower_are_inverse() {
        let t: Term = vec![(2, 1), (5, 3)];
        assert_eq!(lower(&raise(&t, 0), 0), t);
        assert_eq!(lower(&raise(&t, 5), 5), t);
        assert_eq!(raise(&t, 0), vec![(0, 1), (2, 1), (5, 3)]);
    }
}
