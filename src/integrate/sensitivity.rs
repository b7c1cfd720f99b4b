//! Forward sensitivities of an HHT-I3 trajectory with respect to the system's parameters, by direct
//! differentiation of the converged step (docs/sensitivities.md): [`HhtSensitivity`].
//!
//! One step, as data flow (docs/sensitivities.md §1–§4):
//!
//! ```text
//! (state_n, S_n) => HhtIntegrator::step => state_{n+1}                     (unchanged integrator)
//!   => at the converged (t, q, q̇, q̈, λ)_{n+1}: M, Φ_q, K_t = ∂r/∂q, D_t = ∂r/∂q̇
//!      (the system's, or central differences of the residual), the group update's A, B,
//!      ∂r/∂p and ∂Φ/∂p for every parameter
//!   => J = [M + β'h² K_t B + γ'h D_t   Φ_qᵀ; Φ_q B   0], factorised once
//!   => per parameter one solve for (∂q̈_{n+1}/∂p_k, ∂λ_{n+1}/∂p_k)
//!   => the Newmark updates of S: S_a, S_q (tangent), S_q̇
//! ```
//!
//! The start (§5): without constraint rows `q_0`, `q̇_0` do not depend on the parameters and
//! `∂q̈_0/∂p = −M⁻¹ ∂r/∂p` exactly; with rows, the consistent start is differenced along each
//! parameter (a 4-point central difference of
//! [`consistent_start`](crate::integrate::consistent_start)). The reported velocity of a
//! constrained run is projected; its sensitivity is a directional central difference of the
//! projection at record times only (§6).
//!
//! What it does not do: second-order sensitivities, adjoints, adaptive steps. Per step it allocates
//! nothing; the start allocates (it runs [`consistent_start`](crate::integrate::consistent_start)).
//!
//! Files: this one holds the state, the step and its differentiation; `sensitivity/at_start.rs` the
//! start's sensitivities (§5), `sensitivity/projection.rs` the reported velocity's (§6).

use nalgebra::{DMatrix, DVector};

use super::dense_solver::{DenseSolver, FactorKind};
use super::error::IntegrateError;
use super::eval::{self, At};
use super::hht::HhtIntegrator;
use super::settings::HhtCoefficients;
use super::system::{DaeState, DaeSystem};

mod at_start;
mod projection;

/// Step, in tangent coordinates (rad or m) and in velocities (rad/s or m/s), of the central
/// differences that form `K_t` and `D_t` when the system does not provide them
/// (docs/sensitivities.md §2). Joint coordinates are nonlinear on a scale of ~1 rad or ~1 m, so
/// the truncation error is ~ε²/6 ≈ 2e-13 relative; rounding costs ~u·|r|/ε ≈ 1e-10 of the residual's
/// terms. Smoothed friction (`v_s` = 1e-2 rad/s) is the sharpest nonlinearity in velocity:
/// (ε/v_s)²/3 ≈ 3e-9 relative on its term.
pub const JACOBIAN_FD_STEP: f64 = 1e-6;

/// Largest tangent step, rad or m, of the directional 4-point central difference of the velocity
/// projection (docs/sensitivities.md §6): the parameter step is the smaller of the system's
/// [`Parameters::parameter_difference_step`](crate::integrate::Parameters::parameter_difference_step) and this over `max(1, ‖S_q[:, k]‖∞)`. Configurations are
/// nonlinear on the scale of 1 rad or 1 m, so truncation is ~3e-14 relative; the correction is linear
/// in the velocity. Rounding of `Φ_q q̇` (terms of ~|q̇|) costs ~u·|q̇|/ε.
pub const PROJECTION_FD_STEP: f64 = 1e-3;

/// The 4-point central-difference stencil `f' ≈ Σ w f(p + o ε) / 12ε`: `(o, w)`.
const STENCIL: [(f64, f64); 4] = [(2.0, -1.0), (1.0, 8.0), (-1.0, -8.0), (-2.0, 1.0)];

/// Why a sensitivity computation failed.
#[derive(Debug, thiserror::Error)]
pub enum SensitivityError {
    /// The integrator (or a system call made for the sensitivities) failed; names time and step.
    #[error(transparent)]
    Integrate(#[from] IntegrateError),
    /// The sensitivities were started from an integrator that has already stepped.
    #[error(
        "forward sensitivities must start with the trajectory (integrator at step {step}, not 0): \
         create HhtSensitivity right after HhtIntegrator::new or restart"
    )]
    NotAtStart {
        /// The integrator's step count.
        step: u64,
    },
    /// The integrator's velocity projection takes the Newton matrix's `M`, which depends on where
    /// each step's iteration started; the sensitivities differentiate the projection with
    /// `M(q_{n+1})`.
    #[error(
        "forward sensitivities of a constrained run need the velocity projection's metric at          q_{{n+1}}: start the integrator with HhtSettings::projection_keeps_newton_mass = false"
    )]
    ProjectionMetric,
    /// The integrator was stepped without the sensitivities (or another trajectory was swapped in).
    #[error(
        "the integrator is at step {integrator_step} but the sensitivities at step \
         {sensitivity_step}: step both through HhtSensitivity::step"
    )]
    OutOfStep {
        /// The integrator's step count.
        integrator_step: u64,
        /// The sensitivities' step count.
        sensitivity_step: u64,
    },
    /// The grid step just taken was not one plain HHT step of `h`: it was subdivided (a Newton
    /// failure retried as halves, adaptive sub-steps) or contained an impact. The differentiated
    /// step covers plain steps only; an impact's jump would need its own derivative (a saltation
    /// matrix), which is not implemented.
    #[error(
        "forward sensitivities cover plain steps only, but the step to t = {t} s was subdivided or          contained an impact ({substeps} sub-steps, {impacts} impacts so far): use the fixed step          with a step small enough that Newton converges, and no joint-limit impacts"
    )]
    SubdividedStep {
        /// Time reached, s.
        t: f64,
        /// Sub-steps of the trajectory so far.
        substeps: u64,
        /// Impacts of the trajectory so far.
        impacts: u64,
    },
}

/// Counters of one sensitivity run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensitivityStats {
    /// Differentiated steps.
    pub steps: u64,
    /// Parameters `P`.
    pub parameters: usize,
    /// Factorisations of the exact step Jacobian `J` (one per step).
    pub factorisations: u64,
    /// Right-hand sides solved with `J` (`P` per step).
    pub solves: u64,
    /// Residual evaluations spent on central differences of `K_t` and `D_t` (`4 nv` per step when
    /// the system does not provide [`DaeSystem::as_residual_jacobians`], else 0).
    pub jacobian_residual_evaluations: u64,
    /// Consistent starts computed for the start's central difference (`4 P` with constraint rows,
    /// else 0).
    pub start_evaluations: usize,
    /// Velocity projections computed for the reported velocity's sensitivity (`4 P` per record of a
    /// constrained run with velocity projection, else 0).
    pub projection_evaluations: u64,
}

/// Preallocated buffers (sizes `nq`, `nv`, `m`, `P`, `n = nv + m`).
#[derive(Debug, Clone)]
struct Workspace {
    /// M, nv × nv.
    mass: DMatrix<f64>,
    /// M at a perturbed point (residual without `dynamics_residual`), nv × nv.
    mass_scratch: DMatrix<f64>,
    /// Φ_q, m × nv.
    phi_q: DMatrix<f64>,
    /// Φ_q at a perturbed point, m × nv.
    phi_q_scratch: DMatrix<f64>,
    /// K_t, nv × nv.
    stiffness: DMatrix<f64>,
    /// D_t, nv × nv.
    damping: DMatrix<f64>,
    /// A of the group update, nv × nv.
    wrt_q: DMatrix<f64>,
    /// B of the group update, nv × nv.
    wrt_dq: DMatrix<f64>,
    /// K_t B, nv × nv.
    stiffness_b: DMatrix<f64>,
    /// Φ_q B, m × nv.
    phi_q_b: DMatrix<f64>,
    /// ∂r/∂p, nv × P.
    dynamics_p: DMatrix<f64>,
    /// ∂Φ/∂p, m × P.
    constraints_p: DMatrix<f64>,
    /// h S_q̇ + h²(½ − β) S_a − h²βα S_q̈ (the tangent increment's known part), nv × P.
    increment: DMatrix<f64>,
    /// δq_pred, nv × P.
    predicted_q: DMatrix<f64>,
    /// S_q̇ predicted, nv × P.
    predicted_v: DMatrix<f64>,
    /// Right-hand sides of the dynamics rows, nv × P.
    rhs_dynamics: DMatrix<f64>,
    /// Right-hand sides of the constraint rows, m × P.
    rhs_constraints: DMatrix<f64>,
    /// ∂q̈_{n+1}/∂p, nv × P.
    new_qdd: DMatrix<f64>,
    /// B ∂q̈_{n+1}/∂p, nv × P.
    b_new_qdd: DMatrix<f64>,
    /// J, then projection matrices, n × n.
    matrix: DMatrix<f64>,
    /// Factorisation of `matrix`.
    solver: DenseSolver,
    /// One right-hand side, dim n.
    rhs: DVector<f64>,
    /// Perturbed q, dim nq.
    q_perturbed: DVector<f64>,
    /// Tangent increment, dim nv.
    dq: DVector<f64>,
    /// Perturbed velocity, dim nv.
    v_perturbed: DVector<f64>,
    /// Residual at +ε, dim nv.
    r_plus: DVector<f64>,
    /// Residual at −ε, dim nv.
    r_minus: DVector<f64>,
    /// Q, dim nv.
    forces: DVector<f64>,
    /// Φ_t, dim m.
    phi_t: DVector<f64>,
    /// The projection correction's derivative being summed, dim nv.
    dv_plus: DVector<f64>,
}

impl Workspace {
    /// `dynamics_p = ∂r/∂p` and `constraints_p = ∂Φ/∂p` at `point`, the dynamics checked finite
    /// (the caller checks the constraints' where it reads them).
    fn parameter_jacobians_at<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        point: &DaeState<'_>,
    ) -> Result<(), IntegrateError> {
        eval::parameter_jacobians(
            system,
            at,
            point,
            &mut self.dynamics_p,
            &mut self.constraints_p,
        )?;
        at.check_finite("parameter_jacobians.dynamics", self.dynamics_p.as_slice())
    }

    fn new(nq: usize, nv: usize, m: usize, p: usize) -> Self {
        let n = nv + m;
        Self {
            mass: DMatrix::zeros(nv, nv),
            mass_scratch: DMatrix::zeros(nv, nv),
            phi_q: DMatrix::zeros(m, nv),
            phi_q_scratch: DMatrix::zeros(m, nv),
            stiffness: DMatrix::zeros(nv, nv),
            damping: DMatrix::zeros(nv, nv),
            wrt_q: DMatrix::identity(nv, nv),
            wrt_dq: DMatrix::identity(nv, nv),
            stiffness_b: DMatrix::zeros(nv, nv),
            phi_q_b: DMatrix::zeros(m, nv),
            dynamics_p: DMatrix::zeros(nv, p),
            constraints_p: DMatrix::zeros(m, p),
            increment: DMatrix::zeros(nv, p),
            predicted_q: DMatrix::zeros(nv, p),
            predicted_v: DMatrix::zeros(nv, p),
            rhs_dynamics: DMatrix::zeros(nv, p),
            rhs_constraints: DMatrix::zeros(m, p),
            new_qdd: DMatrix::zeros(nv, p),
            b_new_qdd: DMatrix::zeros(nv, p),
            matrix: DMatrix::zeros(n, n),
            solver: DenseSolver::new(n, FactorKind::Lu),
            rhs: DVector::zeros(n),
            q_perturbed: DVector::zeros(nq),
            dq: DVector::zeros(nv),
            v_perturbed: DVector::zeros(nv),
            r_plus: DVector::zeros(nv),
            r_minus: DVector::zeros(nv),
            forces: DVector::zeros(nv),
            phi_t: DVector::zeros(m),
            dv_plus: DVector::zeros(nv),
        }
    }
}

/// The forward sensitivities `S = ∂(state)/∂p` of one HHT-I3 trajectory, advanced step by step beside
/// its [`HhtIntegrator`] (docs/sensitivities.md).
///
/// Every sensitivity is a matrix with one column per parameter `p_k` (`P` = the system's [`Parameters::n_parameters`](crate::integrate::Parameters::n_parameters), 0 without them):
/// positions along the tangent space (`q(p + ε e_k) ≈ q ⊕ ε S_q[:, k]`), velocities, accelerations
/// and multipliers as plain derivatives. Use it as
///
/// ```text
/// let mut hht = HhtIntegrator::new(&mut system, settings, t0, &q0, &v0)?;
/// let mut sens = HhtSensitivity::new(&mut system, &hht, &q0, &v0)?;
/// loop { sens.step(&mut system, &mut hht)?; … sens.position(), sens.reported_velocity(…) … }
/// ```
///
/// The system provides its [`Parameters`](crate::integrate::Parameters) through [`DaeSystem::as_parameters`] (their Jacobians,
/// and with constraint rows [`Parameters::set_parameter_offset`](crate::integrate::Parameters::set_parameter_offset));
/// [`DaeSystem::as_residual_jacobians`] is used when provided,
/// otherwise `K_t` and `D_t` come from central differences of the residual ([`JACOBIAN_FD_STEP`]).
#[derive(Debug, Clone)]
pub struct HhtSensitivity {
    nq: usize,
    nv: usize,
    m: usize,
    p: usize,
    coeffs: HhtCoefficients,
    velocity_projection: bool,
    additive: bool,
    /// Step count of the carried sensitivities.
    step: u64,
    /// ∂q/∂p along the tangent space, nv × P.
    s_q: DMatrix<f64>,
    /// ∂(Newmark q̇)/∂p, nv × P.
    s_v: DMatrix<f64>,
    /// ∂a/∂p, nv × P.
    s_a: DMatrix<f64>,
    /// ∂q̈/∂p, nv × P.
    s_qdd: DMatrix<f64>,
    /// ∂λ/∂p, m × P.
    s_lambda: DMatrix<f64>,
    /// ∂q_0/∂p along the tangent space at the start, nv × P.
    s_q_start: DMatrix<f64>,
    /// ∂(reported q̇)/∂p, nv × P (valid when `reported_fresh`).
    s_v_reported: DMatrix<f64>,
    reported_fresh: bool,
    /// q_n, Newmark q̇_n and a_n kept over a step (for the group update's Jacobians).
    q_before: DVector<f64>,
    v_before: DVector<f64>,
    a_before: DVector<f64>,
    stats: SensitivityStats,
    ws: Workspace,
}

/// `y += a · x` over matching slices.
fn add_scaled(y: &mut [f64], a: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

impl HhtSensitivity {
    /// Number of parameters `P`.
    pub fn n_parameters(&self) -> usize {
        self.p
    }

    /// `∂q/∂p` along the tangent space at the current state (`q(p + ε e_k) ≈ q ⊕ ε S[:, k]`),
    /// `nv × P`.
    pub fn position(&self) -> &DMatrix<f64> {
        &self.s_q
    }

    /// `∂q_0/∂p` along the tangent space at the start, `nv × P` (for outputs relative to the start,
    /// such as a floating base's rotation vector).
    pub fn start_position(&self) -> &DMatrix<f64> {
        &self.s_q_start
    }

    /// `∂q̇/∂p` of the Newmark velocity the recursion carries, `nv × P` (equal to the reported
    /// velocity's without velocity projection; see [`HhtSensitivity::reported_velocity`]).
    pub fn newmark_velocity(&self) -> &DMatrix<f64> {
        &self.s_v
    }

    /// `∂q̈/∂p`, `nv × P`.
    pub fn acceleration(&self) -> &DMatrix<f64> {
        &self.s_qdd
    }

    /// `∂λ/∂p`, `m × P`.
    pub fn multipliers(&self) -> &DMatrix<f64> {
        &self.s_lambda
    }

    /// Counters so far.
    pub fn stats(&self) -> &SensitivityStats {
        &self.stats
    }

    fn check_in_step(&self, integrator: &HhtIntegrator) -> Result<(), SensitivityError> {
        let integrator_step = integrator.state().step;
        if integrator_step != self.step {
            return Err(SensitivityError::OutOfStep {
                integrator_step,
                sensitivity_step: self.step,
            });
        }
        Ok(())
    }

    /// Advances `integrator` by one step and the sensitivities with it (docs/sensitivities.md §1–§4).
    ///
    /// Errors: the integrator's own errors (its state is then left at `t_n`, and so are the
    /// sensitivities); system errors of the derivative calls; [`SensitivityError::OutOfStep`] when the
    /// integrator was stepped elsewhere. Allocation-free.
    pub fn step<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &mut HhtIntegrator,
    ) -> Result<(), SensitivityError> {
        self.check_in_step(integrator)?;
        eval::check_dimensions(system, self.nq, self.nv, self.m)?;
        {
            let state = integrator.state();
            self.q_before.copy_from(&state.q);
            self.a_before.copy_from(&state.a);
        }
        self.v_before.copy_from(integrator.newmark_velocity());
        integrator.step(system)?;
        if !integrator.control().last_step_plain {
            let stats = integrator.stats();
            return Err(SensitivityError::SubdividedStep {
                t: integrator.state().t,
                substeps: stats.substeps,
                impacts: stats.impacts,
            });
        }
        self.step += 1;
        self.reported_fresh = false;
        if self.p > 0 {
            self.differentiate(system, integrator)?;
        }
        self.stats.steps += 1;
        Ok(())
    }

    /// The differentiated step at the converged point of `integrator` (docs/sensitivities.md §1):
    ///
    /// ```text
    /// δq_pred = A S_q + B (h S_q̇ + h²(½ − β) S_a − h²βα S_q̈)        S_q̇,pred = S_q̇ + h(1 − γ) S_a − hγα S_q̈
    /// [ M + β'h² K_t B + γ'h D_t    Φ_qᵀ ] [s]     [ ∂r/∂p + K_t δq_pred + D_t S_q̇,pred ]
    /// [ Φ_q B                        0   ] [μ] = − [ (∂Φ/∂p + Φ_q δq_pred) / (β'h²)     ]
    /// S_q̈ ← s,  S_λ ← μ,  S_a ← (1 + α) s − α S_q̈,  S_q ← δq_pred + β'h² B s,  S_q̇ ← S_q̇,pred + γ'h s
    /// ```
    fn differentiate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
    ) -> Result<(), SensitivityError> {
        let c = self.coeffs;
        let (h, alpha, beta, gamma) = (c.h, c.alpha, c.beta, c.gamma);
        let (beta_h2, gamma_h) = (c.beta_h2(), c.gamma_h());
        let (nv, m, p) = (self.nv, self.m, self.p);
        let state = integrator.state();
        let v_newmark = integrator.newmark_velocity();
        let at = At {
            t: state.t,
            step: state.step,
        };

        // Everything at the converged point.
        eval::mass_matrix(system, at, &state.q, &mut self.ws.mass)?;
        if m > 0 {
            eval::constraint_jacobian(system, at, &state.q, &mut self.ws.phi_q)?;
        }
        let point = DaeState {
            t: state.t,
            q: &state.q,
            v: v_newmark,
            qdd: &state.qdd,
            lambda: &state.lambda,
        };
        if let Some(jacobians) = system.as_residual_jacobians() {
            let ws = &mut self.ws;
            eval::residual_jacobians(jacobians, at, &point, &mut ws.stiffness, &mut ws.damping)?;
        } else {
            self.residual_jacobians_by_differences(system, at, &point)?;
        }
        let ws = &mut self.ws;
        if !self.additive {
            // dq = h q̇_n + h² [(½ − β) a_n + β a_{n+1}]
            for i in 0..nv {
                ws.dq[i] = h * self.v_before[i]
                    + h * h * ((0.5 - beta) * self.a_before[i] + beta * state.a[i]);
            }
            let group = system.as_position_group().ok_or_else(|| {
                eval::capability_withdrawn(at, "integrate_position_jacobians", "as_position_group")
            })?;
            group
                .integrate_position_jacobians(&self.q_before, &ws.dq, &mut ws.wrt_q, &mut ws.wrt_dq)
                .map_err(at.system_error("integrate_position_jacobians"))?;
            at.check_finite("integrate_position_jacobians", ws.wrt_q.as_slice())?;
            at.check_finite("integrate_position_jacobians", ws.wrt_dq.as_slice())?;
        }
        ws.parameter_jacobians_at(system, at, &point)?;
        at.check_finite(
            "parameter_jacobians.constraints",
            ws.constraints_p.as_slice(),
        )?;

        // Predictions from the sensitivities at t_n.
        ws.increment.copy_from(&self.s_v);
        ws.increment.scale_mut(h);
        add_scaled(
            ws.increment.as_mut_slice(),
            h * h * (0.5 - beta),
            self.s_a.as_slice(),
        );
        add_scaled(
            ws.increment.as_mut_slice(),
            -h * h * beta * alpha,
            self.s_qdd.as_slice(),
        );
        if self.additive {
            ws.predicted_q.copy_from(&self.s_q);
            ws.predicted_q += &ws.increment;
        } else {
            ws.predicted_q.gemm(1.0, &ws.wrt_q, &self.s_q, 0.0);
            ws.predicted_q.gemm(1.0, &ws.wrt_dq, &ws.increment, 1.0);
        }
        ws.predicted_v.copy_from(&self.s_v);
        add_scaled(
            ws.predicted_v.as_mut_slice(),
            h * (1.0 - gamma),
            self.s_a.as_slice(),
        );
        add_scaled(
            ws.predicted_v.as_mut_slice(),
            -h * gamma * alpha,
            self.s_qdd.as_slice(),
        );

        // J = [M + β'h² K_t B + γ'h D_t, Φ_qᵀ; Φ_q B, 0].
        let (stiffness_b, phi_q_b) = if self.additive {
            (&ws.stiffness, &ws.phi_q)
        } else {
            ws.stiffness_b.gemm(1.0, &ws.stiffness, &ws.wrt_dq, 0.0);
            if m > 0 {
                ws.phi_q_b.gemm(1.0, &ws.phi_q, &ws.wrt_dq, 0.0);
            }
            (&ws.stiffness_b, &ws.phi_q_b)
        };
        ws.matrix.fill(0.0);
        for j in 0..nv {
            for i in 0..nv {
                ws.matrix[(i, j)] =
                    ws.mass[(i, j)] + beta_h2 * stiffness_b[(i, j)] + gamma_h * ws.damping[(i, j)];
            }
        }
        for r in 0..m {
            for j in 0..nv {
                ws.matrix[(j, nv + r)] = ws.phi_q[(r, j)];
                ws.matrix[(nv + r, j)] = phi_q_b[(r, j)];
            }
        }
        ws.solver
            .factor(&ws.matrix)
            .map_err(|b| IntegrateError::SingularMatrix {
                t: at.t,
                step: at.step,
                matrix: "sensitivity step Jacobian",
                index: b.index,
                pivot_relative: b.pivot_relative,
            })?;
        self.stats.factorisations += 1;

        // Right-hand sides for all parameters at once.
        ws.rhs_dynamics.copy_from(&ws.dynamics_p);
        ws.rhs_dynamics
            .gemm(1.0, &ws.stiffness, &ws.predicted_q, 1.0);
        ws.rhs_dynamics.gemm(1.0, &ws.damping, &ws.predicted_v, 1.0);
        ws.rhs_dynamics.neg_mut();
        if m > 0 {
            ws.rhs_constraints.copy_from(&ws.constraints_p);
            ws.rhs_constraints
                .gemm(1.0, &ws.phi_q, &ws.predicted_q, 1.0);
            ws.rhs_constraints.scale_mut(-1.0 / beta_h2);
        }
        for k in 0..p {
            for i in 0..nv {
                ws.rhs[i] = ws.rhs_dynamics[(i, k)];
            }
            for j in 0..m {
                ws.rhs[nv + j] = ws.rhs_constraints[(j, k)];
            }
            ws.solver.solve_in_place(&mut ws.rhs);
            at.check_finite("sensitivity solve", ws.rhs.as_slice())?;
            for i in 0..nv {
                ws.new_qdd[(i, k)] = ws.rhs[i];
            }
            for j in 0..m {
                self.s_lambda[(j, k)] = ws.rhs[nv + j];
            }
        }
        self.stats.solves += p as u64;

        // The Newmark updates of the sensitivities.
        self.s_a.copy_from(&ws.new_qdd);
        self.s_a.scale_mut(1.0 + alpha);
        add_scaled(self.s_a.as_mut_slice(), -alpha, self.s_qdd.as_slice());
        self.s_q.copy_from(&ws.predicted_q);
        if self.additive {
            add_scaled(self.s_q.as_mut_slice(), beta_h2, ws.new_qdd.as_slice());
        } else {
            ws.b_new_qdd.gemm(1.0, &ws.wrt_dq, &ws.new_qdd, 0.0);
            add_scaled(self.s_q.as_mut_slice(), beta_h2, ws.b_new_qdd.as_slice());
        }
        self.s_v.copy_from(&ws.predicted_v);
        add_scaled(self.s_v.as_mut_slice(), gamma_h, ws.new_qdd.as_slice());
        self.s_qdd.copy_from(&ws.new_qdd);
        Ok(())
    }

    /// The dynamics residual `r = M q̈ + Φ_qᵀ λ − Q` at `point` into `out` (dim nv), through the
    /// system's inverse dynamics when it has one; `mass`, `forces` and `phi_q` are work buffers.
    fn residual<S: DaeSystem + ?Sized>(
        system: &mut S,
        at: At,
        point: &DaeState<'_>,
        mass: &mut DMatrix<f64>,
        forces: &mut DVector<f64>,
        phi_q: &mut DMatrix<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), IntegrateError> {
        let DaeState {
            q, v, qdd, lambda, ..
        } = *point;
        if let Some(inverse_dynamics) = system.as_inverse_dynamics() {
            eval::dynamics_residual(inverse_dynamics, at, q, v, qdd, false, out)?;
        } else {
            eval::mass_matrix(system, at, q, mass)?;
            eval::forces(system, at, q, v, forces)?;
            out.copy_from(forces);
            out.gemv(1.0, mass, qdd, -1.0);
        }
        if !lambda.is_empty() {
            eval::constraint_jacobian(system, at, q, phi_q)?;
            out.gemv_tr(1.0, phi_q, lambda, 1.0);
        }
        Ok(())
    }

    /// `K_t` and `D_t` by central differences of the residual along each tangent coordinate and each
    /// velocity, step [`JACOBIAN_FD_STEP`] (docs/sensitivities.md §2): `4 nv` residual evaluations.
    fn residual_jacobians_by_differences<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        point: &DaeState<'_>,
    ) -> Result<(), IntegrateError> {
        let DaeState { q, v, .. } = *point;
        let eps = JACOBIAN_FD_STEP;
        let ws = &mut self.ws;
        for i in 0..self.nv {
            for (sign, out) in [(1.0, &mut ws.r_plus), (-1.0, &mut ws.r_minus)] {
                ws.dq.fill(0.0);
                ws.dq[i] = sign * eps;
                eval::integrate_position(system, at, q, &ws.dq, &mut ws.q_perturbed)?;
                let moved = DaeState {
                    q: &ws.q_perturbed,
                    ..*point
                };
                Self::residual(
                    system,
                    at,
                    &moved,
                    &mut ws.mass_scratch,
                    &mut ws.forces,
                    &mut ws.phi_q_scratch,
                    out,
                )?;
            }
            for r in 0..self.nv {
                ws.stiffness[(r, i)] = (ws.r_plus[r] - ws.r_minus[r]) / (2.0 * eps);
            }
        }
        for i in 0..self.nv {
            for (sign, out) in [(1.0, &mut ws.r_plus), (-1.0, &mut ws.r_minus)] {
                ws.v_perturbed.copy_from(v);
                ws.v_perturbed[i] += sign * eps;
                let moved = DaeState {
                    v: &ws.v_perturbed,
                    ..*point
                };
                Self::residual(
                    system,
                    at,
                    &moved,
                    &mut ws.mass_scratch,
                    &mut ws.forces,
                    &mut ws.phi_q_scratch,
                    out,
                )?;
            }
            for r in 0..self.nv {
                ws.damping[(r, i)] = (ws.r_plus[r] - ws.r_minus[r]) / (2.0 * eps);
            }
        }
        self.stats.jacobian_residual_evaluations += 4 * self.nv as u64;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
