//! A grid step driven from outside, one evaluation at a time: the caller evaluates the mass matrix
//! and the inverse dynamics of the iterate (for many samples at once, docs/batch.md §5) and hands
//! them in; the integrator does everything else with the same functions, in the same order, as
//! [`HhtIntegrator::step`]. So a step driven this way has the bits of `step` whenever the caller's
//! evaluations have the bits of the system's own.
//!
//! Only the plain case is driven: one attempt of the grid step's size (fixed step control, or
//! adaptive when the controller plans the whole grid step and accepts it) that crosses no limit, no
//! contact coupling, a fresh diagonal Newton matrix at the predictor (the scalar attempt's pass
//! 1), no reuse of the last step's factorisation, no iterate leaving the regime of piecewise forces
//! its matrix was formed in (a joint-limit penalty switching on or off). Anything else — a system or a setting outside
//! that case, a limit crossed (the scalar step locates the impact), a pass that gives up (the scalar
//! attempt would refresh), the iteration limit, a step the adaptive controller rejects, any error — *abandons* the step: the trajectory is put back
//! exactly as it was (until acceptance an attempt writes only the workspace, the counters, the
//! step control's state and the Newton memory's flags, which are restored) and the caller runs
//! [`HhtIntegrator::step`], which repeats the same attempt bit for bit and goes on from there.

use super::events::IMPACT_LOCATE_FRACTION;
use super::newton::NewtonFlags;
use super::newton_pass::{NewtonPass, PassVerdict};
use super::state::ReportedVelocity;
use super::step_size::{
    AdaptiveVerdict, PlannedAttempt, StepControlState, ADAPTIVE_MAX_GROWTH,
    END_OF_INTERVAL_FRACTION,
};
use super::HhtIntegrator;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::settings::{NewtonMatrix, StepControl};
use crate::integrate::system::DaeSystem;
use crate::integrate::FactorKind;
use nalgebra::DVector;

/// A plain grid step in progress ([`HhtIntegrator::begin_plain_step`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PlainStep {
    at: At,
    t_end: f64,
    /// The step control's planned size, s (for the next plan, as `step` keeps it).
    planned: f64,
    /// The smallest sub-step, s (the adaptive controller's floor).
    h_min: f64,
    /// Newton iterations so far.
    iterations: usize,
    /// The step control's growth factor once converged and judged.
    growth: f64,
    judge: NewtonPass,
    /// The regime of piecewise forces the Newton matrix was formed in ([`DaeSystem::newton_regime`]).
    regime: u64,
    /// Whether the step computes its reported velocity (as [`HhtIntegrator::advance`] decides).
    report_velocity: bool,
    /// What the attempt may change before it is accepted, to put back when it is abandoned (the
    /// statistics are kept by the integrator: `HhtIntegrator::plain_stats_before`).
    control_before: StepControlState,
    newton_before: NewtonFlags,
}

/// Where a plain step stands after a Newton iteration ([`HhtIntegrator::plain_correct`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PlainProgress {
    /// Not converged yet: evaluate the residual at the new iterate and correct again.
    Iterate,
    /// Converged and accepted: the grid step is done.
    Done,
    /// Converged, with constraint rows and the velocity projection on: evaluate `M` at the
    /// converged iterate ([`HhtIntegrator::plain_iterate`]) and call
    /// [`HhtIntegrator::plain_accept_with_projection_mass`].
    NeedsProjectionMass,
    /// Abandoned, the trajectory as it was: run [`HhtIntegrator::step`].
    Abandoned,
}

impl HhtIntegrator {
    /// Whether `system` and the settings allow the next grid step to be driven as a plain step.
    fn plain_step_allowed<S: DaeSystem + ?Sized>(&self, system: &mut S) -> bool {
        let full_first = system.as_residual_jacobians().is_some()
            && match self.settings.newton_matrix {
                NewtonMatrix::Diagonal => false,
                NewtonMatrix::Auto => self.trajectory.control.full_newton_hold > 0,
                NewtonMatrix::Full => true,
            };
        !self.settings.reuse_newton_matrix
            && !full_first
            && system.as_inverse_dynamics().is_some()
            && system.as_newton_coupling().is_none()
            && system.as_newton_update_limit().is_none()
    }

    /// Starts the next grid step as a plain step: the predictor and the first iterate, whose
    /// configuration ([`HhtIntegrator::plain_iterate`]) the caller evaluates `M` at next; `report`
    /// as for [`HhtIntegrator::advance`]. `None` when the step is not plain (then nothing was
    /// changed: run [`HhtIntegrator::advance`] with the same `report`).
    pub(crate) fn begin_plain_step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        report: ReportedVelocity,
    ) -> Option<PlainStep> {
        if !self.plain_step_allowed(system)
            || eval::check_dimensions(system, self.nq, self.nv, self.m).is_err()
        {
            return None;
        }
        let step = self.trajectory.state.step + 1;
        let h_grid = self.grid_coeffs.h;
        let t_end = self.trajectory.t0 + step as f64 * h_grid;
        let h_min = h_grid / f64::from(1u32 << self.settings.max_step_halvings);
        let remaining = t_end - self.trajectory.state.t;
        if remaining <= END_OF_INTERVAL_FRACTION * h_grid {
            return None;
        }
        let plan = self.plan_attempt(t_end, h_min, remaining);
        if plan.h != h_grid || !plan.reaches_end {
            return None;
        }
        self.plain_stats_before = self.trajectory.stats;
        let mut plain = PlainStep {
            at: At { t: plan.t1, step },
            t_end,
            planned: plan.planned,
            h_min,
            iterations: 0,
            growth: ADAPTIVE_MAX_GROWTH,
            judge: NewtonPass::at_predictor(self.carried_contraction(self.grid_coeffs.h, false)),
            regime: 0,
            report_velocity: report == ReportedVelocity::Computed || self.n_events > 0,
            control_before: self.trajectory.control,
            newton_before: self.trajectory.newton.flags(),
        };
        self.predict(plan.h, self.predicts_by_order(system));
        if self.update_iterate(system, plain.at).is_err() {
            self.abandon_plain_step(&mut plain);
            return None;
        }
        // A limit the predictor already crosses: the scalar step shortens the step to it.
        if self.n_events > 0 {
            match self.find_crossing(system, plain.at.t, plan.h) {
                Ok(None) => {}
                Ok(Some(crossing)) if crossing.theta >= 1.0 - IMPACT_LOCATE_FRACTION => {}
                _ => {
                    self.abandon_plain_step(&mut plain);
                    return None;
                }
            }
        }
        self.trajectory.newton.reusable = false;
        Some(plain)
    }

    /// The current iterate `(q, q̇, q̈)` (dims nq, nv, nv) of a plain step.
    pub(crate) fn plain_iterate(&self) -> (&DVector<f64>, &DVector<f64>, &DVector<f64>) {
        (&self.ws.q, &self.ws.v, &self.ws.qdd)
    }

    /// Factorises the Newton matrix of a plain step with `mass` = `M` at the first iterate
    /// (`nv × nv`, column-major, as the system's `mass_matrix` would give it). `false` when the
    /// step was abandoned (a singular matrix, an error of the system).
    pub(crate) fn plain_factorise<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
        mass: &[f64],
    ) -> bool {
        self.ws.mass.as_mut_slice().copy_from_slice(mass);
        if self.factorise_diagonal(system, plain.at).is_err() {
            self.abandon_plain_step(plain);
            return false;
        }
        plain.regime = system.newton_regime(&self.ws.q);
        true
    }

    /// Whether this integrator's plain steps factorise a Cholesky of `M + diag` (no constraint
    /// rows), which the caller may make itself: [`HhtIntegrator::plain_newton_diagonal`] and
    /// [`HhtIntegrator::plain_install_factor`] then replace [`HhtIntegrator::plain_factorise`].
    pub(crate) fn plain_factor_is_cholesky(&self) -> bool {
        self.trajectory.newton.solver.kind() == FactorKind::Cholesky
    }

    /// The diagonal the Newton matrix adds to `M` at the plain step's first iterate (`β'h² k +
    /// γ'h c`, dim nv; `Some(None)` when the settings leave it out), evaluated as
    /// [`HhtIntegrator::plain_factorise`] would. `None` when the step was abandoned (an error of
    /// the system).
    pub(crate) fn plain_newton_diagonal<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
    ) -> Option<Option<&[f64]>> {
        match self.evaluate_newton_diagonal(system, plain.at) {
            Ok(true) => Some(Some(self.ws.newton_diagonal.as_slice())),
            Ok(false) => Some(None),
            Err(_) => {
                self.abandon_plain_step(plain);
                None
            }
        }
    }

    /// Takes the plain step's Newton matrix as factorised by the caller: `write_factor` fills in
    /// (`nv × nv`, column-major) the Cholesky factorisation of `M` at the first iterate plus [`HhtIntegrator::plain_newton_diagonal`]'s
    /// diagonal, with the bits and the pivot test of the integrator's own
    /// ([`crate::integrate::DenseSolver::install_cholesky_factor`]); the rest as
    /// [`HhtIntegrator::plain_factorise`] does it, except that `M` itself is not kept (a plain
    /// step takes its residual from the caller and never reads it).
    pub(crate) fn plain_install_factor<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
        write_factor: impl FnOnce(&mut [f64]),
    ) {
        self.ws.use_full = false;
        self.trajectory
            .newton
            .solver
            .install_cholesky_factor(write_factor);
        // `ws.mass` does not hold M at this iterate.
        self.ws.mass_fresh = false;
        // A matrix of `M` alone: no constraint rows, so none to evaluate.
        self.ws.constraints_fresh = true;
        self.trajectory.stats.factorisations += 1;
        plain.regime = system.newton_regime(&self.ws.q);
    }

    /// The iterate `(q, q̇)` and the buffer the caller writes the dynamics rows of the residual
    /// into (dim nv, as the system's `dynamics_residual` would give them) before
    /// [`HhtIntegrator::plain_correct`].
    pub(crate) fn plain_residual_buffers(
        &mut self,
    ) -> (&DVector<f64>, &DVector<f64>, &mut DVector<f64>) {
        let ws = &mut self.ws;
        (&ws.q, &ws.v, &mut ws.dyn_residual)
    }

    /// One Newton correction of a plain step with the residual the caller wrote, then the pass's
    /// tests (the constraint rows, if any, are evaluated here, per lane). On convergence the step
    /// is accepted (with rows: the velocity projection) and the grid step ended, as
    /// [`HhtIntegrator::step`] does. Errors only where `step` would have failed after changing the
    /// state (accepting the step); every other failure abandons the step.
    pub(crate) fn plain_correct<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
    ) -> Result<PlainProgress, IntegrateError> {
        let Some(residual_inf) = self.plain_newton_rhs(system, plain) else {
            return Ok(PlainProgress::Abandoned);
        };
        self.solve_newton_rhs();
        self.plain_correct_solved(system, plain, residual_inf)
    }

    /// The first half of [`HhtIntegrator::plain_correct`], for a caller that solves the Newton
    /// system itself with the factor it installed ([`HhtIntegrator::plain_install_factor`]): counts
    /// the iteration and writes the right-hand side, which [`HhtIntegrator::plain_newton_rhs_mut`]
    /// then lends out. Returns the residual's largest magnitude to hand back to
    /// [`HhtIntegrator::plain_correct_solved`], or `None` when the step was abandoned
    /// ([`PlainProgress::Abandoned`]).
    #[inline]
    pub(crate) fn plain_newton_rhs<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
    ) -> Option<f64> {
        plain.iterations += 1;
        if self.add_constraint_rows(system, plain.at).is_err() {
            self.abandon_plain_step(plain);
            return None;
        }
        Some(self.newton_rhs())
    }

    /// The Newton system's right-hand side after [`HhtIntegrator::plain_newton_rhs`], to be
    /// overwritten by the solution `(Δq̈, Δλ)` (dimension `nv + m`).
    pub(crate) fn plain_newton_rhs_mut(&mut self) -> &mut [f64] {
        let n = self.nv + self.m;
        &mut self.ws.rhs.as_mut_slice()[..n]
    }

    /// The second half of [`HhtIntegrator::plain_correct`], once the right-hand side holds the
    /// solution (solved with the step's factor, so with the bits its own solve would give).
    #[inline]
    pub(crate) fn plain_correct_solved<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
        residual_inf: f64,
    ) -> Result<PlainProgress, IntegrateError> {
        let report = match self.apply_newton_correction(system, plain.at, residual_inf) {
            Ok(report) => report,
            Err(_) => {
                self.abandon_plain_step(plain);
                return Ok(PlainProgress::Abandoned);
            }
        };
        match plain.judge.judge(report, &mut self.trajectory.stats) {
            PassVerdict::Converged => {
                let h = self.grid_coeffs.h;
                self.conclude_attempt(h, plain.iterations, false, false, &plain.judge);
                // An impact inside the converged step: the scalar step locates it.
                if self.n_events > 0
                    && !matches!(self.find_crossing(system, plain.at.t, h), Ok(None))
                {
                    self.abandon_plain_step(plain);
                    return Ok(PlainProgress::Abandoned);
                }
                let mut growth = ADAPTIVE_MAX_GROWTH;
                if self.settings.step_control == StepControl::Adaptive {
                    match self.adaptive_verdict(system, plain.at, h, plain.h_min) {
                        Ok(AdaptiveVerdict::Accept { growth: factor }) => growth = factor,
                        // A rejected step (the scalar step then sub-steps) or a failing state
                        // check: the scalar step repeats this attempt and goes on from there.
                        Ok(AdaptiveVerdict::Retry) | Err(_) => {
                            self.abandon_plain_step(plain);
                            return Ok(PlainProgress::Abandoned);
                        }
                    }
                }
                plain.growth = growth;
                if self.m > 0
                    && self.settings.velocity_projection
                    && plain.report_velocity
                    && !self.projection_keeps_newton_mass()
                {
                    // The projection needs M at q_{n+1}, the converged iterate: the caller's.
                    return Ok(PlainProgress::NeedsProjectionMass);
                }
                self.finish_plain_step(system, plain)?;
                Ok(PlainProgress::Done)
            }
            // An iterate that left the matrix's regime: the scalar attempt refactorises there.
            PassVerdict::Continue
                if plain.iterations < self.settings.max_newton_iterations
                    && system.newton_regime(&self.ws.q) == plain.regime =>
            {
                Ok(PlainProgress::Iterate)
            }
            _ => {
                self.abandon_plain_step(plain);
                Ok(PlainProgress::Abandoned)
            }
        }
    }

    /// Accepts a converged plain step whose velocity projection waits for `M` at the converged
    /// iterate ([`PlainProgress::NeedsProjectionMass`]): `mass` (`nv × nv`, column-major, as the
    /// system's `mass_matrix` at [`HhtIntegrator::plain_iterate`]'s `q` would give it) is used in
    /// its place. Errors where [`HhtIntegrator::step`] would fail after changing the state.
    pub(crate) fn plain_accept_with_projection_mass<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
        mass: &[f64],
    ) -> Result<(), IntegrateError> {
        self.ws.mass.as_mut_slice().copy_from_slice(mass);
        self.ws.projection_mass_given = true;
        let result = self.finish_plain_step(system, plain);
        self.ws.projection_mass_given = false;
        result
    }

    /// Accepts the converged plain step and ends the grid step, as [`HhtIntegrator::step`] does.
    fn finish_plain_step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        plain: &mut PlainStep,
    ) -> Result<(), IntegrateError> {
        let At { t: t1, step } = plain.at;
        let h = self.grid_coeffs.h;
        self.report_velocity = plain.report_velocity;
        let plan = PlannedAttempt {
            planned: plain.planned,
            h,
            reaches_end: true,
            t1,
        };
        let accepted = self.accept(system, plan, step, plain.growth);
        self.report_velocity = true;
        accepted?;
        self.end_grid_step(plain.t_end, step, true);
        Ok(())
    }

    /// Abandons the plain step (the caller runs [`HhtIntegrator::advance`] instead, which repeats
    /// the attempt bit for bit): for a caller whose own evaluation for the step refused it, as
    /// the integrator would (the lock-step's batched factorisation refusing a lane's matrix).
    pub(crate) fn plain_abandon(&mut self, plain: &mut PlainStep) {
        self.abandon_plain_step(plain);
    }

    /// Puts back what a plain attempt changed outside the workspace.
    fn abandon_plain_step(&mut self, plain: &mut PlainStep) {
        self.trajectory.stats = self.plain_stats_before;
        self.trajectory.control = plain.control_before;
        self.trajectory.newton.restore_flags(plain.newton_before);
    }
}
