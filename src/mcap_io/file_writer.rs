//! One MCAP file written whole ([`McapFileWriter`]): the `mcap` crate's writer over a temporary
//! file beside the target ([`crate::atomic_file::TemporaryFile`]), schemas, channels, messages,
//! metadata and attachments in the order the caller gives them, then the summary, a sync and the
//! rename onto the target. Dropped unfinished (an error, a panic), it removes its temporary file,
//! so the target never holds a half-written file.
//!
//! Every failure is a [`McapWriteError`] naming the target file and the step that failed
//! ("add the channel /tf", "write a message on /records", "sync …"); the envelope log and the
//! record blocks turn it into their own error with that text unchanged.
//!
//! The bytes are exactly the `mcap` crate's for the same calls: this layer adds no record and
//! reorders none.

use crate::atomic_file::TemporaryFile;
use ::mcap::records::{MessageHeader, Metadata};
use ::mcap::{Attachment, WriteOptions, Writer};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

/// The stream an MCAP file is written through: the temporary file's buffer, or a writer around it
/// (the record blocks hash every byte on its way, `distributed::integrity`).
pub trait FileStream: Write + Seek {
    /// The buffered temporary file underneath, to flush, sync and rename.
    fn into_buffered_file(self) -> BufWriter<File>;
}

impl FileStream for BufWriter<File> {
    fn into_buffered_file(self) -> BufWriter<File> {
        self
    }
}

/// Why writing an MCAP file failed: the target file, the step, and the cause.
#[derive(Debug, thiserror::Error)]
pub enum McapWriteError {
    /// A file-system operation failed (creating, flushing, syncing or renaming the file).
    #[error("{}: cannot {what}: {source}", .path.display())]
    Io {
        /// The target file.
        path: PathBuf,
        /// The step, e.g. "create a temporary file beside /tmp/a.mcap".
        what: String,
        /// The operating system's reason.
        #[source]
        source: io::Error,
    },
    /// The `mcap` crate's writer refused a record or failed to write it.
    #[error("{}: cannot {what}: {source}", .path.display())]
    Mcap {
        /// The target file.
        path: PathBuf,
        /// The step, e.g. "write a message on /tf".
        what: String,
        /// The `mcap` crate's reason.
        #[source]
        source: ::mcap::McapError,
    },
}

impl McapWriteError {
    /// The cause as an I/O error (an `mcap` crate error becomes one with its text), for callers
    /// whose error names one step for the whole file.
    pub fn into_io_error(self) -> io::Error {
        match self {
            McapWriteError::Io { source, .. } => source,
            McapWriteError::Mcap { source, .. } => io::Error::other(source.to_string()),
        }
    }
}

/// An MCAP file being written through a temporary file beside its target, renamed onto it by
/// [`finish`](Self::finish); dropped unfinished, it removes the temporary (see [`crate::mcap_io`]).
pub struct McapFileWriter<S: FileStream> {
    /// The target path.
    path: PathBuf,
    /// The temporary file; `None` once renamed onto `path`.
    temporary: Option<TemporaryFile>,
    /// Its path (kept for messages).
    temporary_path: PathBuf,
    /// `None` once finished or dropped.
    writer: Option<Writer<S>>,
    /// Every channel's topic, by channel id (for messages).
    topics: BTreeMap<u16, String>,
}

impl<S: FileStream> McapFileWriter<S> {
    /// Creates a unique temporary file beside `path` and writes the MCAP magic and header with
    /// `options`, through the stream `stream` makes of the buffered file.
    pub fn create(
        path: &Path,
        options: WriteOptions,
        stream: impl FnOnce(BufWriter<File>) -> S,
    ) -> Result<Self, McapWriteError> {
        let (file, temporary) =
            TemporaryFile::create_beside(path).map_err(|source| McapWriteError::Io {
                path: path.to_path_buf(),
                what: format!("create a temporary file beside {}", path.display()),
                source,
            })?;
        let mut file_writer = McapFileWriter {
            path: path.to_path_buf(),
            temporary_path: temporary.path().to_path_buf(),
            temporary: Some(temporary),
            writer: None,
            topics: BTreeMap::new(),
        };
        // From here on a failure drops `file_writer`, which removes the temporary file.
        let writer = Writer::with_options(stream(BufWriter::new(file)), options);
        file_writer.writer =
            Some(writer.map_err(|source| file_writer.mcap_error("write the MCAP header", source))?);
        Ok(file_writer)
    }

    /// The target path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary path the bytes go to until [`finish`](Self::finish).
    pub fn temporary_path(&self) -> &Path {
        &self.temporary_path
    }

    /// Adds a schema; returns its id.
    pub fn add_schema(
        &mut self,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<u16, McapWriteError> {
        let result = self.writer_mut().add_schema(name, encoding, data);
        result.map_err(|source| self.mcap_error(&format!("add the schema {name}"), source))
    }

    /// Adds a channel on `topic` (schema id 0: none); returns its id.
    pub fn add_channel(
        &mut self,
        schema: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<u16, McapWriteError> {
        let result = self
            .writer_mut()
            .add_channel(schema, topic, encoding, metadata);
        let id = result
            .map_err(|source| self.mcap_error(&format!("add the channel {topic}"), source))?;
        self.topics.insert(id, topic.to_string());
        Ok(id)
    }

    /// Writes one message on a channel this writer added.
    pub fn write_message(
        &mut self,
        header: &MessageHeader,
        payload: &[u8],
    ) -> Result<(), McapWriteError> {
        let result = self.writer_mut().write_to_known_channel(header, payload);
        result.map_err(|source| {
            let topic = self
                .topics
                .get(&header.channel_id)
                .map_or("", String::as_str);
            self.mcap_error(&format!("write a message on {topic}"), source)
        })
    }

    /// Writes the metadata record `name` with `entries`.
    pub fn write_metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), McapWriteError> {
        let record = Metadata {
            name: name.to_string(),
            metadata: entries,
        };
        let result = self.writer_mut().write_metadata(&record);
        result.map_err(|source| {
            self.mcap_error(&format!("write the `{name}` metadata record"), source)
        })
    }

    /// Attaches a file (`name`, IANA `media_type`, its bytes) at log and create time 0.
    pub fn attach(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
    ) -> Result<(), McapWriteError> {
        let attachment = Attachment {
            log_time: 0,
            create_time: 0,
            name: name.to_string(),
            media_type: media_type.to_string(),
            data: Cow::Borrowed(data),
        };
        let result = self.writer_mut().attach(&attachment);
        result.map_err(|source| self.mcap_error(&format!("attach {name}"), source))
    }

    /// Completes the file: the summary section and footer, then flushes and syncs it and renames
    /// the temporary file onto the target (a regular file or nothing there, see
    /// [`TemporaryFile::commit`]). On error the temporary file is removed.
    pub fn finish(mut self) -> Result<(), McapWriteError> {
        let result = self.writer_mut().finish();
        result.map_err(|source| self.mcap_error("write the summary and footer", source))?;
        let writer = self
            .writer
            .take()
            .expect("a file writer holds its writer until finished");
        let file = writer
            .into_inner()
            .into_buffered_file()
            .into_inner()
            .map_err(|e| {
                self.io_error(
                    format!("flush {}", self.temporary_path.display()),
                    e.into_error(),
                )
            })?;
        file.sync_all().map_err(|source| {
            self.io_error(format!("sync {}", self.temporary_path.display()), source)
        })?;
        drop(file);
        if let Some(temporary) = self.temporary.take() {
            temporary.commit().map_err(|source| {
                let what = format!(
                    "rename {} to {}",
                    self.temporary_path.display(),
                    self.path.display()
                );
                self.io_error(what, source)
            })?;
        }
        Ok(())
    }

    fn writer_mut(&mut self) -> &mut Writer<S> {
        self.writer
            .as_mut()
            .expect("a file writer holds its writer until finished")
    }

    fn mcap_error(&self, what: &str, source: ::mcap::McapError) -> McapWriteError {
        McapWriteError::Mcap {
            path: self.path.clone(),
            what: what.to_string(),
            source,
        }
    }

    fn io_error(&self, what: String, source: io::Error) -> McapWriteError {
        McapWriteError::Io {
            path: self.path.clone(),
            what,
            source,
        }
    }
}

impl<S: FileStream> Drop for McapFileWriter<S> {
    /// An unfinished writer removes its temporary file: the target is never left half-written.
    fn drop(&mut self) {
        if let Some(writer) = self.writer.take() {
            // `into_inner` skips the summary that dropping a `Writer` would write.
            drop(writer.into_inner());
        }
        // An unfinished temporary removes itself when dropped (and leaves the registry).
        drop(self.temporary.take());
    }
}

impl<S: FileStream> std::fmt::Debug for McapFileWriter<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapFileWriter")
            .field("path", &self.path)
            .field("temporary", &self.temporary_path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("ribbon-mcap-io-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("mkdir");
        dir
    }

    fn unchunked() -> WriteOptions {
        WriteOptions::new().use_chunks(false).compression(None)
    }

    /// Files in `dir` (the target and any temporary left behind).
    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_finished_file_is_renamed_into_place_and_reads_back() {
        let dir = scratch("finished");
        let path = dir.join("a.mcap");
        let mut file = McapFileWriter::create(&path, unchunked(), |b| b).expect("create");
        assert_ne!(file.temporary_path(), path.as_path());
        let channel = file
            .add_channel(0, "/x", "raw", &BTreeMap::new())
            .expect("channel");
        for sequence in 0..3u32 {
            let header = MessageHeader {
                channel_id: channel,
                sequence,
                log_time: u64::from(sequence),
                publish_time: u64::from(sequence),
            };
            file.write_message(&header, &[sequence as u8; 4])
                .expect("message");
        }
        file.write_metadata("m", BTreeMap::from([("k".into(), "v".into())]))
            .expect("metadata");
        file.attach("a.txt", "text/plain", b"hello")
            .expect("attach");
        file.finish().expect("finish");
        assert_eq!(entries(&dir), ["a.mcap"]);
        let bytes = std::fs::read(&path).expect("read");
        let messages: Vec<Vec<u8>> = ::mcap::MessageStream::new(&bytes)
            .expect("stream")
            .map(|m| m.expect("message").data.into_owned())
            .collect();
        assert_eq!(messages, [[0u8; 4], [1; 4], [2; 4]]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_writer_dropped_unfinished_leaves_nothing() {
        let dir = scratch("dropped");
        let path = dir.join("b.mcap");
        let mut file = McapFileWriter::create(&path, unchunked(), |b| b).expect("create");
        file.add_channel(0, "/x", "raw", &BTreeMap::new())
            .expect("channel");
        assert_eq!(entries(&dir).len(), 1, "the temporary exists while writing");
        drop(file);
        assert!(entries(&dir).is_empty(), "{:?}", entries(&dir));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_refused_record_names_the_file_and_the_step() {
        let dir = scratch("refused");
        let path = dir.join("c.mcap");
        let mut file = McapFileWriter::create(&path, unchunked(), |b| b).expect("create");
        // Schema 7 was never added.
        let error = file
            .add_channel(7, "/y", "raw", &BTreeMap::new())
            .expect_err("unknown schema");
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("{}: cannot add the channel /y: ", path.display())),
            "{message}"
        );
        assert!(matches!(error, McapWriteError::Mcap { .. }));
        let error = McapFileWriter::create(&dir.join("no/such/dir/d.mcap"), unchunked(), |b| b)
            .expect_err("no directory");
        assert!(
            error
                .to_string()
                .contains("cannot create a temporary file beside"),
            "{error}"
        );
        assert_eq!(error.into_io_error().kind(), io::ErrorKind::NotFound);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
