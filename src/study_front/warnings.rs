//! What a finished study tells a person besides its outputs, on stderr and on the report page:
//! joints whose envelopes pass limits the scene does not enforce (and, where the surrogate is not
//! trusted, how far true runs went there), outputs whose misfit is below the integrator's
//! resolution, surrogates the check did not trust with what to do about them, an unchecked
//! surrogate, runs re-run with the adaptive step after the fixed step failed, and a chaotic
//! nominal motion; and the exit-4 error of an untrusted study.
//!
//! ```text
//! notes (`note: …`):        printed as they are found
//! warnings (`warning: …`):  gathered, then printed in order; the report page shows them too
//! ```
//!
//! Does not: judge trust (the check did, `analysis/check_phase.rs`) or find limit excursions
//! (`scene::limit_excursions`); it words what they found.

use crate::analysis::{
    untrusted_advice, widest_record, CheckMisfit, CheckReport, ElementsReport, Envelope, Method,
    StudyReport, TRUST_RELATIVE_MISFIT,
};
use crate::model::Model;
use crate::scene::{
    describe_limit_excursions, limit_excursions, outputs_at_enforced_limits, LimitExcursion, Scene,
};
use crate::uncertainty::ParameterSpace;
use crate::Error;

/// What a study's warnings found.
pub struct StudyWarnings {
    /// Every warning, without its `warning: ` prefix (printed on stderr; shown on the report page).
    pub warnings: Vec<String>,
    /// Joints whose envelopes pass URDF limits the scene does not enforce (for the summary).
    pub excursions: Vec<LimitExcursion>,
    /// What to do about the untrusted outputs, when some are (said in the warning and in the
    /// exit-4 error, [`untrusted`]).
    pub advice: Option<String>,
}

/// Finds and prints the warnings and notes of a finished study of `report` (`model` and `scene`
/// as it ran, the box `space`).
pub fn warn(
    report: &StudyReport,
    model: &Model,
    scene: &Scene,
    space: &ParameterSpace,
) -> StudyWarnings {
    let dimensions = space.len();
    // What to do about untrusted outputs: said once, in the warning and in the exit-4 error.
    let advice = report
        .check
        .as_ref()
        .filter(|check| !check.untrusted_outputs.is_empty())
        .map(|check| advice(report, check, model, scene, dimensions));
    // Every warning goes to stderr now and into the report's page (`--report`).
    let mut warnings: Vec<String> = Vec::new();
    let excursions = limit_excursions(
        model,
        scene,
        &report.envelope.outputs,
        &report.envelope.times,
        &report.envelope.lower,
        &report.envelope.upper,
    );
    if !excursions.is_empty() {
        let mut warning = describe_limit_excursions(&excursions, true);
        if let Some(check) = &report.check {
            let by_runs = limit_excursions(
                model,
                scene,
                &report.envelope.outputs,
                &report.envelope.times,
                &report.envelope.runs_lower,
                &report.envelope.runs_upper,
            );
            warning += &untrusted_excursions_note(check, &excursions, &by_runs);
        }
        warnings.push(warning);
    }
    note_retries(report);
    if let Some(check) = &report.check {
        note_below_resolution(report, check);
        let elements = report
            .elements
            .as_ref()
            .map(|elements| describe_elements(elements, &report.envelope, space));
        if let (Some(elements), None) = (&elements, &advice) {
            eprintln!("note: {elements}; every output is now trusted (docs/method.md §12)");
        }
        if let Some(advice) = &advice {
            let mut warning = untrusted_warning(report, check, advice);
            if let Some(elements) = &elements {
                warning = format!("{elements}, and still {warning}");
            }
            warnings.push(warning);
        }
    } else if report.check_skipped.is_some() {
        // `--check-runs 0` left the surrogate unchecked.
        eprintln!(
            "note: the surrogate was not checked against the true model (--check-runs 0), so nothing here says whether its envelopes can be trusted; leave --check-runs at its default to check them"
        );
    }
    if let Some(lyapunov) = report.lyapunov.filter(|l| l.is_chaotic()) {
        warnings.push(format!(
            "the nominal motion is chaotic: nearby trajectories separate at about {:.2} /s (largest Lyapunov exponent), so a small difference grows {:.1e}-fold over the {:.3} s horizon and a 1 % parameter change reaches order one after about {:.2} s. Past that time the envelopes describe chaos more than your parameters, and no surrogate in the parameters can follow them; shorten --duration, or check them with --method monte-carlo",
            lyapunov.exponent_per_s,
            lyapunov.amplification,
            lyapunov.horizon_s,
            lyapunov.predictability_horizon_s(0.01),
        ));
    }
    for warning in &warnings {
        eprintln!("warning: {}", crate::text::laid_out(warning));
    }
    StudyWarnings {
        warnings,
        excursions,
        advice,
    }
}

/// What the elements of a split box are, in one clause: for which outputs, how many leaves, how
/// deep, along which parameters, how many runs, and why splitting stopped when it did not end
/// trusted.
pub fn describe_elements(
    elements: &ElementsReport,
    envelope: &Envelope,
    space: &ParameterSpace,
) -> String {
    let dimensions = space.dimensions();
    let mut splits: Vec<(usize, usize)> = elements
        .splits_per_dimension(dimensions.len())
        .into_iter()
        .enumerate()
        .filter(|&(_, count)| count > 0)
        .collect();
    splits.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let along: Vec<String> = splits
        .iter()
        .take(4)
        .map(|&(j, count)| format!("{} ×{count}", dimensions[j].name))
        .collect();
    let outputs: Vec<&str> = elements
        .outputs
        .iter()
        .take(4)
        .map(|&o| envelope.outputs[o].name.as_str())
        .collect();
    let scanned = match elements.scanned_leaves() {
        0 => String::new(),
        n => format!("; {n} of them, where halving stalled, scanned on a grid of true runs and checked by bisecting its steepest cells"),
    };
    let stopped = match elements.stop {
        "trusted" => String::new(),
        "budget" => " (stopped by the --max-runs budget)".to_string(),
        "max-elements" => " (stopped at --max-elements)".to_string(),
        "resolution" => " (stopped: no failing element can be halved further)".to_string(),
        "stalled" => " (stopped: halving no longer improved the failing elements, a sign of a discontinuity or a response that oscillates across the box)".to_string(),
        "interrupted" => " (interrupted)".to_string(),
        other => format!(" (stopped: {other})"),
    };
    format!(
        "the first surrogate was not trusted for {} output(s) ({}{}), so the box was split into {} elements with their own surrogates and checks (depth {}, {} round(s), {} more runs; split along {}{scanned}){stopped}",
        elements.outputs.len(),
        outputs.join(", "),
        if elements.outputs.len() > 4 { ", …" } else { "" },
        elements.leaves(),
        elements.depth(),
        elements.rounds,
        elements.runs,
        if along.is_empty() { "nothing".to_string() } else { along.join(", ") },
    )
}

/// What to do about the untrusted outputs of `report` ([`untrusted_advice`]); `model` and `scene`
/// tell which of them reach an enforced joint limit, `dimensions` is the number of parameters.
fn advice(
    report: &StudyReport,
    check: &CheckReport,
    model: &Model,
    scene: &Scene,
    dimensions: usize,
) -> String {
    let e = &report.envelope;
    let at_stops = outputs_at_enforced_limits(
        model,
        scene,
        &e.outputs,
        &check.untrusted_outputs,
        &e.lower,
        &e.upper,
    );
    let names: Vec<&str> = at_stops
        .iter()
        .map(|&o| e.outputs[o].name.as_str())
        .collect();
    untrusted_advice(
        check,
        &e.times,
        dimensions,
        report.lyapunov.as_ref(),
        &names,
        report.method,
    )
}

/// How the warning and the exit-4 error word what the check found, by the kind of bound the
/// method gives: a scan's surrogate that missed, or an outer (or linearised) range that true runs
/// broke.
struct CheckWording {
    /// What the check found, for "… for N of M outputs".
    finding: &'static str,
    /// How the true runs disagreed, for the warning.
    evidence: &'static str,
    /// What it means for the envelopes, for the exit-4 error.
    consequence: &'static str,
    /// What it means for the envelopes, for the warning (a sentence).
    widened: &'static str,
    /// How the worst output's misfit is said ("53.6 % of its width" + this).
    worst_suffix: &'static str,
}

fn check_wording(method: Method) -> CheckWording {
    match (method.check_misfit(), method) {
        (CheckMisfit::Prediction, _) => CheckWording {
            finding: "the surrogate cannot be trusted",
            evidence: "true-model runs at its predicted extremes differ from it by more than",
            consequence: "their envelopes may be too narrow",
            widened: "The envelopes were widened to contain every true run, but they may still be too narrow",
            worst_suffix: "",
        },
        (CheckMisfit::Excess, Method::Taylor) => CheckWording {
            finding: "the range of the first-order Taylor linearisation was broken by the true model",
            evidence: "true-model runs at the linearisation's extremes lie outside the envelope it gave by more than",
            consequence: "it does not contain the true response, and the envelopes, widened to every true run, may still be too narrow",
            widened: "It does not contain the true response: the envelopes were widened to contain every true run, but they may still be too narrow",
            worst_suffix: " outside the bound",
        },
        (CheckMisfit::Excess, _) => CheckWording {
            finding: "the outer bound of the surrogate was broken by the true model",
            evidence: "true-model runs at the surrogate's extremes lie outside the envelope it gave by more than",
            consequence: "it is not an enclosure of the true response, and the envelopes, widened to every true run, may still be too narrow",
            widened: "It is not an enclosure of the true response: the envelopes were widened to contain every true run, but they may still be too narrow",
            worst_suffix: " outside the bound",
        },
    }
}

/// The exit-4 error of a study whose check did not trust some outputs.
pub fn untrusted(report: &StudyReport, check: &CheckReport, advice: String) -> Error {
    let outputs = &report.envelope.outputs;
    let wording = check_wording(report.method);
    let worst = check
        .untrusted_outputs
        .iter()
        .copied()
        .max_by(|&a, &b| check.relative_misfit[a].total_cmp(&check.relative_misfit[b]))
        .map_or_else(String::new, |o| {
            format!(
                "{}, {:.1} % of its width{}",
                outputs[o].name,
                100.0 * check.relative_misfit[o],
                wording.worst_suffix
            )
        });
    Error::Untrusted {
        finding: wording.finding,
        consequence: wording.consequence,
        untrusted: check.untrusted_outputs.len(),
        total: outputs.len(),
        worst,
        advice,
    }
}

/// Retried runs named on stderr, one line each; past this many, a count of the rest.
const RETRIES_NAMED: usize = 3;

/// Notes the runs that failed at the fixed step and were re-run with the adaptive step: one line
/// per run for the first [`RETRIES_NAMED`], then how many more (all of them are in the summary).
fn note_retries(report: &StudyReport) {
    for retry in report.retried.iter().take(RETRIES_NAMED) {
        let failure = &retry.fixed_step_failure;
        let from = report
            .envelope
            .times
            .get(failure.record)
            .map_or(String::new(), |&t| {
                format!(
                    " (its records from t = {} s on are that run's)",
                    crate::text::message_time(t)
                )
            });
        eprintln!(
            "note: {} of the {} phase failed at the fixed step at t = {} s and was re-run from t = 0 with the adaptive step on the same record grid{from}; the fixed step's failure: {}",
            retry.run,
            retry.phase,
            crate::text::message_time(failure.time_s),
            failure.message
        );
    }
    if report.retried.len() > RETRIES_NAMED {
        eprintln!(
            "note: {} more runs failed at the fixed step and were re-run with the adaptive step ({} in all; the summary's retried_samples lists each)",
            report.retried.len() - RETRIES_NAMED,
            report.retried.len()
        );
    }
}

/// Notes the outputs whose misfit, large against their width, is within the integrator's
/// resolution: numerical noise, not a failed surrogate.
fn note_below_resolution(report: &StudyReport, check: &CheckReport) {
    let outputs = &report.envelope.outputs;
    if check.below_resolution_outputs.is_empty() {
        return;
    }
    let listed: Vec<String> = check
        .below_resolution_outputs
        .iter()
        .take(5)
        .map(|&o| {
            format!(
                "{} ({:.1e} {unit} ≤ {:.1e} {unit})",
                outputs[o].name,
                check.max_misfit[o],
                check.resolution[o].unwrap_or(f64::NAN),
                unit = outputs[o].unit
            )
        })
        .collect();
    eprintln!(
        "note: {} output(s) miss by more than {:.0} % of their envelope width but by less than the integrator's resolution, so their envelopes are numerical noise, not a failed surrogate (docs/method.md §7): {}{}",
        check.below_resolution_outputs.len(),
        100.0 * TRUST_RELATIVE_MISFIT,
        listed.join(", "),
        if check.below_resolution_outputs.len() > 5 { ", …" } else { "" },
    );
}

/// The warning naming the outputs whose surrogates missed the true model at their predicted
/// extremes, or whose outer bounds true runs broke (some did), with what to do ([`advice`]).
fn untrusted_warning(report: &StudyReport, check: &CheckReport, advice: &str) -> String {
    let outputs = &report.envelope.outputs;
    let mut worst: Vec<usize> = check.untrusted_outputs.clone();
    worst.sort_by(|&a, &b| check.relative_misfit[b].total_cmp(&check.relative_misfit[a]));
    let listed: Vec<String> = worst
        .iter()
        .take(5)
        .map(|&o| {
            format!(
                "{} ({:.1} %)",
                outputs[o].name,
                100.0 * check.relative_misfit[o]
            )
        })
        .collect();
    let spread = worst
        .first()
        .and_then(|&o| runs_spread_where_widest(&report.envelope, o))
        .unwrap_or_default();
    let wording = check_wording(report.method);
    format!(
        "{} for {} of {} outputs: {} {:.0} % of the envelope width: {}{}. {}{}; {}",
        wording.finding,
        worst.len(),
        outputs.len(),
        wording.evidence,
        100.0 * TRUST_RELATIVE_MISFIT,
        listed.join(", "),
        if worst.len() > 5 { ", …" } else { "" },
        wording.widened,
        spread,
        advice,
    )
}

/// For the limit-excursion warning: which of `excursions` (found on the envelopes) are envelope
/// bounds of outputs whose surrogate the check does not trust, and how far the study's true runs
/// went there (`by_runs`: the excursions found on the hull of true runs); empty when none is.
fn untrusted_excursions_note(
    check: &CheckReport,
    excursions: &[LimitExcursion],
    by_runs: &[LimitExcursion],
) -> String {
    let untrusted: Vec<&LimitExcursion> = excursions
        .iter()
        .filter(|excursion| check.untrusted_outputs.contains(&excursion.output))
        .collect();
    if untrusted.is_empty() {
        return String::new();
    }
    let described: Vec<String> = untrusted
        .iter()
        .take(5)
        .map(
            |excursion| match by_runs.iter().find(|r| r.joint == excursion.joint) {
                Some(run) => format!(
                    "'{}' to {:.4} {} at t = {} s",
                    run.joint,
                    run.reached,
                    run.unit,
                    crate::text::message_time(run.time_s)
                ),
                None => format!("'{}' stayed within its limits", excursion.joint),
            },
        )
        .collect();
    format!(
        ". Of these, {} are bounds of surrogates the check does not trust (below); the study's true runs went: {}{}",
        untrusted.len(),
        described.join("; "),
        if untrusted.len() > 5 { "; …" } else { "" },
    )
}

/// Where output `o`'s envelope is widest, how much of it the study's true runs reached (`". Where
/// the envelope of q.x is widest (t = …, [l, u]), the study's true runs span [a, b], N % of it"`);
/// `None` without a positive width or without runs there. A small share means the surrogate
/// swings far past anything a true run did between its samples (the envelope is loose there, not
/// established); a share near 100 %, that the runs themselves reach its edges.
fn runs_spread_where_widest(envelope: &Envelope, o: usize) -> Option<String> {
    let k = widest_record(envelope, o)?;
    let width = envelope.upper[o][k] - envelope.lower[o][k];
    let (lowest, highest) = (
        *envelope.runs_lower.get(o)?.get(k)?,
        *envelope.runs_upper.get(o)?.get(k)?,
    );
    // Neither a zero or NaN width nor an empty hull (no run at that record) makes a share.
    let measurable = width > 0.0 && highest >= lowest;
    if !measurable {
        return None;
    }
    let output = &envelope.outputs[o];
    Some(format!(
        ". Where the envelope of {1} is widest (t = {0} s, [{2:.4e}, {3:.4e}] {unit}), the study's true runs span [{4:.4e}, {5:.4e}] {unit}, {6:.1} % of it",
        crate::text::message_time(envelope.times[k]),
        output.name,
        envelope.lower[o][k],
        envelope.upper[o][k],
        lowest,
        highest,
        100.0 * (highest - lowest) / width,
        unit = output.unit,
    ))
}
