//! Recursive Newton–Euler inverse dynamics, in body frames (Featherstone, *Rigid Body Dynamics
//! Algorithms*, §5.3):
//!
//! forward pass, for every body `i` with parent `p` and `X = parent_from_body`:
//!   `v_i = X⁻¹ v_p + S q̇_i`,   `a_i = X⁻¹ a_p + S q̈_i + v_i ×ₘ (S q̇_i)`,   `a_world = −g`
//!   `f_i = I_i a_i + v_i ×* (I_i v_i)`
//! backward pass: `τ_i = Sᵀ f_i`, `f_p += X f_i`.
//!
//! Gravity `g` (world frame, m/s²) is an argument: it is the environment's
//! ([`crate::environment::Environment::gravity`]), not the robot's.

use super::{joint_placements, Data};
use crate::model::Model;
use crate::spatial::{Motion, Transform, Vec3};

/// Inverse dynamics: `data.tau = M(q) q̈ + C(q, v) v + g(q)`, rigid-body terms only.
///
/// `gravity` in the world frame (m/s²), `q: dim nq`, `v, qdd: dim nv`. Overwrites
/// `data.parent_from_body`, `data.velocity`, `data.acceleration`, `data.force` and `data.tau` (not
/// `data.world_from_body`: call [`forward_kinematics`](super::forward_kinematics) for placements);
/// returns `data.tau`.
pub fn rnea<'a>(
    model: &Model,
    gravity: &Vec3,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    qdd: &[f64],
) -> &'a [f64] {
    joint_placements(model, data, q);
    rnea_at_placements(model, gravity, data, v, qdd)
}

/// [`rnea`] with the joint placements already in `data.parent_from_body` (a [`crba`] or
/// [`joint_placements`] pass at the configuration of interest, and nothing since at another one):
/// the same bits as [`rnea`] at that configuration, without recomputing the placements.
///
/// [`crba`]: super::crba
/// [`joint_placements`]: super::joint_placements
pub fn rnea_at_placements<'a>(
    model: &Model,
    gravity: &Vec3,
    data: &'a mut Data,
    v: &[f64],
    qdd: &[f64],
) -> &'a [f64] {
    run(model, gravity, data, v, Some(qdd));
    let Data {
        parent_from_body,
        force,
        tau,
        ..
    } = data;
    backward(model, parent_from_body, force, tau.as_mut_slice());
    data.tau.as_slice()
}

/// Bias forces: `data.bias = C(q, v) v + g(q)` (Pinocchio's `nle`).
///
/// `gravity` in the world frame (m/s²), `q: dim nq`, `v: dim nv`. Overwrites the same kinematic
/// buffers as [`rnea`] and `data.bias`.
pub fn nonlinear_effects<'a>(
    model: &Model,
    gravity: &Vec3,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
) -> &'a [f64] {
    joint_placements(model, data, q);
    run(model, gravity, data, v, None);
    let Data {
        parent_from_body,
        force,
        bias,
        ..
    } = data;
    backward(model, parent_from_body, force, bias.as_mut_slice());
    data.bias.as_slice()
}

/// The forward pass at the joint placements in `data.parent_from_body`.
fn run(model: &Model, gravity: &Vec3, data: &mut Data, v: &[f64], qdd: Option<&[f64]>) {
    let base_acceleration = Motion::new(-gravity, Vec3::zeros());
    for (i, joint) in model.joints.iter().enumerate() {
        let vi = joint.v_index;
        let parent_from_body = data.parent_from_body[i];
        let (parent_velocity, parent_acceleration) = match joint.parent {
            Some(p) => (data.velocity[p], data.acceleration[p]),
            None => (Motion::zero(), base_acceleration),
        };
        let (velocity, acceleration) = match joint.revolute_coordinate_axis() {
            Some(k) => motion_through_coordinate_axis(
                &parent_from_body,
                &parent_velocity,
                &parent_acceleration,
                k,
                v[vi],
                qdd.map(|qdd| qdd[vi]),
            ),
            None => {
                let joint_velocity = joint.motion(&v[vi..vi + joint.nv()]);
                let (moved_velocity, moved_acceleration) =
                    parent_from_body.inv_act_motion_pair(&parent_velocity, &parent_acceleration);
                let velocity = moved_velocity + joint_velocity;
                let mut acceleration = moved_acceleration + velocity.cross_motion(&joint_velocity);
                if let Some(qdd) = qdd {
                    acceleration += joint.motion(&qdd[vi..vi + joint.nv()]);
                }
                (velocity, acceleration)
            }
        };
        let inertia = &model.bodies[i].inertia;
        data.force[i] =
            inertia.apply(&acceleration) + velocity.cross_force(&inertia.apply(&velocity));
        data.velocity[i] = velocity;
        data.acceleration[i] = acceleration;
    }
}

/// A body's velocity and acceleration in the forward pass, moved by a revolute joint about the
/// coordinate axis `e_k` of its frame at rate `rate` (and `q̈` `qdd`, `None` for the bias forces):
/// the general step with the joint motion's zero entries left out, the same bits (signs of zero
/// aside; docs/batch.md §7). Also the batched kernels' aligned lanes of a mixed chunk.
#[inline(always)]
pub(crate) fn motion_through_coordinate_axis(
    parent_from_body: &Transform,
    parent_velocity: &Motion,
    parent_acceleration: &Motion,
    k: usize,
    rate: f64,
    qdd: Option<f64>,
) -> (Motion, Motion) {
    let (x, v, a) = (parent_from_body, parent_velocity, parent_acceleration);
    match k {
        0 => motion_through_axis::<0>(x, v, a, rate, qdd),
        1 => motion_through_axis::<1>(x, v, a, rate, qdd),
        _ => motion_through_axis::<2>(x, v, a, rate, qdd),
    }
}

/// [`motion_through_coordinate_axis`] about `e_K` (`K` a constant: the entries stay registers).
#[inline(always)]
fn motion_through_axis<const K: usize>(
    parent_from_body: &Transform,
    parent_velocity: &Motion,
    parent_acceleration: &Motion,
    rate: f64,
    qdd: Option<f64>,
) -> (Motion, Motion) {
    let (mut velocity, moved_acceleration) =
        parent_from_body.inv_act_motion_pair(parent_velocity, parent_acceleration);
    velocity.angular[K] += rate;
    let mut acceleration = moved_acceleration + velocity.cross_coordinate_axis(K, rate);
    if let Some(qdd) = qdd {
        acceleration.angular[K] += qdd;
    }
    (velocity, acceleration)
}

fn backward(
    model: &Model,
    parent_from_body: &[crate::spatial::Transform],
    force: &mut [crate::spatial::Force],
    out: &mut [f64],
) {
    for (i, joint) in model.joints.iter().enumerate().rev() {
        match joint.revolute_coordinate_axis() {
            Some(k) => out[joint.v_index] = force[i].angular[k],
            None => joint.project_force(
                &force[i],
                &mut out[joint.v_index..joint.v_index + joint.nv()],
            ),
        }
        if let Some(p) = joint.parent {
            let in_parent = parent_from_body[i].act_force(&force[i]);
            force[p] += in_parent;
        }
    }
}

/// Inverse dynamics with external wrenches: `data.tau = M(q) q̈ + C(q, v) v + g(q) − Σ_i J_iᵀ f_i`,
/// where `external[i]` is the wrench applied to body `i` by its surroundings, in body `i`'s frame
/// about its origin (Featherstone §5.3: `f_i = I_i a_i + v_i ×* I_i v_i − f_i^ext`).
///
/// `q: dim nq`, `v, qdd: dim nv`, `external`: one per body. Overwrites the same buffers as
/// [`rnea`]; returns `data.tau`. With every external wrench zero the result is [`rnea`]'s.
pub fn rnea_with_external<'a>(
    model: &Model,
    gravity: &Vec3,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    qdd: &[f64],
    external: &[crate::spatial::Force],
) -> &'a [f64] {
    joint_placements(model, data, q);
    run(model, gravity, data, v, Some(qdd));
    for (f, e) in data.force.iter_mut().zip(external) {
        *f = *f - *e;
    }
    let Data {
        parent_from_body,
        force,
        tau,
        ..
    } = data;
    backward(model, parent_from_body, force, tau.as_mut_slice());
    data.tau.as_slice()
}

/// Adds the generalised forces `Σ_i J_iᵀ f_i` of external wrenches to `out` (dim nv): RNEA's
/// backward pass with the external wrenches as the only body forces. `external[i]` is body `i`'s
/// wrench in its own frame; it is consumed (wrenches accumulate into parents). `parent_from_body`
/// must be the placements at the current `q` (any kinematics pass writes them).
pub fn add_external_forces(
    model: &Model,
    parent_from_body: &[crate::spatial::Transform],
    external: &mut [crate::spatial::Force],
    out: &mut [f64],
) {
    let mut projected = [0.0; 6];
    for (i, joint) in model.joints.iter().enumerate().rev() {
        let nv = joint.nv();
        joint.project_force(&external[i], &mut projected[..nv]);
        for (o, p) in out[joint.v_index..joint.v_index + nv]
            .iter_mut()
            .zip(&projected[..nv])
        {
            *o += p;
        }
        if let Some(p) = joint.parent {
            let in_parent = parent_from_body[i].act_force(&external[i]);
            external[p] += in_parent;
        }
    }
}
