//! `--method auto`: which design a study of d parameters gets, and why (docs/method.md §10).
//!
//! - d ≤ [`AUTO_TENSOR_MAX_DIM`]: the tensor Gauss grid of `legendre-scan` (the seed paper's method,
//!   numbers unchanged).
//! - Otherwise, if the total-degree-k set fits the run budget: a sparse interpolation on it (every
//!   parameter and every interaction up to total degree k).
//! - Otherwise: the dimension-adaptive design (docs/method.md §11): the runs so far decide which
//!   terms to add, until the budget is spent or every remaining term is negligible. It keeps every
//!   run's values in memory; when they would exceed [`ADAPTIVE_VALUE_BUDGET`]:
//! - screening (the star design, 2d + 1 runs), then a set that keeps total degree 2 in
//!   every parameter (all pairwise interactions; if even that does not fit, the pairs among the most
//!   important parameters only) and total degree k among the `top` most important ones, with `top`
//!   as large as the budget allows.
//!
//! Run counts are closed forms: a downward-closed set sampled on nested one-point-per-degree rules
//! has exactly one point per term.

use super::adaptive::ADAPTIVE_TOLERANCE;

/// Largest d for which `auto` uses the tensor grid.
pub const AUTO_TENSOR_MAX_DIM: usize = 4;

/// Default most model runs an `auto` study of d > [`AUTO_TENSOR_MAX_DIM`] parameters plans
/// (screening, design and check together): ~30 s of 1 s ur5 runs on two cores.
pub const DEFAULT_MAX_RUNS: usize = 3000;

/// Most stored values (runs × outputs × record times) of an adaptive design: 2 GB of `f64`. Above
/// it `auto` falls back to the screened design, which holds one block of records at a time. An
/// adaptive study holds a fit of the same size beside its values from its last stage on (the
/// bounding takes each record's coefficients from it), so its peak is about twice this.
pub const ADAPTIVE_VALUE_BUDGET: usize = 250_000_000;

/// Lowest order the screened designs keep in every parameter (all pairwise interactions).
pub const BASE_ORDER: usize = 2;

/// `C(n, k)` without overflow for the sizes used here (saturating).
pub fn binomial(n: usize, k: usize) -> usize {
    if k > n {
        return 0;
    }
    let k = k.min(n - k);
    let mut value: u128 = 1;
    for i in 0..k {
        value = value * (n - i) as u128 / (i + 1) as u128;
        if value > usize::MAX as u128 {
            return usize::MAX;
        }
    }
    value as usize
}

/// Terms of the total-degree-`order` set in `dim` dimensions: `C(dim + order, order)`.
pub fn total_degree_terms(dim: usize, order: usize) -> usize {
    binomial(dim + order, order)
}

/// What `auto` chose.
#[derive(Clone, Debug, PartialEq)]
pub enum AutoDesign {
    /// The tensor Gauss grid of `legendre-scan` at the study's order.
    Tensor,
    /// Sparse interpolation on the total-degree-`order` set of every parameter.
    TotalDegree {
        /// Total degree.
        order: usize,
    },
    /// Screening, then total degree [`BASE_ORDER`] in every parameter (pairs only among the
    /// `pairs` most important when `pairs < d`) and total degree `order` among the `top` most
    /// important.
    Screened {
        /// Total degree among the important parameters.
        order: usize,
        /// How many parameters get it.
        top: usize,
        /// How many of the most important parameters keep all their pairwise interactions.
        pairs: usize,
    },
    /// The dimension-adaptive sparse design with at most `budget` design runs (the nominal run
    /// not included).
    Adaptive {
        /// Most design runs.
        budget: usize,
    },
}

/// The choice with its run counts and the reason, for the user.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoChoice {
    /// The design.
    pub design: AutoDesign,
    /// Runs of the screening (0 when there is none).
    pub screening_runs: usize,
    /// Runs of the design (its points; the nominal run not included).
    pub design_runs: usize,
    /// Why, in one sentence.
    pub reason: String,
}

/// Terms of a screened set (see [`AutoDesign::Screened`]): the base set (constant, every parameter
/// to degree [`BASE_ORDER`] alone, the pairs among the first `pairs` parameters) plus the
/// total-degree-`order` terms among the first `top` that the base does not have.
pub fn screened_terms(dim: usize, order: usize, top: usize, pairs: usize) -> usize {
    let pairs = pairs.min(dim);
    let top = top.min(dim);
    // Constant + BASE_ORDER terms per parameter + the pairs ξ_a ξ_b (degree 2) among `pairs`.
    let base = 1 + BASE_ORDER * dim + binomial(pairs, 2);
    // The total-degree-`order` set in `top` dimensions, minus what the base already holds there:
    // the constant, BASE_ORDER per parameter, and the pairs among min(top, pairs).
    let among_top = total_degree_terms(top, order);
    let overlap =
        1 + BASE_ORDER.min(order) * top + binomial(top.min(pairs), 2) * usize::from(order >= 2);
    base + among_top.saturating_sub(overlap)
}

/// Chooses the design for `dim` parameters at `order` within `max_runs` runs in all; `check_runs`
/// is what the a-posteriori check will add for a design of n runs; `values_per_run` is how many
/// values (outputs × record times) an adaptive design stores per run.
pub fn choose(
    dim: usize,
    order: usize,
    max_runs: usize,
    values_per_run: usize,
    check_runs: impl Fn(usize) -> usize,
) -> AutoChoice {
    if dim <= AUTO_TENSOR_MAX_DIM {
        return AutoChoice {
            design: AutoDesign::Tensor,
            screening_runs: 0,
            design_runs: (order + 1).saturating_pow(dim as u32),
            reason: format!(
                "d = {dim} ≤ {AUTO_TENSOR_MAX_DIM}: the tensor Gauss grid ({}^{dim} runs) is affordable and is the reference method",
                order + 1
            ),
        };
    }
    let full = total_degree_terms(dim, order);
    if full + 1 + check_runs(full) <= max_runs {
        return AutoChoice {
            design: AutoDesign::TotalDegree { order },
            screening_runs: 0,
            design_runs: full,
            reason: format!(
                "d = {dim}: every parameter and interaction up to total degree {order} fits the budget ({full} runs ≤ --max-runs {max_runs} with the check)"
            ),
        };
    }
    let adaptive = adaptive_choice(dim, max_runs, &check_runs);
    if adaptive.design_runs.saturating_mul(values_per_run) <= ADAPTIVE_VALUE_BUDGET {
        return AutoChoice {
            reason: format!(
                "d = {dim}: total degree {order} in every parameter needs {full} runs, over --max-runs {max_runs}; so {}",
                adaptive.reason
            ),
            ..adaptive
        };
    }
    let screened = screened_choice(dim, order, max_runs, &check_runs);
    AutoChoice {
        reason: format!(
            "d = {dim}: total degree {order} in every parameter needs {full} runs, over --max-runs {max_runs}, and an adaptive design would store {} values (over {ADAPTIVE_VALUE_BUDGET}); so {}",
            adaptive.design_runs.saturating_mul(values_per_run),
            screened.reason
        ),
        ..screened
    }
}

/// The adaptive design within `max_runs` runs in all (design, nominal run and check).
pub fn adaptive_choice(
    dim: usize,
    max_runs: usize,
    check_runs: impl Fn(usize) -> usize,
) -> AutoChoice {
    // The largest design that fits with its nominal run and check (check runs grow with the design).
    let mut budget = max_runs.saturating_sub(1);
    while budget > 0 && budget + 1 + check_runs(budget) > max_runs {
        budget -= 1;
    }
    // The start (centre and one point per parameter) runs whatever the budget: say so when it
    // does not fit.
    let start = dim + 1;
    let over = (budget < start).then(|| {
        format!(
            " (--max-runs {max_runs} cannot hold it with the nominal run and the check: the start alone runs, {} runs in all)",
            start + 1 + check_runs(start)
        )
    });
    let budget = budget.max(start);
    AutoChoice {
        design: AutoDesign::Adaptive { budget },
        screening_runs: 0,
        design_runs: budget,
        reason: format!(
            "the dimension-adaptive design starts from every parameter alone ({start} runs{}) and adds the terms the runs show matter, up to {budget} runs, stopping early when every remaining term moves the outputs by less than {ADAPTIVE_TOLERANCE:e} of their spread",
            over.unwrap_or_default()
        ),
    }
}

/// The screened design within `max_runs` runs in all (screening, design, nominal run and check).
pub fn screened_choice(
    dim: usize,
    order: usize,
    max_runs: usize,
    check_runs: impl Fn(usize) -> usize,
) -> AutoChoice {
    let fits =
        |design: usize, screening: usize| design + 1 + screening + check_runs(design) <= max_runs;
    let screening = 2 * dim + 1;
    // All pairs if they fit, else as many of the most important as fit.
    let mut pairs = dim;
    while pairs > 1 && !fits(screened_terms(dim, BASE_ORDER, 0, pairs), screening) {
        pairs -= 1;
    }
    let mut top = 0;
    while top < dim && fits(screened_terms(dim, order, top + 1, pairs), screening) {
        top += 1;
    }
    let design_runs = screened_terms(dim, order, top, pairs);
    AutoChoice {
        design: AutoDesign::Screened { order, top, pairs },
        screening_runs: screening,
        design_runs,
        reason: format!(
            "screening ({screening} runs) ranks the parameters, {dim} keep total degree {BASE_ORDER} with {}, and the {top} most important get total degree {order} ({design_runs} runs)",
            if pairs == dim {
                "all pairwise interactions".to_string()
            } else {
                format!("the pairwise interactions of the {pairs} most important")
            }
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_check(_: usize) -> usize {
        0
    }

    #[test]
    fn counts_match_closed_forms() {
        assert_eq!(total_degree_terms(6, 4), 210);
        assert_eq!(total_degree_terms(60, 2), 1891);
        // With every pair and top = 0 the screened set is total degree 2.
        assert_eq!(screened_terms(60, 4, 0, 60), 1891);
        // top = d makes it total degree k.
        assert_eq!(screened_terms(6, 4, 6, 6), 210);
        assert_eq!(screened_terms(10, 4, 10, 10), total_degree_terms(10, 4));
        // Without pairs: constant + 2 per parameter.
        assert_eq!(screened_terms(60, 2, 0, 0), 121);
        assert_eq!(binomial(1, 2), 0);
        assert_eq!(binomial(5, 2), 10);
    }

    #[test]
    fn small_d_is_tensor_and_the_budget_decides_the_rest() {
        assert_eq!(choose(4, 4, 3000, 100, no_check).design, AutoDesign::Tensor);
        let six = choose(6, 4, 3000, 100, no_check);
        assert_eq!(six.design, AutoDesign::TotalDegree { order: 4 });
        assert_eq!(six.design_runs, 210);
        let sixty = choose(60, 4, 3000, 100, no_check);
        assert_eq!(sixty.design, AutoDesign::Adaptive { budget: 2999 });
        // Values that do not fit in memory: the screened design.
        let sixty = choose(60, 4, 3000, ADAPTIVE_VALUE_BUDGET, no_check);
        match sixty.design {
            AutoDesign::Screened { order, top, pairs } => {
                assert_eq!((order, pairs), (4, 60));
                assert!(top >= 4, "{top}");
            }
            other => panic!("{other:?}"),
        }
        assert!(sixty.design_runs + 1 + sixty.screening_runs <= 3000);
        // A tight budget drops pairs before anything else.
        let tight = screened_choice(60, 4, 600, no_check);
        match tight.design {
            AutoDesign::Screened { pairs, .. } => assert!(pairs < 60),
            other => panic!("{other:?}"),
        }
        assert!(tight.design_runs + 1 + tight.screening_runs <= 600);
    }
}
