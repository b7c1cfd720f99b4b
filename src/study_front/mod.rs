//! The study front end: what the study commands — `analyze`, `compare`, `plan`, `run`, `merge` —
//! share between a person's options and the study's results, without the command line's parser.
//!
//! ```text
//! cli/ (clap) ─▶ StudyRequest, CompareRequest, ShardRequest, MergeRequest (plain structs)
//!   ─▶ options ⇒ StudyOptions ─▶ analysis/ (Study: plan, phases) ─▶ StudyReport
//!   ─▶ output/ (MCAP log, summary JSON, CSV, report page) and the person (progress, warnings,
//!      the stdout table)
//! ```
//!
//! One file per job: [`options`] (flags → study options), [`progress`] (stderr progress),
//! [`warnings`] (the warnings and advice a finished study prints, the exit-4 error), [`table`] (the
//! stdout table), [`run_study`](mod@run_study) (the driver of `analyze` and `merge`),
//! [`report_page`] (`--report DIR`), [`study_log`] (the MCAP log's header and close, the finished
//! blocks kept to write a log later), [`plan_match`] (a plan file against this ribbon's plan), and
//! one per command that is more than the driver: [`compare`](mod@compare) (with
//! [`compare_report`]), [`plan`], [`shard`] (`run`), [`merge`](mod@merge).
//!
//! Sits above `analysis/`, `output/` and `distributed/`, below `cli/`: it may name
//! `crate::Error` and print to stderr; it does not parse command lines or know clap's types.
//! (Named for where it stands — in front of a study; `study` alone would be mistaken for
//! `analysis::Study`, `frontend` alone would hide that `simulate`, `params` and `dynamics` do not
//! use it.)

pub mod compare;
pub mod compare_report;
pub mod merge;
pub mod options;
pub mod plan;
pub mod plan_match;
pub mod progress;
pub mod report_page;
pub mod run_study;
pub mod shard;
pub mod study_log;
pub mod table;
pub mod warnings;

pub use compare::{compare, CompareRequest};
pub use merge::{merge, MergeRequest};
pub use options::{SceneInputs, StudyFlags, StudyOutputs, StudyRequest};
pub use plan::plan_study;
pub use run_study::run_study;
pub use shard::{run_shard, ShardRequest};

/// Installs the SIGINT/SIGTERM watcher ([`crate::interrupt`]); a failure is a warning (the signals
/// then end the process at once, which still never leaves a half-written output in place).
pub fn install_interrupt() {
    if let Err(message) = crate::interrupt::install() {
        eprintln!("warning: {message}; an interruption will not save partial results");
    }
}
