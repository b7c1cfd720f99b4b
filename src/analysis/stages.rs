//! The stages of a study (docs/distributed.md §7): every phase that simulates a set of sample
//! points which a scheduler could run elsewhere — the fixed design, the screening and the design
//! built on it, each round of the adaptive design — is a *stage*, numbered from 1 in the order
//! [`super::Study::run_stages`] reaches it. Before simulating a stage, the study asks a
//! [`StageRecords`] where its records come from:
//!
//! ```text
//! analyze:  SimulateHere  ⇒ every stage is simulated in this process (lock-step)
//! plan:     FirstStage    ⇒ stage 1 is pending: its points are what the plan file holds
//! merge:    the shards    ⇒ stages 1..k read from their record blocks; stage k+1 pending
//! ```
//!
//! A pending stage ends the study with [`StudyError::StageNeeded`], carrying the points the study
//! chose for it. Since the points of stage k+1 are chosen by the same code from the same records
//! whether they were simulated here or read back, a merge that replays stages 1..k takes exactly
//! the decisions `analyze` takes, and its final outputs are the same bytes.

use super::engine::RecordSource;
use super::error::StudyError;
use super::report::PendingStage;

/// What a study asks before simulating a stage.
#[derive(Clone, Copy, Debug)]
pub struct StageRequest<'p> {
    /// The stage's number, from 1.
    pub stage: usize,
    /// The phase it belongs to: `design`, `screening` or `adaptive`.
    pub phase: &'static str,
    /// Its sample points in standard coordinates, row-major `samples × d`.
    pub points: &'p [f64],
    /// Whether the nominal run is simulated with the samples (after them).
    pub nominal: bool,
}

/// Where the records of a stage come from.
pub enum StageSource {
    /// Simulate the stage here, in lock-step.
    Simulate,
    /// Read them from this source (the samples in order, then the nominal run when requested).
    Records(Box<dyn RecordSource>),
    /// The stage has not run yet: the study stops with [`StudyError::StageNeeded`].
    Pending,
}

/// Decides, stage by stage, where a study's records come from.
pub trait StageRecords {
    /// The source of `request`'s records.
    fn stage(&mut self, request: &StageRequest) -> Result<StageSource, StudyError>;
}

/// Every stage is simulated in this process (`ribbon analyze`).
pub struct SimulateHere;

impl StageRecords for SimulateHere {
    fn stage(&mut self, _request: &StageRequest) -> Result<StageSource, StudyError> {
        Ok(StageSource::Simulate)
    }
}

/// No stage has run yet (`ribbon plan`): the first stage requested is pending, so the study stops
/// there and reports the first stage's points.
pub struct FirstStage;

impl StageRecords for FirstStage {
    fn stage(&mut self, _request: &StageRequest) -> Result<StageSource, StudyError> {
        Ok(StageSource::Pending)
    }
}

/// The stages of one study, counted as the study reaches them.
pub(super) struct StageCursor<'s> {
    records: &'s mut dyn StageRecords,
    next: usize,
    dim: usize,
}

impl<'s> StageCursor<'s> {
    /// Stage 1 comes next; `dim` is the box's dimension.
    pub(super) fn new(records: &'s mut dyn StageRecords, dim: usize) -> StageCursor<'s> {
        StageCursor {
            records,
            next: 1,
            dim,
        }
    }

    /// The next stage's source: `None` to simulate it here, the records otherwise; a pending
    /// stage is [`StudyError::StageNeeded`], and a source of the wrong size is refused.
    pub(super) fn source(
        &mut self,
        phase: &'static str,
        points: &[f64],
        nominal: bool,
    ) -> Result<Option<Box<dyn RecordSource>>, StudyError> {
        let request = StageRequest {
            stage: self.next,
            phase,
            points,
            nominal,
        };
        self.next += 1;
        match self.records.stage(&request)? {
            StageSource::Simulate => Ok(None),
            StageSource::Records(source) => {
                let samples = points.len() / self.dim.max(1);
                let expected_nominal = nominal.then_some(samples);
                if source.len() != samples + usize::from(nominal)
                    || source.nominal_index() != expected_nominal
                {
                    return Err(StudyError::BadOptions(format!(
                        "internal: the records of stage {} hold {} runs (nominal {:?}), the stage has {samples} samples (nominal {expected_nominal:?})",
                        request.stage,
                        source.len(),
                        source.nominal_index()
                    )));
                }
                Ok(Some(source))
            }
            StageSource::Pending => Err(StudyError::StageNeeded(Box::new(PendingStage {
                stage: request.stage,
                phase,
                points: points.to_vec(),
                nominal,
            }))),
        }
    }
}
