//! The one error type of the MCAP sink: every variant names the output file and what failed.

use crate::mcap_io::McapWriteError;
use std::path::PathBuf;

/// Why writing an MCAP file failed. `path` is always the final output path the caller asked for
/// (the bytes go to a temporary file beside it until [`McapSink::finish`](super::McapSink::finish) renames it).
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// A file-system operation failed (creating, syncing, renaming or removing the file).
    #[error("{}: cannot {what}: {source}", .path.display())]
    Io {
        /// The output file.
        path: PathBuf,
        /// What was being done, e.g. "create a temporary file beside /tmp/a.mcap".
        what: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The `mcap` crate's writer refused a record or failed to write it.
    #[error("{}: cannot {what}: {source}", .path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// What was being written, e.g. "write a message on /tf".
        what: String,
        /// The underlying error.
        #[source]
        source: ::mcap::McapError,
    },
    /// A ROS 2 message could not be serialized as CDR.
    #[error("{}: cannot encode {what} as CDR: {source}", .path.display())]
    Cdr {
        /// The output file.
        path: PathBuf,
        /// Which message, e.g. "sensor_msgs/msg/JointState on /ribbon/envelope/q/j1".
        what: String,
        /// The underlying error.
        #[source]
        source: cdr::Error,
    },
    /// A time stamp is not a simulation time the file can hold.
    #[error(
        "{}: time {time_s} s on {topic} is not a finite simulation time in [0, 2^31) s",
        .path.display()
    )]
    BadTime {
        /// The output file.
        path: PathBuf,
        /// The topic the message was for.
        topic: String,
        /// The rejected time, s.
        time_s: f64,
    },
    /// An output name has an empty part (`""`, `"q."`, `"q..x"`).
    #[error("{}: output name {name:?} has an empty part", .path.display())]
    BadOutputName {
        /// The output file.
        path: PathBuf,
        /// The rejected name (its parts joined with dots).
        name: String,
    },
    /// Two outputs map to the same topic.
    #[error("{}: topic {topic} is registered twice", .path.display())]
    DuplicateTopic {
        /// The output file.
        path: PathBuf,
        /// The topic.
        topic: String,
    },
    /// A caller's metadata entry would replace a key of the study description.
    #[error("{}: the metadata key '{name}' is reserved for the study description of the `ribbon` record; choose another key", .path.display())]
    ReservedMetadataName {
        /// The output file.
        path: PathBuf,
        /// The key asked for.
        name: String,
    },
    /// A channel handle from another sink (its index is out of range here).
    #[error("{}: channel handle #{index} does not belong to this file", .path.display())]
    UnknownChannel {
        /// The output file.
        path: PathBuf,
        /// The handle's index.
        index: usize,
    },
    /// `McapMetadata::parameters_json` is not a JSON array.
    #[error("{}: metadata `parameters` must be a JSON array: {message}", .path.display())]
    BadParameters {
        /// The output file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A Sobol' message whose values do not match the channel's dimensions.
    #[error("{}: {topic}: {got} Sobol' indices for {expected} dimensions", .path.display())]
    SobolLength {
        /// The output file.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// Dimensions the channel names.
        expected: usize,
        /// Values given.
        got: usize,
    },
}

impl From<McapWriteError> for McapError {
    /// The MCAP layer's failures keep their text: the file, the step and the cause.
    fn from(error: McapWriteError) -> McapError {
        match error {
            McapWriteError::Io { path, what, source } => McapError::Io { path, what, source },
            McapWriteError::Mcap { path, what, source } => McapError::Write { path, what, source },
        }
    }
}
