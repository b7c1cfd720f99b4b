//! Xacro files recognised and refused (docs/ros.md §1). ROS description packages ship their
//! robots as xacro (`ur.urdf.xacro`): XML with macros (`<xacro:macro>`, `<xacro:include>`,
//! macro calls `<xacro:NAME>`), properties and expressions (`${…}`) and substitutions
//! (`$(find PKG)`, `$(arg NAME)`). Read as a URDF such a file either fails on a number like
//! `${pi/2}` or, worse, loads without the links its macros would make. ribbon reads URDF only:
//! a file named `*.xacro`, or holding xacro markup outside comments, is refused (exit 2) with the
//! command that expands it — the `xacro` tool with the package paths its `$(find PKG)` need, and
//! the arguments it declares without a default.
//!
//! Does not: expand xacro (a Python tool of ROS), or find packages (`ros::package`).

use super::package::{find_package, package_search_note};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// What made a file a xacro file.
#[derive(Clone, Debug, PartialEq)]
pub struct XacroMarkup {
    /// The first markup found (`<xacro:include>`, `"${pi/2}" in rpy`, …), or the file name.
    pub what: String,
}

/// Whether a namespace URI is xacro's (`http://www.ros.org/wiki/xacro`, and the variants
/// descriptions declare: any URI naming xacro).
fn is_xacro_namespace(uri: &str) -> bool {
    uri.contains("xacro")
}

/// The first xacro markup of a parsed document, outside comments: an element in a xacro
/// namespace, or an attribute whose value holds `${` (an expression) or `$(` (a substitution).
pub fn first_markup<'a, 'input>(
    doc: &'a roxmltree::Document<'input>,
) -> Option<(roxmltree::Node<'a, 'input>, XacroMarkup)> {
    for node in doc.descendants().filter(roxmltree::Node::is_element) {
        if node.tag_name().namespace().is_some_and(is_xacro_namespace) {
            return Some((
                node,
                XacroMarkup {
                    what: format!("<xacro:{}>", node.tag_name().name()),
                },
            ));
        }
        for attribute in node.attributes() {
            let value = attribute.value();
            if value.contains("${") || value.contains("$(") {
                return Some((
                    node,
                    XacroMarkup {
                        what: format!(
                            "<{} {}=\"{}\">",
                            node.tag_name().name(),
                            attribute.name(),
                            excerpt(value)
                        ),
                    },
                ));
            }
        }
    }
    None
}

/// Longest attribute value quoted in the message, characters.
const EXCERPT_CHARS: usize = 60;

/// `value`, cut to [`EXCERPT_CHARS`] with `…`.
fn excerpt(value: &str) -> String {
    match value.char_indices().nth(EXCERPT_CHARS) {
        Some((cut, _)) => format!("{}…", &value[..cut]),
        None => value.to_string(),
    }
}

/// A path or word as one shell word (quoted when it holds anything but `[A-Za-z0-9_./:=+@%-]`).
fn shell_word(text: &str) -> String {
    if !text.is_empty()
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_./:=+@%-".contains(c))
    {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// Every distinct `$(find PKG)` package of `text`, in order of first use.
fn found_packages(text: &str) -> Vec<String> {
    let mut seen = BTreeSet::new();
    let mut packages = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("$(find ") {
        rest = &rest[start + "$(find ".len()..];
        let name: String = rest
            .trim_start()
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
            .collect();
        if !name.is_empty() && seen.insert(name.clone()) {
            packages.push(name);
        }
    }
    packages
}

/// Every `<xacro:arg name="…">` of `text` without a `default`, in order.
fn arguments_without_default(text: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("<xacro:arg") {
        rest = &rest[start + "<xacro:arg".len()..];
        let tag = &rest[..rest.find('>').unwrap_or(rest.len())];
        if tag.contains("default=") {
            continue;
        }
        if let Some(name) = tag
            .split_once("name=")
            .and_then(|(_, v)| v.get(1..))
            .and_then(|v| v.split(['"', '\'']).next())
        {
            if !names.iter().any(|n| n == name) {
                names.push(name.to_string());
            }
        }
    }
    names
}

/// The output file the command writes: the input's name without `.xacro` (and with `.urdf`);
/// for an input not named `.xacro`, `STEM.expanded.urdf` (never the input's own name, which the
/// shell would empty before xacro reads it).
fn expanded_name(file: &Path) -> String {
    let name = file
        .file_name()
        .map_or("robot".to_string(), |n| n.to_string_lossy().into_owned());
    match name.strip_suffix(".xacro") {
        Some(stem) => format!("{}.urdf", stem.strip_suffix(".urdf").unwrap_or(stem)),
        None => format!(
            "{}.expanded.urdf",
            name.strip_suffix(".urdf").unwrap_or(&name)
        ),
    }
}

/// What to do about the xacro file `file` (with contents `text`): the lines of the message's
/// details, each without indentation — the commands that expand it (ROS 2 in a sourced
/// workspace; ROS 1, or any xacro given `ROS_PACKAGE_PATH`), where its `$(find PKG)` packages
/// are (or that they were not found), and the arguments it needs.
pub fn xacro_command(file: &Path, text: &str) -> Vec<String> {
    let packages = found_packages(text);
    let mut roots: Vec<PathBuf> = Vec::new();
    let mut found = Vec::new();
    let mut missing = Vec::new();
    for package in &packages {
        match find_package(package, file) {
            Some(dir) => {
                let root = dir.parent().map_or(dir.clone(), Path::to_path_buf);
                if !roots.contains(&root) {
                    roots.push(root);
                }
                found.push(format!("{package} at {}", dir.display()));
            }
            None => missing.push(package.clone()),
        }
    }
    let arguments: String = arguments_without_default(text)
        .iter()
        .map(|name| format!(" {name}:=VALUE"))
        .collect();
    let input = shell_word(&file.display().to_string());
    let output = shell_word(&expanded_name(file));
    let mut lines = vec![
        format!("expand it with xacro, then run ribbon on {output}:"),
        format!("    xacro {input}{arguments} > {output}"),
    ];
    if !packages.is_empty() {
        lines[1].push_str("    # ROS 2, with the workspace holding its packages sourced");
        let path = std::env::join_paths(&roots)
            .map(|p| p.to_string_lossy().into_owned())
            .unwrap_or_default();
        if !roots.is_empty() {
            lines.push(format!(
                "    ROS_PACKAGE_PATH={} xacro {input}{arguments} > {output}    # ROS 1 (xacro 1.x), any checkout",
                shell_word(&path)
            ));
        }
        if !found.is_empty() {
            lines.push(format!("its $(find) packages: {}", found.join(", ")));
        }
        if !missing.is_empty() {
            lines.push(format!(
                "not found here: {} ({})",
                missing.join(", "),
                package_search_note()
            ));
        }
    }
    if !arguments.is_empty() {
        lines.push(
            "VALUE: each argument the file declares without a default (<xacro:arg>) needs one"
                .to_string(),
        );
    }
    lines.push(
        "ribbon then resolves the URDF's package:// mesh URIs the same way (docs/ros.md)"
            .to_string(),
    );
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markup_outside_comments_is_found_and_inside_them_is_not() {
        let text = "<robot name=\"r\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n\
                    <!-- <xacro:include filename=\"x\"/> ${a} -->\n\
                    <link name=\"a\"/>\n\
                    <joint name=\"j\" type=\"fixed\"><origin rpy=\"0 ${pi/2} 0\"/></joint>\n\
                    </robot>";
        let doc = roxmltree::Document::parse(text).unwrap();
        let (node, markup) = first_markup(&doc).unwrap();
        assert_eq!(node.tag_name().name(), "origin");
        assert_eq!(markup.what, "<origin rpy=\"0 ${pi/2} 0\">");
        let plain = "<robot name=\"r\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n\
                     <!-- <xacro:macro name=\"m\"/> --><link name=\"a\"/></robot>";
        assert!(first_markup(&roxmltree::Document::parse(plain).unwrap()).is_none());
        let element = "<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\"><xacro:include \
                       filename=\"$(find ur_description)/urdf/ur_macro.xacro\"/></robot>";
        let doc = roxmltree::Document::parse(element).unwrap();
        assert_eq!(first_markup(&doc).unwrap().1.what, "<xacro:include>");
    }

    #[test]
    fn the_command_names_the_output_arguments_and_missing_packages() {
        let text = "<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\
                    <xacro:arg name=\"name\"/><xacro:arg name=\"ur_type\" default=\"ur5x\"/>\
                    <xacro:include filename=\"$(find no_such_pkg_here)/a.xacro\"/>\
                    <xacro:include filename=\"$(find no_such_pkg_here)/b.xacro\"/></robot>";
        let lines = xacro_command(Path::new("/tmp/x y/ur.urdf.xacro"), text);
        assert_eq!(
            lines[1],
            "    xacro '/tmp/x y/ur.urdf.xacro' name:=VALUE > ur.urdf    # ROS 2, with the \
             workspace holding its packages sourced"
        );
        assert!(lines
            .iter()
            .any(|l| l.starts_with("not found here: no_such_pkg_here (")));
        assert_eq!(arguments_without_default(text), ["name"]);
        assert_eq!(found_packages(text), ["no_such_pkg_here"]);
        assert_eq!(expanded_name(Path::new("fr3.xacro")), "fr3.urdf");
        assert_eq!(
            expanded_name(Path::new("husky.urdf")),
            "husky.expanded.urdf"
        );
    }
}
