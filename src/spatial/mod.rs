//! Spatial algebra on nalgebra fixed-size types: 6D motion and force vectors, rigid transforms and
//! rigid-body inertia, and the `(x, y, z, w)` storage of a floating joint's quaternion ([`quaternion`]).
//!
//! Conventions (the same as Pinocchio's, so that results compare directly):
//! - a 6D vector is stored as its linear part then its angular part;
//! - a [`Transform`] named `parent_from_child` maps coordinates of the child frame into the parent frame:
//!   `point_in_parent = parent_from_child.rotation * point_in_child + parent_from_child.translation`;
//! - an [`Inertia`] is expressed about the origin of the frame it lives in.
//!
//! This module does no allocation and knows nothing about robots.

mod inertia;
mod motion;
pub(crate) mod pair;
pub mod quaternion;
mod transform;
pub mod trig;

pub use inertia::Inertia;
pub use motion::{Force, Motion};
pub use transform::{
    rotation_about_axis, rotation_about_axis_given_sin_cos, rotation_from_rpy, Transform,
};

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3×3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
