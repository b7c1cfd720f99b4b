//! One study, in phases over the same record times:
//!
//! ```text
//! design:  lock-step simulation of the plan's samples and the nominal run, block by block
//!          ⇒ fit and bound each block ⇒ envelopes (kept) and predicted extremisers (deduplicated)
//! check:   true-model runs at a budgeted selection of the predicted extremisers
//!          ⇒ envelopes widened to contain them, misfits |true − predicted| recorded
//! sinks:   the finished envelopes, block by block
//! ```
//!
//! Memory holds one block of records of one phase's samples plus the envelopes (a few numbers per
//! output per record time) and the nominal configurations: it does not grow with samples × horizon.
//! Every envelope contains every model run the study made, in every phase.

use super::adaptive_study::AdaptiveReport;
use super::auto::{
    adaptive_choice, choose as choose_auto, screened_choice, AutoChoice, AutoDesign,
    ADAPTIVE_VALUE_BUDGET,
};
use super::bounds::{Bounder, EnvelopePoint};
use super::check::{
    automatic_check_runs, output_resolution, trust_verdict, CheckCandidates, CheckPlan, Side,
    TrustVerdict, TRUST_RELATIVE_MISFIT,
};
use super::engine::{BlockOutcome, LockStep, RecordSource, SampleFailure};
use super::lyapunov::{estimate_lyapunov, LyapunovEstimate};
use super::plan::{Plan, MAX_RUNS};
pub use super::schedule::{RecordSchedule, BLOCK_VALUE_BUDGET, MAX_BLOCK_RECORDS};
use super::screening::Screening;
use super::sobol_indices::{has_sobol_indices, SobolBlock, SobolSeries};
use super::sparse::SparseDesign;
use super::stages::{PendingStage, SimulateHere, StageCursor, StageRecords};
use super::Method;
use crate::effects::ContactStats;
use crate::model::Model;
use crate::scene::{Output, Scene};
use crate::simulate::{hht_settings, RobotSystem};
use crate::uncertainty::ParameterSpace;
use crate::uq::{Truncation, UqError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;
use thiserror::Error;

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
    /// True-model runs of the a-posteriori check for methods that locate their extremes (`None`:
    /// [`automatic_check_runs`] of the design; `Some(0)`: no check).
    pub check_runs: Option<usize>,
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

/// Why a study could not run or finish.
#[derive(Debug, Error)]
pub enum StudyError {
    /// Options that cannot work.
    #[error("{0}")]
    BadOptions(String),
    /// The interval mathematics refused (e.g. an order beyond its range).
    #[error("interval mathematics: {0}")]
    Uq(#[from] UqError),
    /// A sample failed and the study cannot go on.
    #[error("{} failed at t = {} s, at parameter values {:?} (ξ = {:?}): {}. {hint}",
        .run, crate::text::message_time(.failure.time_s), .failure.values, .failure.xi, .failure.message)]
    SampleFailed {
        /// Which run: "the nominal run", "sample 3 of 25", "check run 2 of 8".
        run: String,
        /// The failure.
        failure: Box<SampleFailure>,
        /// What to do.
        hint: &'static str,
    },
    /// A sink (MCAP, …) failed.
    #[error(transparent)]
    Sink(ForeignError),
    /// The recorded values of a phase could not be read (a shard's record block).
    #[error(transparent)]
    Records(ForeignError),
    /// Not a failure: the study needs the records of a stage that has not run yet (`plan` and
    /// `merge` write its plan; `analyze` never stops here). See docs/distributed.md §7.
    #[error("the study needs the records of stage {} ({} phase) before it can go on", .0.stage, .0.phase)]
    StageNeeded(Box<PendingStage>),
    /// The worker threads could not be started.
    #[error("cannot start {threads} worker threads: {message}")]
    Threads {
        /// Requested count.
        threads: usize,
        /// The reason.
        message: String,
    },
}

/// The error of a part a study calls but does not define — a record source that reads files
/// written elsewhere ([`StudyError::Records`]), a sink that writes outputs
/// ([`StudyError::Sink`]) — kept whole, so that whoever knows its type (the crate's error, which
/// decides exit codes) can still tell what it was ([`ForeignError::downcast_ref`]). Its message
/// is the part's own.
#[derive(Debug)]
pub struct ForeignError(Box<dyn std::error::Error + Send + Sync + 'static>);

impl ForeignError {
    /// Wraps a part's error.
    pub fn new(error: impl std::error::Error + Send + Sync + 'static) -> ForeignError {
        ForeignError(Box::new(error))
    }

    /// The part's error, when it is an `E`.
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        self.0.downcast_ref::<E>()
    }
}

impl std::fmt::Display for ForeignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for ForeignError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

/// One block of envelopes, as handed to the sink.
pub struct BlockView<'a> {
    /// Index of the block's first record.
    pub first_record: usize,
    /// Record times of the block, s.
    pub times: &'a [f64],
    /// `records × outputs` envelope points, record-major.
    pub points: &'a [EnvelopePoint],
    /// The nominal run's values, `records × outputs`.
    pub nominal: &'a [f64],
    /// The nominal run's configuration per record (`records × nq`).
    pub nominal_positions: &'a [f64],
    /// Surrogate methods: the block's Sobol' indices.
    pub sobol: Option<SobolBlock<'a>>,
}

/// Progress after a block.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// The phase: `design` or `check`.
    pub phase: &'static str,
    /// Records done in this phase.
    pub records_done: usize,
    /// Records in all.
    pub records_total: usize,
    /// Model runs of this phase.
    pub runs: usize,
    /// Seconds since the start of the study.
    pub elapsed_s: f64,
}

/// The envelopes of a whole study (kept: a few numbers per output per record time).
#[derive(Clone, Debug)]
pub struct Envelope {
    /// The outputs.
    pub outputs: Vec<Output>,
    /// Record times, s.
    pub times: Vec<f64>,
    /// `lower[o][k]`.
    pub lower: Vec<Vec<f64>>,
    /// `upper[o][k]`.
    pub upper: Vec<Vec<f64>>,
    /// `nominal[o][k]`.
    pub nominal: Vec<Vec<f64>>,
    /// `error[o][k]`, where the method has an estimate: the larger of the method's own estimate
    /// and the misfit the check observed at that output and time.
    pub error: Option<Vec<Vec<f64>>>,
    /// `outer_lower[o][k]`, `outer_upper[o][k]`: an outer bound of the surrogate beside the inner
    /// one, where the method has both (sparse designs); the gap between them is what the inner
    /// search might have missed on the surrogate.
    pub outer: Option<OuterBounds>,
    /// `runs_lower[o][k]`, `runs_upper[o][k]`: the smallest and largest value of every true-model
    /// run the study made (design, nominal, screening and check runs; excluded samples left out).
    /// The envelope contains them; where a surrogate is not trusted, they say how much of its
    /// envelope true runs actually reached.
    pub runs_lower: Vec<Vec<f64>>,
    /// See [`Envelope::runs_lower`].
    pub runs_upper: Vec<Vec<f64>>,
}

/// `(outer_lower[o][k], outer_upper[o][k])`.
pub type OuterBounds = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// What the a-posteriori check did.
#[derive(Clone, Debug)]
pub struct CheckReport {
    /// Runs made.
    pub runs: usize,
    /// Distinct predicted extremisers there were to choose from.
    pub unique_candidates: usize,
    /// The points run, in standard coordinates (`runs × d`, row-major).
    pub points: Vec<f64>,
    /// Per output: the largest `|true − predicted|` over its checked predictions, in its unit.
    pub max_misfit: Vec<f64>,
    /// Per output: `max_misfit` over the output's largest envelope width (0 where the width is 0).
    pub relative_misfit: Vec<f64>,
    /// Outputs whose relative misfit exceeds [`TRUST_RELATIVE_MISFIT`] and whose misfit exceeds
    /// [`super::check::TRUST_RESOLUTION_FACTOR`] times their resolution: their surrogate cannot be trusted (the
    /// envelope still contains every true run).
    pub untrusted_outputs: Vec<usize>,
    /// Per output: how finely the true model resolves it ([`output_resolution`]; `None`: no floor).
    pub resolution: Vec<Option<f64>>,
    /// Outputs whose relative misfit exceeds [`TRUST_RELATIVE_MISFIT`] but whose misfit is within
    /// their resolution: envelopes at the integrator's noise level (a planar robot's out-of-plane
    /// coordinate), not a failed surrogate.
    pub below_resolution_outputs: Vec<usize>,
    /// Whether the check ran over the whole horizon (false when interrupted).
    pub complete: bool,
    /// Every checked prediction: `(output, record, true value)` at the record time where the
    /// surrogate put an extreme (for plots: true runs on the envelope's edge).
    pub checked: Vec<(usize, usize, f64)>,
    /// The first record at which a check of an untrusted output missed by more than
    /// [`TRUST_RELATIVE_MISFIT`] of the output's width (`None` when every output is trusted).
    pub first_miss_record: Option<usize>,
    /// Checks made at records before [`CheckReport::first_miss_record`] (all of them when it is
    /// `None`): each agreed within the tolerance or the output's resolution.
    pub checks_before_first_miss: usize,
    /// The last record `R` at which the check, comparing only the misfits and widths of records
    /// `0..=R`, trusts every output — what the check would say of a run that ended there (the last
    /// record exactly when every output is trusted; `None` when no prefix passes).
    pub passes_until_record: Option<usize>,
}

/// What a study did.
#[derive(Clone, Debug)]
pub struct StudyReport {
    /// The envelopes.
    pub envelope: Envelope,
    /// Model runs, the nominal one and the check runs included.
    pub runs: usize,
    /// Samples left out with `keep_going`.
    pub excluded: Vec<SampleFailure>,
    /// Whether the study stopped early (interrupted): the envelopes cover the times done.
    pub partial: bool,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
    /// Seconds spent fitting and bounding.
    pub bound_seconds: f64,
    /// Newton iterations of all samples.
    pub newton_iterations: u64,
    /// Steps of all samples.
    pub steps: u64,
    /// Worker threads used.
    pub threads: usize,
    /// Record times per block of the design phase.
    pub block_records: usize,
    /// The a-posteriori check, when the method has one.
    pub check: Option<CheckReport>,
    /// The method that ran (`auto` resolved).
    pub method: Method,
    /// The design's name (see [`StudyPlan::design_name`]).
    pub design: &'static str,
    /// What `auto` chose and why.
    pub auto: Option<AutoChoice>,
    /// The screening, when there was one.
    pub screening: Option<Screening>,
    /// The dimensions from the most important, when a screening ranked them.
    pub ranking: Option<Vec<usize>>,
    /// Sparse designs: per dimension, the largest total Sobol' index over outputs and record times
    /// of the surrogates, with the output and record where it occurs.
    pub total_index_max: Option<Vec<(f64, usize, usize)>>,
    /// Surrogate methods: the main and total Sobol' indices of every output at every record time
    /// (docs/sobol-indices.md).
    pub sobol: Option<SobolSeries>,
    /// Sparse designs: the condition number of the design's basis matrix.
    pub condition_number: Option<f64>,
    /// The adaptive design's rounds, when it ran.
    pub adaptive: Option<AdaptiveReport>,
    /// The largest Lyapunov exponent of the nominal motion (two extra runs: the nominal
    /// parameters and a shadow with a perturbed state; `None` when either failed or the study was
    /// interrupted before).
    pub lyapunov: Option<LyapunovEstimate>,
    /// The contact counters of all runs, summed (the deepest penetration: the largest;
    /// docs/contacts.md §4); `None` when the scene declares no contacts.
    pub contacts: Option<ContactStats>,
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
    /// Most model runs the study makes.
    pub fn max_runs(&self) -> usize {
        self.screening_runs + self.design_runs + self.check_runs
    }
}

/// What [`Study::simulate_design_part`] calls after each block: `(first record, records, the
/// part's recorded values)`.
pub type PartSink<'s> = dyn FnMut(usize, usize, &dyn RecordSource) -> Result<(), ForeignError> + 's;

/// What simulating a part of a design did ([`Study::simulate_design_part`]).
#[derive(Clone, Debug)]
pub struct DesignPart {
    /// Whether every record time was simulated (false when interrupted).
    pub complete: bool,
    /// Samples left out under `--keep-going`, by their index in the whole design (the nominal
    /// run, which may not fail, never appears).
    pub failures: Vec<SampleFailure>,
    /// Newton iterations of the part's runs.
    pub newton_iterations: u64,
    /// Steps of the part's runs.
    pub steps: u64,
    /// Contact counters of the part's runs, summed; `None` when the scene declares no contacts.
    pub contacts: Option<ContactStats>,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
}

/// A study ready to run.
pub struct Study<'a> {
    /// The nominal model (scene gravity applied).
    pub model: Model,
    /// The scene.
    pub scene: &'a Scene,
    /// The interval parameters.
    pub space: &'a ParameterSpace,
    /// The options.
    pub options: StudyOptions,
}

impl<'a> Study<'a> {
    /// The study of `space` on `scene` with a copy of the nominal `model` (scene gravity applied):
    /// the one way every command (`plan`, `run`, `merge`, `analyze`, `compare`) builds it.
    pub fn new(
        model: &Model,
        scene: &'a Scene,
        space: &'a ParameterSpace,
        options: StudyOptions,
    ) -> Self {
        Study {
            model: model.clone(),
            scene,
            space,
            options,
        }
    }
}

/// What every phase of one study run shares, lent to [`Study::run_stage`], [`Study::run_phase`]
/// and [`Study::run_source`] (and the phases built on them) instead of five loose arguments.
pub(super) struct PhaseContext<'a> {
    /// The study's worker threads.
    pub threads: &'a rayon::ThreadPool,
    /// Set on SIGINT/SIGTERM: a phase stops before its next block (and the lock-step engine before
    /// its next step).
    pub interrupt: &'a AtomicBool,
    /// When the study started (progress reports the elapsed seconds).
    pub started: Instant,
    /// The report the phases add to (runs' counters, timings, exclusions, `partial`).
    pub report: &'a mut StudyReport,
    /// Called after every block with how far the phase is.
    pub progress: &'a mut dyn FnMut(Progress),
}

impl<'a> PhaseContext<'a> {
    /// The context of a run from its parts (the fields, in order).
    pub fn new(
        threads: &'a rayon::ThreadPool,
        interrupt: &'a AtomicBool,
        started: Instant,
        report: &'a mut StudyReport,
        progress: &'a mut dyn FnMut(Progress),
    ) -> Self {
        PhaseContext {
            threads,
            interrupt,
            started,
            report,
            progress,
        }
    }
}

/// What a phase does with each block of records: `(block, report)`.
pub(super) type OnBlock<'a> =
    dyn FnMut(&PhaseBlock, &mut StudyReport) -> Result<(), StudyError> + 'a;

/// Which runs of a phase may be left out when they fail, and what to tell the user.
#[derive(Clone, Copy)]
pub(super) struct FailurePolicy {
    /// Samples may be excluded (`keep_going` and a method that tolerates it).
    can_exclude: bool,
    /// The hint when a sample's failure stops the study.
    hint: &'static str,
    /// How messages name the runs of this phase ("sample", "check run").
    noun: &'static str,
}

/// Per record of one block of one phase: the samples' values.
pub(super) struct PhaseBlock<'b> {
    /// The block's first record.
    pub(super) first: usize,
    /// Records in the block.
    pub(super) count: usize,
    /// The phase's samples.
    pub(super) lockstep: &'b dyn RecordSource,
}

impl PhaseBlock<'_> {
    /// Record `r` of the block for sample `i` (`dim outputs`).
    pub(super) fn record(&self, i: usize, r: usize) -> &[f64] {
        self.lockstep.record(i, r)
    }
}

/// The envelopes under construction, and the hull of every true run.
pub(super) struct Accumulator {
    n_outputs: usize,
    /// Record times done, s.
    pub(super) times: Vec<f64>,
    /// Record-major `records × outputs`.
    points: Vec<EnvelopePoint>,
    /// The nominal run's values, record-major `records × outputs`.
    pub(super) nominal: Vec<f64>,
    /// The nominal run's configuration per record (`records × nq`).
    pub(super) nominal_positions: Vec<f64>,
    /// The hull of every true run, record-major `records × outputs` (`(lowest, highest)`;
    /// `(+∞, −∞)` before any run).
    runs: Vec<(f64, f64)>,
}

impl Accumulator {
    /// Widens the envelopes and the hull of true runs at `record` to contain `values`, a true
    /// run's outputs (or the lowest or highest of several).
    fn widen(&mut self, record: usize, values: &[f64]) {
        let row = &mut self.points[record * self.n_outputs..(record + 1) * self.n_outputs];
        for (point, &value) in row.iter_mut().zip(values) {
            point.lower = point.lower.min(value);
            point.upper = point.upper.max(value);
        }
        self.widen_runs(record, values);
    }

    /// Widens the hull of true runs at `record` to contain `values` (the envelopes already do).
    fn widen_runs(&mut self, record: usize, values: &[f64]) {
        let needed = (record + 1) * self.n_outputs;
        if self.runs.len() < needed {
            self.runs.resize(needed, (f64::INFINITY, f64::NEG_INFINITY));
        }
        let row = &mut self.runs[record * self.n_outputs..needed];
        for (hull, &value) in row.iter_mut().zip(values) {
            *hull = (hull.0.min(value), hull.1.max(value));
        }
    }
}

/// The design's bounding: fits and bounds blocks of records into the accumulator, collecting the
/// predicted extremes for the check and the surrogates' Sobol' indices.
struct DesignBounding<'b> {
    bounder: &'b Bounder,
    threads: &'b rayon::ThreadPool,
    n_outputs: usize,
    locates_extremes: bool,
    candidates: CheckCandidates,
    /// The surrogates' Sobol' indices, record after record.
    sobol: SobolSeries,
    /// Min/max of the screening runs per record and output (empty without screening).
    screen_hull: &'b [EnvelopePoint],
}

impl DesignBounding<'_> {
    /// Bounds records `first..first + count` from the design's `values(r)` (row-major `samples ×
    /// outputs`); `accumulator` already holds those records' times and nominal values.
    fn absorb(
        &mut self,
        first: usize,
        count: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        accumulator: &mut Accumulator,
    ) -> Result<(), StudyError> {
        let n_outputs = self.n_outputs;
        let bounded =
            self.bounder
                .bound_records(count, n_outputs, values, excluded, self.threads)?;
        accumulator.points.extend_from_slice(&bounded.points);
        self.sobol.extend(&bounded);
        for r in 0..count {
            let record = first + r;
            // The design's runs (the bounds already contain them) into the hull of true runs.
            let record_values = values(r);
            for (sample, run) in record_values.chunks_exact(n_outputs.max(1)).enumerate() {
                if !excluded(sample) {
                    accumulator.widen_runs(record, run);
                }
            }
            // The nominal run is a true response inside the box: the envelope contains it.
            let nominal =
                accumulator.nominal[record * n_outputs..(record + 1) * n_outputs].to_vec();
            accumulator.widen(record, &nominal);
            // The screening's runs are true responses too.
            if let Some(hull) = self
                .screen_hull
                .get(record * n_outputs..(record + 1) * n_outputs)
            {
                let (lower, upper): (Vec<f64>, Vec<f64>) =
                    hull.iter().map(|p| (p.lower, p.upper)).unzip();
                accumulator.widen(record, &lower);
                accumulator.widen(record, &upper);
            }
            if !self.locates_extremes {
                continue;
            }
            for o in 0..n_outputs {
                if let Some(extremes) = &bounded.extremes[r * n_outputs + o] {
                    let point = &accumulator.points[record * n_outputs + o];
                    let width = point.upper - point.lower;
                    self.candidates.add(
                        record,
                        o,
                        Side::Lower,
                        &extremes.argmin,
                        extremes.at_min,
                        width,
                    );
                    self.candidates.add(
                        record,
                        o,
                        Side::Upper,
                        &extremes.argmax,
                        extremes.at_max,
                        width,
                    );
                }
            }
        }
        Ok(())
    }
}

impl Study<'_> {
    /// The design, its runs and the check budget; errors for plans that cannot run.
    pub fn plan(&self) -> Result<StudyPlan, StudyError> {
        let o = &self.options;
        let d = self.space.len();
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
        let values_per_run = self.scene.outputs.len() * n_records(self.scene);
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
        let check_runs = if method.locates_extremes() {
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

    /// Simulates the design's samples `range` (indices into [`Study::design_points`]) and, with
    /// `with_nominal`, the nominal run after them, block by block over the horizon under the
    /// design's failure policy (the same as [`Study::run_stages`]); `on_block(first, count,
    /// records)` after each block. This is one shard of a distributed study (`ribbon run`).
    #[allow(clippy::too_many_arguments)]
    pub fn simulate_design_part(
        &self,
        study_plan: &StudyPlan,
        points: &[f64],
        range: std::ops::Range<usize>,
        with_nominal: bool,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        on_block: &mut PartSink<'_>,
    ) -> Result<DesignPart, StudyError> {
        let started = Instant::now();
        let d = self.space.len().max(1);
        let threads = self.thread_pool()?;
        let mut report = self.empty_report(&threads);
        let nominal_xi = self.space.nominal_xi();
        let design_samples = points.len() / d;
        let part = points.get(range.start * d..range.end * d).ok_or_else(|| {
            StudyError::BadOptions(format!(
                "internal: samples {}..{} are outside the design's {design_samples}",
                range.start, range.end
            ))
        })?;
        let mut lockstep = self.lockstep(part, with_nominal.then_some(nominal_xi.as_slice()));
        let offset = |mut failure: SampleFailure, nominal: Option<usize>| {
            if Some(failure.index) != nominal {
                failure.index += range.start;
            }
            failure
        };
        let nominal = lockstep.nominal_index();
        let result = self.run_source(
            &mut PhaseContext::new(&threads, interrupt, started, &mut report, progress),
            "design",
            &mut lockstep,
            self.design_failure_policy(study_plan.method),
            &mut |block, _| {
                on_block(block.first, block.count, block.lockstep).map_err(StudyError::Sink)
            },
        );
        let complete = match result {
            Ok(complete) => complete,
            Err(StudyError::SampleFailed { run, failure, hint }) => {
                // Name the sample by its index in the whole design, not in this part.
                let run = if Some(failure.index) == nominal {
                    run
                } else {
                    format!(
                        "sample {} of {design_samples}",
                        failure.index + range.start + 1
                    )
                };
                return Err(StudyError::SampleFailed {
                    run,
                    failure: Box::new(offset(*failure, nominal)),
                    hint,
                });
            }
            Err(other) => return Err(other),
        };
        Ok(DesignPart {
            complete,
            failures: report
                .excluded
                .into_iter()
                .map(|f| offset(f, nominal))
                .collect(),
            newton_iterations: report.newton_iterations,
            steps: report.steps,
            contacts: report.contacts,
            simulate_seconds: report.simulate_seconds,
        })
    }

    /// The worker threads of `options.threads`.
    pub fn thread_pool(&self) -> Result<rayon::ThreadPool, StudyError> {
        let threads = self.options.threads;
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| StudyError::Threads {
                threads,
                message: e.to_string(),
            })
    }

    /// A report with no runs and empty envelopes over the scene's outputs.
    pub(super) fn empty_report(&self, threads: &rayon::ThreadPool) -> StudyReport {
        StudyReport {
            envelope: Envelope {
                outputs: self.scene.outputs.clone(),
                times: Vec::new(),
                lower: Vec::new(),
                upper: Vec::new(),
                nominal: Vec::new(),
                error: None,
                outer: None,
                runs_lower: Vec::new(),
                runs_upper: Vec::new(),
            },
            runs: 0,
            excluded: Vec::new(),
            partial: false,
            simulate_seconds: 0.0,
            bound_seconds: 0.0,
            newton_iterations: 0,
            steps: 0,
            threads: threads.current_num_threads(),
            block_records: 0,
            check: None,
            lyapunov: None,
            contacts: None,
            method: self.options.method,
            design: "",
            auto: None,
            screening: None,
            ranking: None,
            total_index_max: None,
            sobol: None,
            condition_number: None,
            adaptive: None,
        }
    }

    /// The failure policy of the design's runs: only `scan` and `monte-carlo` may leave a failing
    /// sample out (a fit needs every design point).
    pub(super) fn design_failure_policy(&self, method: Method) -> FailurePolicy {
        let keep_going = self.options.keep_going;
        let can_exclude = keep_going && matches!(method, Method::Scan | Method::MonteCarlo);
        FailurePolicy {
            can_exclude,
            hint: if keep_going && !can_exclude {
                "--keep-going cannot help this method: its fit needs every design point; use --method scan or monte-carlo, or narrow the box"
            } else {
                "Use --keep-going to exclude failing samples (scan and monte-carlo), or narrow the box"
            },
            noun: "sample",
        }
    }

    /// The failure policy of a phase of true-model runs that any run may be left out of (with
    /// `--keep-going`): `noun` names its runs in messages.
    pub(super) fn exclusion_policy(&self, noun: &'static str) -> FailurePolicy {
        FailurePolicy {
            can_exclude: self.options.keep_going,
            hint: "The box contains a point where the model cannot be simulated; use --keep-going to exclude it (it is listed in the summary), or narrow the box",
            noun,
        }
    }

    /// Runs the study: `progress` after each block of each phase, then `sink` with each block of the
    /// finished envelopes. Stops at the next step when `interrupt` is set (the report is then
    /// `partial` and covers the records finished before).
    pub fn run(
        &self,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let study_plan = self.plan()?;
        self.run_planned(study_plan, interrupt, progress, sink)
    }

    /// [`Study::run`] with the plan already made (the caller printed it; planning a regression
    /// design costs seconds at large d, so it is not done twice).
    pub fn run_planned(
        &self,
        study_plan: StudyPlan,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        self.run_stages(study_plan, &mut SimulateHere, interrupt, progress, sink)
    }

    /// The design's sample points (row-major `runs × d`, the nominal run not included) when the
    /// plan fixes them before any run; `None` for designs that depend on runs (screened,
    /// adaptive).
    pub fn design_points(&self, study_plan: &StudyPlan) -> Option<Vec<f64>> {
        study_plan
            .plan
            .as_ref()
            .map(|plan| plan.points(self.space.len()))
    }

    /// The study's phases — screening or adaptive rounds where the design has them, design, fit
    /// and bound, the a-posteriori check, the chaos estimate, the sinks — with the records of
    /// each *stage* (a phase of runs planned before it runs: the design, the screening, each
    /// adaptive round; docs/distributed.md §7) from `stages`: simulated here
    /// ([`SimulateHere`]: `analyze`) or read from the record blocks of shards that simulated
    /// them elsewhere (`merge`). Either way the values reach the fits in the same order, so the
    /// decisions between stages and the results are the same bit for bit. A stage whose records
    /// do not exist yet ends the study with [`StudyError::StageNeeded`] naming its points.
    pub fn run_stages(
        &self,
        study_plan: StudyPlan,
        stages: &mut dyn StageRecords,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let started = Instant::now();
        let o = &self.options;
        let method = study_plan.method;
        let d = self.space.len();
        let threads = self.thread_pool()?;
        let scene = self.scene;
        let n_outputs = scene.outputs.len();
        let schedule = RecordSchedule::of(scene);
        let n_records = schedule.len();
        let design_runs = study_plan.design_runs;
        let mut report = StudyReport {
            runs: 0,
            block_records: schedule.block_records(design_runs, n_outputs),
            method,
            design: study_plan.design_name,
            auto: study_plan.auto.clone(),
            ..self.empty_report(&threads)
        };
        let mut accumulator = Accumulator {
            n_outputs,
            times: Vec::with_capacity(n_records),
            points: Vec::with_capacity(n_records * n_outputs),
            nominal: Vec::with_capacity(n_records * n_outputs),
            nominal_positions: Vec::new(),
            runs: Vec::with_capacity(n_records * n_outputs),
        };

        // Screening (auto above the budget of a full total-degree set): the star design ranks the
        // parameters, and the design is built from the ranking. The adaptive design runs its
        // rounds here and keeps their values; the design phase then bounds from them.
        let mut screen_hull: Vec<EnvelopePoint> = Vec::new();
        let nominal_xi = self.space.nominal_xi();
        let mut adapted = None;
        let mut stages = StageCursor::new(stages, d);
        let plan = match study_plan.plan {
            Some(plan) => {
                report.runs += design_runs;
                plan
            }
            None => {
                let Some(choice) = &study_plan.auto else {
                    return Err(StudyError::BadOptions(
                        "internal: a plan without design or auto choice".to_string(),
                    ));
                };
                if let AutoDesign::Adaptive { budget } = choice.design {
                    let Some((grid, outcome)) = self.adapt(
                        &mut stages,
                        budget,
                        &nominal_xi,
                        &mut PhaseContext::new(&threads, interrupt, started, &mut report, progress),
                        &mut accumulator,
                    )?
                    else {
                        return self.finish(report, accumulator, sink);
                    };
                    let outcome = adapted.insert(outcome);
                    report.adaptive = Some(outcome.report.clone());
                    report.block_records = schedule.block_records(grid.n_points() + 1, n_outputs);
                    Plan::Sparse(Arc::new(SparseDesign::Grid(grid)))
                } else {
                    let (screening, complete) = self.screen(
                        &mut stages,
                        &mut PhaseContext::new(&threads, interrupt, started, &mut report, progress),
                        &mut screen_hull,
                    )?;
                    let ranking = screening.ranking();
                    report.screening = Some(screening);
                    report.ranking = Some(ranking.clone());
                    if !complete {
                        return self.finish(report, accumulator, sink);
                    }
                    report.runs += design_runs;
                    Plan::Sparse(Arc::new(SparseDesign::screened(
                        d,
                        &choice.design,
                        &ranking,
                    )?))
                }
            }
        };
        if let Plan::Sparse(design) = &plan {
            report.condition_number = Some(design.condition_number());
        }
        let bounder = Bounder::new(method, &plan, d, o.order, o.scan_grid)?;
        let candidates = CheckCandidates::new(d);
        let locates_extremes = study_plan.check_runs > 0;
        let mut bounding = DesignBounding {
            bounder: &bounder,
            threads: &threads,
            n_outputs,
            locates_extremes,
            candidates,
            sobol: SobolSeries::new(d, n_outputs),
            screen_hull: &screen_hull,
        };

        // Design phase: bound from the adaptive rounds' values, or run the design.
        let design_complete = match &adapted {
            Some(outcome) => {
                let t_bound = Instant::now();
                let mut first = 0;
                let block = report.block_records.max(1);
                while first < n_records {
                    let count = block.min(n_records - first);
                    let values = |r: usize| outcome.record(first + r, n_outputs);
                    bounding.absorb(first, count, &values, &|_| false, &mut accumulator)?;
                    first += count;
                }
                report.bound_seconds += t_bound.elapsed().as_secs_f64();
                if !outcome.complete {
                    report.partial = true;
                }
                outcome.complete
            }
            None => {
                let points = plan.points(d);
                let mut simulated;
                let mut recorded = stages.source("design", &points, true)?;
                let source: &mut dyn RecordSource = match recorded.as_deref_mut() {
                    Some(source) => source,
                    None => {
                        simulated = self.lockstep(&points, Some(&nominal_xi));
                        &mut simulated
                    }
                };
                let Some(nominal_index) = source.nominal_index() else {
                    return Err(StudyError::BadOptions(
                        "internal: the design's records hold no nominal run".to_string(),
                    ));
                };
                // The design's samples in plan order; the nominal run is named, not positional.
                let plan_samples: Vec<usize> =
                    (0..source.len()).filter(|&i| i != nominal_index).collect();
                self.run_source(
                    &mut PhaseContext::new(&threads, interrupt, started, &mut report, progress),
                    "design",
                    source,
                    self.design_failure_policy(method),
                    &mut |block, report| {
                        let t_bound = Instant::now();
                        let lockstep = block.lockstep;
                        for r in 0..block.count {
                            accumulator.times.push(schedule.time(block.first + r));
                            accumulator
                                .nominal
                                .extend_from_slice(block.record(nominal_index, r));
                            accumulator
                                .nominal_positions
                                .extend_from_slice(lockstep.nominal_positions(r));
                        }
                        let values = |r: usize| -> Vec<f64> {
                            let mut row = Vec::with_capacity(plan_samples.len() * n_outputs);
                            for &i in &plan_samples {
                                row.extend_from_slice(lockstep.record(i, r));
                            }
                            row
                        };
                        let excluded = |i: usize| lockstep.failed(i);
                        bounding.absorb(
                            block.first,
                            block.count,
                            &values,
                            &excluded,
                            &mut accumulator,
                        )?;
                        report.bound_seconds += t_bound.elapsed().as_secs_f64();
                        Ok(())
                    },
                )?
            }
        };
        if matches!(plan, Plan::Sparse(_)) {
            report.total_index_max = Some(bounding.sobol.total_index_max());
        }
        if has_sobol_indices(method) {
            report.sobol = Some(bounding.sobol);
        }
        let candidates = bounding.candidates;

        // The a-posteriori check: true runs where the surrogates put their extremes. An adaptive
        // design that stopped early is checked in proportion to the runs it made.
        let check_budget = match (&report.adaptive, o.check_runs) {
            (Some(adaptive), None) => automatic_check_runs(adaptive.runs),
            _ => study_plan.check_runs,
        };
        if design_complete && locates_extremes {
            let check_plan = candidates.select(check_budget);
            report.check = Some(self.check(
                &check_plan,
                &mut PhaseContext::new(&threads, interrupt, started, &mut report, progress),
                &mut accumulator,
            )?);
        }
        // Is the nominal motion chaotic? Two runs, after the design so that an interruption
        // still saves the envelopes.
        if !report.partial {
            let mut nominal_model = self.model.clone();
            self.space.apply(&mut nominal_model, &nominal_xi);
            let t_lyapunov = Instant::now();
            report.lyapunov = estimate_lyapunov(&nominal_model, scene, interrupt);
            report.simulate_seconds += t_lyapunov.elapsed().as_secs_f64();
        }
        self.finish(report, accumulator, sink)
    }

    /// The screening phase: the star design (`±e_j` and the centre, 2d + 1 runs). Returns the
    /// screening and whether it ran to the end; `hull` receives the runs' min/max per record and
    /// output (record-major), since they are true responses the envelopes must contain.
    fn screen(
        &self,
        stages: &mut StageCursor,
        context: &mut PhaseContext<'_>,
        hull: &mut Vec<EnvelopePoint>,
    ) -> Result<(Screening, bool), StudyError> {
        let d = self.space.len();
        let n_outputs = self.scene.outputs.len();
        let mut points = Screening::points(d);
        points.extend(std::iter::repeat_n(0.0, d));
        let mut screening = Screening::new(d, n_outputs);
        let policy = FailurePolicy {
            can_exclude: false,
            hint: "Screening runs the centres of the box's faces; a failure there means the box contains points the model cannot simulate: narrow the box",
            noun: "screening run",
        };
        context.report.runs += 2 * d + 1;
        let complete = self.run_stage(
            context,
            stages,
            "screening",
            &points,
            None,
            policy,
            &mut |block, _| {
                for r in 0..block.count {
                    screening.add_record(block.record(2 * d, r), |i| block.record(i, r));
                    let mut row = vec![
                        EnvelopePoint {
                            lower: f64::INFINITY,
                            upper: f64::NEG_INFINITY,
                            error: None,
                            outer: None,
                        };
                        n_outputs
                    ];
                    for i in 0..=2 * d {
                        for (point, &value) in row.iter_mut().zip(block.record(i, r)) {
                            point.lower = point.lower.min(value);
                            point.upper = point.upper.max(value);
                        }
                    }
                    hull.extend(row);
                }
                Ok(())
            },
        )?;
        Ok((screening, complete))
    }

    /// Runs the check plan's points, widens the envelopes with them and measures the misfits.
    fn check(
        &self,
        check_plan: &CheckPlan,
        context: &mut PhaseContext<'_>,
        accumulator: &mut Accumulator,
    ) -> Result<CheckReport, StudyError> {
        let n_outputs = accumulator.n_outputs;
        let runs = check_plan.checks.len();
        // Per record, the (run, output, predicted) checks made there.
        let n_records = accumulator.times.len();
        let mut by_record: Vec<Vec<(usize, usize, f64)>> = vec![Vec::new(); n_records];
        for (run, checks) in check_plan.checks.iter().enumerate() {
            for &(record, output, _side, predicted) in checks {
                by_record[record].push((run, output, predicted));
            }
        }
        let mut checked: Vec<(usize, usize, f64)> = Vec::new();
        let mut misfit = vec![vec![0.0_f64; n_records]; n_outputs];
        let policy = self.exclusion_policy("check run");
        context.report.runs += runs;
        let complete = self.run_phase(
            context,
            "check",
            &check_plan.points,
            None,
            policy,
            &mut |block, _report| {
                for r in 0..block.count {
                    let record = block.first + r;
                    for i in 0..runs {
                        if block.lockstep.failed(i) {
                            continue;
                        }
                        accumulator.widen(record, block.record(i, r));
                    }
                    for &(run, output, predicted) in &by_record[record] {
                        if block.lockstep.failed(run) {
                            continue;
                        }
                        let truth = block.record(run, r)[output];
                        checked.push((output, record, truth));
                        let m = &mut misfit[output][record];
                        *m = m.max((truth - predicted).abs());
                    }
                }
                Ok(())
            },
        )?;
        let mut max_misfit = vec![0.0; n_outputs];
        let mut relative_misfit = vec![0.0; n_outputs];
        let mut untrusted_outputs = Vec::new();
        let mut below_resolution_outputs = Vec::new();
        let settings = hht_settings(self.scene);
        let mut resolution = Vec::with_capacity(n_outputs);
        let mut widths = Vec::with_capacity(n_outputs);
        for o in 0..n_outputs {
            max_misfit[o] = misfit[o].iter().copied().fold(0.0, f64::max);
            let (width, magnitude) = (0..n_records)
                .map(|r| accumulator.points[r * n_outputs + o])
                .fold((0.0_f64, 0.0_f64), |(width, magnitude), p| {
                    (
                        width.max(p.upper - p.lower),
                        magnitude.max(p.lower.abs()).max(p.upper.abs()),
                    )
                });
            widths.push(width);
            let floor = output_resolution(&self.scene.outputs[o].kind, magnitude, &settings);
            resolution.push(floor);
            let (relative, verdict) = trust_verdict(max_misfit[o], width, floor);
            relative_misfit[o] = relative;
            match verdict {
                TrustVerdict::Trusted => {}
                TrustVerdict::BelowResolution => below_resolution_outputs.push(o),
                TrustVerdict::Untrusted => untrusted_outputs.push(o),
            }
            for (r, &m) in misfit[o].iter().enumerate() {
                let point = &mut accumulator.points[r * n_outputs + o];
                if let Some(error) = &mut point.error {
                    *error = error.max(m);
                }
            }
        }
        let first_miss_record = untrusted_outputs
            .iter()
            .filter_map(|&o| {
                misfit[o]
                    .iter()
                    .position(|&m| m > TRUST_RELATIVE_MISFIT * widths[o])
            })
            .min();
        // The trust test of every prefix of the records, with running widths and misfits: the
        // last prefix it passes is what the check would say of a run that ended there.
        let mut passes_until_record = None;
        let mut prefix_width = vec![0.0_f64; n_outputs];
        let mut prefix_misfit = vec![0.0_f64; n_outputs];
        for (r, points) in accumulator
            .points
            .chunks_exact(n_outputs.max(1))
            .enumerate()
        {
            let mut passes = true;
            for (o, point) in points.iter().enumerate() {
                prefix_width[o] = prefix_width[o].max(point.upper - point.lower);
                prefix_misfit[o] = prefix_misfit[o].max(misfit[o][r]);
                let (_, verdict) = trust_verdict(prefix_misfit[o], prefix_width[o], resolution[o]);
                passes &= verdict != TrustVerdict::Untrusted;
            }
            if passes {
                passes_until_record = Some(r);
            }
        }
        let checks_before_first_miss = checked
            .iter()
            .filter(|&&(_, record, _)| first_miss_record.is_none_or(|first| record < first))
            .count();
        Ok(CheckReport {
            runs,
            unique_candidates: check_plan.unique_candidates,
            points: check_plan.points.clone(),
            max_misfit,
            relative_misfit,
            untrusted_outputs,
            resolution,
            below_resolution_outputs,
            complete,
            checked,
            first_miss_record,
            checks_before_first_miss,
            passes_until_record,
        })
    }

    /// [`Study::run_phase`] of the next stage: its records read from where `stages` says, or
    /// simulated here. (Eight arguments: the five shared ones already travel in `context`.)
    #[allow(clippy::too_many_arguments)]
    pub(super) fn run_stage(
        &self,
        context: &mut PhaseContext<'_>,
        stages: &mut StageCursor,
        phase: &'static str,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        match stages.source(phase, points, nominal_xi.is_some())? {
            Some(mut source) => self.run_source(context, phase, &mut *source, policy, on_block),
            None => self.run_phase(context, phase, points, nominal_xi, policy, on_block),
        }
    }

    /// Simulates `points` (and the nominal run when given) in lock-step over the whole horizon,
    /// calling `on_block` after each block. Returns whether the phase ran to the end (false when
    /// interrupted: `context.report.partial` is then set).
    pub(super) fn run_phase(
        &self,
        context: &mut PhaseContext<'_>,
        phase: &'static str,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        let mut lockstep = self.lockstep(points, nominal_xi);
        self.run_source(context, phase, &mut lockstep, policy, on_block)
    }

    /// The lock-step simulation of `points` (row-major `n × d`) and, when given, the nominal run
    /// after them, with this study's model, scene and box.
    pub fn lockstep(&self, points: &[f64], nominal_xi: Option<&[f64]>) -> LockStep<'_> {
        let scene = self.scene;
        let template = RobotSystem::new(self.model.clone(), scene);
        LockStep::new(
            template,
            self.space,
            scene,
            hht_settings(scene),
            points,
            nominal_xi,
        )
    }

    /// [`Study::run_phase`] over any source of recorded values: block by block over the horizon,
    /// the failure policy applied after each block, then `on_block`.
    pub(super) fn run_source(
        &self,
        context: &mut PhaseContext<'_>,
        phase: &'static str,
        lockstep: &mut dyn RecordSource,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        let PhaseContext {
            threads,
            interrupt,
            started,
            report,
            progress,
        } = context;
        let (threads, interrupt, started) = (*threads, *interrupt, *started);
        let scene = self.scene;
        let runs = lockstep.len();
        let n_outputs = scene.outputs.len();
        let schedule = RecordSchedule::of(scene);
        let n_records = schedule.len();
        let block_records = schedule.block_records(runs, n_outputs);
        let mut first = 0;
        let mut complete = true;
        while first < n_records {
            if interrupt.load(Ordering::SeqCst) {
                complete = false;
                break;
            }
            let count = block_records.min(n_records - first);
            let t_simulate = Instant::now();
            let outcome = lockstep.advance(first, count, threads, interrupt)?;
            report.simulate_seconds += t_simulate.elapsed().as_secs_f64();
            if outcome == BlockOutcome::Interrupted {
                complete = false;
                break;
            }
            let failures = lockstep.failures();
            let nominal = lockstep.nominal_index();
            if let Some(failure) = failures
                .iter()
                .find(|f| Some(f.index) == nominal || !policy.can_exclude)
            {
                let (run, hint) = if Some(failure.index) == nominal {
                    (
                        "the nominal run".to_string(),
                        "The nominal run must succeed; check the scene and the URDF values",
                    )
                } else {
                    let total = runs - usize::from(nominal.is_some());
                    (
                        format!("{} {} of {total}", policy.noun, failure.index + 1),
                        policy.hint,
                    )
                };
                return Err(StudyError::SampleFailed {
                    run,
                    failure: Box::new(failure.clone()),
                    hint,
                });
            }
            on_block(
                &PhaseBlock {
                    first,
                    count,
                    lockstep: &*lockstep,
                },
                report,
            )?;
            first += count;
            progress(Progress {
                phase,
                records_done: first,
                records_total: n_records,
                runs,
                elapsed_s: started.elapsed().as_secs_f64(),
            });
        }
        let (newton_iterations, steps) = lockstep.counters();
        report.newton_iterations += newton_iterations;
        report.steps += steps;
        if let Some(counters) = lockstep.contact_counters() {
            report
                .contacts
                .get_or_insert_with(ContactStats::default)
                .merge(&counters);
        }
        report.excluded.extend(lockstep.failures());
        if !complete {
            report.partial = true;
        }
        Ok(complete)
    }

    /// Moves the accumulated envelopes into the report and hands them to the sink block by block.
    fn finish(
        &self,
        mut report: StudyReport,
        accumulator: Accumulator,
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let n_outputs = accumulator.n_outputs;
        let n_done = accumulator.times.len();
        let nq = self.model.nq;
        let envelope = &mut report.envelope;
        envelope.times = accumulator.times.clone();
        envelope.lower = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.upper = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.nominal = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.runs_lower = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.runs_upper = vec![Vec::with_capacity(n_done); n_outputs];
        let has_error = accumulator.points.iter().any(|p| p.error.is_some());
        if has_error {
            envelope.error = Some(vec![Vec::with_capacity(n_done); n_outputs]);
        }
        if accumulator.points.iter().any(|p| p.outer.is_some()) {
            envelope.outer = Some((
                vec![Vec::with_capacity(n_done); n_outputs],
                vec![Vec::with_capacity(n_done); n_outputs],
            ));
        }
        for r in 0..n_done {
            for o in 0..n_outputs {
                let point = accumulator.points[r * n_outputs + o];
                envelope.lower[o].push(point.lower);
                envelope.upper[o].push(point.upper);
                envelope.nominal[o].push(accumulator.nominal[r * n_outputs + o]);
                let (lowest, highest) = accumulator
                    .runs
                    .get(r * n_outputs + o)
                    .copied()
                    .unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
                envelope.runs_lower[o].push(lowest);
                envelope.runs_upper[o].push(highest);
                if let Some(errors) = &mut envelope.error {
                    errors[o].push(point.error.unwrap_or(0.0));
                }
                if let Some((outer_lower, outer_upper)) = &mut envelope.outer {
                    // The outer bound contains the envelope (which contains every run).
                    let (lo, hi) = point.outer.unwrap_or((point.lower, point.upper));
                    outer_lower[o].push(lo.min(point.lower));
                    outer_upper[o].push(hi.max(point.upper));
                }
            }
        }
        let block = report.block_records.max(1);
        let mut first = 0;
        while first < n_done {
            let count = block.min(n_done - first);
            let values = first * n_outputs..(first + count) * n_outputs;
            let positions = (first * nq).min(accumulator.nominal_positions.len())
                ..((first + count) * nq).min(accumulator.nominal_positions.len());
            sink(&BlockView {
                first_record: first,
                times: &accumulator.times[first..first + count],
                points: &accumulator.points[values.clone()],
                nominal: &accumulator.nominal[values],
                nominal_positions: &accumulator.nominal_positions[positions],
                sobol: report.sobol.as_ref().and_then(|s| s.block(first, count)),
            })
            .map_err(StudyError::Sink)?;
            first += count;
        }
        Ok(report)
    }
}

/// Record times of `scene`'s horizon ([`RecordSchedule::len`]).
pub(super) fn n_records(scene: &Scene) -> usize {
    RecordSchedule::of(scene).len()
}

/// The time of record `record`, s ([`RecordSchedule::time`]).
pub(super) fn record_time(scene: &Scene, record: usize) -> f64 {
    RecordSchedule::of(scene).time(record)
}
