//! The summary JSON of a study, built from its report ([`Summary::of_study`]): the parameters,
//! the envelopes with the hull of true runs, the sensitivities ranked, the Sobol' indices, and the
//! statistics (runs, timings, the check, `auto`'s choice, the adaptive rounds, the inner-outer gap,
//! the chaos estimate, contacts). What the summary is and how it is written is `summary.rs`.
//!
//! Does not: decide anything about the study (every number comes from its report), or print.

use super::summary::{EnvelopeSeries, ParameterSummary, SensitivitySummary, SobolSummary, Summary};
use crate::analysis::{
    CheckReport, ElementsReport, PhaseSeconds, RefinedExtreme, RefinementReport, Side, StudyReport,
    ADAPTIVE_TOLERANCE, CHAOS_AMPLIFICATION, TRUST_RELATIVE_MISFIT, TRUST_RESOLUTION_FACTOR,
};
use crate::scene::LimitExcursion;
use crate::uncertainty::ParameterSpace;

impl ParameterSummary {
    /// Every dimension of `space`, in index order.
    pub fn of_space(space: &ParameterSpace) -> Vec<ParameterSummary> {
        space
            .dimensions()
            .iter()
            .map(|d| ParameterSummary {
                name: d.name.clone(),
                lower: d.lower,
                upper: d.upper,
                nominal: d.nominal,
                source: d.source.clone(),
                unit: d.unit.to_string(),
            })
            .collect()
    }
}

impl Summary {
    /// The summary of a study of `robot` over the box `space`: what `report` holds, with the
    /// method's `order` (`None` where it has none), the joints past unenforced limits and the
    /// wall time.
    pub fn of_study(
        robot: &str,
        order: Option<usize>,
        space: &ParameterSpace,
        report: &StudyReport,
        limit_excursions: Vec<LimitExcursion>,
        wall_seconds: f64,
    ) -> Summary {
        let e = &report.envelope;
        let mut summary = Summary {
        robot: robot.to_string(),
        method: report.method.name().to_string(),
        order,
        design: Some(report.design.to_string()),
        bound_kind: report.method.bound_kind().to_string(),
        sensitivities: SensitivitySummary::of_study(space, report),
        parameters: ParameterSummary::of_space(space),
        samples: report.runs,
        excluded_samples: report
            .excluded
            .iter()
            .map(|f| serde_json::json!({"index": f.index, "xi": f.xi, "values": f.values, "time": f.time_s, "error": f.message}))
            .collect(),
        retried_samples: report
            .retried
            .iter()
            .map(|retry| {
                let f = &retry.fixed_step_failure;
                serde_json::json!({
                    "phase": retry.phase, "run": retry.run, "index": f.index, "xi": f.xi,
                    "values": f.values, "time": f.time_s, "error": f.message,
                    "adaptive_from_time": e.times.get(f.record),
                })
            })
            .collect(),
        wall_seconds,
        outputs: e
            .outputs
            .iter()
            .enumerate()
            .map(|(o, output)| EnvelopeSeries {
                name: output.name.clone(),
                unit: output.unit.to_string(),
                time: e.times.clone(),
                lower: e.lower[o].clone(),
                upper: e.upper[o].clone(),
                nominal: e.nominal[o].clone(),
                error_estimate: e.error.as_ref().map(|errors| errors[o].clone()),
                outer_lower: e.outer.as_ref().map(|(lower, _)| lower[o].clone()),
                outer_upper: e.outer.as_ref().map(|(_, upper)| upper[o].clone()),
                runs_lower: runs_hull_series(&e.runs_lower, o),
                runs_upper: runs_hull_series(&e.runs_upper, o),
            })
            .collect(),
        stats: serde_json::json!({
            "partial": report.partial,
            "steps": report.steps,
            "newton_iterations": report.newton_iterations,
            "simulate_seconds": report.simulate_seconds,
            "bound_seconds": report.bound_seconds,
            "phase_seconds": phase_seconds_json(&report.phase_seconds, report.beside_simulation_seconds),
            "threads": report.threads,
            "block_records": report.block_records,
            "peak_memory_bytes": peak_memory(),
            "check": report.check.as_ref().map_or_else(
                || report.check_skipped.map(|skipped| serde_json::json!({
                    "runs": 0,
                    "skipped": skipped.reason(),
                })),
                |c| Some(check_json(report, c, space.len())),
            ),
            "auto": report.auto.as_ref().map(|a| serde_json::json!({
                "requested": "auto",
                "design": report.design,
                "reason": a.reason,
                "screening_runs": a.screening_runs,
                "design_runs": a.design_runs,
            })),
            "adaptive": report.adaptive.as_ref().map(|a| serde_json::json!({
                "rounds": a.rounds,
                "stages": a.stages,
                "runs": a.runs,
                "budget": a.budget,
                "max_degree": a.max_degree,
                "interactions": a.interactions,
                "largest_remaining_indicator": a.largest_remaining_indicator,
                "tolerance": ADAPTIVE_TOLERANCE,
                "stop": a.stop,
            })),
            "condition_number": report.condition_number,
            "inner_outer_gap": gap_json(report),
            "lyapunov": report.lyapunov.map(|l| serde_json::json!({
                "exponent_per_s": l.exponent_per_s,
                "amplification": l.amplification,
                "horizon_s": l.horizon_s,
                "chaotic": l.is_chaotic(),
                "chaos_amplification": CHAOS_AMPLIFICATION,
            })),
        }),
        sobol_indices: report
            .sobol
            .as_ref()
            .map(|series| SobolSummary::from_study(series, e, space)),
        limit_excursions,
    };
        // Only when the scene declares contacts: a summary without them keeps its keys.
        if let (Some(contacts), Some(stats)) = (&report.contacts, summary.stats.as_object_mut()) {
            stats.insert("contacts".to_string(), serde_json::json!(contacts));
        }
        // Only when the box was split: a study its first check trusts keeps its keys.
        if let (Some(elements), Some(stats)) = (&report.elements, summary.stats.as_object_mut()) {
            stats.insert(
                "elements".to_string(),
                elements_json(elements, space, &report.envelope),
            );
        }
        // Only when the extremes were refined: a trusted study keeps its keys.
        if let (Some(refinement), Some(stats)) = (&report.refinement, summary.stats.as_object_mut())
        {
            stats.insert(
                "refinement".to_string(),
                refinement_json(refinement, &report.envelope),
            );
        }
        summary
    }
}

/// The refinement of the extremes on the true model (docs/method.md §12) for the summary: its
/// runs per stage and, per extreme, where it started, where the best true value was found and
/// the envelope's bound there before.
fn refinement_json(
    refinement: &RefinementReport,
    envelope: &crate::analysis::Envelope,
) -> serde_json::Value {
    let extreme = |x: &RefinedExtreme| {
        serde_json::json!({
            "output": envelope.outputs[x.output].name,
            "time_s": envelope.times.get(x.record).copied(),
            "side": match x.side { Side::Lower => "lower", Side::Upper => "upper" },
            "value": x.value,
            "envelope_before": x.envelope,
            "start_xi": x.start_xi,
            "best_xi": x.best_xi,
        })
    };
    serde_json::json!({
        "runs": refinement.runs,
        "batches": refinement.batches,
        "gradient_runs": refinement.gradient_runs,
        "vertex_runs": refinement.vertex_runs,
        "flip_runs": refinement.flip_runs,
        "search_runs": refinement.search_runs,
        "extremes": refinement.extremes.iter().map(extreme).collect::<Vec<_>>(),
        "flips": refinement.flips.iter().map(extreme).collect::<Vec<_>>(),
    })
}

/// The per-phase seconds of a study ([`PhaseSeconds`]: the worker phases summed over threads),
/// and `bound_beside_simulation`: the wall seconds of `stats.bound_seconds` during which the
/// simulation of the next block ran on the same threads.
fn phase_seconds_json(p: &PhaseSeconds, beside_simulation_seconds: f64) -> serde_json::Value {
    serde_json::json!({
        "design_choice": p.design_choice,
        "fit": p.fit,
        "inner_bound": p.inner_bound,
        "outer_bound": p.outer_bound,
        "sobol_indices": p.sobol_indices,
        "check_selection": p.check_selection,
        "summary": p.summary,
        "bound_beside_simulation": beside_simulation_seconds,
    })
}

impl Summary {
    /// Sets `stats.phase_seconds.summary`: the seconds building this summary took (the front end
    /// measures them around [`Summary::of_study`]).
    pub fn set_summary_seconds(&mut self, seconds: f64) {
        if let Some(phases) = self.stats.get_mut("phase_seconds") {
            phases["summary"] = serde_json::json!(seconds);
        }
    }
}

/// The elements of a split box (docs/method.md §12) for the summary: counts, why it stopped, which
/// dimensions were split how often, and every element with its corners (standard coordinates and
/// parameter values), design, check and, for leaves, the outputs its check still fails for.
pub fn elements_json(
    elements: &ElementsReport,
    space: &ParameterSpace,
    envelope: &crate::analysis::Envelope,
) -> serde_json::Value {
    let dimensions = space.dimensions();
    let names = |indices: &[usize]| -> Vec<String> {
        indices
            .iter()
            .map(|&o| envelope.outputs[o].name.clone())
            .collect()
    };
    // From the nearer end, so that a corner at ±1 is the interval's end exactly.
    let value = |j: usize, xi: f64| {
        let (dimension, radius) = (&dimensions[j], dimensions[j].radius());
        if xi <= 0.0 {
            dimension.lower + (xi + 1.0) * radius
        } else {
            dimension.upper - (1.0 - xi) * radius
        }
    };
    let splits: serde_json::Map<String, serde_json::Value> = elements
        .splits_per_dimension(dimensions.len())
        .into_iter()
        .enumerate()
        .filter(|&(_, count)| count > 0)
        .map(|(j, count)| (dimensions[j].name.clone(), serde_json::json!(count)))
        .collect();
    serde_json::json!({
        "rounds": elements.rounds,
        "runs": elements.runs,
        "stop": elements.stop,
        "leaves": elements.leaves(),
        "depth": elements.depth(),
        "untrusted_leaves": elements.untrusted_leaves(),
        "outputs": names(&elements.outputs),
        "splits": splits,
        "elements": elements.elements.iter().map(|e| {
            let mut element = serde_json::json!({
            "parent": e.parent,
            "depth": e.depth,
            "leaf": e.leaf,
            "xi_lower": e.lower_xi,
            "xi_upper": e.upper_xi,
            "lower": e.lower_xi.iter().enumerate().map(|(j, &x)| value(j, x)).collect::<Vec<f64>>(),
            "upper": e.upper_xi.iter().enumerate().map(|(j, &x)| value(j, x)).collect::<Vec<f64>>(),
            "split": e.split_dims.iter().map(|&j| dimensions[j].name.clone()).collect::<Vec<String>>(),
            "design_runs": e.design_runs,
            "reused_runs": e.reused_runs,
            "check_runs": e.check_runs,
            "order": e.order,
            "untrusted_outputs": names(&e.untrusted_outputs),
            });
            if let (Some(grid), Some(fields)) = (&e.scan_grid, element.as_object_mut()) {
                fields.insert("scan_grid".to_string(), serde_json::json!(grid));
            }
            element
        }).collect::<Vec<_>>(),
    })
}

impl SensitivitySummary {
    /// Per dimension, how much it moves the outputs, from what the study measured (issue 11 §2):
    /// - `relative_slope`: the screening's largest secant slope `|y(e_j) − y(−e_j)|/2` (∂y/∂ξ
    ///   across the half-width) over outputs and times, relative to the output's largest envelope
    ///   width;
    /// - `importance`: the screening's share of an output's one-at-a-time spread;
    /// - `total_index`: the largest total Sobol' index of the sparse surrogates, with where.
    ///
    /// Sorted by the screening's rank where there was one, else by total index; `None` when the
    /// study measured neither (tensor designs).
    pub fn of_study(
        space: &ParameterSpace,
        report: &StudyReport,
    ) -> Option<Vec<SensitivitySummary>> {
        if report.screening.is_none() && report.total_index_max.is_none() {
            return None;
        }
        let e = &report.envelope;
        let widths: Vec<f64> = (0..e.outputs.len())
            .map(|o| {
                e.upper[o]
                    .iter()
                    .zip(&e.lower[o])
                    .map(|(u, l)| u - l)
                    .fold(0.0, f64::max)
            })
            .collect();
        let mut rows: Vec<SensitivitySummary> = space
            .dimensions()
            .iter()
            .enumerate()
            .map(|(j, dimension)| {
                let screened = report.screening.as_ref().map(|s| {
                    let verdict = &s.dimensions()[j];
                    let (slope, output) = (0..widths.len())
                        .filter(|&o| widths[o] > 0.0)
                        .map(|o| (s.max_slope(j, o) / widths[o], o))
                        .fold((0.0, 0), |best, x| if x.0 > best.0 { x } else { best });
                    (slope, output, verdict.importance)
                });
                let total = report.total_index_max.as_ref().map(|t| t[j]);
                SensitivitySummary {
                    name: dimension.name.clone(),
                    rank: 0,
                    relative_slope: screened.map(|s| s.0),
                    slope_output: screened.map(|s| e.outputs[s.1].name.clone()),
                    importance: screened.map(|s| s.2),
                    total_index: total.map(|t| t.0),
                    total_index_output: total.map(|t| e.outputs[t.1].name.clone()),
                    total_index_time: total.and_then(|t| e.times.get(t.2).copied()),
                }
            })
            .collect();
        let mut order: Vec<usize> = match &report.ranking {
            Some(ranking) => ranking.clone(),
            None => (0..rows.len()).collect(),
        };
        if report.ranking.is_none() {
            order.sort_by(|&a, &b| {
                rows[b]
                    .total_index
                    .unwrap_or(0.0)
                    .total_cmp(&rows[a].total_index.unwrap_or(0.0))
                    .then(a.cmp(&b))
            });
        }
        for (rank, &j) in order.iter().enumerate() {
            rows[j].rank = rank + 1;
        }
        rows.sort_by_key(|r| r.rank);
        Some(rows)
    }
}

/// Per output, the largest gap between the sparse surrogate's outer and inner bounds relative to
/// the envelope's width (what the inner search might have missed on the surrogate).
fn gap_json(report: &StudyReport) -> Option<serde_json::Value> {
    let e = &report.envelope;
    let (outer_lower, outer_upper) = e.outer.as_ref()?;
    let rows: Vec<serde_json::Value> = e
        .outputs
        .iter()
        .enumerate()
        .map(|(o, output)| {
            let width = e.upper[o]
                .iter()
                .zip(&e.lower[o])
                .map(|(u, l)| u - l)
                .fold(0.0, f64::max);
            let gap = (0..e.times.len())
                .map(|k| (e.lower[o][k] - outer_lower[o][k]).max(outer_upper[o][k] - e.upper[o][k]))
                .fold(0.0, f64::max);
            serde_json::json!({
                "name": output.name,
                "max_gap": gap,
                "relative_gap": if width > 0.0 { gap / width } else { 0.0 },
            })
        })
        .collect();
    Some(serde_json::Value::Array(rows))
}

/// The check's statistics for the summary: runs, candidates, and per output its misfit.
fn check_json(report: &StudyReport, check: &CheckReport, dim: usize) -> serde_json::Value {
    let outputs = &report.envelope.outputs;
    let e_times = &report.envelope.times;
    let mut json = serde_json::json!({
        "runs": check.runs,
        "unique_candidates": check.unique_candidates,
        "complete": check.complete,
        "trusted": check.untrusted_outputs.is_empty(),
        "first_miss_time_s": check.first_miss_record.map(|r| e_times[r]),
        "checks_before_first_miss": check.checks_before_first_miss,
        "passes_until_time_s": check.passes_until_record.map(|r| e_times[r]),
        "untrusted_outputs": check.untrusted_outputs.iter().map(|&o| outputs[o].name.clone()).collect::<Vec<_>>(),
        "trust_relative_misfit": TRUST_RELATIVE_MISFIT,
        "trust_resolution_factor": TRUST_RESOLUTION_FACTOR,
        "below_resolution_outputs": check.below_resolution_outputs.iter().map(|&o| outputs[o].name.clone()).collect::<Vec<_>>(),
        "points_xi": check.points.chunks(dim.max(1)).collect::<Vec<_>>(),
        "outputs": outputs.iter().enumerate().map(|(o, output)| serde_json::json!({
            "name": output.name,
            "max_misfit": check.max_misfit[o],
            "relative_misfit": check.relative_misfit[o],
            "resolution": check.resolution[o],
        })).collect::<Vec<_>>(),
    });
    // Only where one ran: the summaries of studies without one keep every byte.
    if let Some(horizon) = &check.horizon {
        json["horizon"] = serde_json::json!({
            "rounds": horizon.rounds,
            "runs": horizon.runs,
            "verified_until_time_s": horizon.verified_until_record.map(|r| e_times[r]),
        });
    }
    json
}

/// Output `o`'s series of the hull of true runs for the summary, when every record has one (every
/// record of a study has at least the nominal run; a record without any would hold ±∞, which JSON
/// cannot carry, so the series is then left out rather than the summary refused).
fn runs_hull_series(series: &[Vec<f64>], o: usize) -> Option<Vec<f64>> {
    series
        .get(o)
        .filter(|values| values.iter().all(|x| x.is_finite()))
        .cloned()
}

/// Peak resident memory of this process (Linux `VmHWM`), bytes: the summary's
/// `stats.peak_memory_bytes` (`None` where `/proc/self/status` does not say).
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
