//! Elements (docs/method.md §12): the box split into sub-boxes where the a-posteriori check did
//! not trust one surrogate, each with its own design, surrogate, bounds and check, and the study's
//! envelope their union. This file holds the element tree and its decisions — which leaves fail,
//! along which dimensions to split them, which design a child gets, what the union is; running
//! the elements is `elements_phase.rs`.
//!
//! ```text
//! root (the study's design, bounds and check) ─ untrusted outputs O ─▶ leaves failing for O
//!   ⇒ split each along the dimensions its failing outputs' surrogates vary most in (total Sobol'
//!     index at the record of the largest misfit; at most MAX_SPLIT_DIMS) ⇒ children
//!   ⇒ (elements_phase) design, bounds and check per child ⇒ the leaves' union for O
//! ```
//!
//! The union of an output the first check trusted is the root's envelope; of an output it did not
//! trust, the lowest lower and highest upper bound over the leaves, the largest error estimate,
//! and — as every envelope of a study — the hull of every true run the study made. An element is
//! judged against the union's width, the scale the study reports.
//!
//! Does not: run anything; choose where in a dimension to split (always the middle).

use super::check::{CheckCandidates, TRUST_RELATIVE_MISFIT, TRUST_RESOLUTION_FACTOR};
use super::envelope::EnvelopePoint;
use super::nested_design::ElementRuns;
use super::sobol_indices::SobolSeries;
use crate::uq::ElementBox;

/// Default most leaves of an element tree (`--max-elements`).
pub const DEFAULT_MAX_ELEMENTS: usize = 64;

/// Elements of up to this many dimensions get the tensor Gauss grid (scanned), as `auto` gives
/// the whole box; above, the Leja sparse grid of total degree k (the box optimiser), whose runs
/// grow polynomially in d. Measured on the vehicle (d = 4): children on the total-degree-4 grid
/// (70 runs) missed by up to the whole union width, on the order-3 tensor grid (256) by 10–20 %.
pub const ELEMENT_TENSOR_MAX_DIM: usize = super::auto::AUTO_TENSOR_MAX_DIM;

/// Most dimensions one split halves (`2^k` children): a kink surface slanted across two
/// parameters needs both, and a third would cost eight designs per failing element.
pub const MAX_SPLIT_DIMS: usize = 2;

/// A dimension is split with the most important one when its share of the failing outputs'
/// total Sobol' indices is at least this fraction of the largest share.
pub const SPLIT_SHARE: f64 = 0.5;

/// No dimension is halved below this half-width in standard coordinates (ten halvings): past it
/// the element is a sliver that an integrator's step noise, not the parameter, shapes.
pub const MIN_ELEMENT_HALF_WIDTH: f64 = 1.0 / 1024.0;

/// A failing leaf is not split again when neither it nor its parent improved on their parents'
/// worst relative misfit by more than this factor: two generations without progress mean a
/// feature no polynomial on a smaller box resolves (a discontinuity, or a chirp across decades),
/// and the budget goes to leaves that converge.
pub const STALL_RATIO: f64 = 0.9;

/// Lowest order an element's design is given when the budget is short (a quadratic still sees
/// curvature; below it there is no surrogate worth checking).
pub const MIN_ELEMENT_ORDER: usize = 2;

/// Points per dimension of a stalled leaf's scan along the dimensions its ancestors were halved
/// along (where the feature that stalled them lies), the finest the budget affords first: 33
/// points put 32 cells across the leaf, so a jump's two sides are each seen within 1/32 of the
/// leaf, and each count nests in the next finer one.
pub const SCAN_FEATURE_POINTS: [usize; 4] = [33, 17, 9, 5];

/// Once every leaf is trusted, a leaf whose check misfit is above this share of an output's width
/// is split further while the budget allows (and halving is not stalled): the trust test's 5 %
/// says the envelope may be trusted, this says how close to the true range it should come (issue
/// 38's goal for the planted kink: within 1 % of a dense scan).
pub const ELEMENT_PRECISION_MISFIT: f64 = 0.01;

/// A split for precision may cost at most this share of `--max-runs` (its children's designs and
/// checks). (Measured without [`PRECISION_MAX_DIM`], on the vehicle at d = 4: a precision split's
/// children spent the budget and one of them failed its own check — exit 4 where the study
/// without them was trusted and within 1.5 % of a 9⁴ scan.)
pub const PRECISION_SPLIT_SHARE: f64 = 0.05;

/// A trusted output's predicted extreme is checked again when it lies more than this fraction
/// of the output's width past the hull of true runs (`check_overshoots` in `elements_phase.rs`,
/// and every element's own check): below it, the envelope there is at most that much wider than
/// the runs show, and no run is spent on it.
pub const MIN_OVERSHOOT: f64 = 0.01;

/// Splits for precision are made in boxes of at most this many dimensions. In one dimension a
/// child's check covers its interval closely and a split costs two 5-point designs and their
/// checks (measured: the planted kink comes within 0.9 % of a 401-point scan at 144 runs, from
/// 2.2 % at 40; the nine-decade double pendulum within 0.6 %, from 1.6 %). Measured in two, the
/// planted kink with the bar's centre of mass went from 70 runs to 914 for 2.3 % → 0.8 %, and
/// with the runs capped at four times 70, to 3.0 %: the children's own surrogates may overshoot
/// where their parent's did not, so more elements need not mean a closer envelope.
pub const PRECISION_MAX_DIM: usize = 1;

/// Most halvings of a scan's steepest cell in its check: 2⁻³² of a grid cell is below any
/// parameter's meaningful resolution, and a jump (an impact that happens or not) keeps its step
/// at every halving, while a response the grid missed (a fast oscillation squeezed against a face
/// of the box) shows itself on the way down as values outside the grid's hull.
pub const SCAN_BISECTIONS: usize = 32;

/// Points per dimension of a stalled leaf's scan along the dimensions no split chose (the response
/// varies smoothly there): both faces and the middle.
pub const SCAN_OTHER_POINTS: usize = 3;

/// Whether and how far a study splits its box into elements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ElementsOptions {
    /// Split where the first check fails (`--elements`; on by default for `--method auto`).
    pub enabled: bool,
    /// Most leaves (`--max-elements`).
    pub max_elements: usize,
}

impl Default for ElementsOptions {
    /// Off, with [`DEFAULT_MAX_ELEMENTS`].
    fn default() -> Self {
        ElementsOptions {
            enabled: false,
            max_elements: DEFAULT_MAX_ELEMENTS,
        }
    }
}

/// One element of the tree.
#[derive(Clone, Debug)]
pub(super) struct Element {
    /// Its sub-box of the whole box.
    pub region: ElementBox,
    /// Its parent (`None` for the root, the whole box).
    pub parent: Option<usize>,
    /// Splits from the root.
    pub depth: usize,
    /// Its children, once split.
    pub children: Vec<usize>,
    /// The dimensions its split halved.
    pub split_dims: Vec<usize>,
    /// Runs made for its design (the root's: the study's design and nominal run); a nested
    /// child's design also holds `reused_runs` of its parent's.
    pub design_runs: usize,
    /// Its design's points that are its parent's runs (docs/method.md §12, "Nested elements").
    pub reused_runs: usize,
    /// Runs of its check.
    pub check_runs: usize,
    /// Its surrogates' order.
    pub order: usize,
    /// Its envelope points, record-major `records × outputs` (its own bounds, widened by its own
    /// runs), for the outputs the elements are made for ([`ElementTree::active`]); a child's
    /// points of the other outputs are empty ([`EnvelopePoint::EMPTY`]; the root's are the
    /// study's).
    pub points: Vec<EnvelopePoint>,
    /// `misfit[o][r]`: its check's largest `|true − predicted|` for output `o` at record `r`.
    pub misfit: Vec<Vec<f64>>,
    /// Its surrogates' Sobol' indices (`None` where the method has none).
    pub sobol: Option<SobolSeries>,
    /// Where its surrogates put their extremes (whole-box coordinates).
    pub candidates: CheckCandidates,
    /// Points per dimension when it is a scanned leaf (a stalled leaf whose envelope is the hull
    /// of a grid of true runs, checked between them: docs/method.md §12); `None` for a surrogate.
    pub scan_grid: Option<Vec<usize>>,
    /// Its design's 1-D nodes per dimension (its own coordinates) when the design is a tensor grid
    /// a child can nest in; `None` otherwise (a sparse design, a scan).
    pub axis_nodes: Option<Vec<Vec<f64>>>,
    /// Its design's runs, kept for its children to reuse while it is a leaf (`None`: not kept).
    pub runs: Option<ElementRuns>,
}

impl Element {
    /// Output `o`'s largest misfit and the record where it is.
    fn worst_misfit(&self, o: usize) -> (f64, usize) {
        self.misfit[o]
            .iter()
            .copied()
            .enumerate()
            .fold(
                (0.0, 0),
                |(m, at), (r, x)| if x > m { (x, r) } else { (m, at) },
            )
    }
}

/// How one output is judged: the union's largest width and the output's resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct OutputScale {
    /// Largest width of the union over the records, in the output's unit.
    pub width: f64,
    /// The output's resolution (`None`: no floor).
    pub resolution: Option<f64>,
}

impl OutputScale {
    /// Whether a misfit this large is above `relative` of the width and above the resolution
    /// (with `relative` = [`TRUST_RELATIVE_MISFIT`]: whether it fails the trust test,
    /// [`super::trust_verdict`]'s rule; below the resolution no split can tell better).
    pub fn exceeds(&self, misfit: f64, relative: f64) -> bool {
        misfit > relative * self.width
            && self
                .resolution
                .is_none_or(|floor| misfit > TRUST_RESOLUTION_FACTOR * floor)
    }
}

/// A leaf that fails its check for some output.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct FailingLeaf {
    /// The element.
    pub element: usize,
    /// Its worst misfit over the failing outputs, relative to that output's union width.
    pub worst: f64,
    /// The outputs it fails for.
    pub outputs: Vec<usize>,
}

/// The element tree of a study (element 0 is the root, the whole box).
#[derive(Clone, Debug)]
pub(super) struct ElementTree {
    /// Every element, parents before children.
    pub elements: Vec<Element>,
    /// Per output: whether elements are made for it (the first check did not trust it).
    pub active: Vec<bool>,
    /// Outputs per record.
    pub n_outputs: usize,
}

impl ElementTree {
    /// The tree of one element, `root`, made for the outputs marked in `active`.
    pub fn new(root: Element, active: Vec<bool>) -> ElementTree {
        let n_outputs = active.len();
        ElementTree {
            elements: vec![root],
            active,
            n_outputs,
        }
    }

    /// The leaves, in the order they were made.
    pub fn leaves(&self) -> Vec<usize> {
        (0..self.elements.len())
            .filter(|&e| self.elements[e].children.is_empty())
            .collect()
    }

    /// Record times every element holds.
    pub fn n_records(&self) -> usize {
        self.elements[0].points.len() / self.n_outputs.max(1)
    }

    /// The union (module documentation), record-major: the root's points for inactive outputs,
    /// the leaves' for active ones, each widened to `hull(record, output)` — the hull of every true
    /// run (`(+∞, −∞)` where there was none).
    pub fn union(&self, hull: &dyn Fn(usize, usize) -> (f64, f64)) -> Vec<EnvelopePoint> {
        let n_outputs = self.n_outputs;
        let leaves = self.leaves();
        let mut union = self.elements[0].points.clone();
        for (k, point) in union.iter_mut().enumerate() {
            let (record, o) = (k / n_outputs, k % n_outputs);
            if self.active[o] {
                let mut merged = EnvelopePoint::EMPTY;
                for &leaf in &leaves {
                    let p = self.elements[leaf].points[k];
                    merged.lower = merged.lower.min(p.lower);
                    merged.upper = merged.upper.max(p.upper);
                    merged.error = match (merged.error, p.error) {
                        (Some(a), Some(b)) => Some(a.max(b)),
                        (a, b) => a.or(b),
                    };
                    let (lo, hi) = p.outer.unwrap_or((p.lower, p.upper));
                    merged.outer = Some(match merged.outer {
                        Some((l, h)) => (l.min(lo), h.max(hi)),
                        None => (lo, hi),
                    });
                }
                if self.elements[0].points[k].outer.is_none()
                    && leaves
                        .iter()
                        .all(|&l| self.elements[l].points[k].outer.is_none())
                {
                    merged.outer = None;
                }
                *point = merged;
            }
            let (lowest, highest) = hull(record, o);
            point.lower = point.lower.min(lowest);
            point.upper = point.upper.max(highest);
        }
        union
    }

    /// `misfit[o][r]` of the union: the leaves' largest for active outputs, the root's for the
    /// others.
    pub fn union_misfit(&self) -> Vec<Vec<f64>> {
        let leaves = self.leaves();
        (0..self.n_outputs)
            .map(|o| {
                if !self.active[o] {
                    return self.elements[0].misfit[o].clone();
                }
                let mut worst = vec![0.0_f64; self.n_records()];
                for &leaf in &leaves {
                    for (w, &m) in worst.iter_mut().zip(&self.elements[leaf].misfit[o]) {
                        *w = w.max(m);
                    }
                }
                worst
            })
            .collect()
    }

    /// The leaves that fail for an active output against `scales`, worst first (ties: the older
    /// element first).
    pub fn failing_leaves(&self, scales: &[OutputScale]) -> Vec<FailingLeaf> {
        self.leaves_above(scales, TRUST_RELATIVE_MISFIT)
    }

    /// The leaves whose misfit for an active output is above `relative` of its width in
    /// `scales` (and its resolution), worst first (ties: the older element first).
    pub fn leaves_above(&self, scales: &[OutputScale], relative: f64) -> Vec<FailingLeaf> {
        let mut failing: Vec<FailingLeaf> = self
            .leaves()
            .into_iter()
            .filter_map(|leaf| {
                let element = &self.elements[leaf];
                let mut outputs = Vec::new();
                let mut worst = 0.0_f64;
                for (o, scale) in scales.iter().enumerate() {
                    if !self.active[o] {
                        continue;
                    }
                    let (misfit, _) = element.worst_misfit(o);
                    if scale.exceeds(misfit, relative) {
                        outputs.push(o);
                        let relative = if scale.width > 0.0 {
                            misfit / scale.width
                        } else {
                            f64::INFINITY
                        };
                        worst = worst.max(relative);
                    }
                }
                (!outputs.is_empty()).then_some(FailingLeaf {
                    element: leaf,
                    worst,
                    outputs,
                })
            })
            .collect();
        failing.sort_by(|a, b| b.worst.total_cmp(&a.worst).then(a.element.cmp(&b.element)));
        failing
    }

    /// Element `e`'s worst misfit over the active outputs, each relative to its union width.
    pub fn worst_relative_misfit(&self, e: usize, scales: &[OutputScale]) -> f64 {
        let element = &self.elements[e];
        (0..self.n_outputs)
            .filter(|&o| self.active[o] && scales[o].width > 0.0)
            .map(|o| element.worst_misfit(o).0 / scales[o].width)
            .fold(0.0, f64::max)
    }

    /// Whether `leaf` stalled ([`STALL_RATIO`]): it and its parent each keep at least that share
    /// of their parents' worst relative misfit.
    pub fn stalled(&self, leaf: usize, scales: &[OutputScale]) -> bool {
        let Some(parent) = self.elements[leaf].parent else {
            return false;
        };
        let Some(grandparent) = self.elements[parent].parent else {
            return false;
        };
        let worst = |e| self.worst_relative_misfit(e, scales);
        worst(leaf) >= STALL_RATIO * worst(parent)
            && worst(parent) >= STALL_RATIO * worst(grandparent)
    }

    /// The dimensions `leaf`'s ancestors were halved along, ascending (where the features that
    /// made them fail lie).
    pub fn feature_dims(&self, leaf: usize) -> Vec<usize> {
        let mut dims = Vec::new();
        let mut at = self.elements[leaf].parent;
        while let Some(e) = at {
            dims.extend_from_slice(&self.elements[e].split_dims);
            at = self.elements[e].parent;
        }
        dims.sort_unstable();
        dims.dedup();
        dims
    }

    /// The dimensions to halve `leaf` along (at most `most`, each still wider than
    /// [`MIN_ELEMENT_HALF_WIDTH`]), ascending: for each of its failing `outputs`, at the record of
    /// its largest misfit, the total Sobol' indices of the leaf's surrogate, weighted by the
    /// misfit relative to the output's union width; the dimensions within [`SPLIT_SHARE`] of the
    /// largest weight. Without indices (or all zero): the widest dimension.
    pub fn split_dims(
        &self,
        leaf: usize,
        outputs: &[usize],
        scales: &[OutputScale],
        most: usize,
    ) -> Vec<usize> {
        let element = &self.elements[leaf];
        let d = element.region.dim();
        let splittable =
            |j: usize| element.region.half_width[j] > MIN_ELEMENT_HALF_WIDTH * (1.0 + 1e-12);
        let mut weight = vec![0.0_f64; d];
        if let Some(sobol) = &element.sobol {
            for &o in outputs {
                let (misfit, record) = element.worst_misfit(o);
                if record >= sobol.records() {
                    continue;
                }
                let scale = if scales[o].width > 0.0 {
                    misfit / scales[o].width
                } else {
                    1.0
                };
                for (w, &t) in weight.iter_mut().zip(sobol.total(record, o)) {
                    if t.is_finite() {
                        *w += scale * t.max(0.0);
                    }
                }
            }
        }
        let mut order: Vec<usize> = (0..d).filter(|&j| splittable(j)).collect();
        order.sort_by(|&a, &b| weight[b].total_cmp(&weight[a]).then(a.cmp(&b)));
        let largest = order.first().map_or(0.0, |&j| weight[j]);
        let mut dims: Vec<usize> = if largest > 0.0 {
            order
                .into_iter()
                .filter(|&j| weight[j] >= SPLIT_SHARE * largest)
                .take(most.max(1))
                .collect()
        } else {
            // No indices to go by: the widest splittable dimension (the first of equals).
            (0..d)
                .filter(|&j| splittable(j))
                .fold(None, |best: Option<usize>, j| match best {
                    Some(b) if element.region.half_width[b] >= element.region.half_width[j] => best,
                    _ => Some(j),
                })
                .into_iter()
                .collect()
        };
        dims.sort_unstable();
        dims
    }

    /// Adds `children` (made from `parent` by halving `dims`) and returns their indices.
    pub fn split(&mut self, parent: usize, dims: Vec<usize>, children: Vec<Element>) -> Vec<usize> {
        let first = self.elements.len();
        self.elements.extend(children);
        let indices: Vec<usize> = (first..self.elements.len()).collect();
        let element = &mut self.elements[parent];
        element.children = indices.clone();
        element.split_dims = dims;
        // Its children have taken what they reuse.
        element.runs = None;
        indices
    }

    /// Values the elements keep for their children
    /// ([`super::nested_design::MAX_KEPT_ELEMENT_VALUES`] bounds them).
    pub fn kept_values(&self) -> usize {
        self.elements
            .iter()
            .filter_map(|e| e.runs.as_ref())
            .map(ElementRuns::len)
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn element(region: ElementBox, points: Vec<EnvelopePoint>, misfit: Vec<Vec<f64>>) -> Element {
        let region_dim = region.dim();
        Element {
            region,
            parent: None,
            depth: 0,
            children: Vec::new(),
            split_dims: Vec::new(),
            design_runs: 1,
            check_runs: 1,
            order: 4,
            scan_grid: None,
            axis_nodes: None,
            runs: None,
            reused_runs: 0,
            points,
            misfit,
            sobol: None,
            candidates: CheckCandidates::new(region_dim),
        }
    }

    fn point(lower: f64, upper: f64) -> EnvelopePoint {
        EnvelopePoint {
            lower,
            upper,
            error: Some(0.0),
            outer: None,
        }
    }

    /// Two outputs over one record: output 0 trusted at the root, output 1 not.
    fn tree() -> ElementTree {
        let root = element(
            ElementBox::whole(2),
            vec![point(0.0, 1.0), point(-5.0, 5.0)],
            vec![vec![0.01], vec![3.0]],
        );
        ElementTree::new(root, vec![false, true])
    }

    #[test]
    fn the_union_takes_the_leaves_for_active_outputs_and_every_true_run() {
        let mut tree = tree();
        let halves = ElementBox::whole(2).split(&[1]);
        let children = vec![
            element(
                halves[0].clone(),
                vec![point(0.2, 0.8), point(-1.0, 2.0)],
                vec![vec![0.0], vec![0.1]],
            ),
            element(
                halves[1].clone(),
                vec![point(0.3, 0.7), point(0.5, 3.0)],
                vec![vec![0.0], vec![0.2]],
            ),
        ];
        tree.split(0, vec![1], children);
        assert_eq!(tree.leaves(), vec![1, 2]);
        // A true run at 3.5 for output 1 (made by some element's check) widens the union.
        let union = tree.union(&|_, o| if o == 1 { (3.5, 3.5) } else { (0.1, 0.9) });
        assert_eq!((union[0].lower, union[0].upper), (0.0, 1.0), "the root's");
        assert_eq!((union[1].lower, union[1].upper), (-1.0, 3.5));
        assert_eq!(tree.union_misfit(), vec![vec![0.01], vec![0.2]]);
    }

    #[test]
    fn failing_leaves_are_judged_against_the_union_width_and_the_resolution() {
        let tree = tree();
        let scales = [
            OutputScale {
                width: 1.0,
                resolution: None,
            },
            OutputScale {
                width: 10.0,
                resolution: None,
            },
        ];
        let failing = tree.failing_leaves(&scales);
        assert_eq!(failing.len(), 1);
        assert_eq!(failing[0].outputs, vec![1], "output 0 is not active");
        assert!((failing[0].worst - 0.3).abs() < 1e-15);
        // Within the resolution: not a failure.
        let resolved = [
            scales[0],
            OutputScale {
                width: 10.0,
                resolution: Some(5.0),
            },
        ];
        assert!(tree.failing_leaves(&resolved).is_empty());
    }

    #[test]
    fn splits_follow_the_total_indices_and_fall_back_to_the_widest_side() {
        let mut tree = tree();
        // Without indices: the widest dimension (the first of equals).
        let scales = [
            OutputScale {
                width: 1.0,
                resolution: None,
            },
            OutputScale {
                width: 10.0,
                resolution: None,
            },
        ];
        assert_eq!(tree.split_dims(0, &[1], &scales, 2), vec![0]);
        tree.elements[0].region.half_width[0] = 0.5;
        assert_eq!(tree.split_dims(0, &[1], &scales, 2), vec![1]);
        // A dimension at the smallest half-width is never split.
        tree.elements[0].region.half_width = vec![MIN_ELEMENT_HALF_WIDTH, 1.0];
        assert_eq!(tree.split_dims(0, &[1], &scales, 2), vec![1]);
    }
}
