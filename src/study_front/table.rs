//! The stdout table of a study: per output its largest envelope width with when and where, the
//! line of the method, its design, runs and check (or why it was skipped), the adaptive design's rounds, the Sobol'
//! contributors and the most influential parameters. The same text heads the report page.
//!
//! Does not: print it (the caller writes it after the outputs), or compute anything the report
//! does not hold.

use super::options::order_of;
use crate::analysis::{
    CheckMisfit, Method, StudyOptions, StudyReport, ADAPTIVE_TOLERANCE, TABLE_SOBOL_CONTRIBUTORS,
};
use crate::output::SensitivitySummary;
use crate::uncertainty::ParameterSpace;

/// The table of `report` (a study with `options` over `space`) that took `wall_seconds`.
pub fn table(
    options: &StudyOptions,
    space: &ParameterSpace,
    report: &StudyReport,
    wall_seconds: f64,
) -> String {
    let e = &report.envelope;
    let width = crate::text::name_column_width(e.outputs.iter().map(|o| o.name.as_str()));
    let mut text = format!(
        "{:<width$}  {:>8}  {:>13}  {:>9}  {:>13}  {:>13}\n",
        "output", "unit", "max width", "at t (s)", "lower there", "upper there"
    );
    for (o, output) in e.outputs.iter().enumerate() {
        let (k, w) = e.lower[o]
            .iter()
            .zip(&e.upper[o])
            .map(|(l, u)| u - l)
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (k, w)| {
                if w > best.1 {
                    (k, w)
                } else {
                    best
                }
            });
        text.push_str(&format!(
            "{:<width$}  {:>8}  {:>13.6e}  {:>9.3}  {:>13.6e}  {:>13.6e}\n",
            output.name,
            output.unit,
            w,
            e.times.get(k).copied().unwrap_or(f64::NAN),
            e.lower[o].get(k).copied().unwrap_or(f64::NAN),
            e.upper[o].get(k).copied().unwrap_or(f64::NAN),
        ));
    }
    text.push_str(&format!(
        "method {} ({} bounds{}, design {}), {} model runs{}, {:.3} s wall{}\n",
        report.method.name(),
        report.method.bound_kind(),
        order_of(report.method, options).map_or(String::new(), |k| format!(", order {k}")),
        report.design,
        report.runs,
        report.check.as_ref().map_or_else(|| check_skipped(report), |c| {
            // Outputs within the integrator's resolution are noise, not the surrogate's misfit.
            let worst = c
                .relative_misfit
                .iter()
                .enumerate()
                .filter(|(o, _)| !c.below_resolution_outputs.contains(o))
                .map(|(_, &m)| m)
                .fold(0.0, f64::max);
            let (subject, misfit) = match (report.method.check_misfit(), report.method) {
                (CheckMisfit::Prediction, _) => ("surrogate", "misfit"),
                (CheckMisfit::Excess, Method::Taylor) => ("linearisation", "excess over the bound"),
                (CheckMisfit::Excess, _) => ("surrogate", "excess over the bound"),
            };
            format!(
                " ({} of them checking the {subject}'s extremes: largest {misfit} {:.2e} of the width{}{})",
                c.runs,
                worst,
                if c.below_resolution_outputs.is_empty() {
                    String::new()
                } else {
                    format!(
                        " outside {} output(s) within the integrator's resolution",
                        c.below_resolution_outputs.len()
                    )
                },
                if c.untrusted_outputs.is_empty() { ", trusted" } else { ", NOT TRUSTED" }
            )
        }),
        wall_seconds,
        if report.excluded.is_empty() {
            String::new()
        } else {
            format!(", {} samples excluded", report.excluded.len())
        }
    ));
    if let Some(a) = &report.adaptive {
        text.push_str(&format!(
            "adaptive design: {} runs in {} rounds, {} stages ({}), {} interaction terms, degree up to {}, largest term left {:.1e} of an output's spread\n",
            a.runs,
            a.rounds,
            a.stages,
            match a.stop {
                "converged" => format!("converged below {ADAPTIVE_TOLERANCE:e}"),
                "budget" => format!("stopped by the budget of {} runs", a.budget),
                other => other.to_string(),
            },
            a.interactions,
            a.max_degree,
            a.largest_remaining_indicator
        ));
    }
    if let Some(elements) = &report.elements {
        text.push_str(&format!(
            "elements: {} leaves{} of {} elements, depth {}, {} round(s), {} runs ({}); split {}\n",
            elements.leaves(),
            match elements.scanned_leaves() {
                0 => String::new(),
                n => format!(" ({n} scanned)"),
            },
            elements.elements.len(),
            elements.depth(),
            elements.rounds,
            elements.runs,
            match elements.untrusted_leaves() {
                0 => "every leaf trusted".to_string(),
                1 => format!("1 leaf untrusted, stopped: {}", elements.stop),
                n => format!("{n} leaves untrusted, stopped: {}", elements.stop),
            },
            {
                let names: Vec<String> = elements
                    .splits_per_dimension(space.len())
                    .into_iter()
                    .enumerate()
                    .filter(|&(_, count)| count > 0)
                    .map(|(j, count)| format!("{} ×{count}", space.dimensions()[j].name))
                    .collect();
                names.join(", ")
            }
        ));
        if report.sobol.is_some() {
            text.push_str("(the Sobol' indices below are the first surrogate's, over the whole box; it was not trusted for the outputs the elements were made for)\n");
        }
    } else if let Some(check) = report
        .check
        .as_ref()
        .filter(|c| report.sobol.is_some() && !c.untrusted_outputs.is_empty())
    {
        text.push_str(&format!(
            "(the Sobol' indices and the ranking below are the surrogate's, which the check did not trust for {} of {} outputs: for those they rank what the surrogate says, not what true runs do)\n",
            check.untrusted_outputs.len(),
            e.outputs.len()
        ));
    }
    if let Some(series) = &report.sobol {
        let names: Vec<String> = space.dimensions().iter().map(|d| d.name.clone()).collect();
        text.push_str(&series.table(e, &names, TABLE_SOBOL_CONTRIBUTORS));
    }
    if let Some(rows) = SensitivitySummary::of_study(space, report) {
        text.push_str(&format!(
            "most influential parameters (of {}):\n",
            rows.len()
        ));
        for row in rows.iter().take(TABLE_SENSITIVITIES) {
            let mut parts = Vec::new();
            if let (Some(slope), Some(output)) = (row.relative_slope, &row.slope_output) {
                parts.push(format!(
                    "slope × half-width {:.1} % of the width of {output}",
                    100.0 * slope
                ));
            }
            if let (Some(index), Some(output)) = (row.total_index, &row.total_index_output) {
                parts.push(format!("total Sobol' index {index:.3} on {output}"));
            }
            text.push_str(&format!(
                "  {:>3}. {}: {}\n",
                row.rank,
                row.name,
                parts.join("; ")
            ));
        }
    }
    text
}

/// The method line's words for a check that was skipped (empty when none was).
fn check_skipped(report: &StudyReport) -> String {
    report.check_skipped.map_or(String::new(), |skipped| {
        format!(", check skipped ({})", skipped.reason())
    })
}

/// Parameters listed in the stdout table's ranking.
const TABLE_SENSITIVITIES: usize = 5;
