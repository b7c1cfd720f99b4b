//! Coulomb joint friction from URDF `<dynamics friction>`, smoothed so the equations stay smooth for
//! the implicit integrator and for the surrogates fitted across samples:
//! `τ_j = −F_j tanh(q̇_j / v_s)` with `v_s` = [`FRICTION_SMOOTHING_VELOCITY`]. Below `v_s` it acts as a
//! stiff viscous damper (`F_j / v_s`), so it does not model true sticking.

use super::JointSlot;
use crate::model::Model;

/// Velocity scale of the tanh smoothing (rad/s or m/s): 1e-2 keeps 96 % of the Coulomb force at
/// 0.02 rad/s while the equivalent damping `F/v_s` stays moderate for the Newton matrix.
pub const FRICTION_SMOOTHING_VELOCITY: f64 = 1e-2;

/// Friction on every 1-dof joint (the value is read from the model: `joint.NAME.friction`).
#[derive(Clone, Debug, Default)]
pub struct JointFriction {
    joints: Vec<JointSlot>,
}

impl JointFriction {
    pub(super) fn new(joints: &[JointSlot]) -> Self {
        Self {
            joints: joints.to_vec(),
        }
    }

    pub(super) fn add_forces(&self, model: &Model, v: &[f64], out: &mut [f64]) {
        for j in &self.joints {
            let force = model.description.joints[j.source].friction;
            out[j.v_index] -= force * (v[j.v_index] / FRICTION_SMOOTHING_VELOCITY).tanh();
        }
    }

    pub(super) fn add_diagonal(&self, model: &Model, v: &[f64], damping: &mut [f64]) {
        for j in &self.joints {
            let force = model.description.joints[j.source].friction;
            let t = (v[j.v_index] / FRICTION_SMOOTHING_VELOCITY).tanh();
            damping[j.v_index] += force / FRICTION_SMOOTHING_VELOCITY * (1.0 - t * t);
        }
    }
}
