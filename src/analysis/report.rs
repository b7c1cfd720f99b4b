//! What a study hands back, and what it hands out while it runs: the shared result types that the
//! phases fill and that `output/`, the study front end and `distributed/` read.
//!
//! ```text
//! while it runs:  Progress after every block of every phase; BlockView of the finished envelopes
//!                 (the sinks); PendingStage when a stage's records do not exist yet
//! when it ends:   StudyReport (the Envelope, the runs, the CheckReport, the AdaptiveReport, the
//!                 excluded samples as SampleFailure, the timings); DesignPart for a shard
//! ```
//!
//! Plain data: nothing here runs a model or computes a bound.

use super::auto::AutoChoice;
use super::envelope::{Envelope, EnvelopePoint, Side};
use super::lyapunov::LyapunovEstimate;
use super::method::Method;
use super::screening::Screening;
use super::sobol_indices::{SobolBlock, SobolSeries};
use crate::effects::ContactStats;
use crate::scene::Output;

/// A sample that failed: where in the box, when, and why.
#[derive(Clone, Debug)]
pub struct SampleFailure {
    /// Index of the sample in the plan (the nominal run is the last index).
    pub index: usize,
    /// Its point in standard coordinates.
    pub xi: Vec<f64>,
    /// Its parameter values.
    pub values: Vec<f64>,
    /// Time of the failure, s.
    pub time_s: f64,
    /// The record the sample was heading for when it failed: its values are missing from this
    /// record on (a study leaves the sample out of the block holding this record and after).
    pub record: usize,
    /// What went wrong.
    pub message: String,
}

/// A run that failed at the study's fixed step and was re-run from t = 0 with the adaptive step
/// on the same record grid (docs/step-control.md §3): its records from the record the fixed step
/// failed to reach on are the adaptive run's.
#[derive(Clone, Debug)]
pub struct SampleRetry {
    /// The phase whose run it is (`design`, `screening`, `adaptive`, `check`).
    pub phase: &'static str,
    /// The run as messages name it (`sample 3 of 17`, `check run 2 of 8`, `the nominal run`).
    pub run: String,
    /// The fixed step's failure: the sample (its index in the phase's runs, the nominal run
    /// last), its ξ and parameter values, where and why the fixed step failed.
    pub fixed_step_failure: SampleFailure,
}

/// A stage whose records do not exist yet, with the points the study chose for it
/// (docs/distributed.md §7).
#[derive(Clone, Debug, PartialEq)]
pub struct PendingStage {
    /// The stage's number, from 1.
    pub stage: usize,
    /// Its phase (`design`, `screening`, `adaptive`).
    pub phase: &'static str,
    /// Its sample points, row-major `samples × d`.
    pub points: Vec<f64>,
    /// Whether its first shard also runs the nominal run.
    pub nominal: bool,
}

impl PendingStage {
    /// Design samples of the stage (the nominal run not counted), for `dim` parameters.
    pub fn samples(&self, dim: usize) -> usize {
        self.points.len() / dim.max(1)
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
    /// The hull of every true run at the block's records, `records × outputs` record-major
    /// (`(lowest, highest)`), when the study shows it beside its envelope
    /// ([`StudyReport::shows_runs_hull`]: the check left some output untrusted).
    pub runs_hull: Option<&'a [(f64, f64)]>,
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

/// What the a-posteriori check did.
#[derive(Clone, Debug)]
pub struct CheckReport {
    /// Runs made.
    pub runs: usize,
    /// Distinct predicted extremisers there were to choose from.
    pub unique_candidates: usize,
    /// The points run, in standard coordinates (`runs × d`, row-major).
    pub points: Vec<f64>,
    /// Per output: the largest misfit in its unit, by the method's [`super::CheckMisfit`]: the
    /// largest `|true − predicted|` over its checked predictions (scans), or the largest excess of
    /// a check run's value past the envelope as the method gave it (outer, approximate).
    pub max_misfit: Vec<f64>,
    /// Per output: `max_misfit` over the output's largest envelope width (0 where the width is 0).
    pub relative_misfit: Vec<f64>,
    /// Outputs whose relative misfit exceeds [`super::TRUST_RELATIVE_MISFIT`] and whose misfit
    /// exceeds [`super::TRUST_RESOLUTION_FACTOR`] times their resolution: their surrogate cannot
    /// be trusted (the envelope still contains every true run).
    pub untrusted_outputs: Vec<usize>,
    /// Per output: how finely the true model resolves it ([`super::output_resolution`]; `None`:
    /// no floor).
    pub resolution: Vec<Option<f64>>,
    /// Outputs whose relative misfit exceeds [`super::TRUST_RELATIVE_MISFIT`] but whose misfit is
    /// within their resolution: envelopes at the integrator's noise level (a planar robot's
    /// out-of-plane coordinate), not a failed surrogate.
    pub below_resolution_outputs: Vec<usize>,
    /// Whether the check ran over the whole horizon (false when interrupted).
    pub complete: bool,
    /// Every checked prediction: `(output, record, true value)` at the record time where the
    /// surrogate put an extreme (for plots: true runs on the envelope's edge).
    pub checked: Vec<(usize, usize, f64)>,
    /// The first record at which a check of an untrusted output missed by more than
    /// [`super::TRUST_RELATIVE_MISFIT`] of the output's width (`None` when every output is
    /// trusted).
    pub first_miss_record: Option<usize>,
    /// Checks made at records before [`CheckReport::first_miss_record`] (all of them when it is
    /// `None`): each agreed within the tolerance or the output's resolution.
    pub checks_before_first_miss: usize,
    /// The last record `R` at which the check, comparing only the misfits and widths of records
    /// `0..=R`, trusts every output — what the check would say of a run that ended there (the last
    /// record exactly when every output is trusted; `None` when no prefix passes).
    pub passes_until_record: Option<usize>,
    /// The horizon check, when one ran: checks aimed at the records up to
    /// [`CheckReport::passes_until_record`] of an untrusted study (`horizon_phase.rs`).
    pub horizon: Option<HorizonCheck>,
}

/// What the horizon check of an untrusted study did (docs/method.md §7, "What to do about a
/// miss"): rounds of checks aimed at the predicted extremes up to the record where the study's
/// checks passed, until a round confirms that record.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HorizonCheck {
    /// Rounds run.
    pub rounds: usize,
    /// Runs made over all rounds.
    pub runs: usize,
    /// The record up to which checks aimed there agree: the record a round aimed at, when the
    /// prefix test with every check's misfits still passed there (`None`: no round confirmed
    /// its aim).
    pub verified_until_record: Option<usize>,
}

/// Why a study whose method the check follows made no check runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckSkipped {
    /// `--check-runs 0`.
    TurnedOff,
}

impl CheckSkipped {
    /// The reason as the summary (`stats.check.skipped`) and the stdout table say it.
    pub fn reason(self) -> &'static str {
        match self {
            CheckSkipped::TurnedOff => {
                "--check-runs 0: the envelopes were not compared with the true model"
            }
        }
    }
}

/// What the adaptive design did, for the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveReport {
    /// Rounds of refinement proposed (round 0, the start, included); several per stage.
    pub rounds: usize,
    /// Stages run: lock-step phases of the rounds' points (each a scheduling round trip of a
    /// distributed study, docs/distributed.md §7).
    pub stages: usize,
    /// Design runs (terms), the nominal run not included.
    pub runs: usize,
    /// The budget of design runs.
    pub budget: usize,
    /// Highest degree of any one parameter.
    pub max_degree: usize,
    /// Terms with two or more parameters (interactions found).
    pub interactions: usize,
    /// Largest indicator left among the candidates not run (relative to the output's spread).
    pub largest_remaining_indicator: f64,
    /// Why it stopped: `converged`, `budget` or `interrupted`.
    pub stop: &'static str,
}

/// One element of a study's box (docs/method.md §12), for the summary and the report.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementSummary {
    /// Its parent element (`None` for the root, the whole box).
    pub parent: Option<usize>,
    /// Splits from the root.
    pub depth: usize,
    /// Its lower corner in standard coordinates ξ.
    pub lower_xi: Vec<f64>,
    /// Its upper corner in standard coordinates ξ.
    pub upper_xi: Vec<f64>,
    /// The dimensions its split halved (empty for a leaf).
    pub split_dims: Vec<usize>,
    /// Runs made for its design (the root's: the study's design with the nominal run).
    pub design_runs: usize,
    /// Its design's points that are its parent's runs, reused (docs/method.md §12, "Nested
    /// elements").
    pub reused_runs: usize,
    /// Its check's runs.
    pub check_runs: usize,
    /// Its surrogates' order (0 for a scan).
    pub order: usize,
    /// Points per dimension of its grid when it is a scanned leaf (docs/method.md §12); `None`
    /// for a surrogate.
    pub scan_grid: Option<Vec<usize>>,
    /// Whether it is a leaf (its bounds are in the union).
    pub leaf: bool,
    /// The outputs its check fails for, against the union's width (leaves only).
    pub untrusted_outputs: Vec<usize>,
    /// A leaf's own envelope of each output the elements were made for: `(output, lower[r],
    /// upper[r])` (for the report's plots: drawn faintly under the union).
    pub series: Vec<(usize, Vec<f64>, Vec<f64>)>,
}

/// What splitting the box into elements did (docs/method.md §12).
#[derive(Clone, Debug, PartialEq)]
pub struct ElementsReport {
    /// Rounds of splitting run.
    pub rounds: usize,
    /// Runs the elements made beyond the first design and check (their designs and checks).
    pub runs: usize,
    /// Why it stopped: `trusted` (every output), `budget` (`--max-runs`), `max-elements`,
    /// `resolution` (no failing element could be halved further), `stalled` (halving stopped
    /// improving the failing elements: docs/method.md §12) or `interrupted`.
    pub stop: &'static str,
    /// The outputs the first check did not trust, for which the elements were made.
    pub outputs: Vec<usize>,
    /// Every element, the root first, parents before children.
    pub elements: Vec<ElementSummary>,
}

impl ElementsReport {
    /// The leaves (the elements whose bounds make the union).
    pub fn leaves(&self) -> usize {
        self.elements.iter().filter(|e| e.leaf).count()
    }

    /// The scanned leaves (stalled leaves whose envelope is the hull of a grid of true runs).
    pub fn scanned_leaves(&self) -> usize {
        self.elements
            .iter()
            .filter(|e| e.leaf && e.scan_grid.is_some())
            .count()
    }

    /// The deepest leaf's depth.
    pub fn depth(&self) -> usize {
        self.elements.iter().map(|e| e.depth).max().unwrap_or(0)
    }

    /// How many splits halved each dimension (length `dim`).
    pub fn splits_per_dimension(&self, dim: usize) -> Vec<usize> {
        let mut count = vec![0; dim];
        for element in &self.elements {
            for &j in &element.split_dims {
                if j < dim {
                    count[j] += 1;
                }
            }
        }
        count
    }

    /// Leaves whose check still fails for some output.
    pub fn untrusted_leaves(&self) -> usize {
        self.elements
            .iter()
            .filter(|e| e.leaf && !e.untrusted_outputs.is_empty())
            .count()
    }
}

/// One extreme refined on the true model (docs/method.md §12).
#[derive(Clone, Debug, PartialEq)]
pub struct RefinedExtreme {
    /// The output.
    pub output: usize,
    /// The record time it was refined at (the output's widest).
    pub record: usize,
    /// Which side.
    pub side: Side,
    /// Where the search started (the surrogates' predicted extreme), ξ.
    pub start_xi: Vec<f64>,
    /// Where the best true value was found, ξ.
    pub best_xi: Vec<f64>,
    /// The best true value found (`NaN` when even the start failed).
    pub value: f64,
    /// The envelope's bound on that side before the refinement.
    pub envelope: f64,
}

/// What refining the untrusted outputs' extremes on the true model did (docs/method.md §12).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefinementReport {
    /// True runs made, all stages.
    pub runs: usize,
    /// Batches (lock-step phases) run.
    pub batches: usize,
    /// Runs of the centre's central-difference stencil (stage 1; the targets' starts besides).
    pub gradient_runs: usize,
    /// Runs at the gradients' sign vertices (stage 2).
    pub vertex_runs: usize,
    /// Runs of the one-flip searches (stage 3).
    pub flip_runs: usize,
    /// Runs of the gradient searches (stage 4).
    pub search_runs: usize,
    /// Every extreme refined: per target, the best true value any stage found at its record.
    pub extremes: Vec<RefinedExtreme>,
    /// The one-flip searches, one per target and record it aimed at (where its output's hull of
    /// true runs first reaches 30 % and 60 % of its widest; empty when stage 3 did not run).
    pub flips: Vec<RefinedExtreme>,
}

/// Where a study's time went besides simulating, phase by phase, in seconds. The phases that run
/// on the worker threads (`fit`, `inner_bound`, `outer_bound`, `sobol_indices`, and the adaptive
/// rounds' fits in `design_choice`) are summed over the threads: on `n` threads they may add up
/// to `n` times the wall they took. The others are wall time on the study's thread.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseSeconds {
    /// Choosing the design: the adaptive rounds' fits (summed over the threads that ran their
    /// chunks of records), term indicators and proposals of the next terms (their runs are
    /// simulation), or the screening's ranking and the screened set.
    pub design_choice: f64,
    /// Fitting the surrogates of the design (and of the elements) at every record time.
    pub fit: f64,
    /// The inner bounds: scanning the surrogates, or the box search from its starts.
    pub inner_bound: f64,
    /// The outer bounds (interval arithmetic, Chebyshev, Bernstein), where the method has one.
    pub outer_bound: f64,
    /// The surrogates' main and total Sobol' indices.
    pub sobol_indices: f64,
    /// Selecting the check's points among the predicted extremes.
    pub check_selection: f64,
    /// Building the summary (set by the front end that writes it; 0 in the study's report).
    pub summary: f64,
}

impl PhaseSeconds {
    /// Adds the bounding phases' seconds (fit, inner and outer bound, Sobol' indices) of `other`.
    pub fn add_bounding(&mut self, other: &PhaseSeconds) {
        self.fit += other.fit;
        self.inner_bound += other.inner_bound;
        self.outer_bound += other.outer_bound;
        self.sobol_indices += other.sobol_indices;
    }
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
    /// Runs that failed at the fixed step and were re-run with the adaptive step, phase by
    /// phase in the order they ran.
    pub retried: Vec<SampleRetry>,
    /// Whether the study stopped early (interrupted): the envelopes cover the times done.
    pub partial: bool,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
    /// Seconds spent fitting and bounding (wall: the design's fit and bound of a block may run
    /// beside the simulation of the next, [`StudyReport::beside_simulation_seconds`]).
    pub bound_seconds: f64,
    /// The wall seconds of `bound_seconds` during which the next block's simulation ran on the
    /// same threads: `simulate_seconds + bound_seconds − beside_simulation_seconds` is about the
    /// wall the two took together.
    pub beside_simulation_seconds: f64,
    /// Where the arithmetic time went, phase by phase ([`PhaseSeconds`]).
    pub phase_seconds: PhaseSeconds,
    /// Newton iterations of all samples.
    pub newton_iterations: u64,
    /// Steps of all samples.
    pub steps: u64,
    /// Worker threads used.
    pub threads: usize,
    /// Record times per block of the design phase.
    pub block_records: usize,
    /// The a-posteriori check, when the method has one and it ran.
    pub check: Option<CheckReport>,
    /// Why a method that is checked ([`Method::is_checked`]) made no check (`None`: it made one,
    /// or the method has none, or the study was interrupted before it).
    pub check_skipped: Option<CheckSkipped>,
    /// The method that ran (`auto` resolved).
    pub method: Method,
    /// The design's name (see [`super::StudyPlan::design_name`]).
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
    /// The elements the box was split into where the first check failed (docs/method.md §12);
    /// `None` when it was not split.
    pub elements: Option<ElementsReport>,
    /// The untrusted outputs' extremes refined on the true model (docs/method.md §12); `None`
    /// when nothing was refined.
    pub refinement: Option<RefinementReport>,
    /// The largest Lyapunov exponent of the nominal motion (two extra runs: the nominal
    /// parameters and a shadow with a perturbed state; `None` when either failed or the study was
    /// interrupted before).
    pub lyapunov: Option<LyapunovEstimate>,
    /// The contact counters of all runs, summed (the deepest penetration: the largest;
    /// docs/contacts.md §4); `None` when the scene declares no contacts.
    pub contacts: Option<ContactStats>,
}

impl StudyReport {
    /// Whether the study's results show the hull of its true runs beside the envelope (the CSV's
    /// `NAME.runs_lower` / `NAME.runs_upper` columns, the MCAP's `/ribbon/runs/…` channels,
    /// docs/mcap.md §1): the a-posteriori check left some output untrusted, so the envelope may be
    /// too narrow or too wide and the true runs are what the study can claim; and every record of
    /// every output has a true run (always so: the nominal run reaches every record done).
    /// A trusted study shows no hull, so its files keep every byte they had before.
    pub fn shows_runs_hull(&self) -> bool {
        let untrusted = self
            .check
            .as_ref()
            .is_some_and(|check| !check.untrusted_outputs.is_empty());
        let e = &self.envelope;
        let finite = |series: &[Vec<f64>]| {
            series.len() == e.outputs.len()
                && series
                    .iter()
                    .all(|s| s.len() == e.times.len() && s.iter().all(|x| x.is_finite()))
        };
        untrusted && finite(&e.runs_lower) && finite(&e.runs_upper)
    }

    /// A report with no runs and empty envelopes over `outputs`, for a study of `method` on
    /// `threads` worker threads.
    pub fn empty(outputs: Vec<Output>, threads: usize, method: Method) -> StudyReport {
        StudyReport {
            envelope: Envelope {
                outputs,
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
            retried: Vec::new(),
            partial: false,
            simulate_seconds: 0.0,
            bound_seconds: 0.0,
            beside_simulation_seconds: 0.0,
            phase_seconds: PhaseSeconds::default(),
            newton_iterations: 0,
            steps: 0,
            threads,
            block_records: 0,
            check: None,
            check_skipped: None,
            lyapunov: None,
            contacts: None,
            method,
            design: "",
            auto: None,
            screening: None,
            ranking: None,
            total_index_max: None,
            sobol: None,
            condition_number: None,
            adaptive: None,
            elements: None,
            refinement: None,
        }
    }
}

/// What simulating a part of a design did (`Study::simulate_design_part`, one shard of
/// `ribbon run`). Its persisted form is [`crate::distributed::BlockTrailer`]: every field but
/// `simulate_seconds` (a timing, kept out of the block so that blocks are byte-identical), written
/// by `study_front/shard.rs` and summed over the shards by the merge. A field added here that the
/// merge must report goes into both.
#[derive(Clone, Debug)]
pub struct DesignPart {
    /// Whether every record time was simulated (false when interrupted).
    pub complete: bool,
    /// Samples left out under `--keep-going`, by their index in the whole design (the nominal
    /// run, which may not fail, never appears).
    pub failures: Vec<SampleFailure>,
    /// Samples re-run with the adaptive step (the fixed step's failure of each), by their index
    /// in the whole design (the nominal run after the design's samples).
    pub retried: Vec<SampleFailure>,
    /// Newton iterations of the part's runs.
    pub newton_iterations: u64,
    /// Steps of the part's runs.
    pub steps: u64,
    /// Contact counters of the part's runs, summed; `None` when the scene declares no contacts.
    pub contacts: Option<ContactStats>,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
}
