//! A joint's own motion per lane: its transform for coordinates `q`, its motion `S v`, a column of
//! `S` and the projection `Sᵀ f` — [`crate::model::Joint`]'s methods with per-lane axes
//! (docs/batch.md §2).

use super::lanes::{v3_scale, v3_zero, ForceLanes, Lanes, MotionLanes, TransformLanes, V3};
use super::model::{lane_transform, lane_v3, set_transform, set_v3, LaneAxes};
use crate::model::JointKind;
use crate::spatial::Motion;

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

/// A joint's placement `parent_from_child` in every lane ([`crate::model::Joint::parent_from_child`]
/// lane by lane): the aligned formula where the scalar kernel takes it (docs/batch.md §7).
#[inline(always)]
pub fn parent_from_child<const W: usize>(
    kind: JointKind,
    axes: &LaneAxes<W>,
    parent_from_joint: &TransformLanes<W>,
    axis: &V3<W>,
    q: &[Lanes<W>],
) -> TransformLanes<W> {
    match axes {
        LaneAxes::Every(k) => parent_from_joint.compose_rotation_about_coordinate_axis(*k, q[0]),
        LaneAxes::None => parent_from_joint.compose(&joint_transform(kind, axis, q)),
        LaneAxes::Mixed(lanes) => {
            let mut placement = parent_from_joint.compose(&joint_transform(kind, axis, q));
            aligned_placements_again(lanes, parent_from_joint, q[0], &mut placement);
            placement
        }
    }
}

/// A mixed chunk's aligned lanes of [`parent_from_child`] again, through the scalar formula
/// (rare, out of line).
#[cold]
#[inline(never)]
fn aligned_placements_again<const W: usize>(
    lanes: &[Option<usize>; W],
    parent_from_joint: &TransformLanes<W>,
    angle: Lanes<W>,
    placement: &mut TransformLanes<W>,
) {
    for (lane, k) in lanes.iter().enumerate() {
        if let Some(k) = *k {
            let aligned = lane_transform(parent_from_joint, lane)
                .compose_rotation_about_coordinate_axis(k, angle.0[lane]);
            set_transform(placement, lane, &aligned);
        }
    }
}

/// RNEA's forward step through a joint in every lane: the body's velocity and acceleration from
/// its parent's (`parent_acceleration` the base's `−g` at the root), its placement, `v` and `q̈`
/// (`None` for the bias forces). [`crate::dynamics::rnea`]'s step lane by lane, aligned where it
/// is aligned (docs/batch.md §7).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn forward_motion<const W: usize>(
    kind: JointKind,
    axes: &LaneAxes<W>,
    axis: &V3<W>,
    parent_from_body: &TransformLanes<W>,
    parent_velocity: &MotionLanes<W>,
    parent_acceleration: &MotionLanes<W>,
    v: &[Lanes<W>],
    qdd: Option<&[Lanes<W>]>,
) -> (MotionLanes<W>, MotionLanes<W>) {
    if let LaneAxes::Every(k) = *axes {
        let (x, rate, qdd) = (parent_from_body, v[0], qdd.map(|qdd| qdd[0]));
        let (pv, pa) = (parent_velocity, parent_acceleration);
        return match k {
            0 => motion_through_axis::<W, 0>(x, pv, pa, rate, qdd),
            1 => motion_through_axis::<W, 1>(x, pv, pa, rate, qdd),
            _ => motion_through_axis::<W, 2>(x, pv, pa, rate, qdd),
        };
    }
    let joint_velocity = joint_motion(kind, axis, v);
    let mut velocity = parent_from_body
        .inv_act_motion(parent_velocity)
        .add(&joint_velocity);
    let mut acceleration = parent_from_body
        .inv_act_motion(parent_acceleration)
        .add(&velocity.cross_motion(&joint_velocity));
    if let Some(qdd) = qdd {
        acceleration = acceleration.add(&joint_motion(kind, axis, qdd));
    }
    if let LaneAxes::Mixed(lanes) = axes {
        aligned_lanes_again(
            lanes,
            parent_from_body,
            parent_velocity,
            parent_acceleration,
            v,
            qdd,
            &mut velocity,
            &mut acceleration,
        );
    }
    (velocity, acceleration)
}

/// A mixed chunk's aligned lanes of [`forward_motion`] again, through the scalar kernel's aligned
/// step (rare: kept out of line so that the common paths keep their values in registers).
#[cold]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn aligned_lanes_again<const W: usize>(
    lanes: &[Option<usize>; W],
    parent_from_body: &TransformLanes<W>,
    parent_velocity: &MotionLanes<W>,
    parent_acceleration: &MotionLanes<W>,
    v: &[Lanes<W>],
    qdd: Option<&[Lanes<W>]>,
    velocity: &mut MotionLanes<W>,
    acceleration: &mut MotionLanes<W>,
) {
    for (lane, k) in lanes.iter().enumerate() {
        if let Some(k) = *k {
            let (lane_velocity, lane_acceleration) =
                crate::dynamics::rnea::motion_through_coordinate_axis(
                    &lane_transform(parent_from_body, lane),
                    &lane_motion(parent_velocity, lane),
                    &lane_motion(parent_acceleration, lane),
                    k,
                    v[0].0[lane],
                    qdd.map(|qdd| qdd[0].0[lane]),
                );
            set_motion(velocity, lane, &lane_velocity);
            set_motion(acceleration, lane, &lane_acceleration);
        }
    }
}

/// [`crate::dynamics::rnea`]'s aligned forward step about `e_K` lane by lane (every lane about
/// `e_K`; `K` a constant so that the entries are registers, not indexed memory).
#[inline(always)]
fn motion_through_axis<const W: usize, const K: usize>(
    parent_from_body: &TransformLanes<W>,
    parent_velocity: &MotionLanes<W>,
    parent_acceleration: &MotionLanes<W>,
    rate: Lanes<W>,
    qdd: Option<Lanes<W>>,
) -> (MotionLanes<W>, MotionLanes<W>) {
    let mut velocity = parent_from_body.inv_act_motion(parent_velocity);
    velocity.angular[K] += rate;
    let mut acceleration = parent_from_body
        .inv_act_motion(parent_acceleration)
        .add(&velocity.cross_coordinate_axis(K, rate));
    if let Some(qdd) = qdd {
        acceleration.angular[K] += qdd;
    }
    (velocity, acceleration)
}

/// `Sᵀ f` into `out` in every lane ([`project_force`]), the aligned joints' by picking the axis
/// entry as the scalar RNEA does (docs/batch.md §7).
#[inline(always)]
pub fn project_force_aligned<const W: usize>(
    kind: JointKind,
    axes: &LaneAxes<W>,
    axis: &V3<W>,
    force: &ForceLanes<W>,
    out: &mut [Lanes<W>],
) {
    match axes {
        LaneAxes::Every(k) => out[0] = force.angular[*k],
        LaneAxes::None => project_force(kind, axis, force, out),
        LaneAxes::Mixed(lanes) => {
            project_force(kind, axis, force, out);
            for (lane, k) in lanes.iter().enumerate() {
                if let Some(k) = *k {
                    out[0].0[lane] = force.angular[k].0[lane];
                }
            }
        }
    }
}

/// Lane `lane` of a motion.
fn lane_motion<const W: usize>(motion: &MotionLanes<W>, lane: usize) -> Motion {
    Motion::new(
        lane_v3(&motion.linear, lane),
        lane_v3(&motion.angular, lane),
    )
}

/// Writes `value` into lane `lane` of `target`.
fn set_motion<const W: usize>(target: &mut MotionLanes<W>, lane: usize, value: &Motion) {
    set_v3(&mut target.linear, lane, &value.linear);
    set_v3(&mut target.angular, lane, &value.angular);
}
