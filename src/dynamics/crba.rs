//! Composite-rigid-body algorithm for the joint-space mass matrix (Featherstone §6.2):
//!
//! `I^c_i = I_i + Σ_children X I^c_child`;  for each column `S_i[:, k]`: `F = I^c_i S_i[:, k]`,
//! `M[i, i] = S_iᵀ F`, then walking up the ancestors `F ← X F`, `M[j, i] = M[i, j]ᵀ = S_jᵀ F`.

use super::{forward_kinematics, Data};
use crate::model::Model;

/// Joint-space mass matrix: `data.mass_matrix = M(q)` (full, symmetric).
///
/// `q: dim nq`. Overwrites `data.parent_from_body`, `data.world_from_body`, `data.composite` and
/// `data.mass_matrix`; returns `data.mass_matrix`.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a nalgebra::DMatrix<f64> {
    forward_kinematics(model, data, q);
    for (composite, body) in data.composite.iter_mut().zip(&model.bodies) {
        *composite = body.inertia;
    }
    for (i, joint) in model.joints.iter().enumerate().rev() {
        if let Some(p) = joint.parent {
            let in_parent = data.parent_from_body[i].act_inertia(&data.composite[i]);
            data.composite[p] += in_parent;
        }
    }
    data.mass_matrix.fill(0.0);
    let mut projected = [0.0; 6];
    for (i, joint) in model.joints.iter().enumerate() {
        for k in 0..joint.nv() {
            let column = joint.v_index + k;
            let mut force = data.composite[i].apply(&joint.subspace_column(k));
            joint.project_force(&force, &mut projected);
            for (kk, value) in projected[..joint.nv()].iter().enumerate() {
                data.mass_matrix[(joint.v_index + kk, column)] = *value;
            }
            let mut child = i;
            while let Some(ancestor) = model.joints[child].parent {
                force = data.parent_from_body[child].act_force(&force);
                let ancestor_joint = &model.joints[ancestor];
                ancestor_joint.project_force(&force, &mut projected);
                for (kk, value) in projected[..ancestor_joint.nv()].iter().enumerate() {
                    let row = ancestor_joint.v_index + kk;
                    data.mass_matrix[(row, column)] = *value;
                    data.mass_matrix[(column, row)] = *value;
                }
                child = ancestor;
            }
        }
    }
    &data.mass_matrix
}
