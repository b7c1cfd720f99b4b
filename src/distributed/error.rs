//! Why a plan, a shard or a merge was refused.

use std::path::PathBuf;
use thiserror::Error;

/// What is wrong with a plan file, a shard's record block or the set of shards.
#[derive(Debug, Error)]
pub enum ShardError {
    /// The plan file cannot be used.
    #[error("plan '{path}': {message}")]
    Plan {
        /// The plan file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
    /// An input of the plan (URDF, sidecar) is not what the plan was made from.
    #[error("plan '{plan}': the {what} '{path}' has changed since the plan was made (hash {found}, the plan has {expected}); make a new plan with `ribbon plan`, or restore the file")]
    InputChanged {
        /// The plan file.
        plan: PathBuf,
        /// "URDF" or "sidecar".
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// Its hash in the plan.
        expected: String,
        /// Its hash now.
        found: String,
    },
    /// `--shard`, `--shards` or the scheduler's index variable is wrong.
    #[error("{flag}: {message}")]
    BadShard {
        /// The flag or variable.
        flag: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A record block file cannot be read as one (not MCAP, another format, inconsistent).
    #[error("record block '{path}': {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A record block file ends early (its writer was killed, or the copy is incomplete).
    #[error("record block '{path}' is truncated: {message}; nothing was written: run its shard again with `{command}` (it overwrites only that shard), then merge again")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Where it ends.
        message: String,
        /// The `ribbon run` command that writes the block again.
        command: String,
    },
    /// A record block whose bytes are not the ones its shard wrote (a flipped bit, a damaged
    /// copy): a checksum or its digest does not match.
    #[error("record block '{path}' is corrupted: {message}; nothing was written: run its shard again with `{command}` (it overwrites only that shard), then merge again")]
    Corrupted {
        /// The file.
        path: PathBuf,
        /// Which check failed.
        message: String,
        /// The `ribbon run` command that writes the block again.
        command: String,
    },
    /// A record block of another plan lies among the shards.
    #[error("record block '{path}' belongs to another plan, or to another stage of this one (hash {found}; this plan or stage is {expected}); move it out of the directory, or merge it with its own plan")]
    Foreign {
        /// The file.
        path: PathBuf,
        /// Its plan hash.
        found: String,
        /// This plan's hash.
        expected: String,
    },
    /// Two record blocks hold the same samples.
    #[error("record blocks '{first}' and '{second}' both hold samples {start}..{end} (and the nominal run: {nominal}); remove the one of the other shard count")]
    Duplicated {
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
        /// First shared sample.
        start: usize,
        /// One past the last shared sample.
        end: usize,
        /// Whether both hold the nominal run.
        nominal: bool,
    },
    /// Samples (or the nominal run) that no record block holds.
    #[error("directory '{dir}': no record block holds {missing}; run the missing shards ({shards}) and merge again")]
    Missing {
        /// The directory merged.
        dir: PathBuf,
        /// The missing samples.
        missing: String,
        /// The commands or shard names that would make them.
        shards: String,
    },
    /// Not a failure of the input: the study needs another stage before it can write its outputs
    /// (exit status [`super::NEXT_STAGE_EXIT_CODE`]).
    #[error("stage {stage} is planned in '{plan}' and has no record blocks yet: run its shards ({command}), then merge again")]
    NextStage {
        /// The stage's number.
        stage: usize,
        /// Its stage plan.
        plan: PathBuf,
        /// The command that runs one of its shards.
        command: String,
    },
    /// Reading or writing a file failed.
    #[error("{what} '{path}': {source}")]
    Io {
        /// What was being done.
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

impl ShardError {
    /// The exit code: 2 when the input (plan, shards, flags) is at fault, 1 when writing failed,
    /// [`super::NEXT_STAGE_EXIT_CODE`] (3) when another stage must run first.
    pub fn exit_code(&self) -> u8 {
        match self {
            ShardError::Io { .. } => 1,
            ShardError::NextStage { .. } => super::NEXT_STAGE_EXIT_CODE,
            _ => 2,
        }
    }
}
