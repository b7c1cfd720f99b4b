//! Forward kinematics: `q ⇒ (parent_from_body, world_from_body)`, and URDF link frames.

use super::Data;
use crate::model::Model;
use crate::spatial::Transform;

/// Computes `data.parent_from_body` and `data.world_from_body` for `q` (`dim nq`).
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) {
    for (i, joint) in model.joints.iter().enumerate() {
        let parent_from_body =
            joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()]);
        data.parent_from_body[i] = parent_from_body;
        data.world_from_body[i] = match joint.parent {
            Some(p) => data.world_from_body[p].compose(&parent_from_body),
            None => parent_from_body,
        };
    }
}

/// `world_from_link` of URDF link `link` (an index into `model.description.links`), from the body
/// placements of the last [`forward_kinematics`].
pub fn frame_placements(model: &Model, data: &Data, link: usize) -> Transform {
    let placement = &model.links[link];
    match placement.body {
        Some(b) => data.world_from_body[b].compose(&placement.body_from_link),
        None => placement.body_from_link,
    }
}
