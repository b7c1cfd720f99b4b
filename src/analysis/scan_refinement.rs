//! Refined scans (docs/method.md §12, "Refined scans"): a scanned leaf whose check failed, with
//! one feature dimension, has its grid cells along that dimension halved where three true values
//! say a cell may hide an extreme, until every cell passes or the runs run out.
//!
//! ```text
//! grid values per node (a slab of runs across the other dimensions) ⇒ cells between neighbours
//! per round: every open cell's middle slab ⇒ run_phase("check") ⇒ per cell, output, record:
//!   excess of the middle past the leaf's hull before the round,
//!   overshoot of the parabola through the three values past the hull after it,
//!   bend of the middle off the chord
//! ⇒ pass (its misfit is final) or halve (down to SCAN_CELL_RESOLUTION of the parameter's value)
//! ```
//!
//! The leaf's envelope stays the hull of its true runs; the refinement only adds runs where the
//! values say an extreme may lie between them, and its misfits are what its passing cells last
//! saw. A cell halved to the resolution keeps only its middle's excess (a jump that happens or
//! not keeps its step at every halving, and both sides of it are runs). Does not: choose which
//! leaf to refine (`elements_phase.rs`), or judge trust (`check_phase.rs`).

use super::accumulator::Accumulator;
use super::check::TRUST_RELATIVE_MISFIT;
use super::check_phase::{excess, CheckRuns};
use super::elements::SCAN_OTHER_POINTS;
use super::envelope::EnvelopePoint;
use super::error::StudyError;
use super::phase::PhaseContext;
use super::plan::grid_point;
use crate::uq::ElementBox;

/// A cell passes when neither its middle's excess past the hull nor its parabola's overshoot is
/// above this share of the output's width: two fifths of the trust test's
/// ([`TRUST_RELATIVE_MISFIT`]), so what the passing cells leave unseen stays well inside it
/// (measured on the spring pendulum over nine decades of mass: misses of a dense reference
/// ≤ 1 % of the width).
pub const SCAN_CELL_TOLERANCE: f64 = 0.4 * TRUST_RELATIVE_MISFIT;

/// A cell whose middle lies further than this share of the output's width off the chord of its
/// ends is halved whatever its parabola says: three values that bend that much may belong to
/// several oscillations the parabola cannot see.
pub const SCAN_CELL_MAX_BEND: f64 = 0.5;

/// A cell is halved no further once it is narrower than this share of its parameter's value
/// there: nine digits is below any meaningful knowledge of a physical value, and a box over
/// many decades (a mass in [0.01, 1e9] kg) needs cells of 1e-5 kg at its light end, far below
/// any fixed share of the box.
pub const SCAN_CELL_RESOLUTION: f64 = 1e-9;

/// Halvings of a grid cell at most, whatever [`SCAN_CELL_RESOLUTION`] allows (2⁻⁹⁶ of a cell
/// is below the resolution of an f64 box coordinate): the refinement always ends.
pub const SCAN_CELL_MAX_DEPTH: usize = 96;

/// Which dimension of a scan grid (`counts`) a refinement follows: the one feature dimension
/// (more points than [`SCAN_OTHER_POINTS`]); `None` when there are several, or none.
pub(super) fn refinable_dimension(counts: &[usize]) -> Option<usize> {
    let mut features = (0..counts.len()).filter(|&j| counts[j] > SCAN_OTHER_POINTS);
    let first = features.next()?;
    features.next().is_none().then_some(first)
}

/// A scanned leaf's grid values kept for its refinement: per grid run, record and active output
/// (run-major), as reported.
pub(super) struct ScanValues {
    /// Points per dimension of the grid.
    counts: Vec<usize>,
    /// The outputs kept.
    outputs: Vec<usize>,
    /// Records per run.
    n_records: usize,
    /// `runs × records × outputs.len()`; NaN where a run failed.
    values: Vec<f64>,
}

impl ScanValues {
    /// Room for a grid of `counts` over `n_records` records of `outputs`.
    pub(super) fn new(counts: &[usize], outputs: &[usize], n_records: usize) -> ScanValues {
        let runs: usize = counts.iter().product();
        ScanValues {
            counts: counts.to_vec(),
            outputs: outputs.to_vec(),
            n_records,
            values: vec![f64::NAN; runs * n_records * outputs.len()],
        }
    }

    /// Takes in grid run `run`'s `values` (every output) at `record`.
    pub(super) fn absorb(
        &mut self,
        accumulator: &Accumulator,
        run: usize,
        record: usize,
        values: &[f64],
    ) {
        let k = self.outputs.len();
        let at = (run * self.n_records + record) * k;
        for (slot, &o) in self.values[at..at + k].iter_mut().zip(&self.outputs) {
            *slot = accumulator.reported(o, values[o]);
        }
    }
}

/// How a refinement ended.
pub(super) enum ScanRefinement {
    /// It ran: what it found.
    Refined(RefinedScan),
    /// It did not (the first round does not fit the runs left, or a run failed: the leaf keeps
    /// its scan's check).
    NotRefined,
    /// The study was interrupted.
    Interrupted,
}

/// What a refinement found: the leaf's misfits (`misfit[o][r]`, every output; 0 for those not
/// refined) and the runs it made.
pub(super) struct RefinedScan {
    /// The passing cells' misfits, and the open cells' last ones.
    pub misfit: Vec<Vec<f64>>,
    /// Runs made.
    pub runs: usize,
}

/// A cell between two nodes (each its coordinate along the feature dimension and its index into
/// the nodes' values, `lines × records × outputs` per node), halved `depth` times below a grid
/// cell, with the misfit its last test saw (`records × outputs`; empty before any test).
struct Cell {
    from: (f64, usize),
    to: (f64, usize),
    depth: usize,
    misfit: Vec<f64>,
}

/// Everything a refinement needs to know of its leaf.
pub(super) struct ScanLeaf<'a> {
    /// The leaf's box.
    pub region: &'a ElementBox,
    /// Its grid's values.
    pub values: ScanValues,
    /// The dimension refined ([`refinable_dimension`]).
    pub feature: usize,
    /// Each output's width the tolerances are shares of (the union's).
    pub widths: &'a [f64],
}

/// Refines `leaf` (module documentation) with at most `budget` runs: every run widens `hull` (the
/// leaf's envelope) and the hull of true runs in `accumulator`, and joins `runs` (the runs made
/// widen the hulls however it ends).
pub(super) fn refine_scan(
    context: &mut PhaseContext<'_>,
    leaf: ScanLeaf<'_>,
    budget: usize,
    hull: &mut Accumulator,
    accumulator: &mut Accumulator,
    runs: &mut CheckRuns,
) -> Result<ScanRefinement, StudyError> {
    let ScanLeaf {
        region,
        values: grid,
        feature,
        widths,
    } = leaf;
    let n_outputs = accumulator.n_outputs;
    let n_records = grid.n_records;
    let k = grid.outputs.len();
    let counts = &grid.counts;
    let n_feature = counts[feature];
    let stride: usize = counts[feature + 1..].iter().product();
    let n_lines: usize = counts.iter().product::<usize>() / n_feature.max(1);
    if grid.values.iter().any(|v| !v.is_finite()) || n_feature < 2 {
        return Ok(ScanRefinement::NotRefined);
    }
    // The other dimensions' grid points, one per line (the feature coordinate left 0).
    let mut other_counts = counts.clone();
    other_counts[feature] = 1;
    let lines: Vec<Vec<f64>> = (0..n_lines).map(|l| grid_point(&other_counts, l)).collect();
    let row = n_records * k;
    let mut nodes: Vec<Vec<f64>> = (0..n_feature)
        .map(|a| {
            let mut values = Vec::with_capacity(n_lines * row);
            for l in 0..n_lines {
                let run = (l / stride) * stride * n_feature + a * stride + l % stride;
                values.extend_from_slice(&grid.values[run * row..(run + 1) * row]);
            }
            values
        })
        .collect();
    let coordinate = |a: usize| grid_point(&[n_feature], a)[0];
    // The parameter's value at a coordinate of the leaf along the feature dimension.
    let dimension = &context.space.dimensions()[feature];
    let value_at = |eta: f64| {
        let mut local = vec![0.0; region.dim()];
        local[feature] = eta;
        dimension.value_at(region.to_whole(&local)[feature])
    };
    let resolved = |cell: &Cell| {
        let (from, to) = (value_at(cell.from.0), value_at(cell.to.0));
        let middle = 0.5 * (cell.from.0 + cell.to.0);
        cell.depth + 1 >= SCAN_CELL_MAX_DEPTH
            || middle <= cell.from.0
            || middle >= cell.to.0
            || (to - from).abs() <= SCAN_CELL_RESOLUTION * from.abs().max(to.abs())
    };
    let mut open: Vec<Cell> = (0..n_feature - 1)
        .map(|a| Cell {
            from: (coordinate(a), a),
            to: (coordinate(a + 1), a + 1),
            depth: 0,
            misfit: Vec::new(),
        })
        .collect();
    let mut misfit = vec![vec![0.0_f64; n_records]; n_outputs];
    let mut made = 0usize;
    let fold = |misfit: &mut Vec<Vec<f64>>, cell_misfit: &[f64]| {
        for (r, per_output) in cell_misfit.chunks_exact(k.max(1)).enumerate() {
            for (&o, &m) in grid.outputs.iter().zip(per_output) {
                misfit[o][r] = misfit[o][r].max(m);
            }
        }
    };
    while !open.is_empty() {
        let round_runs = open.len() * n_lines;
        if made + round_runs > budget {
            if made == 0 {
                return Ok(ScanRefinement::NotRefined);
            }
            break;
        }
        let points: Vec<f64> = open
            .iter()
            .flat_map(|cell| {
                let middle = 0.5 * (cell.from.0 + cell.to.0);
                lines.iter().flat_map(move |line| {
                    let mut point = line.clone();
                    point[feature] = middle;
                    region.to_whole(&point)
                })
            })
            .collect();
        let before: Vec<EnvelopePoint> = hull.points.clone();
        let mut middles = vec![f64::NAN; open.len() * n_lines * row];
        let mut failed = false;
        let mut checked = Vec::new();
        context.report.runs += round_runs;
        let policy = context.exclusion_policy("check run");
        let complete = context.run_phase("check", &points, None, policy, &mut |block, _| {
            for r in 0..block.count {
                let record = block.first + r;
                for run in 0..round_runs {
                    if block.lockstep.failed(run) {
                        failed = true;
                        continue;
                    }
                    let values = block.record(run, r);
                    let at = run * row + record * k;
                    for (j, &o) in grid.outputs.iter().enumerate() {
                        let truth = accumulator.reported(o, values[o]);
                        middles[at + j] = truth;
                        checked.push((o, record, truth));
                    }
                    hull.widen(record, values);
                    accumulator.widen_runs(record, values);
                }
            }
            Ok(())
        })?;
        if !complete {
            return Ok(ScanRefinement::Interrupted);
        }
        made += round_runs;
        runs.runs += round_runs;
        runs.unique_candidates += round_runs;
        runs.points.extend_from_slice(&points);
        runs.checked.extend(checked);
        if failed {
            return Ok(ScanRefinement::NotRefined);
        }
        let mut next = Vec::new();
        for (c, cell) in open.drain(..).enumerate() {
            let middle = &middles[c * n_lines * row..(c + 1) * n_lines * row];
            let (from, to) = (&nodes[cell.from.1], &nodes[cell.to.1]);
            let mut cell_misfit = vec![0.0_f64; row];
            let mut halve = false;
            let at_resolution = resolved(&cell);
            for l in 0..n_lines {
                for r in 0..n_records {
                    for (j, &o) in grid.outputs.iter().enumerate() {
                        let i = l * row + r * k + j;
                        let (fa, fc, fb) = (from[i], middle[i], to[i]);
                        let width = widths[o];
                        let p = r * n_outputs + o;
                        let seen = excess(fc, before[p].lower, before[p].upper);
                        let overshoot = parabola_overshoot(fa, fc, fb, hull.points[p]);
                        let bend = (fc - 0.5 * (fa + fb)).abs();
                        let m = if at_resolution {
                            seen
                        } else {
                            seen.max(overshoot)
                        };
                        let slot = &mut cell_misfit[r * k + j];
                        *slot = slot.max(m);
                        halve |=
                            m > SCAN_CELL_TOLERANCE * width || bend > SCAN_CELL_MAX_BEND * width;
                    }
                }
            }
            if halve && !at_resolution {
                let middle_node = nodes.len();
                let at = 0.5 * (cell.from.0 + cell.to.0);
                nodes.push(middle.to_vec());
                for (from, to) in [(cell.from, (at, middle_node)), ((at, middle_node), cell.to)] {
                    next.push(Cell {
                        from,
                        to,
                        depth: cell.depth + 1,
                        misfit: cell_misfit.clone(),
                    });
                }
            } else {
                fold(&mut misfit, &cell_misfit);
            }
        }
        open = next;
    }
    // Cells still open when the runs ran out keep what their last test saw.
    for cell in &open {
        fold(&mut misfit, &cell.misfit);
    }
    Ok(ScanRefinement::Refined(RefinedScan { misfit, runs: made }))
}

/// How far the parabola through `(−1, from)`, `(0, middle)`, `(1, to)` reaches past `hull` at its
/// vertex, when the vertex lies inside the cell; 0 otherwise.
fn parabola_overshoot(from: f64, middle: f64, to: f64, hull: EnvelopePoint) -> f64 {
    let slope = 0.5 * (to - from);
    let curvature = 0.5 * (from + to) - middle;
    if curvature == 0.0 {
        return 0.0;
    }
    let vertex = -slope / (2.0 * curvature);
    if vertex.abs() >= 1.0 {
        return 0.0;
    }
    let value = middle + slope * vertex + curvature * vertex * vertex;
    excess(value, hull.lower, hull.upper)
}

#[cfg(test)]
mod tests {
    use super::{parabola_overshoot, refinable_dimension};
    use crate::analysis::envelope::EnvelopePoint;

    #[test]
    fn only_a_grid_with_one_feature_dimension_is_refined() {
        assert_eq!(refinable_dimension(&[33]), Some(0));
        assert_eq!(refinable_dimension(&[3, 17, 3]), Some(1));
        assert_eq!(refinable_dimension(&[9, 9]), None);
        assert_eq!(refinable_dimension(&[3, 3]), None);
    }

    #[test]
    fn the_parabola_overshoots_only_when_its_vertex_is_inside_the_cell() {
        let hull = EnvelopePoint {
            lower: 0.0,
            upper: 1.0,
            ..EnvelopePoint::EMPTY
        };
        // 1 − s² sampled at −1, 0, 1 peaks at 1: inside the hull.
        assert_eq!(parabola_overshoot(0.0, 1.0, 0.0, hull), 0.0);
        // Through (−1, 0), (0, 0.9), (1, 0.4): slope 0.2, curvature −0.7, vertex at s = 1/7.
        let narrower = EnvelopePoint { upper: 0.9, ..hull };
        let over = parabola_overshoot(0.0, 0.9, 0.4, narrower);
        let expected = 0.9 + 0.2 / 7.0 - 0.7 / 49.0 - 0.9;
        assert!((over - expected).abs() < 1e-12, "{over} vs {expected}");
        // A vertex outside the cell: monotone inside it.
        assert_eq!(parabola_overshoot(0.0, 0.5, 2.0, hull), 0.0);
    }
}
