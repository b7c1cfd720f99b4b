//! Refinement of the extremes on the true model (docs/method.md §12): for every output the check
//! still does not trust, true runs chosen to reach its extremes, in four stages within one budget.
//! Every stage is a batch of true runs over the whole horizon (a lock-step phase), so every value
//! found widens the hull of true runs — the study's inner bound — at every record, and a value
//! beyond the envelope is a miss the check counts.
//!
//! ```text
//! 1. starts + gradient:  the targets' starts (the surrogates' predicted extremes) and ±h e_j at
//!                        the centre (2d runs) ⇒ every untrusted output's gradient at every record
//! 2. sign vertices:      ±sign(∇y) per (output, record, side), deduplicated, widest spread first,
//!                        round-robin over outputs and sides (CheckCandidates::select)
//! 3. flips:              from the best run so far at each output's widest record of the hull,
//!                        greedy one-flip rounds ([`FlipSearch`]) while they fit
//! 4. gradient search:    projected steepest ascent from each start ([`ExtremeSearch`]) — its
//!                        runs set aside first when a whole search fits in half the budget
//! ```
//!
//! Stages 1–3 suit responses whose extremes lie on the box's vertices (a fast divergence: a few
//! per cent of every parameter spreads the motion to its own size), where a central-difference
//! step costs `2d + 1` runs and moves a fraction of the box; stage 4 finds an interior extreme
//! at small d. What it finds is a local optimum of the true model, never an enclosure. Does not:
//! choose the starting points (the caller knows the surrogates), or judge trust
//! (`check_phase.rs`).

use super::accumulator::Accumulator;
use super::bounds::EnvelopePoint;
use super::check::CheckCandidates;
use super::check::Side;
use super::error::StudyError;
use super::phase::PhaseContext;
use super::report::{RefinedExtreme, RefinementReport};
use crate::uq::{
    ExtremeSearch, ExtremeSearchSettings, FlipSearch, FlipTarget, Probe, SearchSide, SearchTarget,
};

/// One extreme to refine: output `output` at record `record`, on `side`, from `start` (whole-box
/// coordinates ξ).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct RefineTarget {
    /// The output.
    pub output: usize,
    /// The record time it is refined at.
    pub record: usize,
    /// Which side.
    pub side: Side,
    /// Where the search starts.
    pub start: Vec<f64>,
}

/// Most of a study's `--max-runs` the elements leave for refining the extremes: a quarter.
pub const REFINE_BUDGET_FRACTION: f64 = 0.25;

/// The runs set aside for refining `outputs` untrusted outputs' extremes in `dim` dimensions
/// within `max_runs`: a full search of both sides of each (its start and
/// `ExtremeSearchSettings::max_iterations` trials, each with its `2d` differences), at most
/// [`REFINE_BUDGET_FRACTION`] of `max_runs`.
pub(super) fn refine_reserve(dim: usize, outputs: usize, max_runs: usize) -> usize {
    let per_search = (1 + ExtremeSearchSettings::default().max_iterations) * (2 * dim + 1);
    (2 * outputs * per_search).min((REFINE_BUDGET_FRACTION * max_runs as f64) as usize)
}

/// The step of the centre's central differences in ξ (stage 1): small enough that the sign of a
/// difference is the sign of the slope where the response is smooth at the centre, large enough
/// that Newton noise (§5's tolerances, ~1e-10) does not decide it. The same as the vertex
/// reference's (`analysis/reference.rs`, [`super::plan::TAYLOR_STEP`]).
pub const REFINE_GRADIENT_STEP: f64 = super::plan::TAYLOR_STEP;

/// Most of the runs left after stage 1 that the sign vertices (stage 2) may take: a half, so
/// that the flips that climb from the best of them keep as many.
pub const REFINE_VERTEX_SHARE: f64 = 0.5;

/// For every target and record, the best true value any refinement run took there, and that
/// run's point: where each stage starts from.
struct BestRuns {
    dim: usize,
    n_records: usize,
    /// Per target: its output and side.
    targets: Vec<(usize, Side)>,
    /// Target-major `targets × records`: the best value and the run (index into `points`).
    best: Vec<(f64, usize)>,
    /// Every refinement run's point, row-major.
    points: Vec<f64>,
}

impl BestRuns {
    fn new(dim: usize, n_records: usize, targets: &[RefineTarget]) -> BestRuns {
        BestRuns {
            dim,
            n_records,
            targets: targets.iter().map(|t| (t.output, t.side)).collect(),
            best: vec![(f64::NAN, 0); targets.len() * n_records],
            points: Vec::new(),
        }
    }

    /// Registers a batch's points (row-major); returns the index of its first run.
    fn register(&mut self, points: &[f64]) -> usize {
        let first = self.points.len() / self.dim.max(1);
        self.points.extend_from_slice(points);
        first
    }

    /// Takes in run `run`'s outputs `values` at `record`, for every target.
    fn offer(&mut self, run: usize, record: usize, values: &[f64]) {
        for (t, &(output, side)) in self.targets.iter().enumerate() {
            let value = values[output];
            let best = &mut self.best[t * self.n_records + record];
            let better = match side {
                Side::Lower => value < best.0,
                Side::Upper => value > best.0,
            };
            if value.is_finite() && (!best.0.is_finite() || better) {
                *best = (value, run);
            }
        }
    }

    /// Target `t`'s best run at `record`: its point and value (`None` before any).
    fn at(&self, t: usize, record: usize) -> Option<(&[f64], f64)> {
        let (value, run) = self.best[t * self.n_records + record];
        value
            .is_finite()
            .then(|| (&self.points[run * self.dim..(run + 1) * self.dim], value))
    }
}

/// What one stage's batch gives its caller: per run and record, the run's values.
type OnRun<'a> = dyn FnMut(usize, usize, &[f64]) + 'a;

/// Runs `points` (row-major, `d` per run) as one batch of the phase "refine": every run widens
/// the hull of true runs in `accumulator` and is offered to `best`, then
/// `on_run(run, record, values)`. `Ok(false)` when interrupted.
fn run_batch(
    context: &mut PhaseContext<'_>,
    points: &[f64],
    best: &mut BestRuns,
    accumulator: &mut Accumulator,
    on_run: &mut OnRun<'_>,
) -> Result<bool, StudyError> {
    let runs = points.len() / context.space.len().max(1);
    context.report.runs += runs;
    let first = best.register(points);
    let policy = context.exclusion_policy("refinement run");
    context.run_phase("refine", points, None, policy, &mut |block, _report| {
        for r in 0..block.count {
            let record = block.first + r;
            for i in 0..runs {
                if block.lockstep.failed(i) {
                    continue;
                }
                let run = block.record(i, r);
                accumulator.widen_runs(record, run);
                best.offer(first + i, record, run);
                on_run(i, record, run);
            }
        }
        Ok(())
    })
}

/// Runs a search's `probes` (one batch): every run into `best` and the hull of true runs, and
/// each probe's value of output `at(label).1` at record `at(label).0` (`NaN` where its run
/// failed). `None` when interrupted.
fn run_probes(
    context: &mut PhaseContext<'_>,
    probes: &[Probe],
    at: &dyn Fn(usize) -> (usize, usize),
    best: &mut BestRuns,
    accumulator: &mut Accumulator,
) -> Result<Option<Vec<f64>>, StudyError> {
    let points: Vec<f64> = probes.iter().flat_map(|p| p.point.clone()).collect();
    let mut values = vec![f64::NAN; probes.len()];
    let complete = run_batch(
        context,
        &points,
        best,
        accumulator,
        &mut |i, record, run| {
            let (target_record, output) = at(probes[i].label);
            if target_record == record {
                values[i] = run[output];
            }
        },
    )?;
    Ok(complete.then_some(values))
}

/// The runs the refinement of `outputs` untrusted outputs' extremes may make after `runs_made`
/// of a study's `max_runs`: what is left, and at least the reserve ([`refine_reserve`]) even
/// when the design spent the budget (an adaptive design above d = 4 takes all of it before the
/// check can say anything), so an untrusted study makes at most
/// `(1 + REFINE_BUDGET_FRACTION) · max_runs` runs.
pub(super) fn refine_budget(
    dim: usize,
    outputs: usize,
    max_runs: usize,
    runs_made: usize,
) -> usize {
    max_runs
        .saturating_sub(runs_made)
        .max(refine_reserve(dim, outputs, max_runs))
}

/// Runs the refinement of `targets` on the true model (module documentation) within `budget`
/// runs; every run widens the hull of true runs in `accumulator`, and `misfit[o][r]` of every
/// target's output takes in how far the hull then lies beyond the envelope point
/// `accumulator.points` held before. Returns the account, or `None` when interrupted (the runs
/// made still widen the hull).
pub(super) fn refine_extremes(
    context: &mut PhaseContext<'_>,
    targets: &[RefineTarget],
    budget: usize,
    accumulator: &mut Accumulator,
    misfit: &mut [Vec<f64>],
) -> Result<Option<RefinementReport>, StudyError> {
    let d = context.space.len();
    let n_outputs = accumulator.n_outputs;
    let n_records = accumulator.points.len() / n_outputs.max(1);
    let mut outputs: Vec<usize> = targets.iter().map(|t| t.output).collect();
    outputs.sort_unstable();
    outputs.dedup();
    // The envelope before any refinement run: a value found beyond it is a miss.
    let before: Vec<EnvelopePoint> = accumulator.points.clone();
    let mut report = RefinementReport::default();
    let mut best = BestRuns::new(d, n_records, targets);
    let settings = ExtremeSearchSettings::default();
    let search_runs = targets.len() * (1 + settings.max_iterations) * (2 * d + 1);
    let mut flips = None;
    if d > 0 && !targets.is_empty() && budget >= 2 * d + targets.len() {
        // 1. The targets' starts and the centre's stencil, one batch.
        let mut points: Vec<f64> = targets.iter().flat_map(|t| t.start.clone()).collect();
        for j in 0..2 * d {
            let mut point = vec![0.0; d];
            point[j / 2] = if j % 2 == 0 { 1.0 } else { -1.0 } * REFINE_GRADIENT_STEP;
            points.extend_from_slice(&point);
        }
        // The stencil's values of the untrusted outputs, record-major, run by run.
        let mut stencil = vec![f64::NAN; n_records * 2 * d * outputs.len()];
        let first_stencil = targets.len();
        let complete = run_batch(
            context,
            &points,
            &mut best,
            accumulator,
            &mut |i, record, run| {
                if i >= first_stencil {
                    let row = (record * 2 * d + i - first_stencil) * outputs.len();
                    for (k, &o) in outputs.iter().enumerate() {
                        stencil[row + k] = run[o];
                    }
                }
            },
        )?;
        report.runs += points.len() / d;
        report.batches += 1;
        report.gradient_runs = 2 * d;
        if !complete {
            return Ok(None);
        }
        // 2. The sign vertices of every untrusted output's gradient at every record.
        let mut vertices = CheckCandidates::new(d);
        let mut vertex = vec![0.0; d];
        for record in 0..n_records {
            for (k, &o) in outputs.iter().enumerate() {
                let at = |j: usize| stencil[(record * 2 * d + j) * outputs.len() + k];
                let mut spread = 0.0;
                for (j, v) in vertex.iter_mut().enumerate() {
                    let slope = at(2 * j) - at(2 * j + 1);
                    spread += slope.abs();
                    *v = if slope >= 0.0 { 1.0 } else { -1.0 };
                }
                if !(spread > 0.0 && spread.is_finite()) {
                    continue;
                }
                vertices.add(record, o, Side::Upper, &vertex, 0.0, spread);
                for v in vertex.iter_mut() {
                    *v = -*v;
                }
                vertices.add(record, o, Side::Lower, &vertex, 0.0, spread);
            }
        }
        let left = budget - report.runs;
        let reserved = if 2 * search_runs <= left {
            search_runs
        } else {
            0
        };
        let share = (REFINE_VERTEX_SHARE * (left - reserved) as f64) as usize;
        let plan = vertices.select(share);
        if !plan.points.is_empty() {
            let complete = run_batch(
                context,
                &plan.points,
                &mut best,
                accumulator,
                &mut |_, _, _| {},
            )?;
            report.vertex_runs = plan.points.len() / d;
            report.runs += report.vertex_runs;
            report.batches += 1;
            if !complete {
                return Ok(None);
            }
        }
        // 3. Flips from the best run so far, at each target output's widest record of the hull.
        let flip_budget = budget.saturating_sub(report.runs + reserved);
        if flip_budget >= d {
            let Some(found) = flip_stage(
                context,
                targets,
                &mut best,
                flip_budget,
                accumulator,
                &mut report,
            )?
            else {
                return Ok(None);
            };
            flips = Some(found);
        }
    }
    // 4. The gradient search from the starts, while a whole batch fits.
    let search_targets = targets
        .iter()
        .enumerate()
        .map(|(label, target)| SearchTarget {
            label,
            side: search_side(target.side),
            start: target.start.clone(),
        })
        .collect();
    let mut search = ExtremeSearch::new(d, search_targets, settings);
    loop {
        let probes = search.next_probes();
        if probes.is_empty() || report.runs + probes.len() > budget {
            break;
        }
        let at = |label: usize| (targets[label].record, targets[label].output);
        let Some(values) = run_probes(context, &probes, &at, &mut best, accumulator)? else {
            return Ok(None);
        };
        report.runs += probes.len();
        report.search_runs += probes.len();
        report.batches += 1;
        search.absorb(&values);
    }
    // Misfits: how far the hull of true runs now lies beyond the envelope before, at every
    // record of every target's output.
    for &o in &outputs {
        for (r, m) in misfit[o].iter_mut().enumerate().take(n_records) {
            let (lowest, highest) = accumulator.run_hull(r, o);
            let p = before[r * n_outputs + o];
            let excess = (p.lower - accumulator.reported(o, lowest))
                .max(accumulator.reported(o, highest) - p.upper);
            if excess.is_finite() && excess > 0.0 {
                *m = m.max(excess);
            }
        }
    }
    let extreme = |t: usize, record: usize| {
        let target = &targets[t];
        let p = before[record * n_outputs + target.output];
        let found = best.at(t, record);
        RefinedExtreme {
            output: target.output,
            record,
            side: target.side,
            start_xi: target.start.clone(),
            best_xi: found.map_or_else(|| target.start.clone(), |(x, _)| x.to_vec()),
            // The runs' values as recorded; the clamp is monotone, so the best is the best
            // of the output as reported.
            value: accumulator.reported(target.output, found.map_or(f64::NAN, |(_, v)| v)),
            envelope: match target.side {
                Side::Lower => p.lower,
                Side::Upper => p.upper,
            },
        }
    };
    report.extremes = (0..targets.len())
        .map(|t| extreme(t, targets[t].record))
        .collect();
    if let Some(flips) = flips {
        report.flips = flips
            .iter()
            .enumerate()
            .map(|(t, &(record, ref start))| RefinedExtreme {
                start_xi: start.clone(),
                ..extreme(t, record)
            })
            .collect();
    }
    Ok(Some(report))
}

/// The search side of a check side.
fn search_side(side: Side) -> SearchSide {
    match side {
        Side::Lower => SearchSide::Min,
        Side::Upper => SearchSide::Max,
    }
}

/// Where a flip search ran: its record and its starting point.
type FlipStart = (usize, Vec<f64>);

/// Stage 3: per target, greedy one-flip rounds ([`FlipSearch`]) at its output's widest record of
/// the hull of true runs, from the best refinement run there so far (else the target's start),
/// within `budget`. Returns each search's record and starting point, or `None` when interrupted.
fn flip_stage(
    context: &mut PhaseContext<'_>,
    targets: &[RefineTarget],
    best: &mut BestRuns,
    budget: usize,
    accumulator: &mut Accumulator,
    report: &mut RefinementReport,
) -> Result<Option<Vec<FlipStart>>, StudyError> {
    let d = context.space.len();
    let n_records = best.n_records;
    let starts: Vec<FlipStart> = targets
        .iter()
        .enumerate()
        .map(|(t, target)| {
            let width = |r: usize| {
                let (lowest, highest) = accumulator.run_hull(r, target.output);
                highest - lowest
            };
            let record = (0..n_records)
                .filter(|&r| width(r).is_finite())
                .fold(None, |widest: Option<usize>, r| match widest {
                    Some(w) if width(w) >= width(r) => widest,
                    _ => Some(r),
                })
                .unwrap_or(target.record);
            let start = best
                .at(t, record)
                .map_or_else(|| target.start.clone(), |(x, _)| x.to_vec());
            (record, start)
        })
        .collect();
    let flip_targets: Vec<FlipTarget> = targets
        .iter()
        .zip(&starts)
        .enumerate()
        .map(|(t, (target, (record, start)))| FlipTarget {
            label: t,
            side: search_side(target.side),
            start: start.clone(),
            // Unknown when no run reached that record (any finite flip then improves on it).
            value: best.at(t, *record).map_or(f64::NAN, |(_, v)| v),
        })
        .collect();
    let mut search = FlipSearch::new(d, flip_targets);
    loop {
        let probes = search.next_probes(budget.saturating_sub(report.flip_runs));
        if probes.is_empty() {
            break;
        }
        let at = |label: usize| (starts[label].0, targets[label].output);
        let Some(values) = run_probes(context, &probes, &at, best, accumulator)? else {
            return Ok(None);
        };
        report.runs += probes.len();
        report.flip_runs += probes.len();
        report.batches += 1;
        search.absorb(&values);
    }
    Ok(Some(starts))
}
