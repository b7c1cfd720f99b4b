//! The design phase: the design's records — simulated here, read from a stage's record blocks,
//! or, for the adaptive design, the values its rounds already made — fitted and bounded block by
//! block into the envelopes ([`Bounder`]), with the predicted extremes collected for the check
//! ([`CheckCandidates`]) and the surrogates' Sobol' indices ([`SobolSeries`]). Every design run,
//! the nominal run and the screening's runs widen the envelopes and the hull of true runs.
//!
//! ```text
//! per block: records (samples × outputs per record) ⇒ Bounder::bound_records ⇒ envelope points
//!            ⇒ + nominal, screening hull ⇒ accumulator; argmin/argmax ⇒ candidates; indices
//! ```
//!
//! A design simulated (or read) here is bounded block by block beside the simulation of the
//! next block (`PhaseContext::run_source_beside`: the block's values are taken out of the source
//! first); the adaptive design's runs, all made already, go to the bounder in one call, which
//! works through them in blocks (`sparse_bounds.rs`) — except the stage its budget made the last
//! (`adaptive_phase::LastStage`), which runs here: each block's records are taken in, and the
//! chunks of records they complete fitted and bounded beside the next block (`bound_last_stage`;
//! interrupted, it falls back to the stage before, as the rounds do).
//!
//! Does not: choose the design (`study_plan.rs`, the screening and adaptive phases) or run the
//! check (`check_phase.rs`).

use super::accumulator::Accumulator;
use super::adaptive_phase::{AdaptiveOutcome, LastStage};
use super::bounded_block::BoundedBlock;
use super::bounds::Bounder;
use super::check::CheckCandidates;
use super::elements::ELEMENT_TENSOR_MAX_DIM;
use super::engine::RecordSource;
use super::envelope::{EnvelopePoint, Side};
use super::error::StudyError;
use super::method::Method;
use super::nested_design::{ElementRuns, MAX_KEPT_ELEMENT_VALUES};
use super::phase::PhaseContext;
use super::plan::Plan;
use super::schedule::RecordSchedule;
use super::sobol_indices::{has_sobol_indices, SobolSeries};
use super::sparse::SparseDesign;
use super::sparse_bounds::RecordFits;
use super::stages::StageCursor;
use crate::uq::SparseGrid;
use rayon::prelude::*;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

/// What the design phase bounds, once the phases before it are done.
pub(super) struct Design {
    /// The design's sample points (for the adaptive design: its final interpolation grid).
    pub plan: Plan,
    /// The adaptive design's runs, already made by its rounds (`None`: the design is run here).
    pub adapted: Option<AdaptiveOutcome>,
    /// The adaptive design's last stage, run here beside its bounding (`plan` is its final grid).
    pub last_stage: Option<Box<LastStage>>,
    /// Min/max of the screening runs per record and output (empty without screening).
    pub screen_hull: Vec<EnvelopePoint>,
}

/// What the design phase leaves for the check.
pub(super) struct Bounded {
    /// Whether every record time was bounded (false when interrupted).
    pub complete: bool,
    /// The surrogates' predicted extremes (empty unless the method locates them).
    pub candidates: CheckCandidates,
    /// The design's runs, every output, kept for elements to nest in (docs/method.md §12,
    /// "Nested elements"): only for a tensor Legendre design an element could reuse
    /// ([`keeps_design_runs`]) whose runs all succeeded.
    pub runs: Option<ElementRuns>,
}

/// Whether the design phase keeps the runs of `plan` for elements: elements are on, the plan is
/// a tensor Legendre design on Gauss nodes of at most [`ELEMENT_TENSOR_MAX_DIM`] dimensions (what a
/// child nests in), and its values fit [`MAX_KEPT_ELEMENT_VALUES`].
fn keeps_design_runs(context: &PhaseContext<'_>, plan: &Plan, n_records: usize) -> bool {
    let n_outputs = context.scene.outputs.len();
    match plan {
        Plan::Surrogate(design) => {
            context.options.elements.enabled
                && design.family() == crate::uq::Family::Legendre
                && design.has_gauss_nodes()
                && design.dim() <= ELEMENT_TENSOR_MAX_DIM
                && design
                    .n_points()
                    .checked_mul(n_records)
                    .and_then(|v| v.checked_mul(n_outputs))
                    .is_some_and(|v| v <= MAX_KEPT_ELEMENT_VALUES)
        }
        _ => false,
    }
}

/// Bounds `design` into `accumulator` (module documentation) with `method`; `locates_extremes`
/// (a check will run) locates and collects the predicted extremes for it. Sets the report's condition number (sparse
/// designs), largest total indices (sparse designs) and Sobol' series (surrogate methods).
pub(super) fn bound_design(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    design: &mut Design,
    method: Method,
    locates_extremes: bool,
    accumulator: &mut Accumulator,
) -> Result<Bounded, StudyError> {
    if let Some(last) = design.last_stage.take() {
        let plan = &design.plan;
        match bound_last_stage(
            context,
            stages,
            plan,
            *last,
            method,
            locates_extremes,
            accumulator,
        )? {
            Ok(bounded) => return Ok(bounded),
            Err(fallback) => {
                // Interrupted: the rounds' outcome without the last stage, bounded below from
                // the envelopes as they were before it.
                let (grid, outcome, before) = *fallback;
                *accumulator = before;
                let n_outputs = context.scene.outputs.len();
                context.report.adaptive = Some(outcome.report.clone());
                context.report.block_records =
                    RecordSchedule::of(context.scene).block_records(grid.n_points() + 1, n_outputs);
                design.plan = Plan::Sparse(Arc::new(SparseDesign::Grid(grid)));
                design.adapted = Some(outcome);
            }
        }
    }
    let design = &*design;
    let o = context.options;
    let d = context.space.len();
    let scene = context.scene;
    let n_outputs = scene.outputs.len();
    let schedule = RecordSchedule::of(scene);
    let n_records = schedule.len();
    let plan = &design.plan;
    if let Plan::Sparse(design) = plan {
        context.report.condition_number = Some(design.condition_number());
    }
    let bounder = Bounder::new(method, plan, d, o.order, o.scan_grid, locates_extremes)?
        .with_block_records(context.report.block_records);
    let surrogate_ranges = crate::scene::surrogate_ranges(context.model, scene);
    let mut bounding = DesignBounding::of_the_box(
        &bounder,
        context,
        locates_extremes,
        &design.screen_hull,
        &surrogate_ranges,
    );
    let complete = match &design.adapted {
        Some(outcome) => {
            // Every record at once: the bounder works through them in blocks of
            // `block_records`, the next block's fits beside this block's inner bound.
            let t_bound = Instant::now();
            let values = |r: usize| outcome.record(r, n_outputs);
            // The last adaptive stage fitted these records on this grid already.
            let fitted = |r: usize| outcome.record_coefficients(r, n_outputs);
            bounding.absorb(
                0,
                n_records,
                &values,
                &|_| false,
                Some(&fitted),
                accumulator,
            )?;
            context.report.bound_seconds += t_bound.elapsed().as_secs_f64();
            if !outcome.complete {
                context.report.partial = true;
            }
            outcome.complete
        }
        None => {
            let points = plan.points(d);
            let nominal_xi = context.space.nominal_xi();
            let mut simulated;
            let mut recorded = stages.source("design", &points, true)?;
            let source: &mut dyn RecordSource = match recorded.as_deref_mut() {
                Some(source) => source,
                None => {
                    simulated = context.lockstep(&points, Some(&nominal_xi));
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
            let policy = context.design_failure_policy(method);
            if keeps_design_runs(context, plan, n_records) {
                bounding.kept = Some(ElementRuns::new(
                    (0..n_outputs).collect(),
                    plan_samples.len(),
                ));
            }
            // The nominal run and the block's values are taken out of the source at once (the
            // next block overwrites them); the fit and bound of a block run beside the
            // simulation of the next (`PhaseContext::run_source_beside`).
            let threads = context.threads;
            let shared = Mutex::new((&mut bounding, &mut *accumulator, 0.0_f64));
            let complete = context.run_source_beside(
                "design",
                source,
                policy,
                &mut |block, _report| {
                    let t_take = Instant::now();
                    let mut guard = shared.lock().unwrap_or_else(PoisonError::into_inner);
                    let (_, accumulator, bound_seconds) = &mut *guard;
                    let lockstep = block.lockstep;
                    for r in 0..block.count {
                        accumulator.push_nominal(
                            schedule.time(block.first + r),
                            block.record(nominal_index, r),
                            lockstep.nominal_positions(r),
                        );
                    }
                    let rows = threads.install(|| {
                        (0..block.count)
                            .into_par_iter()
                            .map(|r| {
                                let mut row = Vec::with_capacity(plan_samples.len() * n_outputs);
                                for &i in &plan_samples {
                                    row.extend_from_slice(lockstep.record(i, r));
                                }
                                row
                            })
                            .collect()
                    });
                    let failed = (0..plan_samples.len())
                        .map(|i| lockstep.failed(i))
                        .collect();
                    *bound_seconds += t_take.elapsed().as_secs_f64();
                    Ok(Some(TakenBlock {
                        first: block.first,
                        count: block.count,
                        rows,
                        failed,
                    }))
                },
                &mut |taken: TakenBlock| {
                    let t_bound = Instant::now();
                    let mut guard = shared.lock().unwrap_or_else(PoisonError::into_inner);
                    let (bounding, accumulator, bound_seconds) = &mut *guard;
                    let values = |r: usize| taken.rows[r].clone();
                    let excluded = |i: usize| taken.failed[i];
                    bounding.absorb(
                        taken.first,
                        taken.count,
                        &values,
                        &excluded,
                        None,
                        accumulator,
                    )?;
                    *bound_seconds += t_bound.elapsed().as_secs_f64();
                    Ok(())
                },
            )?;
            let (_, _, bound_seconds) = shared.into_inner().unwrap_or_else(PoisonError::into_inner);
            context.report.bound_seconds += bound_seconds;
            complete
        }
    };
    Ok(bounded(context, &bounder, bounding, plan, method, complete))
}

/// What the design phase leaves once its records are bounded; the bounding's timings, largest
/// total indices (sparse designs) and Sobol' series (surrogate methods) into the report.
fn bounded(
    context: &mut PhaseContext<'_>,
    bounder: &Bounder,
    bounding: DesignBounding<'_>,
    plan: &Plan,
    method: Method,
    complete: bool,
) -> Bounded {
    context
        .report
        .phase_seconds
        .add_bounding(&bounder.phase_seconds());
    if matches!(plan, Plan::Sparse(_)) {
        context.report.total_index_max = Some(bounding.sobol.total_index_max());
    }
    if has_sobol_indices(method) {
        context.report.sobol = Some(bounding.sobol);
    }
    Bounded {
        complete,
        candidates: bounding.candidates,
        runs: bounding.kept.filter(|_| complete),
    }
}

/// The envelopes an interrupted last stage falls back to: the rounds' outcome without it (and
/// its grid), and the accumulator as it was before the stage.
type LastStageFallback = Box<(SparseGrid, AdaptiveOutcome, Accumulator)>;

/// What the blocks of the last stage share with their work beside the simulation.
struct LastStageShared<'s, 'b> {
    last: &'s mut LastStage,
    bounding: &'s mut DesignBounding<'b>,
    accumulator: &'s mut Accumulator,
    /// Wall seconds of the work.
    seconds: f64,
}

/// The adaptive design's last stage (`adaptive_phase::LastStage`): each block of its runs taken
/// as it comes, and the chunks of records it completes fitted and bounded beside the simulation
/// of the next block (`PhaseContext::run_stage_beside`), in record order as the bounding of every
/// record after the stage would take them (the same bits: the side searches carry their state
/// from record to record across calls). Returns what the design phase leaves for the check; or,
/// when the stage was interrupted, the fallback ([`LastStageFallback`]): what was bounded from
/// the stage is dropped.
fn bound_last_stage(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    plan: &Plan,
    mut last: LastStage,
    method: Method,
    locates_extremes: bool,
    accumulator: &mut Accumulator,
) -> Result<Result<Bounded, LastStageFallback>, StudyError> {
    let o = context.options;
    let d = context.space.len();
    let bounder = Bounder::new(method, plan, d, o.order, o.scan_grid, locates_extremes)?
        .with_block_records(context.report.block_records);
    let surrogate_ranges = crate::scene::surrogate_ranges(context.model, context.scene);
    let mut bounding =
        DesignBounding::of_the_box(&bounder, context, locates_extremes, &[], &surrogate_ranges);
    let before = accumulator.clone();
    let points = last.points().to_vec();
    context.report.runs += last.runs();
    let policy = context.design_failure_policy(Method::LegendreScan);
    let threads = context.threads;
    let shared = Mutex::new(LastStageShared {
        last: &mut last,
        bounding: &mut bounding,
        accumulator: &mut *accumulator,
        seconds: 0.0,
    });
    let complete = context.run_stage_beside(
        stages,
        "adaptive",
        &points,
        None,
        policy,
        &mut |block, _report| {
            let mut guard = shared.lock().unwrap_or_else(PoisonError::into_inner);
            guard.last.take_block(block);
            Ok(Some(block.first + block.count))
        },
        &mut |records_done: usize| {
            let started = Instant::now();
            let mut guard = shared.lock().unwrap_or_else(PoisonError::into_inner);
            let LastStageShared {
                last,
                bounding,
                accumulator,
                seconds,
            } = &mut *guard;
            // Computed once (the grid keeps it), in the first block's work: beside the
            // simulation.
            last.condition_number();
            let fitted = last.fit_through(records_done, threads)?;
            if !fitted.is_empty() {
                let last: &LastStage = last;
                let first = fitted.start;
                let values = |r: usize| last.record(first + r);
                let coefficients = |r: usize| last.record_coefficients(first + r);
                bounding.absorb(
                    first,
                    fitted.len(),
                    &values,
                    &|_| false,
                    Some(&coefficients),
                    accumulator,
                )?;
            }
            *seconds += started.elapsed().as_secs_f64();
            Ok(())
        },
    )?;
    let LastStageShared { seconds, .. } =
        shared.into_inner().unwrap_or_else(PoisonError::into_inner);
    context.report.bound_seconds += seconds;
    if !complete {
        context
            .report
            .phase_seconds
            .add_bounding(&bounder.phase_seconds());
        let (grid, outcome) = last.interrupted(threads)?;
        return Ok(Err(Box::new((grid, outcome, before))));
    }
    context.report.condition_number = Some(last.condition_number());
    let t_finish = Instant::now();
    let (adaptive, design_choice_seconds) = last.finish()?;
    context.report.bound_seconds += t_finish.elapsed().as_secs_f64();
    context.report.phase_seconds.design_choice += design_choice_seconds;
    context.report.adaptive = Some(adaptive);
    Ok(Ok(bounded(context, &bounder, bounding, plan, method, true)))
}

/// One block of the design's records taken out of the source: bounded while the next block is
/// simulated.
struct TakenBlock {
    /// The block's first record.
    first: usize,
    /// Records in the block.
    count: usize,
    /// Per record: the design's values, row-major `samples × outputs` (plan order).
    rows: Vec<Vec<f64>>,
    /// Per sample (plan order): whether it failed at or before the block's last record.
    failed: Vec<bool>,
}

/// Each output's known range ([`crate::scene::OutputKind::known_range`]), by output index.
pub(super) fn known_ranges(scene: &crate::scene::Scene) -> Vec<Option<(f64, f64)>> {
    scene.outputs.iter().map(|o| o.kind.known_range()).collect()
}

/// Clips a bounded block to the outputs' surrogate ranges (`crate::scene::surrogate_ranges`;
/// docs/method.md §12, "Known ranges"): the bounds and the predicted extremes, since no true value
/// lies outside the range (a surrogate of a contact force that dips below 0 where the contact is
/// open is closer to the truth clipped at 0; a joint held by its stops stays within them, up to
/// the penalty's depth). `n_outputs` outputs per record, record-major.
fn clip_to_surrogate_ranges(
    block: &mut BoundedBlock,
    surrogate_ranges: &[Option<(f64, f64)>],
    n_outputs: usize,
) {
    if surrogate_ranges.iter().all(Option::is_none) {
        return;
    }
    let clip = |value: &mut f64, (low, high): (f64, f64)| *value = value.clamp(low, high);
    for (k, point) in block.points.iter_mut().enumerate() {
        if let Some(range) = surrogate_ranges[k % n_outputs.max(1)] {
            clip(&mut point.lower, range);
            clip(&mut point.upper, range);
            if let Some((lower, upper)) = &mut point.outer {
                clip(lower, range);
                clip(upper, range);
            }
        }
    }
    for (k, extremes) in block.extremes.iter_mut().enumerate() {
        if let (Some(extremes), Some(range)) = (extremes, surrogate_ranges[k % n_outputs.max(1)]) {
            clip(&mut extremes.at_min, range);
            clip(&mut extremes.at_max, range);
        }
    }
}

/// What an element's design covers (docs/method.md §12): its sub-box, whose own standard
/// coordinates the design and the surrogates use, and which outputs its check looks at.
pub(super) struct ElementScope<'b> {
    /// The element.
    pub element: &'b crate::uq::ElementBox,
    /// Per output: whether its predicted extremes become check candidates.
    pub checked_outputs: &'b [bool],
}

/// The design's bounding: fits and bounds blocks of records into the accumulator, collecting the
/// predicted extremes for the check and the surrogates' Sobol' indices.
pub(super) struct DesignBounding<'b> {
    pub bounder: &'b Bounder,
    pub threads: &'b rayon::ThreadPool,
    pub n_outputs: usize,
    pub locates_extremes: bool,
    /// The predicted extremes, in the whole box's coordinates.
    pub candidates: CheckCandidates,
    /// The surrogates' Sobol' indices, record after record.
    pub sobol: SobolSeries,
    /// Min/max of the screening runs per record and output (empty without screening).
    pub screen_hull: &'b [EnvelopePoint],
    /// Each output's surrogate range (`crate::scene::surrogate_ranges`): bounds and predictions
    /// are clipped to it.
    pub surrogate_ranges: &'b [Option<(f64, f64)>],
    /// The element this design covers (`None`: the whole box). An element's envelopes do not take
    /// in the nominal run, which lies outside it in general; its candidates are mapped to the
    /// whole box's coordinates and kept for its checked outputs only.
    pub element: Option<ElementScope<'b>>,
    /// The design's runs, record after record, kept for elements to nest in (docs/method.md §12,
    /// "Nested elements"); `None`: not kept, or dropped once a sample was left out.
    pub kept: Option<ElementRuns>,
}

impl<'b> DesignBounding<'b> {
    /// The bounding of a design over the whole box (no element), its runs not kept.
    fn of_the_box<'c: 'b>(
        bounder: &'b Bounder,
        context: &PhaseContext<'c>,
        locates_extremes: bool,
        screen_hull: &'b [EnvelopePoint],
        surrogate_ranges: &'b [Option<(f64, f64)>],
    ) -> Self {
        let (d, n_outputs) = (context.space.len(), context.scene.outputs.len());
        DesignBounding {
            bounder,
            threads: context.threads,
            n_outputs,
            locates_extremes,
            candidates: CheckCandidates::new(d),
            sobol: SobolSeries::new(d, n_outputs),
            screen_hull,
            surrogate_ranges,
            element: None,
            kept: None,
        }
    }

    /// Bounds records `first..first + count` from the design's `values(r)` (row-major `samples ×
    /// outputs`; `given_fits(r)` their coefficients when fitted already: [`RecordFits`]);
    /// `accumulator` already holds those records' times and nominal values (the whole box; an
    /// element's accumulator holds no nominal run).
    pub fn absorb(
        &mut self,
        first: usize,
        count: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        given_fits: Option<&RecordFits<'_>>,
        accumulator: &mut Accumulator,
    ) -> Result<(), StudyError> {
        let n_outputs = self.n_outputs;
        let mut bounded = self.bounder.bound_records(
            count,
            n_outputs,
            values,
            excluded,
            given_fits,
            self.threads,
        )?;
        clip_to_surrogate_ranges(&mut bounded, self.surrogate_ranges, n_outputs);
        accumulator.points.extend_from_slice(&bounded.points);
        self.sobol.extend(&bounded);
        for r in 0..count {
            let record = first + r;
            // The design's runs (the bounds already contain them) into the hull of true runs.
            let record_values = values(r);
            let mut complete_row = true;
            for (sample, run) in record_values.chunks_exact(n_outputs.max(1)).enumerate() {
                if excluded(sample) {
                    complete_row = false;
                } else {
                    accumulator.widen_runs(record, run);
                }
            }
            if !complete_row {
                self.kept = None;
            }
            if let Some(kept) = &mut self.kept {
                kept.push_record(&record_values, n_outputs);
            }
            // The nominal run is a true response inside the box: the envelope contains it.
            if self.element.is_none() {
                let nominal =
                    accumulator.nominal[record * n_outputs..(record + 1) * n_outputs].to_vec();
                accumulator.widen(record, &nominal);
            }
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
                if let Some(scope) = &self.element {
                    if !scope.checked_outputs[o] {
                        continue;
                    }
                }
                if let Some(extremes) = &bounded.extremes[r * n_outputs + o] {
                    let point = &accumulator.points[record * n_outputs + o];
                    let width = point.upper - point.lower;
                    let (argmin, argmax) = match &self.element {
                        Some(scope) => (
                            scope.element.to_whole(&extremes.argmin),
                            scope.element.to_whole(&extremes.argmax),
                        ),
                        None => (extremes.argmin.clone(), extremes.argmax.clone()),
                    };
                    self.candidates
                        .add(record, o, Side::Lower, &argmin, extremes.at_min, width);
                    self.candidates
                        .add(record, o, Side::Upper, &argmax, extremes.at_max, width);
                }
            }
        }
        Ok(())
    }
}
