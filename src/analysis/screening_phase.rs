//! The screening phase (docs/method.md §10): the star design — the centre of the box and the
//! centres of its faces `±e_j`, 2d + 1 runs, one stage of a distributed study — run over the whole
//! horizon; each record feeds the [`Screening`], which ranks the parameters for the design built
//! on it, and the runs' hull, which the envelopes must contain (they are true responses).
//!
//! Does not: rank (`screening.rs`) or build the design from the ranking (`sparse.rs`).

use super::envelope::EnvelopePoint;
use super::error::StudyError;
use super::phase::{FailurePolicy, PhaseContext};
use super::screening::Screening;
use super::stages::StageCursor;

/// Runs the star design (`±e_j` and the centre, 2d + 1 runs). Returns the screening and whether
/// it ran to the end; `hull` receives the runs' min/max per record and output (record-major),
/// since they are true responses the envelopes must contain.
pub(super) fn screen(
    context: &mut PhaseContext<'_>,
    stages: &mut StageCursor,
    hull: &mut Vec<EnvelopePoint>,
) -> Result<(Screening, bool), StudyError> {
    let d = context.space.len();
    let n_outputs = context.scene.outputs.len();
    let mut points = Screening::points(d);
    points.extend(std::iter::repeat_n(0.0, d));
    let mut screening = Screening::new(d, n_outputs);
    let policy = FailurePolicy {
        can_exclude: false,
        hint: "Screening runs the centres of the box's faces; a failure there means the box contains points the model cannot simulate: narrow the box",
        noun: "screening run",
    };
    context.report.runs += 2 * d + 1;
    let complete = context.run_stage(
        stages,
        "screening",
        &points,
        None,
        policy,
        &mut |block, _| {
            for r in 0..block.count {
                screening.add_record(block.record(2 * d, r), |i| block.record(i, r));
                let mut row = vec![EnvelopePoint::EMPTY; n_outputs];
                for i in 0..=2 * d {
                    for (point, &value) in row.iter_mut().zip(block.record(i, r)) {
                        point.lower = point.lower.min(value);
                        point.upper = point.upper.max(value);
                    }
                }
                hull.extend(row);
            }
            Ok(())
        },
    )?;
    Ok((screening, complete))
}
