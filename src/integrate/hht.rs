//! The HHT-I3 stepper: [`HhtIntegrator`] (docs/method.md §5, second-order form of Arnold & Brüls 2007 with
//! `α_m = 0`, `α_f = −α`).
//!
//! One step, as data flow:
//!
//! ```text
//! (t_n, q_n, q̇_n, a_n, q̈_n, λ_n) => predictor (hht/predictor.rs): on a run of equal steps q̈ and
//!      λ by orders 0–4 blended per entry by their last misses; else q̈ through q̈_{n−1} (and
//!      q̈_{n−2} where smooth), λ linearly                                (docs/step-control.md §2)
//!   => without constraint rows: iterate with the trajectory's stored factorisation if the last
//!      step contracted fast (ρ ≤ NEWTON_REUSE_MAX_RATE) at the same h; slower drops it at once
//!   => else factorise the iteration matrix at the predicted (q, q̇)     (modified Newton)
//!   => iterate: residual at (q(q̈), q̇(q̈)), solve, correct, the pass's tests (newton_pass.rs:
//!      WRMS < 1, the contraction estimate, the first correction by the last step's ρ)
//!                                                                       (≤ max_newton_iterations)
//!   => not converged: refactorise at the current iterate, iterate again; then fail loudly
//!   => (q_{n+1}, q̇_{n+1}, a_{n+1}, q̈_{n+1}, λ_{n+1})
//!   => with constraint rows: record |Φ| and |Φ_q q̇ + Φ_t|; project q̇ if enabled
//! ```
//!
//! Every buffer lives in a workspace sized at construction: a step allocates nothing. `plain.rs`
//! drives the same step from outside, one mass matrix and one residual at a time, for the batched
//! step of many samples (docs/batch.md §5); both go through the functions below.
//!
//! The files, in the order of a step:
//!
//! | file | concept |
//! | --- | --- |
//! | `hht.rs` (this one) | the integrator: construction, (re)start, the carried trajectory, accessors |
//! | `state.rs` | what a trajectory carries: state, history, statistics, step control, Newton memory |
//! | `stats.rs` | the statistics: counters and constraint drift |
//! | `workspace.rs` | the preallocated buffers of one step |
//! | `step_size.rs` | driving one grid step: attempts, the adaptive controller, acceptance |
//! | `events.rs` | unilateral limits: locating a crossing, the impact and the restart after it |
//! | `newmark.rs` | the predictor of an attempt and the Newmark update of an iterate |
//! | `newton.rs` | one attempt's Newton passes and the factorisation a trajectory carries |
//! | `newton_pass.rs` | one pass's convergence tests |
//! | `newton_matrix.rs` | the iteration matrix: its assembly and factorisation at an iterate |
//! | `newton_iteration.rs` | one Newton iteration: residual, solve, weighted correction |
//! | `projection.rs` | after a constrained step: the drift's bookkeeping and the velocity projection |
//! | `predictor.rs` | the accepted history the predictor extrapolates through |
//! | `plain.rs` | a plain grid step driven from outside (the batched step) |

use nalgebra::DVector;

use super::error::IntegrateError;
use super::eval::{self, At};
use super::settings::{HhtCoefficients, HhtSettings};
use super::start::{consistent_start, ConsistentStart};
use super::system::DaeSystem;

mod events;
mod newmark;
mod newton;
mod newton_iteration;
mod newton_matrix;
mod newton_pass;
mod plain;
mod predictor;
mod projection;
mod state;
mod stats;
mod step_size;
mod workspace;

pub use events::{IMPACT_LOCATE_FRACTION, IMPACT_MIN_SPEED};
pub use newmark::PREDICTOR_MAX_ACCELERATION_DISPLACEMENT;
use newton::NewtonMemory;
pub(crate) use newton_matrix::assemble_iteration_matrix;
pub use newton_matrix::{iteration_matrix, ConstraintRowScaling};
pub use newton_pass::{CARRIED_RATE_FLOOR, CARRIED_RATE_SAFETY, RATE_TEST_MAX_CONTRACTION};
pub(crate) use plain::{PlainProgress, PlainStep};
pub use predictor::{PredictorHistory, PREDICTOR_CURVATURE_MAX_STEP_RATIO, PREDICTOR_MAX_ORDER};
pub use state::{HhtState, HhtTrajectory, ReportedVelocity};
pub use stats::HhtStats;
pub use step_size::{StepControlState, MAX_ATTEMPTS_PER_STEP};
use workspace::Workspace;

/// The HHT-I3 integrator of one trajectory (docs/method.md §5) over a [`DaeSystem`]: its settings,
/// the step coefficients, the Newton workspaces and the carried [`HhtTrajectory`]; [`HhtIntegrator::step`]
/// advances it by one grid step.
///
/// ```text
/// M(q_{n+1}) q̈_{n+1} + Φ_q(q_{n+1})ᵀ λ_{n+1} = Q(q_{n+1}, q̇_{n+1}, t_{n+1}),  Φ(q_{n+1}, t_{n+1}) = 0
/// a_{n+1} = (1+α) q̈_{n+1} − α q̈_n                                            (a_0 = q̈_0)
/// q_{n+1} = q_n ⊕ (h q̇_n + h² [(½ − β) a_n + β a_{n+1}])
/// q̇_{n+1} = q̇_n + h [(1 − γ) a_n + γ a_{n+1}]
/// ```
///
/// The system is passed to each call rather than owned, so that a study can keep its per-sample
/// models where it likes; it must be the same system (same dimensions, checked) on every call.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use ribbon::integrate::{DaeSystem, HhtIntegrator, HhtSettings, SystemError};
///
/// /// A unit mass on a spring of stiffness 4 N/m: q̈ = −4 q.
/// struct Spring;
/// impl DaeSystem for Spring {
///     fn nq(&self) -> usize { 1 }
///     fn nv(&self) -> usize { 1 }
///     fn mass_matrix(&mut self, _t: f64, _q: &DVector<f64>, out: &mut DMatrix<f64>)
///         -> Result<(), SystemError> { out[(0, 0)] = 1.0; Ok(()) }
///     fn forces(&mut self, _t: f64, q: &DVector<f64>, _v: &DVector<f64>, out: &mut DVector<f64>)
///         -> Result<(), SystemError> { out[0] = -4.0 * q[0]; Ok(()) }
/// }
///
/// let mut sys = Spring;
/// let q0 = DVector::from_element(1, 1.0);
/// let v0 = DVector::zeros(1);
/// let mut hht = HhtIntegrator::new(&mut sys, HhtSettings::default(), 0.0, &q0, &v0).unwrap();
/// for _ in 0..1000 {
///     hht.step(&mut sys).unwrap();
/// }
/// let exact = (2.0_f64 * 1.0).cos();
/// assert!((hht.state().q[0] - exact).abs() < 1e-5);
/// ```
#[derive(Debug, Clone)]
pub struct HhtIntegrator {
    settings: HhtSettings,
    /// Coefficients of the step being attempted (the grid step's unless sub-stepping).
    coeffs: HhtCoefficients,
    /// Coefficients of the grid step `h`.
    grid_coeffs: HhtCoefficients,
    nq: usize,
    nv: usize,
    m: usize,
    n_events: usize,
    /// The carried trajectory: everything that goes from step to step of one sample (swapped whole
    /// by [`HhtIntegrator::swap_trajectory`]).
    trajectory: HhtTrajectory,
    /// Feed the projected velocity back into the recursion (the textbook post-step projection).
    /// Test-only: it makes q̈ and λ first order (tests.rs pins it).
    projection_feedback: bool,
    /// Whether the step in progress computes its reported velocity ([`ReportedVelocity`]); `true`
    /// outside [`HhtIntegrator::advance`] and a plain step's acceptance.
    report_velocity: bool,
    ws: Workspace,
    /// The statistics before the plain step in progress (hht/plain.rs), to put back when it is
    /// abandoned; kept here rather than in the `PlainStep` its caller moves around.
    plain_stats_before: HhtStats,
}

impl HhtIntegrator {
    /// Validates `settings` for `system`, computes the consistent start from `(t0, q0, v0)` and
    /// allocates the workspace.
    ///
    /// - `t0`: s; `q0`: dim `nq`; `v0`: dim `nv` (both projected onto the constraints).
    ///
    /// Errors: settings errors (see [`HhtSettings::validate`]) and consistent-start errors (see
    /// [`consistent_start`]).
    pub fn new<S: DaeSystem + ?Sized>(
        system: &mut S,
        settings: HhtSettings,
        t0: f64,
        q0: &DVector<f64>,
        v0: &DVector<f64>,
    ) -> Result<Self, IntegrateError> {
        let (nq, nv, m) = (system.nq(), system.nv(), eval::n_constraints(system));
        let n_events = eval::n_events(system);
        let coeffs = settings.validate(m)?;
        let mut integrator = Self {
            settings,
            coeffs,
            grid_coeffs: coeffs,
            nq,
            nv,
            m,
            n_events,
            trajectory: HhtTrajectory {
                t0,
                state: HhtState {
                    t: t0,
                    step: 0,
                    q: DVector::zeros(nq),
                    v: DVector::zeros(nv),
                    a: DVector::zeros(nv),
                    qdd: DVector::zeros(nv),
                    lambda: DVector::zeros(m),
                },
                v_newmark: DVector::zeros(nv),
                predictor: PredictorHistory::new(nv, m),
                stats: HhtStats::default(),
                control: StepControlState::new(coeffs.h),
                newton: NewtonMemory::new(nv, m),
            },
            projection_feedback: false,
            plain_stats_before: HhtStats::default(),
            report_velocity: true,
            ws: Workspace::new(nq, nv, m, n_events),
        };
        integrator.restart(system, t0, q0, v0)?;
        Ok(integrator)
    }

    /// Starts a new trajectory from `(t0, q0, v0)` reusing the workspace (e.g. the next sample of a
    /// study with the same dimensions). Resets the statistics.
    ///
    /// - `t0`: s; `q0`: dim `nq`; `v0`: dim `nv`.
    pub fn restart<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t0: f64,
        q0: &DVector<f64>,
        v0: &DVector<f64>,
    ) -> Result<(), IntegrateError> {
        eval::check_dimensions(system, self.nq, self.nv, self.m)?;
        let start: ConsistentStart = consistent_start(system, t0, q0, v0)?;
        self.trajectory.t0 = t0;
        self.trajectory.state.t = t0;
        self.trajectory.state.step = 0;
        self.trajectory.state.q.copy_from(&start.q);
        self.trajectory.state.v.copy_from(&start.v);
        self.trajectory.v_newmark.copy_from(&start.v);
        self.trajectory.predictor.clear();
        self.trajectory.newton.forget();
        self.trajectory.state.qdd.copy_from(&start.qdd);
        self.trajectory.state.a.copy_from(&start.qdd);
        self.trajectory.state.lambda.copy_from(&start.lambda);
        self.trajectory.control = StepControlState::new(self.grid_coeffs.h);
        self.coeffs = self.grid_coeffs;
        self.trajectory.stats = HhtStats {
            start_projection_iterations: start.projection_iterations,
            max_constraint_violation: start.final_violation,
            ..HhtStats::default()
        };
        if self.m > 0 {
            let at = At { t: t0, step: 0 };
            let violation = self.velocity_violation(system, at)?;
            self.trajectory.stats.max_velocity_violation = violation;
            self.trajectory.stats.max_velocity_violation_unprojected = violation;
        }
        Ok(())
    }

    /// A copy of the trajectory this integrator carries.
    pub fn trajectory(&self) -> HhtTrajectory {
        self.trajectory.clone()
    }

    /// Exchanges the carried trajectory with `other` (same dimensions): the integrator continues
    /// `other`'s trajectory and `other` keeps the one it had. No allocation; the workspace's cached
    /// matrices are marked stale.
    pub fn swap_trajectory(&mut self, other: &mut HhtTrajectory) -> Result<(), IntegrateError> {
        let checks = [
            ("trajectory q", self.nq, other.state.q.len()),
            ("trajectory v", self.nv, other.state.v.len()),
            ("trajectory lambda", self.m, other.state.lambda.len()),
            (
                "trajectory Newmark velocity",
                self.nv,
                other.v_newmark.len(),
            ),
        ];
        let newton_size = (
            "trajectory Newton factorisation",
            self.nv + self.m,
            other.newton.solver.dimension(),
        );
        for (what, expected, got) in checks.into_iter().chain([newton_size]) {
            if expected != got {
                return Err(IntegrateError::DimensionMismatch {
                    what,
                    expected,
                    got,
                });
            }
        }
        std::mem::swap(&mut self.trajectory, other);
        self.ws.mass_fresh = false;
        self.ws.constraints_fresh = false;
        Ok(())
    }

    /// The current state.
    pub fn state(&self) -> &HhtState {
        &self.trajectory.state
    }

    /// The Newmark velocity the recursion carries, dim `nv`: equal to `state().v` unless the
    /// reported velocity was projected (see [`HhtSettings::velocity_projection`]). Read only; the
    /// forward sensitivities ([`HhtSensitivity`](super::HhtSensitivity)) differentiate this one.
    pub fn newmark_velocity(&self) -> &DVector<f64> {
        &self.trajectory.v_newmark
    }

    /// Statistics since the last (re)start.
    pub fn stats(&self) -> &HhtStats {
        &self.trajectory.stats
    }

    /// The validated settings.
    pub fn settings(&self) -> &HhtSettings {
        &self.settings
    }

    /// The derived coefficients (`γ`, `β`, `β'`, `γ'`) of the grid step `h`.
    pub fn coefficients(&self) -> &HhtCoefficients {
        &self.grid_coeffs
    }

    /// The step control's carried state (next and last sub-step, full-matrix hold, whether the last
    /// grid step was plain).
    pub fn control(&self) -> &StepControlState {
        &self.trajectory.control
    }

    /// Advances to the next grid time `t_{n+1} = t0 + (n+1) h` (computed from the step count, so
    /// time does not drift). On error the state is left at the last accepted sub-step (at `t_n`
    /// unless the interval was subdivided).
    ///
    /// With [`StepControl::Fixed`](crate::integrate::StepControl::Fixed) this is one HHT step of `h`, and a Newton failure is reported as
    /// it is. With [`StepControl::Adaptive`](crate::integrate::StepControl::Adaptive) the grid interval is covered by sub-steps that follow
    /// the local error estimate, and a failed sub-step is retried with half its size (down to
    /// `h / 2^`[`HhtSettings::max_step_halvings`]). In both, a crossing of a unilateral limit ([`UnilateralLimits::n_events`](crate::integrate::UnilateralLimits::n_events)) is located
    /// and the system's impact law applied, after which the trajectory restarts from a consistent
    /// state (docs/step-control.md §3–§4). Every sub-step uses the coefficients of its own size.
    ///
    /// Errors: [`IntegrateError::NewtonNotConverged`] (fixed step: the failure; adaptive: the first
    /// failure, when even the smallest sub-step failed), [`IntegrateError::SingularMatrix`], [`IntegrateError::NonFinite`],
    /// [`IntegrateError::System`], [`IntegrateError::DimensionMismatch`]. Allocation-free on success
    /// (an impact allocates in the consistent start).
    pub fn step<S: DaeSystem + ?Sized>(&mut self, system: &mut S) -> Result<(), IntegrateError> {
        self.advance(system, ReportedVelocity::Computed)
    }

    /// [`HhtIntegrator::step`], computing the reported velocity or leaving it out (`report`): a
    /// study steps with [`ReportedVelocity::Skipped`] between its record times and with
    /// [`ReportedVelocity::Computed`] into each, which gives every record the bits of `step` at a
    /// fraction of the cost with constraint rows (the velocity projection is a third of the
    /// panda's step; docs/method.md §5, "Velocity drift"). A system with unilateral events
    /// ([`UnilateralLimits::n_events`](crate::integrate::UnilateralLimits::n_events)) always computes it: locating an impact reads the step's start
    /// velocity.
    pub fn advance<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        report: ReportedVelocity,
    ) -> Result<(), IntegrateError> {
        self.report_velocity = report == ReportedVelocity::Computed || self.n_events > 0;
        let result = self.advance_grid_step(system);
        self.report_velocity = true;
        result
    }
}
