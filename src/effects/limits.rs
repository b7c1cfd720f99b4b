//! Penalty joint limits at URDF `<limit lower upper>` (revolute and prismatic joints with finite
//! limits): beyond a limit by `p > 0`, `τ = −k p − c q̇` pushes back; inside the limits nothing. The
//! force is continuous at the limit in position (not in velocity: the damping switches on there).

use super::JointSlot;
use crate::model::Model;

/// Penalty stiffness (N·m/rad or N/m): 1 mrad of penetration costs 10 N·m.
pub const JOINT_LIMIT_STIFFNESS: f64 = 1e4;
/// Penalty damping while penetrating (N·m·s/rad or N·s/m).
pub const JOINT_LIMIT_DAMPING: f64 = 1e2;

/// Limits of every 1-dof joint with a finite range.
#[derive(Clone, Debug, Default)]
pub struct JointLimits {
    joints: Vec<JointSlot>,
}

impl JointLimits {
    pub(super) fn new(model: &Model, joints: &[JointSlot]) -> Self {
        Self {
            joints: joints
                .iter()
                .copied()
                .filter(|j| {
                    let [lower, upper] = model.description.joints[j.source].limits;
                    lower.is_finite() && upper.is_finite() && lower < upper
                })
                .collect(),
        }
    }

    /// Penetration beyond the limits (positive above `upper`, negative below `lower`, else 0).
    fn penetration(model: &Model, j: &JointSlot, q: &[f64]) -> f64 {
        let [lower, upper] = model.description.joints[j.source].limits;
        let x = q[j.q_index];
        if x > upper {
            x - upper
        } else if x < lower {
            x - lower
        } else {
            0.0
        }
    }

    pub(super) fn add_forces(&self, model: &Model, q: &[f64], v: &[f64], out: &mut [f64]) {
        for j in &self.joints {
            let p = Self::penetration(model, j, q);
            if p != 0.0 {
                out[j.v_index] -= JOINT_LIMIT_STIFFNESS * p + JOINT_LIMIT_DAMPING * v[j.v_index];
            }
        }
    }

    pub(super) fn add_diagonal(
        &self,
        model: &Model,
        q: &[f64],
        stiffness: &mut [f64],
        damping: &mut [f64],
    ) {
        for j in &self.joints {
            if Self::penetration(model, j, q) != 0.0 {
                stiffness[j.v_index] += JOINT_LIMIT_STIFFNESS;
                damping[j.v_index] += JOINT_LIMIT_DAMPING;
            }
        }
    }
}
