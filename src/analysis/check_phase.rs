//! The a-posteriori check's phase (docs/method.md §7): the true-model runs of a [`CheckPlan`]
//! over the whole horizon; each run widens the envelopes (a true response in the box) and gives
//! misfits by the method's [`CheckMisfit`]: for the scans each checked prediction's
//! `|true − predicted|` at its output and record; for outer and approximate methods every true
//! value's excess past the envelope as it was before the check widened it. Then, per output, the
//! largest misfit against the envelope's width and the output's resolution decides whether its
//! surrogate is trusted ([`trust_verdict`]), when the first miss came, and up to when the same
//! checks pass.
//!
//! Does not: choose the points (`check.rs`: [`super::CheckCandidates`]), or say what to do about
//! an untrusted surrogate (`check.rs`: [`super::untrusted_advice`]).

use super::accumulator::Accumulator;
use super::check::{
    output_resolution, trust_verdict, CheckPlan, TrustVerdict, TRUST_RELATIVE_MISFIT,
};
use super::elements::OutputScale;
use super::envelope::EnvelopePoint;
use super::error::StudyError;
use super::method::CheckMisfit;
use super::phase::PhaseContext;
use super::report::CheckReport;
use crate::simulate::hht_settings;

/// What the check found: the report, and the misfit of every checked output at every record
/// (`misfit[o][r]`, 0 where nothing was checked), which the elements phase splits by.
pub(super) struct CheckOutcome {
    /// The verdicts and what they rest on.
    pub report: CheckReport,
    /// `misfit[o][r]`: the largest `|true − predicted|` of output `o`'s checks at record `r`.
    pub misfit: Vec<Vec<f64>>,
}

/// Runs the check plan's points, widens the envelopes with them and measures the misfits.
pub(super) fn check(
    context: &mut PhaseContext<'_>,
    check_plan: &CheckPlan,
    accumulator: &mut Accumulator,
) -> Result<CheckOutcome, StudyError> {
    let n_outputs = accumulator.n_outputs;
    let runs = check_plan.checks.len();
    // Per record, the (run, output, predicted) checks made there.
    let n_records = accumulator.times.len();
    let mut by_record: Vec<Vec<(usize, usize, f64)>> = vec![Vec::new(); n_records];
    for (run, checks) in check_plan.checks.iter().enumerate() {
        for &(record, output, _side, predicted) in checks {
            by_record[record].push((run, output, predicted));
        }
    }
    let mut checked: Vec<(usize, usize, f64)> = Vec::new();
    let mut misfit = vec![vec![0.0_f64; n_records]; n_outputs];
    let rule = context.report.method.check_misfit();
    // An outer bound is broken by a true value outside it as the method gave it (before the
    // check's own runs widened it).
    let before_check: Vec<(f64, f64)> = match rule {
        CheckMisfit::Excess => accumulator
            .points
            .iter()
            .map(|p| (p.lower, p.upper))
            .collect(),
        CheckMisfit::Prediction => Vec::new(),
    };
    let policy = context.exclusion_policy("check run");
    context.report.runs += runs;
    let complete = context.run_phase(
        "check",
        &check_plan.points,
        None,
        policy,
        &mut |block, _report| {
            for r in 0..block.count {
                let record = block.first + r;
                for i in 0..runs {
                    if block.lockstep.failed(i) {
                        continue;
                    }
                    let values = block.record(i, r);
                    if rule == CheckMisfit::Excess {
                        let row = &before_check[record * n_outputs..(record + 1) * n_outputs];
                        for (o, (&truth, &(lower, upper))) in values.iter().zip(row).enumerate() {
                            let truth = accumulator.reported(o, truth);
                            let m = &mut misfit[o][record];
                            *m = m.max(excess(truth, lower, upper));
                        }
                    }
                    accumulator.widen(record, values);
                }
                for &(run, output, predicted) in &by_record[record] {
                    if block.lockstep.failed(run) {
                        continue;
                    }
                    let truth = accumulator.reported(output, block.record(run, r)[output]);
                    checked.push((output, record, truth));
                    if rule == CheckMisfit::Prediction {
                        let m = &mut misfit[output][record];
                        *m = m.max((truth - predicted).abs());
                    }
                }
            }
            Ok(())
        },
    )?;
    let report = judge(
        context.scene,
        CheckRuns {
            runs,
            unique_candidates: check_plan.unique_candidates,
            points: check_plan.points.clone(),
            checked,
            complete,
        },
        &misfit,
        accumulator,
    );
    Ok(CheckOutcome { report, misfit })
}

/// Each output's scale for the trust test over `points` (record-major `records × outputs` of
/// `scene`'s outputs): its largest width, and its resolution at its largest magnitude
/// ([`output_resolution`]).
pub(super) fn output_scales(
    scene: &crate::scene::Scene,
    points: &[super::bounds::EnvelopePoint],
) -> Vec<OutputScale> {
    let n_outputs = scene.outputs.len();
    let settings = hht_settings(scene);
    (0..n_outputs)
        .map(|o| {
            let (width, magnitude) = points.iter().skip(o).step_by(n_outputs.max(1)).fold(
                (0.0_f64, 0.0_f64),
                |(width, magnitude), p| {
                    (
                        width.max(p.upper - p.lower),
                        magnitude.max(p.lower.abs()).max(p.upper.abs()),
                    )
                },
            );
            OutputScale {
                width,
                resolution: output_resolution(&scene.outputs[o].kind, magnitude, &settings),
            }
        })
        .collect()
}

/// The runs a check made, for [`judge`].
#[derive(Clone)]
pub(super) struct CheckRuns {
    /// Runs made.
    pub runs: usize,
    /// Distinct predicted extremisers there were to choose from.
    pub unique_candidates: usize,
    /// The points run, whole-box coordinates, row-major.
    pub points: Vec<f64>,
    /// Every checked prediction: `(output, record, true value)`.
    pub checked: Vec<(usize, usize, f64)>,
    /// Whether the runs covered the whole horizon.
    pub complete: bool,
}

impl CheckRuns {
    /// The runs behind a check's `report`, to take further checks in.
    pub fn of(report: &CheckReport) -> CheckRuns {
        CheckRuns {
            runs: report.runs,
            unique_candidates: report.unique_candidates,
            points: report.points.clone(),
            checked: report.checked.clone(),
            complete: report.complete,
        }
    }

    /// Takes in the runs of a further check (`report`): its runs, points and checked predictions;
    /// the whole stays complete only if that check was.
    pub fn absorb(&mut self, report: &CheckReport) {
        self.runs += report.runs;
        self.points.extend_from_slice(&report.points);
        self.checked.extend_from_slice(&report.checked);
        self.complete &= report.complete;
    }
}

/// The verdicts of a check whose runs found `misfit[o][r]`, against the envelopes in
/// `accumulator` (whose error estimates become at least the misfits): per output the largest
/// misfit against the envelope's largest width and the output's resolution ([`trust_verdict`]),
/// when the first miss came, and up to when the same checks pass.
pub(super) fn judge(
    scene: &crate::scene::Scene,
    runs: CheckRuns,
    misfit: &[Vec<f64>],
    accumulator: &mut Accumulator,
) -> CheckReport {
    let n_outputs = accumulator.n_outputs;
    let n_records = accumulator.times.len();
    let CheckRuns {
        runs,
        unique_candidates,
        points,
        checked,
        complete,
    } = runs;
    let mut max_misfit = vec![0.0; n_outputs];
    let mut relative_misfit = vec![0.0; n_outputs];
    let mut untrusted_outputs = Vec::new();
    let mut below_resolution_outputs = Vec::new();
    let scales = output_scales(scene, &accumulator.points[..n_records * n_outputs]);
    let resolution: Vec<Option<f64>> = scales.iter().map(|s| s.resolution).collect();
    let widths: Vec<f64> = scales.iter().map(|s| s.width).collect();
    for o in 0..n_outputs {
        max_misfit[o] = misfit[o].iter().copied().fold(0.0, f64::max);
        let (relative, verdict) = trust_verdict(max_misfit[o], widths[o], resolution[o]);
        relative_misfit[o] = relative;
        match verdict {
            TrustVerdict::Trusted => {}
            TrustVerdict::BelowResolution => below_resolution_outputs.push(o),
            TrustVerdict::Untrusted => untrusted_outputs.push(o),
        }
        for (r, &m) in misfit[o].iter().enumerate() {
            let point = &mut accumulator.points[r * n_outputs + o];
            if let Some(error) = &mut point.error {
                *error = error.max(m);
            }
        }
    }
    let first_miss_record = untrusted_outputs
        .iter()
        .filter_map(|&o| {
            misfit[o]
                .iter()
                .position(|&m| m > TRUST_RELATIVE_MISFIT * widths[o])
        })
        .min();
    // The last prefix the trust test passes is what the check would say of a run that ended
    // there.
    let passes_until_record = prefix_trust(&resolution, misfit, &accumulator.points)
        .iter()
        .rposition(|&passes| passes);
    let checks_before_first_miss = checked
        .iter()
        .filter(|&&(_, record, _)| first_miss_record.is_none_or(|first| record < first))
        .count();
    CheckReport {
        runs,
        unique_candidates,
        points,
        max_misfit,
        relative_misfit,
        untrusted_outputs,
        resolution,
        below_resolution_outputs,
        complete,
        checked,
        first_miss_record,
        checks_before_first_miss,
        passes_until_record,
        horizon: None,
    }
}

/// How far `value` lies outside `[lower, upper]` (0 inside).
pub(super) fn excess(value: f64, lower: f64, upper: f64) -> f64 {
    (lower - value).max(value - upper).max(0.0)
}

/// The trust test of every prefix of the records, with running widths and misfits
/// (`misfit[o][r]`, against the envelopes in `accumulator`): whether a check of a run that ended
/// at record `r` would trust every output. Not monotone: an envelope that widens fast after a
/// miss can pass again later.
pub(super) fn prefix_verdicts(
    scene: &crate::scene::Scene,
    misfit: &[Vec<f64>],
    accumulator: &Accumulator,
) -> Vec<bool> {
    let n_outputs = accumulator.n_outputs;
    let n_records = accumulator.times.len();
    let resolution: Vec<Option<f64>> =
        output_scales(scene, &accumulator.points[..n_records * n_outputs])
            .iter()
            .map(|s| s.resolution)
            .collect();
    prefix_trust(&resolution, misfit, &accumulator.points)
}

/// [`prefix_verdicts`] of the envelope `points` (record-major, one per output of `resolution`).
fn prefix_trust(
    resolution: &[Option<f64>],
    misfit: &[Vec<f64>],
    points: &[EnvelopePoint],
) -> Vec<bool> {
    let n_outputs = resolution.len();
    let mut prefix_width = vec![0.0_f64; n_outputs];
    let mut prefix_misfit = vec![0.0_f64; n_outputs];
    points
        .chunks_exact(n_outputs.max(1))
        .enumerate()
        .map(|(r, points)| {
            let mut passes = true;
            for (o, point) in points.iter().enumerate() {
                prefix_width[o] = prefix_width[o].max(point.upper - point.lower);
                prefix_misfit[o] = prefix_misfit[o].max(misfit[o][r]);
                let (_, verdict) = trust_verdict(prefix_misfit[o], prefix_width[o], resolution[o]);
                passes &= verdict != TrustVerdict::Untrusted;
            }
            passes
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{excess, prefix_trust};
    use crate::analysis::envelope::EnvelopePoint;

    #[test]
    fn a_prefix_can_fail_at_a_miss_and_pass_again_when_the_envelope_widens() {
        // One output: widths 1, 1, 10; a misfit of 0.1 (10 % of the width) at record 1.
        let point = |width: f64| EnvelopePoint {
            lower: 0.0,
            upper: width,
            error: None,
            outer: None,
        };
        let points = [point(1.0), point(1.0), point(10.0)];
        let misfit = vec![vec![0.0, 0.1, 0.0]];
        assert_eq!(
            prefix_trust(&[None], &misfit, &points),
            vec![true, false, true]
        );
    }

    #[test]
    fn the_excess_is_the_distance_outside_the_envelope() {
        assert_eq!(excess(0.5, 0.0, 1.0), 0.0);
        assert_eq!(excess(1.0, 0.0, 1.0), 0.0);
        assert_eq!(excess(1.25, 0.0, 1.0), 0.25);
        assert_eq!(excess(-2.0, 0.0, 1.0), 2.0);
    }
}
