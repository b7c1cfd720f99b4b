//! The sensitivities of a trajectory's start (docs/sensitivities.md §5): without constraint rows
//! `q_0`, `q̇_0` do not depend on the parameters and `∂q̈_0/∂p = −M⁻¹ ∂r/∂p` exactly; with rows,
//! a 4-point central difference of [`consistent_start`] along each parameter, the position's
//! sensitivity then closed onto the constraint manifold's tangent.
//!
//! Does not: step (`super`'s `step`), or differentiate the reported velocity (`projection.rs`).
//! Allocates (it runs the consistent start).

use nalgebra::{DMatrix, DVector};

use super::{HhtSensitivity, SensitivityError, SensitivityStats, Workspace, STENCIL};
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::hht::HhtIntegrator;
use crate::integrate::start::consistent_start;
use crate::integrate::system::DaeSystem;

impl HhtSensitivity {
    /// The sensitivities of the consistent start of `integrator`'s trajectory (docs/sensitivities.md
    /// §5), which must not have stepped yet; `q0`, `v0` are the values the integrator was started
    /// from (before projection; they do not depend on the parameters).
    ///
    /// - `q0`: dim `nq`; `v0`: dim `nv`.
    ///
    /// Errors: [`SensitivityError::NotAtStart`]; [`SensitivityError::ProjectionMetric`] for a
    /// constrained system whose projection keeps the Newton matrix's `M`; system errors of
    /// `parameter_jacobians`,
    /// `set_parameter_offset` (constrained systems) and the start's own errors at a perturbed point.
    pub fn new<S: DaeSystem + ?Sized>(
        system: &mut S,
        integrator: &HhtIntegrator,
        q0: &DVector<f64>,
        v0: &DVector<f64>,
    ) -> Result<Self, SensitivityError> {
        let state = integrator.state();
        if state.step != 0 {
            return Err(SensitivityError::NotAtStart { step: state.step });
        }
        let settings = integrator.settings();
        if eval::n_constraints(system) > 0
            && settings.velocity_projection
            && settings.projection_keeps_newton_mass
        {
            return Err(SensitivityError::ProjectionMetric);
        }
        let (nq, nv, m, p) = (
            system.nq(),
            system.nv(),
            eval::n_constraints(system),
            eval::n_parameters(system),
        );
        eval::check_dimensions(system, state.q.len(), state.v.len(), state.lambda.len())?;
        let mut sensitivity = Self {
            nq,
            nv,
            m,
            p,
            coeffs: *integrator.coefficients(),
            velocity_projection: integrator.settings().velocity_projection,
            additive: system.as_position_group().is_none(),
            step: 0,
            s_q: DMatrix::zeros(nv, p),
            s_v: DMatrix::zeros(nv, p),
            s_a: DMatrix::zeros(nv, p),
            s_qdd: DMatrix::zeros(nv, p),
            s_lambda: DMatrix::zeros(m, p),
            s_q_start: DMatrix::zeros(nv, p),
            s_v_reported: DMatrix::zeros(nv, p),
            reported_fresh: true,
            q_before: DVector::zeros(nq),
            v_before: DVector::zeros(nv),
            a_before: DVector::zeros(nv),
            stats: SensitivityStats {
                parameters: p,
                ..SensitivityStats::default()
            },
            ws: Workspace::new(nq, nv, m, p),
        };
        if p > 0 {
            if m == 0 {
                sensitivity.start_without_constraints(system, integrator)?;
            } else {
                sensitivity.start_by_differences(system, integrator, q0, v0)?;
            }
        }
        sensitivity.s_a.copy_from(&sensitivity.s_qdd);
        sensitivity.s_q_start.copy_from(&sensitivity.s_q);
        sensitivity.s_v_reported.copy_from(&sensitivity.s_v);
        Ok(sensitivity)
    }

    /// Without constraint rows the start is `q_0`, `q̇_0` as given and `M q̈_0 = Q`: `S_q = S_q̇ = 0`
    /// and `M S_q̈ = −∂r/∂p` (docs/sensitivities.md §5), exactly.
    fn start_without_constraints<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
    ) -> Result<(), SensitivityError> {
        let state = integrator.state();
        let at = At {
            t: state.t,
            step: 0,
        };
        let ws = &mut self.ws;
        eval::mass_matrix(system, at, &state.q, &mut ws.mass)?;
        ws.parameter_jacobians_at(system, at, &state.point())?;
        ws.matrix.copy_from(&ws.mass);
        ws.solver
            .factor(&ws.matrix)
            .map_err(|b| IntegrateError::SingularMatrix {
                t: at.t,
                step: 0,
                matrix: "mass matrix (start sensitivities)",
                index: b.index,
                pivot_relative: b.pivot_relative,
            })?;
        for k in 0..self.p {
            for i in 0..self.nv {
                ws.rhs[i] = -ws.dynamics_p[(i, k)];
            }
            ws.solver.solve_in_place(&mut ws.rhs);
            at.check_finite("start sensitivity", ws.rhs.as_slice())?;
            for i in 0..self.nv {
                self.s_qdd[(i, k)] = ws.rhs[i];
            }
        }
        self.stats.solves += self.p as u64;
        Ok(())
    }

    /// With constraint rows, a 4-point central difference of [`consistent_start`] along each
    /// parameter (docs/sensitivities.md §5): `f' ≈ [−f(2ε) + 8f(ε) − 8f(−ε) + f(−2ε)] / (12ε)` with
    /// ε the system's [`Parameters::parameter_difference_step`](crate::integrate::Parameters::parameter_difference_step). Index-3 steps turn an error `e` of the
    /// start velocity's component normal to the constraints into errors of ~`e/(β'h)` in `∂q̈/∂p`
    /// that decay slowly, so the step is as large as the system allows: the rounding of the
    /// projected velocity (~u·|q̇|) costs ~u·|q̇|/ε.
    fn start_by_differences<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
        q0: &DVector<f64>,
        v0: &DVector<f64>,
    ) -> Result<(), SensitivityError> {
        let state = integrator.state();
        let at = At {
            t: state.t,
            step: 0,
        };
        let mut dq = DVector::zeros(self.nv);
        for k in 0..self.p {
            let eps = eval::parameters(system, at, "parameter_difference_step")?
                .parameter_difference_step(k);
            for (steps, weight) in STENCIL {
                eval::parameters(system, at, "set_parameter_offset")?
                    .set_parameter_offset(k, steps * eps)
                    .map_err(at.system_error("set_parameter_offset"))?;
                let start = consistent_start(system, state.t, q0, v0);
                // Restore before reporting any error.
                eval::parameters(system, at, "set_parameter_offset")?
                    .set_parameter_offset(k, 0.0)
                    .map_err(at.system_error("set_parameter_offset"))?;
                let start = start?;
                self.stats.start_evaluations += 1;
                eval::difference_position(system, at, &state.q, &start.q, &mut dq)?;
                let w = weight / (12.0 * eps);
                for i in 0..self.nv {
                    self.s_q[(i, k)] += w * dq[i];
                    self.s_v[(i, k)] += w * start.v[i];
                    self.s_qdd[(i, k)] += w * start.qdd[i];
                }
                for j in 0..self.m {
                    self.s_lambda[(j, k)] += w * start.lambda[j];
                }
            }
        }
        at.check_finite("start sensitivity", self.s_q.as_slice())?;
        self.close_start_position(system, integrator)?;
        at.check_finite("start sensitivity", self.s_v.as_slice())?;
        at.check_finite("start sensitivity", self.s_qdd.as_slice())?;
        at.check_finite("start sensitivity", self.s_lambda.as_slice())?;
        Ok(())
    }

    /// Removes the central difference's error normal to the constraints from `S_q0`
    /// (docs/sensitivities.md §5): the exact derivative satisfies `Φ_q S_q + ∂Φ/∂p = 0`, and index-3
    /// steps turn a residual `r` of it into a jump of `r/(β'h²)` in `∂q̈/∂p` (measured: 1e-13 of
    /// residual, 2e-9 of jump at h = 10 ms). The least-norm correction `S_q −= Φ_qᵀ (Φ_q Φ_qᵀ)⁻¹ r`
    /// is at the difference's noise level.
    fn close_start_position<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
    ) -> Result<(), SensitivityError> {
        let state = integrator.state();
        let at = At {
            t: state.t,
            step: 0,
        };
        let ws = &mut self.ws;
        eval::constraint_jacobian(system, at, &state.q, &mut ws.phi_q)?;
        ws.parameter_jacobians_at(system, at, &state.point())?;
        at.check_finite(
            "parameter_jacobians.constraints",
            ws.constraints_p.as_slice(),
        )?;
        let mut residual = ws.constraints_p.clone();
        residual.gemm(1.0, &ws.phi_q, &self.s_q, 1.0);
        let gram = &ws.phi_q * ws.phi_q.transpose();
        // Φ_q has full row rank here: consistent_start refused redundant rows already.
        let Some(gram) = gram.cholesky() else {
            return Err(IntegrateError::SingularMatrix {
                t: at.t,
                step: 0,
                matrix: "Φ_q Φ_qᵀ (start sensitivities)",
                index: 0,
                pivot_relative: 0.0,
            }
            .into());
        };
        let correction = ws.phi_q.transpose() * gram.solve(&residual);
        self.s_q -= correction;
        Ok(())
    }
}
