//! Lane arithmetic: `W` samples' values of one scalar side by side, and the spatial-algebra
//! operations of [`crate::spatial`] applied lane by lane (docs/batch.md §2).
//!
//! Every function here performs, in each lane, exactly the IEEE operations of its scalar
//! counterpart in the same order (nalgebra's `Matrix3 · Vector3` sums `((a₀x₀ + a₁x₁) + a₂x₂)`,
//! its `dot` of 3-vectors `(a₀b₀ + a₁b₁) + a₂b₂`, its `cross` `a_y b_z − a_z b_y, …`), and no
//! product known to be zero is skipped unless the scalar code skips it too: a skipped `x · 0`
//! changes the sign of a zero sum, and lanes are compared bit for bit with the scalar kernels.
//! Rust never contracts `a · b + c` into a fused multiply–add, so plain lane loops keep each lane's
//! result identical whatever vector width the compiler picks.

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

/// One `f64` per lane: `W` samples' values of the same scalar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lanes<const W: usize>(pub [f64; W]);

impl<const W: usize> Lanes<W> {
    /// The same value in every lane.
    #[inline(always)]
    pub fn splat(value: f64) -> Self {
        Self([value; W])
    }

    /// Zero in every lane.
    #[inline(always)]
    pub fn zero() -> Self {
        Self([0.0; W])
    }
}

macro_rules! lane_binary {
    ($trait:ident, $method:ident, $op:tt) => {
        // `a ∘= b` is `a = a ∘ b` for IEEE floats: the same rounding, lane by lane.
        impl<const W: usize> $trait for Lanes<W> {
            type Output = Lanes<W>;
            #[inline(always)]
            fn $method(self, rhs: Lanes<W>) -> Lanes<W> {
                let mut out = self.0;
                for (o, r) in out.iter_mut().zip(rhs.0) {
                    *o $op r;
                }
                Lanes(out)
            }
        }
    };
}
lane_binary!(Add, add, +=);
lane_binary!(Sub, sub, -=);
lane_binary!(Mul, mul, *=);

impl<const W: usize> Neg for Lanes<W> {
    type Output = Lanes<W>;
    #[inline(always)]
    fn neg(self) -> Lanes<W> {
        let mut out = self.0;
        for o in out.iter_mut() {
            *o = -*o;
        }
        Lanes(out)
    }
}

impl<const W: usize> AddAssign for Lanes<W> {
    #[inline(always)]
    fn add_assign(&mut self, rhs: Lanes<W>) {
        *self = *self + rhs;
    }
}

/// A 3-vector per lane (`[x, y, z]`).
pub type V3<const W: usize> = [Lanes<W>; 3];

/// A 3×3 matrix per lane, row-major: `m[row][column]`.
pub type M3<const W: usize> = [[Lanes<W>; 3]; 3];

/// The zero 3-vector.
#[inline(always)]
pub fn v3_zero<const W: usize>() -> V3<W> {
    [Lanes::zero(); 3]
}

/// `a + b`, component-wise.
#[inline(always)]
pub fn v3_add<const W: usize>(a: &V3<W>, b: &V3<W>) -> V3<W> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`, component-wise.
#[inline(always)]
pub fn v3_sub<const W: usize>(a: &V3<W>, b: &V3<W>) -> V3<W> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `−a`.
#[inline(always)]
pub fn v3_neg<const W: usize>(a: &V3<W>) -> V3<W> {
    [-a[0], -a[1], -a[2]]
}

/// `a · s` (nalgebra's `Vector3 * f64`: each component times `s`).
#[inline(always)]
pub fn v3_scale<const W: usize>(a: &V3<W>, s: Lanes<W>) -> V3<W> {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `a × b` in nalgebra's order: `(a_y b_z − a_z b_y, a_z b_x − a_x b_z, a_x b_y − a_y b_x)`.
#[inline(always)]
pub fn cross<const W: usize>(a: &V3<W>, b: &V3<W>) -> V3<W> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a · b` in nalgebra's order for 3-vectors: `(a₀b₀ + a₁b₁) + a₂b₂`.
#[inline(always)]
pub fn dot<const W: usize>(a: &V3<W>, b: &V3<W>) -> Lanes<W> {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `|a|²` as nalgebra computes it: `0 + a · a`.
#[inline(always)]
pub fn norm_squared<const W: usize>(a: &V3<W>) -> Lanes<W> {
    Lanes::zero() + dot(a, a)
}

/// `m · x` as nalgebra's `gemv` sums it: `y_i = (m_i0 x₀ + m_i1 x₁) + m_i2 x₂`.
#[inline(always)]
pub fn mat_vec<const W: usize>(m: &M3<W>, x: &V3<W>) -> V3<W> {
    [
        m[0][0] * x[0] + m[0][1] * x[1] + m[0][2] * x[2],
        m[1][0] * x[0] + m[1][1] * x[1] + m[1][2] * x[2],
        m[2][0] * x[0] + m[2][1] * x[1] + m[2][2] * x[2],
    ]
}

/// `mᵀ · x`, same summation order as [`mat_vec`] on the transposed matrix.
#[inline(always)]
pub fn mat_t_vec<const W: usize>(m: &M3<W>, x: &V3<W>) -> V3<W> {
    [
        m[0][0] * x[0] + m[1][0] * x[1] + m[2][0] * x[2],
        m[0][1] * x[0] + m[1][1] * x[1] + m[2][1] * x[2],
        m[0][2] * x[0] + m[1][2] * x[1] + m[2][2] * x[2],
    ]
}

/// `a · b`: each column of the product is [`mat_vec`] of `a` with that column of `b`.
#[inline(always)]
pub fn mat_mat<const W: usize>(a: &M3<W>, b: &M3<W>) -> M3<W> {
    let mut out = [[Lanes::zero(); 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, entry) in row.iter_mut().enumerate() {
            *entry = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    out
}

/// `a · bᵀ`, summed like [`mat_mat`] on the transposed `b`.
#[inline(always)]
pub fn mat_mat_t<const W: usize>(a: &M3<W>, b: &M3<W>) -> M3<W> {
    let mut out = [[Lanes::zero(); 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, entry) in row.iter_mut().enumerate() {
            *entry = a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2];
        }
    }
    out
}

/// A rigid transform per lane (`parent_from_child`, as [`crate::spatial::Transform`]).
#[derive(Clone, Copy, Debug)]
pub struct TransformLanes<const W: usize> {
    /// Rotation taking child to parent coordinates.
    pub rotation: M3<W>,
    /// Child origin in the parent frame (m).
    pub translation: V3<W>,
}

/// A spatial motion vector per lane ([`crate::spatial::Motion`]).
#[derive(Clone, Copy, Debug)]
pub struct MotionLanes<const W: usize> {
    /// Linear part.
    pub linear: V3<W>,
    /// Angular part.
    pub angular: V3<W>,
}

/// A spatial force vector per lane ([`crate::spatial::Force`]).
#[derive(Clone, Copy, Debug)]
pub struct ForceLanes<const W: usize> {
    /// Force (N).
    pub linear: V3<W>,
    /// Moment about the frame origin (N·m).
    pub angular: V3<W>,
}

/// A spatial inertia per lane ([`crate::spatial::Inertia`]).
#[derive(Clone, Copy, Debug)]
pub struct InertiaLanes<const W: usize> {
    /// Mass (kg).
    pub mass: Lanes<W>,
    /// First moment `m · com` (kg·m).
    pub first_moment: V3<W>,
    /// Rotational inertia about the frame origin (kg·m²).
    pub rotational: M3<W>,
}

impl<const W: usize> TransformLanes<W> {
    /// The identity in every lane.
    pub fn identity() -> Self {
        let (one, zero) = (Lanes::splat(1.0), Lanes::zero());
        Self {
            rotation: [[one, zero, zero], [zero, one, zero], [zero, zero, one]],
            translation: v3_zero(),
        }
    }

    /// [`crate::spatial::Transform::compose`] lane by lane.
    #[inline(always)]
    pub fn compose(&self, child_from_x: &Self) -> Self {
        Self {
            rotation: mat_mat(&self.rotation, &child_from_x.rotation),
            translation: v3_add(
                &mat_vec(&self.rotation, &child_from_x.translation),
                &self.translation,
            ),
        }
    }

    /// [`crate::spatial::Transform::compose_rotation_about_coordinate_axis`] lane by lane (every
    /// lane about `e_k`, its angle in `angle`).
    #[inline(always)]
    pub fn compose_rotation_about_coordinate_axis(
        &self,
        axis_index: usize,
        angle: Lanes<W>,
    ) -> Self {
        match axis_index {
            0 => self.compose_rotation_about::<0, 1, 2>(angle),
            1 => self.compose_rotation_about::<1, 2, 0>(angle),
            _ => self.compose_rotation_about::<2, 0, 1>(angle),
        }
    }

    /// The scalar `compose_rotation_about::<K, I, J>`'s operations lane by lane.
    #[inline(always)]
    fn compose_rotation_about<const K: usize, const I: usize, const J: usize>(
        &self,
        angle: Lanes<W>,
    ) -> Self {
        let (s, c) = crate::spatial::trig::sin_cos_lanes(angle.0);
        let (s, c) = (Lanes(s), Lanes(c));
        let along_axis = (Lanes::splat(1.0) - c) + c;
        let r = &self.rotation;
        let mut rotation = [[Lanes::zero(); 3]; 3];
        for row in 0..3 {
            let (a, b) = (r[row][I], r[row][J]);
            rotation[row][I] = a * c + b * s;
            rotation[row][J] = a * -s + b * c;
            rotation[row][K] = r[row][K] * along_axis;
        }
        Self {
            rotation,
            translation: self.translation,
        }
    }

    /// [`crate::spatial::Transform::inv_act_motion`] lane by lane.
    #[inline(always)]
    pub fn inv_act_motion(&self, m: &MotionLanes<W>) -> MotionLanes<W> {
        MotionLanes {
            linear: mat_t_vec(
                &self.rotation,
                &v3_sub(&m.linear, &cross(&self.translation, &m.angular)),
            ),
            angular: mat_t_vec(&self.rotation, &m.angular),
        }
    }

    /// [`crate::spatial::Transform::act_force`] lane by lane.
    #[inline(always)]
    pub fn act_force(&self, f: &ForceLanes<W>) -> ForceLanes<W> {
        let linear = mat_vec(&self.rotation, &f.linear);
        ForceLanes {
            linear,
            angular: v3_add(
                &mat_vec(&self.rotation, &f.angular),
                &cross(&self.translation, &linear),
            ),
        }
    }

    /// [`crate::spatial::Transform::act_inertia`] lane by lane: `h_r = R h`,
    /// `I' = (R I Rᵀ + (2 h_r·p + m|p|²) 1) − (h_r pᵀ + p h_rᵀ + (p pᵀ) m)`, `h' = h_r + p m`.
    #[inline(always)]
    pub fn act_inertia(&self, inertia: &InertiaLanes<W>) -> InertiaLanes<W> {
        let r = &self.rotation;
        let p = &self.translation;
        let m = inertia.mass;
        let h_r = mat_vec(r, &inertia.first_moment);
        let diag = Lanes::splat(2.0) * dot(&h_r, p) + m * norm_squared(p);
        let rotated = mat_mat_t(&mat_mat(r, &inertia.rotational), r);
        let mut rotational = [[Lanes::zero(); 3]; 3];
        for (i, row) in rotational.iter_mut().enumerate() {
            for (j, entry) in row.iter_mut().enumerate() {
                let outer = h_r[i] * p[j] + p[i] * h_r[j] + p[i] * p[j] * m;
                let diagonal = if i == j { diag } else { Lanes::zero() };
                *entry = rotated[i][j] + diagonal - outer;
            }
        }
        InertiaLanes {
            mass: m,
            first_moment: v3_add(&h_r, &v3_scale(p, m)),
            rotational,
        }
    }
}

impl<const W: usize> MotionLanes<W> {
    /// The zero motion.
    #[inline(always)]
    pub fn zero() -> Self {
        Self {
            linear: v3_zero(),
            angular: v3_zero(),
        }
    }

    /// `self + other`.
    #[inline(always)]
    pub fn add(&self, other: &Self) -> Self {
        Self {
            linear: v3_add(&self.linear, &other.linear),
            angular: v3_add(&self.angular, &other.angular),
        }
    }

    /// [`crate::spatial::Motion::cross_motion`] lane by lane.
    #[inline(always)]
    pub fn cross_motion(&self, other: &Self) -> Self {
        Self {
            linear: v3_add(
                &cross(&self.angular, &other.linear),
                &cross(&self.linear, &other.angular),
            ),
            angular: cross(&self.angular, &other.angular),
        }
    }

    /// [`crate::spatial::Motion::cross_coordinate_axis`] lane by lane (every lane about `e_k`).
    #[inline(always)]
    pub fn cross_coordinate_axis(&self, axis_index: usize, rate: Lanes<W>) -> Self {
        let zero = Lanes::zero();
        let cross = |a: &V3<W>| -> V3<W> {
            match axis_index {
                0 => [zero, a[2] * rate, -(a[1] * rate)],
                1 => [-(a[2] * rate), zero, a[0] * rate],
                _ => [a[1] * rate, -(a[0] * rate), zero],
            }
        };
        Self {
            linear: cross(&self.linear),
            angular: cross(&self.angular),
        }
    }

    /// [`crate::spatial::Motion::cross_force`] lane by lane.
    #[inline(always)]
    pub fn cross_force(&self, force: &ForceLanes<W>) -> ForceLanes<W> {
        ForceLanes {
            linear: cross(&self.angular, &force.linear),
            angular: v3_add(
                &cross(&self.angular, &force.angular),
                &cross(&self.linear, &force.linear),
            ),
        }
    }
}

impl<const W: usize> ForceLanes<W> {
    /// The zero force.
    #[inline(always)]
    pub fn zero() -> Self {
        Self {
            linear: v3_zero(),
            angular: v3_zero(),
        }
    }

    /// `self + other`.
    #[inline(always)]
    pub fn add(&self, other: &Self) -> Self {
        Self {
            linear: v3_add(&self.linear, &other.linear),
            angular: v3_add(&self.angular, &other.angular),
        }
    }
}

impl<const W: usize> InertiaLanes<W> {
    /// No mass in any lane.
    pub fn zero() -> Self {
        Self {
            mass: Lanes::zero(),
            first_moment: v3_zero(),
            rotational: [[Lanes::zero(); 3]; 3],
        }
    }

    /// [`crate::spatial::Inertia::apply`] lane by lane: `(m v − h × ω, I_o ω + h × v)`.
    #[inline(always)]
    pub fn apply(&self, motion: &MotionLanes<W>) -> ForceLanes<W> {
        ForceLanes {
            linear: v3_sub(
                &v3_scale(&motion.linear, self.mass),
                &cross(&self.first_moment, &motion.angular),
            ),
            angular: v3_add(
                &mat_vec(&self.rotational, &motion.angular),
                &cross(&self.first_moment, &motion.linear),
            ),
        }
    }

    /// `self += other` ([`crate::spatial::Inertia`]'s `AddAssign`).
    #[inline(always)]
    pub fn add_assign(&mut self, other: &Self) {
        self.mass += other.mass;
        self.first_moment = v3_add(&self.first_moment, &other.first_moment);
        for i in 0..3 {
            for j in 0..3 {
                self.rotational[i][j] += other.rotational[i][j];
            }
        }
    }
}
