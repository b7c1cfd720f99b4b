//! Why a study could not run or finish ([`StudyError`]), and the error of a part it calls but
//! does not define ([`ForeignError`]: a record source that reads files, a sink that writes them).
//!
//! Every variant is the study's own: the crate's error wraps this one and decides the exit code
//! (`crate::Error::exit_code`); nothing here names the crate's error.

use super::report::{PendingStage, SampleFailure};
use crate::uq::UqError;
use thiserror::Error;

/// Why a study could not run or finish.
#[derive(Debug, Error)]
pub enum StudyError {
    /// Options that cannot work.
    #[error("{0}")]
    BadOptions(String),
    /// The interval mathematics refused (e.g. an order beyond its range).
    #[error("interval mathematics: {0}")]
    Uq(#[from] UqError),
    /// A sample failed and the study cannot go on.
    #[error("{} failed at t = {} s: {}; at parameter values {:?} (ξ = {:?}). {hint}",
        .run, crate::text::message_time(.failure.time_s), .failure.message, .failure.values, .failure.xi)]
    SampleFailed {
        /// Which run: "the nominal run", "sample 3 of 25", "check run 2 of 8".
        run: String,
        /// The failure.
        failure: Box<SampleFailure>,
        /// What to do.
        hint: &'static str,
    },
    /// A sink (MCAP, …) failed.
    #[error(transparent)]
    Sink(ForeignError),
    /// The recorded values of a phase could not be read (a shard's record block).
    #[error(transparent)]
    Records(ForeignError),
    /// Not a failure: the study needs the records of a stage that has not run yet (`plan` and
    /// `merge` write its plan; `analyze` never stops here). See docs/distributed.md §7.
    #[error("the study needs the records of stage {} ({} phase) before it can go on", .0.stage, .0.phase)]
    StageNeeded(Box<PendingStage>),
    /// The worker threads could not be started.
    #[error("cannot start {threads} worker threads: {message}")]
    Threads {
        /// Requested count.
        threads: usize,
        /// The reason.
        message: String,
    },
}

/// The error of a part a study calls but does not define — a record source that reads files
/// written elsewhere ([`StudyError::Records`]), a sink that writes outputs
/// ([`StudyError::Sink`]) — kept whole, so that whoever knows its type (the crate's error, which
/// decides exit codes) can still tell what it was ([`ForeignError::downcast_ref`]). Its message
/// is the part's own.
#[derive(Debug)]
pub struct ForeignError(Box<dyn std::error::Error + Send + Sync + 'static>);

impl ForeignError {
    /// Wraps a part's error.
    pub fn new(error: impl std::error::Error + Send + Sync + 'static) -> ForeignError {
        ForeignError(Box::new(error))
    }

    /// The part's error, when it is an `E`.
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        self.0.downcast_ref::<E>()
    }
}

impl std::fmt::Display for ForeignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for ForeignError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}
