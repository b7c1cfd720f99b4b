//! The sensitivity of the velocity the integrator reports (docs/sensitivities.md §6): with
//! constraint rows and velocity projection, the Newmark velocity's plus a directional 4-point
//! central difference of the projection's correction along each parameter, computed once per
//! state (`4 P` projections, at record times only).
//!
//! Does not: change the carried sensitivities (the recursion keeps the Newmark velocity's), or
//! step.

use nalgebra::DMatrix;

use super::{HhtSensitivity, SensitivityError, Workspace, PROJECTION_FD_STEP, STENCIL};
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::hht::{assemble_iteration_matrix, HhtIntegrator};
use crate::integrate::system::DaeSystem;

impl HhtSensitivity {
    /// `∂q̇/∂p` of the velocity the integrator reports (`integrator.state().v`), `nv × P`. With
    /// constraint rows and velocity projection that velocity is projected onto `Φ_q q̇ + Φ_t = 0`,
    /// and its sensitivity is the Newmark velocity's plus a directional central difference of the
    /// projection's correction along each parameter (docs/sensitivities.md §6): `4 P` projections,
    /// computed once per state (call it at record times only; `4 P` projections). Otherwise the Newmark velocity's.
    ///
    /// `integrator` must be the one stepped with these sensitivities.
    pub fn reported_velocity<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
    ) -> Result<&DMatrix<f64>, SensitivityError> {
        self.check_in_step(integrator)?;
        if self.m == 0 || !self.velocity_projection {
            return Ok(&self.s_v);
        }
        if !self.reported_fresh {
            self.project_velocity_sensitivity(system, integrator)?;
            self.reported_fresh = true;
        }
        Ok(&self.s_v_reported)
    }

    /// `S_q̇,reported = S_q̇ + ∂Δq̇/∂p` with `Δq̇` the projection's correction, by a directional
    /// 4-point central difference along `(p_k, q ⊕ ε S_q[:, k], q̇ + ε S_q̇[:, k])` for each
    /// parameter (docs/sensitivities.md §6).
    pub(super) fn project_velocity_sensitivity<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        integrator: &HhtIntegrator,
    ) -> Result<(), SensitivityError> {
        let state = integrator.state();
        let v_newmark = integrator.newmark_velocity();
        let at = At {
            t: state.t,
            step: state.step,
        };
        for k in 0..self.p {
            let spread = (0..self.nv)
                .map(|i| self.s_q[(i, k)].abs())
                .fold(1.0_f64, f64::max);
            let eps = eval::parameters(system, at, "parameter_difference_step")?
                .parameter_difference_step(k)
                .min(PROJECTION_FD_STEP / spread);
            self.ws.dv_plus.fill(0.0);
            for (steps, weight) in STENCIL {
                let ws = &mut self.ws;
                let offset = steps * eps;
                for i in 0..self.nv {
                    ws.dq[i] = offset * self.s_q[(i, k)];
                    ws.v_perturbed[i] = v_newmark[i] + offset * self.s_v[(i, k)];
                }
                eval::integrate_position(system, at, &state.q, &ws.dq, &mut ws.q_perturbed)?;
                eval::parameters(system, at, "set_parameter_offset")?
                    .set_parameter_offset(k, offset)
                    .map_err(at.system_error("set_parameter_offset"))?;
                let correction = Self::projection_correction(system, at, ws);
                eval::parameters(system, at, "set_parameter_offset")?
                    .set_parameter_offset(k, 0.0)
                    .map_err(at.system_error("set_parameter_offset"))?;
                correction?;
                let w = weight / (12.0 * eps);
                for i in 0..self.nv {
                    ws.dv_plus[i] += w * ws.rhs[i];
                }
            }
            for i in 0..self.nv {
                self.s_v_reported[(i, k)] = self.s_v[(i, k)] + self.ws.dv_plus[i];
            }
        }
        self.stats.projection_evaluations += 4 * self.p as u64;
        Ok(())
    }

    /// The velocity projection's correction at `(ws.q_perturbed, ws.v_perturbed)` into
    /// `ws.rhs[0..nv]`: `[M Φ_qᵀ; Φ_q 0][Δq̇; μ] = [0; −(Φ_q q̇ + Φ_t)]`.
    fn projection_correction<S: DaeSystem + ?Sized>(
        system: &mut S,
        at: At,
        ws: &mut Workspace,
    ) -> Result<(), IntegrateError> {
        let nv = ws.mass.nrows();
        let m = ws.phi_q_scratch.nrows();
        eval::mass_matrix(system, at, &ws.q_perturbed, &mut ws.mass_scratch)?;
        eval::constraint_jacobian(system, at, &ws.q_perturbed, &mut ws.phi_q_scratch)?;
        eval::constraint_time_derivative(system, at, &ws.q_perturbed, &mut ws.phi_t)?;
        ws.phi_t.gemv(1.0, &ws.phi_q_scratch, &ws.v_perturbed, 1.0);
        assemble_iteration_matrix(
            &ws.mass_scratch,
            None,
            &ws.phi_q_scratch,
            0.0,
            0.0,
            1.0,
            &mut ws.matrix,
        );
        ws.solver
            .factor(&ws.matrix)
            .map_err(|b| IntegrateError::SingularMatrix {
                t: at.t,
                step: at.step,
                matrix: "velocity projection matrix [M Φ_qᵀ; Φ_q 0] (sensitivities)",
                index: b.index,
                pivot_relative: b.pivot_relative,
            })?;
        for i in 0..nv {
            ws.rhs[i] = 0.0;
        }
        for j in 0..m {
            ws.rhs[nv + j] = -ws.phi_t[j];
        }
        ws.solver.solve_in_place(&mut ws.rhs);
        at.check_finite("velocity projection (sensitivities)", ws.rhs.as_slice())
    }
}
