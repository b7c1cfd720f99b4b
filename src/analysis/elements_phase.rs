//! The elements phase (docs/method.md §12): where the first check did not trust the surrogate,
//! rounds of splitting the failing elements, each child with its own design, bounds and check,
//! until every output is trusted or the budget is spent; then the union becomes the study's
//! envelope and the union's check its verdict.
//!
//! ```text
//! per round:  union ⇒ scales (width, resolution) ⇒ failing leaves ⇒ split plan within the budget
//!             ⇒ one stage "elements": every child's design (its own η mapped to ξ), lock-step
//!               ⇒ per child: fit and bound (DesignBounding with its ElementScope) ⇒ candidates
//!             ⇒ one check phase: every child's selected candidates ⇒ misfits per child
//! at the end: the union into the accumulator ⇒ judge (the union's misfits) ⇒ CheckReport
//! ```
//!
//! Every run any element makes widens the hull of true runs, and the union contains that hull,
//! so no bound is narrower than a true run. A round's designs are one stage, so `plan`/`run`/
//! `merge` replay the same decisions (docs/distributed.md §7); the checks run where the study
//! runs, like the first one. Does not: decide where to split (`elements.rs`).

use super::accumulator::Accumulator;
use super::bounds::Bounder;
use super::check::{automatic_check_runs, CheckCandidates, CheckPlan, Side};
use super::check_phase::{judge, output_scales, CheckRuns};
use super::design_phase::{known_ranges, DesignBounding, ElementScope};
use super::elements::{Element, ElementTree, OutputScale, MAX_SPLIT_DIMS, MIN_ELEMENT_ORDER};
use super::error::StudyError;
use super::method::Method;
use super::phase::PhaseContext;
use super::plan::Plan;
use super::refine_phase::{refine_extremes, refine_reserve, RefineTarget};
use super::report::{ElementSummary, ElementsReport};
use super::sobol_indices::SobolSeries;
use super::sparse::SparseDesign;
use super::stages::StageCursor;
use crate::uq::{Design, ElementBox, Family, Truncation};
use std::sync::Arc;
use std::time::Instant;

/// Elements of up to this many dimensions get the tensor Gauss grid (scanned), as `auto` gives
/// the whole box; above, the Leja sparse grid of total degree k (the box optimiser), whose runs
/// grow polynomially in d. Measured on the vehicle (d = 4): children on the total-degree-4 grid
/// (70 runs) missed by up to the whole union width, on the order-3 tensor grid (256) by 10–20 %.
pub const ELEMENT_TENSOR_MAX_DIM: usize = super::auto::AUTO_TENSOR_MAX_DIM;

/// An element's design: its points in its own coordinates and the runs it and its check cost.
struct ElementDesign {
    plan: Plan,
    order: usize,
    runs: usize,
    check_runs: usize,
}

/// The design of an element of a `dim`-dimensional box: order `order` (the study's), lowered
/// down to [`MIN_ELEMENT_ORDER`] until the design and its check fit `budget` runs; `None` when
/// even that does not.
fn element_design(dim: usize, order: usize, budget: usize) -> Option<ElementDesign> {
    let lowest = MIN_ELEMENT_ORDER.min(order);
    (lowest..=order).rev().find_map(|k| {
        let plan = if dim <= ELEMENT_TENSOR_MAX_DIM {
            Plan::Surrogate(Design::new(Family::Legendre, dim, k, Truncation::Tensor).ok()?)
        } else {
            Plan::Sparse(Arc::new(SparseDesign::total_degree(dim, k).ok()?))
        };
        let runs = plan.runs(dim)?;
        let check_runs = automatic_check_runs(runs);
        (runs.checked_add(check_runs)? <= budget).then_some(ElementDesign {
            plan,
            order: k,
            runs,
            check_runs,
        })
    })
}

/// One failing leaf's split, as planned.
struct PlannedSplit {
    parent: usize,
    dims: Vec<usize>,
    children: Vec<ElementBox>,
    design: ElementDesign,
}

/// The splits of one round: the failing leaves, worst first, each halved along its split
/// dimensions (or the first of them alone) while the leaves stay within `max_elements` and the
/// children's designs and checks within `budget` runs; the reason when none fits.
fn planned_round(
    tree: &ElementTree,
    scales: &[OutputScale],
    order: usize,
    budget: usize,
    max_elements: usize,
) -> Result<Vec<PlannedSplit>, &'static str> {
    let failing = tree.failing_leaves(scales);
    let d = tree.elements[0].region.dim();
    let mut leaves = tree.leaves().len();
    let mut left = budget;
    let mut planned = Vec::new();
    let mut reason = "resolution";
    for leaf in failing {
        if tree.stalled(leaf.element, scales) {
            if planned.is_empty() && reason == "resolution" {
                reason = "stalled";
            }
            continue;
        }
        let dims = tree.split_dims(leaf.element, &leaf.outputs, scales, MAX_SPLIT_DIMS);
        if dims.is_empty() {
            continue;
        }
        // All the chosen dimensions, else the first alone, within the leaves and the runs left.
        let options = if dims.len() > 1 {
            vec![dims.clone(), dims[..1].to_vec()]
        } else {
            vec![dims]
        };
        let mut chosen = None;
        for dims in options {
            let children = 1usize << dims.len();
            if leaves + children - 1 > max_elements {
                reason = "max-elements";
                continue;
            }
            match element_design(d, order, left / children) {
                Some(design) => {
                    chosen = Some((dims, children, design));
                    break;
                }
                None => reason = "budget",
            }
        }
        let Some((dims, children, design)) = chosen else {
            continue;
        };
        left -= children * (design.runs + design.check_runs);
        leaves += children - 1;
        let region = &tree.elements[leaf.element].region;
        planned.push(PlannedSplit {
            parent: leaf.element,
            children: region.split(&dims),
            dims,
            design,
        });
    }
    if planned.is_empty() {
        Err(reason)
    } else {
        Ok(planned)
    }
}

/// Splits the box into elements where the first check (`context.report.check`, whose misfits
/// are `root_misfit[o][r]`) did not trust the surrogate, until every output is trusted or the
/// budget (`--max-runs`, `--max-elements`) is spent; then the union into `accumulator` and the
/// union's check into the report, with the elements' account (`report.elements`). Does nothing
/// when the first check trusted every output or did not finish.
pub(super) fn split_into_elements(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    root_misfit: Vec<Vec<f64>>,
    root_candidates: CheckCandidates,
    accumulator: &mut Accumulator,
) -> Result<(), StudyError> {
    let Some(first_check) = context.report.check.clone() else {
        return Ok(());
    };
    if first_check.untrusted_outputs.is_empty() || !first_check.complete {
        return Ok(());
    }
    let scene = context.scene;
    let n_outputs = scene.outputs.len();
    let n_records = accumulator.times.len();
    let d = context.space.len();
    let order = context.options.order;
    let mut active = vec![false; n_outputs];
    for &o in &first_check.untrusted_outputs {
        active[o] = true;
    }
    let root = Element {
        region: ElementBox::whole(d),
        parent: None,
        depth: 0,
        children: Vec::new(),
        split_dims: Vec::new(),
        design_runs: context.report.runs - first_check.runs,
        check_runs: first_check.runs,
        order,
        points: accumulator.points[..n_records * n_outputs].to_vec(),
        misfit: root_misfit,
        sobol: context.report.sobol.clone(),
        candidates: root_candidates,
    };
    let mut tree = ElementTree::new(root, active);
    let mut runs = CheckRuns {
        runs: first_check.runs,
        unique_candidates: first_check.unique_candidates,
        points: first_check.points.clone(),
        checked: first_check.checked.clone(),
        complete: first_check.complete,
    };
    let runs_before = context.report.runs;
    // Runs set aside for refining the extremes of what stays untrusted.
    let reserve = refine_reserve(
        d,
        first_check.untrusted_outputs.len(),
        context.options.max_runs,
    );
    let mut rounds = 0;
    let stop = loop {
        let union = tree.union(&|r, o| accumulator.run_hull(r, o));
        let scales = output_scales(scene, &union);
        if tree.failing_leaves(&scales).is_empty() {
            break "trusted";
        }
        let budget = context
            .options
            .max_runs
            .saturating_sub(context.report.runs + reserve);
        let planned = match planned_round(
            &tree,
            &scales,
            order,
            budget,
            context.options.elements.max_elements,
        ) {
            Ok(planned) => planned,
            Err(reason) => break reason,
        };
        rounds += 1;
        if !run_round(context, stages, &mut tree, planned, accumulator, &mut runs)? {
            break "interrupted";
        }
    };

    // The union is the study's envelope, and its check the study's verdict.
    let union = tree.union(&|r, o| accumulator.run_hull(r, o));
    accumulator.points.truncate(n_records * n_outputs);
    accumulator.points.copy_from_slice(&union);
    let mut misfit = tree.union_misfit();
    let mut check = judge(scene, runs.clone(), &misfit, accumulator);
    let element_runs = context.report.runs - runs_before;
    // Outputs still untrusted: their extremes refined on the true model, the inner bound that
    // true runs give (the envelope takes in every value found).
    if !check.untrusted_outputs.is_empty() && stop != "interrupted" {
        let targets = refine_targets(&tree, &check.untrusted_outputs, accumulator);
        let budget = context.options.max_runs.saturating_sub(context.report.runs);
        if let Some(refinement) =
            refine_extremes(context, &targets, budget, accumulator, &mut misfit)?
        {
            accumulator.widen_to_runs();
            check = judge(scene, runs, &misfit, accumulator);
            context.report.refinement = Some(refinement);
        }
    }
    let scales = output_scales(scene, &accumulator.points);
    let elements = summarize(&tree, &scales);
    context.report.check = Some(check);
    if rounds > 0 {
        context.report.elements = Some(ElementsReport {
            rounds,
            runs: element_runs,
            stop,
            outputs: first_check.untrusted_outputs.clone(),
            elements,
        });
    }
    Ok(())
}

/// The extremes to refine: for each of `outputs`, at its widest record of the union, both sides,
/// each from where the leaf holding that side's bound put its surrogate's extreme (the root's
/// prediction, or the centre, where that leaf has none).
fn refine_targets(
    tree: &ElementTree,
    outputs: &[usize],
    accumulator: &Accumulator,
) -> Vec<RefineTarget> {
    let n_outputs = tree.n_outputs;
    let n_records = tree.n_records();
    let leaves = tree.leaves();
    let d = tree.elements[0].region.dim();
    let mut targets = Vec::new();
    for &o in outputs {
        let width = |r: usize| {
            let p = accumulator.points[r * n_outputs + o];
            p.upper - p.lower
        };
        let Some(record) = (0..n_records).fold(None, |best: Option<usize>, r| match best {
            Some(b) if width(b) >= width(r) => best,
            _ => Some(r),
        }) else {
            continue;
        };
        for side in [Side::Lower, Side::Upper] {
            let bound = |e: usize| {
                let p = tree.elements[e].points[record * n_outputs + o];
                match side {
                    Side::Lower => -p.lower,
                    Side::Upper => p.upper,
                }
            };
            let holder = leaves
                .iter()
                .copied()
                .fold(None, |best: Option<usize>, e| match best {
                    Some(b) if bound(b) >= bound(e) => best,
                    _ => Some(e),
                })
                .unwrap_or(0);
            let start = tree.elements[holder]
                .candidates
                .extreme(record, o, side)
                .or_else(|| tree.elements[0].candidates.extreme(record, o, side))
                .map_or_else(|| vec![0.0; d], |(point, _)| point.to_vec());
            targets.push(RefineTarget {
                output: o,
                record,
                side,
                start,
            });
        }
    }
    targets
}

/// The elements' account for the report.
fn summarize(tree: &ElementTree, scales: &[OutputScale]) -> Vec<ElementSummary> {
    let failing: Vec<(usize, Vec<usize>)> = tree
        .failing_leaves(scales)
        .into_iter()
        .map(|leaf| (leaf.element, leaf.outputs))
        .collect();
    let n_outputs = tree.n_outputs;
    tree.elements
        .iter()
        .enumerate()
        .map(|(e, element)| {
            let leaf = element.children.is_empty();
            let region = &element.region;
            let series = if leaf && tree.elements.len() > 1 {
                (0..n_outputs)
                    .filter(|&o| tree.active[o])
                    .map(|o| {
                        let column = element.points.iter().skip(o).step_by(n_outputs.max(1));
                        let (lower, upper) = column.map(|p| (p.lower, p.upper)).unzip();
                        (o, lower, upper)
                    })
                    .collect()
            } else {
                Vec::new()
            };
            ElementSummary {
                parent: element.parent,
                depth: element.depth,
                lower_xi: region
                    .center
                    .iter()
                    .zip(&region.half_width)
                    .map(|(c, r)| c - r)
                    .collect(),
                upper_xi: region
                    .center
                    .iter()
                    .zip(&region.half_width)
                    .map(|(c, r)| c + r)
                    .collect(),
                split_dims: element.split_dims.clone(),
                design_runs: element.design_runs,
                check_runs: element.check_runs,
                order: element.order,
                leaf,
                untrusted_outputs: failing
                    .iter()
                    .find(|(f, _)| *f == e)
                    .map(|(_, outputs)| outputs.clone())
                    .unwrap_or_default(),
                series,
            }
        })
        .collect()
}

/// One round: every planned child's design as one stage, bounded per child, then every child's
/// check in one phase; the children join the tree. Returns whether the round ran to the end
/// (an interrupted round adds no element; its runs stay in the hull of true runs).
fn run_round(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    tree: &mut ElementTree,
    planned: Vec<PlannedSplit>,
    accumulator: &mut Accumulator,
    runs: &mut CheckRuns,
) -> Result<bool, StudyError> {
    let d = context.space.len();
    let n_outputs = context.scene.outputs.len();
    let n_records = accumulator.times.len();
    let ranges = known_ranges(context.scene);
    let active = tree.active.clone();
    // Every child in plan order, with the range of its samples in the stage.
    let children: Vec<(usize, &ElementBox, &ElementDesign)> = planned
        .iter()
        .enumerate()
        .flat_map(|(s, split)| split.children.iter().map(move |c| (s, c, &split.design)))
        .collect();
    let mut points = Vec::new();
    let mut samples = Vec::with_capacity(children.len());
    for &(_, region, design) in &children {
        let first = points.len() / d.max(1);
        points.extend(region.rows_to_whole(&design.plan.points(d)));
        samples.push(first..first + design.runs);
    }
    let bounders = children
        .iter()
        .map(|&(_, _, design)| {
            Bounder::new(
                Method::LegendreScan,
                &design.plan,
                d,
                design.order,
                context.options.scan_grid,
                true,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut boundings: Vec<DesignBounding> = children
        .iter()
        .zip(&bounders)
        .map(|(&(_, region, _), bounder)| DesignBounding {
            bounder,
            threads: context.threads,
            n_outputs,
            locates_extremes: true,
            candidates: CheckCandidates::new(d),
            sobol: SobolSeries::new(d, n_outputs),
            screen_hull: &[],
            known_ranges: &ranges,
            element: Some(ElementScope {
                element: region,
                checked_outputs: &active,
            }),
        })
        .collect();
    let mut element_points: Vec<Accumulator> = children
        .iter()
        .map(|_| Accumulator::new(n_outputs, n_records).with_known_ranges(&ranges))
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
            for ((bounding, range), child) in boundings
                .iter_mut()
                .zip(&samples)
                .zip(element_points.iter_mut())
            {
                let values = |r: usize| -> Vec<f64> {
                    let mut row = Vec::with_capacity(range.len() * n_outputs);
                    for i in range.clone() {
                        row.extend_from_slice(block.record(i, r));
                    }
                    row
                };
                bounding.absorb(block.first, block.count, &values, &|_| false, child)?;
            }
            report.bound_seconds += t_bound.elapsed().as_secs_f64();
            Ok(())
        },
    )?;
    for bounder in &bounders {
        context
            .report
            .phase_seconds
            .add_bounding(&bounder.phase_seconds());
    }
    if !complete {
        return Ok(false);
    }

    // Every child's check in one phase.
    let t_select = Instant::now();
    let plans: Vec<CheckPlan> = boundings
        .iter()
        .zip(&children)
        .map(|(bounding, &(_, _, design))| bounding.candidates.select(design.check_runs))
        .collect();
    context.report.phase_seconds.check_selection += t_select.elapsed().as_secs_f64();
    let (sobol, candidates): (Vec<SobolSeries>, Vec<CheckCandidates>) = boundings
        .into_iter()
        .map(|b| (b.sobol, b.candidates))
        .unzip();
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
                    element_points[c].widen(record, block.record(run, r));
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

    // The children join the tree, split by split.
    let mut made = element_points
        .into_iter()
        .zip(misfit)
        .zip(sobol)
        .zip(candidates)
        .zip(plans.iter().map(|p| p.checks.len()));
    for split in planned {
        let depth = tree.elements[split.parent].depth + 1;
        let children: Vec<Element> = split
            .children
            .into_iter()
            .map(|region| {
                let ((((points, misfit), sobol), candidates), check_runs) =
                    made.next().expect("one made child per planned child");
                Element {
                    region,
                    parent: Some(split.parent),
                    depth,
                    children: Vec::new(),
                    split_dims: Vec::new(),
                    design_runs: split.design.runs,
                    check_runs,
                    order: split.design.order,
                    points: points.points,
                    misfit,
                    sobol: Some(sobol),
                    candidates,
                }
            })
            .collect();
        tree.split(split.parent, split.dims, children);
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn element_designs_fit_the_budget_by_lowering_the_order() {
        // d = 1: the tensor grid of k + 1 points, its check at least 8 runs.
        let design = element_design(1, 4, 100).unwrap();
        assert_eq!((design.order, design.runs, design.check_runs), (4, 5, 8));
        // d = 4, k = 4: the tensor grid, 625 runs + 63 checks.
        let design = element_design(4, 4, 688).unwrap();
        assert!(matches!(design.plan, Plan::Surrogate(_)));
        assert_eq!((design.order, design.runs, design.check_runs), (4, 625, 63));
        // 687 runs do not fit order 4; order 3 (256 + 26) does.
        let design = element_design(4, 4, 687).unwrap();
        assert_eq!((design.order, design.runs), (3, 256));
        // Not even order 2 (81 + 9).
        assert!(element_design(4, 4, 89).is_none());
        // d = 5: the total-degree Leja grid, C(9, 4) = 126 runs + 13 checks.
        let design = element_design(5, 4, 139).unwrap();
        assert!(matches!(design.plan, Plan::Sparse(_)));
        assert_eq!((design.order, design.runs, design.check_runs), (4, 126, 13));
    }
}
