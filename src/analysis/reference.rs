//! References for large d, where a scan of the true model is out of reach (docs/method.md §9): the
//! hull of true-model runs at the sign vertices of central-difference gradients, improved by a greedy
//! search that flips one coordinate at a time.
//!
//! ```text
//! gradients: the nominal run and ±h e_j (2d + 1 runs) ⇒ per output and record the sign vector of
//!            ∂y/∂ξ ⇒ the vertices sign(∇y) (maximum) and −sign(∇y) (minimum), deduplicated
//! vertices:  true runs at a budgeted selection of them (widest times first, round-robin over outputs)
//! flips:     per output and side, at the output's widest time: from the best run so far, run the d
//!            vertices one flip away, move to the best improvement, repeat while it improves
//! ```
//!
//! Every run made is a true response in the box, so the reference is an *inner* bound: ribbon's
//! envelopes should contain it (up to their own error). It is not exact: an extreme inside the box
//! (a stationary point) or at a vertex the greedy search does not reach is missed — which is why
//! `compare` also offers Monte Carlo, and why no method may assume extremes lie on vertices.

use super::check::CheckCandidates;
use super::envelope::{EnvelopePoint, Side};
use super::error::StudyError;
use super::phase::{PhaseBlock, PhaseContext};
use super::plan::TAYLOR_STEP;
use super::report::{Progress, StudyReport};
use super::schedule::RecordSchedule;
use super::study::Study;
use crate::uq::{FlipSearch, FlipTarget, SearchSide};
use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Most vertex runs of the second phase (the deduplicated sign vertices are usually far fewer).
pub const MAX_VERTEX_RUNS: usize = 4000;

/// Most rounds of the greedy one-flip search per output and side.
pub const MAX_FLIP_ROUNDS: usize = 6;

/// Times per output at which the greedy search runs (the widest, well separated).
pub const SEARCH_TIMES_PER_OUTPUT: usize = 3;

/// Least separation of those times, as a fraction of the horizon.
pub const SEARCH_TIME_SEPARATION: f64 = 0.1;

/// Options of the vertex reference.
#[derive(Clone, Copy, Debug)]
pub struct VertexReferenceOptions {
    /// Most runs at sign vertices.
    pub max_vertex_runs: usize,
    /// Most greedy rounds.
    pub max_flip_rounds: usize,
}

impl Default for VertexReferenceOptions {
    fn default() -> Self {
        VertexReferenceOptions {
            max_vertex_runs: MAX_VERTEX_RUNS,
            max_flip_rounds: MAX_FLIP_ROUNDS,
        }
    }
}

/// The hull of every run, and per (record, output, side) which run attains it.
struct Hull {
    n_outputs: usize,
    points: Vec<EnvelopePoint>,
    /// Record-major `records × outputs × 2` (lower, upper): the point (ξ) of the attaining run.
    attained_by: Vec<u32>,
    /// Every point run so far (row-major `runs × d`).
    run_points: Vec<f64>,
}

impl Hull {
    fn add(&mut self, record: usize, values: &[f64], run_point: u32) {
        for (o, &value) in values.iter().enumerate() {
            let k = record * self.n_outputs + o;
            let point = &mut self.points[k];
            if value < point.lower {
                point.lower = value;
                self.attained_by[2 * k] = run_point;
            }
            if value > point.upper {
                point.upper = value;
                self.attained_by[2 * k + 1] = run_point;
            }
        }
    }
}

impl Study<'_> {
    /// Computes the vertex reference (see the module documentation). `progress` is called after
    /// each block of each phase.
    pub fn vertex_reference(
        &self,
        options: VertexReferenceOptions,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
    ) -> Result<StudyReport, StudyError> {
        let started = Instant::now();
        let d = self.space.len();
        if d == 0 {
            return Err(StudyError::BadOptions(
                "the sidecar declares no [parameters]: there is nothing to bound".to_string(),
            ));
        }
        let threads = self.thread_pool()?;
        let scene = self.scene;
        let n_outputs = scene.outputs.len();
        let n_records = RecordSchedule::of(scene).len();
        let mut report = self.empty_report(&threads);
        let mut hull = Hull {
            n_outputs,
            points: vec![EnvelopePoint::EMPTY; n_records * n_outputs],
            attained_by: vec![0; 2 * n_records * n_outputs],
            run_points: Vec::new(),
        };
        let mut times = Vec::with_capacity(n_records);
        let mut nominal = Vec::with_capacity(n_records * n_outputs);
        let mut context = self.phase_context(&threads, interrupt, started, &mut report, progress);
        let policy = context.exclusion_policy("reference run");

        // 1. Central-difference gradients at the centre; their sign vertices.
        let mut stencil = Vec::with_capacity(2 * d * d);
        for j in 0..d {
            for sign in [1.0, -1.0] {
                let mut point = vec![0.0; d];
                point[j] = sign * TAYLOR_STEP;
                stencil.extend_from_slice(&point);
            }
        }
        // The centre is a regular run (index 2d); the nominal run is named.
        stencil.extend(std::iter::repeat_n(0.0, d));
        let first_run = register_points(&mut hull, &stencil, d);
        let nominal_xi = self.space.nominal_xi();
        let nominal_run = register_points(&mut hull, &nominal_xi, d);
        let mut vertices = CheckCandidates::new(d);
        let mut gradient = vec![0.0; d];
        let mut vertex = vec![0.0; d];
        let complete = context.run_phase(
            "gradients",
            &stencil,
            Some(&nominal_xi),
            policy,
            &mut |block: &PhaseBlock, _| {
                let lockstep = block.lockstep;
                let nominal_index = lockstep.nominal_index().unwrap_or(2 * d + 1);
                for r in 0..block.count {
                    let record = block.first + r;
                    times.push(RecordSchedule::of(scene).time(record));
                    nominal.extend_from_slice(block.record(nominal_index, r));
                    for i in 0..=2 * d {
                        hull.add(record, block.record(i, r), first_run + i as u32);
                    }
                    hull.add(record, block.record(nominal_index, r), nominal_run);
                    for o in 0..n_outputs {
                        let mut slope_sum = 0.0;
                        for (j, g) in gradient.iter_mut().enumerate() {
                            *g = (block.record(2 * j, r)[o] - block.record(2 * j + 1, r)[o])
                                / (2.0 * TAYLOR_STEP);
                            slope_sum += g.abs();
                        }
                        if !(slope_sum > 0.0 && slope_sum.is_finite()) {
                            continue;
                        }
                        for (side, sign) in [(Side::Upper, 1.0), (Side::Lower, -1.0)] {
                            for (v, g) in vertex.iter_mut().zip(&gradient) {
                                *v = if sign * g >= 0.0 { 1.0 } else { -1.0 };
                            }
                            vertices.add(record, o, side, &vertex, 0.0, 2.0 * slope_sum);
                        }
                    }
                }
                Ok(())
            },
        )?;

        // 2. True runs at the sign vertices.
        if complete {
            let plan = vertices.select(options.max_vertex_runs);
            let first = register_points(&mut hull, &plan.points, d);
            let policy = context.exclusion_policy("vertex run");
            context.run_phase(
                "vertices",
                &plan.points,
                None,
                policy,
                &mut |block: &PhaseBlock, _| {
                    for r in 0..block.count {
                        for i in 0..block.lockstep.len() {
                            if !block.lockstep.failed(i) {
                                hull.add(block.first + r, block.record(i, r), first + i as u32);
                            }
                        }
                    }
                    Ok(())
                },
            )?;
            context.report.runs += plan.points.len() / d;
        }

        // 3. Greedy one-flip search per output and side, at the output's widest time.
        if !context.report.partial {
            greedy_flips(&mut context, &mut hull, options.max_flip_rounds)?;
        }

        let n_done = times.len();
        let envelope = &mut report.envelope;
        envelope.times = times;
        envelope.lower = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.upper = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.nominal = vec![Vec::with_capacity(n_done); n_outputs];
        for r in 0..n_done {
            for o in 0..n_outputs {
                // The runs' values as reported (a contact force clamped at 0; the clamp is
                // monotone, so the hull's clamp is the clamped values' hull).
                let kind = &scene.outputs[o].kind;
                let point = hull.points[r * n_outputs + o];
                envelope.lower[o].push(kind.reported(point.lower));
                envelope.upper[o].push(kind.reported(point.upper));
                envelope.nominal[o].push(kind.reported(nominal[r * n_outputs + o]));
            }
        }
        report.runs += 2 * d + 2;
        Ok(report)
    }
}

/// Step 3 of the module documentation: per output and side, from the best run so far at the
/// output's widest times, the d vertices one flip away, repeated while one improves (at most
/// `max_rounds` rounds). The search is [`FlipSearch`] without its combined step
/// ([`FlipSearch::single_flips_only`]); the points that several searches share run once.
fn greedy_flips(
    context: &mut PhaseContext<'_>,
    hull: &mut Hull,
    max_rounds: usize,
) -> Result<(), StudyError> {
    let d = context.space.len();
    let n_outputs = hull.n_outputs;
    let n_records = hull.points.len() / n_outputs.max(1);
    // Per search (its label): the record and output it looks at.
    let mut searched_at: Vec<(usize, usize)> = Vec::new();
    let mut targets: Vec<FlipTarget> = Vec::new();
    for o in 0..n_outputs {
        let width = |r: usize| {
            let p = hull.points[r * n_outputs + o];
            p.upper - p.lower
        };
        // The widest times, at least SEARCH_TIME_SEPARATION of the horizon apart.
        let mut order: Vec<usize> = (0..n_records)
            .filter(|&r| width(r).is_finite() && width(r) > 0.0)
            .collect();
        order.sort_by(|&a, &b| width(b).total_cmp(&width(a)).then(a.cmp(&b)));
        let separation = ((SEARCH_TIME_SEPARATION * n_records as f64).ceil() as usize).max(1);
        let mut records: Vec<usize> = Vec::new();
        for r in order {
            if records.len() == SEARCH_TIMES_PER_OUTPUT {
                break;
            }
            if records.iter().all(|&q| q.abs_diff(r) >= separation) {
                records.push(r);
            }
        }
        for record in records {
            for upper in [false, true] {
                let k = record * n_outputs + o;
                let run = hull.attained_by[2 * k + usize::from(upper)] as usize;
                let p = hull.points[k];
                targets.push(FlipTarget {
                    label: searched_at.len(),
                    side: if upper {
                        SearchSide::Max
                    } else {
                        SearchSide::Min
                    },
                    start: hull.run_points[run * d..(run + 1) * d].to_vec(),
                    value: if upper { p.upper } else { p.lower },
                });
                searched_at.push((record, o));
            }
        }
    }
    let mut search = FlipSearch::new(d, targets).single_flips_only();
    for _round in 0..max_rounds {
        let probes = search.next_probes(usize::MAX);
        if probes.is_empty() {
            break;
        }
        // The probes' points, deduplicated, in the order of the searches (a round serves every
        // active search; the search only rotates where its round starts).
        let mut in_search_order: Vec<usize> = (0..probes.len()).collect();
        in_search_order.sort_by_key(|&p| probes[p].target);
        let mut index: HashMap<Vec<u64>, usize> = HashMap::new();
        let mut points: Vec<f64> = Vec::new();
        let mut probes_of_point: Vec<Vec<usize>> = Vec::new();
        for p in in_search_order {
            let point = &probes[p].point;
            // `+ 0.0` makes −0 and +0 one key.
            let key: Vec<u64> = point.iter().map(|x| (x + 0.0).to_bits()).collect();
            let next = probes_of_point.len();
            let slot = *index.entry(key).or_insert(next);
            if slot == next {
                points.extend_from_slice(point);
                probes_of_point.push(Vec::new());
            }
            probes_of_point[slot].push(p);
        }
        let first = register_points(hull, &points, d);
        // Each probe's values (NaN: its run failed). A point shared by searches at different
        // records gives every one of them its values at the latest of those records: a quirk this
        // reference has always had, kept so that its numbers do not move (reading each search's
        // own record instead is a change of results, left to a decision of its own).
        let mut values = vec![f64::NAN; probes.len()];
        let policy = context.exclusion_policy("flip run");
        let complete = context.run_phase(
            "flips",
            &points,
            None,
            policy,
            &mut |block: &PhaseBlock, _| {
                for r in 0..block.count {
                    let record = block.first + r;
                    // One run per deduplicated point, in order.
                    for (i, sharing) in probes_of_point.iter().enumerate() {
                        if block.lockstep.failed(i) {
                            continue;
                        }
                        let run_values = block.record(i, r);
                        hull.add(record, run_values, first + i as u32);
                        let searched_here = sharing
                            .iter()
                            .any(|&p| searched_at[probes[p].label].0 == record);
                        if searched_here {
                            for &p in sharing {
                                values[p] = run_values[searched_at[probes[p].label].1];
                            }
                        }
                    }
                }
                Ok(())
            },
        )?;
        context.report.runs += probes_of_point.len();
        if !complete {
            return Ok(());
        }
        search.absorb(&values);
    }
    Ok(())
}

/// Appends `points` to the hull's run list and returns the index of the first.
fn register_points(hull: &mut Hull, points: &[f64], d: usize) -> u32 {
    let first = hull.run_points.len() / d;
    hull.run_points.extend_from_slice(points);
    first as u32
}
