//! Studies: interval parameters of the sidecar propagated through HHT-I3 into bound envelopes.
//!
//! `plan (sample points ξ) ⇒ lock-step simulation in blocks of record times (rayon over samples)
//! ⇒ fit and bound each block ⇒ sinks (MCAP, summary, CSV) ⇒ the samples' records are dropped`
//!
//! Memory holds one block of records for all samples, never whole trajectories: peak memory does not
//! grow with horizon × samples. Results are bitwise identical for any thread count: each sample's
//! trajectory depends only on its parameters, and fits read samples in plan order.

mod bounds;
mod engine;
mod method;
mod plan;
mod study;

pub use bounds::EnvelopePoint;
pub use engine::SampleFailure;
pub use method::{Method, METHODS};
pub use plan::{Plan, SplitMix64, MAX_RUNS, TAYLOR_STEP};
pub use study::{
    BlockView, Envelope, Progress, Study, StudyError, StudyOptions, StudyReport,
    BLOCK_VALUE_BUDGET, MAX_BLOCK_RECORDS,
};
