//! 6D motion vectors (twists, spatial accelerations) and force vectors (wrenches).

use super::Vec3;
use std::ops::{Add, AddAssign, Mul, Neg, Sub};

/// A spatial motion vector: linear velocity of the frame origin and angular velocity, both in the
/// coordinates of the frame it is expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Linear part (m/s, or m/s² for accelerations).
    pub linear: Vec3,
    /// Angular part (rad/s, or rad/s²).
    pub angular: Vec3,
}

/// A spatial force vector: force and moment about the frame origin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Force {
    /// Force (N).
    pub linear: Vec3,
    /// Moment about the frame origin (N·m).
    pub angular: Vec3,
}

impl Motion {
    /// The zero motion.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Builds a motion from its linear and angular parts.
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }

    /// The motion cross product `self ×ₘ other` (derivative of `other` in a frame moving with `self`).
    #[inline]
    pub fn cross_motion(&self, other: &Motion) -> Motion {
        Motion {
            linear: self.angular.cross(&other.linear) + self.linear.cross(&other.angular),
            angular: self.angular.cross(&other.angular),
        }
    }

    /// `self ×ₘ (0, rate · e_k)`: [`Motion::cross_motion`] with the motion of a revolute joint about
    /// the coordinate axis `e_k` (`axis_index` k ∈ {0, 1, 2}), the products by its zero entries left
    /// out. Same bits as `self.cross_motion(&Motion::new(0, rate · e_k))` (signs of zero aside).
    #[inline]
    pub fn cross_coordinate_axis(&self, axis_index: usize, rate: f64) -> Motion {
        let cross = |a: &Vec3| -> Vec3 {
            match axis_index {
                0 => Vec3::new(0.0, a.z * rate, -(a.y * rate)),
                1 => Vec3::new(-(a.z * rate), 0.0, a.x * rate),
                _ => Vec3::new(a.y * rate, -(a.x * rate), 0.0),
            }
        };
        Motion {
            linear: cross(&self.linear),
            angular: cross(&self.angular),
        }
    }

    /// The force cross product `self ×* force`.
    #[inline]
    pub fn cross_force(&self, force: &Force) -> Force {
        Force {
            linear: self.angular.cross(&force.linear),
            angular: self.angular.cross(&force.angular) + self.linear.cross(&force.linear),
        }
    }

    /// The power pairing `self · force` (W).
    #[inline]
    pub fn dot(&self, force: &Force) -> f64 {
        self.linear.dot(&force.linear) + self.angular.dot(&force.angular)
    }
}

impl Force {
    /// The zero force.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Builds a force from its linear (force) and angular (moment) parts.
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }
}

macro_rules! vector_ops {
    ($t:ident) => {
        impl Add for $t {
            type Output = $t;
            #[inline]
            fn add(self, rhs: $t) -> $t {
                $t {
                    linear: self.linear + rhs.linear,
                    angular: self.angular + rhs.angular,
                }
            }
        }
        impl AddAssign for $t {
            #[inline]
            fn add_assign(&mut self, rhs: $t) {
                self.linear += rhs.linear;
                self.angular += rhs.angular;
            }
        }
        impl Sub for $t {
            type Output = $t;
            #[inline]
            fn sub(self, rhs: $t) -> $t {
                $t {
                    linear: self.linear - rhs.linear,
                    angular: self.angular - rhs.angular,
                }
            }
        }
        impl Neg for $t {
            type Output = $t;
            #[inline]
            fn neg(self) -> $t {
                $t {
                    linear: -self.linear,
                    angular: -self.angular,
                }
            }
        }
        impl Mul<f64> for $t {
            type Output = $t;
            #[inline]
            fn mul(self, s: f64) -> $t {
                $t {
                    linear: self.linear * s,
                    angular: self.angular * s,
                }
            }
        }
    };
}
vector_ops!(Motion);
vector_ops!(Force);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_a_coordinate_axis_has_the_bits_of_the_general_cross_product() {
        let a = Motion::new(Vec3::new(0.3, -1.0, 2.0), Vec3::new(0.5, 0.1, -0.7));
        for k in 0..3 {
            for rate in [0.0, 1.3, -7.25e-3] {
                let mut axis = Vec3::zeros();
                axis[k] = 1.0;
                let general = a.cross_motion(&Motion::new(Vec3::zeros(), axis * rate));
                assert_eq!(
                    a.cross_coordinate_axis(k, rate),
                    general,
                    "axis {k}, rate {rate}"
                );
            }
        }
    }

    #[test]
    fn cross_products_are_dual() {
        // (a ×ₘ b) · f = −b · (a ×* f) for all a, b, f.
        let a = Motion::new(Vec3::new(0.3, -1.0, 2.0), Vec3::new(0.5, 0.1, -0.7));
        let b = Motion::new(Vec3::new(-0.2, 0.4, 1.1), Vec3::new(1.5, -0.3, 0.2));
        let f = Force::new(Vec3::new(2.0, 0.7, -0.4), Vec3::new(-1.2, 0.9, 0.3));
        let lhs = a.cross_motion(&b).dot(&f);
        let rhs = -b.dot(&a.cross_force(&f));
        assert!((lhs - rhs).abs() < 1e-12, "{lhs} vs {rhs}");
    }
}
