//! Composite-rigid-body algorithm over a batch: [`crate::dynamics::crba`] lane by lane
//! (Featherstone §6.2; the recursion is in `src/dynamics/crba.rs`).

use super::joint::{project_force, subspace_column};
use super::kinematics::joint_placements_chunks;
use super::lanes::{
    cross, dot, mat_vec, v3_neg, v3_scale, ForceLanes, InertiaLanes, Lanes, MotionLanes, V3,
};
use super::model::{BatchJoint, BatchModel};
use super::state::{BatchData, BatchVectors};
use super::IsaKind;
use crate::model::JointKind;

/// Joint-space mass matrix of every sample: `data.mass_matrix` (`nv × nv` column-major per sample,
/// full, symmetric) `= M(q)`.
///
/// `q: dim nq` per sample. Overwrites `data.parent_from_body`, `data.composite` and
/// `data.mass_matrix` (not `data.world_from_body`, as the scalar kernel). Each sample's matrix has the bits of
/// [`crate::dynamics::crba`] on that sample's model.
pub fn crba<const W: usize>(model: &BatchModel<W>, data: &mut BatchData<W>, q: &BatchVectors<W>) {
    match model.isa.kind() {
        #[cfg(target_arch = "x86_64")]
        IsaKind::Avx2 => {
            // SAFETY: an `Isa` of kind `Avx2` exists only after the running CPU reported AVX2
            // (`Isa::avx2`), which is all `crba_chunks_avx2` requires.
            unsafe { crba_chunks_avx2(model, data, q) }
        }
        _ => crba_chunks(model, data, q),
    }
}

#[inline(always)]
pub(super) fn crba_chunks<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    joint_placements_chunks(model, data, q);
    let nb = model.joints.len();
    let n = model.nv;
    for (c, values) in model.chunks.iter().enumerate() {
        let parent_from_body = &data.parent_from_body[c * nb..(c + 1) * nb];
        let composite = &mut data.composite[c * nb..(c + 1) * nb];
        composite.copy_from_slice(&values.inertia);
        for (i, joint) in model.joints.iter().enumerate().rev() {
            if let Some(p) = joint.parent {
                let in_parent = parent_from_body[i].act_inertia(&composite[i]);
                composite[p].add_assign(&in_parent);
            }
        }
        // Column-major storage: entry (row, column) at `row + column · n`.
        let mass = &mut data.mass_matrix.chunks[c * n * n..(c + 1) * n * n];
        // Every entry below is written except those of joints on different branches, which are
        // zero (and the lock-step's in-place factorisation may have overwritten).
        for &k in &model.mass_matrix_zeros {
            mass[k] = Lanes::zero();
        }
        for (i, joint) in model.joints.iter().enumerate() {
            let axis = &values.axis[i];
            for k in 0..joint.nv() {
                let column = joint.v_index + k;
                let mut force = apply_to_subspace_column(
                    &composite[i],
                    joint.kind,
                    &subspace_column(joint.kind, axis, k),
                );
                for_each_projection(joint, axis, &force, |row, value| {
                    mass[row + column * n] = value
                });
                let mut child = i;
                while let Some(ancestor) = model.joints[child].parent {
                    force = parent_from_body[child].act_force(&force);
                    let ancestor_axis = &values.axis[ancestor];
                    for_each_projection(
                        &model.joints[ancestor],
                        ancestor_axis,
                        &force,
                        |row, value| {
                            mass[row + column * n] = value;
                            mass[column + row * n] = value;
                        },
                    );
                    child = ancestor;
                }
            }
        }
    }
}

/// Calls `write(row, value)` for each entry of `Sᵀ f` ([`project_force`]), `row` counting in `v`:
/// a one-degree-of-freedom joint's single entry without a buffer or a loop (as the scalar CRBA).
#[inline(always)]
fn for_each_projection<const W: usize>(
    joint: &BatchJoint,
    axis: &V3<W>,
    force: &ForceLanes<W>,
    mut write: impl FnMut(usize, Lanes<W>),
) {
    match joint.kind {
        JointKind::Revolute => write(joint.v_index, dot(axis, &force.angular)),
        JointKind::Prismatic => write(joint.v_index, dot(axis, &force.linear)),
        JointKind::Floating => {
            let mut projected = [Lanes::zero(); 6];
            project_force(joint.kind, axis, force, &mut projected);
            for (k, value) in projected.into_iter().enumerate() {
                write(joint.v_index + k, value);
            }
        }
    }
}

/// `I S_k` with the products by the column's known zero half left out, exactly as the scalar CRBA
/// does (so the same products, in the same order, are computed).
#[inline(always)]
fn apply_to_subspace_column<const W: usize>(
    inertia: &InertiaLanes<W>,
    kind: JointKind,
    column: &MotionLanes<W>,
) -> ForceLanes<W> {
    match kind {
        JointKind::Revolute => ForceLanes {
            linear: v3_neg(&cross(&inertia.first_moment, &column.angular)),
            angular: mat_vec(&inertia.rotational, &column.angular),
        },
        JointKind::Prismatic => ForceLanes {
            linear: v3_scale(&column.linear, inertia.mass),
            angular: cross(&inertia.first_moment, &column.linear),
        },
        JointKind::Floating => inertia.apply(column),
    }
}

/// [`crba_chunks`] compiled with AVX2 enabled (4-wide `f64` lanes; no FMA: docs/batch.md §3).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn crba_chunks_avx2<const W: usize>(
    model: &BatchModel<W>,
    data: &mut BatchData<W>,
    q: &BatchVectors<W>,
) {
    crba_chunks(model, data, q)
}
