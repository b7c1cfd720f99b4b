//! Rigid-body dynamics on a [`crate::model::Model`] in joint coordinates:
//! - [`forward_kinematics`] — body placements;
//! - [`rnea`] — inverse dynamics `τ = M(q) q̈ + C(q, q̇) q̇ + g(q)` and [`nonlinear_effects`] (`q̈ = 0`);
//! - [`crba`] — the joint-space mass matrix `M(q)` ([`crba_at_placements`] at placements already
//!   computed);
//! - [`forward_dynamics`] — `q̈ = M⁻¹ (τ − C q̇ − g)` through RNEA, CRBA (at the RNEA's placements)
//!   and an in-place Cholesky factorisation (for the small dense systems of robot arms this is as
//!   fast as ABA and reuses the pieces the implicit integrator needs anyway);
//! - [`world_from_link`] — one URDF link's placement in the world frame;
//! - derivatives for the forward sensitivities ([`link_inertia_derivative`],
//!   [`rnea_inertia_derivative`], [`link_origin_jacobian`], [`rnea_derivatives`];
//!   docs/sensitivities.md).
//!
//! Every algorithm is `algorithm(model, data, …)`: the model is read only, results and scratch live
//! in a per-thread [`Data`] allocated once; the hot path allocates nothing. Only rigid-body terms
//! are computed here: damping, friction, springs and drives are scene effects.

pub mod batch;
mod crba;
mod data;
mod derivatives;
mod kinematics;
mod rnea;

pub use crate::linalg::cholesky::{cholesky_factor_in_place, cholesky_solve_in_place};
pub use crba::{crba, crba_at_placements};
pub use data::Data;
pub use derivatives::{
    link_inertia_derivative, link_origin_jacobian, rnea_derivatives, rnea_inertia_derivative,
    InertialField, RneaDerivatives,
};
pub use kinematics::{
    drift_kinematics, forward_kinematics, joint_placements, world_from_link, world_placements,
};
pub use rnea::{
    add_external_forces, nonlinear_effects, rnea, rnea_at_placements, rnea_with_external,
};

use crate::model::Model;
use crate::spatial::Vec3;
use thiserror::Error;

/// Why a dynamics computation failed.
#[derive(Debug, Error)]
pub enum DynamicsError {
    /// `M(q)` is not positive definite: some joint motion moves nothing with inertia.
    #[error("the mass matrix is singular at this state (pivot {pivot:.3e} at coordinate {coordinate}, joint '{joint}'): {cause}")]
    SingularMassMatrix {
        /// Index of the velocity coordinate whose pivot vanished.
        coordinate: usize,
        /// The joint owning that coordinate (not necessarily the one at fault: see `cause`).
        joint: String,
        /// The pivot found.
        pivot: f64,
        /// Which joints move together without inertia, which link is massless, what to do
        /// ([`singular_mass_cause`]).
        cause: String,
    },
    /// A NaN or infinity appeared in a result.
    #[error("non-finite value in {quantity} at coordinate {coordinate}")]
    NonFinite {
        /// What was being computed.
        quantity: &'static str,
        /// Where.
        coordinate: usize,
    },
}

/// Name of the joint owning position coordinate `q_index` (a floating joint owns seven).
pub fn joint_of_position(model: &Model, q_index: usize) -> &str {
    model
        .joints
        .iter()
        .find(|j| (j.q_index..j.q_index + j.nq()).contains(&q_index))
        .map_or("?", |j| j.name.as_str())
}

/// Name of the joint owning velocity coordinate `v_index`.
pub fn joint_of_velocity(model: &Model, v_index: usize) -> &str {
    model
        .joints
        .iter()
        .find(|j| (j.v_index..j.v_index + j.nv()).contains(&v_index))
        .map_or("?", |j| j.name.as_str())
}

/// Explains a mass matrix whose Cholesky factorisation failed at velocity coordinate
/// `coordinate`: the null direction of the leading `(coordinate + 1)²` block of `M(q)` (the
/// eigenvector of its smallest eigenvalue), in terms of joints and links
/// ([`crate::model::explain_null_motion`]). `q: dim nq`. Overwrites `data.mass_matrix` with `M(q)`
/// and the kinematic buffers of [`drift_kinematics`]; allocates (an error path only).
pub fn singular_mass_cause(model: &Model, data: &mut Data, q: &[f64], coordinate: usize) -> String {
    crba(model, data, q);
    let n = (coordinate + 1).min(model.nv);
    let eigen = data
        .mass_matrix
        .view((0, 0), (n, n))
        .into_owned()
        .symmetric_eigen();
    let smallest = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(k, _)| k);
    let mut direction = vec![0.0; model.nv];
    for (d, x) in direction
        .iter_mut()
        .zip(eigen.eigenvectors.column(smallest).iter())
    {
        *d = *x;
    }
    // Which bodies that direction moves (body-frame twists, norms).
    drift_kinematics(model, data, q, &direction);
    let speeds: Vec<f64> = data
        .velocity
        .iter()
        .map(|m| (m.linear.norm_squared() + m.angular.norm_squared()).sqrt())
        .collect();
    crate::model::explain_null_motion(model, &direction, &speeds)
}

/// Forward dynamics: `data.qdd = M(q)⁻¹ (τ − C(q, v) v − g(q))`.
///
/// `q: dim nq`, `v: dim nv`, `tau: dim nv`. Overwrites `data.mass_matrix` (with its Cholesky factor
/// in the lower triangle), `data.bias` and `data.qdd`; returns `data.qdd`.
pub fn forward_dynamics<'a>(
    model: &Model,
    gravity: &Vec3,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<&'a [f64], DynamicsError> {
    nonlinear_effects(model, gravity, data, q, v);
    // The RNEA has just left the placements at `q` in `data`.
    crba_at_placements(model, data);
    for ((qdd, tau), bias) in data.qdd.iter_mut().zip(tau).zip(data.bias.iter()) {
        *qdd = tau - bias;
    }
    if let Err(crate::linalg::cholesky::NonPositivePivot {
        index: coordinate,
        pivot,
    }) = cholesky_factor_in_place(&mut data.mass_matrix)
    {
        return Err(DynamicsError::SingularMassMatrix {
            coordinate,
            joint: joint_of_velocity(model, coordinate).to_string(),
            pivot,
            cause: singular_mass_cause(model, data, q, coordinate),
        });
    }
    cholesky_solve_in_place(&data.mass_matrix, &mut data.qdd);
    if let Some(coordinate) = data.qdd.iter().position(|x| !x.is_finite()) {
        return Err(DynamicsError::NonFinite {
            quantity: "joint accelerations",
            coordinate,
        });
    }
    Ok(data.qdd.as_slice())
}
