//! Output paths that never destroy anything: the one place where every output file of a command is
//! checked before any simulation ([`check_outputs`]) and written ([`AtomicFile`],
//! [`write_atomically`], on the ground floor's [`TemporaryFile`], `src/atomic_file.rs`).
//!
//! The rules (README "Output safety"):
//! - an output is refused when it is one of the command's inputs (same canonical path, or the same
//!   device and inode: a hard link), a directory, a FIFO, a socket, a device, or a **symbolic link**
//!   (ribbon never writes through a link and never replaces one: pass the link's target instead);
//!   its parent directory must exist and accept a new file (proved by creating and removing a
//!   probe file there); no two outputs may be the same file, whatever the spelling (`a/../x`,
//!   `./x`, a symlinked directory);
//! - the bytes go to a temporary file beside the target, renamed onto it when complete
//!   ([`crate::atomic_file`]: never through a symlink, removed when the writer is dropped
//!   unfinished or the process is interrupted).
//!
//! Not done here: choosing file names (the commands do), and file contents (the writers do).

use super::error::OutputError;
use crate::atomic_file::{describe_non_regular, parent_directory, TemporaryFile};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

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

    // `crate::atomic_file::remove_live_temporaries` removes every temporary of the process, so it
    // is tested in its own process: tests/issue12_signals.rs (a second SIGINT).

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
