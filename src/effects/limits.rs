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
//!   `τ = −k_j p − c_j(p) q̇` with `c_j(p) = c_j · min(1, |p| / d)` (the damping grows over the first
//!   [`JOINT_LIMIT_DAMPING_DEPTH`] of penetration, so the force is continuous in position *and*
//!   velocity at the limit — a located impact step that ends a rounding distance past the limit
//!   sees no force jump), for joints pressed slowly onto their limits (after a plastic impact,
//!   under gravity). Inside the limits nothing.
//!
//! The penalty is tuned per joint to the joint's own inertia, not in absolute units: with `I_j`
//! the diagonal `M_jj` of the mass matrix at the scene's initial configuration (the inertia the
//! joint moves with every other joint held), `k_j = I_j ω²` and `c_j = 2 ζ I_j ω`
//! ([`JOINT_LIMIT_FREQUENCY`], [`JOINT_LIMIT_DAMPING_RATIO`]). So a 10 g gripper jaw and a 10 kg
//! shoulder settle onto their limits alike, and the penalty's share of the Newton matrix,
//! `β'h² k_j / I_j = β'h² ω²`, is the same small number on every joint (docs/step-control.md §4).

use super::JointSlot;
use crate::model::Model;

/// Natural frequency of the penalty spring on the joint's inertia, rad/s (period 31 ms): `k_j = I_j ω²`.
/// On a 1 kg, 1 m bar (`I = 1/3` kg·m²) that is 1.3e4 N·m/rad, where the absolute penalty this
/// replaced had 1e4; pressed by an acceleration `a` (rad/s²) the joint settles `a/ω²` past its limit
/// (2.5e-4 rad at 10 rad/s²). At the 1 ms step `β'h²ω²` ≈ 0.01: the spring switching on or off
/// within a step changes the Newton matrix by 1 %.
pub const JOINT_LIMIT_FREQUENCY: f64 = 200.0;
/// Damping ratio of the penalty once [`JOINT_LIMIT_DAMPING_DEPTH`] deep: critical,
/// `c_j = 2 ζ I_j ω` (133 N·m·s/rad on the bar above).
pub const JOINT_LIMIT_DAMPING_RATIO: f64 = 1.0;
/// Penetration (rad or m) over which the penalty damping ramps up from 0: 1 mrad.
pub const JOINT_LIMIT_DAMPING_DEPTH: f64 = 1e-3;

/// The penalty of one limited joint: stiffness `k_j` (N·m/rad or N/m) and full damping `c_j`
/// (N·m·s/rad or N·s/m) from its inertia `inertia` (kg·m² or kg).
pub fn limit_penalty(inertia: f64) -> (f64, f64) {
    (
        inertia * JOINT_LIMIT_FREQUENCY * JOINT_LIMIT_FREQUENCY,
        2.0 * JOINT_LIMIT_DAMPING_RATIO * inertia * JOINT_LIMIT_FREQUENCY,
    )
}

/// A limited joint's penalty constants (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Penalty {
    /// `k_j`, N·m/rad or N/m.
    stiffness: f64,
    /// `c_j` beyond the damping ramp, N·m·s/rad or N·s/m.
    damping: f64,
}

impl Penalty {
    /// The ramped damping coefficient `c_j(p)` and its derivative `dc_j/dp`.
    fn damping_at(&self, p: f64) -> (f64, f64) {
        let depth = p.abs();
        if depth >= JOINT_LIMIT_DAMPING_DEPTH {
            (self.damping, 0.0)
        } else {
            (
                self.damping * depth / JOINT_LIMIT_DAMPING_DEPTH,
                self.damping / JOINT_LIMIT_DAMPING_DEPTH * p.signum(),
            )
        }
    }
}

/// Limits of every 1-dof joint with a finite range.
#[derive(Clone, Debug, Default)]
pub struct JointLimits {
    joints: Vec<JointSlot>,
    /// One per entry of `joints`.
    penalties: Vec<Penalty>,
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
    /// The limited joints among `joints`, their penalties tuned to `inertia_diagonal` (`M_jj` of
    /// the model at the scene's initial configuration, dim `nv`).
    pub(super) fn new(
        model: &Model,
        joints: &[JointSlot],
        inertia_diagonal: &[f64],
        restitution: f64,
    ) -> Self {
        let joints: Vec<JointSlot> = joints
            .iter()
            .copied()
            .filter(|j| {
                let [lower, upper] = model.description.joints[j.source].limits;
                lower.is_finite() && upper.is_finite() && lower < upper
            })
            .collect();
        let penalties = joints
            .iter()
            .map(|j| {
                let (stiffness, damping) = limit_penalty(inertia_diagonal[j.v_index]);
                Penalty { stiffness, damping }
            })
            .collect();
        Self {
            joints,
            penalties,
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

    /// Which limited joints are beyond a limit at `q`: bit `i % 64` for the `i`-th (see
    /// [`crate::integrate::DaeSystem::newton_regime`]).
    pub(super) fn regime(&self, model: &Model, q: &[f64]) -> u64 {
        let mut bits = 0u64;
        for (i, j) in self.joints.iter().enumerate() {
            if Self::penetration(model, j, q) != 0.0 {
                bits |= 1 << (i % 64);
            }
        }
        bits
    }

    /// Adds the penalty torques `−k_j p − c_j(p) q̇` of the joints beyond a limit to `out` (dim nv).
    pub(super) fn add_forces(&self, model: &Model, q: &[f64], v: &[f64], out: &mut [f64]) {
        for (j, penalty) in self.joints.iter().zip(&self.penalties) {
            let p = Self::penetration(model, j, q);
            if p != 0.0 {
                let (c, _) = penalty.damping_at(p);
                out[j.v_index] -= penalty.stiffness * p + c * v[j.v_index];
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
        for (j, penalty) in self.joints.iter().zip(&self.penalties) {
            let p = Self::penetration(model, j, q);
            if p != 0.0 {
                let (c, dc) = penalty.damping_at(p);
                stiffness[j.v_index] += (penalty.stiffness + dc * v[j.v_index]).max(0.0);
                damping[j.v_index] += c;
            }
        }
    }
}
