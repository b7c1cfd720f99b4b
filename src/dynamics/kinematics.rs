//! Forward kinematics: `q ⇒ (parent_from_body, world_from_body)`, and URDF link frames.

use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::trig::sin_cos_lanes;
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
    if KEEP_JOINT {
        joint_placements(model, data, q);
    }
    for (i, joint) in model.joints.iter().enumerate() {
        let parent_from_body = if KEEP_JOINT {
            data.parent_from_body[i]
        } else {
            joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()])
        };
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
///
/// The revolute joints' sines and cosines are computed eight angles at a time (`SIN_COS_LANES`)
/// ([`crate::spatial::trig::sin_cos_lanes`]: each lane the operations, so the bits, of one
/// [`crate::spatial::trig::sin_cos`]), so that their polynomials run side by side in vector
/// registers; every placement has the bits of [`crate::model::Joint::parent_from_child`].
pub fn joint_placements(model: &Model, data: &mut Data, q: &[f64]) {
    let mut chunk = RevoluteChunk::default();
    for (i, joint) in model.joints.iter().enumerate() {
        if joint.kind == JointKind::Revolute {
            if chunk.len == SIN_COS_LANES {
                chunk.place(model, data);
            }
            chunk.push(i, q[joint.q_index]);
        } else {
            data.parent_from_body[i] =
                joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()]);
        }
    }
    chunk.place(model, data);
}

/// How many revolute joints' sines and cosines [`joint_placements`] computes together: eight
/// `f64` lanes, four SSE2 registers (the baseline instruction set) per statement, so that the
/// polynomials of a whole arm run side by side.
const SIN_COS_LANES: usize = 8;

/// Up to [`SIN_COS_LANES`] revolute joints (their indices and angles) waiting for their sines and
/// cosines.
#[derive(Default)]
struct RevoluteChunk {
    joints: [usize; SIN_COS_LANES],
    angles: [f64; SIN_COS_LANES],
    len: usize,
}

impl RevoluteChunk {
    fn push(&mut self, joint: usize, angle: f64) {
        self.joints[self.len] = joint;
        self.angles[self.len] = angle;
        self.len += 1;
    }

    /// Writes the waiting joints' placements (the unused lanes hold angle 0) and empties the chunk.
    fn place(&mut self, model: &Model, data: &mut Data) {
        if self.len == 0 {
            return;
        }
        self.angles[self.len..].fill(0.0);
        let (sin, cos) = sin_cos_lanes(self.angles);
        for lane in 0..self.len {
            let i = self.joints[lane];
            data.parent_from_body[i] =
                model.joints[i].revolute_parent_from_child(sin[lane], cos[lane]);
        }
        self.len = 0;
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
    joint_placements(model, data, q);
    for (i, joint) in model.joints.iter().enumerate() {
        let vi = joint.v_index;
        let parent_from_body = data.parent_from_body[i];
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

    /// A serial chain of `kinds.len()` joints (`(type, axis)` each) with unit links, as URDF text.
    fn chain_urdf(kinds: &[(&str, &str)]) -> String {
        let link = |i: usize| {
            format!(
                r#"<link name="l{i}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>
                <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>"#
            )
        };
        let mut text = String::from(r#"<robot name="chain">"#);
        text += &link(0);
        for (i, (kind, axis)) in kinds.iter().enumerate() {
            text += &link(i + 1);
            text += &format!(
                r#"<joint name="j{i}" type="{kind}"><parent link="l{i}"/><child link="l{}"/>
                <origin xyz="0.3 0.1 0" rpy="0.2 -0.1 0.4"/><axis xyz="{axis}"/>
                <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#,
                i + 1
            );
        }
        text + "</robot>"
    }

    /// `joint_placements` (sines and cosines eight joints at a time) gives every joint the bits of
    /// its own `parent_from_child`: on a chain of eleven revolute joints (a full chunk and a
    /// partial one) about every coordinate axis and a tilted one (the general rotation), with a
    /// prismatic joint between them, at angles within and beyond the reduced range (libm's sine
    /// and cosine); and on the quadruped (a floating base).
    #[test]
    fn joint_placements_have_the_bits_of_each_joints_own_placement() {
        let mut kinds = vec![("revolute", "0 0 1"); 11];
        kinds[1].1 = "1 0 0";
        kinds[2].1 = "0 1 0";
        kinds[3].1 = "0.6 0 0.8";
        kinds[9].1 = "0 -1 0";
        kinds.insert(5, ("prismatic", "0 1 0"));
        let chain = Model::from_urdf_str(&chain_urdf(&kinds), "chain.urdf", LoadOptions::default())
            .unwrap();
        assert_eq!(chain.joints[3].revolute_coordinate_axis(), None);
        assert!(chain.joints.len() > SIN_COS_LANES + 2);
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/quadruped/quadruped.urdf");
        let quadruped = Model::from_urdf_file(&path, LoadOptions::default()).unwrap();
        for model in [chain, quadruped] {
            let mut q: Vec<f64> = (0..model.nq).map(|i| 0.37 - 0.61 * i as f64).collect();
            if model.joints[0].kind == JointKind::Floating {
                q[3..7].copy_from_slice(&[0.1, -0.2, 0.3, (1.0f64 - 0.14).sqrt()]);
            }
            for far in [0.0, 2.0e3, -7.5e5] {
                let mut q = q.clone();
                *q.last_mut().unwrap() += far;
                let mut data = Data::new(&model);
                joint_placements(&model, &mut data, &q);
                for (i, joint) in model.joints.iter().enumerate() {
                    let own =
                        joint.parent_from_child(&q[joint.q_index..joint.q_index + joint.nq()]);
                    let bits = |x: &Transform| {
                        x.rotation
                            .iter()
                            .chain(x.translation.iter())
                            .map(|v| v.to_bits())
                            .collect::<Vec<_>>()
                    };
                    assert_eq!(
                        bits(&data.parent_from_body[i]),
                        bits(&own),
                        "joint {i}, {far}"
                    );
                }
            }
        }
    }

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
