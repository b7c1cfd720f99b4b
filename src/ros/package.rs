//! Where a ROS package is on disk, as ROS tools find it and for a description checked out by
//! hand (docs/ros.md §2). For package `PKG`, the first of:
//! 1. every directory `DIR` of `ROS_PACKAGE_PATH` (ROS 1, and the standalone `xacro`): `DIR`
//!    itself when it is the package (its `package.xml` names `PKG`, or it is called `PKG`), then
//!    `DIR/PKG`, then a package below `DIR` whose `package.xml` names `PKG` (searched
//!    [`MAX_SEARCH_DEPTH`] levels deep, not into a package, as `rospack` crawls);
//! 2. every prefix `P` of `AMENT_PREFIX_PATH` (ROS 2, a sourced workspace): `P/share/PKG`;
//! 3. the directory of the file that names the package (the URDF) and each of its ancestors `A`:
//!    `A` itself when it is the package, then `A/PKG`, then a directory one level below `A` or
//!    below `A/src` whose `package.xml` names `PKG` (checked-out repositories whose names differ
//!    from their packages', side by side or in a workspace's `src/`).
//!
//! A package is a directory; whether a file inside it exists is the caller's question.

use std::path::{Path, PathBuf};

/// Levels below a `ROS_PACKAGE_PATH` directory searched for a package (rospack's crawl is
/// unbounded; a workspace's packages sit two or three levels down, and a bound keeps a path
/// such as `/` from walking the whole disk).
pub const MAX_SEARCH_DEPTH: usize = 4;

/// Most directories one search visits below a `ROS_PACKAGE_PATH` entry (the same reason).
const MAX_VISITED_DIRECTORIES: usize = 20_000;

/// The name a `package.xml` gives its package (`<name>…</name>`), if `dir` holds one.
pub fn package_name(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join("package.xml")).ok()?;
    let start = text.find("<name>")? + "<name>".len();
    let end = start + text[start..].find("</name>")?;
    Some(text[start..end].trim().to_string())
}

/// Whether `dir` is package `package`: its `package.xml` names it, or it has no `package.xml`
/// and is called `package` (a package directory copied without its manifest).
fn is_package(dir: &Path, package: &str) -> bool {
    match package_name(dir) {
        Some(name) => name == package,
        None => dir.is_dir() && dir.file_name().is_some_and(|n| n == package),
    }
}

/// A package named `package` below `root` (not `root` itself), breadth first, at most
/// `depth` levels down; not inside another package.
fn search_below(root: &Path, package: &str, depth: usize) -> Option<PathBuf> {
    let mut level = vec![root.to_path_buf()];
    let mut visited = 0;
    for _ in 0..depth {
        let mut next = Vec::new();
        for dir in &level {
            let Ok(entries) = std::fs::read_dir(dir) else {
                continue;
            };
            let mut children: Vec<PathBuf> = entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.is_dir())
                .collect();
            children.sort();
            for child in children {
                visited += 1;
                if visited > MAX_VISITED_DIRECTORIES {
                    return None;
                }
                match package_name(&child) {
                    Some(name) if name == package => return Some(child),
                    Some(_) => {}
                    None => next.push(child),
                }
            }
        }
        level = next;
    }
    None
}

/// The directory of ROS package `package`, searched as the module documentation says, for a
/// file at `near` (the URDF or xacro file naming it); `None` when none is found.
pub fn find_package(package: &str, near: &Path) -> Option<PathBuf> {
    if package.is_empty() || package.contains(['/', '\\']) || package == ".." {
        return None;
    }
    if let Some(paths) = std::env::var_os("ROS_PACKAGE_PATH") {
        for dir in std::env::split_paths(&paths).filter(|d| !d.as_os_str().is_empty()) {
            if is_package(&dir, package) {
                return Some(dir);
            }
            if is_package(&dir.join(package), package) {
                return Some(dir.join(package));
            }
            if let Some(found) = search_below(&dir, package, MAX_SEARCH_DEPTH) {
                return Some(found);
            }
        }
    }
    if let Some(prefixes) = std::env::var_os("AMENT_PREFIX_PATH") {
        for prefix in std::env::split_paths(&prefixes) {
            let share = prefix.join("share").join(package);
            if share.is_dir() {
                return Some(share);
            }
        }
    }
    let start = near.parent().unwrap_or(Path::new("."));
    let start = std::fs::canonicalize(if start.as_os_str().is_empty() {
        Path::new(".")
    } else {
        start
    })
    .unwrap_or_else(|_| start.to_path_buf());
    for dir in start.ancestors() {
        if is_package(dir, package) {
            return Some(dir.to_path_buf());
        }
        if is_package(&dir.join(package), package) {
            return Some(dir.join(package));
        }
        for root in [dir.to_path_buf(), dir.join("src")] {
            if let Some(found) = search_below(&root, package, 1) {
                return Some(found);
            }
        }
    }
    None
}

/// Where [`find_package`] looked, for a message about a package it did not find.
pub fn package_search_note() -> &'static str {
    "packages are looked up in ROS_PACKAGE_PATH, AMENT_PREFIX_PATH/share and the URDF's directory \
     and its ancestors (docs/ros.md §2); add the directory holding the package to ROS_PACKAGE_PATH"
}

#[cfg(test)]
mod tests {
    use super::*;

    fn package(dir: &Path, name: &str) {
        std::fs::create_dir_all(dir).unwrap();
        std::fs::write(
            dir.join("package.xml"),
            format!("<package format=\"3\">\n  <name> {name} </name>\n</package>\n"),
        )
        .unwrap();
    }

    /// A checkout whose directory is not named after its package, beside another package, with
    /// the URDF two levels inside: found through the ancestors' `package.xml`.
    #[test]
    fn a_checkout_is_found_by_its_package_xml() {
        let root = std::env::temp_dir().join(format!("ribbon-ros-package-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let repo = root.join("src/Universal_Robots_ROS2_Description");
        package(&repo, "ur_description");
        package(&root.join("src/franka_description"), "franka_description");
        std::fs::create_dir_all(repo.join("urdf")).unwrap();
        let urdf = repo.join("urdf/ur.urdf");
        let canonical = |p: &Path| std::fs::canonicalize(p).unwrap();
        assert_eq!(
            find_package("ur_description", &urdf).map(|p| canonical(&p)),
            Some(canonical(&repo))
        );
        // A sibling package, one level below an ancestor.
        assert_eq!(
            find_package("franka_description", &urdf).map(|p| canonical(&p)),
            Some(canonical(&root.join("src/franka_description")))
        );
        assert_eq!(find_package("no_such_package", &urdf), None);
        assert_eq!(find_package("../etc", &urdf), None);
        assert_eq!(package_name(&repo).as_deref(), Some("ur_description"));
        let _ = std::fs::remove_dir_all(&root);
    }
}
