//! The elements phase (docs/method.md §12): where the first check did not trust the surrogate,
//! rounds of splitting the failing elements, each child with its own design, bounds and check,
//! until every output is trusted or the budget is spent; then the union becomes the study's
//! envelope and the union's check its verdict.
//!
//! ```text
//! first:      the trusted outputs' overshoots checked (check_overshoots) ⇒ the root element
//! per round:  union ⇒ scales (width, resolution) ⇒ failing leaves (or, all trusted and d = 1,
//!             the imprecise ones) ⇒ split plan within the budget ⇒ run_round (element_round.rs)
//! at the end: the union into the accumulator ⇒ judge (the union's misfits) ⇒ CheckReport
//!             ⇒ still untrusted: refine_extremes on the true model (refine_phase.rs)
//! ```
//!
//! A stalled leaf becomes one scanned child (its own box): a grid of true runs whose hull is its
//! envelope, checked by the excess of runs half a grid step from its extreme points and of a
//! bisection of each output's steepest cell (`scanned_leaf.rs`), and refined cell by cell when
//! that check fails (`scan_refinement.rs`). A child's grid nests in its parent's where the parent
//! kept its runs (`nested_design.rs`).
//!
//! Every run any element makes widens the hull of true runs, and the union contains that hull,
//! so no bound is narrower than a true run. A round's designs are one stage, so `plan`/`run`/
//! `merge` replay the same decisions (docs/distributed.md §7); the checks run where the study
//! runs, like the first one. Does not: decide which dimensions to split or when a leaf fails
//! (`elements.rs`), or run a round (`element_round.rs`).

use super::accumulator::Accumulator;
use super::auto::total_degree_terms;
use super::check::{automatic_check_runs, CheckCandidates, Side};
use super::check_phase::{check, judge, output_scales, CheckOutcome, CheckRuns};
use super::element_round::{run_round, ElementDesign, ElementPlan, PlannedSplit};
use super::elements::{
    Element, ElementTree, FailingLeaf, OutputScale, ELEMENT_PRECISION_MISFIT,
    ELEMENT_TENSOR_MAX_DIM, MAX_SPLIT_DIMS, MIN_ELEMENT_ORDER, MIN_OVERSHOOT, PRECISION_MAX_DIM,
    PRECISION_SPLIT_SHARE, SCAN_BISECTIONS, SCAN_FEATURE_POINTS, SCAN_OTHER_POINTS,
};
use super::error::StudyError;
use super::horizon_phase::verify_horizon;
use super::nested_design::{nested_design, ElementRuns};
use super::phase::PhaseContext;
use super::plan::Plan;
use super::refine_phase::{refine_budget, refine_extremes, refine_reserve, RefineTarget};
use super::report::{ElementSummary, ElementsReport};
use super::sparse::SparseDesign;
use super::stages::StageCursor;
use crate::uq::{Design, ElementBox, Family, Truncation};
use std::sync::Arc;
use std::time::Instant;

/// The scan of a stalled `leaf` (docs/method.md §12): the finest of [`SCAN_FEATURE_POINTS`] along
/// the dimensions its ancestors were halved along and [`SCAN_OTHER_POINTS`] along the others whose
/// runs and check (the half steps and one bisection of [`SCAN_BISECTIONS`] runs per output the
/// elements are for) fit `budget`; `None` when not even the coarsest does.
fn scan_design(tree: &ElementTree, leaf: usize, budget: usize) -> Option<ElementDesign> {
    let d = tree.elements[leaf].region.dim();
    let features = tree.feature_dims(leaf);
    let bisections = SCAN_BISECTIONS * tree.active.iter().filter(|&&a| a).count();
    SCAN_FEATURE_POINTS.iter().find_map(|&n| {
        let counts: Vec<usize> = (0..d)
            .map(|j| {
                if features.contains(&j) {
                    n
                } else {
                    SCAN_OTHER_POINTS
                }
            })
            .collect();
        let runs = counts.iter().try_fold(1usize, |a, &c| a.checked_mul(c))?;
        let check_runs = automatic_check_runs(runs) + bisections;
        (runs.checked_add(check_runs)? <= budget).then_some(ElementDesign {
            plan: ElementPlan::Scan(counts),
            order: 0,
            runs,
            check_runs,
            nested: None,
        })
    })
}

/// A fresh design of an element of a `dim`-dimensional box at order `order`: the tensor Gauss
/// grid up to [`ELEMENT_TENSOR_MAX_DIM`], the Leja sparse grid above — `None` when it and its
/// check need more than `budget` runs. The sparse grid's runs (one per term of the total-degree
/// set) are counted before it is built: at d = 77 and order 4 the grid has 1.66 million points,
/// and building it to learn that it does not fit took a minute and 6.4 GB (measured on a Panda
/// with 77 uncertain values, whose elements were planned and none fitted).
fn fresh_design(dim: usize, order: usize, budget: usize) -> Option<ElementDesign> {
    if dim > ELEMENT_TENSOR_MAX_DIM {
        let runs = total_degree_terms(dim, order);
        if runs.checked_add(automatic_check_runs(runs))? > budget {
            return None;
        }
    }
    let plan = if dim <= ELEMENT_TENSOR_MAX_DIM {
        Plan::Surrogate(Design::new(Family::Legendre, dim, order, Truncation::Tensor).ok()?)
    } else {
        Plan::Sparse(Arc::new(SparseDesign::total_degree(dim, order).ok()?))
    };
    let runs = plan.runs(dim)?;
    Some(ElementDesign {
        plan: ElementPlan::Surrogate(plan),
        order,
        runs,
        check_runs: automatic_check_runs(runs),
        nested: None,
    })
}

/// The designs of `children`, parts of element `parent`'s box, at order `k`, if they and their
/// checks fit `budget` runs together. A child whose parent kept its runs (at an order at least
/// `k`) nests in its parent's grid ([`nested_design`]): only its new points are runs, and its
/// check is as large as a fresh design's.
fn child_designs(
    tree: &ElementTree,
    parent: usize,
    children: &[ElementBox],
    k: usize,
    budget: usize,
) -> Option<Vec<ElementDesign>> {
    let element = &tree.elements[parent];
    let dim = element.region.dim();
    let nodes = element
        .axis_nodes
        .as_ref()
        .filter(|_| element.runs.is_some() && element.order >= k);
    let designs: Vec<ElementDesign> = children
        .iter()
        .map(|child| {
            let nested = nodes.and_then(|nodes| nested_design(&element.region, nodes, child, k));
            match nested {
                Some(nested) => Some(ElementDesign {
                    check_runs: automatic_check_runs(nested.sources.len()),
                    runs: nested.new_runs(),
                    plan: ElementPlan::Surrogate(Plan::Surrogate(nested.design.clone())),
                    order: k,
                    nested: Some(nested),
                }),
                None => fresh_design(dim, k, budget),
            }
        })
        .collect::<Option<_>>()?;
    let cost = designs.iter().try_fold(0usize, |sum, x| {
        sum.checked_add(x.runs)?.checked_add(x.check_runs)
    })?;
    (cost <= budget).then_some(designs)
}

/// The most runs a split for precision (every leaf trusted, some above
/// [`ELEMENT_PRECISION_MISFIT`]) may cost, its children's designs and checks together:
/// [`PRECISION_SPLIT_SHARE`] of the study's `--max-runs`.
fn precision_split_cap(max_runs: usize) -> usize {
    (PRECISION_SPLIT_SHARE * max_runs as f64) as usize
}

/// The splits of one round: the leaves `to_split`, worst first, each halved along its split
/// dimensions (or the first of them alone) while the leaves stay within `max_elements` and the
/// children's designs and checks within `budget` runs — a stalled leaf scanned instead (once: a
/// scan that fails is refined in `run_round`, then final); the reason when none fits. A round
/// for `precision` (`Some(most runs per split)`: every leaf trusted) splits within that many runs
/// per leaf and leaves stalled leaves alone.
fn planned_round(
    tree: &ElementTree,
    to_split: Vec<FailingLeaf>,
    precision: Option<usize>,
    scales: &[OutputScale],
    order: usize,
    budget: usize,
    max_elements: usize,
) -> Result<Vec<PlannedSplit>, &'static str> {
    let mut leaves = tree.leaves().len();
    let mut left = budget;
    let mut planned = Vec::new();
    let mut reason = "resolution";
    let split_cap = precision.unwrap_or(usize::MAX);
    for leaf in to_split {
        let element = &tree.elements[leaf.element];
        let stalled = element.scan_grid.is_some() || tree.stalled(leaf.element, scales);
        if stalled && precision.is_some() {
            continue;
        }
        if stalled {
            let scan = element
                .scan_grid
                .is_none()
                .then(|| scan_design(tree, leaf.element, left))
                .flatten();
            match scan {
                Some(design) => {
                    left -= design.runs + design.check_runs;
                    planned.push(PlannedSplit {
                        parent: leaf.element,
                        dims: Vec::new(),
                        children: vec![element.region.clone()],
                        designs: vec![design],
                    });
                }
                None if planned.is_empty() && reason == "resolution" => reason = "stalled",
                None => {}
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
        // The study's order first, halving fewer dimensions before lowering it (a lower order
        // needs more halvings: measured on the vehicle, order-3 children of a two-dimensional
        // split left 10.6 % misses where order-4 children of one-dimensional splits were
        // trusted); down to MIN_ELEMENT_ORDER.
        let mut chosen = None;
        'orders: for k in (MIN_ELEMENT_ORDER.min(order)..=order).rev() {
            for dims in &options {
                let children = element.region.split(dims);
                if leaves + children.len() - 1 > max_elements {
                    reason = "max-elements";
                    continue;
                }
                match child_designs(tree, leaf.element, &children, k, left.min(split_cap)) {
                    Some(designs) => {
                        chosen = Some((dims.clone(), children, designs));
                        break 'orders;
                    }
                    None => reason = "budget",
                }
            }
        }
        let Some((dims, children, designs)) = chosen else {
            continue;
        };
        left -= designs.iter().map(|x| x.runs + x.check_runs).sum::<usize>();
        leaves += children.len() - 1;
        planned.push(PlannedSplit {
            parent: leaf.element,
            children,
            dims,
            designs,
        });
    }
    if planned.is_empty() {
        Err(reason)
    } else {
        Ok(planned)
    }
}

/// What the elements start from: the study's design, its kept runs, its check's misfits and its
/// surrogates' predicted extremes.
pub(super) struct RootDesign<'p> {
    /// The study's design.
    pub plan: &'p Plan,
    /// Its runs, every output (`None`: not kept; its children get fresh designs).
    pub runs: Option<ElementRuns>,
    /// `misfit[o][r]` of the first check.
    pub misfit: Vec<Vec<f64>>,
    /// Where its surrogates put their extremes.
    pub candidates: CheckCandidates,
}

/// Splits the box into elements where the first check (`context.report.check`, whose misfits
/// are `root.misfit[o][r]`) did not trust the surrogate, until every output is trusted or the
/// budget (`--max-runs`, `--max-elements`) is spent; then the union into `accumulator` and the
/// union's check into the report, with the elements' account (`report.elements`). Does nothing
/// when the first check trusted every output or did not finish.
pub(super) fn split_into_elements(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    root: RootDesign<'_>,
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
    let mut runs = CheckRuns::of(&first_check);
    let mut root_misfit = root.misfit;
    let mut untrusted = first_check.untrusted_outputs.clone();
    // The outputs the first check trusted, checked once more where their surrogates overshoot
    // the true runs most: those that fail it get elements too.
    if let Some(overshot) = check_overshoots(context, &root.candidates, &untrusted, accumulator)? {
        // Only the trusted outputs' misfits are new evidence: the others are split anyway, and
        // by the first check's misfits.
        for (o, (worst, probed)) in root_misfit.iter_mut().zip(&overshot.misfit).enumerate() {
            if !untrusted.contains(&o) {
                for (w, &m) in worst.iter_mut().zip(probed) {
                    *w = w.max(m);
                }
            }
        }
        let probe = overshot.report;
        runs.absorb(&probe);
        if !probe.complete {
            context.report.check = Some(judge(scene, runs, &root_misfit, accumulator));
            return Ok(());
        }
        untrusted.extend(probe.untrusted_outputs);
        untrusted.sort_unstable();
        untrusted.dedup();
    }
    let mut active = vec![false; n_outputs];
    for &o in &untrusted {
        active[o] = true;
    }
    // The root's runs of the outputs the elements are for, and its grid, for children to nest in.
    let active_outputs: Vec<usize> = (0..n_outputs).filter(|&o| active[o]).collect();
    let root_runs = root.runs.map(|all| {
        let mut kept = ElementRuns::new(active_outputs.clone(), all.n_samples);
        let row = all.n_samples * n_outputs;
        for record in all.values.chunks_exact(row.max(1)) {
            kept.push_record(record, n_outputs);
        }
        kept
    });
    let root_nodes = match root.plan {
        Plan::Surrogate(design) if root_runs.is_some() => {
            Some((0..d).map(|r| design.axis_nodes(r).to_vec()).collect())
        }
        _ => None,
    };
    let root = Element {
        region: ElementBox::whole(d),
        parent: None,
        depth: 0,
        children: Vec::new(),
        split_dims: Vec::new(),
        design_runs: context.report.runs - runs.runs,
        check_runs: runs.runs,
        order,
        points: accumulator.points[..n_records * n_outputs].to_vec(),
        misfit: root_misfit,
        sobol: context.report.sobol.clone(),
        candidates: root.candidates,
        scan_grid: None,
        axis_nodes: root_nodes,
        runs: root_runs,
        reused_runs: 0,
    };
    let mut tree = ElementTree::new(root, active);
    let runs_before = context.report.runs;
    // Runs set aside for refining the extremes of what stays untrusted, sized by the outputs the
    // first check did not trust: those the overshoot check adds share it (the refinement runs
    // what fits in the runs left, whatever was set aside).
    let reserve = refine_reserve(
        d,
        first_check.untrusted_outputs.len(),
        context.options.max_runs,
    );
    let mut rounds = 0;
    let stop = loop {
        let union = tree.union(&|r, o| accumulator.run_hull(r, o));
        let scales = output_scales(scene, &union);
        // Every leaf trusted: in one dimension, the imprecise ones split further while the runs
        // allow.
        let failing = tree.failing_leaves(&scales);
        let precision = (failing.is_empty() && d <= PRECISION_MAX_DIM)
            .then(|| precision_split_cap(context.options.max_runs));
        let to_split = if precision.is_some() {
            tree.leaves_above(&scales, ELEMENT_PRECISION_MISFIT)
        } else {
            failing
        };
        if to_split.is_empty() {
            break "trusted";
        }
        let budget = context
            .options
            .max_runs
            .saturating_sub(context.report.runs + reserve);
        let planned = match planned_round(
            &tree,
            to_split,
            precision,
            &scales,
            order,
            budget,
            context.options.elements.max_elements,
        ) {
            Ok(planned) => planned,
            Err(_) if precision.is_some() => break "trusted",
            Err(reason) => break reason,
        };
        rounds += 1;
        // What the round's designs and checks leave of the budget: a failing scan's refinement.
        let spare = budget.saturating_sub(
            planned
                .iter()
                .flat_map(|split| &split.designs)
                .map(|design| design.runs + design.check_runs)
                .sum(),
        );
        if !run_round(
            context,
            stages,
            &mut tree,
            planned,
            accumulator,
            &mut runs,
            spare,
        )? {
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
        let budget = refine_budget(
            d,
            check.untrusted_outputs.len(),
            context.options.max_runs,
            context.report.runs,
        );
        if let Some(refinement) =
            refine_extremes(context, &targets, budget, accumulator, &mut misfit)?
        {
            accumulator.widen_to_runs();
            check = judge(scene, runs.clone(), &misfit, accumulator);
            context.report.refinement = Some(refinement);
        }
    }
    // Still untrusted: checks aimed at the records up to where the checks pass.
    if stop != "interrupted" && !context.report.partial {
        let candidates: Vec<&CheckCandidates> = tree
            .leaves()
            .into_iter()
            .map(|leaf| &tree.elements[leaf].candidates)
            .collect();
        check = verify_horizon(
            context,
            &candidates,
            first_check.runs,
            &mut runs,
            &mut misfit,
            accumulator,
            check,
        )?;
    }
    let scales = output_scales(scene, &accumulator.points);
    let elements = summarize(&tree, &scales);
    context.report.check = Some(check);
    if rounds > 0 {
        context.report.elements = Some(ElementsReport {
            rounds,
            runs: element_runs,
            stop,
            outputs: untrusted,
            elements,
        });
    }
    Ok(())
}

/// Checks the outputs the first check trusted (all but `untrusted`) where their surrogates'
/// predicted extremes lie furthest past the hull of true runs (`CheckCandidates::
/// select_overshoots`): the first check runs each output's widest records, and a surrogate that
/// overshoots a narrower record (a landing it rounds into a peak) would keep its envelope there
/// far wider than the true response. A prediction less than [`MIN_OVERSHOOT`] of the output's
/// width past the runs is not worth a run. `None` when there was nothing to check or no budget.
fn check_overshoots(
    context: &mut PhaseContext<'_>,
    candidates: &CheckCandidates,
    untrusted: &[usize],
    accumulator: &mut Accumulator,
) -> Result<Option<CheckOutcome>, StudyError> {
    let n_outputs = accumulator.n_outputs;
    let n_records = accumulator.times.len();
    let trusted: Vec<usize> = (0..n_outputs).filter(|o| !untrusted.contains(o)).collect();
    let scales = output_scales(context.scene, &accumulator.points[..n_records * n_outputs]);
    let min_excess: Vec<f64> = scales.iter().map(|s| MIN_OVERSHOOT * s.width).collect();
    let ran = context
        .report
        .check
        .as_ref()
        .map_or(Vec::new(), |c| c.points.clone());
    let t_select = Instant::now();
    let plan = candidates.select_overshoots(
        &trusted,
        &|r, o| accumulator.run_hull(r, o),
        &min_excess,
        &ran,
    );
    context.report.phase_seconds.check_selection += t_select.elapsed().as_secs_f64();
    let room = context.options.max_runs.saturating_sub(context.report.runs);
    if plan.checks.is_empty() || plan.checks.len() > room {
        return Ok(None);
    }
    check(context, &plan, accumulator).map(Some)
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
                reused_runs: element.reused_runs,
                check_runs: element.check_runs,
                order: element.order,
                scan_grid: element.scan_grid.clone(),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An element tree of the whole `d`-dimensional box on the order-4 Gauss grid, with its runs
    /// kept for its children or not.
    fn gauss_root(d: usize, kept: bool) -> ElementTree {
        let gauss = Design::new(Family::Legendre, d, 4, Truncation::Tensor).unwrap();
        let root = Element {
            region: ElementBox::whole(d),
            parent: None,
            depth: 0,
            children: Vec::new(),
            split_dims: Vec::new(),
            design_runs: gauss.n_points(),
            reused_runs: 0,
            check_runs: 0,
            order: 4,
            points: Vec::new(),
            misfit: Vec::new(),
            sobol: None,
            candidates: CheckCandidates::new(d),
            scan_grid: None,
            axis_nodes: Some(vec![gauss.nodes().to_vec(); d]),
            runs: kept.then(|| ElementRuns::new(vec![0], gauss.n_points())),
        };
        ElementTree::new(root, vec![true])
    }

    #[test]
    fn element_designs_fit_the_budget_by_lowering_the_order() {
        let one = |d: usize, budget: usize| {
            let tree = gauss_root(d, false);
            (MIN_ELEMENT_ORDER..=4).rev().find_map(|k| {
                child_designs(&tree, 0, &[ElementBox::whole(d)], k, budget).map(|mut v| v.remove(0))
            })
        };
        // d = 1: the tensor grid of k + 1 points, its check at least 8 runs.
        let design = one(1, 100).unwrap();
        assert_eq!((design.order, design.runs, design.check_runs), (4, 5, 8));
        // d = 4, k = 4: the tensor grid, 625 runs + 63 checks.
        let design = one(4, 688).unwrap();
        assert!(matches!(
            design.plan,
            ElementPlan::Surrogate(Plan::Surrogate(_))
        ));
        assert_eq!((design.order, design.runs, design.check_runs), (4, 625, 63));
        // 687 runs do not fit order 4; order 3 (256 + 26) does.
        let design = one(4, 687).unwrap();
        assert_eq!((design.order, design.runs), (3, 256));
        // Not even order 2 (81 + 9).
        assert!(one(4, 89).is_none());
        // d = 5: the total-degree Leja grid, C(9, 4) = 126 runs + 13 checks.
        let design = one(5, 139).unwrap();
        assert!(matches!(
            design.plan,
            ElementPlan::Surrogate(Plan::Sparse(_))
        ));
        assert_eq!((design.order, design.runs, design.check_runs), (4, 126, 13));
    }

    #[test]
    fn halves_of_a_kept_grid_nest_in_it_and_cost_their_new_runs() {
        let tree = gauss_root(4, true);
        let halves = ElementBox::whole(4).split(&[0]);
        // Each half: 3 of the 5 nodes along the halved dimension are the parent's, so 2 · 5³ new
        // runs, and a check as large as a fresh design's (63).
        let budget = 2 * (250 + 63);
        let designs = child_designs(&tree, 0, &halves, 4, budget).unwrap();
        assert!(child_designs(&tree, 0, &halves, 4, budget - 1).is_none());
        for design in &designs {
            assert_eq!((design.order, design.runs, design.check_runs), (4, 250, 63));
            assert_eq!(design.n_points(), 625);
            assert_eq!(design.points(4).len(), 250 * 4);
        }
        // Without the parent's runs, each half is a fresh grid: 2 · (625 + 63) do not fit.
        assert!(child_designs(&gauss_root(4, false), 0, &halves, 4, budget).is_none());
        let fresh = child_designs(&gauss_root(4, false), 0, &halves, 3, budget).unwrap();
        assert!(fresh.iter().all(|d| d.nested.is_none() && d.runs == 256));
        // At order 3 a half nests too: 4 of the 5 nodes along each other dimension, and along
        // the halved one its 3 and 1 new: 4³ new runs.
        let lower = child_designs(&tree, 0, &halves, 3, usize::MAX).unwrap();
        assert!(lower.iter().all(|d| d.nested.is_some() && d.runs == 64));
    }
}
