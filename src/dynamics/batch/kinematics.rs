//! Forward kinematics over a batch: [`crate::dynamics::forward_kinematics`] lane by lane.

use super::joint::parent_from_child;
use super::lanes::Lanes;
use super::model::BatchModel;
use super::state::{BatchData, BatchVectors};
use super::IsaKind;

/// Computes `data.parent_from_body` and `data.world_from_body` of every sample for its
/// configuration in `q` (`dim nq`). Each sample's placements have the bits that
/// [`crate::dynamics::forward_kinematics`] gives on that sample's model.
pub fn forward_kinematics<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    match model.isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2
            // (`Isa::avx2`), which is all `forward_kinematics_chunks_avx2` requires.
            unsafe { forward_kinematics_chunks_avx2(model, data, q) }
        }
        _ => forward_kinematics_chunks(model, data, q),
    }
}

#[inline(always)]
pub(super) fn forward_kinematics_chunks<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    let nb = model.joints.len();
    for (c, values) in model.chunks.iter().enumerate() {
        let q = q.chunk(c);
        let parent_from_body = &mut data.parent_from_body[c * nb..(c + 1) * nb];
        let world_from_body = &mut data.world_from_body[c * nb..(c + 1) * nb];
        chunk(model, values, q, parent_from_body, world_from_body);
    }
}

/// Computes `data.parent_from_body` only, of every sample (the batched
/// [`crate::dynamics::joint_placements`]: what CRBA needs, `world_from_body` left as it was).
#[inline(always)]
pub(super) fn joint_placements_chunks<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    let nb = model.joints.len();
    for (c, values) in model.chunks.iter().enumerate() {
        let q = q.chunk(c);
        let parent_from_body = &mut data.parent_from_body[c * nb..(c + 1) * nb];
        for (i, joint) in model.joints.iter().enumerate() {
            parent_from_body[i] = parent_from_child(
                joint.kind,
                &values.coordinate_axes[i],
                &values.parent_from_joint[i],
                &values.axis[i],
                &q[joint.q_index..joint.q_index + joint.nq()],
            );
        }
    }
}

#[inline(always)]
fn chunk<const W: usize>(
    model: &BatchModel<W>,
    values: &super::model::ChunkValues<W>,
    q: &[Lanes<W>],
    parent_from_body: &mut [super::lanes::TransformLanes<W>],
    world_from_body: &mut [super::lanes::TransformLanes<W>],
) {
    for (i, joint) in model.joints.iter().enumerate() {
        let x = parent_from_child(
            joint.kind,
            &values.coordinate_axes[i],
            &values.parent_from_joint[i],
            &values.axis[i],
            &q[joint.q_index..joint.q_index + joint.nq()],
        );
        parent_from_body[i] = x;
        world_from_body[i] = match joint.parent {
            Some(p) => world_from_body[p].compose(&x),
            None => x,
        };
    }
}

/// [`forward_kinematics_chunks`] compiled with AVX2 enabled (4-wide `f64` lanes; no FMA: docs/batch.md §3).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn forward_kinematics_chunks_avx2<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    forward_kinematics_chunks(model, data, q)
}
