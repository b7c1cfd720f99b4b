//! SE(3) pieces the forward sensitivities of a floating base need (docs/sensitivities.md §4): how a
//! tangent perturbation passes through `q ⊕ δ = q · Exp(δ)` (the adjoint `Ad(Exp(−ξ))` and the right
//! Jacobian `J_r(ξ)` of `Exp`), and the inverse of `⊕` (`Log(q0⁻¹ q1)`).
//!
//! Twists are `(v, ω)`: linear then angular, in the body frame, as [`crate::spatial::Motion`] and the
//! floating joint's velocity. `ad_ξ η = ξ ×ₘ η = (ω × η_v + v × η_ω, ω × η_ω)`.
//!
//! The matrix functions are summed as power series of `ad_ξ`, which converge fast for the increment
//! of one step (|ξ| ≲ 0.1) and are refused beyond [`SERIES_MAX_ANGLE`].

use crate::spatial::{Mat3, Vec3};
use nalgebra::{Matrix6, UnitQuaternion};

/// Largest rotation angle (rad) of a twist whose series are summed: `J_r` has radius of convergence
/// 2π and the terms of both series shrink like `|ξ|^n / n!`; one integrator step turns a body by
/// |ω| h (0.05 rad at 50 rad/s and h = 1 ms), far below this.
pub const SERIES_MAX_ANGLE: f64 = 1.0;

/// Terms are summed until the next one is below this fraction of the identity's size (1): the
/// series then agree with their limits to rounding.
const SERIES_TOLERANCE: f64 = 1e-18;

/// Most terms summed (|ξ| = 1 needs ~20).
const SERIES_MAX_TERMS: usize = 40;

/// `ad_ξ` of the twist `ξ = (linear, angular)` (6 × 6, linear rows first).
pub fn ad(linear: &Vec3, angular: &Vec3) -> Matrix6<f64> {
    let w = angular.cross_matrix();
    let v = linear.cross_matrix();
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&w);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&v);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&w);
    out
}

/// `(Ad(Exp(−ξ)), J_r(ξ))` = `(Σ (−ad_ξ)ⁿ / n!, Σ (−ad_ξ)ⁿ / (n+1)!)`: with `q⁺ = q · Exp(ξ)`,
/// perturbing `q` to `q · Exp(δq)` and `ξ` to `ξ + δξ` perturbs `q⁺` to
/// `q⁺ · Exp(Ad(Exp(−ξ)) δq + J_r(ξ) δξ)` to first order.
///
/// Errors: a rotation angle above [`SERIES_MAX_ANGLE`] (a message naming it).
pub fn exp_jacobians(
    linear: &Vec3,
    angular: &Vec3,
) -> Result<(Matrix6<f64>, Matrix6<f64>), String> {
    let angle = angular.norm();
    if angle.is_nan() || angle > SERIES_MAX_ANGLE || !linear.norm().is_finite() {
        return Err(format!(
            "the floating base turns by {angle:.3e} rad in one step (more than {SERIES_MAX_ANGLE} \
             rad): its sensitivities are not computed for such steps; use a smaller step"
        ));
    }
    let minus_ad = -ad(linear, angular);
    let mut term = Matrix6::identity();
    let mut adjoint = Matrix6::identity();
    let mut jacobian = Matrix6::identity();
    for n in 1..=SERIES_MAX_TERMS {
        term = term * minus_ad / n as f64;
        adjoint += term;
        jacobian += term / (n + 1) as f64;
        if term.amax() < SERIES_TOLERANCE {
            return Ok((adjoint, jacobian));
        }
    }
    Err(format!(
        "the SE(3) series did not converge in {SERIES_MAX_TERMS} terms for a twist of norm {:.3e}",
        (linear.norm_squared() + angle * angle).sqrt()
    ))
}

/// `J_r(φ)⁻¹` of SO(3): with `Exp(φ + δ) ≈ Exp(φ) Exp(J_r(φ) δ)`, a rotation vector `φ` moved on
/// the right by `Exp(δω)` changes by `J_r(φ)⁻¹ δω` (and by `J_r(−φ)⁻¹ δω` when moved on the left).
/// `I + ½ φ× + (1/θ² − (1 + cos θ)/(2 θ sin θ)) (φ×)²`, with the series `1/12 + θ²/720` below 1e-4
/// rad. Valid for θ < π.
pub fn so3_right_jacobian_inverse(phi: &Vec3) -> Mat3 {
    let theta = phi.norm();
    let skew = phi.cross_matrix();
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Mat3::identity() + skew * 0.5 + skew * skew * c
}

/// `V(ω) = Σ (ω×)ⁿ / (n+1)!` (the left Jacobian of SO(3)), the matrix that takes a body twist's
/// linear part to the translation of `Exp`: `Exp(v, ω) = (Exp(ω), V(ω) v)`. Closed form (as the
/// integrator's exponential), with the series below 1e-4 rad.
fn translation_matrix(angular: &Vec3) -> Mat3 {
    let theta = angular.norm();
    let skew = angular.cross_matrix();
    let (b, c) = if theta < 1e-4 {
        let t2 = theta * theta;
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let (s, co) = theta.sin_cos();
        (
            (1.0 - co) / (theta * theta),
            (theta - s) / (theta * theta * theta),
        )
    };
    Mat3::identity() + skew * b + skew * skew * c
}

/// The twist `(v, ω)` with `(p0, r0) · Exp(v, ω) = (p1, r1)` (SE(3) logarithm of `T0⁻¹ T1`), for
/// positions `p` (world frame) and orientations `r` (world from body). The rotation must be below π
/// (the logarithm is not unique at π); returns `None` when `V(ω)` is singular.
pub fn log_between(
    p0: &Vec3,
    r0: &UnitQuaternion<f64>,
    p1: &Vec3,
    r1: &UnitQuaternion<f64>,
) -> Option<(Vec3, Vec3)> {
    let relative = r0.inverse() * r1;
    let angular = relative.scaled_axis();
    let translation = r0.inverse() * (p1 - p0);
    let linear = translation_matrix(&angular).lu().solve(&translation)?;
    Some((linear, angular))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Series and closed forms agree to rounding on small twists.
    const EXACT: f64 = 1e-14;

    #[test]
    fn series_match_closed_forms_for_pure_rotation() {
        // For a pure rotation, the angular block of J_r is the SO(3) right Jacobian
        // I − (1 − cos θ)/θ² ω× + (θ − sin θ)/θ³ (ω×)², and the adjoint block is Exp(−ω).
        let w = Vec3::new(0.2, -0.5, 0.3);
        let (adjoint, jacobian) = exp_jacobians(&Vec3::zeros(), &w).unwrap();
        let theta = w.norm();
        let k = w.cross_matrix();
        let so3 = Mat3::identity() - k * ((1.0 - theta.cos()) / (theta * theta))
            + k * k * ((theta - theta.sin()) / theta.powi(3));
        let block = jacobian.fixed_view::<3, 3>(3, 3).into_owned();
        assert!((block - so3).amax() < EXACT);
        let rotation = UnitQuaternion::from_scaled_axis(-w);
        let block = adjoint.fixed_view::<3, 3>(3, 3).into_owned();
        assert!((block - rotation.to_rotation_matrix().matrix()).amax() < EXACT);
    }

    #[test]
    fn log_inverts_the_exponential() {
        let p0 = Vec3::new(0.3, -1.0, 2.0);
        let r0 = UnitQuaternion::from_euler_angles(0.4, -0.2, 1.1);
        let (v, w) = (Vec3::new(0.5, 0.1, -0.3), Vec3::new(-0.4, 0.7, 0.2));
        let p1 = p0 + r0 * (translation_matrix(&w) * v);
        let r1 = r0 * UnitQuaternion::from_scaled_axis(w);
        let (lin, ang) = log_between(&p0, &r0, &p1, &r1).unwrap();
        assert!((lin - v).norm() < EXACT && (ang - w).norm() < EXACT);
    }

    #[test]
    fn right_jacobian_inverse_matches_a_difference_of_logarithms() {
        for phi in [Vec3::new(0.3, -1.2, 0.7), Vec3::new(1e-6, 2e-6, -1e-6)] {
            let base = UnitQuaternion::from_scaled_axis(phi);
            let inverse = so3_right_jacobian_inverse(&phi);
            let h = 1e-6;
            for k in 0..3 {
                let step = Vec3::ith(k, h);
                let plus = (base * UnitQuaternion::from_scaled_axis(step)).scaled_axis();
                let minus = (base * UnitQuaternion::from_scaled_axis(-step)).scaled_axis();
                let numeric = (plus - minus) / (2.0 * h);
                assert!(
                    (numeric - inverse.column(k)).norm() < 1e-8,
                    "{phi} column {k}"
                );
            }
        }
    }

    #[test]
    fn large_twists_are_refused() {
        let message = exp_jacobians(&Vec3::zeros(), &Vec3::new(2.0, 0.0, 0.0)).unwrap_err();
        assert!(message.contains("turns by 2.000e0 rad"), "{message}");
    }
}
