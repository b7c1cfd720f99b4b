//! Unilateral limits (docs/step-control.md §4): the earliest crossing inside a converged step
//! (the root of the gaps' cubic Hermite interpolant), the constants that decide when a crossing is
//! located, and the impact law applied at the located step's end followed by a consistent restart.

use super::HhtIntegrator;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::start::{consistent_start, ConsistentStart};
use crate::integrate::system::DaeSystem;

/// Where an impact may sit in a step: a crossing located at `θ` of the step is accepted as located
/// when the rest of the step, `(1 − θ) h`, is below this fraction of the grid step (1e-6: at
/// 500 rad/s and h = 1 ms, 5e-7 rad past the limit before the impact law puts the joint back on it).
pub const IMPACT_LOCATE_FRACTION: f64 = 1e-6;

/// A located step is aimed this fraction of the grid step beyond the predicted crossing, so that it
/// ends just past the limit rather than just before it (which would need one more tiny step).
pub(super) const IMPACT_OVERSHOOT_FRACTION: f64 = 1e-7;

/// Most attempts to locate one impact inside a grid interval before the crossing is accepted where
/// the last attempt put it (each attempt re-fits the crossing on a shorter, converged step).
pub(super) const IMPACT_LOCATE_ATTEMPTS: usize = 6;

/// Slowest approach, rad/s or m/s, that counts as an impact: slower crossings (a joint settling onto
/// its limit under gravity after a plastic impact) are left to the limit's penalty spring-damper,
/// whose penetration at this speed is `v · sqrt(m/k)` (≈ 6e-4 rad for a 1 kg, 1 m bar at the
/// penalty stiffness 1e4 N·m/rad). Without it a resting contact would be an endless train of
/// impacts (a Zeno sequence).
pub const IMPACT_MIN_SPEED: f64 = 0.1;

/// An impact found in a step: limit `event` crossed at `θ ∈ [0, 1]` of the step.
#[derive(Debug, Clone, Copy)]
pub(super) struct Crossing {
    pub(super) event: usize,
    pub(super) theta: f64,
}

/// The crossing of the cubic Hermite interpolant `p(θ)` through `p(0) = g0`, `p'(0) = d0`,
/// `p(1) = g1`, `p'(1) = d1` (with `g0 ≥ 0 > g1`): the root in `[0, 1]` found by bisection, and the
/// slope `p'(θ)` there (rate per unit `θ`). Bisection keeps the sign change bracketed, so it always
/// returns a crossing even where the cubic has three roots.
pub(super) fn hermite_root(g0: f64, d0: f64, g1: f64, d1: f64) -> (f64, f64) {
    let value = |x: f64| {
        let (x2, x3) = (x * x, x * x * x);
        (2.0 * x3 - 3.0 * x2 + 1.0) * g0
            + (x3 - 2.0 * x2 + x) * d0
            + (-2.0 * x3 + 3.0 * x2) * g1
            + (x3 - x2) * d1
    };
    let slope = |x: f64| {
        let x2 = x * x;
        (6.0 * x2 - 6.0 * x) * g0
            + (3.0 * x2 - 4.0 * x + 1.0) * d0
            + (-6.0 * x2 + 6.0 * x) * g1
            + (3.0 * x2 - 2.0 * x) * d1
    };
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    // 60 halvings: θ to 1e-18, below the rounding of any step.
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if value(mid) >= 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (hi, slope(hi))
}

impl HhtIntegrator {
    /// The earliest impact in the step from the state to the candidate in the workspace (`ws.q`,
    /// `ws.v`), if any: a limit with `g ≥ 0` at the start and `g < 0` at the end, crossing at an
    /// approach speed of at least [`IMPACT_MIN_SPEED`]. The crossing time is the root of the cubic
    /// Hermite interpolant of `g` through `(g, h ġ)` at both ends (docs/step-control.md §4).
    pub(super) fn find_crossing<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t1: f64,
        h: f64,
    ) -> Result<Option<Crossing>, IntegrateError> {
        let at_start = At {
            t: self.trajectory.state.t,
            step: self.trajectory.state.step,
        };
        let at_end = At {
            t: t1,
            step: self.trajectory.state.step + 1,
        };
        {
            let ws = &mut self.ws;
            eval::event_gaps(
                system,
                at_start,
                &self.trajectory.state.q,
                &self.trajectory.state.v,
                &mut ws.gaps_start,
                &mut ws.rates_start,
            )?;
            eval::event_gaps(
                system,
                at_end,
                &ws.q,
                &ws.v,
                &mut ws.gaps_end,
                &mut ws.rates_end,
            )?;
        }
        let ws = &self.ws;
        let mut earliest: Option<Crossing> = None;
        for k in 0..self.n_events {
            let (g0, g1) = (ws.gaps_start[k], ws.gaps_end[k]);
            if !(g0 >= 0.0 && g1 < 0.0) {
                continue;
            }
            let (d0, d1) = (h * ws.rates_start[k], h * ws.rates_end[k]);
            let (theta, slope) = hermite_root(g0, d0, g1, d1);
            if -slope / h < IMPACT_MIN_SPEED {
                continue;
            }
            if earliest.is_none_or(|e| theta < e.theta) {
                earliest = Some(Crossing { event: k, theta });
            }
        }
        Ok(earliest)
    }

    /// Applies the impact law of limit `event` at the current state and restarts the recursion from a
    /// consistent state there (the clock, the step count and the statistics continue).
    pub(super) fn impact<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        event: usize,
        step: u64,
    ) -> Result<(), IntegrateError> {
        let t = self.trajectory.state.t;
        let at = At { t, step };
        self.ws.impact_q.copy_from(&self.trajectory.state.q);
        self.ws.impact_v.copy_from(&self.trajectory.state.v);
        {
            let ws = &mut self.ws;
            eval::apply_impact(system, at, event, &mut ws.impact_q, &mut ws.impact_v)?;
        }
        // A restart that fails is a failure of the run at this step, not of its initial state.
        let start: ConsistentStart =
            consistent_start(system, t, &self.ws.impact_q, &self.ws.impact_v)
                .map_err(|e| e.at_step(step.max(1)))?;
        self.trajectory.state.q.copy_from(&start.q);
        self.trajectory.state.v.copy_from(&start.v);
        self.trajectory.v_newmark.copy_from(&start.v);
        self.trajectory.state.qdd.copy_from(&start.qdd);
        self.trajectory.state.a.copy_from(&start.qdd);
        self.trajectory.state.lambda.copy_from(&start.lambda);
        self.trajectory.predictor.clear();
        self.trajectory.newton.forget();
        self.trajectory.stats.impacts += 1;
        self.ws.mass_fresh = false;
        self.ws.constraints_fresh = false;
        Ok(())
    }
}

#[cfg(test)]
mod step_control_tests {
    use super::hermite_root;

    #[test]
    fn hermite_root_finds_the_crossing_and_its_slope() {
        // A straight line g(θ) = 0.3 − θ (rate −1 per unit θ): the root 0.3, slope −1.
        let (theta, slope) = hermite_root(0.3, -1.0, -0.7, -1.0);
        assert!((theta - 0.3).abs() < 1e-15 && (slope + 1.0).abs() < 1e-12);
        // A parabola g(θ) = 0.25 − θ² (g' = −2θ): root 0.5, slope −1; the cubic Hermite through a
        // parabola's values and slopes is the parabola itself.
        let (theta, slope) = hermite_root(0.25, 0.0, -0.75, -2.0);
        assert!((theta - 0.5).abs() < 1e-15 && (slope + 1.0).abs() < 1e-12);
        // Starting exactly on the limit and moving in at zero speed: the root at 0 with slope 0
        // (not an impact; resting contact is the penalty's).
        let (theta, slope) = hermite_root(0.0, 0.0, -1e-6, -2e-6);
        assert!(theta < 1e-15 && slope.abs() < 1e-12);
    }
}
