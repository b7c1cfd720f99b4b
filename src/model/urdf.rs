//! Reading a URDF file into a [`Description`]: the dynamics-relevant subset of the URDF
//! specification (links with their `<inertial>`, joints with origin, axis, limits, dynamics and
//! mimic), read from a roxmltree document so that every error and every note names the file, the
//! line and the element.
//!
//! Pinocchio 4.1 (urdfdom) is the reference for what loads: `tests/urdf_corpus.rs` checks a corpus
//! of public robot descriptions against it. The policy:
//! - **Markup that does not affect dynamics loads with a note**, as Pinocchio loads it: visual and
//!   collision elements urdfdom cannot read (unknown shapes, wrong vector lengths, a `<material>`
//!   without a name, a second `<material>` in one `<visual>`), a top-level `<material>` without a
//!   name, extra elements in a `<geometry>`, whitespace before the `<?xml?>` declaration, NUL
//!   bytes after the document, bytes that are not UTF-8. `<texture>`,
//!   `<calibration>`, `<safety_controller>`, transmissions, Gazebo tags and other prefixed
//!   elements are ignored; a prefix used without its `xmlns:` declaration (`<sensor:camera>` in
//!   older ROS files) loads with a note, as tinyxml2 does not check namespaces.
//! - **Xacro is refused** (`crate::ros::xacro`, docs/ros.md §1): a file named `*.xacro`, or with an
//!   element in a xacro namespace or a `${…}` / `$(…)` attribute outside comments, is an error
//!   naming the line and the `xacro` command that expands it (Pinocchio reads such a file as
//!   URDF and ignores the macros).
//! - **An element repeated identically** (two equal `<axis>`) loads with a note; **repeated with
//!   different contents** it is an error naming both lines (Pinocchio silently reads the first).
//! - **Values that dynamics depend on are never guessed**: a missing `<mass>` or `<inertia>`
//!   attribute, a number that does not parse, NaN or infinity, a negative mass, damping or
//!   friction are errors (Pinocchio drops an unreadable `<inertial>` and loads the link massless,
//!   and loads negative damping; it refuses the rest too).
//! - Joint limits: a revolute or prismatic joint without `<limit>` loads unlimited with a note
//!   (Pinocchio refuses it); `lower > upper` loads with a note (the `joint_limits` effect skips
//!   that joint); `effort` and `velocity` are required and ≥ 0.
//! - Nesting deeper than [`MAX_XML_DEPTH`] is refused before anything else reads the tree.
//! - `<robot version>` (1.0 without it; 1.0 to 1.2 read, others refused, as by Pinocchio): from
//!   1.1 an `<origin>` may give `quat_xyzw` instead of `rpy` (ignored with a note in a 1.0 file,
//!   as Pinocchio ignores it); from 1.2 `<limit>` needs no effort or velocity (∞ when omitted),
//!   revolute and prismatic joints need `lower` and `upper` with `lower ≤ upper`, and other
//!   joints read omitted ones as ∓∞.
//! - Whitespace around a single number (`value=" 2.5"`) is allowed.
//!
//! Planar joints are refused (not supported yet); types the specification does not define are
//! refused as such.

mod geometry;
mod joint;
mod link;
mod origin;
mod version;
mod xml;

pub use xml::MAX_XML_DEPTH;

use super::description::{Description, JointSpec, LinkSpec};
use super::error::ModelError;
use crate::text::closest_suggestion;
use std::collections::HashMap;
use std::path::Path;

/// Reads and validates a URDF file. Bytes that are not UTF-8 are read as U+FFFD with a note.
pub fn read_description(path: &Path) -> Result<Description, ModelError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ModelError::Io {
        path: name.clone(),
        source,
    })?;
    let mut notes = Vec::new();
    let text = xml::decode(&bytes, &name, &mut notes);
    parse(text, &name, notes)
}

/// Parses URDF text; `path` is only used in messages. Non-fatal findings are in
/// [`Description::notes`].
pub fn parse_description(text: &str, path: &str) -> Result<Description, ModelError> {
    parse(text.to_string(), path, Vec::new())
}

fn parse(text: String, path: &str, mut notes: Vec<String>) -> Result<Description, ModelError> {
    let text = xml::cut_trailing_nul(text, path, &mut notes);
    let text = xml::blank_late_declaration(text, path, &mut notes);
    let declared: String;
    let named_xacro = path.ends_with(".xacro");
    let xacro = |line: u32, what: String| ModelError::Xacro {
        path: path.to_string(),
        line,
        what,
        details: crate::ros::xacro_command(Path::new(path), &text),
    };
    let doc = match xml::parse(&text, path) {
        Ok(doc) => doc,
        Err(error) => match xml::declare_undeclared_prefixes(&text, path, &mut notes) {
            Some(text) => {
                declared = text;
                xml::parse(&declared, path)?
            }
            None if named_xacro => {
                return Err(xacro(1, "the file name ends in .xacro".to_string()))
            }
            None => return Err(error),
        },
    };
    let root = doc.root_element();
    let mut reader = xml::Reader::new(&doc, root, path);
    // Xacro markup (or the name): refused with the command that expands it (docs/ros.md §1).
    if let Some((node, markup)) = crate::ros::xacro::first_markup(&doc) {
        return Err(xacro(reader.line(node), markup.what));
    }
    if named_xacro {
        return Err(xacro(1, "the file name ends in .xacro".to_string()));
    }
    reader.notes = notes;
    if root.tag_name().name() != "robot" {
        return Err(ModelError::NotRobot {
            path: path.to_string(),
            line: reader.line(root),
            found: root.tag_name().name().to_string(),
        });
    }
    reader.version = version::read_version(root, reader.path, reader.line(root))?;
    let robot_name = match root.attribute("name") {
        Some(name) => name.to_string(),
        None => {
            let stem = Path::new(path)
                .file_stem()
                .map_or("robot".to_string(), |s| s.to_string_lossy().into_owned());
            let line = reader.line(root);
            reader.note(
                line,
                format!("<robot> has no name attribute (the URDF specification requires one; Pinocchio refuses the file); named '{stem}' after the file"),
            );
            stem
        }
    };

    let mut links: Vec<LinkSpec> = Vec::new();
    let mut link_index: HashMap<String, usize> = HashMap::new();
    let mut raw_joints = Vec::new();
    for child in root.children().filter(|n| n.is_element()) {
        if reader.is(child, "link") {
            let link = link::read_link(&mut reader, child)?;
            if let Some(&first) = link_index.get(&link.name) {
                return Err(ModelError::Duplicate {
                    path: path.to_string(),
                    line: link.line,
                    first_line: links[first].line,
                    kind: "link",
                    name: link.name,
                });
            }
            link_index.insert(link.name.clone(), links.len());
            links.push(link);
        } else if reader.is(child, "joint") {
            raw_joints.push(joint::read_joint(&mut reader, child)?);
        } else if reader.is(child, "material") {
            geometry::check_material(&mut reader, child);
        }
    }
    if links.is_empty() {
        return Err(ModelError::MissingElement {
            path: path.to_string(),
            line: reader.line(root),
            element: format!("robot '{robot_name}'"),
            child: "link",
            hint: "a robot needs at least one <link>",
        });
    }

    let mut joints: Vec<JointSpec> = Vec::with_capacity(raw_joints.len());
    let mut joint_lines: HashMap<String, u32> = HashMap::new();
    for raw in raw_joints {
        if let Some(&first_line) = joint_lines.get(&raw.name) {
            return Err(ModelError::Duplicate {
                path: path.to_string(),
                line: raw.line,
                first_line,
                kind: "joint",
                name: raw.name,
            });
        }
        joint_lines.insert(raw.name.clone(), raw.line);
        let find = |name: &str, role: &'static str| {
            link_index
                .get(name)
                .copied()
                .ok_or_else(|| ModelError::MissingLink {
                    path: path.to_string(),
                    line: raw.line,
                    joint: raw.name.clone(),
                    role,
                    link: name.to_string(),
                    advice: missing_link_advice(name, role, &links),
                })
        };
        let parent = find(&raw.parent, "parent")?;
        let child = find(&raw.child, "child")?;
        joints.push(JointSpec {
            name: raw.name,
            joint_type: raw.joint_type,
            parent,
            child,
            origin: raw.origin,
            axis: raw.axis,
            damping: raw.damping,
            friction: raw.friction,
            limits: raw.limits,
            effort_velocity: raw.effort_velocity,
            mimic: raw.mimic,
            line: raw.line,
        });
    }
    Ok(Description::new(
        robot_name,
        path.to_string(),
        links,
        joints,
        reader.notes,
    ))
}

/// What to do about a joint's `role` ("parent" or "child") link `name` that the file does not
/// define: the closest defined name if one is close, else how to define it. `world` gets its own
/// advice: Drake and Gazebo read it as the fixed world, but URDF (and Pinocchio) need it defined.
fn missing_link_advice(name: &str, role: &str, links: &[LinkSpec]) -> String {
    let close = closest_suggestion(name, links.iter().map(|l| l.name.as_str()));
    if !close.is_empty() {
        close
    } else if name == "world" {
        "; Drake and Gazebo read 'world' as the fixed world, but a URDF must define every link \
         it names (Pinocchio refuses it too): add <link name=\"world\"/> to the file to fix the \
         robot to the world there"
            .to_string()
    } else {
        format!(
            "; add <link name=\"{name}\"/> if the link belongs to this robot, or correct the \
             joint's <{role} link=\"…\"/> (a file cut out of a larger description often names \
             a link of the part left out)"
        )
    }
}

#[cfg(test)]
mod tests;
