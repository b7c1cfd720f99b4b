//! One shard's part of a distributed study's design (docs/distributed.md §3, `ribbon run`): a
//! contiguous range of the design's samples, and the nominal run in the first shard, simulated
//! block by block under the design's failure policy, each block handed to the shard's writer.
//! Failures are named by their index in the whole design, so a merge reports them as `analyze`.
//!
//! Does not: write the record block (`distributed/`), or fit anything (the merge does).

use super::engine::RecordSource;
use super::error::{ForeignError, StudyError};
use super::report::{DesignPart, Progress, SampleFailure};
use super::study::Study;
use super::study_plan::StudyPlan;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// What [`Study::simulate_design_part`] calls after each block: `(first record, records, the
/// part's recorded values)`.
pub type PartSink<'s> = dyn FnMut(usize, usize, &dyn RecordSource) -> Result<(), ForeignError> + 's;

/// Which part of the design a shard simulates.
#[derive(Clone, Debug)]
pub struct DesignPartRequest<'p> {
    /// The design's sample points, row-major `samples × d` (the whole design or a stage's).
    pub points: &'p [f64],
    /// The part's samples: indices into `points`.
    pub range: std::ops::Range<usize>,
    /// Whether the part also runs the nominal run (after its samples).
    pub with_nominal: bool,
}

impl Study<'_> {
    /// Simulates `part`'s samples of the design and, when it says so, the nominal run after them,
    /// block by block over the horizon under the design's failure policy (the same as
    /// [`Study::run_stages`]); `on_block(first, count, records)` after each block. This is one
    /// shard of a distributed study (`ribbon run`).
    pub fn simulate_design_part(
        &self,
        study_plan: &StudyPlan,
        part: DesignPartRequest<'_>,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        on_block: &mut PartSink<'_>,
    ) -> Result<DesignPart, StudyError> {
        let DesignPartRequest {
            points,
            range,
            with_nominal,
        } = part;
        let started = Instant::now();
        let d = self.space.len().max(1);
        let threads = self.thread_pool()?;
        let mut report = self.empty_report(&threads);
        let nominal_xi = self.space.nominal_xi();
        let design_samples = points.len() / d;
        let part = points.get(range.start * d..range.end * d).ok_or_else(|| {
            StudyError::BadOptions(format!(
                "internal: samples {}..{} are outside the design's {design_samples}",
                range.start, range.end
            ))
        })?;
        let mut lockstep = self.lockstep(part, with_nominal.then_some(nominal_xi.as_slice()));
        let mut context = self.phase_context(&threads, interrupt, started, &mut report, progress);
        let policy = context.design_failure_policy(study_plan.method);
        let offset = |mut failure: SampleFailure, nominal: Option<usize>| {
            if Some(failure.index) != nominal {
                failure.index += range.start;
            }
            failure
        };
        let nominal = lockstep.nominal_index();
        let result = context.run_source("design", &mut lockstep, policy, &mut |block, _| {
            on_block(block.first, block.count, block.lockstep).map_err(StudyError::Sink)
        });
        let complete = match result {
            Ok(complete) => complete,
            Err(StudyError::SampleFailed { run, failure, hint }) => {
                // Name the sample by its index in the whole design, not in this part.
                let run = if Some(failure.index) == nominal {
                    run
                } else {
                    format!(
                        "sample {} of {design_samples}",
                        failure.index + range.start + 1
                    )
                };
                return Err(StudyError::SampleFailed {
                    run,
                    failure: Box::new(offset(*failure, nominal)),
                    hint,
                });
            }
            Err(other) => return Err(other),
        };
        // The nominal run after the whole design's samples, as in `analyze`.
        let whole = |mut retry: SampleFailure| {
            retry.index = if Some(retry.index) == nominal {
                design_samples
            } else {
                retry.index + range.start
            };
            retry
        };
        Ok(DesignPart {
            complete,
            failures: report
                .excluded
                .into_iter()
                .map(|f| offset(f, nominal))
                .collect(),
            retried: report
                .retried
                .into_iter()
                .map(|r| whole(r.fixed_step_failure))
                .collect(),
            newton_iterations: report.newton_iterations,
            steps: report.steps,
            contacts: report.contacts,
            simulate_seconds: report.simulate_seconds,
        })
    }
}
