//! Nested element designs (docs/method.md §12, "Nested elements"): a child element's tensor grid
//! made of its parent's nodes wherever they fall inside the child, so that the parent's runs at
//! those points are reused, and new nodes only where the child needs them.
//!
//! ```text
//! parent nodes per dimension (its own ξ) ─ map into the child ─▶ the ones within NESTED_NODE_REACH
//!   ⇒ along a dimension the split halved: fill to k + 1 nodes, each new node the one within the
//!     reach farthest (product of distances) from those already there (a Leja sequence), and keep
//!     the set only if it interpolates well (Lebesgue constant ≤ MAX_NESTED_LEBESGUE; else the
//!     child gets a fresh Gauss grid)
//!   ⇒ the tensor grid of the child's nodes; a point whose every coordinate is a parent node is
//!     the parent's run at that point, the others are new runs
//! ```
//!
//! No node lies on a face of the element that is a face of its parent's box: a surrogate whose
//! extreme is on the box's face (every monotone response's is) is checked there by a new run, which
//! means something only where the design has no run (an interpolant is exact at its nodes) — a
//! spring pendulum whose mass spans nine decades oscillates hundreds of times against the light
//! face, and a node on that face hid it from the check. The parent's middle node, on the face its
//! two halves share, is reused by both. Halving a dimension of a five-point Gauss grid keeps three
//! of its nodes in each half, so a child split along one dimension needs 2 · 5³ = 250 new runs
//! instead of 5⁴ = 625, and along two 400.
//!
//! Does not: decide where to split (`elements.rs`) or run anything (`elements_phase.rs`).

use crate::uq::{Design, ElementBox, Truncation};

/// Largest Lebesgue constant of a nested dimension's nodes: the interpolant's error is at most
/// `1 + Λ` times the best polynomial approximation's, and the five Gauss–Legendre nodes a fresh
/// element gets have Λ ≈ 3.3 at k = 4; a filled set above this falls back to a fresh grid.
pub const MAX_NESTED_LEBESGUE: f64 = 4.5;

/// Candidate positions in [-reach, reach] among which a new node is chosen (the Leja rule): a
/// grid of 1/200 of the element.
pub const LEJA_CANDIDATES: usize = 401;

/// Nodes of a nested design lie within this distance of an element's middle (its own coordinates),
/// except on the face it shares with a sibling: a run on its parent's face would make the check
/// there void (module documentation), and 5 % of the half-width between the outermost node and the
/// face is where the check sees what the design does not. (The five Gauss nodes reach 0.906.)
/// Measured over six nested halvings of the five-point grid, the filled sets' Lebesgue constants
/// stay within 2.4–4.0.
pub const NESTED_NODE_REACH: f64 = 0.95;

/// Fewest dimensions of a box whose elements nest. In one dimension a fresh child costs k + 1
/// runs beside its check's 8, so nesting saves two or three runs — and measured on a double
/// pendulum with bar 2's mass over nine decades, nested children were trusted by their checks
/// (largest misfit 2.8 % of the width) while missing a 2001-point scan by 6.6 %, where fresh Gauss
/// children failed their check, split once more and stayed within 1.6 %.
pub const MIN_NESTED_DIM: usize = 2;

/// Most values (runs × records × outputs, 8 bytes each) the elements of one study keep for their
/// children to reuse: 2²⁵ doubles, 256 MiB. Past it a child gets a fresh design.
pub const MAX_KEPT_ELEMENT_VALUES: usize = 1 << 25;

/// Parent coordinates within this distance outside the reach of a child count as inside (a parent
/// node at the reach, up to rounding).
const REACH_TOLERANCE: f64 = 1e-12;

/// Points sampled per unit of [-1, 1] when evaluating a Lebesgue constant.
const LEBESGUE_SAMPLES: usize = 2001;

/// A child's design and, per design point (row-major), the parent's design point it reuses.
#[derive(Clone, Debug)]
pub(super) struct NestedDesign {
    /// The child's design, on its own nodes.
    pub design: Design,
    /// `sources[p]`: the parent's design point whose run is the child's point `p`, or `None` for
    /// a new run.
    pub sources: Vec<Option<usize>>,
    /// Its nodes per dimension (the child's own coordinates).
    pub axis_nodes: Vec<Vec<f64>>,
}

impl NestedDesign {
    /// New runs the child needs.
    pub fn new_runs(&self) -> usize {
        self.sources.iter().filter(|s| s.is_none()).count()
    }
}

/// The design of `child`, a part of `parent`'s box whose design is the tensor grid of
/// `parent_nodes` (per dimension, the parent's own coordinates, as many along each), at order
/// `order` (k + 1 nodes per dimension; the parent's order or lower). `None` when no parent run
/// falls on the child's grid or a dimension's nodes would interpolate badly.
pub(super) fn nested_design(
    parent: &ElementBox,
    parent_nodes: &[Vec<f64>],
    child: &ElementBox,
    order: usize,
) -> Option<NestedDesign> {
    let m = order + 1;
    let d = child.dim();
    if d < MIN_NESTED_DIM {
        return None;
    }
    let parent_m = parent_nodes.first().map_or(0, Vec::len);
    let reach = NESTED_NODE_REACH;
    if parent_nodes.len() != d || parent_nodes.iter().any(|nodes| nodes.len() != parent_m) {
        return None;
    }
    // Per dimension: the child's nodes and, for each, the parent's node index it is.
    let mut axis_nodes = Vec::with_capacity(d);
    let mut parent_index: Vec<Vec<Option<usize>>> = Vec::with_capacity(d);
    for (j, nodes) in parent_nodes.iter().enumerate() {
        let to_child = |xi: f64| {
            (parent.center[j] + parent.half_width[j] * xi - child.center[j]) / child.half_width[j]
        };
        // A face of the child inside its parent's box (the face it shares with a sibling).
        let inner_face = |side: f64| {
            let child_face = child.center[j] + side * child.half_width[j];
            let parent_face = parent.center[j] + side * parent.half_width[j];
            (child_face - parent_face).abs() > REACH_TOLERANCE * parent.half_width[j]
        };
        let inside: Vec<(f64, Option<usize>)> = nodes
            .iter()
            .enumerate()
            .map(|(i, &xi)| (to_child(xi), i))
            .filter_map(|(u, i)| {
                if u.abs() <= reach + REACH_TOLERANCE {
                    Some((u.clamp(-reach, reach), Some(i)))
                } else if u.abs() <= 1.0 + REACH_TOLERANCE && inner_face(u.signum()) {
                    Some((u.signum(), Some(i)))
                } else {
                    None
                }
            })
            .collect();
        let nodes = axis_nodes_from(inside, m, reach)?;
        axis_nodes.push(nodes.iter().map(|&(u, _)| u).collect::<Vec<f64>>());
        parent_index.push(nodes.iter().map(|&(_, i)| i).collect::<Vec<_>>());
    }
    let design = Design::with_axis_nodes(order, Truncation::Tensor, axis_nodes.clone()).ok()?;
    crate::uq::Projector::new(design.clone()).ok()?;
    let n_points = design.n_points();
    let mut sources = Vec::with_capacity(n_points);
    let mut digits = vec![0usize; d];
    for p in 0..n_points {
        let mut rest = p;
        for digit in digits.iter_mut().rev() {
            *digit = rest % m;
            rest /= m;
        }
        let source = digits.iter().enumerate().try_fold(0usize, |flat, (j, &i)| {
            Some(flat * parent_m + parent_index[j][i]?)
        });
        sources.push(source);
    }
    if sources.iter().all(Option::is_none) {
        return None;
    }
    Some(NestedDesign {
        design,
        sources,
        axis_nodes,
    })
}

/// A child's `m` nodes along one dimension (ascending, each with the parent's node index it
/// reuses) from the parent's nodes `inside` the child's reach: the `m` of them that interpolate
/// best when there are more, all of them and new ones by the Leja rule when there are fewer;
/// `None` when the set's Lebesgue constant exceeds [`MAX_NESTED_LEBESGUE`].
fn axis_nodes_from(
    inside: Vec<(f64, Option<usize>)>,
    m: usize,
    reach: f64,
) -> Option<Vec<(f64, Option<usize>)>> {
    let mut nodes = if inside.len() > m {
        best_subset(&inside, m)
    } else {
        let kept: Vec<f64> = inside.iter().map(|&(u, _)| u).collect();
        let mut nodes = inside;
        for u in leja_fill(&kept, m, reach).into_iter().skip(kept.len()) {
            nodes.push((u, None));
        }
        nodes
    };
    nodes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let values: Vec<f64> = nodes.iter().map(|&(u, _)| u).collect();
    let distinct = values.windows(2).all(|w| w[0] < w[1]);
    (distinct && values.len() == m && lebesgue_constant(&values) <= MAX_NESTED_LEBESGUE)
        .then_some(nodes)
}

/// The `m` of `nodes` with the smallest Lebesgue constant (ties: the first in lexicographic order
/// of the chosen indices).
fn best_subset(nodes: &[(f64, Option<usize>)], m: usize) -> Vec<(f64, Option<usize>)> {
    let n = nodes.len();
    let mut chosen: Vec<usize> = (0..m).collect();
    let mut best: Option<(f64, Vec<usize>)> = None;
    loop {
        let mut values: Vec<f64> = chosen.iter().map(|&i| nodes[i].0).collect();
        values.sort_by(f64::total_cmp);
        let lebesgue = lebesgue_constant(&values);
        if best.as_ref().is_none_or(|(l, _)| lebesgue < *l) {
            best = Some((lebesgue, chosen.clone()));
        }
        // The next m-combination of 0..n in lexicographic order.
        let Some(i) = (0..m).rev().find(|&i| chosen[i] < n - m + i) else {
            break;
        };
        chosen[i] += 1;
        for k in i + 1..m {
            chosen[k] = chosen[k - 1] + 1;
        }
    }
    best.map_or_else(Vec::new, |(_, indices)| {
        indices.into_iter().map(|i| nodes[i]).collect()
    })
}

/// `kept` (distinct nodes in [-reach, reach]) followed by new nodes up to `m` in all, each the
/// candidate of [`LEJA_CANDIDATES`] in [-reach, reach] farthest from the nodes before it (largest
/// product of distances; ties: the lowest).
pub(super) fn leja_fill(kept: &[f64], m: usize, reach: f64) -> Vec<f64> {
    let mut nodes = kept.to_vec();
    let step = 2.0 * reach / (LEJA_CANDIDATES - 1) as f64;
    while nodes.len() < m {
        let mut best: Option<(f64, f64)> = None;
        for c in 0..LEJA_CANDIDATES {
            let u = -reach + c as f64 * step;
            let product: f64 = nodes.iter().map(|x| (u - x).abs()).product();
            if best.is_none_or(|(p, _)| product > p) {
                best = Some((product, u));
            }
        }
        match best {
            Some((product, u)) if product > 0.0 => nodes.push(u),
            _ => break,
        }
    }
    nodes
}

/// The Lebesgue constant of interpolation at `nodes`, sampled at [`LEBESGUE_SAMPLES`] points.
pub(super) fn lebesgue_constant(nodes: &[f64]) -> f64 {
    crate::uq::lebesgue_constant(nodes, LEBESGUE_SAMPLES)
}

/// The runs an element keeps for its children: per record, per design point, the values of the
/// outputs the elements are made for.
#[derive(Clone, Debug)]
pub(super) struct ElementRuns {
    /// The outputs kept (indices into the study's outputs), ascending.
    pub outputs: Vec<usize>,
    /// Design points.
    pub n_samples: usize,
    /// `values[(record · n_samples + sample) · outputs.len() + k]`.
    pub values: Vec<f64>,
}

impl ElementRuns {
    /// Empty, for `n_samples` design points and `outputs`.
    pub fn new(outputs: Vec<usize>, n_samples: usize) -> ElementRuns {
        ElementRuns {
            outputs,
            n_samples,
            values: Vec::new(),
        }
    }

    /// Values it holds (for the memory bound [`MAX_KEPT_ELEMENT_VALUES`]).
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Appends one record's row (`n_samples × n_outputs`, row-major, every output).
    pub fn push_record(&mut self, row: &[f64], n_outputs: usize) {
        for run in row.chunks_exact(n_outputs.max(1)) {
            self.values.extend(self.outputs.iter().map(|&o| run[o]));
        }
    }

    /// Appends design point `sample`'s values at `record` to `row` as a whole run of `n_outputs`
    /// values: the kept outputs' values, 0 for the others (which the element does not bound:
    /// `ElementTree::union` takes the root's envelope for them).
    pub fn extend_run(&self, record: usize, sample: usize, n_outputs: usize, row: &mut Vec<f64>) {
        let k = self.outputs.len();
        let start = (record * self.n_samples + sample) * k;
        let first = row.len();
        row.resize(first + n_outputs, 0.0);
        for (&o, &v) in self.outputs.iter().zip(&self.values[start..start + k]) {
            row[first + o] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uq::{Family, Projector};

    #[test]
    fn a_halved_gauss_grid_keeps_three_nodes_per_half_and_fills_two() {
        let parent = ElementBox::whole(2);
        let gauss = Design::new(Family::Legendre, 2, 4, Truncation::Tensor).unwrap();
        let nodes = vec![gauss.nodes().to_vec(); 2];
        let children = parent.split(&[0]);
        let mut reused = Vec::new();
        for child in &children {
            let nested = nested_design(&parent, &nodes, child, 4).unwrap();
            // Along the other dimension the parent's nodes, unchanged.
            assert_eq!(nested.axis_nodes[1], nodes[1]);
            assert_eq!(nested.new_runs(), 2 * 5);
            assert!(lebesgue_constant(&nested.axis_nodes[0]) <= MAX_NESTED_LEBESGUE);
            // No node on the parent's faces; one on the face the halves share.
            let shared = if child.center[0] < 0.0 { 1.0 } else { -1.0 };
            for (j, nodes) in nested.axis_nodes.iter().enumerate() {
                for &u in nodes {
                    assert!(u.abs() <= NESTED_NODE_REACH || (j == 0 && u == shared));
                }
            }
            // A reused point is the parent's point, mapped into the child.
            let parent_points = gauss.points();
            let child_points = nested.design.points();
            for (p, source) in nested.sources.iter().enumerate() {
                if let Some(s) = source {
                    let whole = child.to_whole(&child_points[2 * p..2 * p + 2]);
                    for j in 0..2 {
                        assert!((whole[j] - parent_points[2 * s + j]).abs() < 1e-12);
                    }
                    reused.push(*s);
                }
            }
        }
        // Each half reuses the two columns on its side and the middle column (on the shared
        // face): 15 + 15 reuses of 25 points, the middle 5 twice.
        reused.sort_unstable();
        assert_eq!(reused.len(), 30);
        reused.dedup();
        assert_eq!(reused.len(), 25);
    }

    #[test]
    fn a_nested_design_interpolates_polynomials_of_its_order() {
        let parent = ElementBox::whole(2);
        let gauss = Design::new(Family::Legendre, 2, 4, Truncation::Tensor).unwrap();
        let nodes = vec![gauss.nodes().to_vec(); 2];
        let child = &parent.split(&[0, 1])[3];
        let nested = nested_design(&parent, &nodes, child, 4).unwrap();
        let projector = Projector::new(nested.design.clone()).unwrap();
        let f = |x: &[f64]| 0.3 + x[0].powi(4) - 2.0 * x[0] * x[1].powi(3) + x[1];
        let values: Vec<f64> = nested.design.points().chunks(2).map(f).collect();
        let coefficients = projector.fit(&values, 1).unwrap();
        let mut surrogate = crate::uq::Surrogate::zeros(&nested.design);
        surrogate
            .set_from_matrix(&nested.design, &coefficients, 0)
            .unwrap();
        for x in [[-0.9, 0.2], [0.33, -0.71], [1.0, 1.0]] {
            assert!((surrogate.eval(&x).unwrap() - f(&x)).abs() < 1e-12);
        }
    }

    #[test]
    fn leja_fills_far_from_the_kept_nodes() {
        let filled = leja_fill(&[-1.0, 0.0], 4, 1.0);
        assert_eq!(filled.len(), 4);
        assert_eq!(filled[2], 1.0);
        // Then |u|(1 − u²) is largest at u = ±1/√3; the lower of the tie, within the grid's step.
        assert!(filled[3] < 0.0 && (filled[3] + 1.0 / 3f64.sqrt()).abs() < 0.005);
        // Equispaced nodes: Λ = 2.21 at five nodes (a known value).
        let equispaced = [-1.0, -0.5, 0.0, 0.5, 1.0];
        assert!((lebesgue_constant(&equispaced) - 2.2078).abs() < 1e-3);
    }
}
