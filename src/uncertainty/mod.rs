//! Interval parameters of a study: the sidecar's `[parameters]` and `[bind]` (design contract),
//! resolved against a model into a [`ParameterSpace`].
//!
//! ```toml
//! [parameters]                                  # paths are quoted strings; free symbols are bare names
//! "link.forearm_link.mass"     = [2.1, 2.5]     # absolute bounds (must contain the URDF value)
//! "joint.elbow_joint.origin.z" = { rel = 0.01 } # ±1 % of the URDF value (an error if that value is 0)
//! "link.wrist_1_link.com.y"    = { abs = 0.002 }# ± 2 mm around the URDF value
//! l1                           = [0.99, 1.01]   # a free symbol (explicit bounds only) …
//! [bind]                                        # … bound to model values through expressions
//! "link.bar1.inertia.izz"      = "l1 * l1 / 12"
//! ```
//!
//! What it does:
//! - each `[parameters]` entry is one dimension of ξ, in order of appearance (docs/method.md §1:
//!   `x_i = c_i + r_i ξ_i`, `ξ_i ∈ [-1, 1]`); the nominal of a path is its URDF value (so its
//!   nominal ξ need not be 0, see [`ParameterSpace::nominal_xi`]), of a symbol its midpoint;
//! - `[bind]` expressions ([`Expression`]: `+ - * / ^ ( )`, `sqrt`, f64 only) write model values from
//!   the free symbols; [`ParameterSpace::apply`] writes a point into a model without allocating;
//! - the whole box is checked for physical consistency when the space is built
//!   ([`ParameterSpace::check_box`]): bound values must be possible values, and a link's inertia
//!   must stay PSD with principal moments satisfying the triangle inequality wherever its URDF
//!   inertia does. For direct inertia paths the corners of the box are a proof; with `[bind]`
//!   expressions the box is checked densely (corners plus a grid of up to
//!   [`DENSE_CHECK_POINTS_PER_DIMENSION`] points per dimension, at most [`DENSE_CHECK_MAX_POINTS`]
//!   points per link or binding), which can miss a violation confined between grid points.
//!
//! What it does not do: read the file (see [`crate::scene::parse_sidecar`]), apply `--set`
//! overrides, or check merged bodies apart from their links (a sum of physical inertias is
//! physical). A `{ abs = 0 }` or `[a, a]` interval is refused: zero width is no uncertainty.

mod consistency;
mod error;
mod expression;
mod space;

pub use consistency::{DENSE_CHECK_MAX_POINTS, DENSE_CHECK_POINTS_PER_DIMENSION};
pub use error::UncertaintyError;
pub use expression::{Expression, ExpressionError, SQRT};
pub use space::{
    is_symbol_name, Binding, Dimension, DimensionKind, ParameterSpace,
    BIND_NOMINAL_RELATIVE_TOLERANCE,
};

#[cfg(test)]
mod tests;
