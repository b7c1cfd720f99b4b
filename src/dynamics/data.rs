//! Per-thread work buffers of the dynamics algorithms.

use crate::model::Model;
use crate::spatial::{Force, Inertia, Motion, Transform};
use nalgebra::{DMatrix, DVector};

/// Work buffers and results of the dynamics algorithms for one [`Model`]; one per thread.
///
/// Per-body arrays are indexed like `model.bodies`.
#[derive(Clone, Debug)]
pub struct Data {
    /// `parent_from_body` of every body at the last configuration.
    pub parent_from_body: Vec<Transform>,
    /// `world_from_body` of every body at the last configuration.
    pub world_from_body: Vec<Transform>,
    /// Body spatial velocities (body frame).
    pub velocity: Vec<Motion>,
    /// Body spatial accelerations (body frame, gravity included as a base acceleration).
    pub acceleration: Vec<Motion>,
    /// Body forces (body frame).
    pub force: Vec<Force>,
    /// Composite inertias (CRBA; at a revolute root about a coordinate axis `e_k` only entry
    /// `(k, k)` of the rotational part is complete: `crba_at_placements`).
    pub composite: Vec<Inertia>,
    /// Each mass-matrix column's force `I^c S` on its way to the root (CRBA; `nv`).
    pub column_force: Vec<Force>,
    /// One past the last velocity coordinate of each joint's subtree (CRBA; per body).
    pub subtree_velocity_end: Vec<usize>,
    /// Joint-space mass matrix `M(q)` (`nv × nv`), written by [`crba`](super::crba).
    pub mass_matrix: DMatrix<f64>,
    /// Bias `C(q, v) v + g(q)` (`nv`), written by [`nonlinear_effects`](super::nonlinear_effects).
    pub bias: DVector<f64>,
    /// Joint torques (`nv`), written by [`rnea`](super::rnea).
    pub tau: DVector<f64>,
    /// Joint accelerations (`nv`), written by [`forward_dynamics`](super::forward_dynamics).
    pub qdd: DVector<f64>,
}

impl Data {
    /// Allocates the buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let nb = model.bodies.len();
        let nv = model.nv;
        Self {
            parent_from_body: vec![Transform::identity(); nb],
            world_from_body: vec![Transform::identity(); nb],
            velocity: vec![Motion::zero(); nb],
            acceleration: vec![Motion::zero(); nb],
            force: vec![Force::zero(); nb],
            composite: vec![Inertia::zero(); nb],
            column_force: vec![Force::zero(); nv],
            subtree_velocity_end: vec![0; nb],
            mass_matrix: DMatrix::zeros(nv, nv),
            bias: DVector::zeros(nv),
            tau: DVector::zeros(nv),
            qdd: DVector::zeros(nv),
        }
    }
}
