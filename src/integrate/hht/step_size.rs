//! Driving one grid step (docs/step-control.md §3–§4): the attempts that cover the grid interval,
//! their sizes, the adaptive controller's verdict on a converged attempt, retries after a failure,
//! and the acceptance of a sub-step. The grid step is a small loop over an explicit
//! [`GridStepProgress`]; each attempt's Newton iteration is `newton.rs`'s, each impact
//! `events.rs`'s.

use super::events::{IMPACT_LOCATE_ATTEMPTS, IMPACT_LOCATE_FRACTION, IMPACT_OVERSHOOT_FRACTION};
use super::newton::Attempt;
use super::HhtIntegrator;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::settings::StepControl;
use crate::integrate::system::DaeSystem;

/// What the step control carries from step to step of one trajectory: part of [`HhtTrajectory`](crate::integrate::HhtTrajectory), so
/// that a sample's steps never depend on which sample the same integrator advanced before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepControlState {
    /// The sub-step the next attempt starts with, s (at most the grid step).
    pub h_next: f64,
    /// The last accepted sub-step, s (scales the predictor's extrapolation).
    pub h_last: f64,
    /// The accepted sub-step before the last, s (the predictor's curvature term).
    pub h_before_last: f64,
    /// Steps that still use the full Newton matrix ([`NewtonMatrix::Auto`](crate::integrate::NewtonMatrix::Auto)).
    pub full_newton_hold: u32,
    /// Whether the last grid step was one plain step of `h` (no sub-steps, no impact): the forward
    /// sensitivities can only differentiate those.
    pub last_step_plain: bool,
}

impl StepControlState {
    pub(super) fn new(h: f64) -> Self {
        Self {
            h_next: h,
            h_last: h,
            h_before_last: h,
            full_newton_hold: 0,
            last_step_plain: true,
        }
    }
}

/// Most attempts (accepted and rejected sub-steps, retries, located impact steps) within one grid
/// step. A plain step is one attempt; the hardest case of `tests/stability.rs` (an elbow spring of
/// 1e8 N·m/rad released 0.1 rad from rest, resolved adaptively) needs ~350. At the ~2–10 µs of an
/// arm's sub-step 1e5 attempts are 0.2–1 s: also the bound on the work between two interruption
/// checks of a run (which check before every grid step).
pub const MAX_ATTEMPTS_PER_STEP: u64 = 100_000;

/// A grid interval counts as reached when less than this fraction of the grid step remains (the
/// remaining time is rounding, not a step).
pub(super) const END_OF_INTERVAL_FRACTION: f64 = 1e-9;

/// Growth and shrink limits and the safety factor of the adaptive controller (per accepted or
/// rejected sub-step): the new step is `h · clamp(0.9 · err^(−1/3), 0.2, 2)`, the usual choice for
/// an error estimate of order `h³` (Hairer, Nørsett & Wanner I, §II.4).
pub(super) const ADAPTIVE_SAFETY: f64 = 0.9;
pub(super) const ADAPTIVE_MAX_GROWTH: f64 = 2.0;
pub(super) const ADAPTIVE_MAX_SHRINK: f64 = 0.2;

/// The size of an attempt ([`HhtIntegrator::plan_attempt`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct PlannedAttempt {
    /// The step control's planned size, s.
    pub(super) planned: f64,
    /// The attempt's size, s.
    pub(super) h: f64,
    /// The attempt ends the grid interval.
    pub(super) reaches_end: bool,
    /// The time it ends at, s.
    pub(super) t1: f64,
}

/// What the adaptive controller does with a converged attempt
/// ([`HhtIntegrator::adaptive_verdict`]).
#[derive(Debug, Clone, Copy)]
pub(super) enum AdaptiveVerdict {
    /// Rejected: attempt again with the size the controller planned.
    Retry,
    /// Accepted; the next attempt may be `growth` times this one.
    Accept { growth: f64 },
}

/// Whether a failed attempt is worth retrying with a smaller step: Newton failures, non-finite
/// numbers and a singular Newton matrix can all come from a step too long for the dynamics;
/// dimension mismatches and errors of the consistent start cannot.
pub(super) fn retryable(error: &IntegrateError) -> bool {
    matches!(
        error,
        IntegrateError::NewtonNotConverged { .. }
            | IntegrateError::NonFinite { .. }
            | IntegrateError::SingularMatrix { .. }
            | IntegrateError::System { .. }
    )
}

/// Where the search for an impact inside one grid step stands ([`GridStepProgress`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ImpactSearch {
    /// No crossing seen in this grid step: the fixed step reports a failed attempt as it is.
    Clear,
    /// A crossing was seen in this grid step: from now on the fixed step also retries a failed
    /// attempt with half its size (the short located steps are not grid steps).
    Near {
        /// The next attempt is a located step aimed at the crossing: its predictor is not checked
        /// for a crossing again.
        aiming: bool,
        /// Located steps aimed at the current impact so far (at most [`IMPACT_LOCATE_ATTEMPTS`]).
        shortenings: usize,
    },
}

/// What has happened so far in one grid step ([`HhtIntegrator::advance_grid_step`]).
#[derive(Debug)]
struct GridStepProgress {
    /// Attempts so far (at most [`MAX_ATTEMPTS_PER_STEP`]).
    attempts: u64,
    /// Accepted sub-steps so far.
    accepted: usize,
    /// Something other than one attempt of the grid step's size happened: a retry, a rejection,
    /// a located step or an impact.
    detoured: bool,
    /// The first failure of a retried attempt: what is reported when even the smallest sub-step
    /// fails.
    first_failure: Option<IntegrateError>,
    impact: ImpactSearch,
}

impl GridStepProgress {
    fn new() -> Self {
        Self {
            attempts: 0,
            accepted: 0,
            detoured: false,
            first_failure: None,
            impact: ImpactSearch::Clear,
        }
    }

    /// The next attempt is a located step aimed at a crossing (not checked for one again).
    fn aiming(&self) -> bool {
        matches!(self.impact, ImpactSearch::Near { aiming: true, .. })
    }

    /// A crossing was seen in this grid step.
    fn near_impact(&self) -> bool {
        matches!(self.impact, ImpactSearch::Near { .. })
    }

    /// Located steps aimed at the current impact so far.
    fn shortenings(&self) -> usize {
        match self.impact {
            ImpactSearch::Clear => 0,
            ImpactSearch::Near { shortenings, .. } => shortenings,
        }
    }

    /// The next attempt aims at a crossing: one the predictor showed (`counted` false) or one
    /// found inside a converged step (`counted` true: one more shortening towards the impact).
    fn aim_at_crossing(&mut self, counted: bool) {
        self.detoured = true;
        self.impact = ImpactSearch::Near {
            aiming: true,
            shortenings: self.shortenings() + usize::from(counted),
        };
    }

    /// The next attempt is not aimed at a crossing (the last one converged, or failed and so said
    /// nothing about the crossing).
    fn stop_aiming(&mut self) {
        if let ImpactSearch::Near { aiming, .. } = &mut self.impact {
            *aiming = false;
        }
    }

    /// An impact was applied: the next one is located from scratch.
    fn impact_applied(&mut self) {
        self.detoured = true;
        self.accepted += 1;
        if let ImpactSearch::Near { shortenings, .. } = &mut self.impact {
            *shortenings = 0;
        }
    }

    /// The grid step was one plain step of its size (all the forward sensitivities differentiate).
    fn was_plain(&self) -> bool {
        !self.detoured && self.accepted == 1
    }
}

impl HhtIntegrator {
    /// The grid step of [`HhtIntegrator::advance`] (`report_velocity` set): attempts until the
    /// grid time is reached. A converged attempt is shortened to a crossing inside it, ends at a
    /// located impact, is judged by the adaptive controller, or is accepted; a failed one is
    /// retried at half its size where that may help ([`retryable`]).
    pub(super) fn advance_grid_step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
    ) -> Result<(), IntegrateError> {
        eval::check_dimensions(system, self.nq, self.nv, self.m)?;
        let step = self.trajectory.state.step + 1;
        let h_grid = self.grid_coeffs.h;
        let t_end = self.trajectory.t0 + step as f64 * h_grid;
        let adaptive = self.settings.step_control == StepControl::Adaptive;
        let h_min = h_grid / f64::from(1u32 << self.settings.max_step_halvings);
        let mut progress = GridStepProgress::new();
        loop {
            let remaining = t_end - self.trajectory.state.t;
            if remaining <= END_OF_INTERVAL_FRACTION * h_grid {
                break;
            }
            progress.attempts += 1;
            if progress.attempts > MAX_ATTEMPTS_PER_STEP {
                return Err(IntegrateError::TooManySubsteps {
                    t: t_end,
                    step,
                    attempts: MAX_ATTEMPTS_PER_STEP,
                    smallest_s: self.trajectory.stats.smallest_step_s,
                });
            }
            let plan = self.plan_attempt(t_end, h_min, remaining);
            let (h, t1) = (plan.h, plan.t1);
            let check_prediction = self.n_events > 0 && !progress.aiming();
            match self.attempt(system, t1, h, step, check_prediction) {
                Ok(Attempt::PredictedCrossing { theta }) => {
                    progress.aim_at_crossing(false);
                    self.trajectory.control.h_next =
                        (theta * h + IMPACT_OVERSHOOT_FRACTION * h_grid).max(h_min);
                    continue;
                }
                Ok(Attempt::Converged) => {}
                Err(error) if retryable(&error) && (adaptive || progress.near_impact()) => {
                    progress.detoured = true;
                    self.trajectory.stats.step_failures += 1;
                    if 0.5 * h < h_min * (1.0 - 1e-12) {
                        return Err(progress.first_failure.unwrap_or(error));
                    }
                    progress.first_failure.get_or_insert(error);
                    self.trajectory.control.h_next = 0.5 * h;
                    // A failed located step says nothing about the crossing: locate again.
                    progress.stop_aiming();
                    continue;
                }
                Err(error) => return Err(error),
            }
            progress.stop_aiming();

            // An impact inside the converged step: shorten the step to it, or, once located, accept
            // the step and apply the impact law at its end.
            if self.n_events > 0 {
                if let Some(crossing) = self.find_crossing(system, t1, h)? {
                    let rest = (1.0 - crossing.theta) * h;
                    if rest > IMPACT_LOCATE_FRACTION * h_grid
                        && progress.shortenings() < IMPACT_LOCATE_ATTEMPTS
                        && crossing.theta * h >= h_min
                    {
                        progress.aim_at_crossing(true);
                        self.trajectory.control.h_next =
                            crossing.theta * h + IMPACT_OVERSHOOT_FRACTION * h_grid;
                        continue;
                    }
                    self.commit(system, t1, h, step)?;
                    self.impact(system, crossing.event, step)?;
                    progress.impact_applied();
                    // The short located step says nothing about the motion after the impact.
                    self.trajectory.control.h_next = h_grid;
                    continue;
                }
            }

            let mut growth = ADAPTIVE_MAX_GROWTH;
            if adaptive {
                match self.adaptive_verdict(system, At { t: t1, step }, h, h_min)? {
                    AdaptiveVerdict::Retry => {
                        progress.detoured = true;
                        continue;
                    }
                    AdaptiveVerdict::Accept { growth: factor } => growth = factor,
                }
            }
            self.accept(system, plan, step, growth)?;
            progress.accepted += 1;
        }
        self.end_grid_step(t_end, step, progress.was_plain());
        Ok(())
    }

    /// The adaptive controller's verdict on the converged attempt of size `h` to `at.t` (the
    /// candidate in the workspace): retry smaller (the next size planned, the rejection counted)
    /// when the system rejects the state or the error estimate exceeds 1 above `h_min`; else
    /// accept, with the growth factor of the next step (docs/step-control.md §3).
    pub(super) fn adaptive_verdict<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        h: f64,
        h_min: f64,
    ) -> Result<AdaptiveVerdict, IntegrateError> {
        let error = self.error_estimate();
        let factor = if error > 0.0 {
            ADAPTIVE_SAFETY * error.powf(-1.0 / 3.0)
        } else {
            ADAPTIVE_MAX_GROWTH
        };
        let rejection = system
            .state_rejection(at.t, &self.trajectory.state.q, &self.ws.q)
            .map_err(at.system_error("state_rejection"))?;
        if rejection > 1.0 && h > h_min * (1.0 + 1e-12) {
            self.trajectory.stats.state_rejections += 1;
            self.trajectory.control.h_next = 0.5 * h;
            return Ok(AdaptiveVerdict::Retry);
        }
        if error > 1.0 {
            if h > h_min * (1.0 + 1e-12) {
                self.trajectory.stats.error_rejections += 1;
                self.trajectory.control.h_next = h * factor.max(ADAPTIVE_MAX_SHRINK);
                return Ok(AdaptiveVerdict::Retry);
            }
            self.trajectory.stats.error_limited_steps += 1;
        }
        self.trajectory.stats.max_error_estimate =
            self.trajectory.stats.max_error_estimate.max(error);
        Ok(AdaptiveVerdict::Accept {
            growth: factor.clamp(ADAPTIVE_MAX_SHRINK, ADAPTIVE_MAX_GROWTH),
        })
    }

    /// The size of the next attempt towards the grid time `t_end` when `remaining` (s) is left,
    /// from the step control's plan, never below `h_min` nor leaving a sliver below it.
    #[inline]
    pub(super) fn plan_attempt(&self, t_end: f64, h_min: f64, remaining: f64) -> PlannedAttempt {
        let h_grid = self.grid_coeffs.h;
        let planned = self.trajectory.control.h_next.clamp(h_min, h_grid);
        let mut h = planned.min(remaining);
        // Never leave a sliver below the smallest step for later.
        if remaining - h < h_min {
            h = remaining;
        }
        let reaches_end = h == remaining;
        // A whole grid interval is a step of exactly h (remaining differs from it by rounding),
        // so the plain path uses the grid's coefficients and predictor unchanged.
        if (h - h_grid).abs() <= END_OF_INTERVAL_FRACTION * h_grid {
            h = h_grid;
        }
        let t1 = if reaches_end {
            t_end
        } else {
            self.trajectory.state.t + h
        };
        PlannedAttempt {
            planned,
            h,
            reaches_end,
            t1,
        }
    }

    /// Accepts the converged attempt `plan` ([`Self::commit`]) and plans the next one: `growth`
    /// times this one (the adaptive controller's factor; 2 with the fixed step), at most the grid
    /// step.
    pub(super) fn accept<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plan: PlannedAttempt,
        step: u64,
        growth: f64,
    ) -> Result<(), IntegrateError> {
        let h = plan.h;
        self.commit(system, plan.t1, h, step)?;
        let mut next = h * growth;
        if plan.reaches_end && growth >= 1.0 {
            // A step cut short by the grid says nothing against the planned size.
            next = next.max(plan.planned);
        }
        self.trajectory.control.h_next = next.min(self.grid_coeffs.h);
        Ok(())
    }

    /// Ends grid step number `step` at `t_end` (set from the step count, so time does not drift);
    /// `plain`: it was one attempt of the grid step's size.
    pub(super) fn end_grid_step(&mut self, t_end: f64, step: u64, plain: bool) {
        self.trajectory.state.t = t_end;
        self.trajectory.state.step = step;
        self.trajectory.stats.steps += 1;
        self.trajectory.control.last_step_plain = plain;
        self.coeffs = self.grid_coeffs;
    }

    /// Accepts the candidate end state of the last attempt (step `h` to `t1`), keeping `q̈_n` and
    /// `λ_n` for the next predictor.
    pub(super) fn commit<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t1: f64,
        h: f64,
        step: u64,
    ) -> Result<(), IntegrateError> {
        // The history moves back one step by swapping buffers: q̈_n and λ_n go into the predictor's
        // history, and the buffers they leave are overwritten with the new state just below.
        let by_order = self.predicts_by_order(system);
        let trajectory = &mut self.trajectory;
        trajectory.predictor.push(
            h,
            trajectory.control.h_last,
            by_order,
            &mut trajectory.state.qdd,
            &mut trajectory.state.lambda,
            (self.ws.qdd.as_slice(), self.ws.lambda.as_slice()),
        );
        // The converged iterate becomes the state by swapping buffers (of equal dimensions): the
        // next attempt overwrites every one of them (the predictor q̈ and λ, update_iterate a, q
        // and q̇) before it reads them.
        let ws = &mut self.ws;
        let state = &mut self.trajectory.state;
        state.t = t1;
        for (to, from) in [
            (&mut state.q, &mut ws.q),
            (&mut state.v, &mut ws.v),
            (&mut state.a, &mut ws.a),
            (&mut state.qdd, &mut ws.qdd),
            (&mut state.lambda, &mut ws.lambda),
        ] {
            std::mem::swap(to, from);
        }
        self.trajectory
            .v_newmark
            .as_mut_slice()
            .copy_from_slice(state.v.as_slice());
        self.trajectory.control.h_before_last = self.trajectory.control.h_last;
        self.trajectory.control.h_last = h;
        self.trajectory.stats.substeps += 1;
        self.trajectory.stats.smallest_step_s = if self.trajectory.stats.smallest_step_s > 0.0 {
            self.trajectory.stats.smallest_step_s.min(h)
        } else {
            h
        };
        if self.m > 0 && self.report_velocity {
            self.finish_constrained_step(system, At { t: t1, step })?;
        }
        Ok(())
    }

    /// The adaptive controller's error measure of the candidate step: the weighted RMS over the
    /// velocity coordinates of `|β − 1/6| h² |q̈_{n+1} − q̈_n| / tolerance` (the leading local error
    /// of the Newmark position update; docs/step-control.md §3). Accept when ≤ 1.
    pub(super) fn error_estimate(&self) -> f64 {
        if self.nv == 0 {
            return 0.0;
        }
        let c = self.coeffs;
        let factor = (c.beta - 1.0 / 6.0).abs() * c.h * c.h / self.settings.tolerance;
        let sum: f64 = self
            .ws
            .qdd
            .iter()
            .zip(self.trajectory.state.qdd.iter())
            .map(|(new, old)| {
                let e = factor * (new - old);
                e * e
            })
            .sum();
        (sum / self.nv as f64).sqrt()
    }
}
