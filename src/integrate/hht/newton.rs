//! One attempt's Newton iteration (docs/method.md §5): the passes — reuse of the trajectory's stored
//! factorisation, a fresh one at the predictor, the refresh — each judged by `newton_pass.rs`, with
//! refactorisations where an iterate leaves its matrix's regime of piecewise forces; then the
//! bookkeeping a converged attempt leaves for the next step (the factorisation it may reuse, the
//! measured contraction, the full-matrix hold).

use super::events::IMPACT_LOCATE_FRACTION;
use super::newton_pass::{
    CarriedContraction, IterationReport, MeasuredContraction, NewtonPass, PassVerdict,
};
use super::HhtIntegrator;
use crate::integrate::dense_solver::{DenseSolver, FactorKind};
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::At;
use crate::integrate::settings::{NewtonMatrix, FULL_NEWTON_HOLD_STEPS, NEWTON_REUSE_MAX_RATE};
use crate::integrate::system::DaeSystem;

/// The Newton factorisation a trajectory carries from step to step (docs/method.md §5, "Reusing the
/// Newton matrix"). It belongs to the trajectory, not to the workspace, so that whether a step
/// reuses it never depends on which samples the same integrator advanced before (a study's results
/// stay independent of threads and blocks).
#[derive(Debug, Clone)]
pub(super) struct NewtonMemory {
    /// Factorisation of the diagonal Newton matrix `[M + β'h² K + γ'h C, Φ_qᵀ; Φ_q, 0]` (Cholesky
    /// without constraint rows, else LU); after a constrained step with the velocity projection, of
    /// the projection's `[M Φ_qᵀ; Φ_q 0]` at `q_{n+1}` (then not reusable).
    pub(super) solver: DenseSolver,
    /// `solver` holds a Newton matrix of this trajectory that the next step may iterate with.
    pub(super) reusable: bool,
    /// The step size the stored matrix was assembled for, s.
    pub(super) h: f64,
    /// Slowest contraction `ρ` the last step's converging pass saw (0 when one iteration sufficed).
    pub(super) rate: f64,
    /// The contraction the last pass with a matrix factorised at the predictor measured, for the
    /// next step's first correction; `None` at a (re)start, after an impact, and after a step
    /// that needed a refresh.
    pub(super) contraction: Option<MeasuredContraction>,
}

impl NewtonMemory {
    pub(super) fn new(nv: usize, m: usize) -> Self {
        let kind = if m == 0 {
            FactorKind::Cholesky
        } else {
            FactorKind::SaddlePoint { constraint_rows: m }
        };
        Self {
            solver: DenseSolver::new(nv + m, kind),
            reusable: false,
            h: 0.0,
            rate: 0.0,
            contraction: None,
        }
    }

    /// The contraction the next step's first correction may be judged by: the one measured at the
    /// same step size with the same kind of matrix.
    pub(super) fn carried_contraction(&self, h: f64, full: bool) -> Option<CarriedContraction> {
        self.contraction
            .filter(|measured| measured.h == h && measured.full == full)
            .map(|measured| CarriedContraction {
                rate: measured.rate,
                first_correction: measured.first_correction,
            })
    }

    /// Drops what the next step could carry over from the last (a restart, an impact): the stored
    /// matrix is no longer reusable and the measured contraction no longer applies.
    pub(super) fn forget(&mut self) {
        self.reusable = false;
        self.contraction = None;
    }

    /// Everything but the factorisation, for an attempt that may be put back
    /// ([`HhtIntegrator::begin_plain_step`]).
    pub(super) fn flags(&self) -> NewtonFlags {
        NewtonFlags {
            reusable: self.reusable,
            h: self.h,
            rate: self.rate,
            contraction: self.contraction,
        }
    }

    /// Puts back what [`NewtonMemory::flags`] saved.
    pub(super) fn restore_flags(&mut self, flags: NewtonFlags) {
        self.reusable = flags.reusable;
        self.h = flags.h;
        self.rate = flags.rate;
        self.contraction = flags.contraction;
    }
}

/// The [`NewtonMemory`] without its factorisation.
#[derive(Debug, Clone, Copy)]
pub(super) struct NewtonFlags {
    pub(super) reusable: bool,
    pub(super) h: f64,
    pub(super) rate: f64,
    pub(super) contraction: Option<MeasuredContraction>,
}

/// How often one Newton pass may refactorise because its iterate left the regime of piecewise
/// forces its matrix was formed in ([`DaeSystem::newton_regime`]; a joint-limit penalty switching
/// on or off). A converging iteration settles in one regime after one or two such switches; the
/// cap keeps an iterate that keeps crossing from refactorising at every iteration (it then goes on
/// with the last matrix, as before).
pub(super) const MAX_REGIME_REFACTORISATIONS: usize = 4;

/// How one attempt of a (sub-)step ended, when it did not fail.
pub(super) enum Attempt {
    /// Newton converged; the iterate in the workspace is the candidate end state.
    Converged,
    /// The predictor already crosses a limit at `θ` of the step: shorten before solving.
    PredictedCrossing { theta: f64 },
}

impl HhtIntegrator {
    /// One attempt of a (sub-)step of size `h` from the current state to `t1`: predictor, then
    /// Newton (diagonal matrix first; the full matrix on refresh or while held, see
    /// [`NewtonMatrix`]). The state is not touched; the candidate end state is left in the workspace.
    /// With `check_prediction`, a predictor that crosses a limit returns
    /// [`Attempt::PredictedCrossing`] before Newton runs.
    pub(super) fn attempt<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t1: f64,
        h: f64,
        step: u64,
        check_prediction: bool,
    ) -> Result<Attempt, IntegrateError> {
        let at = At { t: t1, step };
        self.predict(h, self.predicts_by_order(system));
        self.update_iterate(system, at)?;
        if check_prediction {
            if let Some(crossing) = self.find_crossing(system, t1, h)? {
                if crossing.theta < 1.0 - IMPACT_LOCATE_FRACTION {
                    return Ok(Attempt::PredictedCrossing {
                        theta: crossing.theta,
                    });
                }
            }
        }

        let provides_full = system.as_residual_jacobians().is_some();
        let full_first = provides_full
            && match self.settings.newton_matrix {
                NewtonMatrix::Diagonal => false,
                NewtonMatrix::Auto => self.trajectory.control.full_newton_hold > 0,
                NewtonMatrix::Full => true,
            };
        let full_on_refresh =
            provides_full && self.settings.newton_matrix != NewtonMatrix::Diagonal;
        let max_iterations = self.settings.max_newton_iterations;
        // Pass 0 iterates with the trajectory's stored factorisation (docs/method.md §5, "Reusing
        // the Newton matrix"); pass 1 factorises at the predictor (or, after a failed pass 0, at the
        // current iterate); pass 2 is the refresh.
        let reuse = self.settings.reuse_newton_matrix
            && self.m == 0
            && !full_first
            && system.as_newton_coupling().is_none()
            && self.trajectory.newton.reusable
            && self.trajectory.newton.h == h
            && self.trajectory.newton.rate <= NEWTON_REUSE_MAX_RATE;
        self.trajectory.newton.reusable = false;
        let mut iterations = 0;
        let mut converged = false;
        let mut converged_with_full = false;
        let mut converged_pass = NewtonPass::new(1);
        let mut last: Option<IterationReport> = None;
        for pass in if reuse { 0..3 } else { 1..3 } {
            let full = match pass {
                0 => false,
                1 => full_first,
                _ => {
                    self.trajectory.stats.refreshes += 1;
                    full_on_refresh
                }
            };
            if pass == 0 {
                self.ws.use_full = false;
            } else {
                self.factorise_at_iterate(system, at, full)?;
            }
            let mut judge = if pass == 1 {
                NewtonPass::at_predictor(self.carried_contraction(h, full))
            } else {
                NewtonPass::new(pass)
            };
            // The regime of piecewise forces (joints beyond a limit) the matrix was formed in.
            let mut matrix_regime = (pass > 0).then(|| system.newton_regime(&self.ws.q));
            let mut regime_refactorisations = 0;
            for _ in 0..max_iterations {
                iterations += 1;
                let report = self.newton_iteration(system, at)?;
                last = Some(report);
                match judge.judge(report, &mut self.trajectory.stats) {
                    PassVerdict::Converged => {
                        converged = true;
                        break;
                    }
                    PassVerdict::GiveUp => break,
                    PassVerdict::Continue => {
                        let Some(formed_in) = matrix_regime else {
                            continue;
                        };
                        let now = system.newton_regime(&self.ws.q);
                        if now != formed_in && regime_refactorisations < MAX_REGIME_REFACTORISATIONS
                        {
                            // The iterate left the matrix's regime (a penalty switched on or
                            // off): its slope there is the other side's; refactorise at the
                            // iterate (docs/step-control.md §4).
                            regime_refactorisations += 1;
                            self.trajectory.stats.regime_refactorisations += 1;
                            self.factorise_at_iterate(system, at, full)?;
                            matrix_regime = Some(now);
                            judge = NewtonPass::new(pass);
                        }
                    }
                }
            }
            if converged {
                converged_with_full = full;
                converged_pass = judge;
                break;
            }
        }
        if !converged {
            self.trajectory.stats.newton_iterations += iterations as u64;
            let report =
                last.expect("at least one Newton iteration runs (max_newton_iterations >= 1)");
            return Err(IntegrateError::NewtonNotConverged {
                t: t1,
                step,
                iterations,
                correction_wrms: report.wrms(),
                residual_inf: report.residual_inf,
                worst: report.worst,
            });
        }
        self.conclude_attempt(
            h,
            iterations,
            full_first,
            converged_with_full,
            &converged_pass,
        );
        Ok(Attempt::Converged)
    }

    /// The contraction a matrix factorised at the predictor for a step of `h` (`full`: the full
    /// matrix) may accept its first correction by: `None` when the settings turn that off.
    pub(super) fn carried_contraction(&self, h: f64, full: bool) -> Option<CarriedContraction> {
        if self.settings.accept_by_carried_contraction {
            self.trajectory.newton.carried_contraction(h, full)
        } else {
            None
        }
    }

    /// The bookkeeping of an attempt whose Newton iteration converged after `iterations`
    /// iterations (with the full matrix when `converged_with_full`; `full_first`: the attempt
    /// started with it; `converged_pass`: the pass that converged): counters, the full-matrix hold of
    /// [`NewtonMatrix::Auto`], the factorisation the next step may reuse, and the contraction the
    /// next step's first correction may be judged by.
    pub(super) fn conclude_attempt(
        &mut self,
        h: f64,
        iterations: usize,
        full_first: bool,
        converged_with_full: bool,
        converged_pass: &NewtonPass,
    ) {
        self.trajectory.stats.newton_iterations += iterations as u64;
        if self.settings.newton_matrix == NewtonMatrix::Auto {
            if converged_with_full && !full_first {
                self.trajectory.control.full_newton_hold = FULL_NEWTON_HOLD_STEPS;
            } else {
                self.trajectory.control.full_newton_hold =
                    self.trajectory.control.full_newton_hold.saturating_sub(1);
            }
        }
        self.trajectory.stats.max_iterations_in_a_step = self
            .trajectory
            .stats
            .max_iterations_in_a_step
            .max(iterations);
        // The full matrix lives in its own solver; the diagonal one just used stays for the next step.
        self.trajectory.newton.reusable = !converged_with_full;
        self.trajectory.newton.h = h;
        self.trajectory.newton.rate = converged_pass.slowest;
        // A pass at the predictor that measured a contraction replaces the carried one; one that
        // converged at its first correction keeps it; any other pass (a reused matrix, a refresh,
        // a refactorisation in another regime) drops it.
        if converged_pass.at_predictor {
            if let Some(measured) = converged_pass.measured(h, converged_with_full) {
                self.trajectory.newton.contraction = Some(measured);
            }
        } else {
            self.trajectory.newton.contraction = None;
        }
    }
}
