//! The MCAP sink (design contract "MCAP"): bound envelopes, error estimates, the nominal robot's
//! frames and its URDF in one file that Foxglove and rerun open as they are.
//!
//! What a file holds:
//! - per output, topic `/ribbon/envelope/<parts joined by '/'>` (see [`OutputName`]): ROS 2
//!   `sensor_msgs/msg/JointState` in CDR with `name = ["lower", "nominal", "upper"]` and the
//!   values in `position`; an error estimate on `/ribbon/error/…` with `name = ["estimate"]`;
//! - for a study whose check left some output untrusted, per output the hull of its true runs on
//!   `/ribbon/runs/…` with `name = ["runs_lower", "runs_upper"]` (docs/mcap.md §1);
//! - for surrogate studies, per output the main and total Sobol' indices on
//!   `/ribbon/sobol/main/…` and `/ribbon/sobol/total/…`, one JointState series per dimension of
//!   the box (`name` = the dimensions' names, docs/mcap.md §1);
//! - `/tf`: `foxglove.FrameTransforms` (protobuf), child frame = link name, parent = its parent
//!   link in the URDF tree (`world` for the root);
//! - `/robot_description`: the URDF text once at t = 0 as `std_msgs/msg/String`;
//! - a metadata record `ribbon` (see [`McapMetadata`]) and the URDF and sidecar as attachments;
//!   callers may add entries to that record and attachments ([`McapSink::add_metadata_entries`],
//!   [`McapSink::attach`]: the viewer facts and the Foxglove layout of docs/mcap.md §4);
//! - lz4-compressed chunks, message and chunk indexes, and the summary section.
//!
//! Every time stamp is simulation time from 0: log time = publish time = `header.stamp`, in
//! nanoseconds (rounded to the nearest).
//!
//! Crash safety: the bytes go to a unique temporary file beside `path`
//! (`<path>.ribbon-<pid>-<n>.tmp`, see [`crate::mcap_io::McapFileWriter`]), renamed to `path` by
//! [`McapSink::finish`] (only onto a regular file or nothing); a sink dropped without `finish` (an
//! error, a panic) removes its temporary file, so `path` never holds a half-written file. An interrupted study calls `finish(true)`: a complete, valid file of what was
//! computed, marked `partial = "true"`.
//!
//! Not done here: choosing what to log (the caller decides the outputs, times and frames), and
//! meshes (`package://` URIs in the URDF cannot be resolved by a viewer reading a file).

#![warn(missing_docs)]

pub(super) mod error;
mod foxglove;
mod name;
mod ros2;

pub use error::McapError;
pub use name::OutputName;

use crate::mcap_io::McapFileWriter;
use ::mcap::records::MessageHeader;
use ::mcap::{Compression, WriteOptions};
use std::collections::{BTreeMap, HashSet};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// Topic prefix of the envelope channels.
pub const ENVELOPE_PREFIX: &str = "/ribbon/envelope/";
/// Topic prefix of the error-estimate channels.
pub const ERROR_PREFIX: &str = "/ribbon/error/";
/// Topic prefix of the channels of the hull of true runs (an untrusted study's, docs/mcap.md §1).
pub const RUNS_PREFIX: &str = "/ribbon/runs/";
/// Topic prefix of the Sobol' index channels (then `main/` or `total/` and the output's parts).
pub const SOBOL_PREFIX: &str = "/ribbon/sobol/";
/// Topic of the nominal frames.
pub const TF_TOPIC: &str = "/tf";
/// Topic of the URDF text.
pub const ROBOT_DESCRIPTION_TOPIC: &str = "/robot_description";
/// Name of the metadata record.
pub const METADATA_NAME: &str = "ribbon";
/// Parent frame of the root link on `/tf`.
pub const WORLD_FRAME: &str = "world";
/// Keys of the `ribbon` metadata record that describe the study (set from [`McapMetadata`]).
const STUDY_METADATA_KEYS: [&str; 7] = [
    "robot",
    "method",
    "order",
    "runs",
    "ribbon_version",
    "partial",
    "parameters",
];
/// Series names of an envelope message, in `position` order.
pub const ENVELOPE_SERIES: [&str; 3] = ["lower", "nominal", "upper"];
/// Series name of an error-estimate message.
pub const ERROR_SERIES: [&str; 1] = ["estimate"];
/// Series names of a message of the hull of true runs, in `position` order (the summary's and the
/// CSV's names for them).
pub const RUNS_SERIES: [&str; 2] = ["runs_lower", "runs_upper"];

/// Uncompressed size at which a chunk is closed. The `mcap` crate's default (1 MiB): big enough for
/// lz4 to compress well, small enough that a reader seeking to a time decompresses little.
const CHUNK_SIZE_BYTES: u64 = 1024 * 1024;

/// Largest time the file holds: `header.stamp.sec` is an `int32`.
const MAX_TIME_S: f64 = i32::MAX as f64;

/// What the `ribbon` metadata record says about the study (MCAP metadata is string → string).
///
/// Written as the keys `robot`, `method`, `order` (the number, or `null`), `runs`,
/// `ribbon_version` (this crate's version), `partial` (`true` | `false`, given to
/// [`McapSink::finish`]) and `parameters`.
#[derive(Clone, Debug, PartialEq)]
pub struct McapMetadata {
    /// The robot's name (the URDF `<robot name>`).
    pub robot: String,
    /// The method, as in the summary JSON (`legendre-scan`, …, or `nominal` for `simulate`).
    pub method: String,
    /// Polynomial order; `None` where meaningless (written `null`).
    pub order: Option<usize>,
    /// Number of model runs (the summary's `samples`).
    pub runs: usize,
    /// The summary's `parameters` list as JSON text: `[{"name", "lower", "upper", "nominal"}, …]`.
    pub parameters_json: String,
}

/// One frame of the nominal robot at one time: the pose of link `link` in its parent frame
/// `parent` (the parent link of its URDF joint, or [`WORLD_FRAME`] for the root link), so that the
/// viewers' frame trees follow the kinematic chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParentFromLink<'a> {
    /// Parent frame name (a link name, or [`WORLD_FRAME`]).
    pub parent: &'a str,
    /// Link (frame) name; the child frame id on `/tf`.
    pub link: &'a str,
    /// The link origin in the parent frame, m.
    pub translation_m: [f64; 3],
    /// The link orientation in the parent frame, unit quaternion `[x, y, z, w]`.
    pub rotation_xyzw: [f64; 4],
}

/// Handle of an envelope channel, from [`McapSink::add_output`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EnvelopeChannel(usize);

/// Handle of an error-estimate channel, from [`McapSink::add_error_channel`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ErrorChannel(usize);

/// Handle of a channel of the hull of true runs, from [`McapSink::add_runs_channel`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RunsChannel(usize);

/// Handle of a Sobol' index channel, from [`McapSink::add_sobol_channel`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SobolChannel(usize);

/// Which Sobol' index a channel carries (docs/sobol-indices.md §1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SobolIndexKind {
    /// The main (first-order) index: the share of the variance from one dimension alone.
    Main,
    /// The total index: the share of the variance from every term involving a dimension.
    Total,
}

impl SobolIndexKind {
    /// `main` or `total`: the topic part and the channel metadata's `index`.
    pub fn name(self) -> &'static str {
        match self {
            SobolIndexKind::Main => "main",
            SobolIndexKind::Total => "total",
        }
    }
}

/// What a registered channel carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ChannelKind {
    Envelope,
    Error,
    Runs,
    Sobol,
    Tf,
    RobotDescription,
}

/// One registered channel.
#[derive(Debug)]
struct Channel {
    kind: ChannelKind,
    id: u16,
    topic: String,
    /// Sequence number of the next message.
    sequence: u32,
}

/// An MCAP file being written; see the [module docs](self).
///
/// ```no_run
/// use ribbon::output::mcap::{McapMetadata, McapSink, ParentFromLink};
/// # fn main() -> Result<(), ribbon::output::mcap::McapError> {
/// let metadata = McapMetadata {
///     robot: "double_pendulum".into(),
///     method: "legendre-scan".into(),
///     order: Some(4),
///     runs: 25,
///     parameters_json: r#"[{"name":"l1","lower":0.99,"upper":1.01,"nominal":1.0}]"#.into(),
/// };
/// let urdf = std::fs::read_to_string("robots/double_pendulum/double_pendulum.urdf").unwrap();
/// let mut sink = McapSink::create("out.mcap".as_ref(), "double_pendulum.urdf", &urdf, None, metadata)?;
/// let q1 = sink.add_output("q.j1", "rad")?;
/// sink.write_envelope(q1, 0.0, -0.01, 0.0, 0.01)?;
/// sink.write_transforms(0.0, &[ParentFromLink {
///     parent: "world",
///     link: "bar1",
///     translation_m: [0.0; 3],
///     rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
/// }])?;
/// sink.finish(false)?; // renames the temporary file to out.mcap
/// # Ok(()) }
/// ```
pub struct McapSink {
    /// The file being written: a temporary beside the final path until `finish` renames it.
    file: McapFileWriter<BufWriter<File>>,
    metadata: McapMetadata,
    /// Entries added to the `ribbon` record besides the study description.
    extra_metadata: BTreeMap<String, String>,
    joint_state_schema: u16,
    /// Every channel; handles index into it.
    channels: Vec<Channel>,
    /// The series names of every Sobol' channel: the box's dimensions, in order (set by the first
    /// [`add_sobol_channel`](McapSink::add_sobol_channel)).
    sobol_dimensions: Vec<String>,
    topics: HashSet<String>,
}

impl McapSink {
    /// Creates a unique temporary file beside `path` and writes the header, the schemas, the `/tf` and
    /// `/robot_description` channels, the URDF message at t = 0 and the attachments: the URDF
    /// (`urdf_name`, `application/xml`) and the sidecar if any (`(name, text)`,
    /// `application/toml`). `metadata` is written by [`finish`](Self::finish).
    pub fn create(
        path: &Path,
        urdf_name: &str,
        urdf_text: &str,
        sidecar: Option<(&str, &str)>,
        metadata: McapMetadata,
    ) -> Result<Self, McapError> {
        check_parameters(path, &metadata.parameters_json)?;
        let options = WriteOptions::new()
            .compression(Some(Compression::Lz4))
            .chunk_size(Some(CHUNK_SIZE_BYTES))
            .library(format!(
                "ribbon {} ({})",
                env!("CARGO_PKG_VERSION"),
                ::mcap::LIBRARY_IDENTIFIER
            ));
        // From here on a failure drops `sink`, whose file removes its temporary.
        let mut sink = Self {
            file: McapFileWriter::create(path, options, |buffered| buffered)?,
            metadata,
            extra_metadata: BTreeMap::new(),
            joint_state_schema: 0,
            channels: Vec::new(),
            sobol_dimensions: Vec::new(),
            topics: HashSet::new(),
        };
        sink.joint_state_schema = sink.add_schema(
            ros2::JOINT_STATE_NAME,
            "ros2msg",
            ros2::JOINT_STATE_DEFINITION.as_bytes(),
        )?;
        let string_schema = sink.add_schema(
            ros2::STRING_NAME,
            "ros2msg",
            ros2::STRING_DEFINITION.as_bytes(),
        )?;
        let tf_schema = sink.add_schema(
            foxglove::FRAME_TRANSFORMS_NAME,
            "protobuf",
            &foxglove::frame_transforms_descriptor_set(),
        )?;
        sink.add_channel(
            ChannelKind::Tf,
            tf_schema,
            TF_TOPIC,
            "protobuf",
            BTreeMap::new(),
        )?;
        let description = sink.add_channel(
            ChannelKind::RobotDescription,
            string_schema,
            ROBOT_DESCRIPTION_TOPIC,
            "cdr",
            BTreeMap::new(),
        )?;
        let payload = sink.cdr(
            &ros2::RosString { data: urdf_text },
            "std_msgs/msg/String on /robot_description",
        )?;
        sink.write_message(description, 0, &payload)?;

        let mut attachments = vec![(urdf_name, urdf_text, "application/xml")];
        if let Some((name, text)) = sidecar {
            attachments.push((name, text, "application/toml"));
        }
        for (name, text, media_type) in attachments {
            sink.attach(name, media_type, text.as_bytes())?;
        }
        Ok(sink)
    }

    /// The final path (where [`finish`](Self::finish) puts the file).
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// The temporary path the bytes go to until [`finish`](Self::finish).
    pub fn temporary_path(&self) -> &Path {
        self.file.temporary_path()
    }

    /// The study description written by [`finish`](Self::finish); change it before then when a
    /// value is known only at the end (e.g. `runs` of a study stopped early).
    pub fn metadata_mut(&mut self) -> &mut McapMetadata {
        &mut self.metadata
    }

    /// Registers an output: topic `/ribbon/envelope/<parts joined by '/'>`, messages
    /// `sensor_msgs/msg/JointState` with names `lower`, `nominal`, `upper`. A `&str` splits at
    /// every dot (`"q.elbow_joint"` → `/ribbon/envelope/q/elbow_joint`); see [`OutputName`] for
    /// names with dots inside. The channel's metadata holds the output name as `output`, its
    /// `unit` (`rad`, `m`, `N·m`, …, empty when unitless) and the viewer tab it belongs to as
    /// `group` (see [`crate::output::viewer::view_group`]).
    pub fn add_output(
        &mut self,
        name: impl Into<OutputName>,
        unit: &str,
    ) -> Result<EnvelopeChannel, McapError> {
        self.add_joint_state_channel(ChannelKind::Envelope, ENVELOPE_PREFIX, &name.into(), unit)
            .map(EnvelopeChannel)
    }

    /// Registers an output's error-estimate channel: topic `/ribbon/error/<parts joined by '/'>`,
    /// `sensor_msgs/msg/JointState` with the one name `estimate` (in `unit`, the output's), channel
    /// metadata as for [`add_output`](Self::add_output).
    pub fn add_error_channel(
        &mut self,
        name: impl Into<OutputName>,
        unit: &str,
    ) -> Result<ErrorChannel, McapError> {
        self.add_joint_state_channel(ChannelKind::Error, ERROR_PREFIX, &name.into(), unit)
            .map(ErrorChannel)
    }

    /// Registers the channel of an output's hull of true runs (docs/mcap.md §1): topic
    /// `/ribbon/runs/<parts joined by '/'>`, `sensor_msgs/msg/JointState` with the names
    /// `runs_lower`, `runs_upper` (in `unit`, the output's), channel metadata as for
    /// [`add_output`](Self::add_output).
    pub fn add_runs_channel(
        &mut self,
        name: impl Into<OutputName>,
        unit: &str,
    ) -> Result<RunsChannel, McapError> {
        self.add_joint_state_channel(ChannelKind::Runs, RUNS_PREFIX, &name.into(), unit)
            .map(RunsChannel)
    }

    /// Writes one output's hull of true runs, `lowest` and `highest`, at simulation time `time_s`
    /// (s from 0).
    pub fn write_runs(
        &mut self,
        channel: RunsChannel,
        time_s: f64,
        lowest: f64,
        highest: f64,
    ) -> Result<(), McapError> {
        self.check_handle(channel.0, ChannelKind::Runs)?;
        self.write_joint_state(channel.0, time_s, &RUNS_SERIES, &[lowest, highest])
    }

    /// Registers an output's Sobol' index channel (docs/mcap.md §1): topic
    /// `/ribbon/sobol/{main|total}/<parts joined by '/'>`, `sensor_msgs/msg/JointState` with one
    /// name per dimension of the box (`dimensions`, the same for every Sobol' channel of the
    /// file), unitless. The channel metadata holds `output`, `unit` (empty), `group` as for
    /// [`add_output`](Self::add_output), and `index` (`main` or `total`).
    ///
    /// Errors: as [`add_output`](Self::add_output); `dimensions` differing from an earlier Sobol'
    /// channel's ([`McapError::SobolLength`]).
    pub fn add_sobol_channel(
        &mut self,
        kind: SobolIndexKind,
        name: impl Into<OutputName>,
        dimensions: &[String],
    ) -> Result<SobolChannel, McapError> {
        let name = name.into();
        let prefix = format!("{SOBOL_PREFIX}{}/", kind.name());
        if self.sobol_dimensions.is_empty() {
            self.sobol_dimensions = dimensions.to_vec();
        } else if self.sobol_dimensions != dimensions {
            return Err(McapError::SobolLength {
                path: self.path().to_path_buf(),
                topic: format!("{prefix}{}", name.topic_suffix()),
                expected: self.sobol_dimensions.len(),
                got: dimensions.len(),
            });
        }
        let index = self.add_joint_state_channel_with(
            ChannelKind::Sobol,
            &prefix,
            &name,
            "",
            Some(("index", kind.name())),
        )?;
        Ok(SobolChannel(index))
    }

    /// Writes one output's Sobol' indices (one per dimension, in the channel's order) at
    /// simulation time `time_s` (s from 0).
    pub fn write_sobol(
        &mut self,
        channel: SobolChannel,
        time_s: f64,
        indices: &[f64],
    ) -> Result<(), McapError> {
        self.check_handle(channel.0, ChannelKind::Sobol)?;
        if indices.len() != self.sobol_dimensions.len() {
            return Err(McapError::SobolLength {
                path: self.path().to_path_buf(),
                topic: self.channels[channel.0].topic.clone(),
                expected: self.sobol_dimensions.len(),
                got: indices.len(),
            });
        }
        let names = std::mem::take(&mut self.sobol_dimensions);
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let result = self.write_joint_state(channel.0, time_s, &refs, indices);
        drop(refs);
        self.sobol_dimensions = names;
        result
    }

    /// Writes one envelope sample at simulation time `time_s` (s from 0).
    pub fn write_envelope(
        &mut self,
        channel: EnvelopeChannel,
        time_s: f64,
        lower: f64,
        nominal: f64,
        upper: f64,
    ) -> Result<(), McapError> {
        self.check_handle(channel.0, ChannelKind::Envelope)?;
        self.write_joint_state(
            channel.0,
            time_s,
            &ENVELOPE_SERIES,
            &[lower, nominal, upper],
        )
    }

    /// Writes one error estimate at simulation time `time_s` (s from 0).
    pub fn write_error(
        &mut self,
        channel: ErrorChannel,
        time_s: f64,
        estimate: f64,
    ) -> Result<(), McapError> {
        self.check_handle(channel.0, ChannelKind::Error)?;
        self.write_joint_state(channel.0, time_s, &ERROR_SERIES, &[estimate])
    }

    /// Writes the nominal robot's frames at simulation time `time_s` on `/tf`: one
    /// `foxglove.FrameTransform` per entry (parent, child the link), time stamp `time_s`.
    pub fn write_transforms(
        &mut self,
        time_s: f64,
        frames: &[ParentFromLink<'_>],
    ) -> Result<(), McapError> {
        let nanos = self.nanos(time_s, TF_TOPIC)?;
        let timestamp = foxglove::Timestamp {
            seconds: (nanos / 1_000_000_000) as i64,
            nanos: (nanos % 1_000_000_000) as i32,
        };
        let message = foxglove::FrameTransforms {
            transforms: frames
                .iter()
                .map(|frame| foxglove::FrameTransform {
                    timestamp: Some(timestamp),
                    parent_frame_id: frame.parent.to_string(),
                    child_frame_id: frame.link.to_string(),
                    translation: Some(foxglove::Vector3 {
                        x: frame.translation_m[0],
                        y: frame.translation_m[1],
                        z: frame.translation_m[2],
                    }),
                    rotation: Some(foxglove::Quaternion {
                        x: frame.rotation_xyzw[0],
                        y: frame.rotation_xyzw[1],
                        z: frame.rotation_xyzw[2],
                        w: frame.rotation_xyzw[3],
                    }),
                })
                .collect(),
        };
        let payload = prost::Message::encode_to_vec(&message);
        let tf = self.channels.iter().position(|c| c.kind == ChannelKind::Tf);
        self.write_message(tf.expect("`create` adds /tf"), nanos, &payload)
    }

    /// Attaches a file (`name`, IANA `media_type`, its bytes) at log time 0, e.g. the Foxglove
    /// layout of docs/mcap.md §4.
    pub fn attach(&mut self, name: &str, media_type: &str, data: &[u8]) -> Result<(), McapError> {
        Ok(self.file.attach(name, media_type, data)?)
    }

    /// Adds entries to the `ribbon` metadata record written by [`finish`](Self::finish) (e.g. the
    /// viewer facts of docs/mcap.md §4: `scene_centre_m`, `scene_radius_m`). A key of the study
    /// description (`robot`, `method`, `order`, `runs`, `ribbon_version`, `partial`, `parameters`)
    /// is refused ([`McapError::ReservedMetadataName`]); a key given twice keeps the last value.
    pub fn add_metadata_entries(
        &mut self,
        entries: BTreeMap<String, String>,
    ) -> Result<(), McapError> {
        if let Some(key) = entries
            .keys()
            .find(|k| STUDY_METADATA_KEYS.contains(&k.as_str()))
        {
            return Err(McapError::ReservedMetadataName {
                path: self.path().to_path_buf(),
                name: key.clone(),
            });
        }
        self.extra_metadata.extend(entries);
        Ok(())
    }

    /// Completes the file: the `ribbon` metadata record with `partial` = `"true"` or `"false"`,
    /// the last chunk, the indexes and the summary; then syncs it and renames the temporary file to
    /// `path` (replacing a regular file there, never a symlink, directory or special file). On
    /// error the temporary file is removed.
    ///
    /// `partial = true` is for a study stopped early (SIGINT, SIGTERM): the file is complete and
    /// valid, holding the envelopes written so far.
    pub fn finish(self, partial: bool) -> Result<(), McapError> {
        check_parameters(self.path(), &self.metadata.parameters_json)?;
        let m = &self.metadata;
        let mut entries = self.extra_metadata;
        entries.extend([
            ("robot".to_string(), m.robot.clone()),
            ("method".to_string(), m.method.clone()),
            (
                "order".to_string(),
                m.order
                    .map_or_else(|| "null".to_string(), |k| k.to_string()),
            ),
            ("runs".to_string(), m.runs.to_string()),
            (
                "ribbon_version".to_string(),
                env!("CARGO_PKG_VERSION").to_string(),
            ),
            ("partial".to_string(), partial.to_string()),
            ("parameters".to_string(), m.parameters_json.clone()),
        ]);
        let mut file = self.file;
        file.write_metadata(METADATA_NAME, entries)?;
        Ok(file.finish()?)
    }

    // ---- helpers ----

    fn cdr<T: serde::Serialize>(&self, message: &T, what: &str) -> Result<Vec<u8>, McapError> {
        ros2::encode(message).map_err(|source| McapError::Cdr {
            path: self.path().to_path_buf(),
            what: what.to_string(),
            source,
        })
    }

    fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> Result<u16, McapError> {
        Ok(self.file.add_schema(name, encoding, data)?)
    }

    /// Adds a channel; returns its index in `channels`.
    fn add_channel(
        &mut self,
        kind: ChannelKind,
        schema: u16,
        topic: &str,
        encoding: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<usize, McapError> {
        if !self.topics.insert(topic.to_string()) {
            return Err(McapError::DuplicateTopic {
                path: self.path().to_path_buf(),
                topic: topic.to_string(),
            });
        }
        let id = self.file.add_channel(schema, topic, encoding, &metadata)?;
        self.channels.push(Channel {
            kind,
            id,
            topic: topic.to_string(),
            sequence: 0,
        });
        Ok(self.channels.len() - 1)
    }

    fn add_joint_state_channel(
        &mut self,
        kind: ChannelKind,
        prefix: &str,
        name: &OutputName,
        unit: &str,
    ) -> Result<usize, McapError> {
        self.add_joint_state_channel_with(kind, prefix, name, unit, None)
    }

    /// [`add_joint_state_channel`](Self::add_joint_state_channel) with one more metadata entry.
    fn add_joint_state_channel_with(
        &mut self,
        kind: ChannelKind,
        prefix: &str,
        name: &OutputName,
        unit: &str,
        extra: Option<(&str, &str)>,
    ) -> Result<usize, McapError> {
        if name.has_empty_part() {
            return Err(McapError::BadOutputName {
                path: self.path().to_path_buf(),
                name: name.name(),
            });
        }
        let topic = format!("{prefix}{}", name.topic_suffix());
        let mut metadata = BTreeMap::from([
            ("output".to_string(), name.name()),
            ("unit".to_string(), unit.to_string()),
            (
                "group".to_string(),
                crate::output::viewer::view_group(name.parts()).title,
            ),
        ]);
        if let Some((key, value)) = extra {
            metadata.insert(key.to_string(), value.to_string());
        }
        self.add_channel(kind, self.joint_state_schema, &topic, "cdr", metadata)
    }

    /// A handle must index a channel of its kind (one from another sink may not).
    fn check_handle(&self, index: usize, kind: ChannelKind) -> Result<(), McapError> {
        match self.channels.get(index) {
            Some(channel) if channel.kind == kind => Ok(()),
            _ => Err(McapError::UnknownChannel {
                path: self.path().to_path_buf(),
                index,
            }),
        }
    }

    /// Simulation time, s → nanoseconds from 0, rounded to the nearest.
    fn nanos(&self, time_s: f64, topic: &str) -> Result<u64, McapError> {
        if !(time_s.is_finite() && (0.0..MAX_TIME_S).contains(&time_s)) {
            return Err(McapError::BadTime {
                path: self.path().to_path_buf(),
                topic: topic.to_string(),
                time_s,
            });
        }
        Ok((time_s * 1e9).round() as u64)
    }

    fn write_joint_state(
        &mut self,
        channel: usize,
        time_s: f64,
        names: &[&str],
        values: &[f64],
    ) -> Result<(), McapError> {
        let topic = &self.channels[channel].topic;
        let nanos = self.nanos(time_s, topic)?;
        let stamp = ros2::Time::from_nanos(nanos).ok_or_else(|| McapError::BadTime {
            path: self.path().to_path_buf(),
            topic: topic.clone(),
            time_s,
        })?;
        let message = ros2::JointState {
            header: ros2::Header {
                stamp,
                frame_id: "",
            },
            name: names,
            position: values,
            velocity: &[],
            effort: &[],
        };
        let payload = self.cdr(&message, &format!("sensor_msgs/msg/JointState on {topic}"))?;
        self.write_message(channel, nanos, &payload)
    }

    /// Writes one message on `channels[channel]` with log time = publish time = `nanos`.
    fn write_message(
        &mut self,
        channel: usize,
        nanos: u64,
        payload: &[u8],
    ) -> Result<(), McapError> {
        let entry = &mut self.channels[channel];
        let header = MessageHeader {
            channel_id: entry.id,
            sequence: entry.sequence,
            log_time: nanos,
            publish_time: nanos,
        };
        entry.sequence = entry.sequence.wrapping_add(1);
        Ok(self.file.write_message(&header, payload)?)
    }
}

/// `parameters_json` must be a JSON array (the summary's `parameters` list).
fn check_parameters(path: &Path, parameters_json: &str) -> Result<(), McapError> {
    let message = match serde_json::from_str::<serde_json::Value>(parameters_json) {
        Ok(serde_json::Value::Array(_)) => return Ok(()),
        Ok(other) => format!("found {other}"),
        Err(e) => e.to_string(),
    };
    Err(McapError::BadParameters {
        path: path.to_path_buf(),
        message,
    })
}

impl std::fmt::Debug for McapSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapSink")
            .field("file", &self.file)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}
