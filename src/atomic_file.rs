//! The atomic file writer's ground floor: a temporary file beside its target that is renamed onto
//! it when complete ([`TemporaryFile`]), never through a symbolic link or onto a special file, and
//! the registry of live temporaries that the signal path empties ([`remove_live_temporaries`]).
//! Used by every writer of a file that must never be left half-written: `output`'s files and
//! `distributed`'s record blocks. Which paths may be written at all is `output::paths`'s.
//!
//! - the bytes go to a temporary file beside the target whose name holds the process id and a
//!   counter (`out.csv.ribbon-4711-0.tmp`), created with `create_new` so that two runs never share
//!   one; it is synced by its writer, then renamed onto the target only if the target is a
//!   regular file or does not exist (checked again just before the rename);
//! - every live temporary is in a registry; a temporary is removed when its writer is dropped
//!   unfinished (an error, an interruption) and by the signal path when a second SIGINT/SIGTERM
//!   ends the process at once ([`crate::interrupt`]). Only `kill -9` can leave one behind — and
//!   then the target still holds its previous contents.

use std::ffi::OsString;
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Temporaries currently on disk, removed by [`remove_live_temporaries`].
static LIVE_TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Distinguishes the temporaries of one process (with the process id, unique on the machine).
static TEMPORARY_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Attempts at a fresh temporary name before giving up (a name is only taken by a leftover of a
/// `kill -9`ed run with the same process id).
const TEMPORARY_NAME_ATTEMPTS: usize = 100;

/// The registry, usable even if a thread panicked while holding it (it is a plain list).
fn live() -> MutexGuard<'static, Vec<PathBuf>> {
    LIVE_TEMPORARIES
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes every temporary file this process still has on disk and returns how many it removed.
/// Called by the signal path before the process ends at once ([`crate::interrupt`]); targets are
/// never touched.
pub fn remove_live_temporaries() -> usize {
    let mut live = live();
    let removed = live
        .drain(..)
        .filter(|path| std::fs::remove_file(path).is_ok())
        .count();
    removed
}

/// A temporary file beside its target, in the registry until [`commit`](Self::commit) renames it
/// onto the target; dropped uncommitted, it removes itself.
#[derive(Debug)]
pub struct TemporaryFile {
    path: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl TemporaryFile {
    /// Creates a new, empty temporary file beside `target` (`<target>.ribbon-<pid>-<n>.tmp`, created
    /// with `create_new`, so never shared with another run) and registers it.
    pub fn create_beside(target: &Path) -> std::io::Result<(File, TemporaryFile)> {
        let file_name = target.file_name().ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "the path names no file (it ends in '..' or '/')",
            )
        })?;
        let mut last_error = None;
        for _ in 0..TEMPORARY_NAME_ATTEMPTS {
            let counter = TEMPORARY_COUNTER.fetch_add(1, Ordering::Relaxed);
            let mut name = OsString::from(file_name);
            name.push(format!(".ribbon-{}-{counter}.tmp", std::process::id()));
            let path = target.with_file_name(name);
            // Registered before it exists, so that the signal path cannot miss it.
            live().push(path.clone());
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok((
                        file,
                        TemporaryFile {
                            path,
                            target: target.to_path_buf(),
                            committed: false,
                        },
                    ))
                }
                Err(error) => {
                    unregister(&path);
                    if error.kind() != std::io::ErrorKind::AlreadyExists {
                        return Err(error);
                    }
                    last_error = Some(error);
                }
            }
        }
        Err(last_error.unwrap_or_else(|| std::io::Error::other("no free temporary name")))
    }

    /// The temporary file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the (already written and synced) temporary onto its target: only when the target
    /// is a regular file or does not exist — never onto a symlink, directory or special file that
    /// appeared since the outputs were checked. Holds the registry while renaming, so that the
    /// signal path sees either the temporary or the finished target.
    pub fn commit(mut self) -> std::io::Result<()> {
        let mut live = live();
        if let Some(kind) = non_regular_kind(&self.target)? {
            return Err(std::io::Error::other(format!(
                "'{}' has become {kind} since the outputs were checked; not replaced",
                self.target.display()
            )));
        }
        std::fs::rename(&self.path, &self.target)?;
        live.retain(|p| p != &self.path);
        drop(live);
        self.committed = true;
        // Make the rename itself durable (best effort: not every file system syncs directories).
        if let Some(parent) = parent_directory(&self.target) {
            if let Ok(directory) = File::open(parent) {
                let _ = directory.sync_all();
            }
        }
        Ok(())
    }
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.path);
            unregister(&self.path);
        }
    }
}

fn unregister(path: &Path) {
    live().retain(|p| p != path);
}

/// What kind of non-regular file `path` is (`"a directory"`, `"a symbolic link"`, …), `None` for
/// a regular file or nothing there. Does not follow a final symlink.
pub(crate) fn non_regular_kind(path: &Path) -> std::io::Result<Option<&'static str>> {
    match std::fs::symlink_metadata(path) {
        Ok(metadata) => Ok(describe_non_regular(&metadata.file_type())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// What kind of non-regular file a file type is, `None` for a regular file.
pub(crate) fn describe_non_regular(file_type: &std::fs::FileType) -> Option<&'static str> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if file_type.is_socket() {
            return Some("a socket");
        }
        if file_type.is_char_device() {
            return Some("a character device");
        }
        if file_type.is_block_device() {
            return Some("a block device");
        }
    }
    if file_type.is_symlink() {
        Some("a symbolic link")
    } else if file_type.is_dir() {
        Some("a directory")
    } else if file_type.is_file() {
        None
    } else {
        Some("a special file")
    }
}

/// The directory a relative or absolute file path lives in (`.` for a bare name).
pub(crate) fn parent_directory(path: &Path) -> Option<&Path> {
    match path.parent() {
        Some(parent) if parent.as_os_str().is_empty() => Some(Path::new(".")),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_are_unique_registered_and_removed_when_dropped() {
        let dir = std::env::temp_dir().join(format!("ribbon-atomic-{}-unique", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("out.csv");
        let (_, a) = TemporaryFile::create_beside(&target).unwrap();
        let (_, b) = TemporaryFile::create_beside(&target).unwrap();
        assert_ne!(a.path(), b.path());
        assert!(a.path().exists() && b.path().exists());
        assert!(live().contains(&a.path().to_path_buf()));
        drop(a);
        drop(b);
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
