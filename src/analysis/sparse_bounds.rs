//! The sparse design's envelopes, block by block (docs/high-dimension.md §7): every record's
//! surrogates fitted at once, then each output's record times bounded in order, each side of the
//! inner bound searched from its own starts — the vertex of the linear part on that side, the
//! design points with that side's best values (the best from itself, the other from where its
//! descent ended at the previous record time when it was a start there too), and where the
//! previous record time's extreme was (extremes move continuously in time, so that start is
//! usually one Newton step from the answer). The search runs on the record's surrogate less its
//! smallest terms ([`PRUNED_MASS_PER_SPREAD`]); the extreme reported is the fitted surrogate's
//! value where it ended.
//!
//! ```text
//! block 0: (parallel over records) fit (or the caller's coefficients: RecordFits) ⇒ per
//!            output: best design points, outer bound, Sobol' indices
//! block b: one queue for the threads, longest first:
//!            per output and side, record after record: starts (vertex, best design points,
//!              previous extreme) ⇒ that side's inner bound ⇒ the previous extreme for the next
//!            then block b + 1's records: fit ⇒ per output: best design points, outer bound,
//!              Sobol' indices
//!          ⇒ per record: outer = the outer bound widened to the inner one, the runs taken in
//! ```
//!
//! Each side of an output runs its records in order on one thread and carries its extreme
//! across blocks, so the results depend neither on the thread count nor on the block size. The
//! two sides of an output share nothing, so they are separate tasks: 2 × outputs of them balance
//! over the threads better than the outputs alone (9 outputs on 2 threads left one thread 5 of
//! them). An output's best design points (both sides'), the outer bound and the Sobol' indices
//! need only a record's runs and fit, not the inner bound (the outer bound is widened to the
//! inner one when the block is put together), so they run in the fit's task per record.
//!
//! The schedule (issue 40): the threads take tasks from one queue in a fixed order — the sides,
//! the longest first by their time on the previous block, then the next block's records, which
//! are small and fill the gap the last side would leave (a barrier after every phase left a
//! third of the two threads' time idle). The order changes only which thread runs a task and
//! when; every task computes the same numbers from the same inputs, so the results do not
//! depend on it. A caller that has many records at once (the adaptive design) passes them all;
//! they are bounded in blocks of `block_records`, two blocks in memory at a time.
//!
//! Does not: fit or bound tensor designs, `taylor` or the runs-only methods (`bounds.rs`).

use super::bound_clock::{BoundClock, BoundPhase};
use super::bounded_block::{BoundedBlock, Extremes};
use super::bounds::include_runs;
use super::envelope::EnvelopePoint;
use super::sparse::SparseDesign;
use crate::uq::{
    outer_widened_to_inner, BoxOptimizer, SobolIndices, SparseSurrogate, SurrogateWorkspace,
    UqError,
};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

/// How many of the best design points start each side's search (the lowest values the minimum,
/// the highest the maximum), besides that side's vertex and the previous record time's extreme:
/// the runs themselves are the best evidence of where the extremes are. Two, not one: one moved
/// the d = 72 all-values ur5 study's envelopes by no more than 9.3e-6 of a width and saved a third
/// of the search, but on `benches/sparse_bounding.rs`'s problem it left four outputs' inner bounds
/// up to 1.8e-3 of their width narrower than the seven shared starts did, two only one (issue 40).
pub const DESIGN_STARTS_PER_SIDE: usize = 2;

/// How many of a side's [`DESIGN_STARTS_PER_SIDE`] design points — the best ones — descend from
/// the design point itself at every record time; the others, when they were among the side's
/// design starts at the previous record time too, descend from where their descent ended there
/// (their basin, followed in time, as the previous extreme is: usually one or two Newton steps
/// instead of four to six from the interior of the box, and often that point is the previous
/// extreme itself, a start the search then skips). The best point still descends afresh, so a
/// basin that opens between two record times is found as before. Measured on the README's
/// scaling rows (d = 8 … 64, 1 s) and the d = 72 all-values ur5 study against every design
/// point afresh (issue 40): envelopes within 9.6e-5 of a width, the inner bound's thread time
/// at d = 72 about a fifth lower. Following every design point's basin (0 here) was within
/// 6.6e-4 at d = 32 … 72 and halved that time, but at d = 16 it missed a basin for two record
/// times by 3.4e-3 of `frame.tool0.x`'s width.
pub const FRESH_DESIGN_STARTS_PER_SIDE: usize = 1;

/// The search of a side runs on the record's surrogate less some of its smallest terms
/// ([`SparseSurrogate::drop_terms`]), whose coefficients' magnitudes sum to at most this
/// fraction of the spread of the record's runs (the largest value less the smallest, runs not
/// excluded). The pruned surrogate differs from the fitted one by at most that sum anywhere in
/// the box, and the extreme reported is the fitted surrogate's value where the search ended, so
/// it is attained, and it lies within twice that sum of what a search of the fitted surrogate
/// would reach in the same basin; the envelope contains the runs, so its width is at least the
/// spread (docs/high-dimension.md §7a): at most 8e-5 of the width, inside the 1e-4 the search's
/// choices are held to. It was 1e-5 until issue 40's search needed the margin: 4e-5 drops more
/// of the small terms (the search's instructions 5.7 % fewer on the d = 32 scaling row, 3.1 % on
/// d = 64), and the envelopes of the scaling rows and the d = 72 study moved by at most 1.4e-5
/// of a width narrower and 3.9e-5 wider.
pub const PRUNED_MASS_PER_SPREAD: f64 = 4e-5;

/// A side chooses the terms to drop so that they sum to at most this fraction of the budget
/// ([`PRUNED_MASS_PER_SPREAD`]) and keeps them for the next records while they still fit the
/// whole budget: the coefficients drift slowly from record to record, and choosing them (then
/// by a sort of the terms) and building the pruned surrogate's evaluation order at every record
/// cost as much as the search it saved at d = 64.
const DROPPED_SHARE_AT_CHOICE: f64 = 0.5;

/// A side chooses its dropped terms afresh at least every this many records (the terms that
/// became small since go too).
const RECORDS_PER_CHOICE: usize = 16;

/// Record `r`'s coefficients of the design's fit, row-major `terms × outputs`, to the bit what
/// [`crate::uq::LinearFit::fit_into`] gives for its values: from a caller that fitted the
/// records already (the adaptive design's last stage), so that they are not fitted twice.
pub(super) type RecordFits<'a> = dyn Fn(usize) -> Vec<f64> + Sync + 'a;

/// What one side (minimum or maximum) of one output carries from record time to record time.
#[derive(Debug, Default, Clone)]
struct SideChain {
    /// Where the last record's extreme was attained (none before the first record).
    previous: Option<Vec<f64>>,
    /// The design points that started the last record's descents.
    followed: Vec<usize>,
    /// Where each of their descents ended, `followed.len() × d`.
    followed_ends: Vec<f64>,
    /// The seconds this side took on the last block: orders the queue (longest first), nothing
    /// else.
    last_block_seconds: f64,
    /// The terms its searches leave out ([`PRUNED_MASS_PER_SPREAD`]), ascending.
    dropped: Vec<u32>,
    /// How many times `dropped` was chosen (a thread's searched surrogate is rebuilt when it
    /// holds another side's or an older choice).
    dropped_choices: u64,
    /// Records bounded since `dropped` was chosen.
    records_since_choice: usize,
}

/// One side (minimum or maximum) of one output's inner bound at every record of a block.
#[derive(Default)]
struct SideSeries {
    /// The extreme value found per record.
    values: Vec<f64>,
    /// Where it is attained, `records × d`.
    args: Vec<f64>,
}

/// Bounds a sparse design's records (module documentation); cheap to share across threads.
#[derive(Debug)]
pub(super) struct SparseBounds {
    design: Arc<SparseDesign>,
    /// The outer bound is the envelope (`legendre-ia`).
    outer_only: bool,
    /// Search the inner bound: the envelope of the scanning method, and where the check looks.
    inner: bool,
    /// Per output side (`2·output` the minimum, `2·output + 1` the maximum), what the last
    /// record bounded left for the next: where its extreme was attained and where its design
    /// starts' descents ended (empty before the first block).
    chains: Mutex<Vec<SideChain>>,
}

/// One record fitted, with what needs no inner bound: every output's outer bound (not yet
/// widened to the inner one), error estimate and Sobol' indices.
struct FittedRecord {
    /// The design's values at the record, row-major `samples × outputs`.
    values: Vec<f64>,
    /// Row-major `terms × outputs` (`LinearFit::fit_into`).
    coefficients: Vec<f64>,
    /// Per output: the outer bound `(lower, upper)`.
    outer: Vec<(f64, f64)>,
    /// Per output: the magnitude of the top-order coefficients.
    errors: Vec<f64>,
    /// Per output: the spread of its runs not excluded ([`runs_spreads`]).
    spreads: Vec<f64>,
    /// Per output: its [`DESIGN_STARTS_PER_SIDE`] design points of lowest and of highest value,
    /// each in increasing order of (value, index) (empty without the inner bound).
    lowest: Vec<Vec<usize>>,
    highest: Vec<Vec<usize>>,
    /// `outputs × d`.
    main_indices: Vec<f64>,
    /// `outputs × d`.
    total_indices: Vec<f64>,
    /// Per output.
    variances: Vec<f64>,
}

/// One task of a block's queue (module documentation).
#[derive(Clone, Copy)]
enum Task {
    /// One output side (`2·output` the minimum, `2·output + 1` the maximum) at every record of
    /// the block.
    Side(usize),
    /// One record of the next block (its place in that block): fitted, outer bounds, indices.
    Fit(usize),
}

/// Per-thread buffers.
struct Workspace {
    surrogate: SparseSurrogate,
    /// The surrogate a side's search runs on: `surrogate` without the side's dropped terms
    /// ([`PRUNED_MASS_PER_SPREAD`]).
    searched: SparseSurrogate,
    /// Whose dropped terms `searched` has: (side, `SideChain::dropped_choices`).
    searched_drops: Option<(usize, u64)>,
    optimizer: BoxOptimizer,
    indices: SobolIndices,
    /// Start points of one side, row-major.
    starts: Vec<f64>,
    /// Where one side's extreme is attained.
    arg: Vec<f64>,
    /// The fitted surrogate's evaluation buffers.
    evaluation: SurrogateWorkspace,
    /// The design points with the lowest and the highest values.
    lowest: Vec<usize>,
    highest: Vec<usize>,
}

/// A slot a task fills, read once the queue is done.
type Slot<T> = Mutex<Option<Result<T, UqError>>>;

/// Locks `mutex`; a poisoned one (a panicking task) still holds its data.
fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What a filled slot holds, in slot order (the first error by slot, whatever the timing).
fn take_slots<T>(slots: Vec<Slot<T>>, what: &'static str) -> Result<Vec<T>, UqError> {
    let expected = slots.len();
    slots
        .into_iter()
        .enumerate()
        .map(|(got, slot)| {
            slot.into_inner()
                .unwrap_or_else(PoisonError::into_inner)
                .unwrap_or(Err(UqError::WrongLength {
                    what,
                    expected,
                    got,
                }))
        })
        .collect()
}

impl SparseBounds {
    /// Bounds for `design`: `outer_only` reports the outer bound (`legendre-ia`), `inner`
    /// searches the inner one as well (always, unless `outer_only` and no check follows).
    pub(super) fn new(design: Arc<SparseDesign>, outer_only: bool, inner: bool) -> SparseBounds {
        SparseBounds {
            design,
            outer_only,
            inner: inner || !outer_only,
            chains: Mutex::new(Vec::new()),
        }
    }

    /// The envelopes of `records` record times after the ones bounded before (in order), from
    /// `values(r)` (row-major `samples × outputs`), widened to every run not `excluded`; in
    /// blocks of `block_records` (module documentation).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn bound(
        &self,
        records: usize,
        n_outputs: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        given_fits: Option<&RecordFits<'_>>,
        block_records: usize,
        clock: &BoundClock,
        threads: &rayon::ThreadPool,
    ) -> Result<BoundedBlock, UqError> {
        let block_records = block_records.max(1);
        let mut out = BoundedBlock {
            points: Vec::with_capacity(records * n_outputs),
            extremes: Vec::with_capacity(records * n_outputs),
            ..BoundedBlock::default()
        };
        let mut chains = lock(&self.chains);
        if chains.len() != 2 * n_outputs {
            *chains = vec![SideChain::default(); 2 * n_outputs];
        }
        let mut fitted = threads.install(|| {
            (0..block_records.min(records))
                .into_par_iter()
                .map_init(
                    || self.workspace(),
                    |ws, r| {
                        let coefficients = given_fits.map(|fits| fits(r));
                        self.fit_record(values(r), coefficients, n_outputs, excluded, ws, clock)
                    },
                )
                .collect::<Result<Vec<FittedRecord>, UqError>>()
        })?;
        let mut first = 0;
        while first < records {
            let next_first = first + fitted.len();
            let next = next_first..next_first.saturating_add(block_records).min(records);
            let (sides, next_fitted) = self.run_queue(
                &fitted,
                next,
                n_outputs,
                values,
                excluded,
                given_fits,
                &mut chains,
                clock,
                threads,
            )?;
            self.put_together(&fitted, &sides, n_outputs, excluded, &mut out);
            first = next_first;
            fitted = next_fitted;
        }
        Ok(out)
    }

    /// Runs one block's queue on the threads (module documentation): every side over the
    /// records `fitted` (when the inner bound is searched), the longest first, then the records
    /// `next` fitted. Returns the sides' series by side and the next block's records in order.
    #[allow(clippy::too_many_arguments)]
    fn run_queue(
        &self,
        fitted: &[FittedRecord],
        next: std::ops::Range<usize>,
        n_outputs: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        given_fits: Option<&RecordFits<'_>>,
        chains: &mut [SideChain],
        clock: &BoundClock,
        threads: &rayon::ThreadPool,
    ) -> Result<(Vec<SideSeries>, Vec<FittedRecord>), UqError> {
        let n_sides = if self.inner { chains.len() } else { 0 };
        let mut order: Vec<usize> = (0..n_sides).collect();
        // Stable: sides that took as long (the first block: all) keep their index order.
        order.sort_by(|&a, &b| {
            chains[b]
                .last_block_seconds
                .total_cmp(&chains[a].last_block_seconds)
        });
        let tasks: Vec<Task> = order
            .into_iter()
            .map(Task::Side)
            .chain((0..next.len()).map(Task::Fit))
            .collect();
        let chains: Vec<Mutex<&mut SideChain>> = chains.iter_mut().map(Mutex::new).collect();
        let sides: Vec<Slot<SideSeries>> = (0..n_sides).map(|_| Mutex::new(None)).collect();
        let fits: Vec<Slot<FittedRecord>> = next.clone().map(|_| Mutex::new(None)).collect();
        let taken = AtomicUsize::new(0);
        let worker = || {
            let mut ws = self.workspace();
            while let Some(&task) = tasks.get(taken.fetch_add(1, Ordering::Relaxed)) {
                match task {
                    Task::Side(side) => {
                        let started = Instant::now();
                        let mut chain = lock(&chains[side]);
                        let series = self.bound_side(
                            side / 2,
                            side % 2 == 1,
                            fitted,
                            n_outputs,
                            &mut chain,
                            &mut ws,
                            clock,
                        );
                        chain.last_block_seconds = started.elapsed().as_secs_f64();
                        *lock(&sides[side]) = Some(series);
                    }
                    Task::Fit(i) => {
                        let record = self.fit_record(
                            values(next.start + i),
                            given_fits.map(|fits| fits(next.start + i)),
                            n_outputs,
                            excluded,
                            &mut ws,
                            clock,
                        );
                        *lock(&fits[i]) = Some(record);
                    }
                }
            }
        };
        let workers = threads.current_num_threads().min(tasks.len());
        threads.install(|| {
            rayon::scope(|scope| {
                for _ in 0..workers {
                    scope.spawn(|_| worker());
                }
            });
        });
        let sides = take_slots(sides, "sparse bounds: a side's task did not run")?;
        let fits = take_slots(fits, "sparse bounds: a record's fit did not run")?;
        Ok((sides, fits))
    }

    fn workspace(&self) -> Workspace {
        let set = self.design.set();
        Workspace {
            surrogate: SparseSurrogate::zeros(Arc::clone(set)),
            searched: SparseSurrogate::zeros(Arc::clone(set)),
            searched_drops: None,
            optimizer: BoxOptimizer::new(),
            indices: SobolIndices::zeros(set.dim()),
            starts: Vec::new(),
            arg: Vec::new(),
            evaluation: SurrogateWorkspace::new(),
            lowest: Vec::new(),
            highest: Vec::new(),
        }
    }

    /// One record's fit from its `values` (or its `coefficients`, when the caller has them), and
    /// every output's outer bound, error estimate and Sobol' indices.
    fn fit_record(
        &self,
        values: Vec<f64>,
        coefficients: Option<Vec<f64>>,
        n_outputs: usize,
        excluded: &(dyn Fn(usize) -> bool + Sync),
        ws: &mut Workspace,
        clock: &BoundClock,
    ) -> Result<FittedRecord, UqError> {
        let design = &*self.design;
        let d = design.set().dim();
        let mut lap = Instant::now();
        let n_coefficients = design.set().len() * n_outputs;
        let coefficients = match coefficients {
            Some(given) if given.len() == n_coefficients => given,
            Some(given) => {
                return Err(UqError::WrongLength {
                    what: "sparse bounds: a record's coefficients (terms × outputs)",
                    expected: n_coefficients,
                    got: given.len(),
                })
            }
            None => {
                let mut fitted = vec![0.0; n_coefficients];
                design.fit().fit_into(&values, n_outputs, &mut fitted)?;
                fitted
            }
        };
        lap = clock.lap(BoundPhase::Fit, lap);
        let spreads = runs_spreads(&values, n_outputs, excluded);
        let (mut lowest, mut highest) = (Vec::new(), Vec::new());
        if self.inner {
            for o in 0..n_outputs {
                extreme_design_points(
                    design.n_points(),
                    |p| values[p * n_outputs + o],
                    DESIGN_STARTS_PER_SIDE,
                    &mut ws.lowest,
                    &mut ws.highest,
                );
                lowest.push(ws.lowest.clone());
                highest.push(ws.highest.clone());
            }
            lap = clock.lap(BoundPhase::Inner, lap);
        }
        let mut record = FittedRecord {
            spreads,
            lowest,
            highest,
            values,
            coefficients,
            outer: Vec::with_capacity(n_outputs),
            errors: Vec::with_capacity(n_outputs),
            main_indices: Vec::with_capacity(n_outputs * d),
            total_indices: Vec::with_capacity(n_outputs * d),
            variances: Vec::with_capacity(n_outputs),
        };
        for o in 0..n_outputs {
            ws.surrogate
                .set_from_fit(&record.coefficients, n_outputs, o)?;
            lap = clock.lap(BoundPhase::Fit, lap);
            record.errors.push(ws.surrogate.top_order_magnitude());
            record.outer.push(ws.optimizer.outer_bound(&ws.surrogate));
            lap = clock.lap(BoundPhase::Outer, lap);
            ws.surrogate.sobol_indices_into(&mut ws.indices);
            record.main_indices.extend_from_slice(&ws.indices.main);
            record.total_indices.extend_from_slice(&ws.indices.total);
            record.variances.push(ws.indices.variance);
            lap = clock.lap(BoundPhase::Sobol, lap);
        }
        Ok(record)
    }

    /// The block's envelope points into `out`, record after record: the inner bound (`sides`,
    /// when searched) with the outer bound widened to it, or the outer bound alone
    /// (`legendre-ia`), then widened to the record's runs not `excluded`.
    fn put_together(
        &self,
        fitted: &[FittedRecord],
        sides: &[SideSeries],
        n_outputs: usize,
        excluded: &(dyn Fn(usize) -> bool + Sync),
        out: &mut BoundedBlock,
    ) {
        let d = self.design.set().dim();
        for (r, record) in fitted.iter().enumerate() {
            let first_point = out.points.len();
            for o in 0..n_outputs {
                let error = Some(record.errors[o]);
                let (outer_lower, outer_upper) = record.outer[o];
                let inner = sides.get(2 * o).zip(sides.get(2 * o + 1));
                out.extremes.push(inner.map(|(lower, upper)| Extremes {
                    argmin: lower.args[r * d..(r + 1) * d].to_vec(),
                    argmax: upper.args[r * d..(r + 1) * d].to_vec(),
                    at_min: lower.values[r],
                    at_max: upper.values[r],
                }));
                out.points.push(match inner {
                    Some((lower, upper)) if !self.outer_only => {
                        let (lower, upper) = (lower.values[r], upper.values[r]);
                        EnvelopePoint {
                            lower,
                            upper,
                            error,
                            outer: Some(outer_widened_to_inner(record.outer[o], lower, upper)),
                        }
                    }
                    _ => EnvelopePoint {
                        lower: outer_lower,
                        upper: outer_upper,
                        error,
                        outer: None,
                    },
                });
            }
            out.main_indices.extend_from_slice(&record.main_indices);
            out.total_indices.extend_from_slice(&record.total_indices);
            out.variances.extend_from_slice(&record.variances);
            include_runs(
                &mut out.points[first_point..],
                &record.values,
                n_outputs,
                excluded,
            );
        }
    }

    /// One side of output `o` (`maximum`: the upper one) at every record of `fitted`, in order,
    /// starting from what `chain` carries and leaving there what the last record leaves for the
    /// next.
    #[allow(clippy::too_many_arguments)]
    fn bound_side(
        &self,
        o: usize,
        maximum: bool,
        fitted: &[FittedRecord],
        n_outputs: usize,
        chain: &mut SideChain,
        ws: &mut Workspace,
        clock: &BoundClock,
    ) -> Result<SideSeries, UqError> {
        let design = &*self.design;
        let d = design.set().dim();
        let records = fitted.len();
        let mut series = SideSeries {
            values: Vec::with_capacity(records),
            args: Vec::with_capacity(records * d),
        };
        for record in fitted {
            let lap = Instant::now();
            ws.surrogate
                .set_from_fit(&record.coefficients, n_outputs, o)?;
            let budget = PRUNED_MASS_PER_SPREAD * record.spreads[o];
            prepare_searched(2 * o + usize::from(maximum), budget, chain, ws)?;
            let point = |p: usize| &design.points()[p * d..(p + 1) * d];
            // In increasing order of value: the best of the minimum first, of the maximum last.
            let chosen = if maximum {
                &record.highest[o]
            } else {
                &record.lowest[o]
            };
            let fresh = |rank: usize| {
                if maximum {
                    rank + FRESH_DESIGN_STARTS_PER_SIDE >= chosen.len()
                } else {
                    rank < FRESH_DESIGN_STARTS_PER_SIDE
                }
            };
            ws.starts.clear();
            for (rank, &p) in chosen.iter().enumerate() {
                match chain.followed.iter().position(|&q| q == p) {
                    Some(i) if !fresh(rank) => ws
                        .starts
                        .extend_from_slice(&chain.followed_ends[i * d..(i + 1) * d]),
                    _ => ws.starts.extend_from_slice(point(p)),
                }
            }
            if let Some(previous) = chain.previous.as_ref() {
                ws.starts.extend_from_slice(previous);
            }
            ws.optimizer.extreme_from_starts_into(
                &ws.searched,
                maximum,
                &ws.starts,
                &mut ws.arg,
            )?;
            // The fitted surrogate's value where the search of the pruned one ended: attained.
            let extreme = ws.surrogate.eval(&ws.arg, &mut ws.evaluation)?;
            series.values.push(extreme);
            series.args.extend_from_slice(&ws.arg);
            match &mut chain.previous {
                Some(previous) => previous.copy_from_slice(&ws.arg),
                None => chain.previous = Some(ws.arg.clone()),
            }
            chain.followed.clear();
            chain.followed.extend_from_slice(chosen);
            chain.followed_ends.clear();
            for rank in 0..chosen.len() {
                let end = ws
                    .optimizer
                    .given_start_end(rank)
                    .ok_or(UqError::WrongLength {
                        what: "sparse bounds: the descents of a side's design starts",
                        expected: chosen.len(),
                        got: rank,
                    })?;
                chain.followed_ends.extend_from_slice(end);
            }
            clock.lap(BoundPhase::Inner, lap);
        }
        Ok(series)
    }
}

/// Loads `ws.searched` with `ws.surrogate` (the record's fit) less the side's dropped
/// terms, chosen afresh when they no longer fit `budget` or every [`RECORDS_PER_CHOICE`]
/// records (`chain` carries them from record to record, so the choice depends on the
/// records alone, not on the blocks or the threads).
fn prepare_searched(
    side: usize,
    budget: f64,
    chain: &mut SideChain,
    ws: &mut Workspace,
) -> Result<(), UqError> {
    let c = ws.surrogate.coefficients();
    let mass: f64 = chain.dropped.iter().map(|&t| c[t as usize].abs()).sum();
    chain.records_since_choice += 1;
    if mass > budget || chain.records_since_choice >= RECORDS_PER_CHOICE {
        ws.surrogate
            .smallest_terms_into(DROPPED_SHARE_AT_CHOICE * budget, &mut chain.dropped);
        chain.dropped_choices += 1;
        chain.records_since_choice = 0;
    }
    let choice = Some((side, chain.dropped_choices));
    if ws.searched_drops != choice {
        ws.searched.drop_terms(&chain.dropped)?;
        ws.searched_drops = choice;
    }
    ws.searched.set_coefficients(ws.surrogate.coefficients())
}

/// Per output, the largest value of the runs not `excluded` less the smallest (`values`
/// row-major `runs × n_outputs`; finite values only; 0 without two such runs): a width the
/// output's envelope is at least as wide as (it contains those runs).
fn runs_spreads(
    values: &[f64],
    n_outputs: usize,
    excluded: &(dyn Fn(usize) -> bool + Sync),
) -> Vec<f64> {
    let mut lowest = vec![f64::INFINITY; n_outputs];
    let mut highest = vec![f64::NEG_INFINITY; n_outputs];
    for (run, row) in values.chunks_exact(n_outputs.max(1)).enumerate() {
        if excluded(run) {
            continue;
        }
        for ((lo, hi), &v) in lowest.iter_mut().zip(&mut highest).zip(row) {
            if v.is_finite() {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
        }
    }
    lowest
        .iter()
        .zip(&highest)
        .map(|(&lo, &hi)| if hi >= lo { hi - lo } else { 0.0 })
        .collect()
}

/// The `k` design points of lowest value into `lowest` and the `k` of highest into `highest`,
/// both in increasing order of (value, index) — the first `k` and the last `k` of the points
/// sorted that way — without sorting all `n`. The points come in increasing index, so a point
/// enters `lowest` only with a value strictly below its last one's and `highest` with one not
/// below its first one's (a tie orders the later index after): one comparison with a kept value
/// per list and point.
fn extreme_design_points(
    n: usize,
    value: impl Fn(usize) -> f64,
    k: usize,
    lowest: &mut Vec<usize>,
    highest: &mut Vec<usize>,
) {
    let before = |a: usize, b: usize| value(a).total_cmp(&value(b)).then(a.cmp(&b)).is_lt();
    lowest.clear();
    highest.clear();
    let k = k.min(n);
    if k == 0 {
        return;
    }
    let (mut lowest_last, mut highest_first) = (f64::NAN, f64::NAN);
    for p in 0..n {
        let v = value(p);
        if lowest.len() < k || v.total_cmp(&lowest_last).is_lt() {
            let at = lowest.partition_point(|&q| before(q, p));
            lowest.insert(at, p);
            lowest.truncate(k);
            lowest_last = value(lowest[lowest.len() - 1]);
        }
        if highest.len() < k || v.total_cmp(&highest_first).is_ge() {
            let at = highest.partition_point(|&q| before(q, p));
            highest.insert(at, p);
            if highest.len() > k {
                highest.remove(0);
            }
            highest_first = value(highest[0]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// Bounds `records` record times of a d = 4 total-degree design (three outputs, smooth in ξ
    /// and drifting in time) in two calls split at `split`, in blocks of `block_records`, on
    /// `threads` threads; the blocks as text (`{:?}` writes every float exactly).
    fn bounded_text(records: usize, split: usize, block_records: usize, threads: usize) -> String {
        let design = Arc::new(SparseDesign::total_degree(4, 3).expect("design"));
        let (d, n_outputs) = (4, 3);
        let points = design.points().to_vec();
        let values = move |r: usize| -> Vec<f64> {
            let t = r as f64 * 0.3;
            points
                .chunks_exact(d)
                .flat_map(|x| {
                    [
                        (t + x[0]).sin() * x[1] + 0.3 * x[2] * x[2] - 0.1 * x[3],
                        x[0] * x[1] * x[2] + t.cos() * x[3] * x[3],
                        (x[0] - 0.2 * t).powi(2) - x[1] * x[3],
                    ]
                })
                .collect()
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let bounds = SparseBounds::new(design, false, true);
        let clock = BoundClock::default();
        let none = |_: usize| false;
        let head = bounds
            .bound(
                split,
                n_outputs,
                &values,
                &none,
                None,
                block_records,
                &clock,
                &pool,
            )
            .expect("first call");
        let tail = bounds
            .bound(
                records - split,
                n_outputs,
                &|r| values(split + r),
                &none,
                None,
                block_records,
                &clock,
                &pool,
            )
            .expect("second call");
        let mut all = head;
        all.points.extend(tail.points);
        all.extremes.extend(tail.extremes);
        all.main_indices.extend(tail.main_indices);
        all.total_indices.extend(tail.total_indices);
        all.variances.extend(tail.variances);
        assert_eq!(all.points.len(), records * n_outputs);
        for point in &all.points {
            let (outer_lower, outer_upper) = point.outer.expect("an outer bound");
            assert!(
                outer_lower <= point.lower
                    && point.lower <= point.upper
                    && point.upper <= outer_upper,
                "{point:?}"
            );
        }
        format!("{all:?}")
    }

    #[test]
    fn the_bounds_depend_neither_on_blocks_nor_calls_nor_threads() {
        let reference = bounded_text(9, 9, usize::MAX, 1);
        for (split, block_records, threads) in
            [(9, 1, 2), (4, 2, 2), (0, 4, 1), (5, 50, 2), (3, 3, 3)]
        {
            // Not assert_eq!: the texts are long; a difference is all there is to say.
            assert!(
                bounded_text(9, split, block_records, threads) == reference,
                "split {split}, blocks of {block_records}, {threads} threads: other bounds"
            );
        }
    }

    /// Each side searches the record's surrogate less its smallest terms, but the extreme it
    /// reports is the fitted surrogate's value where its search ended, bit for bit (so the
    /// inner bound is attained), inside the envelope.
    #[test]
    fn reported_extremes_are_the_fitted_surrogates_values_at_their_points() {
        let design = Arc::new(SparseDesign::total_degree(5, 3).expect("design"));
        let (d, n_outputs, records) = (5, 2, 20);
        let points = design.points().to_vec();
        // Outputs whose coefficients span many decades, so that terms are dropped.
        let values = |r: usize| -> Vec<f64> {
            let t = r as f64 * 0.1;
            points
                .chunks_exact(d)
                .flat_map(|x| {
                    [
                        (t + x[0]).sin() + 1e-4 * x[1] * x[2] * x[3] + 1e-9 * x[4].powi(3),
                        (1.0 + t) * x[0] * x[1] + 1e-7 * (x[2] * x[3]).cos() + 0.3 * x[4],
                    ]
                })
                .collect()
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("pool");
        let bounds = SparseBounds::new(Arc::clone(&design), false, true);
        let none = |_: usize| false;
        let bounded = bounds
            .bound(
                records,
                n_outputs,
                &values,
                &none,
                None,
                7,
                &BoundClock::default(),
                &pool,
            )
            .expect("bounds");
        let mut fitted = SparseSurrogate::zeros(Arc::clone(design.set()));
        let mut ws = SurrogateWorkspace::new();
        let mut coefficients = vec![0.0; design.set().len() * n_outputs];
        let mut dropped_somewhere = false;
        for r in 0..records {
            design
                .fit()
                .fit_into(&values(r), n_outputs, &mut coefficients)
                .expect("fit");
            for o in 0..n_outputs {
                fitted
                    .set_from_fit(&coefficients, n_outputs, o)
                    .expect("coefficients");
                let mut small = Vec::new();
                let spreads = runs_spreads(&values(r), n_outputs, &none);
                fitted.smallest_terms_into(
                    DROPPED_SHARE_AT_CHOICE * PRUNED_MASS_PER_SPREAD * spreads[o],
                    &mut small,
                );
                dropped_somewhere |= !small.is_empty();
                let extremes = bounded.extremes[r * n_outputs + o]
                    .as_ref()
                    .expect("extremes");
                let at_min = fitted.eval(&extremes.argmin, &mut ws).expect("value");
                let at_max = fitted.eval(&extremes.argmax, &mut ws).expect("value");
                assert_eq!(
                    at_min.to_bits(),
                    extremes.at_min.to_bits(),
                    "record {r}, output {o}"
                );
                assert_eq!(
                    at_max.to_bits(),
                    extremes.at_max.to_bits(),
                    "record {r}, output {o}"
                );
                let point = &bounded.points[r * n_outputs + o];
                assert!(point.lower <= at_min && at_max <= point.upper);
            }
        }
        assert!(dropped_somewhere, "no record had terms to drop");
    }

    #[test]
    fn extreme_design_points_are_the_ends_of_the_sorted_order() {
        let mut rng = SplitMix64::new(40);
        let (mut lowest, mut highest) = (Vec::new(), Vec::new());
        for n in [0, 1, 2, 3, 5, 50] {
            for k in [0, 1, 2, 3] {
                // Few distinct values, so that ties are ordered by index.
                let values: Vec<f64> = (0..n).map(|_| rng.uniform(0.0, 4.0).floor()).collect();
                let mut order: Vec<usize> = (0..n).collect();
                order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
                extreme_design_points(n, |p| values[p], k, &mut lowest, &mut highest);
                let take = k.min(n);
                assert_eq!(lowest, order[..take], "n = {n}, k = {k}");
                assert_eq!(highest, order[n - take..], "n = {n}, k = {k}");
            }
        }
    }
}
