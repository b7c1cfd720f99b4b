//! Where the reference venv's example-robot-data lives, found rather than hard-coded: the venv
//! `tests/common/mod.rs` creates at `target/reference-venv` may be built by any Python 3
//! (`lib/python3.X/site-packages/cmeel.prefix/...`). Shared by the benches through `#[path]`.

use std::path::{Path, PathBuf};

/// `…/cmeel.prefix/share/example-robot-data/robots` inside `target/reference-venv` under `root`,
/// or `None` when no venv (or no example-robot-data in it) exists yet.
pub fn example_robot_data_robots(root: &Path) -> Option<PathBuf> {
    let lib = root.join("target/reference-venv/lib");
    let mut candidates: Vec<PathBuf> = std::fs::read_dir(&lib)
        .ok()?
        .filter_map(Result::ok)
        .filter(|entry| entry.file_name().to_string_lossy().starts_with("python3"))
        .map(|entry| {
            entry
                .path()
                .join("site-packages/cmeel.prefix/share/example-robot-data/robots")
        })
        .filter(|path| path.is_dir())
        .collect();
    candidates.sort();
    candidates.pop()
}
