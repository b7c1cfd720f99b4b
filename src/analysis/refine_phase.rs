//! Refinement of the extremes on the true model (docs/method.md §12): for every output the check
//! still does not trust, a few steps of projected steepest ascent (descent for the lower side)
//! of the *true* model, from where the surrogates put its extremes at its widest record time,
//! with central-difference gradients ([`ExtremeSearch`]). Every step is a batch of true runs over
//! the whole horizon (one lock-step phase for all targets), so every value found widens the hull
//! of true runs — the study's inner bound — at every record, and a value beyond the envelope is a
//! miss the check counts.
//!
//! ```text
//! untrusted outputs ⇒ targets (output, widest record, side, start ξ) ⇒ per batch: probes ⇒
//! run_phase("refine") ⇒ each probe's value at its target's record ⇒ ExtremeSearch::absorb …
//! ⇒ best true value per target; every run into the hull; excesses into the misfits
//! ```
//!
//! What it finds is a local optimum of the true model, never an enclosure. Does not: choose the
//! starting points (the caller knows the surrogates), or judge trust (`check_phase.rs`).

use super::accumulator::Accumulator;
use super::check::Side;
use super::error::StudyError;
use super::phase::PhaseContext;
use super::report::{RefinedExtreme, RefinementReport};
use crate::uq::{ExtremeSearch, ExtremeSearchSettings, SearchSide, SearchTarget};

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

/// Runs the searches of `targets` on the true model (module documentation) while a whole batch
/// fits in `budget` runs; every run widens the hull of true runs in `accumulator`, and
/// `misfit[o][r]` takes in how far a found value lies beyond the envelope point
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
    let search_targets = targets
        .iter()
        .enumerate()
        .map(|(label, target)| SearchTarget {
            label,
            side: match target.side {
                Side::Lower => SearchSide::Min,
                Side::Upper => SearchSide::Max,
            },
            start: target.start.clone(),
        })
        .collect();
    let mut search = ExtremeSearch::new(d, search_targets, ExtremeSearchSettings::default());
    // The envelope before any refinement run: a value found beyond it is a miss.
    let before: Vec<(f64, f64)> = targets
        .iter()
        .map(|t| {
            let p = accumulator.points[t.record * n_outputs + t.output];
            (p.lower, p.upper)
        })
        .collect();
    let mut runs = 0;
    let mut batches = 0;
    loop {
        let probes = search.next_probes();
        if probes.is_empty() || runs + probes.len() > budget {
            break;
        }
        let points: Vec<f64> = probes.iter().flat_map(|p| p.point.clone()).collect();
        let mut values = vec![f64::NAN; probes.len()];
        runs += probes.len();
        batches += 1;
        context.report.runs += probes.len();
        let policy = context.exclusion_policy("refinement run");
        let complete =
            context.run_phase("refine", &points, None, policy, &mut |block, _report| {
                for r in 0..block.count {
                    let record = block.first + r;
                    for (i, probe) in probes.iter().enumerate() {
                        if block.lockstep.failed(i) {
                            continue;
                        }
                        let run = block.record(i, r);
                        accumulator.widen_runs(record, run);
                        let target = &targets[probe.label];
                        if target.record == record {
                            values[i] = run[target.output];
                        }
                    }
                }
                Ok(())
            })?;
        if !complete {
            return Ok(None);
        }
        search.absorb(&values);
    }
    let best = search.best();
    let extremes = targets
        .iter()
        .zip(&best)
        .zip(&before)
        .map(|((target, (xi, value)), &(lower, upper))| {
            // The search ran on the recorded value; the clamp is monotone, so its best is the
            // best of the output as reported.
            let value = accumulator.reported(target.output, *value);
            let excess = match target.side {
                Side::Lower => lower - value,
                Side::Upper => value - upper,
            };
            if excess.is_finite() && excess > 0.0 {
                let m = &mut misfit[target.output][target.record];
                *m = m.max(excess);
            }
            RefinedExtreme {
                output: target.output,
                record: target.record,
                side: target.side,
                start_xi: target.start.clone(),
                best_xi: xi.clone(),
                value,
                envelope: match target.side {
                    Side::Lower => lower,
                    Side::Upper => upper,
                },
            }
        })
        .collect();
    Ok(Some(RefinementReport {
        runs,
        batches,
        extremes,
    }))
}
