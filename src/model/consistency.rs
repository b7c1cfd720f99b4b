//! Physical consistency of rigid-body inertia (docs/method.md §6).
//!
//! A rotational inertia about the centre of mass is physical when it is positive **semi**-definite
//! (point masses and slender bars are legitimate) and its principal moments — eigenvalues, not the
//! diagonal of a non-diagonal tensor — satisfy the triangle inequality `λ_a + λ_b ≥ λ_c`.

use crate::spatial::Mat3;

/// Relative tolerance of both checks, against the largest principal moment: URDF files print six to
/// nine significant digits, so exact-equality cases (a slender bar, `ixx = 0, iyy = izz`) must pass.
pub const INERTIA_RELATIVE_TOLERANCE: f64 = 1e-9;

/// Why an inertia tensor is not physical.
#[derive(Clone, Debug, PartialEq)]
pub enum InertiaViolation {
    /// A negative principal moment.
    NotPositiveSemidefinite {
        /// Principal moments, ascending (kg·m²).
        principal_moments: [f64; 3],
    },
    /// The two smaller principal moments sum to less than the largest.
    TriangleInequality {
        /// Principal moments, ascending (kg·m²).
        principal_moments: [f64; 3],
    },
    /// The tensor is not symmetric or has a non-finite entry.
    NotSymmetric,
}

impl std::fmt::Display for InertiaViolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotPositiveSemidefinite { principal_moments: m } => write!(
                f,
                "has a negative principal moment (principal moments {:.6e}, {:.6e}, {:.6e} kg·m²)",
                m[0], m[1], m[2]
            ),
            Self::TriangleInequality { principal_moments: m } => write!(
                f,
                "violates the triangle inequality of principal moments ({:.6e} + {:.6e} < {:.6e} kg·m²)",
                m[0], m[1], m[2]
            ),
            Self::NotSymmetric => write!(f, "is not a finite symmetric tensor"),
        }
    }
}

/// Checks a rotational inertia about the centre of mass; `None` when it is physical.
pub fn check_inertia(inertia_about_com: &Mat3) -> Option<InertiaViolation> {
    let i = inertia_about_com;
    if i.iter().any(|v| !v.is_finite()) || (i - i.transpose()).abs().max() > 1e-12 * i.abs().max() {
        return Some(InertiaViolation::NotSymmetric);
    }
    let mut moments: Vec<f64> = i.symmetric_eigenvalues().iter().copied().collect();
    moments.sort_by(f64::total_cmp);
    let principal_moments = [moments[0], moments[1], moments[2]];
    let scale = principal_moments[2].abs();
    let tolerance = INERTIA_RELATIVE_TOLERANCE * scale;
    if principal_moments[0] < -tolerance {
        return Some(InertiaViolation::NotPositiveSemidefinite { principal_moments });
    }
    if principal_moments[0] + principal_moments[1] < principal_moments[2] - tolerance {
        return Some(InertiaViolation::TriangleInequality { principal_moments });
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slender_bar_and_point_mass_are_physical() {
        assert_eq!(
            check_inertia(&Mat3::from_diagonal(&[0.0, 1.0 / 12.0, 1.0 / 12.0].into())),
            None
        );
        assert_eq!(check_inertia(&Mat3::zeros()), None);
    }

    #[test]
    fn violations_are_found_on_principal_moments() {
        let bad = Mat3::from_diagonal(&[0.1, 0.1, 0.3].into());
        assert!(matches!(
            check_inertia(&bad),
            Some(InertiaViolation::TriangleInequality { .. })
        ));
        let negative = Mat3::from_diagonal(&[-0.1, 0.3, 0.3].into());
        assert!(matches!(
            check_inertia(&negative),
            Some(InertiaViolation::NotPositiveSemidefinite { .. })
        ));
        // Diagonal passes the triangle test, principal moments do not: a large product of inertia.
        let off = Mat3::new(1.0, 0.9, 0.0, 0.9, 1.0, 0.0, 0.0, 0.0, 1.5);
        assert!(check_inertia(&off).is_some());
    }
}
