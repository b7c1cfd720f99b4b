//! A floating joint's orientation as ribbon stores it: four numbers `(x, y, z, w)` — the order of
//! URDF 1.1's `quat_xyzw`, Pinocchio's and ROS's configuration vectors — while nalgebra's
//! `Quaternion::new` takes `(w, x, y, z)`. This is the one place that reads such a quadruple into a
//! nalgebra quaternion, writes one back, and normalises a raw quadruple; everything else calls it,
//! so the component order is written down once.

use nalgebra::{Quaternion, UnitQuaternion};

/// The quaternion stored as `xyzw` (`dim ≥ 4`: x, y, z, w), as it is (not normalised).
#[inline]
pub fn quaternion_from_xyzw(xyzw: &[f64]) -> Quaternion<f64> {
    Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2])
}

/// The rotation of the quaternion stored as `xyzw` (`dim ≥ 4`), normalised by nalgebra
/// (`UnitQuaternion::new_normalize`). A zero quadruple gives NaN entries; callers that read user
/// input check the length first ([`xyzw_norm`]).
#[inline]
pub fn unit_quaternion_from_xyzw(xyzw: &[f64]) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(quaternion_from_xyzw(xyzw))
}

/// Writes `quaternion` as `(x, y, z, w)` into `xyzw[..4]` (overwrites those four entries).
#[inline]
pub fn write_xyzw(quaternion: &Quaternion<f64>, xyzw: &mut [f64]) {
    xyzw[..4].copy_from_slice(&[quaternion.i, quaternion.j, quaternion.k, quaternion.w]);
}

/// Euclidean length `√(x² + y² + z² + w²)` of the quadruple `xyzw` (summed in that order).
#[inline]
pub fn xyzw_norm(xyzw: &[f64]) -> f64 {
    xyzw.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// The quadruple divided by its length [`xyzw_norm`]; `None` when the length is zero or not finite
/// (such a quadruple names no rotation).
pub fn normalized_xyzw(xyzw: [f64; 4]) -> Option<[f64; 4]> {
    let norm = xyzw_norm(&xyzw);
    (norm > 0.0 && norm.is_finite()).then(|| xyzw.map(|c| c / norm))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rounding of one normalisation of entries of order one.
    const ROUNDING_TOL: f64 = 1e-15;

    #[test]
    fn xyzw_order_round_trips_through_nalgebra() {
        let stored = [0.1, -0.2, 0.3, 0.9];
        let quaternion = quaternion_from_xyzw(&stored);
        assert_eq!(
            (quaternion.w, quaternion.i, quaternion.j, quaternion.k),
            (0.9, 0.1, -0.2, 0.3)
        );
        let mut written = [0.0; 5];
        written[4] = 7.0;
        write_xyzw(&quaternion, &mut written);
        assert_eq!(written, [0.1, -0.2, 0.3, 0.9, 7.0]);
    }

    #[test]
    fn a_quarter_turn_about_z_rotates_x_into_y() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let rotation = unit_quaternion_from_xyzw(&[0.0, 0.0, 2.0 * h, 2.0 * h]);
        let turned = rotation * nalgebra::Vector3::x();
        assert!((turned - nalgebra::Vector3::y()).amax() < ROUNDING_TOL);
    }

    #[test]
    fn normalisation_refuses_what_names_no_rotation() {
        assert_eq!(xyzw_norm(&[0.0, 3.0, 0.0, 4.0]), 5.0);
        assert_eq!(
            normalized_xyzw([0.0, 3.0, 0.0, 4.0]),
            Some([0.0, 0.6, 0.0, 0.8])
        );
        assert_eq!(normalized_xyzw([0.0; 4]), None);
        assert_eq!(normalized_xyzw([f64::MAX, 0.0, 0.0, 1.0]), None);
        assert_eq!(normalized_xyzw([f64::NAN, 0.0, 0.0, 1.0]), None);
    }
}
