//! Joint limits at URDF `<limit lower upper>` (revolute and prismatic joints with finite limits), in
//! two parts (docs/step-control.md §4):
//!
//! - **impacts**: each limit is a unilateral constraint `g ≥ 0` (`g = upper − q` and
//!   `g = q − lower`) that the integrator watches ([`crate::integrate::DaeSystem::event_gaps`]); a
//!   crossing faster than [`crate::integrate::IMPACT_MIN_SPEED`] is located in time and replaced by
//!   an impact with the scene's restitution `e ∈ [0, 1]` (`[scene] limit_restitution`): the joint's
//!   approach speed becomes `e` times it, the rest of the mechanism responds through the mass
//!   matrix, and kinetic energy never grows;
//! - **resting contact**: a penalty spring-damper beyond the limit by `p`:
//!   `τ = −k p − c(p) q̇` with `c(p) = c · min(1, |p| / d)` (the damping grows over the first
//!   [`JOINT_LIMIT_DAMPING_DEPTH`] of penetration, so the force is continuous in position *and*
//!   velocity at the limit — a located impact step that ends a rounding distance past the limit
//!   sees no force jump), for joints pressed slowly onto their limits (after a plastic impact,
//!   under gravity). Inside the limits nothing.

use super::JointSlot;
use crate::model::Model;

/// Penalty stiffness (N·m/rad or N/m): 1 mrad of penetration costs 10 N·m.
pub const JOINT_LIMIT_STIFFNESS: f64 = 1e4;
/// Penalty damping once [`JOINT_LIMIT_DAMPING_DEPTH`] deep (N·m·s/rad or N·s/m): about critical
/// for a 1 kg, 1 m bar (`2 √(k I)` = 115 N·m·s/rad at `I = 1/3` kg·m²).
pub const JOINT_LIMIT_DAMPING: f64 = 1e2;
/// Penetration (rad or m) over which the penalty damping ramps up from 0: 1 mrad, the penetration
/// of ~10 N·m of load.
pub const JOINT_LIMIT_DAMPING_DEPTH: f64 = 1e-3;

/// The ramped damping coefficient `c(p)` and its derivative `dc/dp`.
fn damping_at(p: f64) -> (f64, f64) {
    let depth = p.abs();
    if depth >= JOINT_LIMIT_DAMPING_DEPTH {
        (JOINT_LIMIT_DAMPING, 0.0)
    } else {
        (
            JOINT_LIMIT_DAMPING * depth / JOINT_LIMIT_DAMPING_DEPTH,
            JOINT_LIMIT_DAMPING / JOINT_LIMIT_DAMPING_DEPTH * p.signum(),
        )
    }
}

/// Limits of every 1-dof joint with a finite range.
#[derive(Clone, Debug, Default)]
pub struct JointLimits {
    joints: Vec<JointSlot>,
    restitution: f64,
}

/// Which side of a joint's range an impact event watches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitSide {
    /// `g = q − lower ≥ 0`.
    Lower,
    /// `g = upper − q ≥ 0`.
    Upper,
}

/// One impact event of a joint limit, resolved at the model's current limit values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LimitEvent {
    /// Position coordinate of the joint.
    pub q_index: usize,
    /// Velocity coordinate of the joint.
    pub v_index: usize,
    /// The limit, rad or m.
    pub limit: f64,
    /// Which side.
    pub side: LimitSide,
    /// Coefficient of restitution in `[0, 1]`.
    pub restitution: f64,
    /// The URDF joint (index into `model.description.joints`).
    pub source: usize,
}

impl JointLimits {
    pub(super) fn new(model: &Model, joints: &[JointSlot], restitution: f64) -> Self {
        Self {
            joints: joints
                .iter()
                .copied()
                .filter(|j| {
                    let [lower, upper] = model.description.joints[j.source].limits;
                    lower.is_finite() && upper.is_finite() && lower < upper
                })
                .collect(),
            restitution,
        }
    }

    /// Number of impact events: two per limited joint (lower, upper).
    pub(super) fn n_events(&self) -> usize {
        2 * self.joints.len()
    }

    /// Event `k` (`0..n_events`): joint `k / 2`, lower side for even `k`, upper for odd.
    pub(super) fn event(&self, model: &Model, k: usize) -> Option<LimitEvent> {
        let j = self.joints.get(k / 2)?;
        let [lower, upper] = model.description.joints[j.source].limits;
        let (side, limit) = if k.is_multiple_of(2) {
            (LimitSide::Lower, lower)
        } else {
            (LimitSide::Upper, upper)
        };
        Some(LimitEvent {
            q_index: j.q_index,
            v_index: j.v_index,
            limit,
            side,
            restitution: self.restitution,
            source: j.source,
        })
    }

    /// Gaps `g_k` (allowed side ≥ 0) and rates `ġ_k` of every event (`gaps`, `rates`: dim
    /// `n_events`, overwritten).
    pub(super) fn gaps(
        &self,
        model: &Model,
        q: &[f64],
        v: &[f64],
        gaps: &mut [f64],
        rates: &mut [f64],
    ) {
        for (i, j) in self.joints.iter().enumerate() {
            let [lower, upper] = model.description.joints[j.source].limits;
            let (x, xd) = (q[j.q_index], v[j.v_index]);
            gaps[2 * i] = x - lower;
            rates[2 * i] = xd;
            gaps[2 * i + 1] = upper - x;
            rates[2 * i + 1] = -xd;
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
                let (c, _) = damping_at(p);
                out[j.v_index] -= JOINT_LIMIT_STIFFNESS * p + c * v[j.v_index];
            }
        }
    }

    /// `k_j = k + (dc/dp) q̇` (clamped at 0 so that the diagonal Newton matrix stays positive
    /// definite; exact beyond the damping ramp) and `c_j = c(p)`.
    pub(super) fn add_diagonal(
        &self,
        model: &Model,
        q: &[f64],
        v: &[f64],
        stiffness: &mut [f64],
        damping: &mut [f64],
    ) {
        for j in &self.joints {
            let p = Self::penetration(model, j, q);
            if p != 0.0 {
                let (c, dc) = damping_at(p);
                stiffness[j.v_index] += (JOINT_LIMIT_STIFFNESS + dc * v[j.v_index]).max(0.0);
                damping[j.v_index] += c;
            }
        }
    }
}
