//! Viscous joint damping from URDF `<dynamics damping>`: `τ_j = −c_j q̇_j`.

use super::JointSlot;
use crate::model::Model;

/// Damping on every 1-dof joint (the value is read from the model, so `joint.NAME.damping` works).
#[derive(Clone, Debug, Default)]
pub struct JointDamping {
    joints: Vec<JointSlot>,
}

impl JointDamping {
    pub(super) fn new(joints: &[JointSlot]) -> Self {
        Self {
            joints: joints.to_vec(),
        }
    }

    pub(super) fn add_forces(&self, model: &Model, v: &[f64], out: &mut [f64]) {
        for j in &self.joints {
            out[j.v_index] -= model.description.joints[j.source].damping * v[j.v_index];
        }
    }

    pub(super) fn add_diagonal(&self, model: &Model, damping: &mut [f64]) {
        for j in &self.joints {
            damping[j.v_index] += model.description.joints[j.source].damping;
        }
    }
}
