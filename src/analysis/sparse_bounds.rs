//! The sparse design's envelopes, block by block (docs/high-dimension.md §7): every record's
//! surrogates fitted at once, then each output's record times bounded in order, each side of the
//! inner bound searched from its own starts — the vertex of the linear part on that side, the
//! design points with that side's best values (the best from itself, the other from where its
//! descent ended at the previous record time when it was a start there too), and where the
//! previous record time's extreme was (extremes move continuously in time, so that start is
//! usually one Newton step from the answer).
//!
//! ```text
//! block: records ⇒ (parallel over records) fit: coefficients per record
//!        ⇒ (parallel over output sides) per output and side, record after record:
//!            starts (vertex, best design points, previous extreme) ⇒ that side's inner bound
//!            ⇒ the previous extreme for the next record
//!        ⇒ (parallel over outputs) per record: outer bound ⇒ Sobol' indices
//! ```
//!
//! Each side of an output runs its records in order on one thread and carries its extreme
//! across blocks, so the results depend neither on the thread count nor on the block size. The
//! two sides of an output share nothing, so they are separate tasks: 2 × outputs of them balance
//! over the threads better than the outputs alone (9 outputs on 2 threads left one thread 5 of
//! them).
//!
//! Does not: fit or bound tensor designs, `taylor` or the runs-only methods (`bounds.rs`).

use super::bound_clock::{BoundClock, BoundPhase};
use super::bounded_block::{BoundedBlock, Extremes};
use super::envelope::EnvelopePoint;
use super::sparse::SparseDesign;
use crate::uq::{BoxBounds, BoxOptimizer, SobolIndices, SparseSurrogate, UqError};
use rayon::prelude::*;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How many of the best design points start each side's search (the lowest values the minimum,
/// the highest the maximum), besides that side's vertex and the previous record time's extreme:
/// the runs themselves are the best evidence of where the extremes are. Two, not one: one moved
/// the d = 72 all-values ur5 study's envelopes by no more than 9.3e-6 of a width and saved a third
/// of the search, but on `benches/sparse_bounding.rs`'s problem it left four outputs' inner bounds
/// up to 1.8e-3 of their width narrower than the seven shared starts did, two only one (issue 40).
pub const DESIGN_STARTS_PER_SIDE: usize = 2;

/// How many of a side's [`DESIGN_STARTS_PER_SIDE`] design points — the best ones — descend from
/// the design point itself at every record time; the others, when they were among the side's
/// design starts at the previous record time too, descend from where their descent ended there
/// (their basin, followed in time, as the previous extreme is: usually one or two Newton steps
/// instead of four to six from the interior of the box, and often that point is the previous
/// extreme itself, a start the search then skips). The best point still descends afresh, so a
/// basin that opens between two record times is found as before. Measured on the README's
/// scaling rows (d = 8 … 64, 1 s) and the d = 72 all-values ur5 study against every design
/// point afresh (issue 40): envelopes within 9.6e-5 of a width, the inner bound's thread time
/// at d = 72 about a fifth lower. Following every design point's basin (0 here) was within
/// 6.6e-4 at d = 32 … 72 and halved that time, but at d = 16 it missed a basin for two record
/// times by 3.4e-3 of `frame.tool0.x`'s width.
pub const FRESH_DESIGN_STARTS_PER_SIDE: usize = 1;

/// What one side (minimum or maximum) of one output carries from record time to record time.
#[derive(Debug, Default, Clone)]
struct SideChain {
    /// Where the last record's extreme was attained (none before the first record).
    previous: Option<Vec<f64>>,
    /// The design points that started the last record's descents.
    followed: Vec<usize>,
    /// Where each of their descents ended, `followed.len() × d`.
    followed_ends: Vec<f64>,
}

/// One side (minimum or maximum) of one output's inner bound at every record of a block.
#[derive(Default)]
struct SideSeries {
    /// The extreme value found per record.
    values: Vec<f64>,
    /// Where it is attained, `records × d`.
    args: Vec<f64>,
}

/// Bounds a sparse design's records (module documentation); cheap to share across threads.
#[derive(Debug)]
pub(super) struct SparseBounds {
    design: Arc<SparseDesign>,
    /// The outer bound is the envelope (`legendre-ia`).
    outer_only: bool,
    /// Search the inner bound: the envelope of the scanning method, and where the check looks.
    inner: bool,
    /// Per output side (`2·output` the minimum, `2·output + 1` the maximum), what the last
    /// record bounded left for the next: where its extreme was attained and where its design
    /// starts' descents ended (empty before the first block).
    chains: Mutex<Vec<SideChain>>,
}

/// One output's bounds at every record of a block.
struct OutputSeries {
    points: Vec<EnvelopePoint>,
    extremes: Vec<Option<Extremes>>,
    /// `records × d`.
    main_indices: Vec<f64>,
    /// `records × d`.
    total_indices: Vec<f64>,
    variances: Vec<f64>,
}

/// Per-thread buffers.
struct Workspace {
    surrogate: SparseSurrogate,
    optimizer: BoxOptimizer,
    bounds: BoxBounds,
    indices: SobolIndices,
    /// Start points of one side, row-major.
    starts: Vec<f64>,
    /// Where one side's extreme is attained.
    arg: Vec<f64>,
    /// The design points with the lowest and the highest values.
    lowest: Vec<usize>,
    highest: Vec<usize>,
}

impl SparseBounds {
    /// Bounds for `design`: `outer_only` reports the outer bound (`legendre-ia`), `inner`
    /// searches the inner one as well (always, unless `outer_only` and no check follows).
    pub(super) fn new(design: Arc<SparseDesign>, outer_only: bool, inner: bool) -> SparseBounds {
        SparseBounds {
            design,
            outer_only,
            inner: inner || !outer_only,
            chains: Mutex::new(Vec::new()),
        }
    }

    /// The envelopes of `records` record times after the ones bounded before (in order), from
    /// `record_values[r]` (row-major `samples × outputs`); the design's runs are not yet in them.
    pub(super) fn bound(
        &self,
        record_values: &[Vec<f64>],
        n_outputs: usize,
        clock: &BoundClock,
        threads: &rayon::ThreadPool,
    ) -> Result<BoundedBlock, UqError> {
        let design = &*self.design;
        let n_terms = design.set().len();
        let coefficients = threads.install(|| {
            record_values
                .par_iter()
                .map(|values| {
                    let lap = Instant::now();
                    let mut coefficients = vec![0.0; n_terms * n_outputs];
                    design
                        .fit()
                        .fit_into(values, n_outputs, &mut coefficients)?;
                    clock.lap(BoundPhase::Fit, lap);
                    Ok(coefficients)
                })
                .collect::<Result<Vec<Vec<f64>>, UqError>>()
        })?;
        let mut chains = self
            .chains
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if chains.len() != 2 * n_outputs {
            *chains = vec![SideChain::default(); 2 * n_outputs];
        }
        let chains: &mut [SideChain] = &mut chains;
        let sides = if self.inner {
            threads.install(|| {
                chains
                    .par_iter_mut()
                    .enumerate()
                    .map_init(
                        || self.workspace(),
                        |ws, (side, chain)| {
                            self.bound_side(
                                side / 2,
                                side % 2 == 1,
                                record_values,
                                &coefficients,
                                n_outputs,
                                chain,
                                ws,
                                clock,
                            )
                        },
                    )
                    .collect::<Result<Vec<SideSeries>, UqError>>()
            })?
        } else {
            Vec::new()
        };
        let series = threads.install(|| {
            (0..n_outputs)
                .into_par_iter()
                .map_init(
                    || self.workspace(),
                    |ws, o| {
                        let inner = sides.get(2 * o).zip(sides.get(2 * o + 1));
                        self.enclose_output(o, &coefficients, n_outputs, inner, ws, clock)
                    },
                )
                .collect::<Result<Vec<OutputSeries>, UqError>>()
        })?;
        let d = design.set().dim();
        let records = record_values.len();
        let mut out = BoundedBlock {
            points: Vec::with_capacity(records * n_outputs),
            extremes: Vec::with_capacity(records * n_outputs),
            ..BoundedBlock::default()
        };
        for r in 0..records {
            for output in &series {
                out.points.push(output.points[r]);
                out.extremes.push(output.extremes[r].clone());
                out.main_indices
                    .extend_from_slice(&output.main_indices[r * d..(r + 1) * d]);
                out.total_indices
                    .extend_from_slice(&output.total_indices[r * d..(r + 1) * d]);
                out.variances.push(output.variances[r]);
            }
        }
        Ok(out)
    }

    fn workspace(&self) -> Workspace {
        let set = self.design.set();
        Workspace {
            surrogate: SparseSurrogate::zeros(Arc::clone(set)),
            optimizer: BoxOptimizer::new(),
            bounds: BoxBounds::default(),
            indices: SobolIndices::zeros(set.dim()),
            starts: Vec::new(),
            arg: Vec::new(),
            lowest: Vec::new(),
            highest: Vec::new(),
        }
    }

    /// One side of output `o` (`maximum`: the upper one) at every record, in order, starting
    /// from what `chain` carries and leaving there what the last record leaves for the next.
    #[allow(clippy::too_many_arguments)]
    fn bound_side(
        &self,
        o: usize,
        maximum: bool,
        record_values: &[Vec<f64>],
        coefficients: &[Vec<f64>],
        n_outputs: usize,
        chain: &mut SideChain,
        ws: &mut Workspace,
        clock: &BoundClock,
    ) -> Result<SideSeries, UqError> {
        let design = &*self.design;
        let d = design.set().dim();
        let n_points = design.n_points();
        let records = record_values.len();
        let mut series = SideSeries {
            values: Vec::with_capacity(records),
            args: Vec::with_capacity(records * d),
        };
        for (values, coefficients) in record_values.iter().zip(coefficients) {
            let lap = Instant::now();
            ws.surrogate.set_from_fit(coefficients, n_outputs, o)?;
            let value = |p: usize| values[p * n_outputs + o];
            extreme_design_points(
                n_points,
                value,
                DESIGN_STARTS_PER_SIDE,
                &mut ws.lowest,
                &mut ws.highest,
            );
            let point = |p: usize| &design.points()[p * d..(p + 1) * d];
            // In increasing order of value: the best of the minimum first, of the maximum last.
            let chosen = if maximum { &ws.highest } else { &ws.lowest };
            let fresh = |rank: usize| {
                if maximum {
                    rank + FRESH_DESIGN_STARTS_PER_SIDE >= chosen.len()
                } else {
                    rank < FRESH_DESIGN_STARTS_PER_SIDE
                }
            };
            ws.starts.clear();
            for (rank, &p) in chosen.iter().enumerate() {
                match chain.followed.iter().position(|&q| q == p) {
                    Some(i) if !fresh(rank) => ws
                        .starts
                        .extend_from_slice(&chain.followed_ends[i * d..(i + 1) * d]),
                    _ => ws.starts.extend_from_slice(point(p)),
                }
            }
            if let Some(previous) = chain.previous.as_ref() {
                ws.starts.extend_from_slice(previous);
            }
            let (extreme, _) = ws.optimizer.extreme_from_starts_into(
                &ws.surrogate,
                maximum,
                &ws.starts,
                &mut ws.arg,
            )?;
            series.values.push(extreme);
            series.args.extend_from_slice(&ws.arg);
            match &mut chain.previous {
                Some(previous) => previous.copy_from_slice(&ws.arg),
                None => chain.previous = Some(ws.arg.clone()),
            }
            chain.followed.clear();
            chain.followed.extend_from_slice(chosen);
            chain.followed_ends.clear();
            for rank in 0..chosen.len() {
                let end = ws
                    .optimizer
                    .given_start_end(rank)
                    .ok_or(UqError::WrongLength {
                        what: "sparse bounds: the descents of a side's design starts",
                        expected: chosen.len(),
                        got: rank,
                    })?;
                chain.followed_ends.extend_from_slice(end);
            }
            clock.lap(BoundPhase::Inner, lap);
        }
        Ok(series)
    }

    /// Output `o` at every record: the outer bound (widened to the inner one, `inner` = the
    /// minimum's and the maximum's series when searched) and the Sobol' indices.
    fn enclose_output(
        &self,
        o: usize,
        coefficients: &[Vec<f64>],
        n_outputs: usize,
        inner: Option<(&SideSeries, &SideSeries)>,
        ws: &mut Workspace,
        clock: &BoundClock,
    ) -> Result<OutputSeries, UqError> {
        let d = self.design.set().dim();
        let records = coefficients.len();
        let mut series = OutputSeries {
            points: Vec::with_capacity(records),
            extremes: Vec::with_capacity(records),
            main_indices: Vec::with_capacity(records * d),
            total_indices: Vec::with_capacity(records * d),
            variances: Vec::with_capacity(records),
        };
        for (r, coefficients) in coefficients.iter().enumerate() {
            let mut lap = Instant::now();
            ws.surrogate.set_from_fit(coefficients, n_outputs, o)?;
            lap = clock.lap(BoundPhase::Fit, lap);
            let mut extremes = None;
            if let Some((lower, upper)) = inner {
                let b = &mut ws.bounds;
                b.lower = lower.values[r];
                b.upper = upper.values[r];
                b.argmin.clear();
                b.argmin.extend_from_slice(&lower.args[r * d..(r + 1) * d]);
                b.argmax.clear();
                b.argmax.extend_from_slice(&upper.args[r * d..(r + 1) * d]);
                extremes = Some(Extremes {
                    argmin: b.argmin.clone(),
                    argmax: b.argmax.clone(),
                    at_min: b.lower,
                    at_max: b.upper,
                });
            }
            let error = Some(ws.surrogate.top_order_magnitude());
            let point = if self.outer_only {
                let (lower, upper) = ws.optimizer.outer_bound(&ws.surrogate);
                EnvelopePoint {
                    lower,
                    upper,
                    error,
                    outer: None,
                }
            } else {
                ws.optimizer.enclose(&ws.surrogate, &mut ws.bounds);
                let b = &ws.bounds;
                EnvelopePoint {
                    lower: b.lower,
                    upper: b.upper,
                    error,
                    outer: Some((b.outer_lower, b.outer_upper)),
                }
            };
            lap = clock.lap(BoundPhase::Outer, lap);
            series.points.push(point);
            series.extremes.push(extremes);
            ws.surrogate.sobol_indices_into(&mut ws.indices);
            series.main_indices.extend_from_slice(&ws.indices.main);
            series.total_indices.extend_from_slice(&ws.indices.total);
            series.variances.push(ws.indices.variance);
            clock.lap(BoundPhase::Sobol, lap);
        }
        Ok(series)
    }
}

/// The `k` design points of lowest value into `lowest` and the `k` of highest into `highest`,
/// both in increasing order of (value, index) — the first `k` and the last `k` of the points
/// sorted that way — without sorting all `n`.
fn extreme_design_points(
    n: usize,
    value: impl Fn(usize) -> f64,
    k: usize,
    lowest: &mut Vec<usize>,
    highest: &mut Vec<usize>,
) {
    let before = |a: usize, b: usize| value(a).total_cmp(&value(b)).then(a.cmp(&b)).is_lt();
    lowest.clear();
    highest.clear();
    let k = k.min(n);
    if k == 0 {
        return;
    }
    for p in 0..n {
        if lowest.len() < k || before(p, lowest[k - 1]) {
            let at = lowest.partition_point(|&q| before(q, p));
            lowest.insert(at, p);
            lowest.truncate(k);
        }
        if highest.len() < k || before(highest[0], p) {
            let at = highest.partition_point(|&q| before(q, p));
            highest.insert(at, p);
            if highest.len() > k {
                highest.remove(0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    #[test]
    fn extreme_design_points_are_the_ends_of_the_sorted_order() {
        let mut rng = SplitMix64::new(40);
        let (mut lowest, mut highest) = (Vec::new(), Vec::new());
        for n in [0, 1, 2, 3, 5, 50] {
            for k in [0, 1, 2, 3] {
                // Few distinct values, so that ties are ordered by index.
                let values: Vec<f64> = (0..n).map(|_| rng.uniform(0.0, 4.0).floor()).collect();
                let mut order: Vec<usize> = (0..n).collect();
                order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
                extreme_design_points(n, |p| values[p], k, &mut lowest, &mut highest);
                let take = k.min(n);
                assert_eq!(lowest, order[..take], "n = {n}, k = {k}");
                assert_eq!(highest, order[n - take..], "n = {n}, k = {k}");
            }
        }
    }
}
