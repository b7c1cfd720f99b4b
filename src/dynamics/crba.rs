//! Composite-rigid-body algorithm for the joint-space mass matrix (Featherstone §6.2):
//!
//! `I^c_i = I_i + Σ_children X I^c_child`;  for each column `S_i[:, k]`: `F = I^c_i S_i[:, k]`,
//! `M[i, i] = S_iᵀ F`, then walking up the ancestors `F ← X F`, `M[j, i] = M[i, j]ᵀ = S_jᵀ F`.

use super::{joint_placements, Data};
use crate::model::{Joint, JointKind, Model};
use crate::spatial::{Force, Inertia, Motion};

/// Joint-space mass matrix: `data.mass_matrix = M(q)` (full, symmetric).
///
/// `q: dim nq`. Overwrites `data.parent_from_body`, `data.composite` and `data.mass_matrix` (not
/// `data.world_from_body`, which the algorithm does not need: call
/// [`forward_kinematics`](super::forward_kinematics) for placements, as after [`rnea`](super::rnea));
/// returns `data.mass_matrix`.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a nalgebra::DMatrix<f64> {
    joint_placements(model, data, q);
    for (composite, body) in data.composite.iter_mut().zip(&model.bodies) {
        *composite = body.inertia;
    }
    for (i, joint) in model.joints.iter().enumerate().rev() {
        if let Some(p) = joint.parent {
            let in_parent = data.parent_from_body[i].act_inertia(&data.composite[i]);
            data.composite[p] += in_parent;
        }
    }
    let n = model.nv;
    let Data {
        parent_from_body,
        composite,
        mass_matrix,
        ..
    } = data;
    // Column-major storage: entry (row, column) at `row + column · n`.
    let mass = mass_matrix.as_mut_slice();
    mass.fill(0.0);
    for (i, joint) in model.joints.iter().enumerate() {
        for k in 0..joint.nv() {
            let column = joint.v_index + k;
            let mut force =
                apply_to_subspace_column(&composite[i], joint.kind, &joint.subspace_column(k));
            for_each_projection(joint, &force, |row, value| mass[row + column * n] = value);
            let mut child = i;
            while let Some(ancestor) = model.joints[child].parent {
                force = parent_from_body[child].act_force(&force);
                for_each_projection(&model.joints[ancestor], &force, |row, value| {
                    mass[row + column * n] = value;
                    mass[column + row * n] = value;
                });
                child = ancestor;
            }
        }
    }
    &data.mass_matrix
}

/// Calls `write(row, value)` for each entry of `Sᵀ f` ([`crate::model::Joint::project_force`]),
/// `row` counting in `v`: a one-degree-of-freedom joint's single entry without a buffer or a loop.
#[inline(always)]
fn for_each_projection(joint: &Joint, force: &Force, mut write: impl FnMut(usize, f64)) {
    match joint.kind {
        JointKind::Revolute => write(joint.v_index, joint.axis().dot(&force.angular)),
        JointKind::Prismatic => write(joint.v_index, joint.axis().dot(&force.linear)),
        JointKind::Floating => {
            let mut projected = [0.0; 6];
            joint.project_force(force, &mut projected);
            for (k, value) in projected.into_iter().enumerate() {
                write(joint.v_index + k, value);
            }
        }
    }
}

/// `I S_k` for a column of a joint's motion subspace: [`Inertia::apply`] with the products by the
/// column's known zero half left out (a revolute column is purely angular, a prismatic one purely
/// linear). The products left out are exact zeros and so are the sums they would enter, so the
/// result has the same bits as `inertia.apply(column)` (signs of zero aside).
#[inline]
fn apply_to_subspace_column(inertia: &Inertia, kind: JointKind, column: &Motion) -> Force {
    match kind {
        JointKind::Revolute => Force {
            linear: -inertia.first_moment.cross(&column.angular),
            angular: inertia.rotational * column.angular,
        },
        JointKind::Prismatic => Force {
            linear: column.linear * inertia.mass,
            angular: inertia.first_moment.cross(&column.linear),
        },
        JointKind::Floating => inertia.apply(column),
    }
}
