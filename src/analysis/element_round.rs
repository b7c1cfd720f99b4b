//! One round of elements (docs/method.md §12): the planned splits' children designed, run as one
//! stage, fitted and bounded per child, then checked in one phase — a scanned child's check going
//! on into its steepest cells, and refined cell by cell when it fails with one feature dimension
//! — before the children join the tree.
//!
//! ```text
//! planned splits ⇒ every child's new points (its η mapped to ξ) ⇒ run_stage("elements")
//!   ⇒ per child: DesignBounding (a surrogate) or ScanGrid + hull (a scan)
//! ⇒ check points (select_with_overshoots / half steps) ⇒ run_phase("check") ⇒ misfits per child
//! ⇒ scans: bisect_steepest_cells, refine_scan ⇒ children into the tree
//! ```
//!
//! Does not: decide what to split or how (`elements_phase.rs`, `elements.rs`), or judge the union
//! (`check_phase.rs`).

use super::accumulator::Accumulator;
use super::bounds::{Bounder, EnvelopePoint};
use super::check::{trust_verdict, CheckCandidates, CheckPlan, TrustVerdict};
use super::check_phase::{output_scales, CheckRuns};
use super::design_phase::{known_ranges, DesignBounding, ElementScope};
use super::elements::{Element, ElementTree, MIN_OVERSHOOT};
use super::error::StudyError;
use super::method::Method;
use super::nested_design::{ElementRuns, NestedDesign, MAX_KEPT_ELEMENT_VALUES};
use super::phase::PhaseContext;
use super::plan::{grid_point, Plan};
use super::scan_refinement::{
    refinable_dimension, refine_scan, ScanLeaf, ScanRefinement, ScanValues,
};
use super::scanned_leaf::{bisect_steepest_cells, judge_scan_run, ScanCheck, ScanGrid};
use super::sobol_indices::SobolSeries;
use super::stages::StageCursor;
use crate::uq::ElementBox;
use std::time::Instant;

/// Where an element's runs go: a surrogate's design, or a scanned leaf's grid.
pub(super) enum ElementPlan {
    /// The design of the element's surrogates.
    Surrogate(Plan),
    /// A grid of this many points per dimension, faces included (a stalled leaf's scan).
    Scan(Vec<usize>),
}

/// An element's design: its points in its own coordinates and the runs it and its check cost.
pub(super) struct ElementDesign {
    /// Its points: a surrogate's design or a scan's grid.
    pub plan: ElementPlan,
    /// Its surrogates' order (0 for a scan).
    pub order: usize,
    /// New runs (a nested design's points that are not its parent's).
    pub runs: usize,
    /// Runs of its check.
    pub check_runs: usize,
    /// Which of its points are its parent's runs (`None`: every point is a new run).
    pub nested: Option<NestedDesign>,
}

impl ElementDesign {
    /// The points of its new runs, in the element's own coordinates, row-major.
    pub(super) fn points(&self, dim: usize) -> Vec<f64> {
        match (&self.plan, &self.nested) {
            (ElementPlan::Surrogate(plan), None) => plan.points(dim),
            (ElementPlan::Surrogate(plan), Some(nested)) => plan
                .points(dim)
                .chunks_exact(dim.max(1))
                .zip(&nested.sources)
                .filter(|(_, source)| source.is_none())
                .flat_map(|(point, _)| point.to_vec())
                .collect(),
            (ElementPlan::Scan(counts), _) => (0..self.runs)
                .flat_map(|index| grid_point(counts, index))
                .collect(),
        }
    }

    /// Its design's points per dimension when it is a tensor grid its own children can nest in.
    pub(super) fn axis_nodes(&self, dim: usize) -> Option<Vec<Vec<f64>>> {
        match (&self.plan, &self.nested) {
            (_, Some(nested)) => Some(nested.axis_nodes.clone()),
            (ElementPlan::Surrogate(Plan::Surrogate(design)), None) => {
                Some((0..dim).map(|r| design.axis_nodes(r).to_vec()).collect())
            }
            _ => None,
        }
    }

    /// Design points in all (reused and new): the values each record's fit reads.
    pub(super) fn n_points(&self) -> usize {
        self.nested
            .as_ref()
            .map_or(self.runs, |nested| nested.sources.len())
    }
}

/// One failing leaf's split, as planned (or its scan: no dimension halved, one child with the
/// leaf's box and a grid).
pub(super) struct PlannedSplit {
    /// The leaf split.
    pub parent: usize,
    /// The dimensions halved (none for a scan).
    pub dims: Vec<usize>,
    /// The children's boxes.
    pub children: Vec<ElementBox>,
    /// One per child.
    pub designs: Vec<ElementDesign>,
}

/// One round: every planned child's design as one stage, bounded per child, then every child's
/// check in one phase (a scanned child's bisections after it, and its refinement within
/// `spare_runs` when its check failed); the children join the tree. Returns whether the round
/// ran to the end (an interrupted round adds no element; its runs stay in the hull of true runs).
pub(super) fn run_round(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    tree: &mut ElementTree,
    planned: Vec<PlannedSplit>,
    accumulator: &mut Accumulator,
    runs: &mut CheckRuns,
    mut spare_runs: usize,
) -> Result<bool, StudyError> {
    let d = context.space.len();
    let n_outputs = context.scene.outputs.len();
    let n_records = accumulator.times.len();
    let ranges = known_ranges(context.scene);
    let surrogate_ranges = crate::scene::surrogate_ranges(context.model, context.scene);
    let active = tree.active.clone();
    // Every child in plan order, with the range of its samples in the stage.
    let children: Vec<(usize, &ElementBox, &ElementDesign)> = planned
        .iter()
        .enumerate()
        .flat_map(|(s, split)| {
            split
                .children
                .iter()
                .zip(&split.designs)
                .map(move |(c, design)| (s, c, design))
        })
        .collect();
    // What a nested child reuses: its parent's kept runs.
    let parent_runs: Vec<Option<&ElementRuns>> = children
        .iter()
        .map(|&(s, _, design)| {
            design.nested.as_ref()?;
            tree.elements[planned[s].parent].runs.as_ref()
        })
        .collect();
    // Which surrogate children keep their runs for their own children, within the memory bound.
    let active_outputs: Vec<usize> = (0..n_outputs).filter(|&o| tree.active[o]).collect();
    let mut kept_values = tree.kept_values();
    let kept_runs: Vec<Option<ElementRuns>> = children
        .iter()
        .map(|&(_, _, design)| {
            design.axis_nodes(d)?;
            let values = design.n_points() * n_records * active_outputs.len();
            kept_values = kept_values.checked_add(values)?;
            (kept_values <= MAX_KEPT_ELEMENT_VALUES)
                .then(|| ElementRuns::new(active_outputs.clone(), design.n_points()))
        })
        .collect();
    let design_of: Vec<&ElementDesign> = children.iter().map(|&(_, _, design)| design).collect();
    let mut points = Vec::new();
    let mut samples = Vec::with_capacity(children.len());
    for &(_, region, design) in &children {
        let first = points.len() / d.max(1);
        points.extend(region.rows_to_whole(&design.points(d)));
        samples.push(first..first + design.runs);
    }
    // A surrogate child's bounder; `None` for a scan.
    let bounders = children
        .iter()
        .map(|&(_, _, design)| match &design.plan {
            ElementPlan::Surrogate(plan) => Bounder::new(
                Method::LegendreScan,
                plan,
                d,
                design.order,
                context.options.scan_grid,
                true,
            )
            .map(Some),
            ElementPlan::Scan(_) => Ok(None),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut boundings: Vec<Option<DesignBounding>> = children
        .iter()
        .zip(&bounders)
        .zip(kept_runs)
        .map(|((&(_, region, _), bounder), kept)| {
            Some(DesignBounding {
                bounder: bounder.as_ref()?,
                threads: context.threads,
                n_outputs,
                locates_extremes: true,
                candidates: CheckCandidates::new(d),
                sobol: SobolSeries::new(d, n_outputs),
                screen_hull: &[],
                surrogate_ranges: &surrogate_ranges,
                element: Some(ElementScope {
                    element: region,
                    checked_outputs: &active,
                }),
                kept,
            })
        })
        .collect();
    let mut element_points: Vec<Accumulator> = children
        .iter()
        .zip(&bounders)
        .map(|(_, bounder)| {
            let mut hull = Accumulator::new(n_outputs, n_records).with_known_ranges(&ranges);
            if bounder.is_none() {
                hull.points = vec![EnvelopePoint::EMPTY; n_records * n_outputs];
            }
            hull
        })
        .collect();
    // What a scan's check needs to know of its grid.
    let mut scan_grids: Vec<Option<ScanGrid>> = children
        .iter()
        .map(|&(_, _, design)| match &design.plan {
            ElementPlan::Scan(counts) => Some(ScanGrid::new(counts.clone(), &active, n_records)),
            ElementPlan::Surrogate(_) => None,
        })
        .collect();
    // A scan with one feature dimension keeps its grid's values, should it need refining.
    let mut scan_values: Vec<Option<(ScanValues, usize)>> = children
        .iter()
        .map(|&(_, _, design)| match &design.plan {
            ElementPlan::Scan(counts) => refinable_dimension(counts)
                .map(|feature| (ScanValues::new(counts, &active_outputs, n_records), feature)),
            ElementPlan::Surrogate(_) => None,
        })
        .collect();
    context.report.runs += points.len() / d.max(1);
    let policy = context.design_failure_policy(Method::LegendreScan);
    let complete = context.run_stage(
        stages,
        "elements",
        &points,
        None,
        policy,
        &mut |block, report| {
            let t_bound = Instant::now();
            for r in 0..block.count {
                for i in 0..block.lockstep.len() {
                    accumulator.widen_runs(block.first + r, block.record(i, r));
                }
            }
            for (c, ((((bounding, range), child), grid), kept)) in boundings
                .iter_mut()
                .zip(&samples)
                .zip(element_points.iter_mut())
                .zip(scan_grids.iter_mut())
                .zip(scan_values.iter_mut())
                .enumerate()
            {
                let Some(bounding) = bounding else {
                    if let Some(grid) = grid {
                        for r in 0..block.count {
                            grid.absorb(child, block.first + r, &|i| {
                                block.record(range.start + i, r)
                            });
                        }
                    }
                    if let Some((values, _)) = kept {
                        for r in 0..block.count {
                            for i in 0..range.len() {
                                let run = block.record(range.start + i, r);
                                values.absorb(accumulator, i, block.first + r, run);
                            }
                        }
                    }
                    continue;
                };
                let values = |r: usize| -> Vec<f64> {
                    child_row(
                        design_of[c],
                        parent_runs[c],
                        range,
                        block.first + r,
                        n_outputs,
                        &|i| block.record(i, r),
                    )
                };
                bounding.absorb(block.first, block.count, &values, &|_| false, None, child)?;
            }
            report.bound_seconds += t_bound.elapsed().as_secs_f64();
            Ok(())
        },
    )?;
    for bounder in bounders.iter().flatten() {
        context
            .report
            .phase_seconds
            .add_bounding(&bounder.phase_seconds());
    }
    if !complete {
        return Ok(false);
    }

    // Every child's check in one phase: a surrogate's at its predicted extremes, a scan's
    // between its grid's extreme points (their hull, before the check widens it, is what a scan's
    // check judges).
    let t_select = Instant::now();
    let union = tree.union(&|r, o| accumulator.run_hull(r, o));
    let min_excess: Vec<f64> = output_scales(context.scene, &union)
        .iter()
        .map(|s| MIN_OVERSHOOT * s.width)
        .collect();
    let hull = |r: usize, o: usize| accumulator.run_hull(r, o);
    let plans: Vec<CheckPlan> = boundings
        .iter()
        .zip(&children)
        .zip(&scan_grids)
        .map(
            |((bounding, &(_, region, design)), grid)| match (bounding, grid) {
                (Some(bounding), _) => bounding.candidates.select_with_overshoots(
                    design.check_runs,
                    &active_outputs,
                    &hull,
                    &min_excess,
                ),
                (None, Some(grid)) => {
                    grid.half_steps(region, design.check_runs - grid.bisection_runs())
                }
                (None, None) => unreachable!("a child without a bounder is a scan"),
            },
        )
        .collect();
    let grid_hulls: Vec<Option<Vec<EnvelopePoint>>> = boundings
        .iter()
        .zip(&element_points)
        .map(|(bounding, hull)| bounding.is_none().then(|| hull.points.clone()))
        .collect();
    context.report.phase_seconds.check_selection += t_select.elapsed().as_secs_f64();
    let mut sobol: Vec<Option<SobolSeries>> = Vec::with_capacity(children.len());
    let mut candidates = Vec::with_capacity(children.len());
    let mut kept_runs: Vec<Option<ElementRuns>> = Vec::with_capacity(children.len());
    for bounding in boundings {
        match bounding {
            Some(b) => {
                sobol.push(Some(b.sobol));
                candidates.push(b.candidates);
                kept_runs.push(b.kept);
            }
            None => {
                sobol.push(None);
                candidates.push(CheckCandidates::new(d));
                kept_runs.push(None);
            }
        }
    }
    let mut check_points = Vec::new();
    let mut owner = Vec::new();
    let mut by_record: Vec<Vec<(usize, usize, f64, usize)>> = vec![Vec::new(); n_records];
    for (c, plan) in plans.iter().enumerate() {
        let first = owner.len();
        check_points.extend_from_slice(&plan.points);
        for (run, checks) in plan.checks.iter().enumerate() {
            owner.push(c);
            for &(record, output, _side, predicted) in checks {
                by_record[record].push((first + run, output, predicted, c));
            }
        }
    }
    let check_runs = owner.len();
    let mut misfit = vec![vec![vec![0.0_f64; n_records]; n_outputs]; children.len()];
    let mut checked = Vec::new();
    context.report.runs += check_runs;
    let policy = context.exclusion_policy("check run");
    let complete = context.run_phase(
        "check",
        &check_points,
        None,
        policy,
        &mut |block, _report| {
            for r in 0..block.count {
                let record = block.first + r;
                for (run, &c) in owner.iter().enumerate() {
                    if block.lockstep.failed(run) {
                        continue;
                    }
                    let values = block.record(run, r);
                    if let Some(grid_hull) = &grid_hulls[c] {
                        judge_scan_run(
                            accumulator,
                            grid_hull,
                            &active,
                            record,
                            values,
                            &mut misfit[c],
                            &mut checked,
                        );
                    }
                    element_points[c].widen(record, values);
                    accumulator.widen_runs(record, block.record(run, r));
                }
                for &(run, output, predicted, c) in &by_record[record] {
                    if block.lockstep.failed(run) {
                        continue;
                    }
                    let truth = accumulator.reported(output, block.record(run, r)[output]);
                    checked.push((output, record, truth));
                    let m = &mut misfit[c][output][record];
                    *m = m.max((truth - predicted).abs());
                }
            }
            Ok(())
        },
    )?;
    if !complete {
        return Ok(false);
    }
    runs.runs += check_runs;
    runs.unique_candidates += plans.iter().map(|p| p.unique_candidates).sum::<usize>();
    runs.points.extend_from_slice(&check_points);
    runs.checked.extend(checked);

    // A scan's check goes on into its steepest cells, bisecting each down to where a jump is;
    // a scan with one feature dimension that still fails is refined along it.
    let scales = output_scales(context.scene, &union);
    let widths: Vec<f64> = scales.iter().map(|s| s.width).collect();
    let mut bisection_runs = vec![0usize; children.len()];
    for c in 0..children.len() {
        let (Some(grid), Some(grid_hull)) = (&scan_grids[c], &grid_hulls[c]) else {
            continue;
        };
        let leaf = ScanCheck {
            grid,
            grid_hull,
            region: children[c].1,
            active: &active,
        };
        let Some(made) = bisect_steepest_cells(
            context,
            &leaf,
            &mut element_points[c],
            accumulator,
            &mut misfit[c],
            runs,
        )?
        else {
            return Ok(false);
        };
        bisection_runs[c] += made;
        let fails = active_outputs.iter().any(|&o| {
            let worst = misfit[c][o].iter().copied().fold(0.0, f64::max);
            trust_verdict(worst, scales[o].width, scales[o].resolution).1 == TrustVerdict::Untrusted
        });
        let (Some((values, feature)), true) = (scan_values[c].take(), fails) else {
            continue;
        };
        let leaf = ScanLeaf {
            region: children[c].1,
            values,
            feature,
            widths: &widths,
        };
        match refine_scan(
            context,
            leaf,
            spare_runs,
            &mut element_points[c],
            accumulator,
            runs,
        )? {
            ScanRefinement::Refined(refined) => {
                spare_runs -= refined.runs;
                bisection_runs[c] += refined.runs;
                misfit[c] = refined.misfit;
            }
            ScanRefinement::NotRefined => {}
            ScanRefinement::Interrupted => return Ok(false),
        }
    }

    // The children join the tree, split by split. A child's points of the outputs it was not made
    // for are emptied: a nested child's reused runs carry no values for them.
    let active = tree.active.clone();
    let mut made = element_points
        .into_iter()
        .zip(misfit)
        .zip(sobol)
        .zip(candidates)
        .zip(kept_runs)
        .zip(
            plans
                .iter()
                .zip(&bisection_runs)
                .map(|(p, bisected)| p.checks.len() + bisected),
        );
    for split in planned {
        let depth = tree.elements[split.parent].depth + 1;
        let children: Vec<Element> = split
            .children
            .into_iter()
            .zip(split.designs)
            .map(|(region, design)| {
                let (((((mut points, misfit), sobol), candidates), runs), check_runs) =
                    made.next().expect("one made child per planned child");
                let scan_grid = match &design.plan {
                    ElementPlan::Scan(counts) => Some(counts.clone()),
                    ElementPlan::Surrogate(_) => None,
                };
                if scan_grid.is_none() {
                    for (k, point) in points.points.iter_mut().enumerate() {
                        if !active[k % n_outputs.max(1)] {
                            *point = EnvelopePoint::EMPTY;
                        }
                    }
                }
                Element {
                    region,
                    parent: Some(split.parent),
                    // A scan halves nothing: it is its parent's box.
                    depth: if scan_grid.is_some() {
                        depth - 1
                    } else {
                        depth
                    },
                    children: Vec::new(),
                    split_dims: Vec::new(),
                    design_runs: design.runs,
                    reused_runs: design.n_points() - design.runs,
                    check_runs,
                    order: design.order,
                    points: points.points,
                    misfit,
                    sobol,
                    candidates,
                    scan_grid,
                    axis_nodes: design.axis_nodes(d),
                    runs,
                }
            })
            .collect();
        tree.split(split.parent, split.dims, children);
    }
    Ok(true)
}

/// One record's row of a child's design (`n_points × n_outputs`, row-major, design point order):
/// a new run's values from the stage (`stage_record(i)` for stage sample `i`, the child's new
/// runs being `range`, in design point order), a reused point's from its parent's kept runs at
/// `record` (0 for the outputs the parent did not keep).
fn child_row<'v>(
    design: &ElementDesign,
    parent_runs: Option<&ElementRuns>,
    range: &std::ops::Range<usize>,
    record: usize,
    n_outputs: usize,
    stage_record: &dyn Fn(usize) -> &'v [f64],
) -> Vec<f64> {
    let mut row = Vec::with_capacity(design.n_points() * n_outputs);
    match (&design.nested, parent_runs) {
        (Some(nested), Some(parent)) => {
            let mut next = range.start;
            for source in &nested.sources {
                match source {
                    Some(sample) => parent.extend_run(record, *sample, n_outputs, &mut row),
                    None => {
                        row.extend_from_slice(stage_record(next));
                        next += 1;
                    }
                }
            }
        }
        _ => {
            for i in range.clone() {
                row.extend_from_slice(stage_record(i));
            }
        }
    }
    row
}
