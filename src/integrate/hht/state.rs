//! What one trajectory carries from step to step: the state ([`HhtState`]) and the whole carried
//! bundle ([`HhtTrajectory`]: state, predictor history, statistics, step control, Newton memory) a
//! study swaps between samples; also whether a grid step computes the velocity it reports
//! ([`ReportedVelocity`]).

use super::newton::NewtonMemory;
use super::predictor::{pull, PredictorHistory};
use super::stats::HhtStats;
use super::step_size::StepControlState;
use crate::integrate::system::DaeState;
use nalgebra::DVector;

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
    /// Newmark velocity (see [`HhtSettings::velocity_projection`](crate::integrate::HhtSettings::velocity_projection)). After a step that left the
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

impl HhtState {
    /// The state as a point of the DAE, `(t, q, q̇, q̈, λ)`, with the reported velocity.
    pub fn point(&self) -> DaeState<'_> {
        DaeState {
            t: self.t,
            q: &self.q,
            v: &self.v,
            qdd: &self.qdd,
            lambda: &self.lambda,
        }
    }
}

/// Whether a grid step computes the velocity it reports ([`HhtIntegrator::advance`](crate::integrate::HhtIntegrator::advance)). Only systems
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

/// Everything that carries one trajectory from step to step — start time, state, the recursion's
/// velocity, the predictor's history, statistics, step control and the reusable Newton
/// factorisation — without the workspace. The integrator owns one (its only per-trajectory state);
/// a study keeps one per sample and advances many samples in turn with one integrator per thread
/// ([`HhtIntegrator::swap_trajectory`](crate::integrate::HhtIntegrator::swap_trajectory) exchanges the whole struct).
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
    pub(super) newton: NewtonMemory,
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
