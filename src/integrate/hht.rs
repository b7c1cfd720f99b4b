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

use nalgebra::{DMatrix, DVector};

use super::dense_solver::{assemble_constraint_blocks, DenseSolver, FactorKind};
use super::error::{IntegrateError, WorstEntry};
use super::eval::{self, At};
use super::settings::{
    HhtCoefficients, HhtSettings, NewtonMatrix, StepControl, FULL_NEWTON_HOLD_STEPS,
    NEWTON_REUSE_MAX_RATE,
};
use super::start::{consistent_start, ConsistentStart};
use super::system::DaeSystem;

mod newton_pass;
mod plain;
mod predictor;
use newton_pass::{
    CarriedContraction, IterationReport, MeasuredContraction, NewtonPass, PassVerdict,
};
pub use newton_pass::{CARRIED_RATE_FLOOR, CARRIED_RATE_SAFETY, RATE_TEST_MAX_CONTRACTION};
pub(crate) use plain::{PlainProgress, PlainStep};
pub use predictor::{PredictorHistory, PREDICTOR_CURVATURE_MAX_STEP_RATIO, PREDICTOR_MAX_ORDER};

/// The integrator's state at time `t` (all vectors in the system's coordinates).
#[derive(Debug, Clone, PartialEq)]
pub struct HhtState {
    /// Time, s.
    pub t: f64,
    /// Number of steps taken since the start (0 at the consistent start).
    pub step: u64,
    /// Positions, dim `nq`.
    pub q: DVector<f64>,
    /// Velocities, dim `nv`. With constraint rows and `velocity_projection` on, this is the projected
    /// velocity (`Φ_q q̇ + Φ_t = 0` to rounding); the integrator's own recursion keeps the unprojected
    /// Newmark velocity (see [`HhtSettings::velocity_projection`]). After a step that left the
    /// reported velocity out ([`ReportedVelocity::Skipped`]) it is the Newmark velocity until the
    /// next step that computes it.
    pub v: DVector<f64>,
    /// Acceleration-like variable `a` of the generalized-α scheme, dim `nv` (`a_0 = q̈_0`,
    /// `a_{n+1} = (1 + α) q̈_{n+1} − α q̈_n`). Not a physical acceleration: report `qdd`.
    pub a: DVector<f64>,
    /// True accelerations `q̈` satisfying the equations of motion at `t`, dim `nv`.
    pub qdd: DVector<f64>,
    /// Constraint multipliers `λ`, dim `m` (sign: `M q̈ + Φ_qᵀ λ = Q`; a drive's effort is `−λ`).
    pub lambda: DVector<f64>,
}

/// Whether a grid step computes the velocity it reports ([`HhtIntegrator::advance`]). Only systems
/// with constraint rows and no unilateral events tell the two apart: there the reported velocity
/// (`HhtState::v`) is the Newmark velocity projected onto `Φ_q q̇ + Φ_t = 0`, a product of the step
/// that the recursion never reads (docs/method.md §5, "Velocity drift"), and so is the end-of-step
/// bookkeeping of the drift (`Φ` and `Φ_q` at `q_{n+1}`, [`HhtStats::max_constraint_violation`] and
/// the velocity drifts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportedVelocity {
    /// Computed, with the drift's bookkeeping: the state is read after this step (a record time).
    Computed,
    /// Left out: nothing reads `state().v` before the next step that computes it. `state().v` is
    /// then the Newmark velocity and the drift statistics skip this step; every other number, and
    /// every later step, has the bits it would have had (the projection feeds nothing back).
    Skipped,
}

/// Counters and constraint drift since the last (re)start.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HhtStats {
    /// Accepted steps.
    pub steps: u64,
    /// Adaptive sub-steps rejected by the system's state check
    /// ([`DaeSystem::state_rejection`]: a contact deeper than allowed) and retried at half size.
    pub state_rejections: u64,
    /// Newton iterations (residual evaluations + solves), all passes.
    pub newton_iterations: u64,
    /// Factorisations of the Newton iteration matrix (at most one per step while the stored one is
    /// reused, see [`HhtSettings::reuse_newton_matrix`]; plus refreshes).
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
    /// velocity (all of them unless stepped with [`ReportedVelocity::Skipped`]) (m or rad).
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
    /// Sub-steps rejected by the local error estimate ([`StepControl::Adaptive`]).
    pub error_rejections: u64,
    /// Sub-steps accepted at the smallest step with the error estimate still over the tolerance.
    pub error_limited_steps: u64,
    /// Impacts with unilateral limits ([`DaeSystem::apply_impact`]).
    pub impacts: u64,
    /// Factorisations of the full Newton matrix `M + β'h² K_t + γ'h D_t`.
    pub full_factorisations: u64,
    /// Smallest accepted sub-step, s (0 before the first step).
    pub smallest_step_s: f64,
    /// Largest error measure of an accepted sub-step ([`StepControl::Adaptive`]; accepted when ≤ 1,
    /// i.e. the estimated local position error over [`HhtSettings::tolerance`]).
    pub max_error_estimate: f64,
    /// Attempts that used the constant-velocity predictor (an unresolved stiff mode, see
    /// [`PREDICTOR_MAX_ACCELERATION_DISPLACEMENT`]).
    pub stiff_predictions: u64,
    /// Newton iterations that applied only part of their correction
    /// ([`DaeSystem::newton_update_fraction`] < 1: an iterate kept from jumping across a
    /// regularised law's narrow transition).
    pub limited_newton_updates: u64,
    /// Factorisations made because a Newton iterate left the regime of piecewise forces its
    /// matrix was formed in ([`DaeSystem::newton_regime`]: a joint-limit penalty switching on or
    /// off; also counted in `factorisations`).
    pub regime_refactorisations: u64,
    /// Steps accepted after their first Newton correction by the contraction the previous step
    /// measured ([`HhtSettings::accept_by_carried_contraction`]; docs/step-control.md §2,
    /// "Accepting the first correction").
    pub carried_rate_acceptances: u64,
}

/// Which form of the constraint rows [`iteration_matrix`] returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConstraintRowScaling {
    /// Rows `[Φ_q 0]` with right-hand side `−Φ/(β'h²)`: what the integrator factorises. Condition
    /// number bounded as `h → 0`.
    Scaled,
    /// Rows `[β'h² Φ_q 0]` with right-hand side `−Φ` (the plain derivative of `Φ(q(q̈))`). Condition
    /// number grows like `h⁻²`.
    Unscaled,
}

/// Preallocated buffers of one integrator (sizes `nq`, `nv`, `m`, `n = nv + m`).
#[derive(Debug, Clone)]
struct Workspace {
    /// Current Newton iterate q̈_{n+1}, dim nv.
    qdd: DVector<f64>,
    /// Current Newton iterate λ_{n+1}, dim m.
    lambda: DVector<f64>,
    /// a_{n+1}(q̈), dim nv.
    a: DVector<f64>,
    /// q_{n+1}(q̈), dim nq.
    q: DVector<f64>,
    /// q̇_{n+1}(q̈), dim nv.
    v: DVector<f64>,
    /// Tangent increment h q̇_n + h²[(½−β) a_n + β a_{n+1}], dim nv.
    dq: DVector<f64>,
    /// M, nv × nv.
    mass: DMatrix<f64>,
    /// Q, dim nv.
    forces: DVector<f64>,
    /// M q̈ + Φ_qᵀλ − Q, dim nv.
    dyn_residual: DVector<f64>,
    /// Diagonal stiffness k_j, dim nv.
    stiffness: DVector<f64>,
    /// Diagonal damping c_j, dim nv.
    damping: DVector<f64>,
    /// Position magnitudes for error weights, dim nv.
    scale: DVector<f64>,
    /// Φ, dim m.
    phi: DVector<f64>,
    /// Φ_q, m × nv.
    phi_q: DMatrix<f64>,
    /// Φ_t then Φ_q q̇ + Φ_t, dim m.
    phi_dot: DVector<f64>,
    /// Assembled iteration (or projection) matrix, n × n.
    matrix: DMatrix<f64>,
    /// Right-hand side, then solution, dim n.
    rhs: DVector<f64>,
    /// `a_n` as the attempted step sees it, dim nv: `a_n` itself for a step of the last size, else
    /// rescaled to the new size (`q̈_n + (h/h_last)(a_n − q̈_n)`, docs/step-control.md §3).
    a_start: DVector<f64>,
    /// The Newton matrix's diagonal terms `β'h² k_j + γ'h c_j`, dim nv.
    newton_diagonal: DVector<f64>,
    /// Full stiffness `∂r/∂q`, nv × nv.
    stiffness_full: DMatrix<f64>,
    /// Full damping `∂r/∂q̇`, nv × nv.
    damping_full: DMatrix<f64>,
    /// LU factorisation of the full Newton matrix (not symmetric).
    full_solver: DenseSolver,
    /// The current Newton factorisation is the full one (`full_solver`), not `solver`.
    use_full: bool,
    /// Gaps and rates of the unilateral limits at the start and at the end of a step, dim n_events.
    gaps_start: DVector<f64>,
    rates_start: DVector<f64>,
    gaps_end: DVector<f64>,
    rates_end: DVector<f64>,
    /// The state an impact law rewrites, dims nq and nv.
    impact_q: DVector<f64>,
    impact_v: DVector<f64>,
    /// The velocity change of a full Newton correction, `γ'h Δq̈`, dim nv.
    dv_trial: DVector<f64>,
    /// `mass` holds M at the current iterate.
    mass_fresh: bool,
    /// `mass` holds M at the accepted `q_{n+1}`, handed in for the velocity projection (a plain
    /// step driven from outside, `hht/plain.rs`).
    projection_mass_given: bool,
    /// `phi` and `phi_q` hold `Φ` and `Φ_q` at the current iterate (set where they are
    /// evaluated there, cleared where the iterate moves or they are evaluated elsewhere).
    constraints_fresh: bool,
}

impl Workspace {
    fn new(nq: usize, nv: usize, m: usize, n_events: usize) -> Self {
        let n = nv + m;
        Self {
            qdd: DVector::zeros(nv),
            lambda: DVector::zeros(m),
            a: DVector::zeros(nv),
            q: DVector::zeros(nq),
            v: DVector::zeros(nv),
            dq: DVector::zeros(nv),
            mass: DMatrix::zeros(nv, nv),
            forces: DVector::zeros(nv),
            dyn_residual: DVector::zeros(nv),
            stiffness: DVector::zeros(nv),
            damping: DVector::zeros(nv),
            scale: DVector::zeros(nv),
            phi: DVector::zeros(m),
            phi_q: DMatrix::zeros(m, nv),
            phi_dot: DVector::zeros(m),
            matrix: DMatrix::zeros(n, n),
            rhs: DVector::zeros(n),
            a_start: DVector::zeros(nv),
            newton_diagonal: DVector::zeros(nv),
            stiffness_full: DMatrix::zeros(nv, nv),
            damping_full: DMatrix::zeros(nv, nv),
            full_solver: DenseSolver::new(n, FactorKind::Lu),
            use_full: false,
            gaps_start: DVector::zeros(n_events),
            rates_start: DVector::zeros(n_events),
            gaps_end: DVector::zeros(n_events),
            rates_end: DVector::zeros(n_events),
            impact_q: DVector::zeros(nq),
            impact_v: DVector::zeros(nv),
            dv_trial: DVector::zeros(nv),
            mass_fresh: false,
            projection_mass_given: false,
            constraints_fresh: false,
        }
    }
}

/// The Newton factorisation a trajectory carries from step to step (docs/method.md §5, "Reusing the
/// Newton matrix"). It belongs to the trajectory, not to the workspace, so that whether a step
/// reuses it never depends on which samples the same integrator advanced before (a study's results
/// stay independent of threads and blocks).
#[derive(Debug, Clone)]
struct NewtonMemory {
    /// Factorisation of the diagonal Newton matrix `[M + β'h² K + γ'h C, Φ_qᵀ; Φ_q, 0]` (Cholesky
    /// without constraint rows, else LU); after a constrained step with the velocity projection, of
    /// the projection's `[M Φ_qᵀ; Φ_q 0]` at `q_{n+1}` (then not reusable).
    solver: DenseSolver,
    /// `solver` holds a Newton matrix of this trajectory that the next step may iterate with.
    reusable: bool,
    /// The step size the stored matrix was assembled for, s.
    h: f64,
    /// Slowest contraction `ρ` the last step's converging pass saw (0 when one iteration sufficed).
    rate: f64,
    /// The contraction the last pass with a matrix factorised at the predictor measured, for the
    /// next step's first correction; `None` at a (re)start, after an impact, and after a step
    /// that needed a refresh.
    contraction: Option<MeasuredContraction>,
}

impl NewtonMemory {
    fn new(nv: usize, m: usize) -> Self {
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
    fn carried_contraction(&self, h: f64, full: bool) -> Option<CarriedContraction> {
        self.contraction
            .filter(|measured| measured.h == h && measured.full == full)
            .map(|measured| CarriedContraction {
                rate: measured.rate,
                first_correction: measured.first_correction,
            })
    }

    /// Drops what the next step could carry over from the last (a restart, an impact): the stored
    /// matrix is no longer reusable and the measured contraction no longer applies.
    fn forget(&mut self) {
        self.reusable = false;
        self.contraction = None;
    }

    /// Everything but the factorisation, for an attempt that may be put back
    /// ([`HhtIntegrator::begin_plain_step`]).
    fn flags(&self) -> NewtonFlags {
        NewtonFlags {
            reusable: self.reusable,
            h: self.h,
            rate: self.rate,
            contraction: self.contraction,
        }
    }

    /// Puts back what [`NewtonMemory::flags`] saved.
    fn restore_flags(&mut self, flags: NewtonFlags) {
        self.reusable = flags.reusable;
        self.h = flags.h;
        self.rate = flags.rate;
        self.contraction = flags.contraction;
    }
}

/// The [`NewtonMemory`] without its factorisation.
#[derive(Debug, Clone, Copy)]
struct NewtonFlags {
    reusable: bool,
    h: f64,
    rate: f64,
    contraction: Option<MeasuredContraction>,
}

/// How often one Newton pass may refactorise because its iterate left the regime of piecewise
/// forces its matrix was formed in ([`DaeSystem::newton_regime`]; a joint-limit penalty switching
/// on or off). A converging iteration settles in one regime after one or two such switches; the
/// cap keeps an iterate that keeps crossing from refactorising at every iteration (it then goes on
/// with the last matrix, as before).
const MAX_REGIME_REFACTORISATIONS: usize = 4;

/// Everything that carries one trajectory from step to step — start time, state, the recursion's
/// velocity, the predictor's history, statistics, step control and the reusable Newton
/// factorisation — without the workspace. The integrator owns one (its only per-trajectory state);
/// a study keeps one per sample and advances many samples in turn with one integrator per thread
/// ([`HhtIntegrator::swap_trajectory`] exchanges the whole struct).
#[derive(Debug, Clone)]
pub struct HhtTrajectory {
    /// Start time, s.
    pub t0: f64,
    /// The state.
    pub state: HhtState,
    /// The Newmark velocity of the recursion (differs from `state.v` after a velocity projection).
    pub v_newmark: DVector<f64>,
    /// The accepted `q̈` and `λ` before the current ones, which the predictor extrapolates
    /// through (emptied at a start, a restart and an impact).
    pub predictor: PredictorHistory,
    /// Statistics of this trajectory.
    pub stats: HhtStats,
    /// Step control of this trajectory (the next sub-step, the last one, the full-matrix hold).
    pub control: StepControlState,
    /// The Newton factorisation this trajectory's next step may reuse.
    newton: NewtonMemory,
}

impl HhtTrajectory {
    /// Moves every vector the recursion carries (the state's `q`, `q̇`, `a`, `q̈`, `λ`, the Newmark
    /// velocity and the predictor's history) towards `reference`'s, `x ← r + scale (x − r)`: the
    /// Lyapunov estimate pulls a shadow trajectory back to its reference this way instead of
    /// restarting it (a restart would reset the generalized-α recursion). Time, step count,
    /// statistics, step control and Newton memory stay this trajectory's.
    pub fn pull_towards(&mut self, reference: &Self, scale: f64) {
        let (own, base) = (&mut self.state, &reference.state);
        for (x, r) in [
            (&mut own.q, &base.q),
            (&mut own.v, &base.v),
            (&mut own.a, &base.a),
            (&mut own.qdd, &base.qdd),
            (&mut own.lambda, &base.lambda),
            (&mut self.v_newmark, &reference.v_newmark),
        ] {
            pull(x, r, scale);
        }
        self.predictor.pull_towards(&reference.predictor, scale);
    }
}

/// `x ← r + scale (x − r)` entry by entry ([`HhtTrajectory::pull_towards`]).
fn pull(x: &mut DVector<f64>, reference: &DVector<f64>, scale: f64) {
    for (x, r) in x.iter_mut().zip(reference.iter()) {
        *x = r + scale * (*x - r);
    }
}

/// What the step control carries from step to step of one trajectory: part of [`HhtTrajectory`], so
/// that a sample's steps never depend on which sample the same integrator advanced before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepControlState {
    /// The sub-step the next attempt starts with, s (at most the grid step).
    pub h_next: f64,
    /// The last accepted sub-step, s (scales the predictor's extrapolation).
    pub h_last: f64,
    /// The accepted sub-step before the last, s (the predictor's curvature term).
    pub h_before_last: f64,
    /// Steps that still use the full Newton matrix ([`NewtonMatrix::Auto`]).
    pub full_newton_hold: u32,
    /// Whether the last grid step was one plain step of `h` (no sub-steps, no impact): the forward
    /// sensitivities can only differentiate those.
    pub last_step_plain: bool,
}

impl StepControlState {
    fn new(h: f64) -> Self {
        Self {
            h_next: h,
            h_last: h,
            h_before_last: h,
            full_newton_hold: 0,
            last_step_plain: true,
        }
    }
}

/// Largest position change (rad or m) the predictor's acceleration term may make before the
/// constant-velocity predictor replaces it: 0.01 is ~3000× what the shipped robots' predictors move
/// at 1 ms (≤ 3e-6), and a stiff mode that moves a joint by more within one step is not resolved
/// by the step anyway.
pub const PREDICTOR_MAX_ACCELERATION_DISPLACEMENT: f64 = 1e-2;

/// Most attempts (accepted and rejected sub-steps, retries, located impact steps) within one grid
/// step. A plain step is one attempt; the hardest case of `tests/stability.rs` (an elbow spring of
/// 1e8 N·m/rad released 0.1 rad from rest, resolved adaptively) needs ~350. At the ~2–10 µs of an
/// arm's sub-step 1e5 attempts are 0.2–1 s: also the bound on the work between two interruption
/// checks of a run (which check before every grid step).
pub const MAX_ATTEMPTS_PER_STEP: u64 = 100_000;

/// Where an impact may sit in a step: a crossing located at `θ` of the step is accepted as located
/// when the rest of the step, `(1 − θ) h`, is below this fraction of the grid step (1e-6: at
/// 500 rad/s and h = 1 ms, 5e-7 rad past the limit before the impact law puts the joint back on it).
pub const IMPACT_LOCATE_FRACTION: f64 = 1e-6;

/// A located step is aimed this fraction of the grid step beyond the predicted crossing, so that it
/// ends just past the limit rather than just before it (which would need one more tiny step).
const IMPACT_OVERSHOOT_FRACTION: f64 = 1e-7;

/// Most attempts to locate one impact inside a grid interval before the crossing is accepted where
/// the last attempt put it (each attempt re-fits the crossing on a shorter, converged step).
const IMPACT_LOCATE_ATTEMPTS: usize = 6;

/// Slowest approach, rad/s or m/s, that counts as an impact: slower crossings (a joint settling onto
/// its limit under gravity after a plastic impact) are left to the limit's penalty spring-damper,
/// whose penetration at this speed is `v · sqrt(m/k)` (≈ 6e-4 rad for a 1 kg, 1 m bar at the
/// penalty stiffness 1e4 N·m/rad). Without it a resting contact would be an endless train of
/// impacts (a Zeno sequence).
pub const IMPACT_MIN_SPEED: f64 = 0.1;

/// A grid interval counts as reached when less than this fraction of the grid step remains (the
/// remaining time is rounding, not a step).
const END_OF_INTERVAL_FRACTION: f64 = 1e-9;

/// Growth and shrink limits and the safety factor of the adaptive controller (per accepted or
/// rejected sub-step): the new step is `h · clamp(0.9 · err^(−1/3), 0.2, 2)`, the usual choice for
/// an error estimate of order `h³` (Hairer, Nørsett & Wanner I, §II.4).
const ADAPTIVE_SAFETY: f64 = 0.9;
const ADAPTIVE_MAX_GROWTH: f64 = 2.0;
const ADAPTIVE_MAX_SHRINK: f64 = 0.2;

/// How one attempt of a (sub-)step ended, when it did not fail.
enum Attempt {
    /// Newton converged; the iterate in the workspace is the candidate end state.
    Converged,
    /// The predictor already crosses a limit at `θ` of the step: shorten before solving.
    PredictedCrossing { theta: f64 },
}

/// The size of an attempt ([`HhtIntegrator::plan_attempt`]).
#[derive(Debug, Clone, Copy)]
struct PlannedAttempt {
    /// The step control's planned size, s.
    planned: f64,
    /// The attempt's size, s.
    h: f64,
    /// The attempt ends the grid interval.
    reaches_end: bool,
    /// The time it ends at, s.
    t1: f64,
}

/// What the adaptive controller does with a converged attempt
/// ([`HhtIntegrator::adaptive_verdict`]).
#[derive(Debug, Clone, Copy)]
enum AdaptiveVerdict {
    /// Rejected: attempt again with the size the controller planned.
    Retry,
    /// Accepted; the next attempt may be `growth` times this one.
    Accept { growth: f64 },
}

/// An impact found in a step: limit `event` crossed at `θ ∈ [0, 1]` of the step.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    event: usize,
    theta: f64,
}

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
        let (nq, nv, m) = (system.nq(), system.nv(), system.n_constraints());
        let n_events = system.n_events();
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
    /// With [`StepControl::Fixed`] this is one HHT step of `h`, and a Newton failure is reported as
    /// it is. With [`StepControl::Adaptive`] the grid interval is covered by sub-steps that follow
    /// the local error estimate, and a failed sub-step is retried with half its size (down to
    /// `h / 2^`[`HhtSettings::max_step_halvings`]). In both, a crossing of a unilateral limit ([`DaeSystem::n_events`]) is located
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
    /// ([`DaeSystem::n_events`]) always computes it: locating an impact reads the step's start
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

    /// The grid step of [`HhtIntegrator::advance`] (`report_velocity` set).
    fn advance_grid_step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
    ) -> Result<(), IntegrateError> {
        eval::check_dimensions(system, self.nq, self.nv, self.m)?;
        let step = self.trajectory.state.step + 1;
        let h_grid = self.grid_coeffs.h;
        let t_end = self.trajectory.t0 + step as f64 * h_grid;
        let adaptive = self.settings.step_control == StepControl::Adaptive;
        let h_min = h_grid / f64::from(1u32 << self.settings.max_step_halvings);
        let mut plain = true;
        let mut accepted = 0usize;
        let mut first_failure: Option<IntegrateError> = None;
        let mut locating = false;
        let mut locate_attempts = 0usize;
        // The fixed step retries a failed attempt only while it is locating an impact (the short
        // located steps are not grid steps); any other failure is reported as it is.
        let mut near_impact = false;
        let mut attempts: u64 = 0;
        loop {
            let remaining = t_end - self.trajectory.state.t;
            if remaining <= END_OF_INTERVAL_FRACTION * h_grid {
                break;
            }
            attempts += 1;
            if attempts > MAX_ATTEMPTS_PER_STEP {
                return Err(IntegrateError::TooManySubsteps {
                    t: t_end,
                    step,
                    attempts: MAX_ATTEMPTS_PER_STEP,
                    smallest_s: self.trajectory.stats.smallest_step_s,
                });
            }
            let PlannedAttempt {
                planned,
                h,
                reaches_end,
                t1,
            } = self.plan_attempt(t_end, h_min, remaining);
            let check_prediction = self.n_events > 0 && !locating;
            let outcome = self.attempt(system, t1, h, step, check_prediction);
            match outcome {
                Ok(Attempt::PredictedCrossing { theta }) => {
                    plain = false;
                    locating = true;
                    near_impact = true;
                    self.trajectory.control.h_next =
                        (theta * h + IMPACT_OVERSHOOT_FRACTION * h_grid).max(h_min);
                    continue;
                }
                Ok(Attempt::Converged) => {}
                Err(error) if retryable(&error) && (adaptive || near_impact) => {
                    plain = false;
                    self.trajectory.stats.step_failures += 1;
                    if 0.5 * h < h_min * (1.0 - 1e-12) {
                        return Err(first_failure.unwrap_or(error));
                    }
                    first_failure.get_or_insert(error);
                    self.trajectory.control.h_next = 0.5 * h;
                    // A failed located step says nothing about the crossing: locate again.
                    locating = false;
                    continue;
                }
                Err(error) => return Err(error),
            }
            locating = false;

            // An impact inside the converged step: shorten the step to it, or, once located, accept
            // the step and apply the impact law at its end.
            if self.n_events > 0 {
                if let Some(crossing) = self.find_crossing(system, t1, h)? {
                    let rest = (1.0 - crossing.theta) * h;
                    if rest > IMPACT_LOCATE_FRACTION * h_grid
                        && locate_attempts < IMPACT_LOCATE_ATTEMPTS
                        && crossing.theta * h >= h_min
                    {
                        plain = false;
                        locate_attempts += 1;
                        locating = true;
                        near_impact = true;
                        self.trajectory.control.h_next =
                            crossing.theta * h + IMPACT_OVERSHOOT_FRACTION * h_grid;
                        continue;
                    }
                    self.commit(system, t1, h, step)?;
                    self.impact(system, crossing.event, step)?;
                    plain = false;
                    accepted += 1;
                    locate_attempts = 0;
                    // The short located step says nothing about the motion after the impact.
                    self.trajectory.control.h_next = h_grid;
                    continue;
                }
            }

            let mut growth = ADAPTIVE_MAX_GROWTH;
            if adaptive {
                match self.adaptive_verdict(system, At { t: t1, step }, h, h_min)? {
                    AdaptiveVerdict::Retry => {
                        plain = false;
                        continue;
                    }
                    AdaptiveVerdict::Accept { growth: factor } => growth = factor,
                }
            }
            self.accept(system, t1, h, step, growth, planned, reaches_end)?;
            accepted += 1;
        }
        self.end_grid_step(t_end, step, plain && accepted == 1);
        Ok(())
    }

    /// The adaptive controller's verdict on the converged attempt of size `h` to `at.t` (the
    /// candidate in the workspace): retry smaller (the next size planned, the rejection counted)
    /// when the system rejects the state or the error estimate exceeds 1 above `h_min`; else
    /// accept, with the growth factor of the next step (docs/step-control.md §3).
    fn adaptive_verdict<S: DaeSystem + ?Sized>(
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
    fn plan_attempt(&self, t_end: f64, h_min: f64, remaining: f64) -> PlannedAttempt {
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

    /// Accepts the converged attempt of size `h` to `t1` ([`Self::commit`]) and plans the next
    /// one: `growth` times this one (the adaptive controller's factor; 2 with the fixed step), at
    /// most the grid step.
    #[allow(clippy::too_many_arguments)]
    fn accept<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t1: f64,
        h: f64,
        step: u64,
        growth: f64,
        planned: f64,
        reaches_end: bool,
    ) -> Result<(), IntegrateError> {
        self.commit(system, t1, h, step)?;
        let mut next = h * growth;
        if reaches_end && growth >= 1.0 {
            // A step cut short by the grid says nothing against the planned size.
            next = next.max(planned);
        }
        self.trajectory.control.h_next = next.min(self.grid_coeffs.h);
        Ok(())
    }

    /// Ends grid step number `step` at `t_end` (set from the step count, so time does not drift);
    /// `plain`: it was one attempt of the grid step's size.
    fn end_grid_step(&mut self, t_end: f64, step: u64, plain: bool) {
        self.trajectory.state.t = t_end;
        self.trajectory.state.step = step;
        self.trajectory.stats.steps += 1;
        self.trajectory.control.last_step_plain = plain;
        self.coeffs = self.grid_coeffs;
    }

    /// Sets the coefficients of a step of size `h` and the predictor: `a_n` as this step sees it
    /// (`ws.a_start`) and the first iterate `ws.qdd`, `ws.lambda` (counted in
    /// `stats.stiff_predictions` when the constant-velocity predictor replaces the extrapolation).
    fn predict(&mut self, h: f64, by_order: bool) {
        self.coeffs = if h == self.grid_coeffs.h {
            self.grid_coeffs
        } else {
            HhtCoefficients::new(self.grid_coeffs.alpha, h)
        };

        // a_n stands for q̈ at t_n + α h_last (a_n = q̈_n + α (q̈_n − q̈_{n−1})); a step of another
        // size needs it at t_n + α h: rescale its offset from q̈_n, or the variable step loses its
        // second order.
        let ratio = h / self.trajectory.control.h_last;
        if ratio == 1.0 {
            self.ws
                .a_start
                .as_mut_slice()
                .copy_from_slice(self.trajectory.state.a.as_slice());
        } else {
            for ((x, a_n), qdd_n) in self
                .ws
                .a_start
                .as_mut_slice()
                .iter_mut()
                .zip(self.trajectory.state.a.as_slice())
                .zip(self.trajectory.state.qdd.as_slice())
            {
                *x = qdd_n + ratio * (a_n - qdd_n);
            }
        }
        // Predictor (docs/step-control.md §2, hht/predictor.rs): q̈_{n+1} and λ_{n+1} extrapolated
        // through the accepted history, each entry by the order that predicted its last value best
        // on a run of equal steps. The converged result is the same to the Newton tolerance.
        let trajectory = &self.trajectory;
        trajectory.predictor.predict(
            h,
            by_order,
            &trajectory.control,
            (
                trajectory.state.qdd.as_slice(),
                trajectory.state.lambda.as_slice(),
            ),
            self.ws.qdd.as_mut_slice(),
            self.ws.lambda.as_mut_slice(),
        );
        // An unresolved stiff mode (a spring whose period is far below h) makes the extrapolated
        // q̈ meaningless: its position term h²[(½ − β) a_n + β a_{n+1}] can throw the predicted
        // configuration radians away, where no Newton matrix helps. Then predict constant velocity
        // instead (that term zero): q_{n+1} = q_n ⊕ h q̇_n (docs/step-control.md §1–§2).
        let newmark = NewmarkUpdate::of(&self.coeffs);
        // Two entries at a time; the largest is the same in any order (comparisons are exact, NaN
        // skipped as `f64::max` skips it).
        let nv = self.nv;
        let (qdd, qdd_n, a_start) = (
            &self.ws.qdd.as_slice()[..nv],
            &self.trajectory.state.qdd.as_slice()[..nv],
            &self.ws.a_start.as_slice()[..nv],
        );
        let displacement = |qdd: f64, qdd_n: f64, a_n: f64| {
            newmark
                .acceleration_displacement(a_n, newmark.acceleration(qdd, qdd_n))
                .abs()
        };
        let mut largest = [0.0_f64; 2];
        let pairs = nv - nv % 2;
        for i in (0..pairs).step_by(2) {
            for l in 0..2 {
                let d = displacement(qdd[i + l], qdd_n[i + l], a_start[i + l]);
                largest[l] = if d > largest[l] { d } else { largest[l] };
            }
        }
        for i in pairs..nv {
            let d = displacement(qdd[i], qdd_n[i], a_start[i]);
            largest[0] = if d > largest[0] { d } else { largest[0] };
        }
        let acceleration_displacement = largest[0].max(largest[1]);
        if acceleration_displacement > PREDICTOR_MAX_ACCELERATION_DISPLACEMENT {
            self.trajectory.stats.stiff_predictions += 1;
            for ((x, qdd_n), a_n) in self
                .ws
                .qdd
                .as_mut_slice()
                .iter_mut()
                .zip(self.trajectory.state.qdd.as_slice())
                .zip(self.ws.a_start.as_slice())
            {
                let (alpha, beta) = (newmark.alpha, newmark.beta);
                let a = -(0.5 - beta) / beta * a_n;
                *x = (a + alpha * qdd_n) / (1.0 + alpha);
            }
        }
    }

    /// Whether the predictor blends its orders by the history on runs of equal steps
    /// ([`HhtSettings::choose_predictor_order`] and a system whose forces are smooth between steps,
    /// [`DaeSystem::smooth_between_steps`]).
    fn predicts_by_order<S: DaeSystem + ?Sized>(&self, system: &S) -> bool {
        self.settings.choose_predictor_order && system.smooth_between_steps()
    }

    /// One attempt of a (sub-)step of size `h` from the current state to `t1`: predictor, then
    /// Newton (diagonal matrix first; the full matrix on refresh or while held, see
    /// [`NewtonMatrix`]). The state is not touched; the candidate end state is left in the workspace.
    /// With `check_prediction`, a predictor that crosses a limit returns
    /// [`Attempt::PredictedCrossing`] before Newton runs.
    fn attempt<S: DaeSystem + ?Sized>(
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

        let provides_full = system.provides_residual_jacobians();
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
            && !system.provides_newton_coupling()
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
    fn carried_contraction(&self, h: f64, full: bool) -> Option<CarriedContraction> {
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
    fn conclude_attempt(
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

    /// Accepts the candidate end state of the last attempt (step `h` to `t1`), keeping `q̈_n` and
    /// `λ_n` for the next predictor.
    fn commit<S: DaeSystem + ?Sized>(
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
    fn error_estimate(&self) -> f64 {
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

    /// The earliest impact in the step from the state to the candidate in the workspace (`ws.q`,
    /// `ws.v`), if any: a limit with `g ≥ 0` at the start and `g < 0` at the end, crossing at an
    /// approach speed of at least [`IMPACT_MIN_SPEED`]. The crossing time is the root of the cubic
    /// Hermite interpolant of `g` through `(g, h ġ)` at both ends (docs/step-control.md §4).
    fn find_crossing<S: DaeSystem + ?Sized>(
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
    fn impact<S: DaeSystem + ?Sized>(
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

    /// From the iterate `ws.qdd` (and the state at `t_n`), computes `a_{n+1}`, `q_{n+1}`, `q̇_{n+1}`:
    ///
    /// ```text
    /// a_{n+1} = (1+α) q̈_{n+1} − α q̈_n
    /// q_{n+1} = q_n ⊕ (h q̇_n + h² [(½ − β) a_n + β a_{n+1}])
    /// q̇_{n+1} = q̇_n + h [(1 − γ) a_n + γ a_{n+1}]
    /// ```
    fn update_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &S,
        at: At,
    ) -> Result<(), IntegrateError> {
        let newmark = NewmarkUpdate::of(&self.coeffs);
        let s = &self.trajectory.state;
        let v_n = &self.trajectory.v_newmark;
        let ws = &mut self.ws;
        // Over slices of one length (no per-entry bounds checks); the same operations per entry.
        let nv = self.nv;
        let (qdd, qdd_n, a_start) = (
            &ws.qdd.as_slice()[..nv],
            &s.qdd.as_slice()[..nv],
            &ws.a_start.as_slice()[..nv],
        );
        let v_n = &v_n.as_slice()[..nv];
        let (a, dq, v) = (
            &mut ws.a.as_mut_slice()[..nv],
            &mut ws.dq.as_mut_slice()[..nv],
            &mut ws.v.as_mut_slice()[..nv],
        );
        // Two entries at a time (one vector register of the x86-64 baseline), the last alone.
        let pairs = nv - nv % 2;
        let pair = |x: &[f64]| -> [f64; 2] { [x[0], x[1]] };
        for (((a, dq), v), (((qdd, qdd_n), a_start), v_n)) in a[..pairs]
            .chunks_exact_mut(2)
            .zip(dq[..pairs].chunks_exact_mut(2))
            .zip(v[..pairs].chunks_exact_mut(2))
            .zip(
                qdd[..pairs]
                    .chunks_exact(2)
                    .zip(qdd_n[..pairs].chunks_exact(2))
                    .zip(a_start[..pairs].chunks_exact(2))
                    .zip(v_n[..pairs].chunks_exact(2)),
            )
        {
            let (a_new, dq_new, v_new) =
                newmark.entries(pair(qdd), pair(qdd_n), pair(a_start), pair(v_n));
            a.copy_from_slice(&a_new);
            dq.copy_from_slice(&dq_new);
            v.copy_from_slice(&v_new);
        }
        for i in pairs..nv {
            let ([a_new], [dq_new], [v_new]) =
                newmark.entries([qdd[i]], [qdd_n[i]], [a_start[i]], [v_n[i]]);
            (a[i], dq[i], v[i]) = (a_new, dq_new, v_new);
        }
        eval::integrate_position(system, at, &s.q, &ws.dq, &mut ws.q)?;
        ws.mass_fresh = false;
        ws.constraints_fresh = false;
        Ok(())
    }

    /// Evaluates `M`, the diagonal spring/damper terms and `Φ_q` at the current iterate and factorises
    /// the iteration matrix (see [`assemble_iteration_matrix`]).
    fn factorise_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        full: bool,
    ) -> Result<(), IntegrateError> {
        if full {
            return self.factorise_full_at_iterate(system, at);
        }
        eval::mass_matrix(system, at, &self.ws.q, &mut self.ws.mass)?;
        self.factorise_diagonal(system, at)
    }

    /// Factorises the diagonal Newton matrix `[M + β'h² K + γ'h C, Φ_qᵀ; Φ_q, 0]` (plus the
    /// contacts' coupling) at the current iterate, with `M` already in `ws.mass`: evaluates the
    /// diagonal spring/damper terms and `Φ`, `Φ_q` there (see [`assemble_iteration_matrix`]).
    fn factorise_diagonal<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        self.ws.use_full = false;
        let has_diagonal = self.evaluate_newton_diagonal(system, at)?;
        self.constraint_rows_at_iterate(system, at)?;
        let ws = &mut self.ws;
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        let solver = &mut self.trajectory.newton.solver;
        let factorised = if self.settings.newton_diagonal_terms && system.provides_newton_coupling()
        {
            assemble_iteration_matrix(
                &ws.mass,
                has_diagonal.then_some((&ws.stiffness, &ws.damping)),
                &ws.phi_q,
                beta_h2,
                gamma_h,
                1.0,
                &mut ws.matrix,
            );
            // Forces that couple joints (contacts): their Jacobians beside the diagonal ones,
            // in the buffers of the full matrix (unused on this path).
            eval::newton_coupling(
                system,
                at,
                &ws.q,
                &ws.v,
                &mut ws.stiffness_full,
                &mut ws.damping_full,
            )?;
            for c in 0..self.nv {
                for r in 0..self.nv {
                    ws.matrix[(r, c)] +=
                        beta_h2 * ws.stiffness_full[(r, c)] + gamma_h * ws.damping_full[(r, c)];
                }
            }
            solver.factor(&ws.matrix)
        } else {
            // The matrix of docs/method.md §5 from its blocks, unassembled (the same bits).
            let diagonal = has_diagonal.then_some(ws.newton_diagonal.as_slice());
            solver.factor_blocks(&ws.mass, diagonal, &ws.phi_q)
        };
        factorised.map_err(|b| IntegrateError::SingularMatrix {
            t: at.t,
            step: at.step,
            matrix: "Newton iteration matrix",
            index: b.index,
            pivot_relative: b.pivot_relative,
        })?;
        ws.mass_fresh = true;
        self.trajectory.stats.factorisations += 1;
        Ok(())
    }

    /// With constraint rows, `Φ` and `Φ_q` at the current iterate in one pass of the kinematics
    /// (`ws.phi`, `ws.phi_q`): a factorisation needs `Φ_q`, and the iteration that follows at this
    /// iterate reads both (`add_constraint_rows`).
    fn constraint_rows_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        if self.m > 0 {
            let ws = &mut self.ws;
            eval::constraints_and_jacobian(system, at, &ws.q, &mut ws.phi, &mut ws.phi_q)?;
        }
        self.ws.constraints_fresh = true;
        Ok(())
    }

    /// With [`HhtSettings::newton_diagonal_terms`]: the spring/damper terms at the current iterate
    /// (`ws.stiffness`, `ws.damping`) and the Newton matrix's diagonal `β'h² k + γ'h c` from them
    /// (`ws.newton_diagonal`); returns whether there is one.
    fn evaluate_newton_diagonal<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<bool, IntegrateError> {
        if !self.settings.newton_diagonal_terms {
            return Ok(false);
        }
        let ws = &mut self.ws;
        if !system.provides_newton_diagonal() {
            // No terms: `stiffness` and `damping` are left as they are, and nothing reads them.
            return Ok(false);
        }
        eval::newton_diagonal(system, at, &ws.q, &ws.v, &mut ws.stiffness, &mut ws.damping)?;
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        for ((d, k), c) in ws
            .newton_diagonal
            .as_mut_slice()
            .iter_mut()
            .zip(ws.stiffness.as_slice())
            .zip(ws.damping.as_slice())
        {
            *d = beta_h2 * k + gamma_h * c;
        }
        Ok(true)
    }

    /// Evaluates `M`, the full residual Jacobians and `Φ`, `Φ_q` at the current iterate and
    /// factorises the full Newton matrix `[M + β'h² K_t + γ'h D_t, Φ_qᵀ; Φ_q, 0]` (LU;
    /// docs/step-control.md §1–§2).
    fn factorise_full_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        let nv = self.nv;
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        let ws = &mut self.ws;
        ws.use_full = true;
        eval::mass_matrix(system, at, &ws.q, &mut ws.mass)?;
        eval::residual_jacobians(
            system,
            at,
            &ws.q,
            &ws.v,
            &ws.qdd,
            &ws.lambda,
            &mut ws.stiffness_full,
            &mut ws.damping_full,
        )?;
        self.constraint_rows_at_iterate(system, at)?;
        let ws = &mut self.ws;
        assemble_iteration_matrix(&ws.mass, None, &ws.phi_q, 0.0, 0.0, 1.0, &mut ws.matrix);
        for c in 0..nv {
            for r in 0..nv {
                ws.matrix[(r, c)] +=
                    beta_h2 * ws.stiffness_full[(r, c)] + gamma_h * ws.damping_full[(r, c)];
            }
        }
        ws.full_solver
            .factor(&ws.matrix)
            .map_err(|b| IntegrateError::SingularMatrix {
                t: at.t,
                step: at.step,
                matrix: "full Newton iteration matrix",
                index: b.index,
                pivot_relative: b.pivot_relative,
            })?;
        ws.mass_fresh = true;
        self.trajectory.stats.factorisations += 1;
        self.trajectory.stats.full_factorisations += 1;
        Ok(())
    }

    /// One modified-Newton iteration at the current iterate: residual, solve with the stored
    /// factorisation, correction, convergence measure.
    ///
    /// ```text
    /// r = [ M q̈ + Φ_qᵀ λ − Q ]      J [Δq̈; Δλ] = −r,   q̈ += Δq̈,  λ += Δλ
    ///     [ Φ / (β'h²)       ]
    /// converged ⇔ ‖β'h² Δq̈‖_WRMS < 1 and ‖Δλ‖_WRMS < 1,   ewt_i = 1 / (reltol |x_i| + abstol)
    /// ```
    fn newton_iteration<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<IterationReport, IntegrateError> {
        {
            let ws = &mut self.ws;
            // Dynamics rows: M q̈ − Q (+ Φ_qᵀ λ below).
            if system.provides_dynamics_residual() {
                // With M fresh, the factorisation just evaluated it at this iterate (the
                // system's last mass_matrix call): its kinematics may be reused.
                let after_mass_matrix = ws.mass_fresh;
                eval::dynamics_residual(
                    system,
                    at,
                    &ws.q,
                    &ws.v,
                    &ws.qdd,
                    after_mass_matrix,
                    &mut ws.dyn_residual,
                )?;
            } else {
                if !ws.mass_fresh {
                    eval::mass_matrix(system, at, &ws.q, &mut ws.mass)?;
                    ws.mass_fresh = true;
                }
                eval::forces(system, at, &ws.q, &ws.v, &mut ws.forces)?;
                ws.dyn_residual.copy_from(&ws.forces);
                ws.dyn_residual.gemv(1.0, &ws.mass, &ws.qdd, -1.0);
            }
        }
        self.add_constraint_rows(system, at)?;
        self.correct_iterate(system, at)
    }

    /// With constraint rows: `Φ` at the iterate into `ws.phi`, and `Φ_qᵀ λ` added to the dynamics
    /// rows in `ws.dyn_residual` (`Φ_q` evaluated unless fresh). Nothing without rows.
    fn add_constraint_rows<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        if self.m == 0 {
            return Ok(());
        }
        let ws = &mut self.ws;
        if !ws.constraints_fresh {
            eval::constraints_and_jacobian(system, at, &ws.q, &mut ws.phi, &mut ws.phi_q)?;
            ws.constraints_fresh = true;
        }
        ws.dyn_residual.gemv_tr(1.0, &ws.phi_q, &ws.lambda, 1.0);
        Ok(())
    }

    /// The rest of a modified-Newton iteration once the dynamics rows of the residual are in
    /// `ws.dyn_residual` (and, with constraint rows, `Φ` in `ws.phi`): solve with the stored
    /// factorisation, the convergence measure, the correction (limited where the system asks) and
    /// the new iterate.
    fn correct_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<IterationReport, IntegrateError> {
        let residual_inf = self.newton_rhs();
        self.solve_newton_rhs();
        self.apply_newton_correction(system, at, residual_inf)
    }

    /// Solves the Newton system in place of its right-hand side `ws.rhs`, with the stored
    /// factorisation (the full Newton matrix's when it is in use).
    #[inline(always)]
    fn solve_newton_rhs(&mut self) {
        if self.ws.use_full {
            self.ws.full_solver.solve_in_place(&mut self.ws.rhs);
        } else {
            self.trajectory
                .newton
                .solver
                .solve_in_place(&mut self.ws.rhs);
        }
    }

    /// The Newton system's right-hand side `−(r, Φ/(β'h²))` into `ws.rhs` (`r` the dynamics rows
    /// in `ws.dyn_residual`); returns its largest magnitude, the residual the report carries.
    #[inline(always)]
    fn newton_rhs(&mut self) -> f64 {
        let (nv, m) = (self.nv, self.m);
        let beta_h2 = self.coeffs.beta_h2();
        let ws = &mut self.ws;
        // The largest magnitude by comparison (NaN skipped, as `f64::max` skips it), which
        // compiles to fewer instructions than `max`'s NaN handling.
        let larger = |largest: f64, r: f64| if r.abs() > largest { r.abs() } else { largest };
        let mut residual_inf: f64 = 0.0;
        let rhs = &mut ws.rhs.as_mut_slice()[..nv + m];
        for (x, r) in rhs[..nv].iter_mut().zip(&ws.dyn_residual.as_slice()[..nv]) {
            residual_inf = larger(residual_inf, *r);
            *x = -r;
        }
        for (x, phi) in rhs[nv..].iter_mut().zip(&ws.phi.as_slice()[..m]) {
            let r = phi / beta_h2;
            residual_inf = larger(residual_inf, r);
            *x = -r;
        }
        residual_inf
    }

    /// [`Self::correct_iterate`] after the solve: `ws.rhs` holds the correction `(Δq̈, Δλ)`;
    /// `residual_inf` is [`Self::newton_rhs`]'s.
    #[inline(always)]
    fn apply_newton_correction<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        residual_inf: f64,
    ) -> Result<IterationReport, IntegrateError> {
        let (nv, m) = (self.nv, self.m);
        let beta_h2 = self.coeffs.beta_h2();
        let ws = &mut self.ws;
        at.check_finite("newton_update", ws.rhs.as_slice())?;

        // Weighted RMS of the position-level correction β'h² Δq̈ and of Δλ, at the iterate before
        // the correction; the worst weighted entry is kept for the failure report.
        // A system whose scale is zero everywhere is not asked for it (and `ws.scale` not read).
        let scale_is_zero = system.position_scale_is_zero();
        if !scale_is_zero {
            system.position_scale(&ws.q, &mut ws.scale);
        }
        let reltol = self.settings.reltol;
        // The worst weighted entry over coordinates then rows (index ≥ nv: row index − nv); the
        // first of equal ones.
        let (mut worst_value, mut worst_index) = (-1.0, 0);
        let mut sum_q = 0.0;
        let (rhs, scale) = (&ws.rhs.as_slice()[..nv + m], &ws.scale.as_slice()[..nv]);
        let abstol = self.settings.abstol_position;
        let mut take = |i: usize, ewt: f64| {
            let x = (beta_h2 * rhs[i] * ewt).abs();
            sum_q += x * x;
            if x > worst_value {
                (worst_value, worst_index) = (x, i);
            }
        };
        if scale_is_zero {
            // `1 / (reltol · 0 + abstol)`, bit for bit, once.
            let ewt = 1.0 / abstol;
            for i in 0..nv {
                take(i, ewt);
            }
        } else {
            for (i, scale) in scale.iter().enumerate() {
                take(i, 1.0 / (reltol * scale + abstol));
            }
        }
        let mut sum_l = 0.0;
        for j in 0..m {
            let ewt = 1.0 / (reltol * ws.lambda[j].abs() + self.settings.abstol_multiplier);
            let x = (rhs[nv + j] * ewt).abs();
            sum_l += x * x;
            if x > worst_value {
                (worst_value, worst_index) = (x, nv + j);
            }
        }
        let worst = if worst_index < nv || worst_value < 0.0 {
            WorstEntry::Coordinate {
                index: worst_index,
                weighted_correction: worst_value.max(0.0),
            }
        } else {
            WorstEntry::Constraint {
                index: worst_index - nv,
                weighted_correction: worst_value,
                violation: ws.phi[worst_index - nv],
            }
        };
        let wrms_q = if nv > 0 {
            (sum_q / nv as f64).sqrt()
        } else {
            0.0
        };
        let wrms_l = if m > 0 {
            (sum_l / m as f64).sqrt()
        } else {
            0.0
        };

        if system.limits_newton_updates() {
            // The velocity change of the full correction: Δq̇ = γ'h Δq̈.
            let gamma_h = self.coeffs.gamma_h();
            for i in 0..nv {
                ws.dv_trial[i] = gamma_h * ws.rhs[i];
            }
            let fraction = eval::newton_update_fraction(system, at, &ws.q, &ws.v, &ws.dv_trial)?;
            if fraction < 1.0 {
                self.trajectory.stats.limited_newton_updates += 1;
                for x in ws.rhs.iter_mut() {
                    *x *= fraction;
                }
            }
        }
        let rhs = ws.rhs.as_slice();
        for (x, dx) in ws.qdd.as_mut_slice().iter_mut().zip(&rhs[..nv]) {
            *x += dx;
        }
        for (x, dx) in ws.lambda.as_mut_slice().iter_mut().zip(&rhs[nv..nv + m]) {
            *x += dx;
        }
        self.update_iterate(system, at)?;
        Ok(IterationReport {
            wrms_position: wrms_q,
            wrms_multiplier: wrms_l,
            residual_inf,
            worst,
        })
    }

    /// After an accepted step with constraint rows: records `max |Φ|` and the velocity-level drift,
    /// and projects the reported `q̇` (`state.v`) when enabled; the recursion keeps the Newmark
    /// velocity (see [`HhtSettings::velocity_projection`]):
    ///
    /// ```text
    /// [ M    Φ_qᵀ ] [Δq̇]   [ 0                ]
    /// [ Φ_q  0    ] [μ  ] = [ −(Φ_q q̇ + Φ_t)   ],   q̇ += Δq̇
    /// ```
    fn finish_constrained_step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        let (nv, m) = (self.nv, self.m);
        {
            let ws = &mut self.ws;
            eval::constraints_and_jacobian(
                system,
                at,
                &self.trajectory.state.q,
                &mut ws.phi,
                &mut ws.phi_q,
            )?;
            ws.constraints_fresh = false;
        }
        self.trajectory.stats.max_constraint_violation = self
            .trajectory
            .stats
            .max_constraint_violation
            .max(self.ws.phi.amax());
        let before = self.velocity_violation_at_jacobian(system, at)?;
        self.trajectory.stats.max_velocity_violation_unprojected = self
            .trajectory
            .stats
            .max_velocity_violation_unprojected
            .max(before);
        if !self.settings.velocity_projection {
            self.trajectory.stats.max_velocity_violation =
                self.trajectory.stats.max_velocity_violation.max(before);
            return Ok(());
        }
        // ws.phi_q holds Φ_q(q_{n+1}), ws.phi_dot Φ_q q̇ + Φ_t.
        // The projection's matrix [M Φ_qᵀ; Φ_q 0] replaces the stored Newton factorisation
        // (never reused with constraint rows). Its metric M is the Newton matrix's when that was
        // M alone (docs/method.md §5, "Velocity drift"): only the rows are refactorised.
        self.trajectory.newton.reusable = false;
        let keeps_newton_mass = self.projection_keeps_newton_mass()
            && self
                .trajectory
                .newton
                .solver
                .refactor_constraint_rows(&self.ws.phi_q)
                .is_ok();
        let ws = &mut self.ws;
        if !keeps_newton_mass {
            if !ws.projection_mass_given {
                eval::mass_matrix(system, at, &self.trajectory.state.q, &mut ws.mass)?;
            }
            self.trajectory
                .newton
                .solver
                .factor_blocks(&ws.mass, None, &ws.phi_q)
                .map_err(|b| IntegrateError::SingularMatrix {
                    t: at.t,
                    step: at.step,
                    matrix: "velocity projection matrix [M Φ_qᵀ; Φ_q 0]",
                    index: b.index,
                    pivot_relative: b.pivot_relative,
                })?;
        }
        ws.mass_fresh = false;
        self.trajectory.stats.projection_factorisations += 1;
        for i in 0..nv {
            ws.rhs[i] = 0.0;
        }
        for j in 0..m {
            ws.rhs[nv + j] = -ws.phi_dot[j];
        }
        self.trajectory.newton.solver.solve_in_place(&mut ws.rhs);
        at.check_finite("velocity_projection", ws.rhs.as_slice())?;
        for i in 0..nv {
            self.trajectory.state.v[i] += ws.rhs[i];
        }
        if self.projection_feedback {
            self.trajectory
                .v_newmark
                .copy_from(&self.trajectory.state.v);
        }
        // The projection changed q̇ only: Φ_q(q_{n+1}) is still in ws.phi_q.
        let after = self.velocity_violation_at_jacobian(system, at)?;
        self.trajectory.stats.max_velocity_violation =
            self.trajectory.stats.max_velocity_violation.max(after);
        Ok(())
    }

    /// Whether the velocity projection of the step being accepted can keep the factor of `M` in
    /// the Newton matrix it converged with: that matrix was `[M Φ_qᵀ; Φ_q 0]` of this step (no
    /// diagonal terms, not the full Newton matrix), so the projection refactorises only its rows
    /// at `q_{n+1}` (docs/method.md §5, "Velocity drift").
    pub(crate) fn projection_keeps_newton_mass(&self) -> bool {
        self.settings.projection_keeps_newton_mass
            && !self.ws.use_full
            && self.trajectory.newton.solver.holds_mass_factor()
    }

    /// Test-only: feed the projected velocity back into the recursion (the textbook post-step
    /// projection), to measure what that costs.
    #[cfg(test)]
    pub(crate) fn set_projection_feedback(&mut self, on: bool) {
        self.projection_feedback = on;
    }

    /// `max_j |Φ_q q̇ + Φ_t|_j` at the current state; leaves `Φ_q` in `ws.phi_q` and the vector in
    /// `ws.phi_dot`.
    fn velocity_violation<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<f64, IntegrateError> {
        let ws = &mut self.ws;
        eval::constraint_jacobian(system, at, &self.trajectory.state.q, &mut ws.phi_q)?;
        ws.constraints_fresh = false;
        self.velocity_violation_at_jacobian(system, at)
    }

    /// [`velocity_violation`](Self::velocity_violation) with `Φ_q` at the current state already
    /// in `ws.phi_q`; leaves the vector in `ws.phi_dot`.
    fn velocity_violation_at_jacobian<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<f64, IntegrateError> {
        let ws = &mut self.ws;
        let s = &self.trajectory.state;
        if system.constraints_are_scleronomic() {
            ws.phi_dot.as_mut_slice().fill(0.0);
        } else {
            eval::constraint_time_derivative(system, at, &s.q, &mut ws.phi_dot)?;
        }
        ws.phi_dot.gemv(1.0, &ws.phi_q, &s.v, 1.0);
        Ok(ws.phi_dot.amax())
    }
}

/// Assembles the Newton iteration matrix of docs/method.md §5 into `out` (`(nv + m) × (nv + m)`).
///
/// The Newton system for the unknowns `(q̈_{n+1}, λ_{n+1})`, with `β' = (1+α)β`, `γ' = (1+α)γ`:
///
/// ```text
/// [ M + β'h² K_t − γ'h C_t    Φ_qᵀ ] [Δq̈]      [ M q̈ + Φ_qᵀλ − Q ]
/// [ c · Φ_q                   0    ] [Δλ ]  = − [ c · Φ / (β'h²)    ]
///
/// K_t = ∂(M q̈ + Φ_qᵀλ − Q)/∂q,  C_t = ∂Q/∂q̇
/// ```
///
/// Modified Newton keeps only `M` and the diagonal spring/damper parts of `K_t` and `C_t`: a spring
/// `Q_j = −k_j q_j` gives `K_t,jj = +k_j`, a damper `Q_j = −c_j q̇_j` gives `C_t,jj = −c_j`, so the
/// diagonal gets `+β'h² k_j + γ'h c_j`.
///
/// The constraint rows are written with `c = 1` (`constraint_row_factor = 1`): that is the plain
/// derivative of `Φ(q(q̈))` (`Φ_q β'h²`) divided by `β'h²`, which keeps the condition number bounded
/// as `h → 0`. `constraint_row_factor = β'h²` gives the unscaled rows (condition ∝ h⁻²), exposed only
/// for [`iteration_matrix`]. With `beta_h2 = gamma_h = 0` and no diagonal this is the saddle-point
/// matrix `[M Φ_qᵀ; Φ_q 0]` of the consistent start and the velocity projection.
///
/// - `mass`: `nv × nv`; `diagonal`: `(stiffness, damping)`, each dim `nv` (`None` = no diagonal
///   terms); `phi_q`: `m × nv`; `out`: overwritten.
pub(crate) fn assemble_iteration_matrix(
    mass: &DMatrix<f64>,
    diagonal: Option<(&DVector<f64>, &DVector<f64>)>,
    phi_q: &DMatrix<f64>,
    beta_h2: f64,
    gamma_h: f64,
    constraint_row_factor: f64,
    out: &mut DMatrix<f64>,
) {
    let nv = mass.nrows();
    let m = phi_q.nrows();
    let n = nv + m;
    debug_assert_eq!((out.nrows(), out.ncols()), (n, n));
    // Column by column in the column-major storage: M's columns over the first nv rows, the
    // (scaled) constraint rows below them; Φ_qᵀ in the last m columns over a zero block.
    let mass = mass.as_slice();
    let out = out.as_mut_slice();
    for j in 0..nv {
        out[j * n..j * n + nv].copy_from_slice(&mass[j * nv..(j + 1) * nv]);
    }
    assemble_constraint_blocks(out, n, phi_q, constraint_row_factor);
    if let Some((k, c)) = diagonal {
        for j in 0..nv {
            out[j * n + j] += beta_h2 * k[j] + gamma_h * c[j];
        }
    }
}

/// The iteration matrix the integrator would factorise at `(t, q, v)`, for diagnostics (condition
/// numbers). Allocates.
///
/// - `t`: s; `q`: dim `nq`; `v`: dim `nv`; returns `(nv + m) × (nv + m)`.
/// - `scaling`: [`ConstraintRowScaling::Scaled`] is what [`HhtIntegrator`] uses.
///
/// Errors: settings errors, dimension mismatches, system errors and non-finite outputs.
pub fn iteration_matrix<S: DaeSystem + ?Sized>(
    system: &mut S,
    settings: &HhtSettings,
    t: f64,
    q: &DVector<f64>,
    v: &DVector<f64>,
    scaling: ConstraintRowScaling,
) -> Result<DMatrix<f64>, IntegrateError> {
    let (nq, nv, m) = (system.nq(), system.nv(), system.n_constraints());
    let coeffs = settings.validate(m)?;
    if q.len() != nq {
        return Err(IntegrateError::DimensionMismatch {
            what: "q",
            expected: nq,
            got: q.len(),
        });
    }
    if v.len() != nv {
        return Err(IntegrateError::DimensionMismatch {
            what: "v",
            expected: nv,
            got: v.len(),
        });
    }
    let at = At { t, step: 0 };
    let mut mass = DMatrix::zeros(nv, nv);
    eval::mass_matrix(system, at, q, &mut mass)?;
    let mut stiffness = DVector::zeros(nv);
    let mut damping = DVector::zeros(nv);
    if settings.newton_diagonal_terms {
        eval::newton_diagonal(system, at, q, v, &mut stiffness, &mut damping)?;
    }
    let mut phi_q = DMatrix::zeros(m, nv);
    if m > 0 {
        eval::constraint_jacobian(system, at, q, &mut phi_q)?;
    }
    let factor = match scaling {
        ConstraintRowScaling::Scaled => 1.0,
        ConstraintRowScaling::Unscaled => coeffs.beta_h2(),
    };
    let mut out = DMatrix::zeros(nv + m, nv + m);
    assemble_iteration_matrix(
        &mass,
        Some((&stiffness, &damping)),
        &phi_q,
        coeffs.beta_h2(),
        coeffs.gamma_h(),
        factor,
        &mut out,
    );
    Ok(out)
}

/// The HHT-α/Newmark update of an iterate ([`HhtIntegrator::update_iterate`]), whose
/// acceleration term the predictor's stiffness check also measures: one owner of the formulas.
#[derive(Clone, Copy)]
struct NewmarkUpdate {
    h: f64,
    alpha: f64,
    beta: f64,
    gamma: f64,
}

impl NewmarkUpdate {
    /// The update of a step with `coeffs`.
    fn of(coeffs: &HhtCoefficients) -> Self {
        Self {
            h: coeffs.h,
            alpha: coeffs.alpha,
            beta: coeffs.beta,
            gamma: coeffs.gamma,
        }
    }

    /// `a_{n+1} = (1 + α) q̈_{n+1} − α q̈_n`.
    #[inline(always)]
    fn acceleration(self, qdd: f64, qdd_n: f64) -> f64 {
        (1.0 + self.alpha) * qdd - self.alpha * qdd_n
    }

    /// The acceleration part of the position update, `h² [(½ − β) a_n + β a_{n+1}]`.
    #[inline(always)]
    fn acceleration_displacement(self, a_n: f64, a_new: f64) -> f64 {
        let (h, beta) = (self.h, self.beta);
        h * h * ((0.5 - beta) * a_n + beta * a_new)
    }

    /// `W` entries' `(a_{n+1}, Δq, q̇_{n+1})` from `q̈_{n+1}`, `q̈_n`, `a_n` and the Newmark
    /// `q̇_n`, lane by lane over arrays (vector instructions; each lane the operations of one
    /// entry).
    #[inline(always)]
    fn entries<const W: usize>(
        self,
        qdd: [f64; W],
        qdd_n: [f64; W],
        a_n: [f64; W],
        v_n: [f64; W],
    ) -> ([f64; W], [f64; W], [f64; W]) {
        let (h, gamma) = (self.h, self.gamma);
        let (mut a, mut dq, mut v) = ([0.0; W], [0.0; W], [0.0; W]);
        for l in 0..W {
            let a_new = self.acceleration(qdd[l], qdd_n[l]);
            a[l] = a_new;
            dq[l] = h * v_n[l] + self.acceleration_displacement(a_n[l], a_new);
            v[l] = v_n[l] + h * ((1.0 - gamma) * a_n[l] + gamma * a_new);
        }
        (a, dq, v)
    }
}

/// Whether a failed attempt is worth retrying with a smaller step: Newton failures, non-finite
/// numbers and a singular Newton matrix can all come from a step too long for the dynamics;
/// dimension mismatches and errors of the consistent start cannot.
fn retryable(error: &IntegrateError) -> bool {
    matches!(
        error,
        IntegrateError::NewtonNotConverged { .. }
            | IntegrateError::NonFinite { .. }
            | IntegrateError::SingularMatrix { .. }
            | IntegrateError::System { .. }
    )
}

/// The crossing of the cubic Hermite interpolant `p(θ)` through `p(0) = g0`, `p'(0) = d0`,
/// `p(1) = g1`, `p'(1) = d1` (with `g0 ≥ 0 > g1`): the root in `[0, 1]` found by bisection, and the
/// slope `p'(θ)` there (rate per unit `θ`). Bisection keeps the sign change bracketed, so it always
/// returns a crossing even where the cubic has three roots.
fn hermite_root(g0: f64, d0: f64, g1: f64, d1: f64) -> (f64, f64) {
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
