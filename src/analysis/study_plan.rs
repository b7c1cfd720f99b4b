//! What a study is asked to do and what it will do, known before anything runs: the options
//! ([`StudyOptions`], command-line flags over the sidecar's `[analysis]`), their checks with the
//! flag to blame ("--grid 4 must be odd …"), and the plan they make ([`StudyPlan`]: the method
//! with `auto` resolved by [`super::auto`], the design and its sample points where they are fixed
//! beforehand, the runs of the screening, the design and the check).
//!
//! Does not: run anything (the phases do, `study.rs`), or choose the `auto` design itself
//! (`auto.rs`).

use super::auto::{
    adaptive_choice, choose as choose_auto, screened_choice, AutoChoice, AutoDesign,
    ADAPTIVE_VALUE_BUDGET,
};
use super::check::automatic_check_runs;
use super::error::StudyError;
use super::method::Method;
use super::plan::{Plan, MAX_RUNS};
use super::sparse::SparseDesign;
use crate::uq::Truncation;
use std::sync::Arc;

/// Options of a study (command-line flags override the sidecar's `[analysis]`).
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Method.
    pub method: Method,
    /// Polynomial order `k` of surrogate methods.
    pub order: usize,
    /// `tensor` or `total` truncation of surrogate methods on the tensor Gauss grid.
    pub truncation: Truncation,
    /// The design of surrogate methods: the tensor Gauss grid, a Leja sparse grid or a Sobol'
    /// regression (`auto` chooses itself).
    pub design: DesignKind,
    /// Most model runs an `auto` study above d = 4 plans (screening, design and check).
    pub max_runs: usize,
    /// Points per dimension of the true-model `scan` (odd).
    pub grid: usize,
    /// Points per dimension of the surrogate scan (odd); `None` for the default (21 for d ≤ 2, 11
    /// for d ≥ 3).
    pub scan_grid: Option<usize>,
    /// Monte Carlo runs.
    pub samples: usize,
    /// Monte Carlo seed.
    pub seed: u64,
    /// Worker threads (0: all cores).
    pub threads: usize,
    /// Exclude failing samples instead of stopping (`scan` and `monte-carlo` samples, and check
    /// runs).
    pub keep_going: bool,
    /// True-model runs of the a-posteriori check of the methods it follows
    /// ([`Method::is_checked`]; `None`: [`automatic_check_runs`] of the design; `Some(0)`: no
    /// check, said in the report as [`super::CheckSkipped::TurnedOff`]).
    pub check_runs: Option<usize>,
    /// Whether the box is split into elements where the first check fails, and into how many at
    /// most (docs/method.md §12; `legendre-scan` and `auto` only).
    pub elements: super::elements::ElementsOptions,
}

/// Where a surrogate method runs the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignKind {
    /// The (k+1)^d tensor Gauss grid (with [`StudyOptions::truncation`]).
    Tensor,
    /// Interpolation on the Leja sparse grid of total degree k (docs/high-dimension.md).
    Sparse,
    /// Least squares on total degree k at twice as many Sobol' points as terms.
    Regression,
    /// The dimension-adaptive Leja design within `--max-runs` (docs/method.md §11).
    Adaptive,
    /// Screening, then a Leja design that refines the most important parameters, within
    /// `--max-runs` (docs/method.md §10).
    Screened,
}

/// What a study will do, known before it runs.
#[derive(Clone, Debug)]
pub struct StudyPlan {
    /// The method that runs (`auto` resolved).
    pub method: Method,
    /// The design's sample points; `None` until a screening has ranked the parameters.
    pub plan: Option<Plan>,
    /// The design's name: `tensor`, `total`, `sparse`, `sparse-screened`, `regression`, `grid`,
    /// `random`, `central-differences`.
    pub design_name: &'static str,
    /// What `auto` chose and why.
    pub auto: Option<AutoChoice>,
    /// Runs of the screening (0 without).
    pub screening_runs: usize,
    /// Model runs of the design, the nominal run included.
    pub design_runs: usize,
    /// Most runs the a-posteriori check will add (0: no check).
    pub check_runs: usize,
}

impl StudyPlan {
    /// The design, its runs and the check budget of a study with `options` over `dimensions`
    /// parameters whose every run records `values_per_run` values (outputs × record times);
    /// errors, naming the flag, for plans that cannot run.
    pub fn new(
        options: &StudyOptions,
        dimensions: usize,
        values_per_run: usize,
    ) -> Result<StudyPlan, StudyError> {
        let o = options;
        let d = dimensions;
        if d == 0 {
            return Err(StudyError::BadOptions(
                "the sidecar declares no [parameters]: there is nothing to bound (use `ribbon simulate` for one nominal run)".to_string(),
            ));
        }
        if o.method == Method::Scan && (o.grid < 2 || o.grid.is_multiple_of(2)) {
            return Err(StudyError::BadOptions(format!(
                "--grid {} must be odd and ≥ 3 so that the centre of the box is on the grid",
                o.grid
            )));
        }
        if let Some(n) = o.scan_grid {
            if n < 3 || n.is_multiple_of(2) {
                return Err(StudyError::BadOptions(format!(
                    "--scan-grid {n} must be odd and ≥ 3 so that the centre of the box is on the grid"
                )));
            }
        }
        if o.method == Method::MonteCarlo && o.samples == 0 {
            return Err(StudyError::BadOptions("--samples must be ≥ 1".to_string()));
        }
        if o.method.family().is_some() && o.order == 0 {
            return Err(StudyError::BadOptions(
                "--order 0 fits a constant, whose range is a single value: every envelope would be as narrow as the runs make it. Use --order 1 or more (default 4)".to_string(),
            ));
        }
        let check_for = |runs: usize| match o.check_runs {
            Some(n) => n,
            None => automatic_check_runs(runs),
        };
        let mut auto = None;
        let (method, design) = match o.method {
            Method::Auto => {
                let choice = choose_auto(d, o.order, o.max_runs, values_per_run, check_for);
                let resolved = choice.design.clone();
                auto = Some(choice);
                (Method::LegendreScan, Some(resolved))
            }
            method => (method, None),
        };
        let sparse_ok = matches!(method, Method::LegendreScan | Method::LegendreIa);
        let (plan, design_name, screening_runs) = match (&design, o.design) {
            (Some(AutoDesign::Tensor), _) => (
                Some(Plan::new(method, d, o.order, o.truncation, o.grid, o.samples, o.seed)?),
                "tensor",
                0,
            ),
            (Some(AutoDesign::TotalDegree { order }), _) => (
                Some(Plan::Sparse(Arc::new(SparseDesign::total_degree(d, *order)?))),
                "sparse",
                0,
            ),
            (Some(AutoDesign::Screened { .. }), _) => (None, "sparse-screened", 2 * d + 1),
            (Some(AutoDesign::Adaptive { .. }), _) => (None, "sparse-adaptive", 0),
            (
                None,
                DesignKind::Sparse
                | DesignKind::Regression
                | DesignKind::Adaptive
                | DesignKind::Screened,
            ) if !sparse_ok => {
                return Err(StudyError::BadOptions(format!(
                    "--design sparse, regression, adaptive and screened fit Legendre surrogates: use them with --method legendre-scan or legendre-ia, not {}",
                    method.name()
                )))
            }
            (None, DesignKind::Adaptive) => {
                let choice = adaptive_choice(d, o.max_runs, check_for);
                let budget = choice.design_runs;
                if budget.saturating_mul(values_per_run) > ADAPTIVE_VALUE_BUDGET {
                    return Err(StudyError::BadOptions(format!(
                        "--design adaptive keeps every run's values: {budget} runs × {values_per_run} values (outputs × record times) exceed {ADAPTIVE_VALUE_BUDGET}; lower --max-runs, record less often (record_every) or use --design screened"
                    )));
                }
                auto = Some(choice);
                (None, "sparse-adaptive", 0)
            }
            (None, DesignKind::Screened) => {
                let choice = screened_choice(d, o.order, o.max_runs, check_for);
                auto = Some(choice);
                (None, "sparse-screened", 2 * d + 1)
            }
            (None, DesignKind::Sparse) => (
                Some(Plan::Sparse(Arc::new(SparseDesign::total_degree(d, o.order)?))),
                "sparse",
                0,
            ),
            (None, DesignKind::Regression) => (
                Some(Plan::Sparse(Arc::new(SparseDesign::regression(d, o.order)?))),
                "regression",
                0,
            ),
            (None, DesignKind::Tensor) => (
                Some(Plan::new(method, d, o.order, o.truncation, o.grid, o.samples, o.seed)?),
                match (method, o.truncation) {
                    (Method::Scan, _) => "grid",
                    (Method::MonteCarlo, _) => "random",
                    (Method::Taylor, _) => "central-differences",
                    (_, Truncation::Tensor) => "tensor",
                    (_, Truncation::Total) => "total",
                },
                0,
            ),
        };
        let runs = match (&plan, &auto) {
            (Some(plan), _) => plan.runs(d),
            (None, Some(choice)) => Some(choice.design_runs),
            (None, None) => None,
        }
        .filter(|r| *r <= MAX_RUNS)
        .ok_or_else(|| {
            StudyError::BadOptions(format!(
                "{} with {d} parameters needs more than {MAX_RUNS} model runs; lower --order/--grid/--samples, use --method auto, or use fewer parameters",
                method.name()
            ))
        })?;
        let check_runs = if method.is_checked() {
            check_for(runs)
        } else {
            0
        };
        Ok(StudyPlan {
            method,
            plan,
            design_name,
            auto,
            screening_runs,
            design_runs: runs + 1,
            check_runs,
        })
    }

    /// Most model runs the study makes.
    pub fn max_runs(&self) -> usize {
        self.screening_runs + self.design_runs + self.check_runs
    }
}
