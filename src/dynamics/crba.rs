//! Composite-rigid-body algorithm for the joint-space mass matrix (Featherstone §6.2):
//!
//! `I^c_i = I_i + Σ_children X I^c_child`;  for each column `S_i[:, k]`: `F = I^c_i S_i[:, k]`,
//! `M[i, i] = S_iᵀ F`, then walking up the ancestors `F ← X F`, `M[j, i] = M[i, j]ᵀ = S_jᵀ F`.

use super::{joint_placements, Data};
use crate::model::{Joint, JointKind, Model};
use crate::spatial::{Force, Inertia, Motion, Transform};

/// Joint-space mass matrix: `data.mass_matrix = M(q)` (full, symmetric).
///
/// `q: dim nq`. Overwrites `data.parent_from_body`, `data.mass_matrix` and the work buffers of
/// [`crba_at_placements`] (not `data.world_from_body`, which the algorithm does not need: call
/// [`forward_kinematics`](super::forward_kinematics) for placements, as after [`rnea`](super::rnea));
/// returns `data.mass_matrix`.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a nalgebra::DMatrix<f64> {
    joint_placements(model, data, q);
    crba_at_placements(model, data)
}

/// [`crba`] at the joint placements `data.parent_from_body` already holds (as [`rnea`](super::rnea),
/// [`nonlinear_effects`](super::nonlinear_effects) and [`crba`] leave them for their `q`): the same
/// bits as `crba` at that `q`, without computing the placements again.
///
/// One sweep from the leaves to the root (the order of Featherstone's Table 6.2 and of Pinocchio's
/// CRBA): at joint `i` its composite inertia is complete, so its own columns start there
/// (`F = I^c_i S_i`); then the composite inertia and the forces of every column of its subtree
/// move on to the parent, each force projected onto the parent's `S` as it arrives. Each column's
/// force goes through the same transforms in the same order as a walk up from its own joint, and
/// the composite inertias are summed in the same order as a separate pass, so the bits do not
/// depend on the interleaving; what the interleaving buys is independent work beside the
/// composite inertias' chain of dependent transforms (measured in benches/README.md, "The CRBA in
/// one sweep").
///
/// A root joint (no parent) that turns about a coordinate axis `e_k` of its frame
/// ([`Joint::revolute_coordinate_axis`]) reads only entry `k` of each force arriving from its
/// child and entry `(k, k)` of its composite inertia (`Sᵀ F` and `Sᵀ I^c S` with `S = (0, e_k)`),
/// so the last carry computes only those ([`Transform::act_force_angular_entry`],
/// [`Transform::act_inertia_rotational_diagonal`]: the same products in the same order as the
/// full transforms' entries; our ur5: 5 059 → 4 805 instructions per call, benches/README.md,
/// "Our ur5 against erd's, and the CRBA's root carry"). The general projection adds the other
/// entries times an exact zero, which changes nothing unless the kept entry is itself zero (then
/// the zero's sign can differ) or not finite; such an entry sends the whole call through the
/// general sweep, so `M` has the general formulas' bits always (overflow of an unread entry aside,
/// at forces above ~1e300).
///
/// Overwrites `data.composite` (at such a root only its entry `(k, k)` is complete),
/// `data.column_force`, `data.subtree_velocity_end` and `data.mass_matrix`; returns
/// `data.mass_matrix`.
pub fn crba_at_placements<'a>(model: &Model, data: &'a mut Data) -> &'a nalgebra::DMatrix<f64> {
    if !sweep::<true>(model, data) {
        general_sweep(model, data);
    }
    &data.mass_matrix
}

/// [`crba_at_placements`]'s sweep without the root's shortcut: for a root entry that was zero or
/// not finite (rare, hence out of line).
#[cold]
#[inline(never)]
fn general_sweep(model: &Model, data: &mut Data) {
    sweep::<false>(model, data);
}

/// Whether the root's shortcut gives the general formulas' bits for this entry: any finite
/// nonzero value (see [`crba_at_placements`]).
#[inline(always)]
fn shortcut_exact(value: f64) -> bool {
    value != 0.0 && value.is_finite()
}

/// The sweep of [`crba_at_placements`]; with `ROOT_SHORTCUT` the root joints about a coordinate
/// axis take the shortcut, and the return value says whether every entry it gave was exact
/// (else `M` must be computed again without it). Without, always `true`.
#[inline(always)]
fn sweep<const ROOT_SHORTCUT: bool>(model: &Model, data: &mut Data) -> bool {
    let Data {
        parent_from_body,
        composite,
        column_force,
        subtree_velocity_end,
        mass_matrix,
        ..
    } = data;
    sweep_buffers::<ROOT_SHORTCUT>(
        model,
        parent_from_body,
        composite,
        column_force,
        subtree_velocity_end,
        mass_matrix.as_mut_slice(),
    )
}

/// [`sweep`] on `Data`'s buffers, each its own argument: the compiler then knows that the
/// stores to `mass` and the forces never change `parent_from_body` (a reference argument does
/// not alias another), so the transforms are read where they are, with no copy.
#[inline(always)]
fn sweep_buffers<const ROOT_SHORTCUT: bool>(
    model: &Model,
    parent_from_body: &[Transform],
    composite: &mut [Inertia],
    column_force: &mut [Force],
    subtree_velocity_end: &mut [usize],
    mass: &mut [f64],
) -> bool {
    let n = model.nv;
    for (composite, body) in composite.iter_mut().zip(&model.bodies) {
        *composite = body.inertia;
    }
    for (end, joint) in subtree_velocity_end.iter_mut().zip(&model.joints) {
        *end = joint.v_index + joint.nv();
    }
    // The root shortcut's axis of a joint: `Some(k)` for a root about `e_k` (with the shortcut).
    let shortcut_axis = |joint: &Joint| match ROOT_SHORTCUT && joint.parent.is_none() {
        true => joint.revolute_coordinate_axis(),
        false => None,
    };
    let mut exact = true;
    // Column-major storage: entry (row, column) at `row + column · n`.
    mass.fill(0.0);
    for (i, joint) in model.joints.iter().enumerate().rev() {
        // Depth-first coordinates (crate::model): the subtree's columns are the joint's own and
        // then its descendants', one contiguous range. The descendants' entries of this joint's
        // rows were written when their forces came up (below, as the child's parent).
        let subtree_end = subtree_velocity_end[i];
        if let Some(k) = shortcut_axis(joint) {
            // `Sᵀ I^c S` (the root's force goes nowhere).
            let value = composite[i].rotational[(k, k)];
            exact &= shortcut_exact(value);
            mass[joint.v_index * (n + 1)] = value;
        } else {
            for column in joint.v_index..joint.v_index + joint.nv() {
                let force = apply_to_subspace_column(
                    &composite[i],
                    joint.kind,
                    &joint.subspace_column(column - joint.v_index),
                );
                for_each_projection(joint, &force, |row, value| mass[row + column * n] = value);
                column_force[column] = force;
            }
        }
        if let Some(p) = joint.parent {
            debug_assert!(p < i, "joints come after their parents");
            let parent = &model.joints[p];
            let parent_from_joint = &parent_from_body[i];
            let forces = &mut column_force[joint.v_index..subtree_end];
            let columns = joint.v_index..subtree_end;
            subtree_velocity_end[p] = subtree_velocity_end[p].max(subtree_end);
            if let Some(k) = shortcut_axis(parent) {
                composite[p].rotational[(k, k)] +=
                    parent_from_joint.act_inertia_rotational_diagonal(k, &composite[i]);
                let row = parent.v_index;
                for (column, force) in columns.zip(forces.iter()) {
                    let value = parent_from_joint.act_force_angular_entry(k, force);
                    exact &= shortcut_exact(value);
                    mass[row + column * n] = value;
                    mass[column + row * n] = value;
                }
                continue;
            }
            let in_parent = parent_from_joint.act_inertia(&composite[i]);
            composite[p] += in_parent;
            // One loop per kind of parent joint, so that the loop does not ask again per column.
            match parent.kind {
                JointKind::Revolute | JointKind::Prismatic => {
                    let (row, axis) = (parent.v_index, *parent.axis());
                    let revolute = parent.kind == JointKind::Revolute;
                    for (column, force) in columns.zip(forces) {
                        *force = parent_from_joint.act_force(force);
                        // `Sᵀ f` as `for_each_projection` computes it.
                        let value = if revolute {
                            axis.dot(&force.angular)
                        } else {
                            axis.dot(&force.linear)
                        };
                        mass[row + column * n] = value;
                        mass[column + row * n] = value;
                    }
                }
                JointKind::Floating => {
                    for (column, force) in columns.zip(forces) {
                        *force = parent_from_joint.act_force(force);
                        for_each_projection(parent, force, |row, value| {
                            mass[row + column * n] = value;
                            mass[column + row * n] = value;
                        });
                    }
                }
            }
        }
    }
    exact
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::nonlinear_effects;
    use crate::model::LoadOptions;
    use std::path::Path;

    /// The sweep with the root shortcut gives the general sweep's bits (signs of zero included),
    /// on our ur5 (a root about `z`) at configurations in every quadrant and on the axes, where
    /// the joint frames' exact zeros meet sines and cosines of both signs; and an entry that the
    /// shortcut cannot give exactly (a zero) is refused, so that the general sweep runs.
    #[test]
    fn root_shortcut_has_the_bits_of_the_general_sweep() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
        let model = Model::from_urdf_file(&path, LoadOptions::default()).unwrap();
        assert_eq!(model.joints[0].revolute_coordinate_axis(), Some(2));
        let half_pi = std::f64::consts::FRAC_PI_2;
        let bits = |m: &nalgebra::DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut shortcut_taken = 0;
        for case in 0..64 {
            let q: Vec<f64> = (0..model.nq)
                .map(|i| match case % 4 {
                    0 => 0.0,
                    1 => half_pi * ((case / 4 + i) % 4) as f64,
                    _ => 0.3 + 0.7 * (case * 7 + i * 3) as f64,
                })
                .collect();
            let mut data = Data::new(&model);
            joint_placements(&model, &mut data, &q);
            let mut general = data.clone();
            sweep::<false>(&model, &mut general);
            if sweep::<true>(&model, &mut data) {
                shortcut_taken += 1;
                assert_eq!(
                    bits(&data.mass_matrix),
                    bits(&general.mass_matrix),
                    "q {q:?}"
                );
            }
            let mut full = Data::new(&model);
            assert_eq!(
                bits(crba(&model, &mut full, &q)),
                bits(&general.mass_matrix)
            );
        }
        assert!(shortcut_taken > 32, "shortcut taken {shortcut_taken} of 64");
        assert!(!shortcut_exact(0.0) && !shortcut_exact(-0.0) && !shortcut_exact(f64::NAN));
        assert!(!shortcut_exact(f64::INFINITY) && shortcut_exact(-1e-300));
    }

    /// `crba_at_placements` after the RNEA at `q` has the bits of `crba` at `q`, on a fixed-base arm
    /// and on a floating-base robot (a six-degree-of-freedom joint's block included).
    #[test]
    fn mass_matrix_at_given_placements_has_the_bits_of_the_full_call() {
        for file in ["robots/ur5/ur5.urdf", "robots/quadruped/quadruped.urdf"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
            let model = Model::from_urdf_file(&path, LoadOptions::default()).unwrap();
            let mut q: Vec<f64> = (0..model.nq).map(|i| 0.3 + 0.1 * i as f64).collect();
            if model.joints[0].kind == JointKind::Floating {
                // A unit quaternion for the base (x, y, z, w after the position).
                q[3..7].copy_from_slice(&[0.1, -0.2, 0.3, (1.0f64 - 0.14).sqrt()]);
            }
            let v: Vec<f64> = (0..model.nv).map(|i| 0.5 - 0.2 * i as f64).collect();
            let mut data = Data::new(&model);
            let full = crba(&model, &mut data, &q).clone();
            let mut other = Data::new(&model);
            let gravity = crate::spatial::Vec3::from(crate::environment::DEFAULT_GRAVITY);
            nonlinear_effects(&model, &gravity, &mut other, &q, &v);
            let given = crba_at_placements(&model, &mut other);
            let bits =
                |m: &nalgebra::DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(given), bits(&full), "{file}");
        }
    }
}
