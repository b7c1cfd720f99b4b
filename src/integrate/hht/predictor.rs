//! The predictor of a step: the accepted `q̈` and `λ` before the current ones, and their
//! extrapolation to the end of the next step (docs/step-control.md §2).
//!
//! On a run of equal steps every coordinate of `q̈` (and every row of `λ`) is extrapolated by the
//! polynomials of orders 0 to [`PREDICTOR_MAX_ORDER`], each weighted by how well it predicted the
//! entry's last accepted value: smooth motion takes the high orders, a value that flips sign from
//! step to step (a mode the step does not resolve) the constant one. Across a change of step size,
//! and with [`HhtSettings::choose_predictor_order`](super::super::HhtSettings::choose_predictor_order)
//! off, `q̈` is extrapolated linearly in the step ratio, plus a quadratic term where the steps are
//! within [`PREDICTOR_CURVATURE_MAX_STEP_RATIO`] of each other and the history is smooth, and `λ`
//! linearly.

use nalgebra::DVector;

use super::step_size::StepControlState;

/// Highest order of the extrapolation on a run of equal steps: the predictor keeps the backward
/// differences of `q̈` and `λ` up to this order (docs/step-control.md §2, where the Newton
/// iterations it saves are measured).
pub const PREDICTOR_MAX_ORDER: usize = 4;

/// The predictor uses its quadratic term across a change of step size only when the next step and
/// the last two accepted ones are within this factor of each other: the curvature is a difference
/// of differences divided by the steps, and across a sharp change of step size (a step shortened to
/// an impact, a halving) it would amplify the history's rounding noise rather than extrapolate the
/// motion.
pub const PREDICTOR_CURVATURE_MAX_STEP_RATIO: f64 = 2.0;

/// The history of one vector (`q̈` or `λ`) on the run of equal steps ending at `t_n`: its backward
/// differences `∇¹ … ∇⁴` there, and the extrapolation to `t_{n+1}` made when the current value
/// was accepted.
///
/// The order-`o` extrapolation one equal step ahead is `x_n + ∇¹x_n + … + ∇ᵒx_n` (Newton's
/// backward form of the polynomial through the last `o + 1` values), and the new value's
/// difference `∇^{o+1}x_{n+1}` is exactly what that extrapolation missed by. So taking in a value
/// both updates the differences and says, per entry, how well each order predicted it. The next
/// extrapolation blends the orders with weights `max(0, 2 − miss_o / smallest miss)`: the best
/// order weighs 1, one that missed by twice as much or more nothing, and unlike picking the best
/// order the blend is continuous in the history, so neighbouring samples of a study (or the points
/// of a difference quotient) do not start Newton from predictions that jump where two orders tie.
#[derive(Debug, Clone)]
struct DifferenceTable {
    /// `differences[k]`: `∇^{k+1}` of every entry at `t_n` (valid up to the run's length).
    differences: [DVector<f64>; PREDICTOR_MAX_ORDER],
    /// Every entry extrapolated to `t_{n+1}` by the blend of orders (valid when the run has two
    /// values or more).
    next: DVector<f64>,
}

impl DifferenceTable {
    fn new(n: usize) -> Self {
        Self {
            differences: std::array::from_fn(|_| DVector::zeros(n)),
            next: DVector::zeros(n),
        }
    }

    /// Takes in `new` (accepted one step after `current`): the differences at the new value, and,
    /// when `highest ≥ 1`, every entry's extrapolation to the step after it by the orders 0 to
    /// `highest`, blended by how well each predicted `new` from the old differences. Entries of the
    /// differences beyond the run's length are left meaningless but finite; they are never read.
    fn push(&mut self, current: &[f64], new: &[f64], highest: usize) {
        // One loop per highest order, so that the loop over the orders unrolls.
        match highest {
            0 => self.push_testing::<0>(current, new),
            1 => self.push_testing::<1>(current, new),
            2 => self.push_testing::<2>(current, new),
            3 => self.push_testing::<3>(current, new),
            _ => self.push_testing::<PREDICTOR_MAX_ORDER>(current, new),
        }
    }

    /// [`Self::push`] blending the orders 0 to `HIGHEST`, [`BLEND_LANES`] entries at a time
    /// ([`blend`]: each entry's operations are those of one at a time, in vector instructions).
    fn push_testing<const HIGHEST: usize>(&mut self, current: &[f64], new: &[f64]) {
        let n = new.len();
        let [d1, d2, d3, d4] = &mut self.differences;
        let differences = [
            &mut d1.as_mut_slice()[..n],
            &mut d2.as_mut_slice()[..n],
            &mut d3.as_mut_slice()[..n],
            &mut d4.as_mut_slice()[..n],
        ];
        let (current, next) = (&current[..n], &mut self.next.as_mut_slice()[..n]);
        let full = n - n % BLEND_LANES;
        for start in (0..full).step_by(BLEND_LANES) {
            let entries = start..start + BLEND_LANES;
            let lanes = |x: &[f64]| -> [f64; BLEND_LANES] {
                x[entries.clone()].try_into().expect("BLEND_LANES entries")
            };
            let old = [
                lanes(differences[0]),
                lanes(differences[1]),
                lanes(differences[2]),
                lanes(differences[3]),
            ];
            let (best, rises) = blend::<BLEND_LANES, HIGHEST>(lanes(new), lanes(current), old);
            next[entries.clone()].copy_from_slice(&best);
            for k in 0..PREDICTOR_MAX_ORDER {
                differences[k][entries.clone()].copy_from_slice(&rises[k]);
            }
        }
        for i in full..n {
            let old = [
                [differences[0][i]],
                [differences[1][i]],
                [differences[2][i]],
                [differences[3][i]],
            ];
            let (best, rises) = blend::<1, HIGHEST>([new[i]], [current[i]], old);
            next[i] = best[0];
            for k in 0..PREDICTOR_MAX_ORDER {
                differences[k][i] = rises[k][0];
            }
        }
    }

    /// Moves the table towards `reference`'s, `x ← r + scale (x − r)` (linear: the differences of
    /// the pulled values).
    fn pull_towards(&mut self, reference: &Self, scale: f64) {
        for (own, base) in self
            .differences
            .iter_mut()
            .zip(&reference.differences)
            .chain(std::iter::once((&mut self.next, &reference.next)))
        {
            pull(own, base, scale);
        }
    }
}

/// What the predictor keeps of a trajectory's accepted steps: the backward differences of `q̈` and
/// `λ` on the run of equal steps ending at the current state (with the blended extrapolation of
/// each entry), and the last two values of `q̈` and the last of `λ` for a step of
/// another size. Part of [`HhtTrajectory`](super::HhtTrajectory): a sample's predictions depend on
/// its own history only.
#[derive(Debug, Clone)]
pub struct PredictorHistory {
    /// `q̈` on the run of equal steps.
    qdd_run: DifferenceTable,
    /// `λ` on the run of equal steps.
    lambda_run: DifferenceTable,
    /// `q̈_{n−1}` and `q̈_{n−2}` (the first `held` valid), for a step of another size.
    qdd_previous: [DVector<f64>; 2],
    /// `λ_{n−1}` (valid when `held ≥ 1`), for a step of another size.
    lambda_previous: DVector<f64>,
    /// How many of `qdd_previous` are valid (0 after a start, a restart or an impact; at most 2).
    held: usize,
    /// How many of them continue the last step's size back from `t_n` (the run's length).
    equal_run: usize,
    /// The runs' extrapolations were made (blending orders 0 and 1 at least) for a next step of the
    /// run's size.
    run_chosen: bool,
}

impl PredictorHistory {
    /// An empty history for `nv` coordinates and `m` multipliers.
    pub(super) fn new(nv: usize, m: usize) -> Self {
        Self {
            qdd_run: DifferenceTable::new(nv),
            lambda_run: DifferenceTable::new(m),
            qdd_previous: [DVector::zeros(nv), DVector::zeros(nv)],
            lambda_previous: DVector::zeros(m),
            held: 0,
            equal_run: 0,
            run_chosen: false,
        }
    }

    /// How many accepted values of `q̈` before the current one the predictor holds for a step of
    /// another size (0, 1 or 2; the run of equal steps is counted apart).
    pub fn held(&self) -> usize {
        self.held
    }

    /// Forgets the history (a start, a restart, an impact): the next step starts from the current
    /// `q̈` and `λ`.
    pub(super) fn clear(&mut self) {
        self.held = 0;
        self.equal_run = 0;
        self.run_chosen = false;
    }

    /// Moves every held vector towards `reference`'s, `x ← r + scale (x − r)`
    /// ([`HhtTrajectory::pull_towards`](super::HhtTrajectory::pull_towards)).
    pub(super) fn pull_towards(&mut self, reference: &Self, scale: f64) {
        self.qdd_run.pull_towards(&reference.qdd_run, scale);
        self.lambda_run.pull_towards(&reference.lambda_run, scale);
        for (own, base) in self
            .qdd_previous
            .iter_mut()
            .zip(&reference.qdd_previous)
            .chain(std::iter::once((
                &mut self.lambda_previous,
                &reference.lambda_previous,
            )))
        {
            pull(own, base, scale);
        }
    }

    /// The predicted `q̈_{n+1}` and `λ_{n+1}` of a step of `h` into `qdd_out`, `lambda_out`, from the
    /// current `q̈`, `λ` (`current`) and the history (`control`: the last two accepted step sizes);
    /// `by_order`: [`HhtSettings::choose_predictor_order`](super::super::HhtSettings::choose_predictor_order).
    pub(super) fn predict(
        &self,
        h: f64,
        by_order: bool,
        control: &StepControlState,
        current: (&[f64], &[f64]),
        qdd_out: &mut [f64],
        lambda_out: &mut [f64],
    ) {
        let (qdd, lambda) = current;
        if self.held == 0 {
            qdd_out.copy_from_slice(qdd);
            lambda_out.copy_from_slice(lambda);
            return;
        }
        if by_order && self.run_chosen && h == control.h_last {
            qdd_out.copy_from_slice(self.qdd_run.next.as_slice());
            if !lambda_out.is_empty() {
                lambda_out.copy_from_slice(self.lambda_run.next.as_slice());
            }
            return;
        }
        let ratio = h / control.h_last;
        let curvature = (self.held >= 2)
            .then(|| CurvatureWeights::new(h, control))
            .flatten();
        predict_accelerations(
            qdd_out,
            [
                qdd,
                self.qdd_previous[0].as_slice(),
                self.qdd_previous[1].as_slice(),
            ],
            ratio,
            curvature,
        );
        extrapolate_linearly(lambda_out, lambda, self.lambda_previous.as_slice(), ratio);
    }

    /// Takes in an accepted step of `h` (the one before it was `h_last`) from the current `qdd`,
    /// `lambda` to `new = (q̈_{n+1}, λ_{n+1})` (`by_order`: keep the difference tables, as
    /// [`Self::predict`]). `qdd` and `lambda` are swapped with the history's oldest buffers: the
    /// caller overwrites them with the new state.
    pub(super) fn push(
        &mut self,
        h: f64,
        h_last: f64,
        by_order: bool,
        qdd: &mut DVector<f64>,
        lambda: &mut DVector<f64>,
        new: (&[f64], &[f64]),
    ) {
        let continues_run = h == h_last;
        // The orders a run of `equal_run` steps can test: order o reads o + 1 values.
        let highest = if continues_run { self.equal_run } else { 0 };
        if by_order {
            self.qdd_run.push(qdd.as_slice(), new.0, highest);
            if !new.1.is_empty() {
                self.lambda_run.push(lambda.as_slice(), new.1, highest);
            }
        }
        self.run_chosen = by_order && highest >= 1;
        self.qdd_previous.swap(0, 1);
        std::mem::swap(&mut self.qdd_previous[0], qdd);
        std::mem::swap(&mut self.lambda_previous, lambda);
        self.held = (self.held + 1).min(self.qdd_previous.len());
        self.equal_run = if continues_run {
            (self.equal_run + 1).min(PREDICTOR_MAX_ORDER)
        } else {
            1
        };
    }
}

/// How many entries [`DifferenceTable::push`] blends together: two `f64` fill a vector register of
/// the x86-64 baseline (SSE2).
const BLEND_LANES: usize = 2;

/// `W` entries of [`DifferenceTable::push`]: from their new values `x`, their current values and
/// their old differences `∇¹ … ∇⁴` (`old[k]`: `∇^{k+1}`), the blend of the orders 0 to `HIGHEST`
/// extrapolated from `x`, and the new differences. Written lane by lane over arrays so that the
/// compiler emits vector instructions; each lane's operations are those of one entry.
#[inline(always)]
fn blend<const W: usize, const HIGHEST: usize>(
    x: [f64; W],
    current: [f64; W],
    old: [[f64; W]; PREDICTOR_MAX_ORDER],
) -> ([f64; W], [[f64; W]; PREDICTOR_MAX_ORDER]) {
    // n[k] = ∇^{k+1} x_{n+1}: x_{n+1} minus the order-k extrapolation from t_n.
    let mut n = [[0.0; W]; PREDICTOR_MAX_ORDER + 1];
    for l in 0..W {
        n[0][l] = x[l] - current[l];
    }
    for k in 1..=PREDICTOR_MAX_ORDER {
        for l in 0..W {
            n[k][l] = n[k - 1][l] - old[k - 1][l];
        }
    }
    // The order-o extrapolation from x_{n+1} is x + rises[o] (x + n1 + … + n_o); order o missed
    // x_{n+1} by |n_{o+1}|. Each order weighs max(0, 2 − miss/smallest miss): the best one 1, one
    // that missed by twice as much or more nothing, so that the best order dominates and the
    // prediction stays continuous in the history.
    let mut rises = [[0.0; W]; PREDICTOR_MAX_ORDER + 1];
    rises[1] = n[0];
    for o in 2..=PREDICTOR_MAX_ORDER {
        for l in 0..W {
            rises[o][l] = rises[o - 1][l] + n[o - 1][l];
        }
    }
    let mut misses = [[0.0; W]; PREDICTOR_MAX_ORDER + 1];
    for o in 0..=PREDICTOR_MAX_ORDER {
        for l in 0..W {
            misses[o][l] = n[o][l].abs();
        }
    }
    let mut smallest = misses[0];
    for miss in &misses[1..=HIGHEST] {
        for l in 0..W {
            smallest[l] = if miss[l] < smallest[l] {
                miss[l]
            } else {
                smallest[l]
            };
        }
    }
    // An order that was exact (smallest miss 0) weighs 2 and every other one nothing: the floor
    // keeps the inverse finite, no branch.
    let mut inverse = [0.0; W];
    for l in 0..W {
        let floored = if smallest[l] > f64::MIN_POSITIVE {
            smallest[l]
        } else {
            f64::MIN_POSITIVE
        };
        inverse[l] = 1.0 / floored;
    }
    let (mut weight_sum, mut rise) = ([0.0; W], [0.0; W]);
    for o in 0..=HIGHEST {
        for l in 0..W {
            // max(0, ·) by comparison (never −0: 2 − y rounds to +0), without `max`'s NaN code.
            let w = 2.0 - misses[o][l] * inverse[l];
            let w = if w > 0.0 { w } else { 0.0 };
            weight_sum[l] += w;
            rise[l] += w * rises[o][l];
        }
    }
    let mut best = [0.0; W];
    for l in 0..W {
        best[l] = x[l] + rise[l] / weight_sum[l];
    }
    (best, [n[0], n[1], n[2], n[3]])
}

/// The quadratic term of the predictor for a step of `h` after accepted steps `h_last` (from
/// `t_{n−1}` to `t_n`) and `h_before_last`: with `Δ₁ = q̈_n − q̈_{n−1}`, `Δ₀ = q̈_{n−1} − q̈_{n−2}`,
/// the term `h (h + h_last)/(h_last + h_before_last) · (Δ₁/h_last − Δ₀/h_before_last)` that
/// Newton's divided differences add to the linear extrapolation (`Δ₁ − Δ₀` when all three steps
/// are equal, giving `3q̈_n − 3q̈_{n−1} + q̈_{n−2}`).
#[derive(Debug, Clone, Copy)]
enum CurvatureWeights {
    /// All three steps equal: the term is `Δ₁ − Δ₀`.
    Equal,
    /// The term is `scale · (Δ₁/h_last − Δ₀/h_before_last)`.
    Variable {
        scale: f64,
        h_last: f64,
        h_before_last: f64,
    },
}

impl CurvatureWeights {
    /// The weights for a step of `h`, or `None` when the steps differ by more than
    /// [`PREDICTOR_CURVATURE_MAX_STEP_RATIO`].
    fn new(h: f64, control: &StepControlState) -> Option<Self> {
        let (h_last, h_before_last) = (control.h_last, control.h_before_last);
        if h == h_last && h_last == h_before_last {
            return Some(Self::Equal);
        }
        let largest = h.max(h_last).max(h_before_last);
        let smallest = h.min(h_last).min(h_before_last);
        (largest <= PREDICTOR_CURVATURE_MAX_STEP_RATIO * smallest).then(|| Self::Variable {
            scale: h * (h + h_last) / (h_last + h_before_last),
            h_last,
            h_before_last,
        })
    }
}

/// The predicted `q̈_{n+1}` of every coordinate into `out` from `[q̈_n, q̈_{n−1}, q̈_{n−2}]`
/// (`history`; the last is read only with `curvature`): the linear extrapolation with the step
/// ratio `ratio = h/h_last`, plus the quadratic term where the coordinate's history is smooth — a
/// history that bends more than it rises in either of its last two steps is not (a mode the step
/// does not resolve flips q̈'s sign from step to step, and the quadratic term would throw the
/// prediction 7× the swing away), and keeps the linear prediction.
fn predict_accelerations(
    out: &mut [f64],
    history: [&[f64]; 3],
    ratio: f64,
    curvature: Option<CurvatureWeights>,
) {
    let [now, before, before_that] = history;
    let Some(curvature) = curvature else {
        return extrapolate_linearly(out, now, before, ratio);
    };
    let entries = out.iter_mut().zip(now).zip(before).zip(before_that);
    match curvature {
        CurvatureWeights::Equal => {
            for (((x, now), before), before_that) in entries {
                let rise = now - before;
                let rise_before = before - before_that;
                let bend = rise - rise_before;
                let linear = 2.0 * now - before;
                let smooth = bend.abs() <= rise.abs().max(rise_before.abs());
                *x = if smooth { linear + bend } else { linear };
            }
        }
        CurvatureWeights::Variable {
            scale,
            h_last,
            h_before_last,
        } => {
            for (((x, now), before), before_that) in entries {
                let rise = now - before;
                let (linear, increment) = if ratio == 1.0 {
                    (2.0 * now - before, rise)
                } else {
                    let increment = ratio * rise;
                    (now + increment, increment)
                };
                let rise_before = before - before_that;
                let bend = scale * (rise / h_last - rise_before / h_before_last);
                let smooth = bend.abs() <= increment.abs().max(rise_before.abs());
                *x = if smooth { linear + bend } else { linear };
            }
        }
    }
}

/// The linear extrapolation `now + ratio · (now − before)` of every entry into `out`
/// (`2 now − before` for equal steps): the predictor's `λ` across a change of step size, and its
/// `q̈` without a curvature term.
fn extrapolate_linearly(out: &mut [f64], now: &[f64], before: &[f64], ratio: f64) {
    let entries = out.iter_mut().zip(now).zip(before);
    if ratio == 1.0 {
        for ((x, now), before) in entries {
            *x = 2.0 * now - before;
        }
    } else {
        for ((x, now), before) in entries {
            *x = now + ratio * (now - before);
        }
    }
}

/// `x ← r + scale (x − r)` entry by entry ([`HhtTrajectory::pull_towards`]).
pub(super) fn pull(x: &mut DVector<f64>, reference: &DVector<f64>, scale: f64) {
    for (x, r) in x.iter_mut().zip(reference.iter()) {
        *x = r + scale * (*x - r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A history of a scalar `q̈` (no multiplier) that took in `values` one step of `h` apart; returns
    /// it with the current value.
    fn history_of(values: &[f64], h: f64) -> (PredictorHistory, DVector<f64>) {
        let mut history = PredictorHistory::new(1, 0);
        let mut current = DVector::from_element(1, values[0]);
        let mut lambda = DVector::zeros(0);
        for &next in &values[1..] {
            history.push(h, h, true, &mut current, &mut lambda, (&[next], &[]));
            current = DVector::from_element(1, next);
        }
        (history, current)
    }

    fn predicted(history: &PredictorHistory, current: &DVector<f64>, h: f64) -> f64 {
        let mut out = [0.0];
        let control = StepControlState::new(h);
        history.predict(
            h,
            true,
            &control,
            (current.as_slice(), &[]),
            &mut out,
            &mut [],
        );
        out[0]
    }

    #[test]
    fn a_polynomial_history_is_extrapolated_exactly_by_its_degree() {
        // Degree d needs d + 1 values behind the current one to be tested (an order is weighted by
        // how well it predicted the current value); the orders ≥ d are then exact and the others
        // weigh nothing, up to degree 4.
        for degree in 0..=PREDICTOR_MAX_ORDER as i32 {
            let p = |k: f64| 0.5 * k.powi(degree) - 2.0 * k.powi((degree - 1).max(0)) + 3.0;
            let values: Vec<f64> = (0..=degree + 1).map(|k| p(f64::from(k))).collect();
            let (history, current) = history_of(&values, 1e-3);
            let next = p(f64::from(degree + 2));
            let miss = (predicted(&history, &current, 1e-3) - next).abs();
            assert!(
                miss <= 1e-14 * next.abs(),
                "degree {degree}: missed by {miss:e}"
            );
        }
    }

    #[test]
    fn a_smooth_history_beyond_the_highest_order_is_extrapolated_by_it() {
        // A sine sampled 0.05 rad apart: order 4 misses by its fifth difference, at most 0.05⁵,
        // about 0.05² of what the quadratic extrapolation misses by; the blend stays within twice
        // that.
        let f = |k: f64| (0.05 * k).sin();
        let values: Vec<f64> = (0..10).map(|k| f(f64::from(k))).collect();
        let (history, current) = history_of(&values, 1e-3);
        let miss = (predicted(&history, &current, 1e-3) - f(10.0)).abs();
        let quadratic = 3.0 * f(9.0) - 3.0 * f(8.0) + f(7.0);
        assert!(miss <= 2.0 * 0.05f64.powi(5), "miss {miss:e}");
        assert!(miss < 0.01 * (quadratic - f(10.0)).abs(), "miss {miss:e}");
    }

    #[test]
    fn a_sign_flipping_history_is_predicted_mostly_by_the_constant() {
        // An unresolved mode: ±1 around a slow drift. Order 0 misses by about 2, every higher order
        // by more (order 1 by about 4, order 4 by about 32): only order 0 is within twice the
        // best miss, so the blend is the constant, where the quadratic extrapolation would miss by
        // about 8.
        let values: Vec<f64> = (0..8)
            .map(|k| 1e-3 * f64::from(k) + if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let (history, current) = history_of(&values, 1e-3);
        let next = 1e-3 * 8.0 + 1.0;
        let miss = (predicted(&history, &current, 1e-3) - next).abs();
        assert!((2.0..3.0).contains(&miss), "missed by {miss}");
    }

    #[test]
    fn a_step_of_another_size_falls_back_to_the_ratio_and_starts_a_new_run() {
        let line = |t: f64| 2.0 + 3.0 * t;
        let h = 1e-3;
        // One value behind: no order chosen yet, the linear extrapolation.
        let (mut history, mut current) = history_of(&[line(0.0), line(h)], h);
        assert!(!history.run_chosen);
        assert!((predicted(&history, &current, h) - line(2.0 * h)).abs() < 1e-15);
        // A half step: the linear extrapolation in the step ratio, exact for a line.
        let control = StepControlState::new(h);
        let mut out = [0.0];
        history.predict(
            h / 2.0,
            true,
            &control,
            (current.as_slice(), &[]),
            &mut out,
            &mut [],
        );
        assert!((out[0] - line(1.5 * h)).abs() < 1e-15);
        let mut lambda = DVector::zeros(0);
        history.push(
            h / 2.0,
            h,
            true,
            &mut current,
            &mut lambda,
            (&[line(1.5 * h)], &[]),
        );
        assert!(!history.run_chosen);
        assert_eq!((history.held(), history.equal_run), (2, 1));
        history.clear();
        assert_eq!(history.held(), 0);
    }
}
