//! Why a sidecar's `[parameters]` and `[bind]` were refused. Every message names the file, the key
//! (`[parameters] "link.forearm_link.mass"`), the value and what to do.

use super::expression::ExpressionError;
use crate::params::ParamError;
use crate::sidecar::SidecarError;
use thiserror::Error;

/// A refused interval parameter, binding or parameter box.
#[derive(Debug, Error)]
pub enum UncertaintyError {
    /// A `[parameters]` key or value refused by the sidecar's expansion (unknown key, misplaced
    /// `*`, a pattern matching nothing, a form that does not fit the key, `shared` over mixed
    /// units).
    #[error(transparent)]
    Sidecar(#[from] SidecarError),
    /// An interval whose numbers do not work for its path (bounds not finite or empty after
    /// `rel`/`abs`, a free symbol without explicit bounds).
    #[error("{file}: {key} = {value}: {reason}")]
    BadInterval {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The value as written (TOML).
        value: String,
        /// What is wrong and what to write instead.
        reason: String,
    },
    /// `{ rel = … }` on a path whose URDF value is 0: the interval would be empty.
    #[error("{file}: {key} = {value}: the URDF value is 0, so a relative interval is empty; give absolute bounds [lower, upper] or {{ abs = … }}")]
    RelativeOfZero {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
    },
    /// Explicit bounds that do not contain the URDF value (which is the nominal).
    #[error("{file}: {key} = [{lower}, {upper}] does not contain the URDF value {urdf_value}; the nominal of a path is its URDF value, so widen the interval (or change the URDF)")]
    UrdfValueOutside {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
        /// The value in the URDF.
        urdf_value: f64,
    },
    /// A bound that no model can have (a negative mass, …).
    #[error("{file}: {key}: a bound is impossible: {source}; narrow the interval")]
    ImpossibleBound {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The registry's reason, naming the bound's value.
        source: ParamError,
    },
    /// The same model value declared twice (in `[parameters]` and `[bind]`, or twice in one).
    #[error("{file}: {key}: {other} already declares this value; a path may appear once, in [parameters] (an interval) or in [bind] (an expression)")]
    Duplicate {
        /// The sidecar file.
        file: String,
        /// The later key.
        key: String,
        /// The earlier key.
        other: String,
    },
    /// A `[bind]` key that is not a parameter path.
    #[error("{file}: {key}: {reason}; a [bind] key is a parameter path (`ribbon params ROBOT.urdf` lists them), free symbols are declared in [parameters]")]
    BindKeyNotAPath {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The registry's reason.
        reason: String,
    },
    /// A `[bind]` value that is not a string.
    #[error("{file}: {key} = {value}: a binding is an expression in quotes, e.g. \"l1 / 2\"")]
    BindNotAString {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
    },
    /// An expression that does not parse.
    #[error("{file}: {key}: {source}")]
    BadExpression {
        /// The sidecar file.
        file: String,
        /// The key with its expression, e.g. `[bind] "link.b.com.x" = "l1 /"`.
        key: String,
        /// The parser's reason, with its column.
        source: ExpressionError,
    },
    /// An expression that uses a name not declared as a free symbol.
    #[error("{file}: {key}: unknown symbol '{name}'{hint}; declare it in [parameters] with bounds, e.g. {name} = [lower, upper]")]
    UnknownSymbol {
        /// The sidecar file.
        file: String,
        /// The key with its expression.
        key: String,
        /// The unknown name.
        name: String,
        /// "; did you mean '…'?" when one is close, then the declared symbols.
        hint: String,
    },
    /// A bound path whose expression gives an impossible value somewhere in the box.
    #[error("{file}: {key} is {value} at {point}, which is impossible: {reason}; narrow the symbols' intervals or change the expression")]
    ImpossibleBoundValue {
        /// The sidecar file.
        file: String,
        /// The key with its expression.
        key: String,
        /// The value it takes.
        value: f64,
        /// The symbol values there, e.g. `l1 = -0.1`.
        point: String,
        /// Why the value is impossible.
        reason: &'static str,
    },
    /// A bound value that is not finite or not possible at one point: a sample of a study (between
    /// the points the box check visits), or the symbol values `simulate --set` gives.
    #[error("{file}: {key} gives {value} at {point}, which is impossible: {reason}; {advice}")]
    BoundValueAt {
        /// The sidecar file.
        file: String,
        /// The `[bind]` key with its expression.
        key: String,
        /// The value it gives.
        value: f64,
        /// The symbols and their values there, e.g. `k = 0.34, m0 = 2`.
        point: String,
        /// Why the value is impossible.
        reason: &'static str,
        /// Where the point came from, and so what to do.
        advice: BoundValueSource,
    },
    /// Bound inertia values that no rigid body has at one point (a sample, or `--set` values).
    #[error("{file}: {keys} make the inertia of link '{link}' {violation_at}, while its URDF inertia is physical; {advice}")]
    BoundInertiaAt {
        /// The sidecar file.
        file: String,
        /// The `[bind]` keys with their expressions that write the link's inertia.
        keys: String,
        /// The link.
        link: String,
        /// What is violated, with the principal moments, and the symbols' values there
        /// (`… at k = 0.2`).
        violation_at: String,
        /// Where the point came from, and so what to do.
        advice: BoundValueSource,
    },
    /// The box contains inertia values that no rigid body has, while the URDF values are physical.
    #[error("{file}: [parameters]: at the {point} of the box, the inertia of link '{link}' {violation}, while its URDF inertia is physical; narrow the intervals of these parameters, or vary the link's mass and inertia together with \"link.{link}.scale\" (a scale keeps them physical)")]
    InconsistentInertia {
        /// The sidecar file.
        file: String,
        /// The link.
        link: String,
        /// `corner` or `grid point`, then the parameter values there, e.g.
        /// `corner "link.a.inertia.izz" = 0.3, l1 = 1.2`.
        point: String,
        /// What is violated, with the principal moments.
        violation: String,
    },
}

/// Where a point with an impossible bound value came from; displayed as what to do about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoundValueSource {
    /// A point a study applies (a design sample, a check run, the nominal run).
    Sample,
    /// The symbol values `simulate --set` gives.
    SetFlags,
}

impl std::fmt::Display for BoundValueSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BoundValueSource::Sample => "the box check visits the corners and a grid of the symbols, and this point lies between them: narrow the symbols' intervals or change the expression",
            BoundValueSource::SetFlags => "give the symbols other values with --set, or change the expression",
        })
    }
}
