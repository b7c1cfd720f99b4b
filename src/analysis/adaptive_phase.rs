//! The rounds of a dimension-adaptive study (docs/method.md §11):
//!
//! ```text
//! stage 1: round 0 — the centre and one Leja point per parameter (d + 1 runs) and the nominal run
//! stage s: fit every output at every record time on the runs so far (Leja interpolation)
//!          ⇒ each candidate term's indicator: its largest |coefficient| over records, relative
//!            to the output's spread ⇒ AdaptiveSet::refine picks the next terms, then up to
//!            ADAPTIVE_ROUNDS_PER_STAGE − 1 more rounds (ADAPTIVE_FIRST_STAGE_ROUNDS − 1 in stage 2)
//!            on predicted indicators ⇒ run their points
//! stop:    the budget is spent, or every candidate's indicator is below ADAPTIVE_TOLERANCE
//! ```
//!
//! Every stage is a lock-step phase over the whole horizon (and a stage of a distributed study:
//! docs/distributed.md §7), and every run's values are kept (the
//! next round's fit needs them): `runs × outputs × records` values, which `auto` checks against
//! [`super::auto::ADAPTIVE_VALUE_BUDGET`] before choosing this design. The study then bounds the
//! final interpolant from the stored values like any other sparse design, with each record's
//! coefficients from the last stage's fit ([`AdaptiveOutcome::record_coefficients`]) instead of
//! a fit of its own.
//!
//! A stage whose runs reach the budget is the last before it runs. The rounds hand it to the
//! design phase unrun ([`Adapted::LastStage`], [`LastStage`]), which simulates it block by block
//! and, beside each next block, fits the chunks of records the blocks completed
//! ([`LastStage::fit_through`]: the chunks and surpluses of a whole-stage fit, the same bits) and
//! bounds them; the bounding no longer waits for the whole stage (docs/method.md §11). The first
//! stage always runs here. A stage that converges instead is not known to be the last until it is
//! fitted, and is bounded after it as before.

use super::accumulator::Accumulator;
use super::adaptive::{
    AdaptiveSet, Term, ADAPTIVE_BATCH_FRACTION, ADAPTIVE_FIRST_STAGE_ROUNDS, ADAPTIVE_MIN_BATCH,
    ADAPTIVE_ROUNDS_PER_STAGE, ADAPTIVE_TOLERANCE,
};
use super::error::StudyError;
use super::method::Method;
use super::phase::{PhaseBlock, PhaseContext};
use super::report::AdaptiveReport;
use super::schedule::RecordSchedule;
use super::sparse::SparseDesign;
use super::stages::StageCursor;
use crate::uq::{Factor, SparseGrid, UqError};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// An output whose spread over the runs is below this fraction of `1 + max |value|` carries no
/// signal above the integrator's convergence noise (Newton stops at ~10⁻¹⁰ relative): its
/// coefficients do not steer the refinement.
pub const ADAPTIVE_NOISE_FLOOR: f64 = 1e-9;

/// Every run's values of the design the rounds produced (its grid is returned beside it).
pub(super) struct AdaptiveOutcome {
    /// `values[row][record · outputs + output]` by [`AdaptiveSet::evaluated`] row.
    values: Vec<Vec<f64>>,
    /// Grid point t → row of `values`.
    row_of_point: Vec<usize>,
    /// The last complete stage's fit of every record on the grid: the coefficients the bounding
    /// would fit again, to the bit.
    coefficients: RecordCoefficients,
    /// The summary.
    pub(super) report: AdaptiveReport,
    /// Whether every round ran to the end (false: interrupted; the grid is the last complete one).
    pub(super) complete: bool,
}

impl AdaptiveOutcome {
    /// Record `r`'s values in grid order, row-major `points × outputs`.
    pub(super) fn record(&self, r: usize, n_outputs: usize) -> Vec<f64> {
        gather_record(&self.values, &self.row_of_point, r, n_outputs)
    }

    /// Record `r`'s Legendre coefficients on the grid, row-major `terms × outputs`: what the
    /// grid's fit of [`AdaptiveOutcome::record`] gives, to the bit (the last stage fitted them).
    pub(super) fn record_coefficients(&self, r: usize, n_outputs: usize) -> Vec<f64> {
        self.coefficients.record(r, n_outputs)
    }
}

/// What the adaptive rounds hand the design phase (once per study: the variants' sizes do not
/// matter).
#[allow(clippy::large_enum_variant)]
pub(super) enum Adapted {
    /// The rounds are over: the interpolation grid on the terms of the complete rounds and the
    /// runs' values, to be bounded.
    Done(SparseGrid, AdaptiveOutcome),
    /// The next stage is the last (its runs reach the budget): the design phase runs it, and fits
    /// and bounds each block of its records beside the simulation of the next block.
    LastStage(LastStage),
}

/// Runs the rounds (module documentation) within `budget` design runs; the first round also
/// runs the nominal parameters into `accumulator`. Returns the rounds' outcome, or the last
/// stage still to run when the budget ends the rounds after it; `None` when interrupted during
/// the first round (nothing to fit).
pub(super) fn adapt(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    budget: usize,
    nominal_xi: &[f64],
    accumulator: &mut Accumulator,
) -> Result<Option<Adapted>, StudyError> {
    let d = context.space.len();
    let scene = context.scene;
    let schedule = RecordSchedule::of(scene);
    let n_outputs = scene.outputs.len();
    let n_records = schedule.len();
    let stride = n_records * n_outputs;
    let mut set = AdaptiveSet::new(d);
    let mut values: Vec<Vec<f64>> = Vec::new();
    let mut extremes = RunExtremes::new();
    let mut new_terms = set.evaluated().to_vec();
    // The last complete stage's grid, rows and fit.
    let mut last_fit: Option<StageFit> = None;
    // The runs' hierarchical surpluses, kept from stage to stage.
    let mut surpluses = Surpluses::default();
    // Round 0 is proposed with the set; `propose_stage` counts the rest.
    let mut rounds = 1;
    let mut stages_run = 0;
    let policy = context.design_failure_policy(Method::LegendreScan);
    let (stop, complete) = loop {
        // The rounds end after a stage whose runs reach the budget: the design phase runs that
        // one beside its bounding (the first stage, which has no fit to fall back on when
        // interrupted, runs here).
        if set.len() >= budget {
            if let Some(previous) = last_fit.take() {
                let last = LastStage::new(LastStageStart {
                    set,
                    new_terms,
                    values,
                    previous,
                    surpluses,
                    extremes,
                    rounds,
                    stages_run,
                    budget,
                    n_records,
                    n_outputs,
                })?;
                return Ok(Some(Adapted::LastStage(last)));
            }
        }
        // Run this stage's points.
        let points = set.points(&new_terms)?;
        let first_row = values.len();
        values.resize_with(first_row + new_terms.len(), || vec![0.0; stride]);
        let with_nominal = stages_run == 0;
        context.report.runs += new_terms.len() + usize::from(with_nominal);
        let stage_complete = context.run_stage(
            stages,
            "adaptive",
            &points,
            with_nominal.then_some(nominal_xi),
            policy,
            &mut |block, _| {
                let lockstep = block.lockstep;
                copy_block(&mut values[first_row..], block, n_outputs);
                for r in 0..block.count {
                    let record = block.first + r;
                    if with_nominal {
                        let nominal = lockstep.nominal_index().unwrap_or(new_terms.len());
                        accumulator.push_nominal(
                            schedule.time(record),
                            block.record(nominal, r),
                            lockstep.nominal_positions(r),
                        );
                    }
                }
                Ok(())
            },
        )?;
        stages_run += 1;
        if !stage_complete {
            if last_fit.is_none() {
                return Ok(None);
            }
            values.truncate(first_row);
            break ("interrupted", false);
        }
        // Fit the set evaluated so far and measure the candidates.
        let t_fit = Instant::now();
        let (fitted, thread_seconds) = fit_and_measure(
            &mut set,
            &values,
            &mut extremes,
            n_outputs,
            context.threads,
            &mut surpluses,
            last_fit.take(),
        )?;
        last_fit = Some(fitted);
        context.report.bound_seconds += t_fit.elapsed().as_secs_f64();
        context.report.phase_seconds.design_choice += thread_seconds;
        if set.len() >= budget {
            break ("budget", true);
        }
        if set.largest_indicator() < ADAPTIVE_TOLERANCE {
            break ("converged", true);
        }
        let per_stage = if stages_run == 1 {
            ADAPTIVE_FIRST_STAGE_ROUNDS
        } else {
            ADAPTIVE_ROUNDS_PER_STAGE
        };
        // Choosing the next terms is part of the design choice too (one thread).
        let t_propose = Instant::now();
        new_terms = propose_stage(&mut set, per_stage, budget, &mut rounds);
        let propose_seconds = t_propose.elapsed().as_secs_f64();
        context.report.bound_seconds += propose_seconds;
        context.report.phase_seconds.design_choice += propose_seconds;
        if new_terms.is_empty() {
            break ("converged", true);
        }
    };
    let StageFit {
        grid,
        row_of_point,
        coefficients,
    } = last_fit.expect("a complete round built a grid");
    let report = adaptive_report(&grid, &set, rounds, stages_run, budget, stop);
    Ok(Some(Adapted::Done(
        grid,
        AdaptiveOutcome {
            report,
            values,
            row_of_point,
            coefficients,
            complete,
        },
    )))
}

/// The summary of rounds that ended on `grid`.
fn adaptive_report(
    grid: &SparseGrid,
    set: &AdaptiveSet,
    rounds: usize,
    stages: usize,
    budget: usize,
    stop: &'static str,
) -> AdaptiveReport {
    let set_of_grid = grid.set();
    let interactions = (0..set_of_grid.len())
        .filter(|&t| set_of_grid.term(t).len() >= 2)
        .count();
    AdaptiveReport {
        rounds,
        stages,
        runs: set_of_grid.len(),
        budget,
        max_degree: set_of_grid.max_degree(),
        interactions,
        largest_remaining_indicator: set.largest_indicator(),
        stop,
    }
}

/// Copies a block's records of a stage's runs (`rows`, in the stage's order) into their rows.
fn copy_block(rows: &mut [Vec<f64>], block: &PhaseBlock<'_>, n_outputs: usize) {
    for r in 0..block.count {
        let record = block.first + r;
        for (i, row) in rows.iter_mut().enumerate() {
            row[record * n_outputs..(record + 1) * n_outputs].copy_from_slice(block.record(i, r));
        }
    }
}

/// The grid of the last stage's design (always a grid: [`LastStage::new`] makes it one).
fn grid_of(design: &SparseDesign) -> Result<&SparseGrid, StudyError> {
    match design {
        SparseDesign::Grid(grid) => Ok(grid),
        SparseDesign::Regression(_) => Err(StudyError::BadOptions(
            "internal: the adaptive design's last stage holds no grid".to_string(),
        )),
    }
}

/// What the rounds leave to their last stage ([`LastStage::new`]).
struct LastStageStart {
    set: AdaptiveSet,
    new_terms: Vec<Term>,
    values: Vec<Vec<f64>>,
    previous: StageFit,
    surpluses: Surpluses,
    extremes: RunExtremes,
    rounds: usize,
    stages_run: usize,
    budget: usize,
    n_records: usize,
    n_outputs: usize,
}

/// The adaptive design's last stage, which the budget makes the last before it runs: its runs
/// and the final grid, for the design phase to simulate block by block and, beside the next
/// block, to fit ([`LastStage::fit_through`], the chunks of records complete so far, the same
/// bits as the fit of every record after the stage) and bound. An interrupted last stage falls
/// back to the stage before ([`LastStage::interrupted`]), as the rounds do.
pub(super) struct LastStage {
    set: AdaptiveSet,
    /// The stage's points, row-major `runs × d`.
    points: Vec<f64>,
    /// Every run's values; the stage's from `first_row` on, filled block by block.
    values: Vec<Vec<f64>>,
    first_row: usize,
    /// The final interpolation grid (every term the rounds evaluated, this stage's included).
    design: Arc<SparseDesign>,
    /// Per point of the grid, its row of the values.
    rows: Vec<usize>,
    /// Per run, its point of the grid.
    term_of_run: Vec<usize>,
    /// Runs whose surplus rows the earlier stages left.
    kept: usize,
    surpluses: Surpluses,
    /// The earlier stage's coefficient chunks, whose memory the new ones reuse.
    buffers: Vec<Vec<f64>>,
    /// The chunks fitted so far.
    coefficients: RecordCoefficients,
    /// Thread-seconds of the chunks' fits.
    fit_seconds: f64,
    extremes: RunExtremes,
    rounds: usize,
    stages_run: usize,
    budget: usize,
    n_records: usize,
    n_outputs: usize,
}

impl LastStage {
    /// The last stage of rounds that end with `start`: its points and the final grid.
    fn new(start: LastStageStart) -> Result<LastStage, StudyError> {
        let LastStageStart {
            set,
            new_terms,
            mut values,
            previous,
            mut surpluses,
            extremes,
            rounds,
            stages_run,
            budget,
            n_records,
            n_outputs,
        } = start;
        let points = set.points(&new_terms)?;
        let first_row = values.len();
        values.resize_with(first_row + new_terms.len(), || {
            vec![0.0; n_records * n_outputs]
        });
        let grid = SparseGrid::new(Arc::new(set.multi_index_set()?))?;
        let rows = rows_of_points(&grid, &set)?;
        let n_terms = grid.n_points();
        let term_of_run = terms_of_runs(&rows, n_terms, values.len())?;
        let kept = surpluses.keep_for(n_terms, n_records, n_outputs);
        // The stage before's grid is not kept (an interrupted last stage builds it again from
        // the terms run before): it is as large as the final one.
        let mut buffers = previous.coefficients.chunks;
        buffers.resize_with(chunk_count(n_records), Vec::new);
        Ok(LastStage {
            set,
            points,
            values,
            first_row,
            design: Arc::new(SparseDesign::Grid(grid)),
            rows,
            term_of_run,
            kept,
            surpluses,
            buffers,
            coefficients: RecordCoefficients::empty(n_terms, n_outputs),
            fit_seconds: 0.0,
            extremes,
            rounds,
            stages_run,
            budget,
            n_records,
            n_outputs,
        })
    }

    /// The stage's points, row-major `runs × d`.
    pub(super) fn points(&self) -> &[f64] {
        &self.points
    }

    /// The stage's runs.
    pub(super) fn runs(&self) -> usize {
        self.values.len() - self.first_row
    }

    /// The final design: the interpolation grid on every term of the rounds.
    pub(super) fn design(&self) -> &Arc<SparseDesign> {
        &self.design
    }

    /// The final grid's condition number (computed once).
    pub(super) fn condition_number(&self) -> f64 {
        self.design.condition_number()
    }

    /// Copies a block of the stage's records into the runs' values.
    pub(super) fn take_block(&mut self, block: &PhaseBlock<'_>) {
        copy_block(&mut self.values[self.first_row..], block, self.n_outputs);
    }

    /// Fits the chunks of records that are complete once the first `records_done` records of
    /// the stage are in (every chunk from the last record on) and not fitted yet; returns the
    /// records they hold (empty when none).
    pub(super) fn fit_through(
        &mut self,
        records_done: usize,
        threads: &rayon::ThreadPool,
    ) -> Result<std::ops::Range<usize>, StudyError> {
        let n_chunks = chunk_count(self.n_records);
        let complete = if records_done >= self.n_records {
            n_chunks
        } else {
            records_done / FIT_CHUNK_RECORDS
        };
        let from = self.coefficients.chunks.len();
        let first_record = (from * FIT_CHUNK_RECORDS).min(self.n_records);
        if complete <= from {
            return Ok(first_record..first_record);
        }
        let buffers = self.buffers[from..complete]
            .iter_mut()
            .map(std::mem::take)
            .collect();
        let runs = StageRuns {
            grid: grid_of(&self.design)?,
            rows: &self.rows,
            values: &self.values,
            n_outputs: self.n_outputs,
            n_records: self.n_records,
            kept: self.kept,
            new_terms: &self.term_of_run[self.kept..],
        };
        let fitted = runs.fit_chunks(
            from,
            &mut self.surpluses.chunks[from..complete],
            buffers,
            threads,
        )?;
        for chunk in fitted {
            self.fit_seconds += self.coefficients.push(chunk);
        }
        Ok(first_record..(complete * FIT_CHUNK_RECORDS).min(self.n_records))
    }

    /// Record `r`'s values in grid order, row-major `points × outputs`.
    pub(super) fn record(&self, r: usize) -> Vec<f64> {
        gather_record(&self.values, &self.rows, r, self.n_outputs)
    }

    /// Record `r`'s coefficients on the final grid (fitted by [`LastStage::fit_through`]).
    pub(super) fn record_coefficients(&self, r: usize) -> Vec<f64> {
        self.coefficients.record(r, self.n_outputs)
    }

    /// The summary of the rounds once every chunk is fitted: the candidates measured on the
    /// whole fit (the largest term left), and the thread-seconds of the design choice in this
    /// stage (the fits and the measuring).
    pub(super) fn finish(mut self) -> Result<(AdaptiveReport, f64), StudyError> {
        let started = Instant::now();
        let n_chunks = chunk_count(self.n_records);
        if self.coefficients.chunks.len() != n_chunks {
            return Err(StudyError::BadOptions(format!(
                "internal: the adaptive design's last stage fitted {} of {n_chunks} chunks of records",
                self.coefficients.chunks.len()
            )));
        }
        let grid = grid_of(&self.design)?;
        measure_candidates(
            &mut self.set,
            &mut self.extremes,
            &self.values,
            self.n_outputs,
            grid,
            &self.coefficients,
        );
        let report = adaptive_report(
            grid,
            &self.set,
            self.rounds,
            self.stages_run + 1,
            self.budget,
            "budget",
        );
        Ok((report, self.fit_seconds + started.elapsed().as_secs_f64()))
    }

    /// The rounds as they stand when this stage is interrupted: the stage before's grid (built
    /// again from the terms run before this stage, in their order: the grid that stage fitted)
    /// and its runs' values, fitted again, as the rounds keep them when a stage of theirs is.
    pub(super) fn interrupted(
        mut self,
        threads: &rayon::ThreadPool,
    ) -> Result<(SparseGrid, AdaptiveOutcome), StudyError> {
        self.values.truncate(self.first_row);
        let before = self.set.multi_index_set_of(self.first_row)?;
        let grid = SparseGrid::new(Arc::new(before))?;
        let row_of_point = rows_of_points(&grid, &self.set)?;
        let (coefficients, _) = fit_all_records(
            &grid,
            &row_of_point,
            &self.values,
            self.n_outputs,
            threads,
            &mut Surpluses::default(),
            Vec::new(),
        )?;
        let report = adaptive_report(
            &grid,
            &self.set,
            self.rounds,
            self.stages_run + 1,
            self.budget,
            "interrupted",
        );
        Ok((
            grid,
            AdaptiveOutcome {
                report,
                values: self.values,
                row_of_point,
                coefficients,
                complete: false,
            },
        ))
    }
}

/// A stage's fit: the grid on the terms evaluated so far, per grid point its row of the values,
/// and every record's coefficients.
struct StageFit {
    grid: SparseGrid,
    row_of_point: Vec<usize>,
    coefficients: RecordCoefficients,
}

/// Fits every output at every record on the runs of `set`'s evaluated terms and measures the
/// active candidates' indicators; returns the fit, with the thread-seconds it took (the fit's
/// chunks run on the threads at once, the rest on the caller's).
#[allow(clippy::too_many_arguments)]
fn fit_and_measure(
    set: &mut AdaptiveSet,
    values: &[Vec<f64>],
    extremes: &mut RunExtremes,
    n_outputs: usize,
    threads: &rayon::ThreadPool,
    surpluses: &mut Surpluses,
    earlier: Option<StageFit>,
) -> Result<(StageFit, f64), StudyError> {
    let started = Instant::now();
    let grid = SparseGrid::new(Arc::new(set.multi_index_set()?))?;
    let rows = rows_of_points(&grid, set)?;
    let recycled = earlier.map_or_else(Vec::new, |fit| fit.coefficients.chunks);
    let fit_started = Instant::now();
    let (coefficients, fit_thread_seconds) = fit_all_records(
        &grid, &rows, values, n_outputs, threads, surpluses, recycled,
    )?;
    let fit_wall = fit_started.elapsed().as_secs_f64();
    measure_candidates(set, extremes, values, n_outputs, &grid, &coefficients);
    let thread_seconds = started.elapsed().as_secs_f64() - fit_wall + fit_thread_seconds;
    let fit = StageFit {
        grid,
        row_of_point: rows,
        coefficients,
    };
    Ok((fit, thread_seconds))
}

/// Measures the active candidates' indicators on the fit `coefficients` of every record on
/// `grid`: each term's largest coefficient relative to its output's spread over the runs of
/// `values` (folded into `extremes` first).
fn measure_candidates(
    set: &mut AdaptiveSet,
    extremes: &mut RunExtremes,
    values: &[Vec<f64>],
    n_outputs: usize,
    grid: &SparseGrid,
    coefficients: &RecordCoefficients,
) {
    extremes.absorb(values, n_outputs);
    let spread = extremes.spreads(n_outputs);
    let mi = grid.set();
    set.measure(|term| {
        let factors: Vec<Factor> = term.iter().map(|&(j, k)| Factor::new(j, k)).collect();
        let Some(t) = mi.index_of(&factors) else {
            return 0.0;
        };
        coefficients.largest_normalised(t, &spread)
    });
}

/// A round's batch: [`ADAPTIVE_BATCH_FRACTION`] of the terms so far, at least
/// [`ADAPTIVE_MIN_BATCH`].
fn round_batch(set: &AdaptiveSet) -> usize {
    ADAPTIVE_MIN_BATCH.max((ADAPTIVE_BATCH_FRACTION * set.len() as f64) as usize)
}

/// The terms of the next stage (docs/method.md §11, several rounds per stage): `per_stage` rounds
/// of refinement, the first ranked by the indicators just measured, each later one after the terms
/// proposed before it were given predicted indicators ([`AdaptiveSet::predict_unmeasured`]).
/// `rounds` counts the rounds that proposed terms. Empty when no candidate is left above the
/// tolerance.
fn propose_stage(
    set: &mut AdaptiveSet,
    per_stage: usize,
    budget: usize,
    rounds: &mut usize,
) -> Vec<Term> {
    let mut terms = Vec::new();
    for round in 0..per_stage {
        if round > 0 {
            set.predict_unmeasured();
        }
        let proposed = set.refine(round_batch(set), budget, ADAPTIVE_TOLERANCE);
        if proposed.is_empty() {
            break;
        }
        *rounds += 1;
        terms.extend(proposed);
    }
    terms
}

/// Per point of `grid` (built on `set`'s evaluated terms), the row of its run in the values.
fn rows_of_points(grid: &SparseGrid, set: &AdaptiveSet) -> Result<Vec<usize>, StudyError> {
    let mi = grid.set();
    (0..mi.len())
        .map(|t| {
            let term: Vec<(usize, usize)> = mi
                .term(t)
                .iter()
                .map(|f| (f.dim as usize, f.degree as usize))
                .collect();
            set.row_of(&term).ok_or(StudyError::Uq(UqError::Empty {
                what: "adaptive design row of a grid term",
            }))
        })
        .collect()
}

/// Record `r` of the runs `rows` (in that order), row-major `rows × outputs`.
fn gather_record(values: &[Vec<f64>], rows: &[usize], r: usize, n_outputs: usize) -> Vec<f64> {
    let mut record = Vec::with_capacity(rows.len() * n_outputs);
    for &row in rows {
        record.extend_from_slice(&values[row][r * n_outputs..(r + 1) * n_outputs]);
    }
    record
}

/// Records per chunk of the fit of every record at once: each chunk is one application of the
/// fitting map to `16 × outputs` columns (long enough rows for the vector units, and enough
/// chunks for the threads).
const FIT_CHUNK_RECORDS: usize = 16;

/// The Legendre coefficients of every output at every record, in chunks of records: chunk k
/// holds records `k · FIT_CHUNK_RECORDS ..` as `terms × (records · outputs)`, row-major.
struct RecordCoefficients {
    chunks: Vec<Vec<f64>>,
    n_terms: usize,
    /// Per term and output (`terms × outputs`, row-major), the largest |coefficient| over every
    /// record: taken in each chunk's task while its coefficients are fresh in the cache (reading
    /// them all again for the indicators was most of the indicators' time on the d = 32 scaling
    /// row; issue 40). The largest of the chunks' largest is the largest of all, exactly.
    largest: Vec<f64>,
}

impl RecordCoefficients {
    /// No chunk yet, for `n_terms` terms of `n_outputs` outputs.
    fn empty(n_terms: usize, n_outputs: usize) -> RecordCoefficients {
        RecordCoefficients {
            chunks: Vec::new(),
            n_terms,
            largest: vec![0.0; n_terms * n_outputs],
        }
    }

    /// Appends the next chunk, its largest magnitudes into the largest of all; returns its seconds.
    fn push(&mut self, chunk: FittedChunk) -> f64 {
        for (m, &c) in self.largest.iter_mut().zip(&chunk.largest) {
            *m = m.max(c);
        }
        self.chunks.push(chunk.coefficients);
        chunk.seconds
    }

    /// Record `r`'s coefficients, row-major `terms × outputs` (as
    /// [`crate::uq::LinearFit::fit_into`] writes one record's); empty past the last record.
    fn record(&self, r: usize, n_outputs: usize) -> Vec<f64> {
        let Some(chunk) = self.chunks.get(r / FIT_CHUNK_RECORDS) else {
            return Vec::new();
        };
        let width = chunk.len() / self.n_terms.max(1);
        let first = (r % FIT_CHUNK_RECORDS) * n_outputs;
        if first + n_outputs > width {
            // Past the last record.
            return Vec::new();
        }
        let mut out = Vec::with_capacity(self.n_terms * n_outputs);
        for row in chunk.chunks_exact(width.max(1)) {
            out.extend_from_slice(&row[first..first + n_outputs]);
        }
        out
    }

    /// Term t's largest `|coefficient| / spread` over every record and every output with a
    /// spread (`spread[o]`, [`RunExtremes::spreads`]), or 0. Each output's largest magnitude is
    /// divided once: a correctly rounded division by a positive spread never orders two
    /// quotients against their dividends, so the largest quotient is the quotient of the largest
    /// magnitude, the same bits as dividing every coefficient (the division per coefficient was a
    /// quarter of the d = 32 scaling row's design choice; issue 40).
    fn largest_normalised(&self, t: usize, spread: &[Option<f64>]) -> f64 {
        let n_outputs = spread.len().max(1);
        self.largest[t * n_outputs..(t + 1) * n_outputs]
            .iter()
            .zip(spread)
            .filter_map(|(&largest, spread)| spread.map(|s| largest / s))
            .fold(0.0_f64, f64::max)
    }
}

/// Per term and output of a chunk's coefficients (`terms × width`, `width` a multiple of
/// `n_outputs`), the largest magnitude over its records, into `largest` (`terms × outputs`).
fn largest_magnitudes(chunk: &[f64], width: usize, n_outputs: usize, largest: &mut [f64]) {
    for (row, out) in chunk
        .chunks_exact(width)
        .zip(largest.chunks_exact_mut(n_outputs))
    {
        for record in row.chunks_exact(n_outputs) {
            for (m, value) in out.iter_mut().zip(record) {
                *m = m.max(value.abs());
            }
        }
    }
}

/// The hierarchical surpluses of every run so far (the first factor of the sparse grid's fit,
/// `crate::uq::sparse_grid`): per chunk of records ([`FIT_CHUNK_RECORDS`]), row-major by run (the
/// rows of the values), `runs × (records · outputs)`. A run's surplus depends only on its term and
/// on the runs of the terms below it, which the set holds from then on, so a later stage computes
/// the rows of its own runs only and keeps the others, the same bits (issue 40: the d = 32
/// scaling row's eight stages computed 25 102 first-factor entries' row updates, of which 6 665
/// once each would do).
#[derive(Default)]
struct Surpluses {
    chunks: Vec<Vec<f64>>,
    /// Runs whose rows the chunks hold.
    runs: usize,
}

impl Surpluses {
    /// Readies the chunks for a fit of `n_terms` terms over `n_records` records (one per chunk of
    /// records) and returns how many runs' rows it keeps: all the chunks hold, when every chunk
    /// holds them for the same records; else 0 (computed again).
    fn keep_for(&mut self, n_terms: usize, n_records: usize, n_outputs: usize) -> usize {
        let consistent =
            self.runs <= n_terms
                && self.chunks.len() == chunk_count(n_records)
                && self.chunks.iter().enumerate().all(|(c, chunk)| {
                    chunk.len() == self.runs * chunk_width(c, n_records, n_outputs)
                });
        self.chunks.resize_with(chunk_count(n_records), Vec::new);
        if consistent {
            self.runs
        } else {
            0
        }
    }
}

/// The Legendre coefficients of every output at every record (docs/high-dimension.md §5: one
/// multi-right-hand-side application of the grid's fitting map per chunk of records, read from
/// the runs' rows in place); `rows` maps the grid's points to rows of `values`
/// ([`rows_of_points`]). Each coefficient is the one a fit of its record alone gives, to the bit.
/// The map's first factor is applied to the runs `surpluses` does not hold yet (and they are
/// added), its second to every term; `recycled` are an earlier stage's chunks, whose memory the
/// new ones reuse. Also returns the seconds its chunks took, summed over the threads.
fn fit_all_records(
    grid: &SparseGrid,
    rows: &[usize],
    values: &[Vec<f64>],
    n_outputs: usize,
    threads: &rayon::ThreadPool,
    surpluses: &mut Surpluses,
    recycled: Vec<Vec<f64>>,
) -> Result<(RecordCoefficients, f64), StudyError> {
    let n_records = values.first().map_or(0, |v| v.len() / n_outputs.max(1));
    let n_terms = grid.n_points();
    let term_of_run = terms_of_runs(rows, n_terms, values.len())?;
    let kept = surpluses.keep_for(n_terms, n_records, n_outputs);
    let mut buffers = recycled;
    buffers.resize_with(chunk_count(n_records), Vec::new);
    let runs = StageRuns {
        grid,
        rows,
        values,
        n_outputs,
        n_records,
        kept,
        new_terms: &term_of_run[kept..],
    };
    let chunks = runs.fit_chunks(0, &mut surpluses.chunks, buffers, threads)?;
    surpluses.runs = n_terms;
    let mut coefficients = RecordCoefficients::empty(n_terms, n_outputs);
    let mut thread_seconds = 0.0;
    for chunk in chunks {
        thread_seconds += coefficients.push(chunk);
    }
    Ok((coefficients, thread_seconds))
}

/// Per run (row of the values) the grid point it belongs to, checked: one run per grid point.
fn terms_of_runs(rows: &[usize], n_terms: usize, n_runs: usize) -> Result<Vec<usize>, StudyError> {
    // Grid point of each run: the rows are the runs in the order their terms came.
    let mut term_of_run = vec![usize::MAX; n_terms];
    for (t, &row) in rows.iter().enumerate() {
        if let Some(slot) = term_of_run.get_mut(row) {
            *slot = t;
        }
    }
    if rows.len() != n_terms || n_runs != n_terms || term_of_run.contains(&usize::MAX) {
        return Err(StudyError::Uq(UqError::WrongLength {
            what: "adaptive fit: runs (one per grid point)",
            expected: n_terms,
            got: n_runs,
        }));
    }
    Ok(term_of_run)
}

/// Chunks of [`FIT_CHUNK_RECORDS`] records that `n_records` records make (the last may be short).
fn chunk_count(n_records: usize) -> usize {
    n_records.div_ceil(FIT_CHUNK_RECORDS)
}

/// Columns (records · outputs) of chunk `c` of `n_records` records.
fn chunk_width(c: usize, n_records: usize, n_outputs: usize) -> usize {
    let first = c * FIT_CHUNK_RECORDS;
    ((first + FIT_CHUNK_RECORDS).min(n_records) - first.min(n_records)) * n_outputs
}

/// One chunk's coefficients (`terms × width`, row-major), per term and output their largest
/// magnitude over its records, and the seconds it took.
struct FittedChunk {
    coefficients: Vec<f64>,
    largest: Vec<f64>,
    seconds: f64,
}

/// The runs a stage fits: the grid, its points' rows of the values, and which runs are new (the
/// surpluses hold the first `kept`).
struct StageRuns<'a> {
    grid: &'a SparseGrid,
    rows: &'a [usize],
    values: &'a [Vec<f64>],
    n_outputs: usize,
    n_records: usize,
    kept: usize,
    /// The grid point of every run from `kept` on.
    new_terms: &'a [usize],
}

impl StageRuns<'_> {
    /// Fits the chunks `first_chunk ..` (as many as `surpluses`, their surplus rows, which gain
    /// the new runs' rows; `buffers` their memory to reuse) on the threads.
    fn fit_chunks(
        &self,
        first_chunk: usize,
        surpluses: &mut [Vec<f64>],
        buffers: Vec<Vec<f64>>,
        threads: &rayon::ThreadPool,
    ) -> Result<Vec<FittedChunk>, StudyError> {
        let jobs: Vec<(usize, &mut Vec<f64>, Vec<f64>)> = surpluses
            .iter_mut()
            .zip(buffers)
            .enumerate()
            .map(|(i, (chunk, buffer))| (first_chunk + i, chunk, buffer))
            .collect();
        threads.install(|| {
            jobs.into_par_iter()
                .map(|(c, chunk, out)| self.fit_chunk(c, chunk, out))
                .collect::<Result<Vec<FittedChunk>, StudyError>>()
        })
    }

    /// Chunk `c`'s fit (see [`fit_all_records`]).
    fn fit_chunk(
        &self,
        c: usize,
        chunk: &mut Vec<f64>,
        mut out: Vec<f64>,
    ) -> Result<FittedChunk, StudyError> {
        let started = Instant::now();
        let (n_outputs, kept) = (self.n_outputs, self.kept);
        let n_terms = self.grid.n_points();
        let width = chunk_width(c, self.n_records, n_outputs);
        let first = c * FIT_CHUNK_RECORDS * n_outputs;
        let columns = first..first + width;
        for (k, &t) in self.new_terms.iter().enumerate() {
            let run = &self.values[kept + k][columns.clone()];
            if let Some(column) = run.iter().position(|v| !v.is_finite()) {
                return Err(StudyError::Uq(UqError::NonFinite {
                    what: "fit: values",
                    index: t * width + column,
                    value: run[column],
                }));
            }
        }
        let fit = self.grid.fit();
        let (values, rows) = (self.values, self.rows);
        chunk.resize(n_terms * width, 0.0);
        fit.first_factor_rows_into(
            self.new_terms,
            |p| &values[rows[p]][columns.clone()],
            width,
            &mut chunk[kept * width..],
        )?;
        // Every entry is overwritten: only a longer buffer's new part is zeroed first.
        out.truncate(n_terms * width);
        out.resize(n_terms * width, 0.0);
        let by_run = &chunk[..];
        fit.second_factor_into(
            |t| &by_run[rows[t] * width..(rows[t] + 1) * width],
            width,
            &mut out,
        )?;
        let mut largest = vec![0.0; n_terms * n_outputs];
        if n_outputs > 0 {
            largest_magnitudes(&out, width, n_outputs, &mut largest);
        }
        Ok(FittedChunk {
            coefficients: out,
            largest,
            seconds: started.elapsed().as_secs_f64(),
        })
    }
}

/// Per record and output the lowest and the highest value of the runs folded in so far, and per
/// output the largest magnitude: what the outputs' spreads ([`RunExtremes::spreads`]) need. Kept
/// from stage to stage, so that a stage folds in only its own runs (the d = 32 scaling row's
/// eight stages went over every run again each time: a fifth of the design choice's work); a
/// minimum or maximum does not depend on the order its values come in, so the spreads are the
/// same bits.
struct RunExtremes {
    lowest: Vec<f64>,
    highest: Vec<f64>,
    magnitude: Vec<f64>,
    /// How many runs (rows of the values) are folded in.
    runs: usize,
}

impl RunExtremes {
    fn new() -> RunExtremes {
        RunExtremes {
            lowest: Vec::new(),
            highest: Vec::new(),
            magnitude: Vec::new(),
            runs: 0,
        }
    }

    /// Folds in the runs of `values` (`values[row][record · outputs + output]`) not folded in
    /// yet; starts over if `values` has fewer rows than were folded in.
    fn absorb(&mut self, values: &[Vec<f64>], n_outputs: usize) {
        let width = n_outputs.max(1);
        let stride = values.first().map_or(0, Vec::len);
        if values.len() < self.runs || self.lowest.len() != stride || self.magnitude.len() != width
        {
            self.lowest = vec![f64::INFINITY; stride];
            self.highest = vec![f64::NEG_INFINITY; stride];
            self.magnitude = vec![0.0; width];
            self.runs = 0;
        }
        // Run after run (each run's values are contiguous): min and max per record and output.
        for run in &values[self.runs..] {
            for ((lowest, highest), &v) in self.lowest.iter_mut().zip(&mut self.highest).zip(run) {
                *lowest = lowest.min(v);
                *highest = highest.max(v);
            }
            for record in run.chunks_exact(width) {
                for (m, v) in self.magnitude.iter_mut().zip(record) {
                    *m = m.max(v.abs());
                }
            }
        }
        self.runs = values.len();
    }

    /// Per output: its largest spread (max − min over the runs folded in) over the records, or
    /// `None` when that is below the noise floor ([`ADAPTIVE_NOISE_FLOOR`]).
    fn spreads(&self, n_outputs: usize) -> Vec<Option<f64>> {
        let width = n_outputs.max(1);
        let stride = self.lowest.len();
        (0..n_outputs)
            .map(|o| {
                let spread = (o..stride)
                    .step_by(width)
                    .map(|k| self.highest[k] - self.lowest[k])
                    .fold(0.0_f64, f64::max);
                (spread.is_finite() && spread > ADAPTIVE_NOISE_FLOOR * (1.0 + self.magnitude[o]))
                    .then_some(spread)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// The coefficients a stage's fit of every record at once hands to the bounding are, record
    /// by record, those the grid's fit of that record's values alone gives, to the bit: records
    /// in several chunks (the last one short), runs stored out of grid order, and a second stage
    /// on a grown set that keeps the first stage's surpluses and reuses its chunks' memory.
    /// Two stages' runs: the grids of total degree 2 and 3 in three parameters, the runs' terms
    /// (the small set's first, then the grown set's others; each part from its last term when
    /// `reversed`) and every run's random values (`n_records × n_outputs`, from `seed`).
    struct TwoStages {
        small: SparseGrid,
        grown: SparseGrid,
        run_terms: Vec<Vec<Factor>>,
        values: Vec<Vec<f64>>,
    }

    fn two_stages(n_outputs: usize, n_records: usize, seed: u64, reversed: bool) -> TwoStages {
        use crate::uq::MultiIndexSet;
        let grid = |degree| {
            SparseGrid::new(Arc::new(
                MultiIndexSet::total_degree(3, degree).expect("set"),
            ))
            .expect("grid")
        };
        let (small, grown) = (grid(2), grid(3));
        let order = |n: usize| -> Vec<usize> {
            if reversed {
                (0..n).rev().collect()
            } else {
                (0..n).collect()
            }
        };
        let mut run_terms: Vec<Vec<Factor>> = order(small.n_points())
            .into_iter()
            .map(|t| small.set().term(t).to_vec())
            .collect();
        for t in order(grown.n_points()) {
            let term = grown.set().term(t);
            if small.set().index_of(term).is_none() {
                run_terms.push(term.to_vec());
            }
        }
        let mut rng = SplitMix64::new(seed);
        let values: Vec<Vec<f64>> = run_terms
            .iter()
            .map(|_| {
                (0..n_records * n_outputs)
                    .map(|_| rng.uniform(-2.0, 2.0))
                    .collect()
            })
            .collect();
        TwoStages {
            small,
            grown,
            run_terms,
            values,
        }
    }

    impl TwoStages {
        /// Per point of `grid`, the row of its run.
        fn rows_of(&self, grid: &SparseGrid) -> Vec<usize> {
            (0..grid.n_points())
                .map(|t| {
                    let term = grid.set().term(t);
                    self.run_terms
                        .iter()
                        .position(|r| r.as_slice() == term)
                        .expect("run")
                })
                .collect()
        }
    }

    #[test]
    fn a_record_of_the_stage_fit_is_the_fit_of_that_record() {
        let n_outputs = 4;
        let n_records = 2 * FIT_CHUNK_RECORDS + 5;
        // Runs in the order their terms came: the small set's last term first, then the grown
        // set's other terms, again from the last.
        let stages = two_stages(n_outputs, n_records, 56, true);
        let TwoStages {
            small,
            grown,
            values,
            ..
        } = &stages;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("pool");
        let mut surpluses = Surpluses::default();
        let mut recycled = Vec::new();
        for grid in [small, grown] {
            let n_points = grid.n_points();
            let rows = stages.rows_of(grid);
            let values = &values[..n_points];
            let (coefficients, _) = fit_all_records(
                grid,
                &rows,
                values,
                n_outputs,
                &pool,
                &mut surpluses,
                std::mem::take(&mut recycled),
            )
            .expect("fit");
            assert_eq!(surpluses.runs, n_points);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            let mut largest = vec![0.0_f64; n_points * n_outputs];
            for r in 0..n_records {
                let record = gather_record(values, &rows, r, n_outputs);
                let alone = grid
                    .fit()
                    .fit(&record, n_outputs)
                    .expect("fit of one record");
                let handed = coefficients.record(r, n_outputs);
                assert_eq!(bits(&handed), bits(&alone), "{n_points} points, record {r}");
                for (m, c) in largest.iter_mut().zip(&alone) {
                    *m = m.max(c.abs());
                }
            }
            // Each term's and output's largest magnitude over the records, which the indicators
            // divide by the spreads.
            assert_eq!(bits(&coefficients.largest), bits(&largest));
            let spread = vec![Some(0.5); n_outputs];
            let t = n_points - 1;
            let want = largest[t * n_outputs..(t + 1) * n_outputs]
                .iter()
                .fold(0.0_f64, |m, &c| m.max(c / 0.5));
            assert_eq!(coefficients.largest_normalised(t, &spread), want);
            // Past the last record: in the last chunk's range, and beyond every chunk.
            assert!(coefficients.record(n_records, n_outputs).is_empty());
            assert!(coefficients
                .record(n_records + FIT_CHUNK_RECORDS, n_outputs)
                .is_empty());
            recycled = coefficients.chunks;
        }
    }

    /// The last stage's fit, chunk group after chunk group as its blocks of records come in
    /// ([`StageRuns::fit_chunks`] from a later chunk on, as `LastStage::fit_through` calls it),
    /// gives the coefficients and largest magnitudes of the fit of every record at once, to the
    /// bit, keeping the earlier stage's surpluses either way.
    #[test]
    fn the_last_stage_fitted_chunk_by_chunk_is_the_fit_of_every_record() {
        let n_outputs = 3;
        let n_records = 3 * FIT_CHUNK_RECORDS + 7;
        let stages = two_stages(n_outputs, n_records, 91, false);
        let TwoStages {
            small,
            grown,
            values,
            ..
        } = &stages;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("pool");
        let earlier_stage = || {
            let mut surpluses = Surpluses::default();
            let small_rows = stages.rows_of(small);
            fit_all_records(
                small,
                &small_rows,
                &values[..small.n_points()],
                n_outputs,
                &pool,
                &mut surpluses,
                Vec::new(),
            )
            .expect("fit");
            surpluses
        };
        let rows = stages.rows_of(grown);
        let (whole, _) = fit_all_records(
            grown,
            &rows,
            values,
            n_outputs,
            &pool,
            &mut earlier_stage(),
            Vec::new(),
        )
        .expect("fit");
        // Chunk by chunk: the first chunk alone, then the next two, then the short last one.
        let mut surpluses = earlier_stage();
        let n_terms = grown.n_points();
        let kept = surpluses.keep_for(n_terms, n_records, n_outputs);
        assert_eq!(kept, small.n_points());
        let term_of_run = terms_of_runs(&rows, n_terms, values.len()).expect("runs");
        let runs = StageRuns {
            grid: grown,
            rows: &rows,
            values,
            n_outputs,
            n_records,
            kept,
            new_terms: &term_of_run[kept..],
        };
        let mut by_chunks = RecordCoefficients::empty(n_terms, n_outputs);
        for chunks in [0..1, 1..3, 3..4] {
            let buffers = chunks.clone().map(|_| Vec::new()).collect();
            let first = chunks.start;
            for chunk in runs
                .fit_chunks(first, &mut surpluses.chunks[chunks], buffers, &pool)
                .expect("fit")
            {
                by_chunks.push(chunk);
            }
        }
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        for r in 0..n_records {
            assert_eq!(
                bits(&by_chunks.record(r, n_outputs)),
                bits(&whole.record(r, n_outputs)),
                "record {r}"
            );
        }
        assert_eq!(bits(&by_chunks.largest), bits(&whole.largest));
    }

    /// A run's non-finite value is an error naming it, whether the run is new or not; runs that
    /// are not one per grid point are an error, not a panic.
    #[test]
    fn a_stage_fit_names_a_non_finite_value_and_refuses_mismatched_runs() {
        use crate::uq::MultiIndexSet;
        let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(2, 2).expect("set")))
            .expect("grid");
        let n = grid.n_points();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let rows: Vec<usize> = (0..n).collect();
        let mut values = vec![vec![1.0; 3]; n];
        values[2][1] = f64::NAN;
        let mut surpluses = Surpluses::default();
        let error = fit_all_records(&grid, &rows, &values, 1, &pool, &mut surpluses, Vec::new())
            .err()
            .expect("a NaN is an error");
        assert!(error.to_string().contains("NaN"), "{error}");
        let short = &values[..n - 1];
        assert!(
            fit_all_records(&grid, &rows, short, 1, &pool, &mut surpluses, Vec::new()).is_err()
        );
    }

    /// Spreads of every run at once, as each stage computed them before [`RunExtremes`].
    fn spreads_from_scratch(values: &[Vec<f64>], n_outputs: usize) -> Vec<Option<f64>> {
        let mut extremes = RunExtremes::new();
        extremes.absorb(values, n_outputs);
        extremes.spreads(n_outputs)
    }

    /// Folding the runs in stage by stage gives every stage the spreads of all its runs at once,
    /// bit for bit (a NaN among them and an output without signal included), and a shorter set
    /// of runs (an interrupted stage's truncation) starts over.
    #[test]
    fn stage_by_stage_extremes_are_those_of_every_run() {
        let mut rng = SplitMix64::new(20);
        let (records, n_outputs) = (5, 3);
        let mut values: Vec<Vec<f64>> = Vec::new();
        let mut extremes = RunExtremes::new();
        for stage in 0..6 {
            for _ in 0..=stage {
                let mut run: Vec<f64> = (0..records * n_outputs)
                    .map(|_| rng.uniform(-2.0, 3.0))
                    .collect();
                // Output 2 carries no signal: the same value in every run.
                for record in run.chunks_exact_mut(n_outputs) {
                    record[2] = 0.5;
                }
                if stage == 3 {
                    run[4] = f64::NAN;
                }
                values.push(run);
            }
            extremes.absorb(&values, n_outputs);
            let expected = spreads_from_scratch(&values, n_outputs);
            let bits =
                |s: &[Option<f64>]| s.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>();
            assert_eq!(
                bits(&extremes.spreads(n_outputs)),
                bits(&expected),
                "stage {stage}"
            );
            // One run has no spread; from two on, outputs 0 and 1 have one and output 2 none.
            assert_eq!(expected[0].is_some(), values.len() > 1);
            assert!(expected[2].is_none());
        }
        values.truncate(4);
        extremes.absorb(&values, n_outputs);
        let bits = |s: &[Option<f64>]| s.iter().map(|v| v.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(
            bits(&extremes.spreads(n_outputs)),
            bits(&spreads_from_scratch(&values, n_outputs))
        );
    }
}
