//! Forward kinematics: `q ⇒ (parent_from_body, world_from_body)`, and URDF link frames.

use super::Data;
use crate::model::Model;
use crate::spatial::Transform;

/// Computes `data.parent_from_body` and `data.world_from_body` for `q` (`dim nq`).
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) {
    placements::<true>(model, data, q);
}

/// Computes `data.world_from_body` for `q` (`dim nq`) and nothing else: [`forward_kinematics`]'s
/// world placements, with the same bits, for a caller that reads only those (the loop
/// closures' rows); `data.parent_from_body` is left as it was.
pub fn world_placements(model: &Model, data: &mut Data, q: &[f64]) {
    placements::<false>(model, data, q);
}

/// The world placements, and with `KEEP_JOINT` the joint placements they compose.
#[inline(always)]
fn placements<const KEEP_JOINT: bool>(model: &Model, data: &mut Data, q: &[f64]) {
    for (i, joint) in model.joints.iter().enumerate() {
        let parent_from_body =
            joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()]);
        if KEEP_JOINT {
            data.parent_from_body[i] = parent_from_body;
        }
        data.world_from_body[i] = match joint.parent {
            Some(p) => data.world_from_body[p].compose(&parent_from_body),
            None => parent_from_body,
        };
    }
}

/// Computes `data.parent_from_body` only (each joint's placement in its parent body, `q: dim
/// nq`): what the composite-rigid-body algorithm needs, without composing the world placements
/// (`data.world_from_body` is left as it was; [`forward_kinematics`] computes both, with the same
/// `parent_from_body` bits).
pub fn joint_placements(model: &Model, data: &mut Data, q: &[f64]) {
    for (i, joint) in model.joints.iter().enumerate() {
        data.parent_from_body[i] =
            joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()]);
    }
}

/// The placement of URDF link `link` (an index into `model.links`, same order as
/// `model.description.links`) in the world frame: `world_from_body[b] ∘ body_from_link` of the body
/// `b` it is fixed to (`body_from_link` itself for a link on the world). Reads only
/// `data.world_from_body`, so `data` must hold a [`forward_kinematics`] (or [`drift_kinematics`])
/// pass at the `q` of interest; writes nothing.
pub fn world_from_link(model: &Model, data: &Data, link: usize) -> Transform {
    model.links[link].world_from_link(&data.world_from_body)
}

/// Drift kinematics: body placements, velocities and the accelerations they would have with `q̈ = 0`
/// and no gravity (the `J̇ q̇` terms of constraint accelerations). `q: dim nq`, `v: dim nv`.
/// Overwrites `data.parent_from_body`, `data.world_from_body`, `data.velocity`, `data.acceleration`.
pub fn drift_kinematics(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) {
    for (i, joint) in model.joints.iter().enumerate() {
        let (qi, vi) = (joint.q_index, joint.v_index);
        let parent_from_body = joint.parent_from_child(&q[qi..qi + joint.nq()]);
        let joint_velocity = joint.motion(&v[vi..vi + joint.nv()]);
        let (parent_velocity, parent_acceleration, world_from_parent) = match joint.parent {
            Some(p) => (
                data.velocity[p],
                data.acceleration[p],
                Some(data.world_from_body[p]),
            ),
            None => (
                crate::spatial::Motion::zero(),
                crate::spatial::Motion::zero(),
                None,
            ),
        };
        let (moved_velocity, moved_acceleration) =
            parent_from_body.inv_act_motion_pair(&parent_velocity, &parent_acceleration);
        let velocity = moved_velocity + joint_velocity;
        data.acceleration[i] = moved_acceleration + velocity.cross_motion(&joint_velocity);
        data.velocity[i] = velocity;
        data.parent_from_body[i] = parent_from_body;
        data.world_from_body[i] = match world_from_parent {
            Some(w) => w.compose(&parent_from_body),
            None => parent_from_body,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::LoadOptions;
    use std::path::Path;

    /// `world_placements` writes `forward_kinematics`'s world placements bit for bit and leaves
    /// the joint placements as they were.
    #[test]
    fn world_placements_have_the_bits_of_forward_kinematics_and_leave_the_joints() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/four_bar/four_bar.urdf");
        let model = Model::from_urdf_file(&path, LoadOptions::default()).unwrap();
        let q: Vec<f64> = (0..model.nq).map(|i| 0.4 - 0.7 * i as f64).collect();
        let mut full = Data::new(&model);
        forward_kinematics(&model, &mut full, &q);
        let mut world_only = Data::new(&model);
        let elsewhere: Vec<f64> = q.iter().map(|x| x + 1.0).collect();
        forward_kinematics(&model, &mut world_only, &elsewhere);
        let joints_before = world_only.parent_from_body.clone();
        world_placements(&model, &mut world_only, &q);
        let bits = |placements: &[Transform]| {
            placements
                .iter()
                .flat_map(|x| x.rotation.iter().chain(x.translation.iter()))
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        };
        assert!(model.joints.iter().any(|j| j.parent.is_some()));
        assert_eq!(
            bits(&world_only.world_from_body),
            bits(&full.world_from_body)
        );
        assert_eq!(bits(&world_only.parent_from_body), bits(&joints_before));
    }
}
