//! After an accepted step with constraint rows (docs/method.md §5, "Velocity drift"): `max |Φ|` and
//! the velocity-level drift `|Φ_q q̇ + Φ_t|` recorded, and the reported velocity projected onto
//! the constraints when enabled (the recursion keeps the Newmark velocity).

use super::HhtIntegrator;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::system::DaeSystem;

impl HhtIntegrator {
    /// After an accepted step with constraint rows: records `max |Φ|` and the velocity-level drift,
    /// and projects the reported `q̇` (`state.v`) when enabled; the recursion keeps the Newmark
    /// velocity (see [`HhtSettings::velocity_projection`]):
    ///
    /// ```text
    /// [ M    Φ_qᵀ ] [Δq̇]   [ 0                ]
    /// [ Φ_q  0    ] [μ  ] = [ −(Φ_q q̇ + Φ_t)   ],   q̇ += Δq̇
    /// ```
    pub(super) fn finish_constrained_step<S: DaeSystem + ?Sized>(
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
    pub(super) fn velocity_violation<S: DaeSystem + ?Sized>(
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
    pub(super) fn velocity_violation_at_jacobian<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<f64, IntegrateError> {
        let ws = &mut self.ws;
        let s = &self.trajectory.state;
        if eval::constraints_are_scleronomic(system) {
            ws.phi_dot.as_mut_slice().fill(0.0);
        } else {
            eval::constraint_time_derivative(system, at, &s.q, &mut ws.phi_dot)?;
        }
        ws.phi_dot.gemv(1.0, &ws.phi_q, &s.v, 1.0);
        Ok(ws.phi_dot.amax())
    }
}
