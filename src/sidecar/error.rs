//! Why a sidecar could not be read, or its `[parameters]` keys or values were refused before any
//! number was computed. Every message names the file, the key (`[parameters] "link.*.mass"`), and
//! what to do.

use thiserror::Error;

/// An unreadable sidecar, or a refused `[parameters]` key or value form.
#[derive(Debug, Error)]
pub enum SidecarError {
    /// The sidecar could not be read.
    #[error("cannot read '{path}': {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// Not valid TOML, or a key the sidecar format does not have.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The TOML parser's message, with line and column.
        message: String,
    },
    /// A `[parameters]` key that is neither a parameter path, a pattern nor a symbol name.
    #[error("{file}: {key}: {reason}; a key is a parameter path, a pattern with '*' segments or a free symbol name (letters, digits and '_', not starting with a digit)")]
    UnknownKey {
        /// The sidecar file.
        file: String,
        /// The key, e.g. `[parameters] "link.x.mass"`.
        key: String,
        /// The registry's reason, with its "did you mean" suggestion.
        reason: String,
    },
    /// A free symbol named like the function `sqrt`.
    #[error("{file}: {key}: 'sqrt' is the square-root function and cannot be a symbol; rename the symbol")]
    ReservedSymbol {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
    },
    /// An interval written in a form the format does not have, or with impossible numbers, or a
    /// form that does not fit the kind of key (bounds on a pattern, `rel` on a symbol, `shared` on
    /// a single path).
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
    /// A key whose `*` is misplaced.
    #[error("{file}: {key}: {reason}")]
    BadPattern {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// What is wrong, with an example.
        reason: String,
    },
    /// A pattern that matches no parameter path of the robot.
    #[error("{file}: {key}: the pattern matches no parameter of robot '{robot}'{hint}; `ribbon params ROBOT.urdf` lists every path")]
    PatternMatchesNothing {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The robot's name.
        robot: String,
        /// "; did you mean '…'?" and the shapes the pattern could have meant.
        hint: String,
    },
    /// A pattern whose every match was skipped or taken by other keys.
    #[error("{file}: {key}: the pattern matches {matched} paths but gives no dimension: {reason}; remove it or change it")]
    PatternGivesNothing {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// How many registry paths it matched.
        matched: usize,
        /// What happened to them.
        reason: String,
    },
    /// `shared = true` with `abs` over matches of different units: one offset cannot be metres
    /// and radians at once.
    #[error("{file}: {key} = {value}: a shared absolute offset is added to every match, but the matches have different units ({units}); split the pattern by unit (e.g. \"joint.*.origin.x\") or use {{ rel = …, shared = true }}")]
    SharedMixedUnits {
        /// The sidecar file.
        file: String,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
        /// Each unit with an example path.
        units: String,
    },
}
