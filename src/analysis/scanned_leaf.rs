//! Scanned leaves (docs/method.md §12, "Scanned leaves"): a stalled leaf's grid of true runs,
//! whose hull is its envelope, and its check — true runs half a grid step from the grid's extreme
//! points, then a bisection of each output's steepest cell — judged by the excess of a run past the
//! grid's hull.
//!
//! Does not: choose which leaf to scan or how fine (`elements_phase.rs`: `scan_design`), or refine
//! a scan that fails (`scan_refinement.rs`).

use super::accumulator::Accumulator;
use super::bounds::EnvelopePoint;
use super::check::{CheckPlan, TRUST_RELATIVE_MISFIT};
use super::check_phase::{excess, CheckRuns};
use super::elements::SCAN_BISECTIONS;
use super::error::StudyError;
use super::phase::PhaseContext;
use super::plan::{grid_point, SplitMix64};
use crate::uq::ElementBox;

/// A scan's check of one true run at `record` (`values`, every output): for each `active` output,
/// how far it lies outside the grid's hull (`grid_hull`, record-major) raises `misfit[o][record]`,
/// and the value joins `checked`.
pub(super) fn judge_scan_run(
    accumulator: &Accumulator,
    grid_hull: &[EnvelopePoint],
    active: &[bool],
    record: usize,
    values: &[f64],
    misfit: &mut [Vec<f64>],
    checked: &mut Vec<(usize, usize, f64)>,
) {
    let n_outputs = active.len();
    for o in (0..n_outputs).filter(|&o| active[o]) {
        let truth = accumulator.reported(o, values[o]);
        let hull = grid_hull[record * n_outputs + o];
        checked.push((o, record, truth));
        let m = &mut misfit[o][record];
        *m = m.max(excess(truth, hull.lower, hull.upper));
    }
}

/// What a scanned child's check needs to know of its grid, gathered while its runs come in.
pub(super) struct ScanGrid {
    /// Points per dimension.
    counts: Vec<usize>,
    /// Per output: whether the elements are made for it.
    active: Vec<bool>,
    /// Per record and output (record-major): the grid runs holding the lowest and highest value.
    holders: Vec<(usize, usize)>,
    /// Per output: its steepest cell, `None` before any.
    steepest: Vec<Option<Bisection>>,
}

impl ScanGrid {
    /// A grid of `counts[j]` points per dimension over `n_records` records of `active.len()`
    /// outputs.
    pub(super) fn new(counts: Vec<usize>, active: &[bool], n_records: usize) -> ScanGrid {
        ScanGrid {
            counts,
            active: active.to_vec(),
            holders: vec![(0, 0); n_records * active.len()],
            steepest: vec![None; active.len()],
        }
    }

    /// Takes in every grid run's values at `record` (`values(i)`: run `i`'s outputs): widens
    /// `child`'s hull, notes which runs hold its sides and the steepest step between neighbours.
    pub(super) fn absorb<'v>(
        &mut self,
        child: &mut Accumulator,
        record: usize,
        values: &dyn Fn(usize) -> &'v [f64],
    ) {
        let n_outputs = self.active.len();
        let runs: usize = self.counts.iter().product();
        let hull: &Accumulator = child;
        let reported: Vec<f64> = (0..runs)
            .flat_map(|i| {
                let row = values(i);
                (0..n_outputs).map(move |o| hull.reported(o, row[o]))
            })
            .collect();
        for i in 0..runs {
            let row = &reported[i * n_outputs..(i + 1) * n_outputs];
            for (o, &value) in row.iter().enumerate() {
                let k = record * n_outputs + o;
                let point = child.points[k];
                if value < point.lower {
                    self.holders[k].0 = i;
                }
                if value > point.upper {
                    self.holders[k].1 = i;
                }
            }
            child.widen(record, values(i));
        }
        // Neighbours along each dimension: run i and i + stride (row-major, last dimension fastest).
        let d = self.counts.len();
        for o in (0..n_outputs).filter(|&o| self.active[o]) {
            for j in 0..d {
                let stride: usize = self.counts[j + 1..].iter().product();
                for i in 0..runs {
                    if (i / stride) % self.counts[j] + 1 == self.counts[j] {
                        continue;
                    }
                    let (from_value, to_value) = (
                        reported[i * n_outputs + o],
                        reported[(i + stride) * n_outputs + o],
                    );
                    let step = (to_value - from_value).abs();
                    if self.steepest[o].as_ref().is_none_or(|b| step > b.step()) {
                        self.steepest[o] = Some(Bisection {
                            output: o,
                            record,
                            from: grid_point(&self.counts, i),
                            to: grid_point(&self.counts, i + stride),
                            from_value,
                            to_value,
                        });
                    }
                }
            }
        }
    }

    /// Runs its bisections take at most.
    pub(super) fn bisection_runs(&self) -> usize {
        SCAN_BISECTIONS * self.active.iter().filter(|&&a| a).count()
    }

    /// The first part of its check (`runs` runs in `region`): between the grid points that hold a
    /// side of an active output at some record, the most often first — half a grid step from each
    /// along each dimension — then seeded random points of the box if those run short. It predicts
    /// nothing: the check phase measures each run's excess over the grid's hull.
    pub(super) fn half_steps(&self, region: &ElementBox, runs: usize) -> CheckPlan {
        let d = self.counts.len();
        let n_outputs = self.active.len().max(1);
        let mut held = vec![0usize; self.counts.iter().product()];
        for (k, &(low, high)) in self.holders.iter().enumerate() {
            if self.active[k % n_outputs] {
                held[low] += 1;
                held[high] += 1;
            }
        }
        let mut order: Vec<usize> = (0..held.len()).filter(|&i| held[i] > 0).collect();
        order.sort_by(|&a, &b| held[b].cmp(&held[a]).then(a.cmp(&b)));
        let mut chosen: Vec<Vec<f64>> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        'grid: for index in order {
            let centre = grid_point(&self.counts, index);
            for (j, &n) in self.counts.iter().enumerate() {
                let half_step = if n > 1 { 1.0 / (n - 1) as f64 } else { 1.0 };
                for side in [-1.0, 1.0] {
                    let mut point = centre.clone();
                    point[j] += side * half_step;
                    if point[j].abs() > 1.0 {
                        continue;
                    }
                    if seen.insert(point.iter().map(|x| x.to_bits()).collect::<Vec<u64>>()) {
                        chosen.push(point);
                        if chosen.len() == runs {
                            break 'grid;
                        }
                    }
                }
            }
        }
        let mut random = SplitMix64::new(SCAN_CHECK_SEED);
        while chosen.len() < runs {
            chosen.push((0..d).map(|_| random.next_symmetric()).collect());
        }
        let points: Vec<f64> = chosen.iter().flat_map(|p| region.to_whole(p)).collect();
        CheckPlan {
            checks: vec![Vec::new(); chosen.len()],
            unique_candidates: chosen.len(),
            points,
        }
    }

    /// The second part: a bisection of each active output's steepest cell whose step is not
    /// already within the trust test of the grid's hull (`grid_hull`).
    pub(super) fn bisections(&self, grid_hull: &[EnvelopePoint]) -> Vec<Bisection> {
        let n_outputs = self.active.len();
        self.steepest
            .iter()
            .flatten()
            .filter(|b| !b.resolved(grid_hull, n_outputs))
            .cloned()
            .collect()
    }
}

/// The bisection of one cell of a scan, for one output at one record: two points (the element's
/// own coordinates) and the output's values there.
#[derive(Clone, Debug)]
pub(super) struct Bisection {
    /// The output whose step it follows.
    pub output: usize,
    /// The record where that step is.
    pub record: usize,
    /// One end of the cell (the leaf's own coordinates).
    pub from: Vec<f64>,
    /// The other end.
    pub to: Vec<f64>,
    /// The output's value at `from` (NaN once a run failed).
    pub from_value: f64,
    /// Its value at `to`.
    pub to_value: f64,
}

impl Bisection {
    /// How far the output steps across the cell.
    pub(super) fn step(&self) -> f64 {
        (self.to_value - self.from_value).abs()
    }

    /// Whether the step is within the trust test's share of the output's widest grid hull (a
    /// smooth response resolves as the cell shrinks; a jump never does).
    pub(super) fn resolved(&self, grid_hull: &[EnvelopePoint], n_outputs: usize) -> bool {
        let width = grid_hull
            .iter()
            .skip(self.output)
            .step_by(n_outputs.max(1))
            .map(|p| p.upper - p.lower)
            .fold(0.0, f64::max);
        self.step() <= TRUST_RELATIVE_MISFIT * width
    }

    /// The cell's middle.
    pub(super) fn middle(&self) -> Vec<f64> {
        self.from
            .iter()
            .zip(&self.to)
            .map(|(a, b)| 0.5 * (a + b))
            .collect()
    }

    /// Keeps the half across which the output steps further, `value` being the middle's.
    pub(super) fn halve(&mut self, value: f64) {
        let middle = self.middle();
        if (value - self.from_value).abs() >= (self.to_value - value).abs() {
            self.to = middle;
            self.to_value = value;
        } else {
            self.from = middle;
            self.from_value = value;
        }
    }
}

/// A scanned child as its check sees it.
pub(super) struct ScanCheck<'a> {
    /// Its grid.
    pub grid: &'a ScanGrid,
    /// Its grid's hull, before the check widened it (record-major).
    pub grid_hull: &'a [EnvelopePoint],
    /// Its box.
    pub region: &'a ElementBox,
    /// Per output: whether the elements are made for it.
    pub active: &'a [bool],
}

/// The second part of a scan's check: each active output's steepest cell bisected, one run per
/// cell and halving, down to where a jump is ([`SCAN_BISECTIONS`] halvings at most). Every run
/// widens `hull` (the leaf's envelope) and the hull of true runs in `accumulator`, raises
/// `misfit[o][r]` by its excess past the grid's hull, and joins `runs`. Returns the runs made,
/// `None` when the study was interrupted.
pub(super) fn bisect_steepest_cells(
    context: &mut PhaseContext<'_>,
    leaf: &ScanCheck<'_>,
    hull: &mut Accumulator,
    accumulator: &mut Accumulator,
    misfit: &mut [Vec<f64>],
    runs: &mut CheckRuns,
) -> Result<Option<usize>, StudyError> {
    let n_outputs = leaf.active.len();
    let mut made = 0;
    let mut bisections = leaf.grid.bisections(leaf.grid_hull);
    for _ in 0..SCAN_BISECTIONS {
        bisections.retain(|b| !b.resolved(leaf.grid_hull, n_outputs));
        if bisections.is_empty() {
            break;
        }
        let points: Vec<f64> = bisections
            .iter()
            .flat_map(|b| leaf.region.to_whole(&b.middle()))
            .collect();
        let mut middle_values = vec![f64::NAN; bisections.len()];
        let mut checked = Vec::new();
        context.report.runs += bisections.len();
        let policy = context.exclusion_policy("check run");
        let complete =
            context.run_phase("check", &points, None, policy, &mut |block, _report| {
                for r in 0..block.count {
                    let record = block.first + r;
                    for (run, bisection) in bisections.iter().enumerate() {
                        if block.lockstep.failed(run) {
                            continue;
                        }
                        let values = block.record(run, r);
                        judge_scan_run(
                            accumulator,
                            leaf.grid_hull,
                            leaf.active,
                            record,
                            values,
                            misfit,
                            &mut checked,
                        );
                        if record == bisection.record {
                            middle_values[run] =
                                accumulator.reported(bisection.output, values[bisection.output]);
                        }
                        hull.widen(record, values);
                        accumulator.widen_runs(record, values);
                    }
                }
                Ok(())
            })?;
        if !complete {
            return Ok(None);
        }
        runs.runs += bisections.len();
        made += bisections.len();
        runs.unique_candidates += bisections.len();
        runs.points.extend_from_slice(&points);
        runs.checked.extend(checked);
        for (bisection, &value) in bisections.iter_mut().zip(&middle_values) {
            bisection.halve(value);
        }
        // A failed run leaves no value to halve by: that bisection ends.
        bisections.retain(|b| b.from_value.is_finite() && b.to_value.is_finite());
    }
    Ok(Some(made))
}

/// Seed of the random points that fill a scan's check (fixed, so studies repeat).
const SCAN_CHECK_SEED: u64 = 0x5ca0_c4ec;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scan_grid_runs_row_major_with_both_faces() {
        let counts = [3, 2];
        let points: Vec<Vec<f64>> = (0..6).map(|i| grid_point(&counts, i)).collect();
        assert_eq!(points[0], vec![-1.0, -1.0]);
        assert_eq!(points[1], vec![-1.0, 1.0]);
        assert_eq!(points[2], vec![0.0, -1.0]);
        assert_eq!(points[5], vec![1.0, 1.0]);
    }

    #[test]
    fn a_bisection_follows_the_jump_and_stops_on_a_smooth_step() {
        // A jump at x = 0.3 between 0 (left) and 1 (right): the kept cell always holds it.
        let jump = |x: f64| if x < 0.3 { 0.0 } else { 1.0 };
        let mut bisection = Bisection {
            output: 0,
            record: 0,
            from: vec![-1.0],
            to: vec![1.0],
            from_value: jump(-1.0),
            to_value: jump(1.0),
        };
        for _ in 0..20 {
            let middle = bisection.middle()[0];
            bisection.halve(jump(middle));
        }
        assert!(bisection.from[0] < 0.3 && bisection.to[0] >= 0.3);
        assert!(bisection.to[0] - bisection.from[0] < 1e-5);
        assert_eq!(bisection.step(), 1.0);
        // Resolved once the step is within 5 % of the hull's widest width (here 1).
        let hull = vec![EnvelopePoint {
            lower: 0.0,
            upper: 1.0,
            ..EnvelopePoint::EMPTY
        }];
        assert!(!bisection.resolved(&hull, 1));
        bisection.to_value = 0.04;
        assert!(bisection.resolved(&hull, 1));
    }
}
