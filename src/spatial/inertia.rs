//! Rigid-body spatial inertia in the additive form (mass, first moment, rotational inertia about the
//! frame origin): sums of bodies are plain sums, and point masses and zero-mass bodies need no
//! special case.

use super::{Force, Mat3, Motion, Vec3};
use std::ops::{Add, AddAssign};

/// Spatial inertia of a rigid body, expressed about the origin of the frame it lives in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia {
    /// Mass (kg).
    pub mass: f64,
    /// First moment of mass `m · com` (kg·m).
    pub first_moment: Vec3,
    /// Rotational inertia about the frame origin (kg·m²).
    pub rotational: Mat3,
}

impl Default for Inertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl Inertia {
    /// No mass at all.
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            first_moment: Vec3::zeros(),
            rotational: Mat3::zeros(),
        }
    }

    /// From mass (kg), centre of mass (m) and rotational inertia about the centre of mass (kg·m²),
    /// all in this frame's coordinates (parallel-axis theorem).
    pub fn from_com(mass: f64, com: Vec3, inertia_about_com: Mat3) -> Self {
        let shift = Mat3::from_diagonal_element(com.norm_squared()) - com * com.transpose();
        Self {
            mass,
            first_moment: com * mass,
            rotational: inertia_about_com + shift * mass,
        }
    }

    /// Centre of mass (m); `None` for a massless body.
    pub fn com(&self) -> Option<Vec3> {
        (self.mass > 0.0).then(|| self.first_moment / self.mass)
    }

    /// Rotational inertia about the centre of mass (kg·m²); `None` for a massless body.
    pub fn inertia_about_com(&self) -> Option<Mat3> {
        let com = self.com()?;
        let shift = Mat3::from_diagonal_element(com.norm_squared()) - com * com.transpose();
        Some(self.rotational - shift * self.mass)
    }

    /// Momentum `I · motion`: `(m v − h × ω, I_o ω + h × v)`.
    #[inline]
    pub fn apply(&self, motion: &Motion) -> Force {
        Force {
            linear: motion.linear * self.mass - self.first_moment.cross(&motion.angular),
            angular: self.rotational * motion.angular + self.first_moment.cross(&motion.linear),
        }
    }
}

impl Add for Inertia {
    type Output = Inertia;
    #[inline]
    fn add(self, rhs: Inertia) -> Inertia {
        Inertia {
            mass: self.mass + rhs.mass,
            first_moment: self.first_moment + rhs.first_moment,
            rotational: self.rotational + rhs.rotational,
        }
    }
}

impl AddAssign for Inertia {
    #[inline]
    fn add_assign(&mut self, rhs: Inertia) {
        self.mass += rhs.mass;
        self.first_moment += rhs.first_moment;
        self.rotational += rhs.rotational;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn com_round_trip() {
        let ic = Mat3::new(0.3, 0.01, 0.0, 0.01, 0.2, 0.0, 0.0, 0.0, 0.1);
        let body = Inertia::from_com(2.0, Vec3::new(0.5, -0.1, 0.2), ic);
        assert!((body.com().unwrap() - Vec3::new(0.5, -0.1, 0.2)).norm() < 1e-15);
        assert!((body.inertia_about_com().unwrap() - ic).abs().max() < 1e-14);
        assert!(Inertia::zero().com().is_none());
    }

    #[test]
    fn kinetic_energy_of_a_point_mass() {
        // A 3 kg point at (1, 0, 0) spinning at 2 rad/s about z: v = 2 m/s, E = ½ m v² = 6 J.
        let point = Inertia::from_com(3.0, Vec3::new(1.0, 0.0, 0.0), Mat3::zeros());
        let spin = Motion::new(Vec3::zeros(), Vec3::new(0.0, 0.0, 2.0));
        let energy = 0.5 * spin.dot(&point.apply(&spin));
        assert!((energy - 6.0).abs() < 1e-14);
    }
}
