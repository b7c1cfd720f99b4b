//! The contract between the integrator and a mechanical system: [`DaeSystem`].
//!
//! The integrator sees the system only through this trait — no robot types, no effects, no scene. A
//! robot model implements it once (CRBA for `M`, RNEA for the bias, the scene's effects for `Q`, the
//! loop closures and drives for `Φ`).
//!
//! Equations (index-3 DAE, joint coordinates):
//!
//! ```text
//! M(q) q̈ + Φ_q(q, t)ᵀ λ = Q(t, q, q̇)        (nv rows)
//!              Φ(q, t) = 0                   (m rows)
//! ```
//!
//! Conventions:
//! - `q` has `nq` entries, velocities and accelerations `nv` (`nq ≠ nv` for a quaternion floating
//!   base). Every derivative "with respect to q" is taken along the tangent space: `Φ(q ⊕ δ) ≈ Φ(q) +
//!   Φ_q δ` with `δ` of dimension `nv` and `⊕` = [`DaeSystem::integrate_position`].
//! - `Q` is the right-hand side: generalised applied forces minus the bias `C(q, q̇) q̇ + g(q)`.
//! - `λ` has the sign fixed by `M q̈ + Φ_qᵀ λ = Q`: a drive row `Φ = q_j − f(t)` gives `λ = −τ`.
//! - Each method overwrites its `out` argument(s) entirely; sizes are checked by the integrator before
//!   the call, so implementations may index without checks.
//! - Methods return `Result`: report an invalid state (e.g. a singular configuration or a NaN the
//!   system detects itself) as an error rather than panicking. The integrator also checks every output
//!   for NaN/Inf itself.
//!
//! Optional groups of methods, all default-implemented so that a system only writes what it uses.
//! A capability whose methods have no sensible default is a sub-trait the system hands out through
//! an `Option`-returning hook (`None` by default), so that a system cannot claim it without
//! implementing it:
//! - **inverse dynamics** ([`DaeSystem::as_inverse_dynamics`], the sub-trait [`InverseDynamics`]):
//!   the residual `M q̈ − Q` in one pass, instead of `mass_matrix` and `forces`;
//! - **full residual Jacobians** ([`DaeSystem::as_residual_jacobians`], the sub-trait
//!   [`ResidualJacobians`]): `∂r/∂q` and `∂r/∂q̇` of the dynamics residual `r = M q̈ + Φ_qᵀ λ − Q`,
//!   what a full Newton matrix and the forward sensitivities need (docs/sensitivities.md §2);
//!   without them users form them by central differences of the residual;
//! - **the position update on a group** ([`DaeSystem::position_update_is_additive`],
//!   [`DaeSystem::integrate_position_jacobians`], [`DaeSystem::difference_position`]): how tangent
//!   perturbations travel through `q ⊕ δ` (docs/sensitivities.md §4);
//! - **parameters** ([`DaeSystem::n_parameters`], [`DaeSystem::parameter_jacobians`],
//!   [`DaeSystem::set_parameter_offset`]): the derivatives of the residual and the constraints with
//!   respect to the system's parameters `p_k`, for forward sensitivities (docs/sensitivities.md §3).

use nalgebra::{DMatrix, DVector};

use super::error::SystemError;

/// The default of [`DaeSystem::parameter_difference_step`]: a step of 1e-3 in a parameter of natural
/// scale 1. The 4-point central differences of whole computations (the consistent start, the
/// velocity projection) then have a truncation error of ~ε⁴/30 ≈ 3e-14 relative.
pub const PARAMETER_FD_STEP: f64 = 1e-3;

/// A multibody system `M(q) q̈ + Φ_qᵀ λ = Q(t, q, q̇)`, `Φ(q, t) = 0`, as the HHT-I3 integrator needs it.
///
/// Required methods: [`nq`](Self::nq), [`nv`](Self::nv), [`mass_matrix`](Self::mass_matrix),
/// [`forces`](Self::forces). A tree (no constraints) needs nothing else. A system with constraint
/// rows also implements [`n_constraints`](Self::n_constraints), [`constraints`](Self::constraints),
/// [`constraint_jacobian`](Self::constraint_jacobian),
/// [`constraint_acceleration_bias`](Self::constraint_acceleration_bias) and, when a row depends on
/// time explicitly (drives), [`constraint_time_derivative`](Self::constraint_time_derivative).
///
/// Methods take `&mut self` so that an implementation can keep its work buffers (a Pinocchio-style
/// `Data`) inside. Within one Newton iteration the integrator evaluates everything it needs at one
/// `(t, q, q̇)` consecutively (mass matrix and Jacobian first, then residual terms), so caching the
/// kinematics of the last `q` is effective.
pub trait DaeSystem {
    /// Number of position coordinates `nq` (length of `q`).
    fn nq(&self) -> usize;

    /// Number of velocity coordinates `nv` (length of `q̇`, `q̈`, `Q`; size of `M`).
    fn nv(&self) -> usize;

    /// Number of constraint rows `m` (length of `Φ` and `λ`). Default 0 (a tree): then the integrator
    /// never calls a constraint method and allocates no constraint storage.
    fn n_constraints(&self) -> usize {
        0
    }

    /// `out = q ⊕ dq`: the configuration reached from `q` by the tangent increment `dq`.
    ///
    /// - `q`: dim `nq`; `dq`: dim `nv`; `out`: dim `nq`, overwritten.
    ///
    /// Default: vector addition, valid when `nq == nv`. A floating base (quaternion) overrides it with
    /// the exponential map on SE(3)/SO(3) and renormalises the quaternion.
    fn integrate_position(
        &self,
        q: &DVector<f64>,
        dq: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        if q.len() != dq.len() || out.len() != q.len() {
            return Err(format!(
                "default integrate_position needs nq == nv (got q {}, dq {}, out {}); a system with \
                 nq != nv must implement integrate_position",
                q.len(),
                dq.len(),
                out.len()
            )
            .into());
        }
        for i in 0..q.len() {
            out[i] = q[i] + dq[i];
        }
        Ok(())
    }

    /// Whether [`DaeSystem::constraint_time_derivative`] writes `+0` into every row at every
    /// `(q, t)` (no row depends on time explicitly); the integrator then writes those zeros
    /// without asking. Default: `false`.
    fn constraints_are_scleronomic(&self) -> bool {
        false
    }

    /// Whether [`DaeSystem::position_scale`] is zero at every `q` (the Newton test weighs every
    /// coordinate by the absolute tolerance alone); the integrator then need not ask for it at
    /// every iteration. Default: `false`.
    fn position_scale_is_zero(&self) -> bool {
        false
    }

    /// Magnitude of each velocity coordinate's position, for the error weights of the Newton test
    /// (`ewt_i = 1 / (reltol · scale_i + abstol)`).
    ///
    /// - `q`: dim `nq`; `out`: dim `nv`, overwritten with values ≥ 0.
    ///
    /// Default: `|q_i|` when `nq == nv`, otherwise 0 (absolute tolerance only). A floating base may
    /// return `|x|, |y|, |z|` for its translation and 0 for its rotation.
    fn position_scale(&self, q: &DVector<f64>, out: &mut DVector<f64>) {
        if q.len() == out.len() {
            for i in 0..q.len() {
                out[i] = q[i].abs();
            }
        } else {
            out.fill(0.0);
        }
    }

    /// The joint-space mass matrix `M(q)` (symmetric positive definite).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: `nv × nv`, overwritten (both triangles).
    fn mass_matrix(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError>;

    /// The right-hand side `Q(t, q, q̇)` = generalised applied forces − `(C(q, q̇) q̇ + g(q))`.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `out`: dim `nv`, overwritten.
    fn forces(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError>;

    /// The inverse-dynamics residual `M q̈ − Q`, when the system has one (one inverse-dynamics
    /// pass, e.g. RNEA, O(nv), instead of `mass_matrix` + `forces`, CRBA, O(nv²)); the Newton
    /// residual then uses it, and `M` is only evaluated when the iteration matrix is factorised.
    /// Default `None`: the residual is formed from [`mass_matrix`](Self::mass_matrix) and
    /// [`forces`](Self::forces).
    fn as_inverse_dynamics(&mut self) -> Option<&mut dyn InverseDynamics> {
        None
    }

    /// The cheap diagonal parts of `−∂Q/∂q` and `−∂Q/∂q̇`: per velocity coordinate, the stiffness
    /// `k_j ≥ 0` of springs (and penalty limits) and the damping `c_j ≥ 0` of dampers acting on that
    /// coordinate alone. The modified Newton matrix adds `β'h² k_j + γ'h c_j` to `M_jj`; without them a
    /// stiff spring on a light link makes the iteration diverge.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`;
    /// - `stiffness_out`: dim `nv`, overwritten, N·m/rad or N/m;
    /// - `damping_out`: dim `nv`, overwritten, N·m·s/rad or N·s/m.
    ///
    /// Default: zeros (no springs or dampers).
    fn newton_diagonal(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DVector<f64>,
        damping_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v);
        stiffness_out.fill(0.0);
        damping_out.fill(0.0);
        Ok(())
    }

    /// Which regime of its piecewise forces the system is in at `q` (`q`: dim `nq`), as a
    /// fingerprint: for joint limits, one bit per joint beyond its limit. A piecewise force's
    /// Newton terms jump between regimes (a penalty spring's stiffness is `k` on one side, 0 on the
    /// other), so when a Newton iterate's regime differs from the one its matrix was formed in,
    /// the integrator refactorises at the iterate (docs/step-control.md §4). Default 0 (one
    /// regime).
    fn newton_regime(&self, q: &DVector<f64>) -> u64 {
        let _ = q;
        0
    }

    /// Whether the forces are smooth along a trajectory between steps, so that the predictor may
    /// extrapolate `q̈` and `λ` by polynomials of up to fourth order
    /// ([`HhtSettings::choose_predictor_order`](super::HhtSettings::choose_predictor_order)).
    /// Default `true`. A system whose forces switch within a step (contacts touching down, a
    /// sliding contact coming to stick) returns `false`: high orders extrapolate such a kink into
    /// an overshoot that Newton cannot recover from at the fixed step (docs/step-control.md §2).
    fn smooth_between_steps(&self) -> bool {
        true
    }

    /// Whether [`newton_diagonal`](Self::newton_diagonal) can be non-zero (springs, dampers,
    /// friction, limits). Default `true`; a system that answers `false` is never asked for it and
    /// its Newton matrix is `M` alone (the same bits as adding a zero diagonal).
    fn provides_newton_diagonal(&self) -> bool {
        true
    }

    /// Whether [`newton_coupling`](Self::newton_coupling) adds anything. Default `false`.
    fn provides_newton_coupling(&self) -> bool {
        false
    }

    /// The parts of `−∂Q/∂q` and `−∂Q/∂q̇` that couple coordinates — forces acting on several
    /// joints at once, such as contacts (`Jᵀ K J`, `Jᵀ C J`; docs/contacts.md §4) — which the
    /// modified Newton matrix adds as `β'h² K + γ'h C` beside the diagonal of
    /// [`newton_diagonal`](Self::newton_diagonal) (which must not contain them too).
    ///
    /// - `t`: s; `q`: dim `nq`; `v`: dim `nv`;
    /// - `stiffness_out`, `damping_out`: `nv × nv`, overwritten (N·m/rad or N/m; N·m·s/rad or
    ///   N·s/m per column).
    ///
    /// Only called when [`provides_newton_coupling`](Self::provides_newton_coupling) is `true`.
    fn newton_coupling(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v);
        stiffness_out.fill(0.0);
        damping_out.fill(0.0);
        Ok(())
    }

    /// A state check of the adaptive step (docs/step-control.md §3, docs/contacts.md §4): a value
    /// above 1 for a sub-step from `q_start` to `q_end` makes
    /// [`StepControl::Adaptive`](super::StepControl) reject it and retry with half the step (down
    /// to the smallest sub-step), e.g. a contact whose penetration grew by more than the scene
    /// allows in one sub-step (a fast touch-down). Default 0 (every sub-step acceptable).
    ///
    /// - `t`: s (end of the sub-step); `q_start`, `q_end`: dim `nq`; returns a ratio ≥ 0.
    fn state_rejection(
        &mut self,
        t: f64,
        q_start: &DVector<f64>,
        q_end: &DVector<f64>,
    ) -> Result<f64, SystemError> {
        let _ = (t, q_start, q_end);
        Ok(0.0)
    }

    /// The constraint values `Φ(q, t)`.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: dim `m`, overwritten (m or rad, per row).
    ///
    /// Default: nothing to do for `m = 0`; an error if a system declares rows without implementing it.
    fn constraints(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraints() is not implemented but n_constraints() > 0".into())
        }
    }

    /// The constraint Jacobian `Φ_q` along the tangent space (`Φ(q ⊕ δ) ≈ Φ + Φ_q δ`).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: `m × nv`, overwritten.
    fn constraint_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraint_jacobian() is not implemented but n_constraints() > 0".into())
        }
    }

    /// `Φ(q, t)` and `Φ_q(q)` at one configuration, as [`constraints`](Self::constraints) and
    /// [`constraint_jacobian`](Self::constraint_jacobian) would give them (same bits); a system
    /// overrides it to share the work both need (the kinematics of a loop's chains).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `phi`: dim `m`; `phi_q`: `m × nv`; both overwritten.
    fn constraints_and_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        phi: &mut DVector<f64>,
        phi_q: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.constraints(t, q, phi)?;
        self.constraint_jacobian(t, q, phi_q)
    }

    /// The explicit time derivative `Φ_t(q, t)` (rheonomic rows such as drives; velocity level:
    /// `Φ̇ = Φ_q q̇ + Φ_t`).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: dim `m`, overwritten.
    ///
    /// Default: zeros (scleronomic constraints).
    ///
    /// A system whose `Φ_t` is zero at every `(q, t)` says so with
    /// [`DaeSystem::constraints_are_scleronomic`], and the integrator writes the zeros itself.
    fn constraint_time_derivative(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        out.fill(0.0);
        Ok(())
    }

    /// Number of unilateral limits `g_k(q) ≥ 0` the integrator watches for impacts
    /// (docs/step-control.md §4). Default 0: the integrator then never calls [`event_gaps`](Self::event_gaps) or
    /// [`apply_impact`](Self::apply_impact).
    fn n_events(&self) -> usize {
        0
    }

    /// The gaps `g_k(q)` (allowed side `g ≥ 0`, m or rad) and their rates `ġ_k = ∂g_k/∂q · q̇` of
    /// every unilateral limit. A step that starts with `g_k ≥ 0` and ends with `g_k < 0`, crossing
    /// at an approach speed `−ġ_k` of at least [`IMPACT_MIN_SPEED`](super::IMPACT_MIN_SPEED), is an
    /// impact: the integrator locates it and calls [`apply_impact`](Self::apply_impact).
    ///
    /// - `t`: s; `q`: dim `nq`; `v`: dim `nv`; `gaps_out`, `rates_out`: dim `n_events`, overwritten.
    fn event_gaps(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        gaps_out: &mut DVector<f64>,
        rates_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v, gaps_out, rates_out);
        Err("event_gaps is not implemented but n_events() > 0".into())
    }

    /// The impact law of limit `event` at the located contact state: moves `q` onto the limit
    /// (`g_event = 0`; a correction of rounding size) and replaces `v` by the post-impact velocity
    /// (restitution, never more kinetic energy than before). The integrator then restarts from
    /// `(t, q, v)` with a consistent start.
    ///
    /// - `t`: s; `event`: `0..n_events()`; `q`: dim `nq`, `v`: dim `nv`, both overwritten.
    fn apply_impact(
        &mut self,
        t: f64,
        event: usize,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, event, q, v);
        Err("apply_impact is not implemented but n_events() > 0".into())
    }

    /// The full Jacobians of the dynamics residual, when the system has them (what a full Newton
    /// matrix and the forward sensitivities need). Default `None`: a user that needs them (the
    /// forward sensitivities of [`HhtSensitivity`](super::HhtSensitivity)) then forms them by
    /// central differences of the residual, `2 nv` evaluations each (docs/sensitivities.md §2), and
    /// the integrator keeps to the diagonal Newton matrix.
    fn as_residual_jacobians(&mut self) -> Option<&mut dyn ResidualJacobians> {
        None
    }

    /// Whether `q ⊕ δ` is plain vector addition (`nq == nv`, every coordinate additive), so that a
    /// tangent perturbation passes through the position update unchanged. Default `nq == nv`, which
    /// matches the default [`integrate_position`](Self::integrate_position); a system that
    /// overrides `integrate_position` with a group update overrides this too (and
    /// [`integrate_position_jacobians`](Self::integrate_position_jacobians)).
    fn position_update_is_additive(&self) -> bool {
        self.nq() == self.nv()
    }

    /// How a tangent perturbation passes through the position update `q⁺ = q ⊕ dq`
    /// (docs/sensitivities.md §4): with `q` perturbed to `q ⊕ δq` and `dq` to `dq + δdq`,
    ///
    /// ```text
    /// q⁺ is perturbed to q⁺ ⊕ (A δq + B δdq)       A = wrt_q_out, B = wrt_dq_out
    /// ```
    ///
    /// (on SE(3) with `q ⊕ δ = q · Exp(δ)`: `A = Ad(Exp(−dq))`, `B` = the right Jacobian of `Exp` at
    /// `dq`).
    ///
    /// - `q`: dim `nq`; `dq`: dim `nv`; `wrt_q_out`, `wrt_dq_out`: `nv × nv`, overwritten.
    ///
    /// Only called when [`position_update_is_additive`](Self::position_update_is_additive) is
    /// `false`. Default: identities when `nq == nv`, an error otherwise.
    fn integrate_position_jacobians(
        &self,
        q: &DVector<f64>,
        dq: &DVector<f64>,
        wrt_q_out: &mut DMatrix<f64>,
        wrt_dq_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        if q.len() != dq.len() {
            return Err(
                "integrate_position_jacobians must be implemented by a system with nq != nv".into(),
            );
        }
        wrt_q_out.fill_with_identity();
        wrt_dq_out.fill_with_identity();
        Ok(())
    }

    /// `out = q1 ⊖ q0`: the tangent increment `δ` with `q0 ⊕ δ = q1` (the inverse of
    /// [`integrate_position`](Self::integrate_position)); used to difference two configurations,
    /// e.g. the consistent starts of two parameter values.
    ///
    /// - `q0`, `q1`: dim `nq`; `out`: dim `nv`, overwritten.
    ///
    /// Default: `q1 − q0` when `nq == nv`, an error otherwise.
    fn difference_position(
        &self,
        q0: &DVector<f64>,
        q1: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        if q0.len() != out.len() || q1.len() != out.len() {
            return Err(format!(
                "default difference_position needs nq == nv (got q0 {}, q1 {}, out {}); a system \
                 with nq != nv must implement difference_position",
                q0.len(),
                q1.len(),
                out.len()
            )
            .into());
        }
        for i in 0..out.len() {
            out[i] = q1[i] - q0[i];
        }
        Ok(())
    }

    /// Number of parameters `P` the system can be differentiated by (docs/sensitivities.md §3).
    /// Default 0.
    ///
    /// Parameters are coordinates `p_k` of the system's own choosing, with one convention that
    /// finite differences rely on: **a parameter's natural scale is 1** (its plausible range is about
    /// `p_k ± 1`, as for the standard coordinate `ξ ∈ [−1, 1]` of docs/method.md §1), so that a step of
    /// 1e-3 in `p_k` is a small relative change. The current values are `p = 0`.
    fn n_parameters(&self) -> usize {
        0
    }

    /// The partial derivatives of the residual and of the constraints with respect to every
    /// parameter, at fixed `(t, q, q̇, q̈, λ)` (docs/sensitivities.md §3):
    ///
    /// ```text
    /// dynamics_out[:, k]    = ∂(M q̈ + Φ_qᵀ λ − Q)/∂p_k      (nv × P; N·m or N per unit p_k)
    /// constraints_out[:, k] = ∂Φ/∂p_k                        (m × P; m or rad per unit p_k)
    /// ```
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`, `qdd`: dim `nv`; `lambda`: dim `m`; both outputs
    ///   overwritten. Called with every parameter at its current value (no offset).
    ///
    /// Default: an error (no parameters).
    #[allow(clippy::too_many_arguments)]
    fn parameter_jacobians(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        lambda: &DVector<f64>,
        dynamics_out: &mut DMatrix<f64>,
        constraints_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v, qdd, lambda, dynamics_out, constraints_out);
        Err("parameter_jacobians is not implemented by this system".into())
    }

    /// A step in `p_k` for central differences of whole computations (the consistent start, the
    /// velocity projection; docs/sensitivities.md §5, §6): as large as the system's nonlinearity
    /// allows, since their rounding error is divided by it. Default
    /// [`PARAMETER_FD_STEP`] (1e-3, for a parameter of natural scale 1).
    fn parameter_difference_step(&self, k: usize) -> f64 {
        let _ = k;
        PARAMETER_FD_STEP
    }

    /// Moves the system to the parameter point `p = offset · e_k` (every other parameter at its
    /// current value); `offset = 0` restores the current point exactly. Each call replaces the
    /// previous offset (offsets never accumulate). Used for finite differences of whole
    /// computations — the consistent start, the velocity projection — along one parameter
    /// (docs/sensitivities.md §5, §6).
    ///
    /// - `k`: `0..n_parameters()`; `offset`: in units of `p_k` (natural scale 1).
    ///
    /// Default: an error (no parameters).
    fn set_parameter_offset(&mut self, k: usize, offset: f64) -> Result<(), SystemError> {
        let _ = (k, offset);
        Err("set_parameter_offset is not implemented by this system".into())
    }

    /// Whether [`DaeSystem::newton_update_fraction`] may shorten Newton corrections at the current
    /// state. Default `false`; when `false` the integrator never calls it, so a system without a
    /// narrow regularised law pays nothing and its iterates are unchanged.
    fn limits_newton_updates(&self) -> bool {
        false
    }

    /// The fraction in `(0, 1]` of a Newton correction to apply at the iterate `(q, v)` whose full
    /// correction would change the velocity by `dv` (dim `nv`). For laws with a narrow transition,
    /// such as regularised friction, whose slope changes by orders of magnitude within a small
    /// velocity band: a full correction computed with a matrix from outside the band jumps across
    /// it, and the iteration oscillates from one side to the other (docs/contacts.md §4, "Newton
    /// across the stiction band"). Default 1 (the full correction).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `dv`: dim `nv`.
    fn newton_update_fraction(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        dv: &DVector<f64>,
    ) -> Result<f64, SystemError> {
        let _ = (t, q, v, dv);
        Ok(1.0)
    }

    /// The acceleration-level right-hand side `Φ_q q̈ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt`, used once for
    /// the consistent initial acceleration and multipliers.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `out`: dim `m`, overwritten.
    fn constraint_acceleration_bias(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraint_acceleration_bias() is not implemented but n_constraints() > 0".into())
        }
    }
}

/// The inverse-dynamics residual of a system that has one: a [`DaeSystem`] offers it through
/// [`DaeSystem::as_inverse_dynamics`].
pub trait InverseDynamics {
    /// `out = M(q) q̈ − Q(t, q, q̇)` (the inverse-dynamics residual, without the constraint forces).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `qdd`: dim `nv`; `out`: dim `nv`, overwritten.
    fn dynamics_residual(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError>;

    /// [`dynamics_residual`](Self::dynamics_residual) at the configuration `q` of the last
    /// [`DaeSystem::mass_matrix`] call: the integrator calls it for the first residual
    /// after it factorised at that iterate, so that a system may reuse the mass matrix's
    /// kinematics. It must give the same bits as `dynamics_residual`. Default: that call.
    fn dynamics_residual_after_mass_matrix(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.dynamics_residual(t, q, v, qdd, out)
    }
}

/// The full Jacobians of the dynamics residual of a system that has them: a [`DaeSystem`] offers
/// them through [`DaeSystem::as_residual_jacobians`].
pub trait ResidualJacobians {
    /// The full Jacobians of the dynamics residual `r(q, q̇) = M(q) q̈ + Φ_q(q, t)ᵀ λ − Q(t, q, q̇)` at
    /// fixed `q̈` and `λ` (docs/sensitivities.md §2):
    ///
    /// ```text
    /// stiffness_out = ∂r/∂q  = ∂(M q̈)/∂q + ∂(Φ_qᵀ λ)/∂q − ∂Q/∂q     (the tangent stiffness K_t)
    /// damping_out   = ∂r/∂q̇ = −∂Q/∂q̇                              (the tangent damping  D_t)
    /// ```
    ///
    /// `∂/∂q` is taken along the tangent space (column `i`: the derivative along `q ⊕ ε e_i`). These
    /// are what a full Newton matrix `M + β'h² K_t + γ'h D_t` needs; the diagonal of
    /// [`DaeSystem::newton_diagonal`] is the cheap part of them.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`, `qdd`: dim `nv`; `lambda`: dim `m`;
    /// - `stiffness_out`: `nv × nv`, overwritten (N·m/rad or N/m per column);
    /// - `damping_out`: `nv × nv`, overwritten (N·m·s/rad or N·s/m per column).
    #[allow(clippy::too_many_arguments)]
    fn residual_jacobians(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        lambda: &DVector<f64>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError>;
}
