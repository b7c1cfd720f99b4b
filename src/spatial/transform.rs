//! Rigid transforms and the rotations URDF needs (roll-pitch-yaw, axis-angle).

use super::{Force, Inertia, Mat3, Motion, Vec3};

/// A rigid transform `parent_from_child`: `point_in_parent = rotation * point_in_child + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation taking child coordinates to parent coordinates.
    pub rotation: Mat3,
    /// Position of the child origin in the parent frame (m).
    pub translation: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::identity()
    }
}

/// URDF's roll-pitch-yaw rotation: `Rz(yaw) · Ry(pitch) · Rx(roll)` (fixed axes x, y, z).
pub fn rotation_from_rpy(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Mat3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// Rotation by `angle` (rad) about the unit vector `axis` (Rodrigues' formula; sine and cosine by
/// [`super::trig::sin_cos`], as the batched joint transform).
#[inline]
pub fn rotation_about_axis(axis: &Vec3, angle: f64) -> Mat3 {
    let (sin, cos) = super::trig::sin_cos(angle);
    rotation_about_axis_given_sin_cos(axis, sin, cos)
}

/// [`rotation_about_axis`] from the angle's sine and cosine (as [`super::trig::sin_cos`] gives them).
#[inline]
pub fn rotation_about_axis_given_sin_cos(axis: &Vec3, s: f64, c: f64) -> Mat3 {
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    Mat3::new(
        t * x * x + c,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        t * y * y + c,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        t * z * z + c,
    )
}

impl Transform {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Mat3::identity(),
            translation: Vec3::zeros(),
        }
    }

    /// Builds a transform from a rotation and a translation.
    pub fn new(rotation: Mat3, translation: Vec3) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// A URDF `<origin xyz rpy>`.
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        Self {
            rotation: rotation_from_rpy(rpy[0], rpy[1], rpy[2]),
            translation: Vec3::new(xyz[0], xyz[1], xyz[2]),
        }
    }

    /// `self ∘ (rotation by angle about e_k)`: [`Transform::compose`] with
    /// `Transform::new(rotation_about_axis(&e_k, angle), 0)` for the coordinate axis `e_k`
    /// (`axis_index` k ∈ {0, 1, 2}), the products by that rotation's zero entries left out (a
    /// revolute joint about a coordinate axis of its frame, docs/batch.md §7). Every entry is the
    /// same sum of the same nonzero products, so the result has the same bits as the composition
    /// (signs of zero aside); the axis entry of the rotation is written `(1 − c) + c`, as Rodrigues'
    /// formula computes it.
    #[inline]
    pub fn compose_rotation_about_coordinate_axis(
        &self,
        axis_index: usize,
        angle: f64,
    ) -> Transform {
        let (sin, cos) = super::trig::sin_cos(angle);
        self.compose_rotation_about_coordinate_axis_given_sin_cos(axis_index, sin, cos)
    }

    /// [`Self::compose_rotation_about_coordinate_axis`] from the angle's sine and cosine (as
    /// [`super::trig::sin_cos`] gives them).
    #[inline]
    pub fn compose_rotation_about_coordinate_axis_given_sin_cos(
        &self,
        axis_index: usize,
        sin: f64,
        cos: f64,
    ) -> Transform {
        match axis_index {
            0 => self.compose_rotation_about::<0, 1, 2>(sin, cos),
            1 => self.compose_rotation_about::<1, 2, 0>(sin, cos),
            _ => self.compose_rotation_about::<2, 0, 1>(sin, cos),
        }
    }

    /// [`Self::compose_rotation_about_coordinate_axis`] about `e_K`, where the rotation takes `e_I`
    /// to `c e_I + s e_J` and `e_J` to `−s e_I + c e_J` (`(K, I, J)` a cyclic order of 0, 1, 2).
    #[inline(always)]
    fn compose_rotation_about<const K: usize, const I: usize, const J: usize>(
        &self,
        s: f64,
        c: f64,
    ) -> Transform {
        let along_axis = (1.0 - c) + c;
        let r = &self.rotation;
        let mut columns = [[0.0; 3]; 3];
        for row in 0..3 {
            let (a, b) = (r[(row, I)], r[(row, J)]);
            columns[I][row] = a * c + b * s;
            columns[J][row] = a * -s + b * c;
            columns[K][row] = r[(row, K)] * along_axis;
        }
        Transform {
            rotation: Mat3::from_column_slice(columns.as_flattened()),
            translation: self.translation,
        }
    }

    /// `self * child_from_x`: composes `parent_from_child` with `child_from_x` into `parent_from_x`.
    #[inline]
    pub fn compose(&self, child_from_x: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * child_from_x.rotation,
            translation: self.rotation * child_from_x.translation + self.translation,
        }
    }

    /// The inverse transform (`child_from_parent`).
    #[inline]
    pub fn inverse(&self) -> Transform {
        let rt = self.rotation.transpose();
        Transform {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Maps a point from child to parent coordinates.
    #[inline]
    pub fn transform_point(&self, point_in_child: &Vec3) -> Vec3 {
        self.rotation * point_in_child + self.translation
    }

    /// Expresses a child-frame motion in the parent frame.
    #[inline]
    pub fn act_motion(&self, m: &Motion) -> Motion {
        let angular = self.rotation * m.angular;
        Motion {
            linear: self.rotation * m.linear + self.translation.cross(&angular),
            angular,
        }
    }

    /// Expresses a parent-frame motion in the child frame.
    #[inline]
    pub fn inv_act_motion(&self, m: &Motion) -> Motion {
        let rt = self.rotation.transpose();
        Motion {
            linear: rt * (m.linear - self.translation.cross(&m.angular)),
            angular: rt * m.angular,
        }
    }

    /// [`Transform::inv_act_motion`] of two motions at once, each operation on both in one
    /// two-lane instruction (the same operations, so the same bits, as two calls).
    #[inline(always)]
    pub fn inv_act_motion_pair(&self, a: &Motion, b: &Motion) -> (Motion, Motion) {
        use super::pair::{cross, mat_t_vec, pair, unpair, v3_sub};
        let angular = pair(&a.angular, &b.angular);
        let linear = pair(&a.linear, &b.linear);
        let shifted = v3_sub(&linear, &cross(&self.translation, &angular));
        let (linear_a, linear_b) = unpair(&mat_t_vec(&self.rotation, &shifted));
        let (angular_a, angular_b) = unpair(&mat_t_vec(&self.rotation, &angular));
        (
            Motion::new(linear_a, angular_a),
            Motion::new(linear_b, angular_b),
        )
    }

    /// Expresses a child-frame force in the parent frame.
    #[inline]
    pub fn act_force(&self, f: &Force) -> Force {
        let linear = self.rotation * f.linear;
        Force {
            linear,
            angular: self.rotation * f.angular + self.translation.cross(&linear),
        }
    }

    /// Expresses a parent-frame force in the child frame.
    #[inline]
    pub fn inv_act_force(&self, f: &Force) -> Force {
        let rt = self.rotation.transpose();
        Force {
            linear: rt * f.linear,
            angular: rt * (f.angular - self.translation.cross(&f.linear)),
        }
    }

    /// Entry `k` of `self.act_force(f).angular` alone, with the bits of that entry of the full
    /// call (the same products summed in the same order: `(R f_a)_k + (p × R f_l)_k`, of which
    /// only the two entries of `R f_l` other than `k` are needed). What a revolute root joint
    /// about `e_k` reads of a force arriving from its child (the CRBA's last carry).
    #[inline(always)]
    pub fn act_force_angular_entry(&self, k: usize, f: &Force) -> f64 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let r = &self.rotation;
        let p = &self.translation;
        let r_row = |i: usize| [r[(i, 0)], r[(i, 1)], r[(i, 2)]];
        let linear = [f.linear.x, f.linear.y, f.linear.z];
        let angular = [f.angular.x, f.angular.y, f.angular.z];
        let (linear_a, linear_b) = (row_dot(r_row(a), linear), row_dot(r_row(b), linear));
        // nalgebra's cross product: entry k is `p_a q_b − p_b q_a`.
        row_dot(r_row(k), angular) + (p[a] * linear_b - p[b] * linear_a)
    }

    /// Expresses a child-frame inertia in the parent frame (about the parent origin).
    ///
    /// With `h_r = R h` and `p` the translation: `h' = h_r + m p` and
    /// `I' = R I Rᵀ + (2 h_r·p + m|p|²) 1 − (h_r pᵀ + p h_rᵀ + m p pᵀ)`.
    ///
    /// Written out entry by entry in the order nalgebra's products sum them (`(a₀b₀ + a₁b₁) +
    /// a₂b₂` for a row times a column, `|p|² = 0 + p·p`), which is the order the batched
    /// kernels' lanes follow (src/dynamics/batch/lanes.rs, compared bit for bit). Always inlined:
    /// in the CRBA's sweep it is the chain every composite inertia waits on.
    #[inline(always)]
    pub fn act_inertia(&self, inertia: &Inertia) -> Inertia {
        let r = &self.rotation;
        let p = &self.translation;
        let m = inertia.mass;
        let h = &inertia.first_moment;
        let inertia_in_child = &inertia.rotational;
        let r_row = |i: usize| [r[(i, 0)], r[(i, 1)], r[(i, 2)]];
        let h_r = [
            row_dot(r_row(0), [h.x, h.y, h.z]),
            row_dot(r_row(1), [h.x, h.y, h.z]),
            row_dot(r_row(2), [h.x, h.y, h.z]),
        ];
        let p = [p.x, p.y, p.z];
        let diag = 2.0 * row_dot(h_r, p) + m * (0.0 + row_dot(p, p));
        // `R I`, then `(R I) Rᵀ`.
        let mut r_i = [[0.0; 3]; 3];
        for (i, row) in r_i.iter_mut().enumerate() {
            for (j, entry) in row.iter_mut().enumerate() {
                let column = [
                    inertia_in_child[(0, j)],
                    inertia_in_child[(1, j)],
                    inertia_in_child[(2, j)],
                ];
                *entry = row_dot(r_row(i), column);
            }
        }
        let mut rotational = Mat3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                let rotated = row_dot(r_i[i], r_row(j));
                let outer = (h_r[i] * p[j] + p[i] * h_r[j]) + (p[i] * p[j]) * m;
                let diagonal = if i == j { diag } else { 0.0 };
                rotational[(i, j)] = (rotated + diagonal) - outer;
            }
        }
        Inertia {
            mass: m,
            first_moment: Vec3::new(h_r[0] + p[0] * m, h_r[1] + p[1] * m, h_r[2] + p[2] * m),
            rotational,
        }
    }

    /// Diagonal entry `(k, k)` of `self.act_inertia(inertia).rotational` alone, with its bits
    /// (the same products summed in the same order as [`Transform::act_inertia`]'s entry: `h_r`,
    /// the diagonal shift, row `k` of `R I`): what a revolute root joint about `e_k` reads of a
    /// composite inertia arriving from its child (`S_kᵀ I S_k`, the CRBA's last carry).
    #[inline(always)]
    pub fn act_inertia_rotational_diagonal(&self, k: usize, inertia: &Inertia) -> f64 {
        let r = &self.rotation;
        let m = inertia.mass;
        let h = &inertia.first_moment;
        let c = &inertia.rotational;
        let r_row = |i: usize| [r[(i, 0)], r[(i, 1)], r[(i, 2)]];
        let h_r = [0, 1, 2].map(|i| row_dot(r_row(i), [h.x, h.y, h.z]));
        let p = [self.translation.x, self.translation.y, self.translation.z];
        let diag = 2.0 * row_dot(h_r, p) + m * (0.0 + row_dot(p, p));
        let r_i_k = [0, 1, 2].map(|j| row_dot(r_row(k), [c[(0, j)], c[(1, j)], c[(2, j)]]));
        let rotated = row_dot(r_i_k, r_row(k));
        let outer = (h_r[k] * p[k] + p[k] * h_r[k]) + (p[k] * p[k]) * m;
        (rotated + diag) - outer
    }
}

/// A row times a column in nalgebra's order: `(a₀b₀ + a₁b₁) + a₂b₂`.
#[inline(always)]
fn row_dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXACT: f64 = 1e-12;

    #[test]
    fn rpy_matches_nalgebra_euler_angles() {
        let (r, p, y) = (0.3, -1.1, 2.4);
        let ours = rotation_from_rpy(r, p, y);
        let theirs = *nalgebra::Rotation3::from_euler_angles(r, p, y).matrix();
        assert!((ours - theirs).abs().max() < EXACT);
    }

    /// The paired motion transform gives each motion the bits of its own call, for transforms
    /// with and without exact zeros and motions with zero entries of either sign.
    #[test]
    fn paired_motion_transform_has_the_bits_of_two_calls() {
        let transforms = [
            Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, 0.2, -1.0]),
            Transform::from_xyz_rpy([0.0, -0.09, 0.0], [std::f64::consts::FRAC_PI_2, 0.0, 0.0]),
            Transform::identity(),
        ];
        let motions = [
            Motion::new(Vec3::new(0.3, -1.7, 2.9), Vec3::new(-0.25, 8.5, 1e-9)),
            Motion::new(Vec3::new(-0.0, 0.0, 5.0), Vec3::new(0.0, -0.0, -3.5)),
            Motion::new(Vec3::new(1e300, -2e-300, 7.0), Vec3::new(-4.0, 0.5, 0.0)),
        ];
        let bits = |m: &Motion| {
            [m.linear, m.angular]
                .iter()
                .flat_map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                .collect::<Vec<_>>()
        };
        for x in &transforms {
            for a in &motions {
                for b in &motions {
                    let (pa, pb) = x.inv_act_motion_pair(a, b);
                    assert_eq!(bits(&pa), bits(&x.inv_act_motion(a)));
                    assert_eq!(bits(&pb), bits(&x.inv_act_motion(b)));
                }
            }
        }
    }

    #[test]
    fn axis_rotation_matches_nalgebra() {
        let axis = Vec3::new(0.2, -0.5, 0.9).normalize();
        let ours = rotation_about_axis(&axis, 0.77);
        let unit = nalgebra::Unit::new_normalize(axis);
        let theirs = *nalgebra::Rotation3::from_axis_angle(&unit, 0.77).matrix();
        assert!((ours - theirs).abs().max() < EXACT);
    }

    #[test]
    fn composing_a_coordinate_axis_rotation_has_the_bits_of_the_general_composition() {
        let parent_from_joint = Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, 0.2, -1.0]);
        let aligned =
            Transform::from_xyz_rpy([0.0, -0.09, 0.0], [std::f64::consts::FRAC_PI_2, 0.0, 0.0]);
        for x in [parent_from_joint, aligned, Transform::identity()] {
            for k in 0..3 {
                let mut axis = Vec3::zeros();
                axis[k] = 1.0;
                for angle in [0.0, 0.3, -1.7, 2.9, 1e-9, -41.0, std::f64::consts::PI] {
                    let general = x.compose(&Transform::new(
                        rotation_about_axis(&axis, angle),
                        Vec3::zeros(),
                    ));
                    let special = x.compose_rotation_about_coordinate_axis(k, angle);
                    // `==` on f64 equates the two zeros and nothing else.
                    assert_eq!(special, general, "axis {k}, angle {angle}");
                }
            }
        }
    }

    #[test]
    fn motion_and_force_actions_invert_and_preserve_power() {
        let x = Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, 0.2, -1.0]);
        let m = Motion::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-0.5, 0.4, 0.2));
        let f = Force::new(Vec3::new(0.3, -0.2, 1.0), Vec3::new(2.0, 0.1, -0.7));
        let back = x.inv_act_motion(&x.act_motion(&m));
        assert!((back.linear - m.linear).norm() < EXACT);
        let fb = x.inv_act_force(&x.act_force(&f));
        assert!((fb.angular - f.angular).norm() < EXACT);
        // Power is frame independent.
        assert!((x.act_motion(&m).dot(&x.act_force(&f)) - m.dot(&f)).abs() < EXACT);
        let composed = x.compose(&x.inverse());
        assert!((composed.rotation - Mat3::identity()).abs().max() < EXACT);
        assert!(composed.translation.norm() < EXACT);
    }

    /// The single entries the CRBA's root carry reads have the bits (sign of zero included) of
    /// the same entries of the full transforms, for transforms with and without exact zeros and
    /// forces and inertias with zero entries of either sign.
    #[test]
    fn single_entries_have_the_bits_of_the_full_actions() {
        let transforms = [
            Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, 0.2, -1.0]),
            Transform::from_xyz_rpy([0.0, -0.09, 0.0], [std::f64::consts::FRAC_PI_2, 0.0, 0.0]),
            Transform::from_xyz_rpy([-0.425, 0.0, 0.0], [0.0, 0.0, 0.0]),
            Transform::identity(),
        ];
        let forces = [
            Force::new(Vec3::new(0.3, -1.7, 2.9), Vec3::new(-0.25, 8.5, 1e-9)),
            Force::new(Vec3::new(-0.0, 0.0, 5.0), Vec3::new(0.0, -0.0, -3.5)),
            Force::new(Vec3::new(-0.0, -0.0, -0.0), Vec3::new(-0.0, -0.0, -0.0)),
            Force::new(Vec3::new(1e-300, -2e-300, 7.0), Vec3::new(-4.0, 0.5, 0.0)),
        ];
        let inertias = [
            Inertia::from_com(
                2.5,
                Vec3::new(0.1, -0.2, 0.05),
                Mat3::new(0.3, 0.01, 0.02, 0.01, 0.2, -0.03, 0.02, -0.03, 0.25),
            ),
            Inertia::from_com(
                1.2,
                Vec3::new(0.0, -0.0163, 0.0),
                Mat3::from_diagonal_element(0.002),
            ),
            Inertia::zero(),
        ];
        // And 200 pseudo-random transforms, forces and inertias (rounding differs between
        // summation orders on some of them, as it does not on the exact values above).
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut transforms = transforms.to_vec();
        let mut forces = forces.to_vec();
        let mut inertias = inertias.to_vec();
        for _ in 0..200 {
            let mut v3 = || Vec3::new(uniform(), uniform(), uniform());
            let (xyz, rpy) = (v3(), v3() * 3.0);
            transforms.push(Transform::from_xyz_rpy(xyz.into(), rpy.into()));
            forces.push(Force::new(v3() * 10.0, v3()));
            let (com, spread) = (v3() * 0.2, v3());
            let rotational = Mat3::from_diagonal(&(spread.abs() * 0.1)) + Mat3::identity() * 0.01;
            inertias.push(Inertia::from_com(1.0 + uniform().abs(), com, rotational));
        }
        for x in &transforms {
            for k in 0..3 {
                for f in &forces {
                    let full = x.act_force(f).angular[k];
                    assert_eq!(x.act_force_angular_entry(k, f).to_bits(), full.to_bits());
                }
                for inertia in &inertias {
                    let full = x.act_inertia(inertia).rotational[(k, k)];
                    let entry = x.act_inertia_rotational_diagonal(k, inertia);
                    assert_eq!(entry.to_bits(), full.to_bits(), "axis {k}");
                }
            }
        }
    }

    #[test]
    fn inertia_action_is_consistent_with_force_and_motion_actions() {
        // (X I) (X m) = X (I m) for every motion m.
        let x = Transform::from_xyz_rpy([0.4, 0.1, -0.3], [-0.6, 0.9, 0.2]);
        let body = Inertia::from_com(
            2.5,
            Vec3::new(0.1, -0.2, 0.05),
            Mat3::new(0.3, 0.01, 0.02, 0.01, 0.2, -0.03, 0.02, -0.03, 0.25),
        );
        let m = Motion::new(Vec3::new(0.7, -1.0, 0.2), Vec3::new(0.3, 0.5, -0.9));
        let lhs = x.act_inertia(&body).apply(&x.act_motion(&m));
        let rhs = x.act_force(&body.apply(&m));
        assert!((lhs.linear - rhs.linear).norm() < EXACT);
        assert!((lhs.angular - rhs.angular).norm() < EXACT);
    }
}
