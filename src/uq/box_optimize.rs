//! Bounds of a sparse surrogate over the box [−1, 1]^d whose cost grows polynomially in d
//! (docs/high-dimension.md §7):
//!
//! - **inner**: the smallest and largest surrogate values found by projected Newton with an active
//!   set, from several starts — the centre, the sign vertex of the linear part and its negative,
//!   and caller-given points (the best design points); or each side from its own starts only
//!   ([`BoxOptimizer::inner_bound_per_side_into`], docs/high-dimension.md §7a). Every reported value is attained at the
//!   reported point, so `[lower, upper]` lies inside the surrogate's range;
//! - **outer**: interval arithmetic with exact ranges — each dimension's univariate part
//!   `Σ_n c_{n e_r} P_n(ξ_r)` by its exact range ([`legendre_series_range`]), every interaction
//!   term by the product of the exact ranges of its `P_n` factors ([`Family::exact_range`]) — so
//!   `[outer_lower, outer_upper]` contains the surrogate's range (exact for separable surrogates);
//! - the **gap** between them.
//!
//! Newton iteration for `φ = σ·y` (σ = +1 for the minimum, −1 for the maximum):
//! 1. active set: coordinates on a face whose gradient points out of the box stay fixed; where
//!    no step on the others can lower φ by more than [`DECREASE_TOL`] of the surrogate's
//!    variation to first order, only step 4 is left;
//! 2. on the free ones solve `(H_ff + μI) Δ = −g_f` with μ = 0 if `H_ff` is positive definite, else
//!    the Gershgorin shift that makes it so (one factorisation, no trial loop);
//! 3. projected backtracking (Armijo) along `clamp(x + tΔ)`; if it fails, the same along `−g_f`;
//!    after a shifted or gradient step, the step is lengthened by the doubling `2^k t` that the
//!    quadratic model at x (value, gradient, `H_ff`) predicts lowest, φ evaluated only there
//!    (and at shorter doublings if that one is not lower): the shift makes such steps short, and
//!    their extrema lie on faces that the projection reaches; a descent ends after a step that
//!    lowered φ by at most [`STALLED_DECREASE_TOL`] of the variation;
//! 4. when no descent step remains and `H_ff` is indefinite (a saddle, e.g. ξ1·ξ2 at the centre,
//!    where the gradient vanishes), step along the eigenvector of its most negative eigenvalue to
//!    the box boundary (the only place this allocates).
//!
//! The descent itself (steps 1–4 and the `DescentTrail`) lives in `box_optimize/descent.rs`;
//! this file chooses the starts, keeps each side's best and computes the outer bound.
//!
//! Neither bound encloses the true model: the surrogate's own error is not in them
//! (docs/high-dimension.md §8, the engine's a-posteriori check).

use crate::uq::basis::{Family, MAX_ORDER};
use crate::uq::error::UqError;
use crate::uq::legendre_range::legendre_series_range;
use crate::uq::multi_index::MultiIndexSet;
use crate::uq::sparse_surrogate::{SparseSurrogate, SurrogateWorkspace};
use std::sync::Arc;

mod descent;

use descent::DescentTrail;

/// Newton stops once every coordinate of the accepted step is this small: the extremiser is then
/// located to ~1e-12 and its value (stationary there) to rounding.
pub const STEP_TOL: f64 = 1e-12;

/// A descent stops at a point where no step on the free coordinates can lower φ by more than
/// this fraction of the surrogate's variation `Σ_{α≠0} |c_α|` to first order
/// (`first_order_gain` in `box_optimize/descent.rs`: the sum over the free coordinates of |∂φ/∂ξ_r| times the
/// room to the face φ falls towards; the variation bounds the half-width of the outer bound, so
/// it is the surrogate's own scale); there only the step along negative curvature is still
/// tried (a saddle, where the gradient vanishes). Before, the line searches at such points tried
/// steps whose promised decrease was of the order of rounding and failed (3.3 surrogate values
/// per descent's last iteration on the d = 72 study), or accepted steps gaining 1e-16 to 1e-11
/// of the variation and went on for another iteration (issue 40). What a descent gives up there
/// is at most about this fraction of the variation, far below the 1e-4 of an envelope's width the
/// measurements allow; but the descents that follow take other paths, and a path may end at
/// another local extreme. Measured against no stop on the README's scaling rows and the d = 72
/// study (`scripts/compare_envelopes.py`): with 1e-11 every output within 5.5e-6 of its width
/// (d = 64, `frame.tool0.y`); 1e-13 the same; 1e-12 moved one record time of the d = 16 row's
/// `q.wrist_3_joint` by 3.6e-4 of its width (a lower minimum found, on an output 1.8e-6 wide);
/// 1e-14 within 4.3e-8. The search's instructions (callgrind, 1 thread): d = 32 row −14 %, d = 72
/// study −5.7 % with 1e-11; −6 % at d = 32 with 1e-13.
pub const DECREASE_TOL: f64 = 1e-11;

/// A descent stops after an iteration that lowered φ by no more than this fraction of the
/// surrogate's variation (the scale of [`DECREASE_TOL`]). Such iterations were mostly of two
/// kinds: a Newton step that converged (the next iteration only confirmed it, at the cost of a
/// gradient, a Hessian block and its eigenvalues), and crawls along an almost flat, indefinite
/// valley, where the shifted steps gained 1e-8 of the variation each and ran to the iteration
/// cap (on the README's d = 32 scaling row 38 descents of 6 837 took 50 iterations, 9 % of
/// all). Measured on the scaling rows d = 8 … 64 against no such stop (issue 40): 13–17 %
/// fewer Newton iterations, every envelope within 1.9e-6 of its width. The stop gives up what
/// the crawl would still have found; the value kept is still attained at the point kept.
///
/// It was 1e-6 until issue 40's d = 32 row needed the margin: a descent from an interior design
/// point moves onto the faces a few coordinates per iteration, and its last iterations gained
/// 1e-6 to 1e-5 of the variation each (a temporary per-iteration log of the d = 64 row). With
/// 1e-5 the inner bound took 0.92 of its time at
/// d = 32 (two sets of side-by-side rounds, one per core), 0.95 at d = 16, 0.98 at d = 64 and 1.0
/// on the d = 72 study; the envelopes of the scaling rows and the d = 72 study moved by at most
/// 1.1e-5 of a width narrower (d = 72, `q.wrist_2_joint`) and 9.8e-5 wider (d = 72,
/// `q.wrist_1_joint`: a lower minimum on another path), with the same runs and every check
/// trusted.
pub const STALLED_DECREASE_TOL: f64 = 1e-5;

/// Default iteration cap per start. Newton converges in a few steps near an extremum; the cap
/// only limits pathological cases.
pub const DEFAULT_MAX_ITERATIONS: usize = 50;

/// The inner and outer bounds of one surrogate, with the points where the inner ones are attained.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BoxBounds {
    /// Smallest surrogate value found (attained at `argmin`).
    pub lower: f64,
    /// Largest surrogate value found (attained at `argmax`).
    pub upper: f64,
    /// Where `lower` is attained, in ξ (length d).
    pub argmin: Vec<f64>,
    /// Where `upper` is attained, in ξ (length d).
    pub argmax: Vec<f64>,
    /// Lower end of the interval enclosure of the surrogate's range (≤ `lower`).
    pub outer_lower: f64,
    /// Upper end of the interval enclosure of the surrogate's range (≥ `upper`).
    pub outer_upper: f64,
    /// Newton iterations spent over all starts (both directions).
    pub iterations: usize,
}

impl BoxBounds {
    /// `lower − outer_lower` (≥ 0): how far the true minimum of the surrogate may lie below the
    /// one found.
    pub fn lower_gap(&self) -> f64 {
        self.lower - self.outer_lower
    }

    /// `outer_upper − upper` (≥ 0).
    pub fn upper_gap(&self) -> f64 {
        self.outer_upper - self.upper
    }

    /// Outer width minus inner width (≥ 0): 0 means the surrogate's range is known exactly.
    pub fn gap(&self) -> f64 {
        self.lower_gap() + self.upper_gap()
    }
}

/// Work buffers and settings of the box optimiser; reuse one per thread.
#[derive(Debug, Clone)]
pub struct BoxOptimizer {
    /// Iteration cap per start (default [`DEFAULT_MAX_ITERATIONS`]).
    pub max_iterations: usize,
    ws: SurrogateWorkspace,
    grad: Vec<f64>,
    hess: Vec<f64>,
    free: Vec<usize>,
    reduced: Vec<f64>,
    step: Vec<f64>,
    trial: Vec<f64>,
    spare: Vec<f64>,
    x: Vec<f64>,
    starts: Vec<f64>,
    linear: Vec<f64>,
    univariate: Vec<f64>,
    /// What the outer bound needs of each term of the set it was last computed for (the set's
    /// own, not the coefficients'): [`OuterTerms`].
    outer_terms: Option<OuterTerms>,
    /// The descents of the side being searched, for [`BoxOptimizer::descend`] to recognise a
    /// point an earlier descent started an iteration from.
    trail: DescentTrail,
    /// Where each descent of the last side searched ended, `k × d` in the order of its starts.
    ends: Vec<f64>,
    /// [`DECREASE_TOL`] times the variation of the surrogate being searched.
    decrease_floor: f64,
    /// [`STALLED_DECREASE_TOL`] times the variation of the surrogate being searched.
    stalled_floor: f64,
    /// Per start given to [`BoxOptimizer::extreme_from_starts_into`], the descent (row of
    /// `ends`) that went from it or from an equal earlier start.
    given_descents: Vec<usize>,
    /// Per free coordinate on its face, its offset from `x` there (length d), for the
    /// expansion's path model.
    moved: Vec<f64>,
    /// The expansion's path model: `H_ff` times the step on the free coordinates still inside
    /// the box, times their face offsets on those on a face, and which are on a face (each
    /// length d; `descent.rs`, `start_path_model`).
    along_inside: Vec<f64>,
    along_faces: Vec<f64>,
    on_face: Vec<bool>,
}

impl Default for BoxOptimizer {
    fn default() -> Self {
        BoxOptimizer::new()
    }
}

impl BoxOptimizer {
    /// An optimiser with empty buffers (sized on first use).
    pub fn new() -> BoxOptimizer {
        BoxOptimizer {
            max_iterations: DEFAULT_MAX_ITERATIONS,
            ws: SurrogateWorkspace::new(),
            grad: Vec::new(),
            hess: Vec::new(),
            free: Vec::new(),
            reduced: Vec::new(),
            step: Vec::new(),
            trial: Vec::new(),
            spare: Vec::new(),
            x: Vec::new(),
            starts: Vec::new(),
            linear: Vec::new(),
            univariate: Vec::new(),
            outer_terms: None,
            trail: DescentTrail::default(),
            ends: Vec::new(),
            decrease_floor: 0.0,
            stalled_floor: 0.0,
            given_descents: Vec::new(),
            moved: Vec::new(),
            along_inside: Vec::new(),
            along_faces: Vec::new(),
            on_face: Vec::new(),
        }
    }

    /// Inner and outer bounds of `s` (module doc). `starts` are extra start points, `k × d`
    /// row-major in [−1, 1]^d (may be empty).
    ///
    /// ```
    /// use std::sync::Arc;
    /// use ribbon::uq::{BoxOptimizer, MultiIndexSet, SparseSurrogate};
    /// // ξ1 ξ2 = P_1(ξ1) P_1(ξ2): zero slope at the centre, range [−1, 1].
    /// let set = Arc::new(MultiIndexSet::total_degree(2, 2)?);
    /// let mut c = vec![0.0; set.len()];
    /// c[set.index_of_dense(&[1, 1]).unwrap()] = 1.0;
    /// let b = BoxOptimizer::new().bound(&SparseSurrogate::new(set, c)?, &[])?;
    /// assert_eq!((b.lower, b.upper), (-1.0, 1.0));
    /// assert_eq!(b.argmin[0] * b.argmin[1], -1.0);
    /// assert_eq!((b.outer_lower, b.outer_upper), (-1.0, 1.0));
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    ///
    /// Errors: `starts` not a multiple of d, a start coordinate non-finite or outside [−1, 1].
    pub fn bound(&mut self, s: &SparseSurrogate, starts: &[f64]) -> Result<BoxBounds, UqError> {
        let mut out = BoxBounds::default();
        self.bound_into(s, starts, &mut out)?;
        Ok(out)
    }

    /// As [`BoxOptimizer::bound`], overwriting `out`. No allocation once the buffers have the
    /// surrogate's size, except at saddle points (an eigen-decomposition, module doc) and for
    /// univariate parts of degree ≥ 3 in the outer bound (their root isolation).
    pub fn bound_into(
        &mut self,
        s: &SparseSurrogate,
        starts: &[f64],
        out: &mut BoxBounds,
    ) -> Result<(), UqError> {
        self.inner_bound_into(s, starts, out)?;
        self.enclose(s, out);
        Ok(())
    }

    /// The inner half of [`BoxOptimizer::bound_into`]: `lower`, `upper`, `argmin`, `argmax` and
    /// `iterations` of `out`; its outer fields are left as they were ([`BoxOptimizer::enclose`]
    /// sets them).
    ///
    /// Errors: as [`BoxOptimizer::bound`].
    pub fn inner_bound_into(
        &mut self,
        s: &SparseSurrogate,
        starts: &[f64],
        out: &mut BoxBounds,
    ) -> Result<(), UqError> {
        let d = s.dim();
        check_starts(starts, d)?;
        self.resize(d);
        // Built-in starts: centre, sign vertex of the linear part, its negative.
        s.linear_part(&mut self.linear)?;
        self.starts.clear();
        self.starts.resize(d, 0.0);
        if self.linear.iter().any(|&c| c != 0.0) {
            for sign in [1.0, -1.0] {
                self.push_sign_vertex(sign);
            }
        }
        self.starts.extend_from_slice(starts);
        out.argmin.resize(d, 0.0);
        out.argmax.resize(d, 0.0);
        out.iterations = 0;
        let all = std::mem::take(&mut self.starts);
        out.lower = self.search_side(s, 1.0, &all, &mut out.argmin, &mut out.iterations);
        out.upper = -self.search_side(s, -1.0, &all, &mut out.argmax, &mut out.iterations);
        self.starts = all;
        Ok(())
    }

    /// As [`BoxOptimizer::inner_bound_into`], but each side searched only from its own starts
    /// (docs/high-dimension.md §7, "Starts per side"): the minimum from the vertex where the linear
    /// part is smallest and `lower_starts`, the maximum from the opposite vertex and
    /// `upper_starts` (both `k × d` row-major in [−1, 1]^d; the centre instead of the vertex when
    /// the surrogate has no linear part). A start equal to an earlier one of its side is skipped:
    /// the descent from it would repeat the earlier one.
    ///
    /// Errors: as [`BoxOptimizer::bound`], for either list of starts.
    pub fn inner_bound_per_side_into(
        &mut self,
        s: &SparseSurrogate,
        lower_starts: &[f64],
        upper_starts: &[f64],
        out: &mut BoxBounds,
    ) -> Result<(), UqError> {
        let (lower, lower_iterations) =
            self.extreme_from_starts_into(s, false, lower_starts, &mut out.argmin)?;
        let (upper, upper_iterations) =
            self.extreme_from_starts_into(s, true, upper_starts, &mut out.argmax)?;
        out.lower = lower;
        out.upper = upper;
        out.iterations = lower_iterations + upper_iterations;
        Ok(())
    }

    /// One side of [`BoxOptimizer::inner_bound_per_side_into`]: the smallest surrogate value
    /// found (`maximum` false) or the largest (true), searched from that side's vertex of the
    /// linear part (the centre without one) and `starts` (`k × d` row-major in [−1, 1]^d; a start
    /// equal to an earlier one is skipped). The point where it is attained goes to `arg` (resized
    /// to d). Returns the value and the Newton iterations spent. The two sides share nothing, so
    /// they may run on different threads with the same results.
    ///
    /// Errors: as [`BoxOptimizer::bound`].
    pub fn extreme_from_starts_into(
        &mut self,
        s: &SparseSurrogate,
        maximum: bool,
        given: &[f64],
        arg: &mut Vec<f64>,
    ) -> Result<(f64, usize), UqError> {
        let d = s.dim();
        check_starts(given, d)?;
        self.resize(d);
        s.linear_part(&mut self.linear)?;
        let has_slope = self.linear.iter().any(|&c| c != 0.0);
        arg.resize(d, 0.0);
        let mut iterations = 0;
        let sign = if maximum { -1.0 } else { 1.0 };
        self.starts.clear();
        if has_slope {
            // φ = sign·y falls along −sign·c: the vertex −sign·sgn(c).
            self.push_sign_vertex(-sign);
        } else {
            self.starts.resize(d, 0.0);
        }
        self.given_descents.clear();
        for start in given.chunks_exact(d) {
            match self
                .starts
                .chunks_exact(d)
                .position(|earlier| earlier == start)
            {
                Some(earlier) => self.given_descents.push(earlier),
                None => {
                    self.given_descents.push(self.starts.len() / d);
                    self.starts.extend_from_slice(start);
                }
            }
        }
        let starts = std::mem::take(&mut self.starts);
        let phi = self.search_side(s, sign, &starts, arg, &mut iterations);
        self.starts = starts;
        Ok((sign * phi, iterations))
    }

    /// Where the descent from given start `i` of the last
    /// [`BoxOptimizer::extreme_from_starts_into`] ended (length d; a start equal to an earlier
    /// one shares that one's descent): the point from which a later record time's search may
    /// follow that descent's basin (`analysis::sparse_bounds`). `None` when `i` was not a start
    /// of that call.
    pub fn given_start_end(&self, i: usize) -> Option<&[f64]> {
        let d = self.x.len();
        let row = *self.given_descents.get(i)?;
        self.ends.get(row * d..(row + 1) * d)
    }

    /// Appends the vertex `sign · sgn(c_r)` of the linear part `c` (0 where `c_r = 0`) to the
    /// starts.
    fn push_sign_vertex(&mut self, sign: f64) {
        for &c in &self.linear {
            self.starts
                .push(if c == 0.0 { 0.0 } else { sign * c.signum() });
        }
    }

    /// The smallest `φ = sign·y` the descents from `starts` (`k × d`) reach, with its point in
    /// `arg` (the first of equal ones); the descents' iterations are added to `iterations`.
    fn search_side(
        &mut self,
        s: &SparseSurrogate,
        sign: f64,
        starts: &[f64],
        arg: &mut [f64],
        iterations: &mut usize,
    ) -> f64 {
        let d = arg.len();
        let mut best_phi = f64::INFINITY;
        self.trail.clear();
        self.ends.clear();
        let variation: f64 = s.coefficients()[1..].iter().map(|c| c.abs()).sum();
        self.decrease_floor = DECREASE_TOL * variation;
        self.stalled_floor = STALLED_DECREASE_TOL * variation;
        for start in starts.chunks_exact(d) {
            self.x.copy_from_slice(start);
            let (phi, spent) = self.descend(s, sign);
            *iterations += spent;
            self.ends.extend_from_slice(&self.x);
            if phi < best_phi {
                best_phi = phi;
                arg.copy_from_slice(&self.x);
            }
        }
        best_phi
    }

    /// The outer half of [`BoxOptimizer::bound_into`]: `outer_lower` and `outer_upper` of `out`
    /// from the interval enclosure of `s`'s range, widened to the inner bounds already in `out`.
    pub fn enclose(&mut self, s: &SparseSurrogate, out: &mut BoxBounds) {
        (out.outer_lower, out.outer_upper) =
            outer_widened_to_inner(self.outer(s), out.lower, out.upper);
    }

    /// The outer bound alone (module doc): `(lower, upper)` containing the surrogate's range.
    pub fn outer_bound(&mut self, s: &SparseSurrogate) -> (f64, f64) {
        self.outer(s)
    }

    fn resize(&mut self, d: usize) {
        self.grad.resize(d, 0.0);
        self.hess.resize(d * d, 0.0);
        self.reduced.resize(d * d, 0.0);
        self.step.resize(d, 0.0);
        self.trial.resize(d, 0.0);
        self.spare.resize(d, 0.0);
        self.x.resize(d, 0.0);
        self.moved.resize(d, 0.0);
        self.along_inside.resize(d, 0.0);
        self.along_faces.resize(d, 0.0);
        self.on_face.resize(d, false);
        self.linear.resize(d, 0.0);
    }

    fn outer(&mut self, s: &SparseSurrogate) -> (f64, f64) {
        let set = s.set();
        let stride = set.max_degree() + 1;
        if !self
            .outer_terms
            .as_ref()
            .is_some_and(|terms| Arc::ptr_eq(&terms.set, set))
        {
            self.outer_terms = Some(OuterTerms::of(set));
        }
        let Some(terms) = self.outer_terms.as_ref() else {
            unreachable!("the outer terms were just built")
        };
        self.univariate.clear();
        self.univariate.resize(set.dim() * stride, 0.0);
        let c = s.coefficients();
        let (mut lower, mut upper) = (c[0], c[0]);
        for ((&ct, &slot), &(lo, hi)) in c.iter().zip(&terms.slots).zip(&terms.ranges).skip(1) {
            if ct == 0.0 {
                continue;
            }
            if slot != OuterTerms::PRODUCT {
                self.univariate[slot as usize] = ct;
                continue;
            }
            let (a, b) = (ct * lo, ct * hi);
            lower += a.min(b);
            upper += a.max(b);
        }
        for row in self.univariate.chunks_exact(stride) {
            if row.iter().any(|&v| v != 0.0) {
                let (lo, hi) = legendre_series_range(row);
                lower += lo;
                upper += hi;
            }
        }
        (lower, upper)
    }
}

/// Per term of a multi-index set, what the outer bound needs of it whatever its coefficient:
/// a term of one factor `P_n(ξ_r)` goes into dimension r's univariate series (its slot
/// `r·(max degree + 1) + n`), any other term is bounded by the product of its factors' exact
/// ranges (interval multiplication, factor by factor). Built once per set: the products and the
/// table lookups were half the outer bound's time at d = 64 (issue 40), the same numbers each
/// record and output.
#[derive(Debug, Clone)]
struct OuterTerms {
    /// The set these describe.
    set: Arc<MultiIndexSet>,
    /// Per term: its univariate slot, or [`OuterTerms::PRODUCT`].
    slots: Vec<u32>,
    /// Per term: the range of the product of its factors (unused for univariate terms).
    ranges: Vec<(f64, f64)>,
}

impl OuterTerms {
    /// The slot of a term bounded as a product.
    const PRODUCT: u32 = u32::MAX;

    fn of(set: &Arc<MultiIndexSet>) -> OuterTerms {
        let stride = set.max_degree() + 1;
        let factor_ranges: Vec<(f64, f64)> = (0..stride)
            .map(|n| {
                if n <= MAX_ORDER {
                    Family::Legendre.exact_range(n).unwrap_or((-1.0, 1.0))
                } else {
                    // |P_n| ≤ 1 on [−1, 1]: a valid (if crude) enclosure beyond the table.
                    (-1.0, 1.0)
                }
            })
            .collect();
        let mut slots = Vec::with_capacity(set.len());
        let mut ranges = Vec::with_capacity(set.len());
        for t in 0..set.len() {
            let term = set.term(t);
            if term.len() == 1 {
                let slot = term[0].dim as usize * stride + term[0].degree as usize;
                slots.push(u32::try_from(slot).unwrap_or(OuterTerms::PRODUCT));
                ranges.push((-1.0, 1.0));
                continue;
            }
            let (mut lo, mut hi) = (1.0, 1.0);
            for f in term {
                let r = factor_ranges[f.degree as usize];
                let p = [lo * r.0, lo * r.1, hi * r.0, hi * r.1];
                lo = p.iter().copied().fold(f64::INFINITY, f64::min);
                hi = p.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            }
            slots.push(OuterTerms::PRODUCT);
            ranges.push((lo, hi));
        }
        OuterTerms {
            set: Arc::clone(set),
            slots,
            ranges,
        }
    }
}

/// The outer bound `(lower, upper)` widened to contain the inner one `[inner_lower,
/// inner_upper]`: rounding must never put the enclosure inside an attained value.
pub fn outer_widened_to_inner(
    (lower, upper): (f64, f64),
    inner_lower: f64,
    inner_upper: f64,
) -> (f64, f64) {
    (lower.min(inner_lower), upper.max(inner_upper))
}

/// Refuses start points that are not `k × d`, not finite or outside [−1, 1].
fn check_starts(starts: &[f64], d: usize) -> Result<(), UqError> {
    if !starts.len().is_multiple_of(d) {
        return Err(UqError::WrongLength {
            what: "box bound: start points (k × d)",
            expected: (starts.len() / d + 1) * d,
            got: starts.len(),
        });
    }
    if let Some(index) = starts.iter().position(|v| !v.is_finite()) {
        return Err(UqError::NonFinite {
            what: "box bound: start points",
            index,
            value: starts[index],
        });
    }
    if let Some(index) = starts.iter().position(|v| v.abs() > 1.0) {
        return Err(UqError::InvalidInterval {
            index,
            lo: starts[index],
            hi: starts[index],
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::multi_index::MultiIndexSet;

    /// Newton converges quadratically; values at stationary points are exact to rounding of sums
    /// of d terms.
    const VALUE_TOL: f64 = 1e-12;

    fn set_coef(set: &MultiIndexSet, c: &mut [f64], alpha: &[(usize, usize)], value: f64) {
        let mut dense = vec![0; set.dim()];
        for &(r, a) in alpha {
            dense[r] = a;
        }
        c[set.index_of_dense(&dense).unwrap()] += value;
    }

    /// Σ_r (ξ_r² − ξ_r/2) = Σ_r (1/3 − P_1/2 + 2/3 P_2): minimum −d/16 at ξ_r = 1/4, maximum
    /// 3d/2 at ξ_r = −1.
    #[test]
    fn separable_interior_minimum_in_24_and_60_dimensions() {
        for d in [24, 60] {
            let set = Arc::new(MultiIndexSet::total_degree(d, 2).unwrap());
            let mut c = vec![0.0; set.len()];
            for r in 0..d {
                c[0] += 1.0 / 3.0;
                set_coef(&set, &mut c, &[(r, 1)], -0.5);
                set_coef(&set, &mut c, &[(r, 2)], 2.0 / 3.0);
            }
            let s = SparseSurrogate::new(set, c).unwrap();
            let b = BoxOptimizer::new().bound(&s, &[]).unwrap();
            let (want_lo, want_hi) = (-(d as f64) / 16.0, 1.5 * d as f64);
            assert!((b.lower - want_lo).abs() < VALUE_TOL, "d={d}: {}", b.lower);
            assert!((b.upper - want_hi).abs() < VALUE_TOL, "d={d}: {}", b.upper);
            assert!(b.argmin.iter().all(|&x| (x - 0.25).abs() < 1e-9));
            assert!(b.argmax.iter().all(|&x| x == -1.0));
            // Separable: the outer bound is exact too.
            assert!((b.outer_lower - want_lo).abs() < VALUE_TOL);
            assert!((b.outer_upper - want_hi).abs() < VALUE_TOL);
            assert!(b.gap() < 1e-10);
        }
    }

    #[test]
    fn bilinear_saddle_at_the_centre() {
        // ξ1 ξ2 + 0 ξ3 in d = 3 with a pure quadratic making the centre a saddle of the whole.
        let set = Arc::new(MultiIndexSet::total_degree(3, 2).unwrap());
        let mut c = vec![0.0; set.len()];
        set_coef(&set, &mut c, &[(0, 1), (1, 1)], 1.0);
        let s = SparseSurrogate::new(set, c).unwrap();
        let b = BoxOptimizer::new().bound(&s, &[]).unwrap();
        assert_eq!((b.lower, b.upper), (-1.0, 1.0));
        assert_eq!(b.argmin[0] * b.argmin[1], -1.0);
        assert_eq!(b.argmax[0] * b.argmax[1], 1.0);
        assert_eq!((b.outer_lower, b.outer_upper), (-1.0, 1.0));
    }

    #[test]
    fn vertex_extremum() {
        // 2ξ1 − 3ξ2 + 0.1 ξ1 ξ2 + 0.2 P_2(ξ3): extremes at vertices in ξ1, ξ2; P_2 max at ±1, min 0.
        let set = Arc::new(MultiIndexSet::total_degree(3, 2).unwrap());
        let mut c = vec![0.0; set.len()];
        set_coef(&set, &mut c, &[(0, 1)], 2.0);
        set_coef(&set, &mut c, &[(1, 1)], -3.0);
        set_coef(&set, &mut c, &[(0, 1), (1, 1)], 0.1);
        set_coef(&set, &mut c, &[(2, 2)], 0.2);
        let s = SparseSurrogate::new(set, c).unwrap();
        let b = BoxOptimizer::new().bound(&s, &[]).unwrap();
        // min: ξ1 = −1, ξ2 = 1: −2 − 3 − 0.1 − 0.1 (P_2(0) = −½) = −5.2; max: 2 + 3 − 0.1 + 0.2 = 5.1.
        assert!((b.lower + 5.2).abs() < VALUE_TOL, "{}", b.lower);
        assert!((b.upper - 5.1).abs() < VALUE_TOL, "{}", b.upper);
        assert_eq!(&b.argmin[..2], &[-1.0, 1.0]);
        assert!(b.argmin[2].abs() < 1e-9);
        assert!(b.outer_lower <= b.lower && b.outer_upper >= b.upper);
    }

    #[test]
    fn random_polynomials_against_a_dense_scan() {
        let mut rng = SplitMix64::new(77);
        let mut opt = BoxOptimizer::new();
        let mut ws = SurrogateWorkspace::new();
        for (d, k, grid) in [(2, 4, 401usize), (2, 3, 401), (3, 3, 81), (3, 2, 81)] {
            for trial in 0..20 {
                let set = Arc::new(MultiIndexSet::total_degree(d, k).unwrap());
                let c: Vec<f64> = (0..set.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let s = SparseSurrogate::new(set, c).unwrap();
                // Caller starts: a coarse 3^d grid, as the engine would pass its best design points.
                let coarse: Vec<f64> = (0..3usize.pow(d as u32))
                    .flat_map(|i| {
                        (0..d).map(move |r| ((i / 3usize.pow(r as u32)) % 3) as f64 - 1.0)
                    })
                    .collect();
                let b = opt.bound(&s, &coarse).unwrap();
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                let mut x = vec![0.0; d];
                for i in 0..grid.pow(d as u32) {
                    let mut rest = i;
                    for xr in x.iter_mut() {
                        *xr = -1.0 + 2.0 * (rest % grid) as f64 / (grid - 1) as f64;
                        rest /= grid;
                    }
                    let v = s.eval(&x, &mut ws).unwrap();
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                // The found extremes are attained values...
                assert!((s.eval(&b.argmin, &mut ws).unwrap() - b.lower).abs() < 1e-14);
                assert!((s.eval(&b.argmax, &mut ws).unwrap() - b.upper).abs() < 1e-14);
                // ...at least as extreme as the scan's (which only samples the grid)...
                assert!(
                    b.lower <= lo + 1e-12,
                    "d={d} k={k} #{trial}: {} > {lo}",
                    b.lower
                );
                assert!(
                    b.upper >= hi - 1e-12,
                    "d={d} k={k} #{trial}: {} < {hi}",
                    b.upper
                );
                // ...and the outer bound contains them.
                assert!(b.outer_lower <= b.lower && b.outer_upper >= b.upper);
            }
        }
    }

    /// End to end: a separable non-polynomial model `Σ_r cos(a_r ξ_r + b_r)` at d = 24, fitted on
    /// the sparse grid of degree 6 per dimension without interactions (145 runs), bounded; the
    /// exact range is the sum of the 1-D ranges. Truncation error of degree 6 for a_r ≤ 1.2 is
    /// ≲ 1.2⁷/7! ≈ 7e-4 per dimension (a crude bound: the Legendre coefficients decay faster; the
    /// measured error is 5e-7 of the width). The issue asks for 1 %; this test asks for 1e-4.
    #[test]
    fn planted_separable_model_at_d24() {
        use crate::uq::sparse_grid::SparseGrid;
        let d = 24;
        let mut rng = SplitMix64::new(24);
        let ab: Vec<(f64, f64)> = (0..d)
            .map(|_| (rng.uniform(0.3, 1.2), rng.uniform(-1.5, 1.5)))
            .collect();
        let model = |x: &[f64]| -> f64 {
            x.iter()
                .zip(&ab)
                .map(|(&xi, &(a, b))| (a * xi + b).cos())
                .sum()
        };
        let (mut lo, mut hi) = (0.0, 0.0);
        for &(a, b) in &ab {
            let (mut l, mut h) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..=100_000 {
                let v = (a * (-1.0 + 2.0 * i as f64 / 100_000.0) + b).cos();
                l = l.min(v);
                h = h.max(v);
            }
            lo += l;
            hi += h;
        }
        let set = Arc::new(MultiIndexSet::anisotropic(&vec![6; d], 6, 1).unwrap());
        let grid = SparseGrid::new(set.clone()).unwrap();
        assert_eq!(grid.n_points(), 1 + 6 * d);
        let values: Vec<f64> = grid.points().chunks_exact(d).map(model).collect();
        let coef = grid.fit().fit(&values, 1).unwrap();
        let s = SparseSurrogate::new(set, coef).unwrap();
        let b = BoxOptimizer::new()
            .bound(&s, &grid.points()[..3 * d])
            .unwrap();
        let width = hi - lo;
        eprintln!(
            "planted d = 24: relative errors lower {:.1e} upper {:.1e} (width {width:.3})",
            (b.lower - lo).abs() / width,
            (b.upper - hi).abs() / width
        );
        for (got, want) in [
            (b.lower, lo),
            (b.upper, hi),
            (b.outer_lower, lo),
            (b.outer_upper, hi),
        ] {
            assert!(
                (got - want).abs() < 1e-4 * width,
                "{got} vs {want} (width {width})"
            );
        }
        // Separable surrogate: outer = inner.
        assert!(b.gap() < 1e-9 * width, "gap {}", b.gap());
        // The model at the predicted extremisers is close to the exact extremes.
        assert!((model(&b.argmin) - lo).abs() < 1e-4 * width);
        assert!((model(&b.argmax) - hi).abs() < 1e-4 * width);
    }

    /// Each given start's descent end is where that descent stopped, an equal start shares the
    /// earlier one's, and a start that was not given has none.
    #[test]
    fn each_given_start_reports_where_its_descent_ended() {
        // ξ1² − ξ1/2 + ξ2²: minimum at (1/4, 0) from any start.
        let set = Arc::new(MultiIndexSet::total_degree(2, 2).unwrap());
        let mut c = vec![0.0; set.len()];
        c[0] = 2.0 / 3.0;
        set_coef(&set, &mut c, &[(0, 1)], -0.5);
        set_coef(&set, &mut c, &[(0, 2)], 2.0 / 3.0);
        set_coef(&set, &mut c, &[(1, 2)], 2.0 / 3.0);
        let s = SparseSurrogate::new(set, c).unwrap();
        let mut opt = BoxOptimizer::new();
        let mut arg = Vec::new();
        let given = [0.9, -0.7, -0.6, 0.8, 0.9, -0.7];
        let (lower, _) = opt
            .extreme_from_starts_into(&s, false, &given, &mut arg)
            .unwrap();
        assert!((lower + 1.0 / 16.0).abs() < VALUE_TOL, "{lower}");
        for i in 0..3 {
            let end = opt.given_start_end(i).unwrap();
            assert!(
                (end[0] - 0.25).abs() < 1e-9 && end[1].abs() < 1e-9,
                "{i}: {end:?}"
            );
        }
        assert_eq!(opt.given_start_end(0), opt.given_start_end(2));
        assert_eq!(opt.given_start_end(3), None);
        // Maximum (convex: every vertex is a local one): each start's own end, not the best.
        let (upper, _) = opt
            .extreme_from_starts_into(&s, true, &given[..4], &mut arg)
            .unwrap();
        assert!((upper - 2.5).abs() < VALUE_TOL, "{upper}");
        assert_eq!(opt.given_start_end(0).unwrap(), &[1.0, -1.0]);
        assert_eq!(opt.given_start_end(1).unwrap(), &[-1.0, 1.0]);
    }

    /// No projected step, whatever its direction and length, promises a larger first-order
    /// decrease than `first_order_gain`, the bound the descent's stop (DECREASE_TOL) relies on;
    /// the box-size gradient step attains it.
    #[test]
    fn no_step_promises_more_than_the_first_order_gain() {
        let mut rng = SplitMix64::new(40);
        let mut opt = BoxOptimizer::new();
        let d = 6;
        opt.resize(d);
        for _ in 0..200 {
            for r in 0..d {
                // Some coordinates on a face.
                opt.x[r] = match rng.uniform(0.0, 4.0) as usize {
                    0 => -1.0,
                    1 => 1.0,
                    _ => rng.uniform(-1.0, 1.0),
                };
                opt.grad[r] = rng.uniform(-2.0, 2.0);
            }
            opt.free = (0..d).filter(|&r| r != 2).collect();
            let gain = opt.first_order_gain();
            let predicted = |step: &dyn Fn(usize) -> f64| -> f64 {
                opt.free
                    .iter()
                    .map(|&r| opt.grad[r] * ((opt.x[r] + step(r)).clamp(-1.0, 1.0) - opt.x[r]))
                    .sum()
            };
            for _ in 0..20 {
                let t = rng.uniform(0.0, 3.0);
                let direction: Vec<f64> = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let promised = -predicted(&|r| t * direction[r]);
                assert!(promised <= gain * (1.0 + 1e-12), "{promised} > {gain}");
            }
            let along_gradient = -predicted(&|r| -2.0 * opt.grad[r].signum());
            assert!(
                (along_gradient - gain).abs() <= 1e-12 * gain,
                "{along_gradient} vs {gain}"
            );
        }
    }

    /// A random surrogate of total degree `k` in d dimensions, coefficients in [−1, 1].
    fn random_surrogate(rng: &mut SplitMix64, d: usize, k: usize) -> SparseSurrogate {
        let set = Arc::new(MultiIndexSet::total_degree(d, k).unwrap());
        let c: Vec<f64> = (0..set.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        SparseSurrogate::new(set, c).unwrap()
    }

    /// One optimiser's outer bounds, over surrogates on different sets in turn (its per-set
    /// table rebuilt when the set changes), equal those of a fresh optimiser bit for bit, and
    /// contain a dense sample of each surrogate.
    #[test]
    fn the_outer_bound_follows_the_set() {
        let mut rng = SplitMix64::new(4_117);
        let mut ws = SurrogateWorkspace::new();
        let first = random_surrogate(&mut rng, 3, 4);
        let second = random_surrogate(&mut rng, 4, 3);
        // The first set again, other coefficients: the table is the set's, not the surrogate's.
        let c: Vec<f64> = (0..first.set().len())
            .map(|_| rng.uniform(-1.0, 1.0))
            .collect();
        let third = SparseSurrogate::new(Arc::clone(first.set()), c).unwrap();
        let mut reused = BoxOptimizer::new();
        for s in [&first, &second, &third, &first] {
            let (lower, upper) = reused.outer_bound(s);
            let fresh = BoxOptimizer::new().outer_bound(s);
            assert_eq!(
                (lower.to_bits(), upper.to_bits()),
                (fresh.0.to_bits(), fresh.1.to_bits())
            );
            for _ in 0..2_000 {
                let x: Vec<f64> = (0..s.dim()).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let y = s.eval(&x, &mut ws).unwrap();
                assert!(lower <= y && y <= upper, "{lower} <= {y} <= {upper}");
            }
        }
    }

    /// The expansion's model `g·Δ + ½ Δ·H_ff Δ` is the surrogate's change itself for a
    /// surrogate of total degree 2, along projected steps that reach the faces too, on a free
    /// subset of the coordinates; for degree 4 it is not (the model is only a guide there).
    #[test]
    fn the_expansion_model_is_exact_for_quadratic_surrogates() {
        let mut rng = SplitMix64::new(4_009);
        let mut ws = SurrogateWorkspace::new();
        let d = 6;
        let mut largest_quartic_miss = 0.0_f64;
        for (degree, trials) in [(2, 40), (4, 10)] {
            for _ in 0..trials {
                let s = random_surrogate(&mut rng, d, degree);
                let mut opt = BoxOptimizer::new();
                opt.resize(d);
                for sign in [1.0, -1.0] {
                    for r in 0..d {
                        opt.x[r] = rng.uniform(-1.0, 1.0);
                    }
                    let phi = opt.evaluate(&s, sign);
                    opt.free = (0..d).filter(|&r| r != 3).collect();
                    opt.evaluate_hessian(&s, sign);
                    for a in 0..opt.free.len() {
                        opt.step[a] = rng.uniform(-1.0, 1.0);
                    }
                    // The path model kept up to date along doublings gives the direct model's
                    // value to rounding.
                    let mut path = opt.start_path_model(0.01);
                    let mut t = 0.01;
                    for _ in 0..12 {
                        let direct = opt.model_change_at(t);
                        assert!(
                            (path - direct).abs() <= 1e-12 * (1.0 + direct.abs()),
                            "{path} vs {direct} at {t}"
                        );
                        match opt.advance_path_model(2.0 * t, t) {
                            Some(next) => path = next,
                            None => break,
                        }
                        t *= 2.0;
                    }
                    for t in [0.01, 0.3, 1.0, 4.0] {
                        let model = opt.model_change_at(t);
                        let mut y = opt.x.clone();
                        for (a, &r) in opt.free.iter().enumerate() {
                            y[r] = (opt.x[r] + t * opt.step[a]).clamp(-1.0, 1.0);
                        }
                        let change = sign * s.eval(&y, &mut ws).unwrap() - phi;
                        let miss = (model - change).abs();
                        if degree == 2 {
                            assert!(miss <= 1e-12 * (1.0 + change.abs()), "{model} vs {change}");
                        } else {
                            largest_quartic_miss = largest_quartic_miss.max(miss);
                        }
                    }
                }
            }
        }
        assert!(largest_quartic_miss > 1e-3, "{largest_quartic_miss}");
    }

    /// After an accepted step, the expansion returns a value attained at the point it leaves
    /// in `trial`, no higher than the accepted one, and that point lies on the projected path
    /// at a doubling of the accepted length (or is the accepted point).
    #[test]
    fn the_expansion_returns_an_attained_lower_point_on_the_path() {
        let mut rng = SplitMix64::new(4_010);
        let mut ws = SurrogateWorkspace::new();
        let d = 5;
        let mut moved_on = 0;
        for _ in 0..200 {
            let s = random_surrogate(&mut rng, d, 4);
            let mut opt = BoxOptimizer::new();
            opt.resize(d);
            let sign = if rng.uniform(0.0, 1.0) < 0.5 {
                1.0
            } else {
                -1.0
            };
            for r in 0..d {
                opt.x[r] = rng.uniform(-0.5, 0.5);
            }
            opt.evaluate(&s, sign);
            opt.free = (0..d).collect();
            opt.evaluate_hessian(&s, sign);
            // A short step along the negative gradient: accepted, with room to go further.
            let t = 1e-3;
            for r in 0..d {
                opt.step[r] = -opt.grad[r];
            }
            opt.project_into_trial(t);
            let accepted = opt.phi_at_trial(&s, sign);
            let path_point = opt.trial.clone();
            let value = opt.expand(&s, sign, t, accepted);
            assert!(value <= accepted);
            let attained = sign * s.eval(&opt.trial, &mut ws).unwrap();
            assert!((attained - value).abs() <= 1e-12 * (1.0 + value.abs()));
            if value < accepted {
                moved_on += 1;
                let on_path = (1..=descent::MAX_DOUBLINGS).any(|k| {
                    let longer = t * (1u64 << k) as f64;
                    (0..d)
                        .all(|r| opt.trial[r] == (opt.x[r] + longer * opt.step[r]).clamp(-1.0, 1.0))
                });
                assert!(on_path, "{:?}", opt.trial);
            } else {
                assert_eq!(opt.trial, path_point);
            }
        }
        // Steps of a thousandth of the gradient are short: most expand.
        assert!(moved_on > 100, "{moved_on}");
    }

    #[test]
    fn refuses_bad_starts() {
        let set = Arc::new(MultiIndexSet::total_degree(2, 1).unwrap());
        let s = SparseSurrogate::new(set, vec![0.0, 1.0, 1.0]).unwrap();
        let mut opt = BoxOptimizer::new();
        assert!(opt.bound(&s, &[0.0]).is_err());
        assert!(opt.bound(&s, &[0.0, 1.5]).is_err());
        assert!(opt.bound(&s, &[0.0, f64::NAN]).is_err());
        let b = opt.bound(&s, &[0.5, 0.5]).unwrap();
        assert_eq!((b.lower, b.upper), (-2.0, 2.0));
    }
}
