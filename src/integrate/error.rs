//! Errors of the integrator: one `thiserror` enum with structured variants.
//!
//! Every variant raised while stepping names the time and the step number, so that a failed sample of
//! a study can be reported precisely ("sample 17: Newton did not converge at t = 0.412 s, step 412,
//! worst: constraint row 1").

use std::fmt;

/// An error reported by a [`DaeSystem`](super::DaeSystem) implementation (an invalid state, a NaN in
/// its own computations, a method it does not provide, …). Boxed so that a robot model can return its
/// own error type with `?`; it is only allocated on the error path.
pub type SystemError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Which unknown of the Newton system stopped convergence (the entry with the largest weighted
/// correction in the last iteration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WorstEntry {
    /// A velocity coordinate (index into `v`, `0..nv`): its position-level correction `β'h² Δq̈_i`,
    /// multiplied by its error weight, was the largest.
    Coordinate {
        /// Velocity-coordinate index, `0..nv`.
        index: usize,
        /// `|β'h² Δq̈_i| · ewt_i` (converged entries are < 1).
        weighted_correction: f64,
    },
    /// A constraint row (index into `Φ`, `0..n_constraints`): its multiplier correction `Δλ_j`,
    /// multiplied by its error weight, was the largest.
    Constraint {
        /// Constraint-row index, `0..n_constraints`.
        index: usize,
        /// `|Δλ_j| · ewt_j` (converged entries are < 1).
        weighted_correction: f64,
        /// `Φ_j` at the last iterate (m or rad, as the row is written).
        violation: f64,
    },
}

impl fmt::Display for WorstEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorstEntry::Coordinate {
                index,
                weighted_correction,
            } => write!(
                f,
                "velocity coordinate {index} (weighted correction {weighted_correction:.3e})"
            ),
            WorstEntry::Constraint {
                index,
                weighted_correction,
                violation,
            } => write!(
                f,
                "constraint row {index} (weighted multiplier correction {weighted_correction:.3e}, \
                 Φ = {violation:.3e})"
            ),
        }
    }
}

/// Everything that can go wrong in `integrate`: invalid settings, inconsistent dimensions, an initial
/// state that cannot be made consistent, a failed Newton iteration, non-finite numbers, or an error
/// reported by the system itself.
#[derive(Debug, thiserror::Error)]
pub enum IntegrateError {
    /// `alpha` is outside `[-1/3, 0]` (or not finite).
    #[error("HHT alpha = {alpha} is outside [-1/3, 0]")]
    InvalidAlpha {
        /// The rejected value.
        alpha: f64,
    },
    /// `alpha = 0` was requested for a system with constraint rows: the trapezoidal member of the
    /// family does not converge in `q̈` and `λ` on index-3 problems (docs/method.md §5).
    #[error(
        "HHT alpha = 0 is refused with {n_constraints} constraint row(s): accelerations and \
         multipliers do not converge (they oscillate with growing amplitude); use alpha ≤ -0.05, e.g. -0.1"
    )]
    AlphaZeroWithConstraints {
        /// Number of constraint rows of the system.
        n_constraints: usize,
    },
    /// `alpha` is in `(limit, 0)` for a system with constraint rows: the start transient of `q̈` and
    /// `λ` is barely damped and the multipliers come out wrong (see
    /// [`ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`](super::settings::ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS)).
    #[error(
        "HHT alpha = {alpha} is too close to 0 with {n_constraints} constraint row(s): it must be at \
         most {limit}, because closer to 0 the start transient of the accelerations and multipliers \
         is barely damped and constraint forces come out wrong by up to ten times their size; use \
         alpha in [-1/3, {limit}], e.g. -0.1"
    )]
    AlphaTooCloseToZero {
        /// The rejected value.
        alpha: f64,
        /// The largest accepted value (`−ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`).
        limit: f64,
        /// Number of constraint rows of the system.
        n_constraints: usize,
    },
    /// The step `h` is not a finite positive number.
    #[error("step h = {step_s} s must be finite and > 0")]
    InvalidStep {
        /// The rejected value, s.
        step_s: f64,
    },
    /// A tolerance or iteration limit of [`HhtSettings`](super::HhtSettings) is invalid.
    #[error("setting `{name}` = {value} is invalid: {reason}")]
    InvalidSetting {
        /// Field name in `HhtSettings`.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// One grid step needed more sub-step attempts than [`MAX_ATTEMPTS_PER_STEP`](super::MAX_ATTEMPTS_PER_STEP)
    /// (adaptive sub-steps, retries, impacts): the motion is far faster than the step, or a Zeno
    /// sequence of impacts. Also the bound on the work between two interruption checks.
    #[error(
        "the step to t = {} s (step {step}) needed more than {attempts} sub-step attempts \
         (smallest sub-step {smallest_s:.3e} s): the motion is far faster than the step of the \
         scene; use a smaller step or a looser tolerance, or check the stiffness and the limits",
        crate::text::message_time(*.t)
    )]
    TooManySubsteps {
        /// Time of the grid step, s.
        t: f64,
        /// Grid step number.
        step: u64,
        /// The attempts made.
        attempts: u64,
        /// The smallest sub-step accepted so far, s.
        smallest_s: f64,
    },
    /// An argument or a system output has the wrong size.
    #[error("dimension mismatch for {what}: expected {expected}, got {got}")]
    DimensionMismatch {
        /// Which vector or matrix.
        what: &'static str,
        /// Expected size.
        expected: usize,
        /// Actual size.
        got: usize,
    },
    /// The system reported an error from one of its methods.
    #[error("system error in `{call}` at t = {} s (step {step}): {source}", crate::text::message_time(*.t))]
    System {
        /// Time at which the system was evaluated, s.
        t: f64,
        /// Step number being computed (0 = consistent start).
        step: u64,
        /// Name of the trait method that failed.
        call: &'static str,
        /// The system's own error.
        source: SystemError,
    },
    /// A NaN or infinity appeared in a quantity (system output, initial state or Newton update).
    #[error("non-finite value in {quantity}[{index}] at t = {} s (step {step})", crate::text::message_time(*.t))]
    NonFinite {
        /// Time, s.
        t: f64,
        /// Step number being computed (0 = consistent start).
        step: u64,
        /// Which quantity (`"forces"`, `"mass_matrix"`, `"newton_update"`, …).
        quantity: &'static str,
        /// Index of the first non-finite entry (column-major for a matrix).
        index: usize,
    },
    /// A linear system was singular to working precision (a pivot below
    /// `SINGULAR_PIVOT_RELATIVE` times the matrix's largest entry; for a Cholesky factorisation its
    /// largest diagonal entry, the same for a positive semi-definite matrix).
    #[error(
        "singular {matrix} at t = {} s (step {step}): pivot {index} is {pivot_relative:.3e} of the \
         largest entry (M not positive definite, or constraint rows dependent?)",
        crate::text::message_time(*.t)
    )]
    SingularMatrix {
        /// Time, s.
        t: f64,
        /// Step number being computed (0 = consistent start).
        step: u64,
        /// Which matrix (`"Newton iteration matrix"`, `"velocity projection matrix"`, …).
        matrix: &'static str,
        /// Row at which elimination broke down.
        index: usize,
        /// |pivot| / max |entry|.
        pivot_relative: f64,
    },
    /// The constraint Jacobian `Φ_q` is rank deficient: some rows are redundant (a loop declared with
    /// more rows than it really constrains, or a singular configuration).
    #[error(
        "redundant constraint rows at t = {} s: smallest singular value of Φ_q is {smallest:.3e} vs \
         largest {largest:.3e} (relative tolerance {tolerance:.1e}); row {row} contributes most to the \
         dependent combination",
        crate::text::message_time(*.t)
    )]
    RedundantConstraints {
        /// Time, s.
        t: f64,
        /// Smallest singular value of `Φ_q`.
        smallest: f64,
        /// Largest singular value of `Φ_q`.
        largest: f64,
        /// Relative tolerance below which rows count as dependent.
        tolerance: f64,
        /// The row with the largest weight in the left singular vector of the smallest singular value.
        row: usize,
    },
    /// The initial positions cannot be projected onto `Φ(q, t0) = 0` ("the loop cannot close").
    #[error(
        "cannot close the constraints at t = {} s: |Φ| = {violation:.3e} after {iterations} \
         Gauss–Newton iterations (worst row {worst_row}; tolerance {tolerance:.1e})",
        crate::text::message_time(*.t)
    )]
    CannotClose {
        /// Initial time, s.
        t: f64,
        /// Gauss–Newton iterations performed.
        iterations: usize,
        /// max |Φ_j| at the last iterate.
        violation: f64,
        /// Row with the largest |Φ_j|.
        worst_row: usize,
        /// The tolerance that was not reached.
        tolerance: f64,
    },
    /// Newton did not converge within `max_newton_iterations`, even after refreshing the iteration
    /// matrix at the current iterate.
    #[error(
        "Newton did not converge at t = {} s (step {step}) after {iterations} iterations and one \
         matrix refresh: correction WRMS {correction_wrms:.3e} (needs < 1), residual max-norm \
         {residual_inf:.3e}; worst: {worst}",
        crate::text::message_time(*.t)
    )]
    NewtonNotConverged {
        /// The time the step was advancing to, s.
        t: f64,
        /// Step number (1-based).
        step: u64,
        /// Iterations performed in total (both passes).
        iterations: usize,
        /// Largest of the position and multiplier WRMS norms of the last correction.
        correction_wrms: f64,
        /// max-norm of the last evaluated residual `[M q̈ + Φ_qᵀλ − Q; Φ/(β'h²)]`.
        residual_inf: f64,
        /// The entry that stopped convergence.
        worst: WorstEntry,
    },
}

impl IntegrateError {
    /// The same error, with the step it names set to `step` where it names one: a consistent start
    /// made in the middle of a run (the restart after a joint-limit impact) reports its failures
    /// at step 0, as a run's start does; the run's own step tells a failure that happens later
    /// (exit 1, "the run failed at t") from an initial state that cannot start (exit 2).
    pub fn at_step(mut self, step: u64) -> Self {
        match &mut self {
            IntegrateError::TooManySubsteps { step: s, .. }
            | IntegrateError::System { step: s, .. }
            | IntegrateError::NonFinite { step: s, .. }
            | IntegrateError::SingularMatrix { step: s, .. }
            | IntegrateError::NewtonNotConverged { step: s, .. } => *s = step,
            _ => {}
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_step_relabels_only_errors_that_name_a_step() {
        let singular = IntegrateError::SingularMatrix {
            t: 0.45,
            step: 0,
            matrix: "mass matrix (initial acceleration)",
            index: 2,
            pivot_relative: 1e-14,
        }
        .at_step(458);
        assert!(matches!(
            singular,
            IntegrateError::SingularMatrix { step: 458, .. }
        ));
        assert!(singular.to_string().contains("(step 458)"), "{singular}");
        let step = IntegrateError::InvalidStep { step_s: -1.0 }.at_step(3);
        assert!(matches!(step, IntegrateError::InvalidStep { .. }));
    }
}
