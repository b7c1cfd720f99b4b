//! The dimensions of a parameter box and what they move: a dimension (a path, a shared group or a
//! free symbol, with its interval), a group's members, a `[bind]` binding (an expression of the
//! symbols) and their derivatives in ξ. `space.rs` builds them from the sidecar; `consistency.rs`
//! checks the box they span.

use super::expression::Expression;
use crate::params::ParamTarget;

/// Step in ξ of the central differences that differentiate `[bind]` expressions
/// ([`ParameterSpace::target_derivatives`](super::ParameterSpace::target_derivatives); docs/method.md §1). With Richardson extrapolation over h and h/2 the
/// truncation error is about `h⁴/480 · |∂⁵f/∂ξ⁵|` (≈ 2e-15 relative for an expression whose
/// derivatives in ξ are of its own size; in practice far less, since the box is a few percent
/// wide) and the rounding error about `3 ε |f| / h` ≈ 7e-13 |f|: together ~1e-12 of the value,
/// for smooth expressions.
pub const BIND_DERIVATIVE_STEP: f64 = 1e-3;

/// What one dimension of ξ moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DimensionKind {
    /// A model value, written directly.
    Path(ParamTarget),
    /// A free symbol, which moves the model only through `[bind]` expressions.
    Symbol,
    /// A shared pattern (`{ rel = …, shared = true }`): group `0` of [`ParameterSpace::groups`](super::ParameterSpace::groups),
    /// whose every member moves with this one dimension.
    Group(usize),
}

/// One interval parameter: dimension `i` of ξ, `x_i = c_i + r_i ξ_i` with `ξ_i ∈ [-1, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Dimension {
    /// The dimension's name: a parameter path (`link.forearm_link.mass`, also for a pattern's
    /// match), a symbol name (`l1`), or the pattern key of a shared group (`link.*.mass`).
    pub name: String,
    /// The `[parameters]` key it came from: the name itself, or the pattern key.
    pub source: String,
    /// The unit of `lower`, `upper` and `nominal` (`kg`, `m`, …; `""` for unitless values, free
    /// symbols and the factor of a relative group).
    pub unit: &'static str,
    /// Lower bound `x̲_i` (in `unit`).
    pub lower: f64,
    /// Upper bound `x̄_i` (> `lower`).
    pub upper: f64,
    /// The nominal value: the URDF value of a path, the midpoint of a symbol, 1 for the factor of a
    /// relative group and 0 for the offset of an absolute group.
    pub nominal: f64,
    /// What the dimension moves.
    pub kind: DimensionKind,
}

impl Dimension {
    /// The midpoint `c_i = (x̲_i + x̄_i) / 2`.
    pub fn center(&self) -> f64 {
        0.5 * (self.lower + self.upper)
    }

    /// The radius `r_i = (x̄_i − x̲_i) / 2`.
    pub fn radius(&self) -> f64 {
        0.5 * (self.upper - self.lower)
    }

    /// The physical value at `xi` (`ξ_i ∈ [-1, 1]`): `c_i + r_i ξ_i`, computed as the convex
    /// combination `((1 − ξ) x̲ + (1 + ξ) x̄) / 2` so that the bounds are hit exactly at ξ = ±1
    /// (a mass bound of 0 stays 0, never −1e-17). (A group's members are written through
    /// [`Group::member_value`], which is exact at ξ = 0 too.)
    #[inline]
    pub fn value_at(&self, xi: f64) -> f64 {
        0.5 * ((1.0 - xi) * self.lower + (1.0 + xi) * self.upper)
    }

    /// The ξ of a physical value: `(x − c_i) / r_i`.
    pub fn xi_of(&self, value: f64) -> f64 {
        (value - self.center()) / self.radius()
    }
}

/// How a shared group moves its members.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupMode {
    /// `rel`: each member is its URDF value times the factor `1 + amount · ξ` (nominal 1).
    Factor,
    /// `abs`: each member is its URDF value plus the offset `amount · ξ` (nominal 0).
    Offset,
}

/// One value a shared group moves.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupMember {
    /// Its full path.
    pub path: String,
    /// The value it writes.
    pub target: ParamTarget,
    /// Its URDF value (the nominal model's value when the space was built).
    pub urdf_value: f64,
}

/// A shared pattern: one dimension moving every member together.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// Factor or offset.
    pub mode: GroupMode,
    /// `rel` (a fraction) or `abs` (in the members' unit): the half-width of the factor or offset.
    pub amount: f64,
    /// The matches, in registry order.
    pub members: Vec<GroupMember>,
}

impl Group {
    /// The value `member` takes at `xi` (the group dimension's ξ): `u · (1 + amount · ξ)` or
    /// `u + amount · ξ` with `u` its URDF value — exactly `u` at ξ = 0.
    #[inline]
    pub fn member_value(&self, member: &GroupMember, xi: f64) -> f64 {
        match self.mode {
            GroupMode::Factor => member.urdf_value * (1.0 + self.amount * xi),
            GroupMode::Offset => member.urdf_value + self.amount * xi,
        }
    }

    /// `∂ member_value / ∂ξ` (constant: the members are affine in ξ).
    #[inline]
    pub fn member_derivative(&self, member: &GroupMember) -> f64 {
        match self.mode {
            GroupMode::Factor => member.urdf_value * self.amount,
            GroupMode::Offset => self.amount,
        }
    }
}

/// A model value bound to an expression of the free symbols (`[bind]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    /// The parameter path as written.
    pub path: String,
    /// The value it writes.
    pub target: ParamTarget,
    /// The expression; its symbol `k` is dimension `k` (always a [`DimensionKind::Symbol`]).
    pub expression: Expression,
}

impl Binding {
    /// The expression's value at `xi` (`xi: dim d`). Allocates nothing.
    #[inline]
    pub fn value_at(&self, dimensions: &[Dimension], xi: &[f64]) -> f64 {
        self.expression
            .eval(&|k: usize| dimensions[k].value_at(xi[k]))
    }

    /// The expression's value at `xi` with dimension `k`'s ξ replaced by `xi_k`. Allocates nothing.
    #[inline]
    fn value_with(&self, dimensions: &[Dimension], xi: &[f64], k: usize, xi_k: f64) -> f64 {
        self.expression
            .eval(&|j: usize| dimensions[j].value_at(if j == k { xi_k } else { xi[j] }))
    }

    /// `∂value/∂ξ_k` at `xi` by central differences with Richardson extrapolation (steps
    /// [`BIND_DERIVATIVE_STEP`] and half of it: error O(h⁴)); where the stencil would leave
    /// [−1, 1], by the second-order one-sided difference pointing into the box, extrapolated the
    /// same way (error O(h³)). See [`ParameterSpace::target_derivatives`](super::ParameterSpace::target_derivatives).
    pub(super) fn derivative(&self, dimensions: &[Dimension], xi: &[f64], k: usize) -> f64 {
        let x = xi[k];
        let f = |t: f64| self.value_with(dimensions, xi, k, t);
        let h = BIND_DERIVATIVE_STEP;
        if x - h >= -1.0 && x + h <= 1.0 {
            let central = |h: f64| (f(x + h) - f(x - h)) / (2.0 * h);
            (4.0 * central(0.5 * h) - central(h)) / 3.0
        } else {
            let inward = if x - h < -1.0 { 1.0 } else { -1.0 };
            let f0 = f(x);
            let one_sided = |h: f64| {
                inward * (-3.0 * f0 + 4.0 * f(x + inward * h) - f(x + 2.0 * inward * h)) / (2.0 * h)
            };
            (4.0 * one_sided(0.5 * h) - one_sided(h)) / 3.0
        }
    }
}

/// ξ of the nominal point of `dimensions` (see [`ParameterSpace::nominal_xi`](super::ParameterSpace::nominal_xi)).
pub(super) fn nominal_xi(dimensions: &[Dimension]) -> Vec<f64> {
    dimensions
        .iter()
        .map(|d| match d.kind {
            DimensionKind::Path(_) => d.xi_of(d.nominal),
            DimensionKind::Symbol | DimensionKind::Group(_) => 0.0,
        })
        .collect()
}
