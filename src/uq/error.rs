//! The one error type of `uq`: every way a caller's input can be refused, with the numbers that
//! explain why. Bugs inside `uq` are not represented here (they would be panics).

use crate::uq::family::Family;

/// Why a `uq` computation refused its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UqError {
    /// A quadrature rule was asked for zero points.
    #[error("a quadrature rule needs at least one point")]
    NoPoints,

    /// A quadrature rule was asked for more points than the tested range.
    #[error("{points} quadrature points requested; at most {max} are supported")]
    TooManyPoints {
        /// Points requested.
        points: usize,
        /// [`crate::uq::quadrature::MAX_POINTS`].
        max: usize,
    },

    /// A polynomial order beyond what the quadrature (order + 1 points) supports.
    #[error("polynomial order {order} is too large: at most {max} (the fit uses order + 1 Gauss points)")]
    OrderTooLarge {
        /// Order requested.
        order: usize,
        /// [`crate::uq::basis::MAX_ORDER`].
        max: usize,
    },

    /// A design's 1-D nodes along one dimension are not order + 1 distinct ascending values in
    /// [-1, 1], or they interpolate too badly to fit from.
    #[error("design nodes along dimension {dimension}: expected {expected} distinct ascending nodes in [-1, 1] that interpolate well, got {got} nodes")]
    BadNodes {
        /// The dimension.
        dimension: usize,
        /// order + 1.
        expected: usize,
        /// Nodes given.
        got: usize,
    },

    /// A design or scan with zero parameters.
    #[error("the number of parameters (dimension) must be at least 1")]
    ZeroDimension,

    /// A tensor grid (design or scan) whose point count exceeds the memory budget.
    #[error("{what}: {per_dim}^{dim} points exceed the supported maximum of {max}")]
    GridTooLarge {
        /// Which grid ("design", "scan grid").
        what: &'static str,
        /// Points per dimension.
        per_dim: usize,
        /// Number of dimensions.
        dim: usize,
        /// Largest supported point count.
        max: usize,
    },

    /// A slice had the wrong number of entries.
    #[error("{what}: expected {expected} values, got {got}")]
    WrongLength {
        /// Which argument.
        what: &'static str,
        /// Length required.
        expected: usize,
        /// Length given.
        got: usize,
    },

    /// A NaN or infinity where a finite number is required.
    #[error("{what}: entry {index} is not finite ({value})")]
    NonFinite {
        /// Which argument.
        what: &'static str,
        /// Flat index of the offending entry.
        index: usize,
        /// The entry.
        value: f64,
    },

    /// An index past the end of a design, matrix or series.
    #[error("{what}: index {index} is out of range (there are {len})")]
    IndexOutOfRange {
        /// Which collection.
        what: &'static str,
        /// Index given.
        index: usize,
        /// Number of entries.
        len: usize,
    },

    /// A physical interval with lower > upper or a non-finite end.
    #[error("interval {index}: [{lo}, {hi}] must have finite ends with lower <= upper")]
    InvalidInterval {
        /// Parameter index.
        index: usize,
        /// Lower end given.
        lo: f64,
        /// Upper end given.
        hi: f64,
    },

    /// A scan grid with an even or too small number of points per dimension.
    #[error(
        "scan grid needs an odd number >= 3 of points per dimension (got {points}), \
         so that the centre and both endpoints are on it"
    )]
    InvalidScanGrid {
        /// Points per dimension given.
        points: usize,
    },

    /// A finite-difference step outside (0, 1] in standard coordinates.
    #[error("finite-difference step must lie in (0, 1] in standard coordinates, got {step}")]
    InvalidStep {
        /// Step given.
        step: f64,
    },

    /// An operation that only makes sense for one polynomial family.
    #[error("{what} needs a {expected:?} surrogate, got a {got:?} one")]
    WrongFamily {
        /// The operation.
        what: &'static str,
        /// Family it needs.
        expected: Family,
        /// Family given.
        got: Family,
    },

    /// A surrogate whose family, dimension or order does not match the tool it is given to.
    #[error(
        "{what}: built for {expected_family:?} d = {expected_dim} k = {expected_order}, \
         got a surrogate with {got_family:?} d = {got_dim} k = {got_order}"
    )]
    SurrogateMismatch {
        /// The tool (scanner, design, ...).
        what: &'static str,
        /// Family the tool was built for.
        expected_family: Family,
        /// Dimension the tool was built for.
        expected_dim: usize,
        /// Order the tool was built for.
        expected_order: usize,
        /// Family of the surrogate.
        got_family: Family,
        /// Dimension of the surrogate.
        got_dim: usize,
        /// Order of the surrogate.
        got_order: usize,
    },

    /// A reference envelope whose upper bound lies below its lower bound.
    #[error("reference envelope at time index {index}: upper {upper} < lower {lower}")]
    InvertedReference {
        /// Time index.
        index: usize,
        /// Reference lower bound.
        lower: f64,
        /// Reference upper bound.
        upper: f64,
    },

    /// A reference envelope of zero width at every time: the relative error is undefined.
    #[error("reference envelope has zero width at every time; the relative error is undefined")]
    ZeroReferenceWidth,

    /// An empty series or point set where at least one entry is needed.
    #[error("{what} is empty")]
    Empty {
        /// Which argument.
        what: &'static str,
    },

    /// A multi-index set larger than the supported maximum.
    #[error("the multi-index set would have {terms} terms; at most {max} are supported (lower the order, the interactions or the dimensions given high degree)")]
    TooManyTerms {
        /// Terms the set would have (or reached when the build stopped).
        terms: usize,
        /// [`crate::uq::multi_index::MAX_TERMS`].
        max: usize,
    },

    /// A term given to [`crate::uq::MultiIndexSet::from_terms`] that is not a valid multi-index.
    #[error("multi-index set term {term}: {reason}")]
    InvalidMultiIndex {
        /// Position of the term (in the given list, or in canonical order for a repeated term).
        term: usize,
        /// What is wrong with it.
        reason: String,
    },

    /// A set of multi-indices that is not downward closed: a term is there without one of its
    /// predecessors.
    #[error("the multi-index set is not downward closed: it has {term} but not {missing}; add the missing term (every term needs all terms below it)")]
    NotDownwardClosed {
        /// The term whose predecessor is missing (1-based dimensions: `ξ1^2·ξ4`).
        term: String,
        /// The missing predecessor.
        missing: String,
    },

    /// A least-squares fit with fewer points than terms.
    #[error("least squares needs at least as many points as terms: {points} points for {terms} terms (use at least {terms}, better twice as many)")]
    TooFewPoints {
        /// Points given.
        points: usize,
        /// Terms of the set.
        terms: usize,
    },

    /// A least-squares matrix that is numerically rank deficient: the points do not determine
    /// every coefficient.
    #[error("the regression matrix is numerically rank deficient (column {column}: |R_jj| = {pivot:e} relative to the largest {largest:e}); use more or better-spread points, or fewer terms")]
    RankDeficient {
        /// Column (term) where the triangular factor lost rank.
        column: usize,
        /// Its diagonal entry.
        pivot: f64,
        /// Largest diagonal entry.
        largest: f64,
    },

    /// A low-discrepancy design with more dimensions or points than its generator supports.
    #[error("{what}: {got} requested, at most {max} supported")]
    DesignTooLarge {
        /// What is too large ("Sobol' dimensions", "Sobol' points").
        what: &'static str,
        /// Requested.
        got: usize,
        /// Largest supported.
        max: usize,
    },
}
