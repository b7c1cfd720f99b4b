//! Recursive Newton–Euler inverse dynamics over a batch: [`crate::dynamics::rnea`] and
//! [`crate::dynamics::nonlinear_effects`] lane by lane (Featherstone §5.3; the recursion is in
//! `src/dynamics/rnea.rs`).

use super::joint::{forward_motion, parent_from_child, project_force_aligned};
use super::lanes::{v3_neg, v3_zero, ForceLanes, Lanes, MotionLanes, TransformLanes};
use super::model::{BatchModel, ChunkValues};
use super::state::{BatchData, BatchVectors};
use super::IsaKind;

/// Inverse dynamics of every sample: `data.tau = M(q) q̈ + C(q, v) v + g(q)`, rigid-body terms only.
///
/// `q: dim nq`, `v, qdd: dim nv` per sample. Overwrites `data.parent_from_body`, `data.velocity`,
/// `data.acceleration`, `data.force` and `data.tau`. Each sample's torques have the bits of
/// [`crate::dynamics::rnea`] on that sample's model.
pub fn rnea<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
    v: &BatchVectors<W>,
    qdd: &BatchVectors<W>,
) {
    rnea_dispatch(model, data, Some(q), v, Some(qdd));
}

/// [`rnea`] at the configurations whose placements `data.parent_from_body` already holds (as
/// [`super::crba`] or [`super::forward_kinematics`] left them, or the last [`rnea`]): the joint
/// transforms are not computed again. Each sample's torques have the bits of [`rnea`] at that
/// configuration, since the placements are the same values computed the same way. Overwrites
/// `data.velocity`, `data.acceleration`, `data.force` and `data.tau`.
pub fn rnea_at_placements<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    v: &BatchVectors<W>,
    qdd: &BatchVectors<W>,
) {
    rnea_dispatch(model, data, None, v, Some(qdd));
}

/// Bias forces of every sample: `data.bias = C(q, v) v + g(q)`; overwrites the same kinematic
/// buffers as [`rnea`] and `data.bias`. Bitwise [`crate::dynamics::nonlinear_effects`] per sample.
pub fn nonlinear_effects<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
    v: &BatchVectors<W>,
) {
    rnea_dispatch(model, data, Some(q), v, None);
}

/// Runs [`rnea_chunks`] with the model's instruction set; `q: None` reuses the placements in
/// `data.parent_from_body`.
fn rnea_dispatch<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: Option<&BatchVectors<W>>,
    v: &BatchVectors<W>,
    qdd: Option<&BatchVectors<W>>,
) {
    match model.isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2
            // (`Isa::avx2`), which is all `rnea_chunks_avx2` requires.
            unsafe { rnea_chunks_avx2(model, data, q, v, qdd) }
        }
        _ => rnea_chunks(model, data, q, v, qdd),
    }
}

#[inline(always)]
fn rnea_chunks<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: Option<&BatchVectors<W>>,
    v: &BatchVectors<W>,
    qdd: Option<&BatchVectors<W>>,
) {
    let nb = model.joints.len();
    let nv = model.nv;
    for (c, values) in model.chunks.iter().enumerate() {
        let range = c * nb..(c + 1) * nb;
        let buffers = Buffers {
            parent_from_body: &mut data.parent_from_body[range.clone()],
            velocity: &mut data.velocity[range.clone()],
            acceleration: &mut data.acceleration[range.clone()],
            force: &mut data.force[range],
        };
        let out = match qdd {
            Some(_) => &mut data.tau.chunks[c * nv..(c + 1) * nv],
            None => &mut data.bias.chunks[c * nv..(c + 1) * nv],
        };
        chunk(
            model,
            values,
            buffers,
            q.map(|q| q.chunk(c)),
            v.chunk(c),
            qdd.map(|a| a.chunk(c)),
            out,
        );
    }
}

/// The kinematic buffers of one chunk.
struct Buffers<'a, const W: usize> {
    parent_from_body: &'a mut [TransformLanes<W>],
    velocity: &'a mut [MotionLanes<W>],
    acceleration: &'a mut [MotionLanes<W>],
    force: &'a mut [ForceLanes<W>],
}

#[inline(always)]
fn chunk<const W: usize>(
    model: &BatchModel<W>,
    values: &ChunkValues<W>,
    b: Buffers<'_, W>,
    q: Option<&[Lanes<W>]>,
    v: &[Lanes<W>],
    qdd: Option<&[Lanes<W>]>,
    out: &mut [Lanes<W>],
) {
    let base_acceleration = MotionLanes {
        linear: v3_neg(&values.gravity),
        angular: v3_zero(),
    };
    for (i, joint) in model.joints.iter().enumerate() {
        let (qi, vi) = (joint.q_index, joint.v_index);
        let axis = &values.axis[i];
        let axes = &values.coordinate_axes[i];
        // Without `q`, the placement this configuration already has (`rnea_at_placements`).
        if let Some(q) = q {
            b.parent_from_body[i] = parent_from_child(
                joint.kind,
                axes,
                &values.parent_from_joint[i],
                axis,
                &q[qi..qi + joint.nq()],
            );
        }
        let parent_from_body = &b.parent_from_body[i];
        let (parent_velocity, parent_acceleration) = match joint.parent {
            Some(p) => (b.velocity[p], b.acceleration[p]),
            None => (MotionLanes::zero(), base_acceleration),
        };
        let (velocity, acceleration) = forward_motion(
            joint.kind,
            axes,
            axis,
            parent_from_body,
            &parent_velocity,
            &parent_acceleration,
            &v[vi..vi + joint.nv()],
            qdd.map(|qdd| &qdd[vi..vi + joint.nv()]),
        );
        let inertia = &values.inertia[i];
        b.force[i] = inertia
            .apply(&acceleration)
            .add(&velocity.cross_force(&inertia.apply(&velocity)));
        b.velocity[i] = velocity;
        b.acceleration[i] = acceleration;
    }
    for (i, joint) in model.joints.iter().enumerate().rev() {
        project_force_aligned(
            joint.kind,
            &values.coordinate_axes[i],
            &values.axis[i],
            &b.force[i],
            &mut out[joint.v_index..joint.v_index + joint.nv()],
        );
        if let Some(p) = joint.parent {
            let in_parent = b.parent_from_body[i].act_force(&b.force[i]);
            b.force[p] = b.force[p].add(&in_parent);
        }
    }
}

/// [`rnea_chunks`] compiled with AVX2 enabled (4-wide `f64` lanes; no FMA: docs/batch.md §3).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn rnea_chunks_avx2<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: Option<&BatchVectors<W>>,
    v: &BatchVectors<W>,
    qdd: Option<&BatchVectors<W>>,
) {
    rnea_chunks(model, data, q, v, qdd)
}
