//! The robot's full residual Jacobians `∂r/∂q`, `∂r/∂q̇` (docs/sensitivities.md §2), which
//! `RobotSystem` hands out as [`ResidualJacobians`]: RNEA's analytic derivatives, the effects'
//! diagonal, and the loop closures' `∂(Φ_qᵀ λ)/∂q` by central differences; with their work buffers,
//! allocated on first use.
//!
//! Does not: assemble the residual itself or the Newton matrix's diagonal terms (`system.rs`).

use super::RobotSystem;
use crate::dynamics::{rnea_derivatives, RneaDerivatives};
use crate::integrate::{DaeState, PositionGroup, ResidualJacobians, SystemError};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Work buffers of the robot's full residual Jacobians.
#[derive(Clone, Debug)]
pub(super) struct JacobianBuffers {
    rnea: RneaDerivatives,
    /// Diagonal stiffness and damping of the effects, dim nv.
    stiffness: DVector<f64>,
    damping: DVector<f64>,
    /// Φ_q at a moved configuration, m × nv.
    phi_q: DMatrix<f64>,
    /// A moved configuration, dim nq; a tangent step, dim nv; Φ_qᵀ λ at ±ε, dim nv.
    q_moved: DVector<f64>,
    tangent: DVector<f64>,
    plus: DVector<f64>,
    minus: DVector<f64>,
}

impl JacobianBuffers {
    fn new(model: &Model, m: usize) -> Self {
        Self {
            rnea: RneaDerivatives::new(model),
            stiffness: DVector::zeros(model.nv),
            damping: DVector::zeros(model.nv),
            phi_q: DMatrix::zeros(m, model.nv),
            q_moved: DVector::zeros(model.nq),
            tangent: DVector::zeros(model.nv),
            plus: DVector::zeros(model.nv),
            minus: DVector::zeros(model.nv),
        }
    }
}

impl RobotSystem {
    /// Adds `∂(Φ_qᵀ λ)/∂q` (central differences along each tangent coordinate) to `stiffness`.
    fn add_loop_stiffness(
        &mut self,
        q: &DVector<f64>,
        lambda: &DVector<f64>,
        buffers: &mut JacobianBuffers,
        stiffness: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let eps = crate::integrate::JACOBIAN_FD_STEP;
        for i in 0..self.model.nv {
            for sign in [1.0, -1.0] {
                buffers.tangent.fill(0.0);
                buffers.tangent[i] = sign * eps;
                self.integrate_position(q, &buffers.tangent, &mut buffers.q_moved)?;
                self.constraints.jacobian(
                    &self.model,
                    &mut self.data,
                    buffers.q_moved.as_slice(),
                    &mut buffers.phi_q,
                );
                let out = if sign > 0.0 {
                    &mut buffers.plus
                } else {
                    &mut buffers.minus
                };
                out.gemv_tr(1.0, &buffers.phi_q, lambda, 0.0);
            }
            for r in 0..self.model.nv {
                stiffness[(r, i)] += (buffers.plus[r] - buffers.minus[r]) / (2.0 * eps);
            }
        }
        Ok(())
    }
}

impl ResidualJacobians for RobotSystem {
    /// `∂r/∂q`, `∂r/∂q̇` of `r = M q̈ + Φ_qᵀ λ − Q` (docs/sensitivities.md §2): RNEA's analytic
    /// Jacobians, plus the effects' (each acts on its own coordinate: the diagonal of
    /// [`NewtonDiagonal::newton_diagonal`](crate::integrate::NewtonDiagonal::newton_diagonal), exact), plus `∂(Φ_qᵀ λ)/∂q` of loop closures by central
    /// differences (step [`JACOBIAN_FD_STEP`](crate::integrate::JACOBIAN_FD_STEP); mimic and drive
    /// rows have a constant `Φ_q`). Allocates once, on first use.
    fn residual_jacobians(
        &mut self,
        state: &DaeState<'_>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState {
            q, v, qdd, lambda, ..
        } = *state;
        let mut buffers = match self.jacobians.take() {
            Some(buffers) => buffers,
            None => Box::new(JacobianBuffers::new(&self.model, self.constraints.len())),
        };
        rnea_derivatives(
            &self.model,
            &self.environment.gravity,
            &mut self.data,
            &mut buffers.rnea,
            q.as_slice(),
            v.as_slice(),
            qdd.as_slice(),
            stiffness_out,
            damping_out,
        );
        buffers.stiffness.fill(0.0);
        buffers.damping.fill(0.0);
        self.effects.add_newton_diagonal(
            &self.model,
            q.as_slice(),
            v.as_slice(),
            buffers.stiffness.as_mut_slice(),
            buffers.damping.as_mut_slice(),
        );
        for j in 0..self.model.nv {
            stiffness_out[(j, j)] += buffers.stiffness[j];
            damping_out[(j, j)] += buffers.damping[j];
        }
        let result = if self.constraints.loops.is_empty() || lambda.is_empty() {
            Ok(())
        } else {
            self.add_loop_stiffness(q, lambda, &mut buffers, stiffness_out)
        };
        self.jacobians = Some(buffers);
        result
    }
}
