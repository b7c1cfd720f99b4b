//! HHT-I3 time integration of index-3 multibody DAEs (docs/method.md §5).
//!
//! ```text
//! M(q) q̈ + Φ_q(q, t)ᵀ λ = Q(t, q, q̇),      Φ(q, t) = 0
//! ```
//!
//! What it does: the second-order form of the HHT method (Arnold & Brüls 2007, generalized-α with
//! `α_m = 0`, `α_f = −α`), modified Newton on `(q̈_{n+1}, λ_{n+1})` with constraint rows scaled by
//! `1/(β'h²)` and the diagonal spring/damper terms in the iteration matrix, a consistent start
//! (positions, velocities, accelerations and multipliers), an optional post-step velocity projection,
//! NaN/Inf detection where numbers arise, and statistics (Newton iterations, factorisations,
//! constraint drift). It works on any system implementing the narrow trait [`DaeSystem`]; it knows
//! nothing about robots.
//!
//! Step control (docs/step-control.md): the Newton matrix is the cheap diagonal one (`M`, `Φ_q`,
//! the effects' diagonal terms) until it fails, then the full `M + β'h² K_t + γ'h D_t`
//! ([`NewtonMatrix`]); a failed step is retried as halves; [`StepControl::Adaptive`] sub-steps each
//! grid interval by a local error estimate; crossings of unilateral limits (joint limits) are
//! located and the system's impact law applied. Every call of [`HhtIntegrator::step`] still ends on
//! the grid `t0 + n h`.
//!
//! What it does not do (yet): the perturbed starting value of Arnold & Brüls for second-order multipliers from the very first
//! steps (`a_0 = q̈_0` here: `λ` and `q̈` carry an O(h) transient that the numerical damping removes
//! within a few dozen steps).
//!
//! Forward sensitivities of a trajectory with respect to the system's parameters, by direct
//! differentiation of the converged step, run beside the integrator: [`HhtSensitivity`]
//! (docs/sensitivities.md).
//!
//! Read order: [`DaeSystem`] (the contract), [`HhtSettings`], [`HhtIntegrator`], [`consistent_start`],
//! [`IntegrateError`], [`HhtSensitivity`].
//!
//! Why not the form printed by Negrut et al. (and Chrono's `ChTimestepperHHT`): its accelerations
//! represent `t_{n+1+α}`, which `γ = ½ − α` compensates only when `M` is constant; in joint
//! coordinates it is first order. The scalar test system `(2 + cos q) q̈ = −3 sin q + ½ sin q q̇²` in
//! `tests.rs` pins the difference (error ratio 4 per halving here, 2 there).

mod dense_solver;
mod error;
mod eval;
mod hht;
mod sensitivity;
mod settings;
mod start;
mod system;

#[cfg(test)]
pub(crate) mod tests;

pub use dense_solver::SINGULAR_PIVOT_RELATIVE;
pub(crate) use dense_solver::{DenseSolver, FactorKind};
pub use error::{IntegrateError, SystemError, WorstEntry};
pub use hht::{
    iteration_matrix, ConstraintRowScaling, HhtIntegrator, HhtState, HhtStats, HhtTrajectory,
    PredictorHistory, ReportedVelocity, StepControlState, CARRIED_RATE_FLOOR, CARRIED_RATE_SAFETY,
    IMPACT_LOCATE_FRACTION, IMPACT_MIN_SPEED, MAX_ATTEMPTS_PER_STEP,
    PREDICTOR_CURVATURE_MAX_STEP_RATIO, PREDICTOR_MAX_ACCELERATION_DISPLACEMENT,
    PREDICTOR_MAX_ORDER, RATE_TEST_MAX_CONTRACTION,
};
pub(crate) use hht::{PlainProgress, PlainStep};
pub use sensitivity::{
    HhtSensitivity, SensitivityError, SensitivityStats, JACOBIAN_FD_STEP, PROJECTION_FD_STEP,
};
pub use settings::{
    check_alpha, AlphaRefusal, HhtCoefficients, HhtSettings, NewtonMatrix, StepControl, ALPHA_MIN,
    ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS, DEFAULT_STEP_HALVINGS, DEFAULT_STEP_TOLERANCE,
    FULL_NEWTON_HOLD_STEPS, MAX_STEP_HALVINGS, NEWTON_REUSE_MAX_RATE,
};
pub use start::{
    consistent_start, ConsistentStart, REDUNDANT_ROW_RELATIVE_SV, START_CONSTRAINT_TOL,
    START_MAX_ITERATIONS,
};
pub use system::PARAMETER_FD_STEP;
pub use system::{
    Constraints, CoordinateMagnitude, DaeState, DaeSystem, InverseDynamics, NewtonCoupling,
    NewtonDiagonal, NewtonUpdateLimit, Parameters, PositionGroup, PositionScale, ResidualJacobians,
    UnilateralLimits,
};
