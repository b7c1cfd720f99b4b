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
//! A stalled leaf becomes one scanned child (its own box): a grid of true runs whose hull is its
//! envelope, checked by the excess of runs half a grid step from its extreme points and of a
//! bisection of each output's steepest cell (`scanned_leaf.rs`). A child's grid nests in its
//! parent's where the parent kept its runs (`nested_design.rs`).
//!
//! Every run any element makes widens the hull of true runs, and the union contains that hull,
//! so no bound is narrower than a true run. A round's designs are one stage, so `plan`/`run`/
//! `merge` replay the same decisions (docs/distributed.md §7); the checks run where the study
//! runs, like the first one. Does not: decide where to split (`elements.rs`).

use super::accumulator::Accumulator;
use super::bounds::{Bounder, EnvelopePoint};
use super::check::{automatic_check_runs, CheckCandidates, CheckPlan, Side};
use super::check_phase::{check, judge, output_scales, CheckOutcome, CheckRuns};
use super::design_phase::{known_ranges, DesignBounding, ElementScope};
use super::elements::{
    Element, ElementTree, OutputScale, ELEMENT_TENSOR_MAX_DIM, MAX_SPLIT_DIMS, MIN_ELEMENT_ORDER,
    SCAN_BISECTIONS, SCAN_FEATURE_POINTS, SCAN_OTHER_POINTS,
};
use super::error::StudyError;
use super::method::Method;
use super::nested_design::{nested_design, ElementRuns, NestedDesign, MAX_KEPT_ELEMENT_VALUES};
use super::phase::PhaseContext;
use super::plan::{grid_point, Plan};
use super::refine_phase::{refine_budget, refine_extremes, refine_reserve, RefineTarget};
use super::report::{ElementSummary, ElementsReport};
use super::scanned_leaf::{judge_scan_run, ScanGrid};
use super::sobol_indices::SobolSeries;
use super::sparse::SparseDesign;
use super::stages::StageCursor;
use crate::uq::{Design, ElementBox, Family, Truncation};
use std::sync::Arc;
use std::time::Instant;

/// A trusted output's predicted extreme is checked again when it lies more than this fraction
/// of the output's width past the hull of true runs (`check_overshoots`): below it, the envelope
/// there is at most that much wider than the runs show, and no run is spent on it.
pub const MIN_OVERSHOOT: f64 = 0.01;

/// Where an element's runs go: a surrogate's design, or a scanned leaf's grid.
enum ElementPlan {
    /// The design of the element's surrogates.
    Surrogate(Plan),
    /// A grid of this many points per dimension, faces included (a stalled leaf's scan).
    Scan(Vec<usize>),
}

/// An element's design: its points in its own coordinates and the runs it and its check cost.
struct ElementDesign {
    plan: ElementPlan,
    /// Its surrogates' order (0 for a scan).
    order: usize,
    /// New runs (a nested design's points that are not its parent's).
    runs: usize,
    check_runs: usize,
    /// Which of its points are its parent's runs (`None`: every point is a new run).
    nested: Option<NestedDesign>,
}

impl ElementDesign {
    /// The points of its new runs, in the element's own coordinates, row-major.
    fn points(&self, dim: usize) -> Vec<f64> {
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
    fn axis_nodes(&self, dim: usize) -> Option<Vec<Vec<f64>>> {
        match (&self.plan, &self.nested) {
            (_, Some(nested)) => Some(nested.axis_nodes.clone()),
            (ElementPlan::Surrogate(Plan::Surrogate(design)), None) => {
                Some((0..dim).map(|r| design.axis_nodes(r).to_vec()).collect())
            }
            _ => None,
        }
    }

    /// Design points in all (reused and new): the values each record's fit reads.
    fn n_points(&self) -> usize {
        self.nested
            .as_ref()
            .map_or(self.runs, |nested| nested.sources.len())
    }
}

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
/// grid up to [`ELEMENT_TENSOR_MAX_DIM`], the Leja sparse grid above.
fn fresh_design(dim: usize, order: usize) -> Option<ElementDesign> {
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
                None => fresh_design(dim, k),
            }
        })
        .collect::<Option<_>>()?;
    let cost = designs.iter().try_fold(0usize, |sum, x| {
        sum.checked_add(x.runs)?.checked_add(x.check_runs)
    })?;
    (cost <= budget).then_some(designs)
}

/// One failing leaf's split, as planned (or its scan: no dimension halved, one child with the
/// leaf's box and a grid).
struct PlannedSplit {
    parent: usize,
    dims: Vec<usize>,
    children: Vec<ElementBox>,
    /// One per child.
    designs: Vec<ElementDesign>,
}

/// The splits of one round: the failing leaves, worst first, each halved along its split
/// dimensions (or the first of them alone) while the leaves stay within `max_elements` and the
/// children's designs and checks within `budget` runs — a stalled leaf scanned instead (once: a
/// scan that fails its check is final); the reason when none fits.
fn planned_round(
    tree: &ElementTree,
    scales: &[OutputScale],
    order: usize,
    budget: usize,
    max_elements: usize,
) -> Result<Vec<PlannedSplit>, &'static str> {
    let mut leaves = tree.leaves().len();
    let mut left = budget;
    let mut planned = Vec::new();
    let mut reason = "resolution";
    for leaf in tree.failing_leaves(scales) {
        let element = &tree.elements[leaf.element];
        if element.scan_grid.is_some() || tree.stalled(leaf.element, scales) {
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
                match child_designs(tree, leaf.element, &children, k, left) {
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
    let mut runs = CheckRuns {
        runs: first_check.runs,
        unique_candidates: first_check.unique_candidates,
        points: first_check.points.clone(),
        checked: first_check.checked.clone(),
        complete: first_check.complete,
    };
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
        runs.runs += probe.runs;
        runs.points.extend_from_slice(&probe.points);
        runs.checked.extend_from_slice(&probe.checked);
        if !probe.complete {
            runs.complete = false;
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
            for (c, (((bounding, range), child), grid)) in boundings
                .iter_mut()
                .zip(&samples)
                .zip(element_points.iter_mut())
                .zip(scan_grids.iter_mut())
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
                bounding.absorb(block.first, block.count, &values, &|_| false, child)?;
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

    // A scan's check goes on into its steepest cells, bisecting each down to where a jump is.
    let mut bisection_runs = vec![0usize; children.len()];
    for c in 0..children.len() {
        let (Some(grid), Some(grid_hull)) = (&scan_grids[c], &grid_hulls[c]) else {
            continue;
        };
        let region = children[c].1;
        let mut bisections = grid.bisections(grid_hull);
        for _ in 0..SCAN_BISECTIONS {
            bisections.retain(|b| !b.resolved(grid_hull, n_outputs));
            if bisections.is_empty() {
                break;
            }
            let points: Vec<f64> = bisections
                .iter()
                .flat_map(|b| region.to_whole(&b.middle()))
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
                                grid_hull,
                                &active,
                                record,
                                values,
                                &mut misfit[c],
                                &mut checked,
                            );
                            if record == bisection.record {
                                middle_values[run] = accumulator
                                    .reported(bisection.output, values[bisection.output]);
                            }
                            element_points[c].widen(record, values);
                            accumulator.widen_runs(record, values);
                        }
                    }
                    Ok(())
                })?;
            if !complete {
                return Ok(false);
            }
            runs.runs += bisections.len();
            bisection_runs[c] += bisections.len();
            runs.unique_candidates += bisections.len();
            runs.points.extend_from_slice(&points);
            runs.checked.extend(checked);
            for (bisection, &value) in bisections.iter_mut().zip(&middle_values) {
                bisection.halve(value);
            }
            // A failed run leaves no value to halve by: that bisection ends.
            bisections.retain(|b| b.from_value.is_finite() && b.to_value.is_finite());
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
