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
//!   `x_i = c_i + r_i ξ_i`, `ξ_i ∈ [-1, 1]`), a pattern (`"link.*.mass"`) one per match in
//!   registry order ([`crate::sidecar::expand_parameters`] says who owns which path); the
//!   nominal of a path is its URDF value (so its nominal ξ need not be 0, see
//!   [`ParameterSpace::nominal_xi`]), of a symbol its midpoint;
//! - a shared pattern (`{ rel = 0.05, shared = true }`) is one dimension — a factor
//!   `1 + rel · ξ` on every match's URDF value, or an offset `abs · ξ` added to it ([`Group`]);
//! - `link.NAME.scale` multiplies a link's mass and inertia tensor (whatever values they have,
//!   declared or not: a scale and a mass interval on the same link multiply);
//! - [`ParameterSpace::target_derivatives`] gives `∂value/∂ξ_j` of every value dimension `j`
//!   moves, for sensitivities;
//! - `[bind]` expressions ([`Expression`]: `+ - * / ^ ( )`, `sqrt`, f64 only) write model values from
//!   the free symbols; [`ParameterSpace::apply`] writes a point into a model without allocating;
//! - the whole box is checked for physical consistency when the space is built
//!   ([`ParameterSpace::check_box`]): bound values must be possible values, and a link's inertia
//!   must stay PSD with principal moments satisfying the triangle inequality wherever its URDF
//!   inertia does, checked link by link over only the dimensions that move that link (so a box
//!   of d = 100 is checked in milliseconds). For direct inertia paths and groups (affine in ξ)
//!   the corners of those dimensions are a proof; a positive scale changes neither property;
//!   with `[bind]` expressions the box is checked densely (corners plus a grid of up to
//!   [`DENSE_CHECK_POINTS_PER_DIMENSION`] points per dimension, at most [`DENSE_CHECK_MAX_POINTS`]
//!   points per link or binding), which can miss a violation confined between grid points.
//!
//! What it does not do: read the file or expand patterns (see [`crate::sidecar`]), apply `--set`
//! overrides, or check merged bodies apart from their links (a sum of physical inertias is
//! physical). A `{ abs = 0 }` or `[a, a]` interval is refused: zero width is no uncertainty.

mod bound_values;
mod consistency;
mod dimension;
mod error;
mod expression;
mod space;

pub use crate::sidecar::is_symbol_name;
pub use consistency::{BoxCheckSummary, DENSE_CHECK_MAX_POINTS, DENSE_CHECK_POINTS_PER_DIMENSION};
pub use dimension::{
    Binding, Dimension, DimensionKind, Group, GroupMember, GroupMode, BIND_DERIVATIVE_STEP,
};
pub use error::{BoundValueSource, UncertaintyError};
pub use expression::{Expression, ExpressionError, SQRT};
pub use space::{ParameterSpace, BIND_NOMINAL_RELATIVE_TOLERANCE, QUOTED_EXPRESSION_MAX_CHARS};

#[cfg(test)]
mod tests;
