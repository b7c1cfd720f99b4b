//! Output paths that never destroy anything: the one place where every output file of a command is
//! checked before any simulation ([`check_outputs`]) and written ([`AtomicFile`],
//! [`write_atomically`], [`TemporaryFile`]).
//!
//! The rules (README "Output safety"):
//! - an output is refused when it is one of the command's inputs (same canonical path, or the same
//!   device and inode: a hard link), a directory, a FIFO, a socket, a device, or a **symbolic link**
//!   (ribbon never writes through a link and never replaces one: pass the link's target instead);
//!   its parent directory must exist and accept a new file (proved by creating and removing a
//!   probe file there); no two outputs may be the same file, whatever the spelling (`a/../x`,
//!   `./x`, a symlinked directory);
//! - the bytes go to a temporary file beside the target whose name holds the process id and a
//!   counter (`out.csv.ribbon-4711-0.tmp`), created with `create_new` so that two runs never share
//!   one; it is synced, then renamed onto the target only if the target is a regular file or does
//!   not exist (checked again just before the rename);
//! - every live temporary is in a registry ([`remove_live_temporaries`]); a temporary is removed
//!   when its writer is dropped unfinished (an error, an interruption) and by the signal path when
//!   a second SIGINT/SIGTERM ends the process at once ([`crate::interrupt`]). Only `kill -9` can
//!   leave one behind — and then the target still holds its previous contents.
//!
//! Not done here: choosing file names (the commands do), and file contents (the writers do).

use super::error::OutputError;
use std::ffi::OsString;
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
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

/// An output file being written: a buffered writer on a [`TemporaryFile`], put in place by
/// [`commit`](Self::commit); dropped uncommitted, nothing changes at the target.
pub struct AtomicFile {
    writer: BufWriter<File>,
    temporary: TemporaryFile,
    what: String,
}

impl AtomicFile {
    /// Starts writing `target`; `what` names the output in messages ("CSV", "summary").
    pub fn create(target: &Path, what: &str) -> Result<AtomicFile, OutputError> {
        let what = format!("{what} '{}'", target.display());
        let (file, temporary) =
            TemporaryFile::create_beside(target).map_err(|source| OutputError::Write {
                what: what.clone(),
                source,
            })?;
        Ok(AtomicFile {
            writer: BufWriter::new(file),
            temporary,
            what,
        })
    }

    /// Flushes, syncs and renames the file into place.
    pub fn commit(self) -> Result<(), OutputError> {
        let AtomicFile {
            writer,
            temporary,
            what,
        } = self;
        let fail = |source| OutputError::Write {
            what: what.clone(),
            source,
        };
        let file = writer.into_inner().map_err(|e| fail(e.into_error()))?;
        file.sync_all().map_err(fail)?;
        drop(file);
        temporary.commit().map_err(fail)
    }

    /// The error for a failed write of this file.
    pub fn error(&self, source: std::io::Error) -> OutputError {
        OutputError::Write {
            what: self.what.clone(),
            source,
        }
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.writer.flush()
    }
}

/// Writes `bytes` to `path` through a unique temporary file, a sync and a rename.
pub fn write_atomically(path: &Path, what: &str, bytes: &[u8]) -> Result<(), OutputError> {
    let mut file = AtomicFile::create(path, what)?;
    file.write_all(bytes).map_err(|e| file.error(e))?;
    file.commit()
}

/// What kind of non-regular file `path` is (`"a directory"`, `"a symbolic link"`, …), `None` for
/// a regular file or nothing there. Does not follow a final symlink.
fn non_regular_kind(path: &Path) -> std::io::Result<Option<&'static str>> {
    match std::fs::symlink_metadata(path) {
        Ok(metadata) => Ok(describe_non_regular(&metadata.file_type())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

fn describe_non_regular(file_type: &std::fs::FileType) -> Option<&'static str> {
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
fn parent_directory(path: &Path) -> Option<&Path> {
    match path.parent() {
        Some(parent) if parent.as_os_str().is_empty() => Some(Path::new(".")),
        other => other,
    }
}

/// One file's identity: device and inode (unix), to catch hard links and other spellings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FileId(u64, u64);

fn file_id(metadata: &std::fs::Metadata) -> Option<FileId> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some(FileId(metadata.dev(), metadata.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = metadata;
        None
    }
}

/// An input file of a command: outputs may never be it.
#[derive(Debug)]
struct Input<'a> {
    role: &'a str,
    path: &'a Path,
    canonical: Option<PathBuf>,
    id: Option<FileId>,
}

/// A checked output: its canonical spelling (canonical parent + file name) and identity if it
/// exists.
struct Checked<'a> {
    flag: &'a str,
    path: &'a Path,
    canonical: PathBuf,
    id: Option<FileId>,
}

/// [`check_outputs`] of a command that reads `urdf` and, when given, a `sidecar`: its `outputs`
/// are `(flag, path)` pairs, `None` for a flag not given.
pub fn check_command_outputs(
    urdf: &Path,
    sidecar: Option<&Path>,
    outputs: &[(&str, Option<&Path>)],
) -> Result<(), OutputError> {
    let mut inputs = vec![("URDF", urdf)];
    if let Some(sidecar) = sidecar {
        inputs.push(("sidecar", sidecar));
    }
    let outputs: Vec<(&str, &Path)> = outputs
        .iter()
        .filter_map(|(flag, path)| path.map(|p| (*flag, p)))
        .collect();
    check_outputs(&inputs, &outputs)
}

/// Checks every output file of a command before any simulation: `inputs` are `(role, path)` pairs
/// (`("URDF", urdf)`, `("sidecar", sidecar)`), `outputs` are `(flag, path)` pairs (`("--csv",
/// csv)`). Refuses, naming the flag and what to do: an output that is an input, a directory, a
/// FIFO, socket or device, a symbolic link, a path without a file name, a parent that does not
/// exist or is not writable, and two outputs that are the same file. Exit code 2 (bad argument).
pub fn check_outputs(
    inputs: &[(&str, &Path)],
    outputs: &[(&str, &Path)],
) -> Result<(), OutputError> {
    let inputs: Vec<Input> = inputs
        .iter()
        .map(|(role, path)| Input {
            role,
            path,
            canonical: std::fs::canonicalize(path).ok(),
            id: std::fs::metadata(path).ok().as_ref().and_then(file_id),
        })
        .collect();
    let mut checked: Vec<Checked> = Vec::with_capacity(outputs.len());
    for (flag, path) in outputs {
        let output = check_one(flag, path, &inputs)?;
        if let Some(other) = checked
            .iter()
            .find(|c| c.canonical == output.canonical || (c.id.is_some() && c.id == output.id))
        {
            return Err(bad(
                flag,
                format!(
                    "'{}' is the same file as {} '{}'; give each output its own file",
                    path.display(),
                    other.flag,
                    other.path.display()
                ),
            ));
        }
        checked.push(output);
    }
    Ok(())
}

fn bad(flag: &str, message: String) -> OutputError {
    OutputError::BadPath {
        flag: flag.to_string(),
        message,
    }
}

fn check_one<'a>(
    flag: &'a str,
    path: &'a Path,
    inputs: &[Input],
) -> Result<Checked<'a>, OutputError> {
    let shown = path.display();
    let file_name = match path.file_name() {
        Some(name) if !path.as_os_str().to_string_lossy().ends_with('/') => name,
        _ => {
            return Err(bad(
                flag,
                format!(
                "'{shown}' names no file (it is empty or ends in '/' or '..'); give a file path"
            ),
            ))
        }
    };
    let metadata = match std::fs::symlink_metadata(path) {
        Ok(metadata) => Some(metadata),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(bad(flag, format!("cannot inspect '{shown}': {e}"))),
    };
    if let Some(metadata) = &metadata {
        let file_type = metadata.file_type();
        if file_type.is_symlink() {
            let target = std::fs::read_link(path)
                .map(|t| format!(" to '{}'", t.display()))
                .unwrap_or_default();
            return Err(bad(
                flag,
                format!(
                    "'{shown}' is a symbolic link{target}; ribbon replaces an output by renaming a new file onto it, which would replace the link, and never writes through links: give the target's path instead, or remove the link"
                ),
            ));
        }
        if file_type.is_dir() {
            return Err(bad(
                flag,
                format!("'{shown}' is a directory; give a file path (e.g. '{shown}/result')"),
            ));
        }
        if let Some(kind) = describe_non_regular(&file_type) {
            return Err(bad(
                flag,
                format!(
                    "'{shown}' is {kind}; ribbon writes outputs as regular files (a new file renamed into place), which would replace it: give a regular file path"
                ),
            ));
        }
    }
    let id = metadata.as_ref().and_then(file_id);
    let parent = parent_directory(path).unwrap_or(Path::new("."));
    let canonical_parent = match std::fs::canonicalize(parent) {
        Ok(p) if p.is_dir() => p,
        Ok(p) => return Err(bad(flag, format!("'{}' is not a directory", p.display()))),
        Err(e) => {
            return Err(bad(
                flag,
                format!(
                    "the directory '{}' of '{shown}' cannot be used ({e}); create it first",
                    parent.display()
                ),
            ))
        }
    };
    let canonical = canonical_parent.join(file_name);
    for input in inputs {
        let same_path = input.canonical.as_deref() == Some(canonical.as_path());
        let same_file = id.is_some() && input.id == id;
        if same_path || same_file {
            return Err(bad(
                flag,
                format!(
                    "'{shown}' is the {} input '{}'{}; writing the output there would replace it: choose another path",
                    input.role,
                    input.path.display(),
                    if same_path { "" } else { " (the same file under another name)" }
                ),
            ));
        }
    }
    // Prove that a new file can be created beside the target, as the writer will do.
    match TemporaryFile::create_beside(path) {
        Ok((file, probe)) => {
            drop(file);
            drop(probe);
        }
        Err(e) => {
            return Err(bad(
                flag,
                format!(
                    "cannot create a file in '{}' ({e}); choose a writable directory",
                    parent.display()
                ),
            ))
        }
    }
    Ok(Checked {
        flag,
        path,
        canonical,
        id,
    })
}

/// Prepares an output directory (`compare --report DIR`) before any simulation: creates it (with
/// its parents) when missing, refuses a path that exists and is not a directory, and checks that
/// each of `files` inside it is a valid output ([`check_outputs`] against `inputs`).
pub fn prepare_output_directory(
    flag: &str,
    directory: &Path,
    files: &[&str],
    inputs: &[(&str, &Path)],
) -> Result<(), OutputError> {
    match std::fs::metadata(directory) {
        Ok(metadata) if metadata.is_dir() => {}
        Ok(_) => {
            return Err(bad(
                flag,
                format!(
                    "'{}' exists and is not a directory; give a directory path",
                    directory.display()
                ),
            ))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            std::fs::create_dir_all(directory).map_err(|e| {
                bad(
                    flag,
                    format!("cannot create the directory '{}': {e}", directory.display()),
                )
            })?;
        }
        Err(e) => {
            return Err(bad(
                flag,
                format!("cannot inspect '{}': {e}", directory.display()),
            ))
        }
    }
    let paths: Vec<PathBuf> = files.iter().map(|f| directory.join(f)).collect();
    let outputs: Vec<(&str, &Path)> = paths.iter().map(|p| (flag, p.as_path())).collect();
    check_outputs(inputs, &outputs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ribbon-paths-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    }

    #[test]
    fn temporaries_are_unique_registered_and_removed_when_dropped() {
        let dir = scratch("unique");
        let target = dir.join("out.csv");
        let (_, a) = TemporaryFile::create_beside(&target).unwrap();
        let (_, b) = TemporaryFile::create_beside(&target).unwrap();
        assert_ne!(a.path(), b.path());
        assert!(a.path().exists() && b.path().exists());
        assert!(live().contains(&a.path().to_path_buf()));
        drop(a);
        drop(b);
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn commit_replaces_a_regular_file_but_not_a_symlink() {
        let dir = scratch("commit");
        let target = dir.join("out.csv");
        std::fs::write(&target, "old").unwrap();
        write_atomically(&target, "CSV", b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        #[cfg(unix)]
        {
            let precious = dir.join("precious");
            std::fs::write(&precious, "keep").unwrap();
            let link = dir.join("link.csv");
            std::os::unix::fs::symlink(&precious, &link).unwrap();
            let e = write_atomically(&link, "CSV", b"new").unwrap_err();
            assert!(e.to_string().contains("symbolic link"), "{e}");
            assert_eq!(std::fs::read_to_string(&precious).unwrap(), "keep");
            assert!(std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink());
        }
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    // `remove_live_temporaries` removes every temporary of the process, so it is tested in its own
    // process: tests/issue12_signals.rs (a second SIGINT).

    #[test]
    fn outputs_are_checked() {
        let dir = scratch("check");
        let input = dir.join("robot.urdf");
        std::fs::write(&input, "<robot/>").unwrap();
        let inputs = [("URDF", input.as_path())];
        let fine = dir.join("a.csv");
        check_outputs(&inputs, &[("--csv", &fine)]).unwrap();
        let message =
            |outputs: &[(&str, &Path)]| check_outputs(&inputs, outputs).unwrap_err().to_string();
        let m = message(&[("--csv", &input)]);
        assert!(
            m.starts_with("--csv:") && m.contains("is the URDF input"),
            "{m}"
        );
        let spelled = dir.join("sub/../robot.urdf");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let m = message(&[("--summary", &spelled)]);
        assert!(m.contains("is the URDF input"), "{m}");
        #[cfg(unix)]
        {
            let hard = dir.join("hard.urdf");
            std::fs::hard_link(&input, &hard).unwrap();
            let m = message(&[("--out", &hard)]);
            assert!(m.contains("the same file under another name"), "{m}");
        }
        let m = message(&[("--csv", &dir)]);
        assert!(m.contains("is a directory"), "{m}");
        let m = message(&[("--csv", &dir.join("missing/x.csv"))]);
        assert!(m.contains("create it first"), "{m}");
        let m = message(&[("--csv", &fine), ("--summary", &dir.join("sub/../a.csv"))]);
        assert!(
            m.starts_with("--summary:") && m.contains("same file as --csv"),
            "{m}"
        );
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
