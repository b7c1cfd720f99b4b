//! The descent of the box optimiser ([`super::BoxOptimizer`]): projected Newton with an active
//! set from one start point (the module doc of [`super`] lists its steps) — the Newton direction
//! on the free coordinates with a Gershgorin shift where the Hessian is indefinite, the projected
//! Armijo line search and its expansion, the step along negative curvature at a saddle — and the
//! [`DescentTrail`] that lets a descent reaching an earlier descent's point take that descent's end.
//!
//! Does not: choose the starts or keep the best of them (`super::search_side`), or bound the
//! surrogate from outside (`super::outer`).

use nalgebra::DMatrix;

use super::{BoxOptimizer, STEP_TOL};
use crate::linalg::cholesky;
use crate::uq::sparse_surrogate::SparseSurrogate;

/// Armijo sufficient-decrease constant (standard choice).
const ARMIJO: f64 = 1e-4;

/// Backtracking halvings before giving up on a direction (t ≥ 2⁻³⁰ ≈ 1e-9).
const MAX_HALVINGS: usize = 30;

/// Relative size (to the Hessian's scale) of the extra shift beyond Gershgorin's, and the
/// eigenvalue below which curvature counts as negative.
const CURVATURE_TOL: f64 = 1e-10;

/// The shifts `μ` an indefinite `H_ff + μI` is factorised with, in turn, as fractions of the
/// Gershgorin shift ([`BoxOptimizer::gershgorin_shift`]), which always makes it positive definite
/// (the last, 1) but is far larger than needed when the rows have many entries (it bounds the
/// smallest eigenvalue by the sum of a row's off-diagonal magnitudes): a step
/// `−(H_ff + μI)⁻¹ g` shrinks as `1/μ`, and the line search then doubled it back, one surrogate
/// value per doubling. Any shift the Cholesky factorisation accepts gives a descent direction, so
/// trying a sixteenth and a quarter first costs at most two failed factorisations of the free
/// block and takes longer, more Newton-like steps. At a descent's first two iterations only for
/// a free block small enough that a failed factorisation costs no more than about four surrogate
/// values (`nf³ ≤ 24 |Λ|`; later ones at any size: [`SHIFT_FRACTIONS_AT_ANY_SIZE_FROM`]): at
/// d = 72 the descents from interior design points free all 72 coordinates, and with the
/// fractions there too the search took 3.6 % more instructions than with none (callgrind, the
/// d = 72 study at 0.5 s); with `nf³ ≤ 6 |Λ|` the d = 32 row saved 13.7 % instead of 17.1 %.
/// Measured on the README's scaling rows and the d = 72 study (issue 40; fractions at every nf):
/// 4–19 % fewer Newton iterations and 12–28 % fewer step doublings; a sixty-fourth and a 256th as
/// well saved at most 3 % more iterations.
const SHIFT_FRACTIONS: [f64; 3] = [1.0 / 16.0, 0.25, 1.0];

/// From this iteration of a descent on (the first is 1), an indefinite free block is factorised
/// with the [`SHIFT_FRACTIONS`] whatever its size, not only where a failed factorisation is
/// cheap. A descent still going at its third iteration is mostly one from an interior design
/// point crawling along an indefinite valley with all or almost all coordinates free: with the
/// whole Gershgorin shift alone its steps stay short, and on the README's d = 64 scaling row the
/// 1.4 % of descents that took 20 iterations or more were a fifth of the search's time (counted
/// with a temporary log, one thread). Trying the fractions there costs up to two failed
/// factorisations per iteration and saves more iterations than that (issue 40): the inner
/// bound's time 0.87–0.89 of before at d = 64, 0.98–0.99 at d = 32 and 1.0 at d = 8, 16 and the
/// all-values d = 72 study (medians of 6–10 side-by-side rounds, one per core, one thread
/// each). From the first iteration on (every descent) it was 5 % slower than from the second at
/// d = 64, from the fourth 2 % slower than from the third. The envelopes of the scaling rows and
/// the d = 72 study moved by at most 1.5e-5 of an output's width (d = 64, `q.wrist_3_joint`);
/// runs, check runs and misfits the same. The rule makes an iteration's path depend on its
/// number, so the [`DescentTrail`] matches a point only in the same [`iteration_regime`].
const SHIFT_FRACTIONS_AT_ANY_SIZE_FROM: usize = 3;

/// The most doublings of an accepted step the expansion's model considers (`2^30 t`, as many
/// as the backtracking's halvings).
pub(super) const MAX_DOUBLINGS: usize = MAX_HALVINGS;

/// Rows of the Hessian whose Gershgorin sums [`BoxOptimizer::gershgorin_shift`] adds side by side.
const GERSHGORIN_ROWS_AT_ONCE: usize = 4;

/// The points earlier descents of one side started an iteration from (`k × d`), each with how
/// many iterations its descent took from there to its end, and the ends (points and values).
/// A descent's path depends on its point and on its iteration's [`iteration_regime`] alone, so
/// a later descent that reaches one of these points bitwise in the same regime would repeat the
/// earlier one's path from there to the same end: it stops and takes that end (issue 40; the
/// d = 72 all-values ur5 study's descents from the design points often join the vertex's).
#[derive(Debug, Clone, Default)]
pub(super) struct DescentTrail {
    points: Vec<f64>,
    /// Per point, its [`point_key`]: a lookup compares the keys first and the points only where
    /// they agree (vertices share most coordinates, so whole points compared long before
    /// differing).
    keys: Vec<u64>,
    /// Per point, the [`iteration_regime`] of the iteration started from it.
    regimes: Vec<usize>,
    /// Per point: (iterations from it to its descent's end, index of that end).
    remaining: Vec<(usize, usize)>,
    end_points: Vec<f64>,
    end_values: Vec<f64>,
    /// The points of the descent under way.
    current: Vec<f64>,
    /// Their keys.
    current_keys: Vec<u64>,
    /// Their iterations' regimes.
    current_regimes: Vec<usize>,
}

/// What of an iteration's number the descent's rules depend on: the number, up to
/// [`SHIFT_FRACTIONS_AT_ANY_SIZE_FROM`], from which on every iteration is alike.
fn iteration_regime(iteration: usize) -> usize {
    iteration.min(SHIFT_FRACTIONS_AT_ANY_SIZE_FROM)
}

/// A hash of a point's bits: equal points have equal keys (so a lookup by key first finds every
/// bitwise-equal point the full comparison would).
fn point_key(x: &[f64]) -> u64 {
    x.iter().fold(0x9e37_79b9_7f4a_7c15_u64, |key, v| {
        (key.rotate_left(23) ^ v.to_bits()).wrapping_mul(0xff51_afd7_ed55_8ccd)
    })
}

impl DescentTrail {
    pub(super) fn clear(&mut self) {
        self.points.clear();
        self.keys.clear();
        self.regimes.clear();
        self.remaining.clear();
        self.end_points.clear();
        self.end_values.clear();
        self.current.clear();
        self.current_keys.clear();
        self.current_regimes.clear();
    }

    /// The earlier point bitwise equal to `x` (key `key`) whose iteration had the regime
    /// `regime` (its remaining iterations and end), if any: the first such, as a scan of the
    /// points in order finds.
    fn find(&self, x: &[f64], key: u64, regime: usize) -> Option<(usize, usize)> {
        let d = x.len();
        self.keys
            .iter()
            .enumerate()
            .filter(|&(i, &k)| k == key && self.regimes[i] == regime)
            .map(|(i, _)| i)
            .find(|&i| {
                self.points[i * d..(i + 1) * d]
                    .iter()
                    .zip(x)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            })
            .map(|i| self.remaining[i])
    }

    /// Starts an iteration of the descent under way from `x` (key `key`) in regime `regime`.
    fn push_current(&mut self, x: &[f64], key: u64, regime: usize) {
        self.current.extend_from_slice(x);
        self.current_keys.push(key);
        self.current_regimes.push(regime);
    }

    /// Forgets the descent under way (stopped by the iteration cap).
    fn drop_current(&mut self) {
        self.current.clear();
        self.current_keys.clear();
        self.current_regimes.clear();
    }

    /// Files the current descent's points: it ended at end index `end` after `total` iterations
    /// in all (the point started at iteration j has `total − j` left).
    fn file_current(&mut self, d: usize, total: usize, end: usize) {
        let n = self.current.len() / d;
        self.points.extend_from_slice(&self.current);
        self.keys.extend_from_slice(&self.current_keys);
        self.regimes.extend_from_slice(&self.current_regimes);
        self.remaining.extend((0..n).map(|j| (total - j, end)));
        self.current.clear();
        self.current_keys.clear();
        self.current_regimes.clear();
    }
}

impl BoxOptimizer {
    /// φ = sign·y and its gradient at `self.x` into grad (sign applied). The Hessian is left for
    /// [`BoxOptimizer::evaluate_hessian`]: a descent that stops at this point (no free
    /// coordinate, or converged) never needs it.
    pub(super) fn evaluate(&mut self, s: &SparseSurrogate, sign: f64) -> f64 {
        let y = s.derivatives_unchecked(&self.x, &mut self.grad, &mut self.ws);
        if sign < 0.0 {
            self.grad.iter_mut().for_each(|g| *g = -*g);
        }
        sign * y
    }

    /// The Hessian of φ = sign·y at `self.x` on the free coordinates into hess (`nf × nf`
    /// row-major, entry `(a, b)` for `free[a]`, `free[b]`; sign applied): nothing else of it is
    /// read.
    pub(super) fn evaluate_hessian(&mut self, s: &SparseSurrogate, sign: f64) {
        // The tables hold `self.x` with derivatives: every Hessian follows the gradient at the
        // same point (`descend` evaluates there and loads nothing else before asking).
        s.free_hessian_at_loaded(&self.free, &mut self.hess, &mut self.ws);
        if sign < 0.0 {
            let nf = self.free.len();
            self.hess[..nf * nf].iter_mut().for_each(|h| *h = -*h);
        }
    }

    /// φ at `self.trial`, which differs from `self.x` (evaluated with derivatives this
    /// iteration) only in the free coordinates: only those are reloaded
    /// ([`SparseSurrogate::value_moved_unchecked`]).
    pub(super) fn phi_at_trial(&mut self, s: &SparseSurrogate, sign: f64) -> f64 {
        sign * s.value_moved_unchecked(&self.trial, &self.free, &mut self.ws)
    }

    /// Projected Newton from `self.x` (overwritten with the best point); returns (φ, iterations).
    pub(super) fn descend(&mut self, s: &SparseSurrogate, sign: f64) -> (f64, usize) {
        let d = self.x.len();
        let mut f = self.evaluate(s, sign);
        let mut iterations = 0;
        self.trail.drop_current();
        loop {
            let key = point_key(&self.x);
            let regime = iteration_regime(iterations + 1);
            if let Some((remaining, end)) = self.trail.find(&self.x, key, regime) {
                // An earlier descent went on from here to `end` within the cap; this one would
                // take the same path (DescentTrail), if the cap leaves it the same iterations.
                if iterations + remaining <= self.max_iterations {
                    self.trail.file_current(d, iterations + remaining, end);
                    self.x
                        .copy_from_slice(&self.trail.end_points[end * d..(end + 1) * d]);
                    return (self.trail.end_values[end], iterations);
                }
            }
            if iterations >= self.max_iterations {
                // Stopped by the cap: not an end another descent may take.
                self.trail.drop_current();
                return (f, iterations);
            }
            self.trail.push_current(&self.x, key, regime);
            iterations += 1;
            self.free.clear();
            for r in 0..d {
                let (x, g) = (self.x[r], self.grad[r]);
                if !((x <= -1.0 && g > 0.0) || (x >= 1.0 && g < 0.0)) {
                    self.free.push(r);
                }
            }
            let nf = self.free.len();
            if nf == 0 {
                break;
            }
            self.evaluate_hessian(s, sign);
            // Stationary to first order (DECREASE_TOL): no Newton or gradient step, only the
            // step along negative curvature is left to try.
            let stationary = self.first_order_gain() <= self.decrease_floor;
            let definite = !stationary && self.newton_direction(s.set().len(), iterations);
            let f_before = f;
            let mut moved = false;
            if stationary {
            } else if let Some(t) = self.line_search(s, sign, f, false, !definite) {
                moved = true;
                f = t;
            } else {
                // Steepest descent on the free coordinates.
                for (a, &r) in self.free.iter().enumerate() {
                    self.step[a] = -self.grad[r];
                }
                if self.free.iter().any(|&r| self.grad[r] != 0.0) {
                    if let Some(t) = self.line_search(s, sign, f, true, true) {
                        moved = true;
                        f = t;
                    }
                }
            }
            if !moved {
                if definite {
                    break;
                }
                match self.negative_curvature_step(s, sign, f) {
                    Some(t) => f = t,
                    None => break,
                }
            }
            // The last step when it was tiny (STEP_TOL) or gained too little to go on
            // (STALLED_DECREASE_TOL): then no gradient there.
            let last = self.trial_distance() <= STEP_TOL || f_before - f <= self.stalled_floor;
            self.x.copy_from_slice(&self.trial);
            if last {
                if s.has_dense_bilinear_part() {
                    // The trial's dense bilinear part was summed from the moved rows: the
                    // point's value as a whole evaluation sums it.
                    f = sign * s.value_unchecked(&self.x, &mut self.ws);
                } else {
                    // Without one the trial's value is that sum already, to the bit
                    // (`value_moved_unchecked`); before (issue 40) it was summed again here.
                    debug_assert_eq!(
                        f.to_bits(),
                        (sign * s.value_unchecked(&self.x, &mut self.ws)).to_bits()
                    );
                }
                break;
            }
            let check = self.evaluate(s, sign);
            debug_assert!((check - f).abs() <= 1e-9 * (1.0 + f.abs()));
            f = check;
        }
        let end = self.trail.end_values.len();
        self.trail.end_points.extend_from_slice(&self.x);
        self.trail.end_values.push(f);
        self.trail.file_current(d, iterations, end);
        (f, iterations)
    }

    /// The largest decrease of φ a step on the free coordinates can promise to first order:
    /// `Σ_r |g_r|` times the room from `x_r` to the face that φ falls towards (a line search's
    /// predicted decrease is at most this, whatever its direction and length).
    pub(super) fn first_order_gain(&self) -> f64 {
        self.free
            .iter()
            .map(|&r| {
                let (x, g) = (self.x[r], self.grad[r]);
                g.abs() * if g > 0.0 { x + 1.0 } else { 1.0 - x }
            })
            .sum()
    }

    pub(super) fn trial_distance(&self) -> f64 {
        self.x
            .iter()
            .zip(&self.trial)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    /// Newton direction on the free coordinates into `step[..nf]`; true if `H_ff` was positive
    /// definite without a shift. `terms`: the terms a surrogate value sums (fewer when terms were
    /// dropped), the measure of what a surrogate value costs (see [`SHIFT_FRACTIONS`]).
    pub(super) fn newton_direction(&mut self, terms: usize, iteration: usize) -> bool {
        let nf = self.free.len();
        let scale = (0..nf)
            .map(|a| self.hess[a * nf + a].abs())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        // A pivot of the factorisation never exceeds its diagonal entry: with a diagonal entry
        // ≤ 0 (or NaN) the unshifted factorisation fails for sure, so it goes straight to the
        // shift (same decision, same bits; the bilinear parts of high-dimensional surrogates
        // leave most of the diagonal at 0).
        let definite = (0..nf).all(|a| self.hess[a * nf + a] > cholesky::ANY_POSITIVE_PIVOT);
        // The shifts tried in turn: none (only when every diagonal entry is positive), then the
        // fractions SHIFT_FRACTIONS of the Gershgorin shift, the last of them the whole shift,
        // which cannot fail.
        // The fractions only where a failed factorisation (up to nf³/6 multiply-adds) costs no
        // more than about four surrogate values (a few operations per term each), or where the
        // descent is a long one (SHIFT_FRACTIONS_AT_ANY_SIZE_FROM).
        let first = if nf * nf * nf <= 24 * terms || iteration >= SHIFT_FRACTIONS_AT_ANY_SIZE_FROM {
            0
        } else {
            SHIFT_FRACTIONS.len() - 1
        };
        let mut gershgorin = 0.0;
        let mut attempt = None;
        if !definite {
            gershgorin = self.gershgorin_shift(scale);
            attempt = Some(first);
        }
        loop {
            let shift = attempt.map_or(0.0, |i| SHIFT_FRACTIONS[i] * gershgorin);
            if self.factor_shifted_free_block(shift) {
                break;
            }
            attempt = match attempt {
                None => {
                    gershgorin = self.gershgorin_shift(scale);
                    Some(first)
                }
                Some(i) if i + 1 < SHIFT_FRACTIONS.len() => Some(i + 1),
                Some(_) => {
                    // The whole Gershgorin shift guarantees definiteness; failing there means
                    // NaN entries.
                    for a in 0..nf {
                        self.step[a] = -self.grad[self.free[a]];
                    }
                    return false;
                }
            };
        }
        for (a, &r) in self.free.iter().enumerate() {
            self.step[a] = -self.grad[r];
        }
        cholesky::solve_in_place(&self.reduced[..nf * nf], nf, &mut self.step[..nf]);
        attempt.is_none()
    }

    /// Factorises `H_ff + shift·I` (the free block of `hess`) into `reduced`; whether it is
    /// positive definite (every pivot positive). The block is copied in one pass (symmetric:
    /// row-major read as column-major), the shift added to its diagonal.
    fn factor_shifted_free_block(&mut self, shift: f64) -> bool {
        let nf = self.free.len();
        for (reduced, &h) in self.reduced[..nf * nf]
            .iter_mut()
            .zip(&self.hess[..nf * nf])
        {
            *reduced = h + 0.0;
        }
        for a in 0..nf {
            self.reduced[a * nf + a] = self.hess[a * nf + a] + shift;
        }
        cholesky::factor_in_place(
            &mut self.reduced[..nf * nf],
            nf,
            cholesky::ANY_POSITIVE_PIVOT,
        )
        .is_ok()
    }

    /// The shift that makes `H_ff` positive definite: λ_min ≥ min_a (H_aa − Σ_{b≠a} |H_ab|)
    /// (Gershgorin), shifted past it by a margin relative to `scale`.
    pub(super) fn gershgorin_shift(&self, scale: f64) -> f64 {
        let nf = self.free.len();
        let block = &self.hess[..nf * nf];
        let mut lowest = f64::INFINITY;
        // Four rows at a time: each row's sum still adds its terms one by one in the order of
        // `free` (the bits of one sum per row), but four independent sums overlap instead of
        // one chain of nf² dependent additions (issue 40); entry (a, b) is read as the equal
        // (b, a), so that the four rows' entries of column b are adjacent.
        let whole = nf - nf % GERSHGORIN_ROWS_AT_ONCE;
        for first in (0..whole).step_by(GERSHGORIN_ROWS_AT_ONCE) {
            let mut off = [0.0_f64; GERSHGORIN_ROWS_AT_ONCE];
            for (b, row_b) in block.chunks_exact(nf).enumerate() {
                let entries = &row_b[first..first + GERSHGORIN_ROWS_AT_ONCE];
                for (i, (sum, entry)) in off.iter_mut().zip(entries).enumerate() {
                    if b != first + i {
                        *sum += entry.abs();
                    }
                }
            }
            for (i, sum) in off.iter().enumerate() {
                let a = first + i;
                lowest = lowest.min(block[a * nf + a] - sum);
            }
        }
        for a in whole..nf {
            let mut off = 0.0_f64;
            for b in 0..nf {
                if b != a {
                    off += block[a * nf + b].abs();
                }
            }
            lowest = lowest.min(block[a * nf + a] - off);
        }
        (-lowest).max(0.0) + CURVATURE_TOL * scale + f64::MIN_POSITIVE
    }

    /// Projected backtracking along `step` (on the free coordinates) from `self.x`; on success
    /// `trial` holds the new point and the new φ is returned. With `expand`, an accepted first
    /// trial is followed by the model's best doubled step ([`BoxOptimizer::expand`]): a shifted
    /// (indefinite) or gradient direction has no natural length, and the projection turns long
    /// steps into moves onto the faces where such extrema lie.
    pub(super) fn line_search(
        &mut self,
        s: &SparseSurrogate,
        sign: f64,
        f: f64,
        gradient: bool,
        expand: bool,
    ) -> Option<f64> {
        // A gradient step starts at the length that reaches the box's size.
        let mut t = if gradient {
            let norm = self
                .free
                .iter()
                .map(|&r| self.grad[r].abs())
                .fold(0.0, f64::max);
            if norm > 0.0 {
                2.0 / norm
            } else {
                return None;
            }
        } else {
            1.0
        };
        for _ in 0..=MAX_HALVINGS {
            self.trial.copy_from_slice(&self.x);
            let mut predicted = 0.0;
            let mut moved = 0.0_f64;
            for (a, &r) in self.free.iter().enumerate() {
                let new = (self.x[r] + t * self.step[a]).clamp(-1.0, 1.0);
                predicted += self.grad[r] * (new - self.x[r]);
                moved = moved.max((new - self.x[r]).abs());
                self.trial[r] = new;
            }
            if moved <= STEP_TOL || predicted >= 0.0 || -predicted <= f64::EPSILON * f.abs() {
                // No move, not a descent direction after projection, or a promised decrease below
                // the rounding of φ: nothing to gain here.
                return None;
            }
            let f_trial = self.phi_at_trial(s, sign);
            if f_trial < f && f_trial <= f + ARMIJO * predicted {
                return Some(if expand {
                    self.expand(s, sign, t, f_trial)
                } else {
                    f_trial
                });
            }
            t *= 0.5;
        }
        None
    }

    /// From an accepted step length `t` (point in `trial`, value `f_accepted`), the longer step
    /// `2^k t` along the projected path that the quadratic model at `x` (value, gradient and
    /// free-block Hessian there; [`BoxOptimizer::start_path_model`]) predicts lowest, found by
    /// doubling the model's step while the model keeps dropping and the projected point still
    /// moves ([`MAX_DOUBLINGS`] at most). φ itself is evaluated only there, then at the halved
    /// counts below it until one is lower than `f_accepted`: the model is exact only for the
    /// terms of total degree ≤ 2, so it may overshoot. Leaves the best point in `trial` and
    /// returns its φ (`f_accepted` when no longer step is lower). Before (issue 40), each
    /// doubling was a surrogate value while φ kept dropping, and the last one, where it rose,
    /// was spent too: 2.9 values per expansion on the d = 32 scaling row, 58 % of the search's
    /// values; with the model 0.6 (docs/high-dimension.md §7a).
    pub(super) fn expand(
        &mut self,
        s: &SparseSurrogate,
        sign: f64,
        t: f64,
        f_accepted: f64,
    ) -> f64 {
        // The accepted point, kept to return to.
        self.spare.copy_from_slice(&self.trial);
        let mut predicted_best = self.start_path_model(t);
        let mut doublings = 0;
        for k in 1..=MAX_DOUBLINGS {
            let longer = t * (1u64 << k) as f64;
            let Some(change) = self.advance_path_model(longer, t * (1u64 << (k - 1)) as f64) else {
                break;
            };
            if change < predicted_best {
                predicted_best = change;
                doublings = k;
            } else {
                break;
            }
        }
        while doublings > 0 {
            let longer = t * (1u64 << doublings) as f64;
            self.project_into_trial(longer);
            let f_trial = self.phi_at_trial(s, sign);
            if f_trial < f_accepted {
                return f_trial;
            }
            doublings -= 1;
        }
        std::mem::swap(&mut self.trial, &mut self.spare);
        f_accepted
    }

    /// The quadratic model's change of φ from `x` to `clamp(x + t·step)`,
    /// `g·Δ + ½ Δ·H_ff Δ` with `Δ` that move of the free coordinates (gradient and Hessian at
    /// `x`), kept up to date for the doublings of `t` that follow
    /// ([`BoxOptimizer::advance_path_model`]): a free coordinate still inside the box moves by
    /// `t·step_a`, one on its face by a fixed `δ_a`, so `H_ff Δ = t·(H_ff step_U) + H_ff δ_C`
    /// with U the coordinates inside and C those on a face. Both products are kept, and a
    /// coordinate that reaches its face moves its column from the first to the second (`nf`
    /// products); a doubling's model then costs `nf` products instead of `nf²` (at d = 64 the
    /// expansions' models were a tenth of the search, nf = 22 on average, issue 40). The sums
    /// differ from the direct ones by rounding only.
    pub(super) fn start_path_model(&mut self, t: f64) -> f64 {
        let nf = self.free.len();
        self.along_inside[..nf].fill(0.0);
        self.along_faces[..nf].fill(0.0);
        for (a, &r) in self.free.iter().enumerate() {
            let x = self.x[r];
            let step = self.step[a];
            let inside = x + t * step;
            let new = inside.clamp(-1.0, 1.0);
            let column = &self.hess[a * nf..(a + 1) * nf];
            if new != inside {
                self.on_face[a] = true;
                let delta = new - x;
                self.moved[a] = delta;
                for (sum, &h) in self.along_faces[..nf].iter_mut().zip(column) {
                    *sum += h * delta;
                }
            } else {
                self.on_face[a] = false;
                if step != 0.0 {
                    for (sum, &h) in self.along_inside[..nf].iter_mut().zip(column) {
                        *sum += h * step;
                    }
                }
            }
        }
        self.path_model(t)
    }

    /// The path model ([`BoxOptimizer::start_path_model`]) at `t`, twice the length it was at
    /// (`shorter`): the coordinates that reach their face on the way move to the face part.
    /// `None` when the projected point is the same as at `shorter` (every coordinate that
    /// moves already on its face).
    pub(super) fn advance_path_model(&mut self, t: f64, shorter: f64) -> Option<f64> {
        let nf = self.free.len();
        let mut changed = false;
        for (a, &r) in self.free.iter().enumerate() {
            if self.on_face[a] {
                continue;
            }
            let x = self.x[r];
            let step = self.step[a];
            let inside = x + t * step;
            let new = inside.clamp(-1.0, 1.0);
            changed |= new != x + shorter * step;
            if new != inside {
                self.on_face[a] = true;
                let delta = new - x;
                self.moved[a] = delta;
                let column = &self.hess[a * nf..(a + 1) * nf];
                for ((inside_sum, face_sum), &h) in self.along_inside[..nf]
                    .iter_mut()
                    .zip(&mut self.along_faces[..nf])
                    .zip(column)
                {
                    *inside_sum -= h * step;
                    *face_sum += h * delta;
                }
            }
        }
        changed.then(|| self.path_model(t))
    }

    /// `g·Δ + ½ Δ·(t·along_inside + along_faces)` with `Δ_a = t·step_a` inside the box and the
    /// face offset `moved[a]` on a face.
    fn path_model(&self, t: f64) -> f64 {
        let mut linear = 0.0;
        let mut curvature = 0.0;
        for (a, &r) in self.free.iter().enumerate() {
            let delta = if self.on_face[a] {
                self.moved[a]
            } else {
                t * self.step[a]
            };
            linear += self.grad[r] * delta;
            curvature += delta * (t * self.along_inside[a] + self.along_faces[a]);
        }
        linear + 0.5 * curvature
    }

    /// `trial` = `clamp(x + t·step)` on the free coordinates, `x` elsewhere.
    pub(super) fn project_into_trial(&mut self, t: f64) {
        self.trial.copy_from_slice(&self.x);
        for (a, &r) in self.free.iter().enumerate() {
            self.trial[r] = (self.x[r] + t * self.step[a]).clamp(-1.0, 1.0);
        }
    }

    /// The quadratic model's change of φ from `x` to `clamp(x + t·step)`:
    /// `g·Δ + ½ Δ·H_ff Δ` with `Δ` the move of the free coordinates (gradient and Hessian at `x`),
    /// summed directly: the reference the path model ([`BoxOptimizer::start_path_model`]) is
    /// tested against.
    #[cfg(test)]
    pub(super) fn model_change_at(&self, t: f64) -> f64 {
        let nf = self.free.len();
        let moved: Vec<f64> = self
            .free
            .iter()
            .enumerate()
            .map(|(a, &r)| (self.x[r] + t * self.step[a]).clamp(-1.0, 1.0) - self.x[r])
            .collect();
        let mut linear = 0.0;
        let mut curvature = 0.0;
        for ((&r, &delta), row) in self
            .free
            .iter()
            .zip(&moved)
            .zip(self.hess[..nf * nf].chunks_exact(nf))
        {
            linear += self.grad[r] * delta;
            let row_times_move: f64 = row.iter().zip(&moved).map(|(h, m)| h * m).sum();
            curvature += delta * row_times_move;
        }
        linear + 0.5 * curvature
    }

    /// At a point with no descent direction from first-order information and an indefinite
    /// `H_ff`: move along the eigenvector of the most negative eigenvalue, as far as the box allows,
    /// backtracking until φ drops.
    pub(super) fn negative_curvature_step(
        &mut self,
        s: &SparseSurrogate,
        sign: f64,
        f: f64,
    ) -> Option<f64> {
        let nf = self.free.len();
        let scale = self.hess[..nf * nf]
            .iter()
            .fold(0.0_f64, |largest, h| largest.max(h.abs()))
            .max(f64::MIN_POSITIVE);
        let tolerance = CURVATURE_TOL * scale;
        // `H_ff + τI` factorises exactly when its smallest eigenvalue is above −τ: then there is
        // no negative curvature to follow, and the eigen-decomposition (tridiagonalisation and
        // QR sweeps with the eigenvectors, many times the factorisation's work) is not needed.
        // Descents end at such points (a local minimum on its face), so most calls stop here:
        // at d = 136 (the Upkie starter) the eigen-decompositions were a fifth of a one-thread
        // study (`perf`).
        if self.factor_shifted_free_block(tolerance) {
            return None;
        }
        let h = DMatrix::from_fn(nf, nf, |a, b| self.hess[a * nf + b]);
        let eigen = h.symmetric_eigen();
        let (i, &lambda) = eigen
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        if lambda >= -tolerance {
            return None;
        }
        let u = eigen.eigenvectors.column(i);
        // Descent along the sign with gᵀu ≤ 0 (both signs when the gradient is orthogonal).
        let slope: f64 = self
            .free
            .iter()
            .enumerate()
            .map(|(a, &r)| self.grad[r] * u[a])
            .sum();
        let signs: &[f64] = if slope < 0.0 {
            &[1.0]
        } else if slope > 0.0 {
            &[-1.0]
        } else {
            &[1.0, -1.0]
        };
        let mut best: Option<(f64, f64)> = None;
        for &dir in signs {
            let mut t = 2.0;
            for _ in 0..=MAX_HALVINGS {
                self.trial.copy_from_slice(&self.x);
                for (a, &r) in self.free.iter().enumerate() {
                    self.trial[r] = (self.x[r] + t * dir * u[a]).clamp(-1.0, 1.0);
                }
                let f_trial = self.phi_at_trial(s, sign);
                if f_trial < f && f - f_trial > f64::EPSILON * f.abs() {
                    if best.is_none_or(|(bf, _)| f_trial < bf) {
                        best = Some((f_trial, dir * t));
                    }
                    break;
                }
                t *= 0.5;
            }
        }
        let (f_best, step) = best?;
        self.trial.copy_from_slice(&self.x);
        for (a, &r) in self.free.iter().enumerate() {
            self.trial[r] = (self.x[r] + step * u[a]).clamp(-1.0, 1.0);
        }
        Some(f_best)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trail point is taken only by a descent at an iteration of its regime: the shift rule
    /// depends on the iteration ([`SHIFT_FRACTIONS_AT_ANY_SIZE_FROM`]), so the same point at
    /// another iteration need not lead to the same end.
    #[test]
    fn a_trail_point_is_found_only_in_its_iterations_regime() {
        let mut trail = DescentTrail::default();
        let (first, second) = ([0.5, -1.0, 0.25], [1.0, -1.0, 0.0]);
        let (k1, k2) = (point_key(&first), point_key(&second));
        // A descent started iterations 1 and 2 from these points and ended at end 0.
        trail.push_current(&first, k1, iteration_regime(1));
        trail.push_current(&second, k2, iteration_regime(2));
        trail.end_points.extend_from_slice(&[1.0, -1.0, -1.0]);
        trail.end_values.push(-2.0);
        trail.file_current(3, 2, 0);
        assert_eq!(trail.find(&first, k1, iteration_regime(1)), Some((2, 0)));
        assert_eq!(trail.find(&second, k2, iteration_regime(2)), Some((1, 0)));
        assert_eq!(trail.find(&first, k1, iteration_regime(2)), None);
        assert_eq!(trail.find(&second, k2, iteration_regime(5)), None);
        // From the threshold on every iteration is alike.
        assert_eq!(
            iteration_regime(SHIFT_FRACTIONS_AT_ANY_SIZE_FROM),
            iteration_regime(SHIFT_FRACTIONS_AT_ANY_SIZE_FROM + 7)
        );
        assert_ne!(
            iteration_regime(SHIFT_FRACTIONS_AT_ANY_SIZE_FROM - 1),
            iteration_regime(SHIFT_FRACTIONS_AT_ANY_SIZE_FROM)
        );
    }

    /// A large indefinite free block (where a failed factorisation is dear) is shifted by the
    /// whole Gershgorin shift at a descent's first iteration and by a fraction of it from
    /// [`SHIFT_FRACTIONS_AT_ANY_SIZE_FROM`] on when one suffices: the step is then longer, and
    /// still a descent direction.
    #[test]
    fn late_iterations_try_the_shift_fractions_at_any_size() {
        use crate::test_support::SplitMix64;
        let nf = 40;
        let mut optimizer = BoxOptimizer::new();
        optimizer.resize(nf);
        optimizer.free = (0..nf).collect();
        let mut rng = SplitMix64::new(40);
        let noise: Vec<f64> = (0..nf * nf).map(|_| rng.uniform(-0.1, 0.1)).collect();
        // (a) Tridiagonal with a zero diagonal: the Gershgorin shift 2 is about the smallest
        // eigenvalue's magnitude (2 cos(π / 41)), so no fraction of it factorises. (b) A diagonal
        // of 0.4 and small entries of random sign everywhere else: the Gershgorin shift (about
        // 1.6) is far larger than the smallest eigenvalue's magnitude (about 0.3).
        for tridiagonal in [true, false] {
            for a in 0..nf {
                for b in 0..nf {
                    let (lo, hi) = (a.min(b), a.max(b));
                    optimizer.hess[a * nf + b] = match (tridiagonal, hi - lo) {
                        (true, 1) => -1.0,
                        (true, _) => 0.0,
                        (false, 0) => 0.4,
                        (false, _) => noise[lo * nf + hi],
                    };
                }
                optimizer.grad[a] = if a % 3 == 0 { 1.0 } else { -0.5 };
            }
            // Few terms: nf³ far above 24 per term, so no fractions by size.
            let terms = 10;
            let mut steps = Vec::new();
            for iteration in [1, SHIFT_FRACTIONS_AT_ANY_SIZE_FROM] {
                assert!(!optimizer.newton_direction(terms, iteration), "indefinite");
                let step = optimizer.step[..nf].to_vec();
                let slope: f64 = step.iter().zip(&optimizer.grad).map(|(s, g)| s * g).sum();
                assert!(slope < 0.0, "a descent direction at iteration {iteration}");
                steps.push(step.iter().map(|s| s * s).sum::<f64>().sqrt());
            }
            if tridiagonal {
                // Only the whole shift factorises: the same step either way.
                assert_eq!(steps[0], steps[1]);
            } else {
                // A fraction of the shift factorises: a longer step than the whole one's.
                assert!(steps[1] > 1.5 * steps[0], "{steps:?}");
            }
        }
    }
}
