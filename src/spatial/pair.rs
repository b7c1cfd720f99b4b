//! Two 3-vectors carried side by side, `[[a_x, b_x], [a_y, b_y], [a_z, b_z]]`, so that the same
//! operation on both is one two-lane instruction of the x86-64 baseline: the RNEA's forward pass
//! moves a body's velocity and acceleration through the same transform
//! ([`super::Transform::inv_act_motion_pair`]). Every function performs, lane by lane, the
//! operations of the nalgebra expression it names, in the same order, so each lane has that
//! expression's bits.

use super::{Mat3, Vec3};

/// One value of each of the two vectors.
pub(crate) type Pair = [f64; 2];
/// Two 3-vectors, entry by entry.
pub(crate) type PairV3 = [Pair; 3];

#[inline(always)]
fn add(a: Pair, b: Pair) -> Pair {
    [a[0] + b[0], a[1] + b[1]]
}

#[inline(always)]
fn sub(a: Pair, b: Pair) -> Pair {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline(always)]
fn scale(a: Pair, s: f64) -> Pair {
    [a[0] * s, a[1] * s]
}

/// `(a, b)` side by side.
#[inline(always)]
pub(crate) fn pair(a: &Vec3, b: &Vec3) -> PairV3 {
    [[a.x, b.x], [a.y, b.y], [a.z, b.z]]
}

/// The two vectors apart again.
#[inline(always)]
pub(crate) fn unpair(p: &PairV3) -> (Vec3, Vec3) {
    (
        Vec3::new(p[0][0], p[1][0], p[2][0]),
        Vec3::new(p[0][1], p[1][1], p[2][1]),
    )
}

/// `a − b` of each lane (nalgebra's `Vector3 − Vector3`).
#[inline(always)]
pub(crate) fn v3_sub(a: &PairV3, b: &PairV3) -> PairV3 {
    [sub(a[0], b[0]), sub(a[1], b[1]), sub(a[2], b[2])]
}

/// `c × x` of each lane, in nalgebra's order: `(c_y x_z − c_z x_y, c_z x_x − c_x x_z,
/// c_x x_y − c_y x_x)`.
#[inline(always)]
pub(crate) fn cross(c: &Vec3, x: &PairV3) -> PairV3 {
    [
        sub(scale(x[2], c.y), scale(x[1], c.z)),
        sub(scale(x[0], c.z), scale(x[2], c.x)),
        sub(scale(x[1], c.x), scale(x[0], c.y)),
    ]
}

/// `mᵀ x` of each lane, in the order of nalgebra's `m.transpose() * x`:
/// `(m_0i x_0 + m_1i x_1) + m_2i x_2`.
#[inline(always)]
pub(crate) fn mat_t_vec(m: &Mat3, x: &PairV3) -> PairV3 {
    let row = |i: usize| {
        add(
            add(scale(x[0], m[(0, i)]), scale(x[1], m[(1, i)])),
            scale(x[2], m[(2, i)]),
        )
    };
    [row(0), row(1), row(2)]
}
