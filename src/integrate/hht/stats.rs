//! The statistics of one trajectory ([`HhtStats`]): counters of steps, attempts, Newton work and
//! impacts, and the constraint drift, since the last (re)start. Every stage of a step adds to them;
//! they decide nothing.

/// Counters and constraint drift since the last (re)start.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HhtStats {
    /// Accepted steps.
    pub steps: u64,
    /// Adaptive sub-steps rejected by the system's state check
    /// ([`DaeSystem::state_rejection`](crate::integrate::DaeSystem::state_rejection): a contact deeper than allowed) and retried at half size.
    pub state_rejections: u64,
    /// Newton iterations (residual evaluations + solves), all passes.
    pub newton_iterations: u64,
    /// Factorisations of the Newton iteration matrix (at most one per step while the stored one is
    /// reused, see [`HhtSettings::reuse_newton_matrix`](crate::integrate::HhtSettings::reuse_newton_matrix); plus refreshes).
    pub factorisations: u64,
    /// Steps whose first Newton pass failed and that refreshed the matrix.
    pub refreshes: u64,
    /// Factorisations of `[M Φ_qᵀ; Φ_q 0]` for the velocity projection (of its rows only when it
    /// keeps the Newton matrix's `M`).
    pub projection_factorisations: u64,
    /// Steps accepted with the multiplier correction at its rounding floor (positions converged, `Δλ`
    /// stagnating above the multiplier tolerance; see `LAMBDA_STAGNATION_RATIO`). Non-zero means the
    /// multiplier tolerance is tighter than `Φ`'s rounding allows at this step size.
    pub rounding_limited_steps: u64,
    /// Most Newton iterations any single step needed.
    pub max_iterations_in_a_step: usize,
    /// Gauss–Newton iterations of the consistent start.
    pub start_projection_iterations: usize,
    /// Largest `max_j |Φ_j|` over the start and every accepted step that computed its reported
    /// velocity (all of them unless stepped with [`ReportedVelocity::Skipped`](crate::integrate::ReportedVelocity::Skipped)) (m or rad).
    pub max_constraint_violation: f64,
    /// Largest `max_j |Φ_q q̇ + Φ_t|_j` of the state returned (after projection when enabled), over
    /// the same steps.
    pub max_velocity_violation: f64,
    /// Largest `max_j |Φ_q q̇ + Φ_t|_j` before the velocity projection (the drift plain I3 would
    /// have), over the same steps.
    pub max_velocity_violation_unprojected: f64,
    /// Accepted integration steps, sub-steps included (equals `steps` when no grid interval was
    /// subdivided).
    pub substeps: u64,
    /// Step attempts whose Newton iteration failed and that were retried with half the step.
    pub step_failures: u64,
    /// Sub-steps rejected by the local error estimate ([`StepControl::Adaptive`](crate::integrate::StepControl::Adaptive)).
    pub error_rejections: u64,
    /// Sub-steps accepted at the smallest step with the error estimate still over the tolerance.
    pub error_limited_steps: u64,
    /// Impacts with unilateral limits ([`UnilateralLimits::apply_impact`](crate::integrate::UnilateralLimits::apply_impact)).
    pub impacts: u64,
    /// Factorisations of the full Newton matrix `M + β'h² K_t + γ'h D_t`.
    pub full_factorisations: u64,
    /// Smallest accepted sub-step, s (0 before the first step).
    pub smallest_step_s: f64,
    /// Largest error measure of an accepted sub-step ([`StepControl::Adaptive`](crate::integrate::StepControl::Adaptive); accepted when ≤ 1,
    /// i.e. the estimated local position error over [`HhtSettings::tolerance`](crate::integrate::HhtSettings::tolerance)).
    pub max_error_estimate: f64,
    /// Attempts that used the constant-velocity predictor (an unresolved stiff mode, see
    /// [`PREDICTOR_MAX_ACCELERATION_DISPLACEMENT`](crate::integrate::PREDICTOR_MAX_ACCELERATION_DISPLACEMENT)).
    pub stiff_predictions: u64,
    /// Newton iterations that applied only part of their correction
    /// ([`NewtonUpdateLimit::newton_update_fraction`](crate::integrate::NewtonUpdateLimit::newton_update_fraction) < 1: an iterate kept from jumping across a
    /// regularised law's narrow transition).
    pub limited_newton_updates: u64,
    /// Factorisations made because a Newton iterate left the regime of piecewise forces its
    /// matrix was formed in ([`DaeSystem::newton_regime`](crate::integrate::DaeSystem::newton_regime): a joint-limit penalty switching on or
    /// off; also counted in `factorisations`).
    pub regime_refactorisations: u64,
    /// Steps accepted after their first Newton correction by the contraction the previous step
    /// measured ([`HhtSettings::accept_by_carried_contraction`](crate::integrate::HhtSettings::accept_by_carried_contraction); docs/step-control.md §2,
    /// "Accepting the first correction").
    pub carried_rate_acceptances: u64,
}
