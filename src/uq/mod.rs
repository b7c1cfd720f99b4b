//! Uncertainty quantification, pure mathematics (no robots): quadrature, polynomial bases, tensor
//! and sparse designs, surrogate fitting, bounds of a surrogate's range and error measures
//! (docs/method.md §2–4, docs/high-dimension.md).
//!
//! Data flow for one study:
//! ```text
//! Design::new(family, d, k, truncation)        (k+1)^d points ξ ∈ [-1,1]^d (row-major order)
//!   └─ ParameterBox::x_from_xi_rows            physical parameter values x = c + r ξ per run
//! model runs (caller)                          values: n_points × n_outputs, run-major
//!   └─ Projector::fit                          coefficients: n_terms per output, output-major
//!        └─ Surrogate::set_from_matrix         one output
//!             ├─ sobol_indices                          main and total Sobol' indices (exact)
//!             ├─ interval_bound / chebyshev_inclusion   Outer (of the surrogate's range)
//!             ├─ BernsteinBounder::bound                Outer, sharpened by subdivision, with the
//!             │                                         attained values (its gap) beside it
//!             └─ Scanner::scan                          Inner (grid + Newton refinement)
//! TaylorStencil (2d+1 runs) ─ bounds           Approximate (linearisation)
//! envelope_error(lower, upper, lower_ref, upper_ref)   max / mean relative error over time
//! ```
//!
//! High dimension (docs/high-dimension.md), cost polynomial in d:
//! ```text
//! MultiIndexSet::total_degree / anisotropic      downward-closed Λ, sparse terms, canonical order
//!   ├─ SparseGrid::new(Λ)                        |Λ| Leja points (point 0 = centre) + LinearFit
//!   └─ Regression::new(Λ, sobol_design(…))       n ≥ |Λ| points, QR least squares + LinearFit,
//!                                                condition number, leverages, leave-one-out
//! model runs (caller)                            values: n_points × n_outputs, run-major
//!   └─ LinearFit::fit_into                       coefficients: n_terms × n_outputs, term-major
//!        └─ SparseSurrogate::set_from_fit        one output; Sobol' indices (sobol_indices), top order
//!             └─ BoxOptimizer::bound_into        inner (attained, with argmin/argmax) + outer
//! ```
//!
//! Conventions stated once: standard coordinates ξ ∈ [-1, 1]; "order" k = highest degree per
//! dimension (tensor) or in total (total-degree); Gauss rules with m = k + 1 nodes, ascending;
//! design points and dense terms numbered row-major with ξ_1 slowest ([`design`]); Chebyshev
//! coefficients carry ½ per zero index so that every surrogate is `Σ c_i Π_r φ_{i_r}(ξ_r)`.
//!
//! Limitations: the tensor path (`Design`, `Projector`, `Surrogate`, `Scanner`) is for d ≲ 6; the
//! sparse path is Legendre only; no bound here is a rigorous enclosure of the true model
//! (truncation and aliasing are estimated, not bounded); interval arithmetic uses round-to-nearest.

pub mod basis;
pub mod bernstein;
pub mod bounds;
pub mod box_optimize;
pub mod design;
pub mod element_box;
pub mod error;
pub mod error_measure;
pub mod extreme_search;
pub mod family;
pub(crate) mod householder;
pub mod interval_map;
pub mod legendre_range;
pub mod leja;
pub mod linear_fit;
pub mod multi_index;
pub mod projection;
pub mod quadrature;
pub(crate) mod refine;
pub mod regression;
pub mod scan;
pub mod sobol_design;
pub mod sobol_indices;
pub mod sparse_grid;
pub mod sparse_surrogate;
pub mod surrogate;
pub mod taylor;
pub(crate) mod tensor_contraction;

pub use basis::{legendre_min, MAX_ORDER};
pub use bernstein::{BernsteinBound, BernsteinBounder, BernsteinOptions, BERNSTEIN_MAX_ORDER};
pub use bounds::{chebyshev_inclusion, interval_bound, Bound, BoundKind, RangeMode};
pub use box_optimize::{outer_widened_to_inner, BoxBounds, BoxOptimizer};
pub use design::{Design, Truncation};
pub use element_box::ElementBox;
pub use error::UqError;
pub use error_measure::{envelope_error, EnvelopeError};
pub use extreme_search::{
    ExtremeSearch, ExtremeSearchSettings, FlipSearch, FlipTarget, Probe, SearchSide, SearchTarget,
};
pub use family::Family;
pub use interval_map::{IntervalMap, ParameterBox};
pub use leja::{lebesgue_constant, leja_points, MAX_LEJA_POINTS};
pub use linear_fit::LinearFit;
pub use multi_index::{Factor, MultiIndexSet, MAX_TERMS};
pub use projection::{CoefficientMatrix, Projector};
pub use quadrature::{gauss_chebyshev, gauss_legendre, GaussRule};
pub use regression::{LooError, Regression, MIN_GOOD_OVERSAMPLING};
pub use scan::{ScanOptions, ScanOutcome, Scanner};
pub use sobol_design::{sobol_design, SOBOL_MAX_DIM, SOBOL_MAX_POINTS};
pub use sobol_indices::{sobol_indices_monte_carlo, tensor_sobol_indices_into, SobolIndices};
pub use sparse_grid::SparseGrid;
pub use sparse_surrogate::{SparseSurrogate, SurrogateWorkspace};
pub use surrogate::{ErrorEstimate, Surrogate};
pub use taylor::{taylor_first_order, TaylorStencil};
