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
//! 3. flips:              from the best run so far where each output's hull of true runs first
//!                        reaches 30 % and 60 % of its widest, greedy one-flip rounds
//!                        ([`FlipSearch`]) while they fit
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
use std::collections::HashMap;

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

/// Most of a study's `--max-runs` the refinement may make beyond what the design and the
/// elements left: a half, so an untrusted study makes at most 1.5 × `--max-runs` runs. Measured
/// on the limp iiwa (d = 37, docs/method.md §12), whose adaptive design spends the whole budget:
/// a quarter (745 refinement runs) left one flip round for 11 of its 28 searches and missed
/// 29.5 % of the reference; a half (1 470 runs, +3.7 s wall) 19.5 %; the whole `--max-runs`
/// (2 972 runs, +7.6 s) 17.1 %.
pub const REFINE_EXTRA_FRACTION: f64 = 0.5;

/// A full search of both sides of `outputs` untrusted outputs' extremes in `dim` dimensions
/// (its start and `ExtremeSearchSettings::max_iterations` trials, each with its `2d`
/// differences), at most `fraction` of `max_runs`.
fn refine_runs(dim: usize, outputs: usize, max_runs: usize, fraction: f64) -> usize {
    let per_search = (1 + ExtremeSearchSettings::default().max_iterations) * (2 * dim + 1);
    (2 * outputs * per_search).min((fraction * max_runs as f64) as usize)
}

/// The runs the elements set aside for refining `outputs` untrusted outputs' extremes in `dim`
/// dimensions within `max_runs`: [`refine_runs`] at [`REFINE_BUDGET_FRACTION`].
pub(super) fn refine_reserve(dim: usize, outputs: usize, max_runs: usize) -> usize {
    refine_runs(dim, outputs, max_runs, REFINE_BUDGET_FRACTION)
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

/// Runs a search's `probes` (one batch), each distinct point once (flip searches that start
/// from the same run ask for the same flips): every run into `best` and the hull of true runs,
/// and each probe's value of output `at(label).1` at record `at(label).0` (`NaN` where its run
/// failed). Returns the values and the runs made, or `None` when interrupted.
fn run_probes(
    context: &mut PhaseContext<'_>,
    probes: &[Probe],
    at: &dyn Fn(usize) -> (usize, usize),
    best: &mut BestRuns,
    accumulator: &mut Accumulator,
) -> Result<Option<(Vec<f64>, usize)>, StudyError> {
    // The distinct points in order of first request, and the probes each serves.
    let mut index: HashMap<Vec<u64>, usize> = HashMap::new();
    let mut points: Vec<f64> = Vec::new();
    let mut served: Vec<Vec<usize>> = Vec::new();
    for (p, probe) in probes.iter().enumerate() {
        let key: Vec<u64> = probe.point.iter().map(|x| x.to_bits()).collect();
        let next = served.len();
        let slot = *index.entry(key).or_insert(next);
        if slot == next {
            points.extend_from_slice(&probe.point);
            served.push(Vec::new());
        }
        served[slot].push(p);
    }
    let mut values = vec![f64::NAN; probes.len()];
    let complete = run_batch(
        context,
        &points,
        best,
        accumulator,
        &mut |i, record, run| {
            for &p in &served[i] {
                let (target_record, output) = at(probes[p].label);
                if target_record == record {
                    values[p] = run[output];
                }
            }
        },
    )?;
    Ok(complete.then_some((values, served.len())))
}

/// The runs the refinement of `outputs` untrusted outputs' extremes may make after `runs_made`
/// of a study's `max_runs`: what is left, and at least [`refine_runs`] at
/// [`REFINE_EXTRA_FRACTION`] even when the design spent the budget (an adaptive design above
/// d = 4 takes all of it before the check can say anything), so an untrusted study makes at most
/// `(1 + REFINE_EXTRA_FRACTION) · max_runs` runs.
pub(super) fn refine_budget(
    dim: usize,
    outputs: usize,
    max_runs: usize,
    runs_made: usize,
) -> usize {
    max_runs.saturating_sub(runs_made).max(refine_runs(
        dim,
        outputs,
        max_runs,
        REFINE_EXTRA_FRACTION,
    ))
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
        // 3. Flips from the best run so far, at each target output's rising records.
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
        let Some((values, runs)) = run_probes(context, &probes, &at, &mut best, accumulator)?
        else {
            return Ok(None);
        };
        report.runs += runs;
        report.search_runs += runs;
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
            .map(|&(t, record, ref start)| RefinedExtreme {
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

/// Where a flip search ran: its target, its record and its starting point.
type FlipStart = (usize, usize, Vec<f64>);

/// The shares of its widest spread at which an output's flip searches aim (stage 3): each search
/// runs at the first record where the hull of true runs is at least that share of its widest.
/// Not the widest record itself: once a fast divergence has spread the motion, many runs are
/// extreme there, but while the spread rises the extremes belong to the few runs that diverge
/// first — where the sign vertices miss most. Measured on the limp iiwa (docs/method.md §12) in a
/// prototype of these stages driving the true model: aimed at the widest record the searches
/// converge near a 30 % miss of the reference however many runs they get (30.1 % at 1 500
/// refinement runs, 29.8 % at 3 000); aimed at 30 % and 60 %, 18.3 % at 1 500.
pub const FLIP_WIDTH_SHARES: [f64; 2] = [0.3, 0.6];

/// The records an output's flip searches aim at ([`FLIP_WIDTH_SHARES`]), given the width of its
/// hull of true runs at each of `n_records` records: the first record whose width reaches each
/// share of the widest, deduplicated; `fallback` alone when no record has a positive finite
/// width.
fn flip_records(width: &dyn Fn(usize) -> f64, n_records: usize, fallback: usize) -> Vec<usize> {
    let widest = (0..n_records)
        .map(width)
        .filter(|w| w.is_finite())
        .fold(0.0_f64, f64::max);
    if widest <= 0.0 {
        return vec![fallback];
    }
    let mut records: Vec<usize> = Vec::new();
    for share in FLIP_WIDTH_SHARES {
        let record = (0..n_records)
            .find(|&r| width(r) >= share * widest)
            .unwrap_or(fallback);
        if !records.contains(&record) {
            records.push(record);
        }
    }
    records
}

/// Stage 3: per target, greedy one-flip rounds ([`FlipSearch`]) at its output's records of
/// [`flip_records`], from the best refinement run there so far (else the target's start), within
/// `budget`; every target's first record before any target's second. Returns each search's
/// target, record and starting point, or `None` when interrupted.
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
    let records: Vec<Vec<usize>> = targets
        .iter()
        .map(|target| {
            let width = |r: usize| {
                let (lowest, highest) = accumulator.run_hull(r, target.output);
                highest - lowest
            };
            flip_records(&width, n_records, target.record)
        })
        .collect();
    let mut starts: Vec<FlipStart> = Vec::new();
    for k in 0..FLIP_WIDTH_SHARES.len() {
        for (t, target) in targets.iter().enumerate() {
            let Some(&record) = records[t].get(k) else {
                continue;
            };
            let start = best
                .at(t, record)
                .map_or_else(|| target.start.clone(), |(x, _)| x.to_vec());
            starts.push((t, record, start));
        }
    }
    let flip_targets: Vec<FlipTarget> = starts
        .iter()
        .enumerate()
        .map(|(label, (t, record, start))| FlipTarget {
            label,
            side: search_side(targets[*t].side),
            start: start.clone(),
            // Unknown when no run reached that record (any finite flip then improves on it).
            value: best.at(*t, *record).map_or(f64::NAN, |(_, v)| v),
        })
        .collect();
    let mut search = FlipSearch::new(d, flip_targets);
    loop {
        let probes = search.next_probes(budget.saturating_sub(report.flip_runs));
        if probes.is_empty() {
            break;
        }
        let at = |label: usize| (starts[label].1, targets[starts[label].0].output);
        let Some((values, runs)) = run_probes(context, &probes, &at, best, accumulator)? else {
            return Ok(None);
        };
        report.runs += runs;
        report.flip_runs += runs;
        report.batches += 1;
        search.absorb(&values);
    }
    Ok(Some(starts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flips_aim_where_the_spread_rises_not_where_it_is_widest() {
        // A spread that grows tenfold every ten records: 30 % of the widest is first reached at
        // record 15 (10^(1.5 − 2) ≈ 0.316), 60 % at record 18 (≈ 0.631); the widest is record 20.
        let width = |r: usize| 10f64.powf(r as f64 / 10.0);
        assert_eq!(flip_records(&width, 21, 7), vec![15, 18]);
        // A spread that jumps at once: both shares land on the same record, searched once.
        let step = |r: usize| if r >= 4 { 1.0 } else { 0.0 };
        assert_eq!(flip_records(&step, 10, 7), vec![4]);
        // No spread at all (or none finite): the target's own record.
        assert_eq!(flip_records(&|_| 0.0, 10, 7), vec![7]);
        assert_eq!(flip_records(&|_| f64::NAN, 10, 7), vec![7]);
    }

    #[test]
    fn an_untrusted_study_may_refine_with_half_its_budget_beyond_it() {
        // d = 37, 7 outputs: a full search of each is far above the share, so the share decides.
        assert_eq!(refine_reserve(37, 7, 3000), 750);
        assert_eq!(refine_budget(37, 7, 3000, 3000), 1500);
        // Runs left over count when they are more.
        assert_eq!(refine_budget(37, 7, 3000, 1000), 2000);
        // d = 1, one output: the full search (2 · 7 · 3 runs) is below either share.
        assert_eq!(refine_budget(1, 1, 3000, 3000), 42);
    }
}
