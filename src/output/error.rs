//! The one error type of `output/`: why an output could not be checked or written.
//!
//! Every writer of this module (CSV, summary JSON, MCAP log, report page and plots, atomic files)
//! and the output-path checks return [`OutputError`]; `crate::Error` wraps it and maps it to the
//! exit code ([`OutputError::exit_code`]). Does not: decide file names or contents (the writers
//! do), or know the commands that call them.

use super::mcap::error::McapError;
use thiserror::Error;

/// Why an output was refused or could not be written.
#[derive(Debug, Error)]
pub enum OutputError {
    /// An output path (or directory) that would destroy something or cannot be written: an
    /// input, a directory, a special file, a symbolic link, two outputs on one file
    /// ([`super::check_outputs`]), refused before anything runs.
    #[error("{flag}: {message}")]
    BadPath {
        /// The flag that named it (`--csv`, `--report`, …).
        flag: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// Writing a result failed.
    #[error("cannot write {what}: {source}")]
    Write {
        /// What was being written (`CSV 'out.csv'`, `to standard output`, …).
        what: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A result holds a NaN or an infinity: it is never written or printed.
    #[error("{what}: output '{output}' is {value} at t = {} s; a non-finite number is never reported as a result, so nothing was written (the run overflowed: check the scene's values, or use a smaller step)", crate::text::message_time(*.time_s))]
    NonFinite {
        /// Where it would have gone (`CSV 'out.csv'`, `summary 'x.json'`, `the table`).
        what: String,
        /// The output (series) name.
        output: String,
        /// The record time, s.
        time_s: f64,
        /// The value found (NaN or ±inf).
        value: f64,
    },
    /// Writing the MCAP log failed.
    #[error(transparent)]
    Mcap(#[from] McapError),
}

impl OutputError {
    /// The process exit code: 2 for a refused path (the input is at fault and nothing ran), 1 for
    /// a result that could not be written.
    pub fn exit_code(&self) -> u8 {
        match self {
            OutputError::BadPath { .. } => 2,
            OutputError::Write { .. } | OutputError::NonFinite { .. } | OutputError::Mcap(_) => 1,
        }
    }
}
