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

/// The robots the kernel and step benches time, as `(name, URDF path)`: our ur5, then
/// example-robot-data's ur5 and panda when the reference venv exists (each one missing is named on
/// stderr with the command that creates the venv, and left out).
pub fn benchmark_robots(root: &Path) -> Vec<(String, PathBuf)> {
    let mut list = vec![("ribbon-ur5".to_string(), root.join("robots/ur5/ur5.urdf"))];
    let share = example_robot_data_robots(root)
        .unwrap_or_else(|| root.join("target/reference-venv (not created yet)"));
    for (name, relative) in [
        ("erd-ur5", "ur_description/urdf/ur5_robot.urdf"),
        ("erd-panda", "panda_description/urdf/panda.urdf"),
    ] {
        let path = share.join(relative);
        if path.exists() {
            list.push((name.to_string(), path));
        } else {
            eprintln!(
                "{name}: skipped, {} not found (run `cargo test --release` once to create the venv)",
                path.display()
            );
        }
    }
    list
}
