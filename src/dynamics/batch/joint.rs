//! A joint's own motion per lane: its transform for coordinates `q`, its motion `S v`, a column of
//! `S` and the projection `Sᵀ f` — [`crate::model::Joint`]'s methods with per-lane axes
//! (docs/batch.md §2).

use super::lanes::{v3_scale, v3_zero, ForceLanes, Lanes, MotionLanes, TransformLanes, V3};
use crate::model::JointKind;

/// `joint_from_child` for the coordinates `q` (`q: dim nq` of the joint): Rodrigues' rotation
/// about `axis` for a revolute joint (sine and cosine by [`crate::spatial::trig::sin_cos_lanes`],
/// the rest lane-wise in [`crate::spatial::rotation_about_axis`]'s order), a translation along `axis` for a
/// prismatic one, position and unit quaternion `(x y z w)` for a floating one (nalgebra's
/// quaternion-to-matrix formula).
#[inline(always)]
pub fn joint_transform<const W: usize>(
    kind: JointKind,
    axis: &V3<W>,
    q: &[Lanes<W>],
) -> TransformLanes<W> {
    let one = Lanes::splat(1.0);
    let zero = Lanes::zero();
    match kind {
        JointKind::Revolute => {
            let (s, c) = crate::spatial::trig::sin_cos_lanes(q[0].0);
            let (s, c) = (Lanes(s), Lanes(c));
            let t = one - c;
            let [x, y, z] = *axis;
            TransformLanes {
                rotation: [
                    [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                    [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                    [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
                ],
                translation: v3_zero(),
            }
        }
        JointKind::Prismatic => TransformLanes {
            rotation: [[one, zero, zero], [zero, one, zero], [zero, zero, one]],
            translation: v3_scale(axis, q[0]),
        },
        JointKind::Floating => {
            let (i, j, k, w) = (q[3], q[4], q[5], q[6]);
            let two = Lanes::splat(2.0);
            let (ww, ii, jj, kk) = (w * w, i * i, j * j, k * k);
            let ij = i * j * two;
            let wk = w * k * two;
            let wj = w * j * two;
            let ik = i * k * two;
            let jk = j * k * two;
            let wi = w * i * two;
            TransformLanes {
                rotation: [
                    [ww + ii - jj - kk, ij - wk, wj + ik],
                    [wk + ij, ww - ii + jj - kk, jk - wi],
                    [ik - wj, wi + jk, ww - ii - jj + kk],
                ],
                translation: [q[0], q[1], q[2]],
            }
        }
    }
}

/// Joint motion `S v` in the child frame (`v: dim nv` of the joint).
#[inline(always)]
pub fn joint_motion<const W: usize>(
    kind: JointKind,
    axis: &V3<W>,
    v: &[Lanes<W>],
) -> MotionLanes<W> {
    match kind {
        JointKind::Revolute => MotionLanes {
            linear: v3_zero(),
            angular: v3_scale(axis, v[0]),
        },
        JointKind::Prismatic => MotionLanes {
            linear: v3_scale(axis, v[0]),
            angular: v3_zero(),
        },
        JointKind::Floating => MotionLanes {
            linear: [v[0], v[1], v[2]],
            angular: [v[3], v[4], v[5]],
        },
    }
}

/// Column `k` of the motion subspace `S`.
#[inline(always)]
pub fn subspace_column<const W: usize>(kind: JointKind, axis: &V3<W>, k: usize) -> MotionLanes<W> {
    match kind {
        JointKind::Revolute => MotionLanes {
            linear: v3_zero(),
            angular: *axis,
        },
        JointKind::Prismatic => MotionLanes {
            linear: *axis,
            angular: v3_zero(),
        },
        JointKind::Floating => {
            let mut m = MotionLanes::zero();
            if k < 3 {
                m.linear[k] = Lanes::splat(1.0);
            } else {
                m.angular[k - 3] = Lanes::splat(1.0);
            }
            m
        }
    }
}

/// Generalised force `Sᵀ f` written into `out` (`out: dim nv` of the joint).
#[inline(always)]
pub fn project_force<const W: usize>(
    kind: JointKind,
    axis: &V3<W>,
    force: &ForceLanes<W>,
    out: &mut [Lanes<W>],
) {
    match kind {
        JointKind::Revolute => out[0] = super::lanes::dot(axis, &force.angular),
        JointKind::Prismatic => out[0] = super::lanes::dot(axis, &force.linear),
        JointKind::Floating => {
            out[..3].copy_from_slice(&force.linear);
            out[3..6].copy_from_slice(&force.angular);
        }
    }
}
