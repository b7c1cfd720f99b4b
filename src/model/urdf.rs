//! Reading a URDF file into a [`Description`].
//!
//! urdf-rs does the parsing. Around it, a roxmltree pass gives what urdf-rs does not: line numbers for
//! error messages, whether a link really has an `<inertial>` (urdf-rs fills in zeros), and the
//! removal of `<texture/>` elements without `filename` (valid in practice — three example-robot-data
//! robots have them — but rejected by urdf-rs; textures do not matter to dynamics).
//!
//! Ignored URDF content: visuals, collisions, materials, `<calibration>`, `<safety_controller>`,
//! transmissions and Gazebo extensions.

use super::description::{
    Description, InertialSpec, JointSpec, LinkSpec, MimicSpec, UrdfJointType,
};
use super::error::ModelError;
use crate::text::closest_suggestion;
use std::collections::HashMap;
use std::path::Path;

/// What the roxmltree pass learns about one element.
struct ElementInfo {
    line: u32,
    has_inertial: bool,
}

/// Reads and validates a URDF file.
pub fn read_description(path: &Path) -> Result<Description, ModelError> {
    let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_description(&text, &path.display().to_string())
}

/// Parses URDF text; `path` is only used in messages.
pub fn parse_description(text: &str, path: &str) -> Result<Description, ModelError> {
    let (links_info, joints_info, cleaned) = scan_xml(text, path)?;
    let robot = urdf_rs::read_from_string(&cleaned).map_err(|e| ModelError::NotUrdf {
        path: path.to_string(),
        message: format!(
            "urdf-rs: {e}. Check that element against the URDF specification (http://wiki.ros.org/urdf/XML)"
        ),
    })?;

    let mut links = Vec::with_capacity(robot.links.len());
    let mut link_lines: HashMap<&str, u32> = HashMap::new();
    for (index, link) in robot.links.iter().enumerate() {
        let info = &links_info[index];
        if let Some(&first_line) = link_lines.get(link.name.as_str()) {
            return Err(ModelError::Duplicate {
                path: path.to_string(),
                line: info.line,
                first_line,
                kind: "link",
                name: link.name.clone(),
            });
        }
        link_lines.insert(&link.name, info.line);
        let i = &link.inertial;
        let inertial = InertialSpec {
            mass: i.mass.value,
            com: i.origin.xyz.0,
            rpy: i.origin.rpy.0,
            inertia: [
                i.inertia.ixx,
                i.inertia.ixy,
                i.inertia.ixz,
                i.inertia.iyy,
                i.inertia.iyz,
                i.inertia.izz,
            ],
        };
        let element = || format!("link '{}'", link.name);
        check_finite(path, info.line, &element, "<mass value>", &[inertial.mass])?;
        check_finite(
            path,
            info.line,
            &element,
            "<inertial><origin>",
            &inertial.com,
        )?;
        check_finite(
            path,
            info.line,
            &element,
            "<inertial><origin rpy>",
            &inertial.rpy,
        )?;
        check_finite(path, info.line, &element, "<inertia>", &inertial.inertia)?;
        if inertial.mass < 0.0 {
            return Err(ModelError::NegativeMass {
                path: path.to_string(),
                line: info.line,
                link: link.name.clone(),
                mass: inertial.mass,
            });
        }
        links.push(LinkSpec {
            name: link.name.clone(),
            has_inertial: info.has_inertial,
            inertial,
            line: info.line,
        });
    }

    let link_names: Vec<&str> = links.iter().map(|l| l.name.as_str()).collect();
    let find_link = |name: &str, joint: &str, line: u32, role: &'static str| {
        link_lines
            .contains_key(name)
            .then(|| link_names.iter().position(|n| *n == name))
            .flatten()
            .ok_or_else(|| ModelError::MissingLink {
                path: path.to_string(),
                line,
                joint: joint.to_string(),
                role,
                link: name.to_string(),
                suggestion: closest_suggestion(name, link_names.iter().copied()),
            })
    };

    let mut joints = Vec::with_capacity(robot.joints.len());
    let mut joint_lines: HashMap<&str, u32> = HashMap::new();
    for (index, joint) in robot.joints.iter().enumerate() {
        let line = joints_info[index].line;
        if let Some(&first_line) = joint_lines.get(joint.name.as_str()) {
            return Err(ModelError::Duplicate {
                path: path.to_string(),
                line,
                first_line,
                kind: "joint",
                name: joint.name.clone(),
            });
        }
        joint_lines.insert(&joint.name, line);
        let joint_type = match joint.joint_type {
            urdf_rs::JointType::Revolute => UrdfJointType::Revolute,
            urdf_rs::JointType::Continuous => UrdfJointType::Continuous,
            urdf_rs::JointType::Prismatic => UrdfJointType::Prismatic,
            urdf_rs::JointType::Fixed => UrdfJointType::Fixed,
            urdf_rs::JointType::Floating => UrdfJointType::Floating,
            ref other => {
                return Err(ModelError::UnsupportedJoint {
                    path: path.to_string(),
                    line,
                    joint: joint.name.clone(),
                    joint_type: format!("{other:?}").to_lowercase(),
                })
            }
        };
        let parent = find_link(&joint.parent.link, &joint.name, line, "parent")?;
        let child = find_link(&joint.child.link, &joint.name, line, "child")?;
        let o = &joint.origin;
        let origin = [o.xyz[0], o.xyz[1], o.xyz[2], o.rpy[0], o.rpy[1], o.rpy[2]];
        let axis = joint.axis.xyz.0;
        let (damping, friction) = joint
            .dynamics
            .as_ref()
            .map_or((0.0, 0.0), |d| (d.damping, d.friction));
        let element = || format!("joint '{}'", joint.name);
        check_finite(path, line, &element, "<origin>", &origin)?;
        check_finite(path, line, &element, "<axis>", &axis)?;
        check_finite(path, line, &element, "<dynamics>", &[damping, friction])?;
        if joint_type.has_axis() && axis.iter().all(|a| *a == 0.0) {
            return Err(ModelError::ZeroAxis {
                path: path.to_string(),
                line,
                joint: joint.name.clone(),
            });
        }
        let mimic = joint.mimic.as_ref().map(|m| MimicSpec {
            joint: m.joint.clone(),
            multiplier: m.multiplier.unwrap_or(1.0),
            offset: m.offset.unwrap_or(0.0),
        });
        if let Some(m) = &mimic {
            check_finite(path, line, &element, "<mimic>", &[m.multiplier, m.offset])?;
        }
        let limit = &joint.limit;
        joints.push(JointSpec {
            name: joint.name.clone(),
            joint_type,
            parent,
            child,
            origin,
            axis,
            damping,
            friction,
            limits: [limit.lower, limit.upper],
            effort_velocity: [limit.effort, limit.velocity],
            mimic,
            line,
        });
    }
    Ok(Description {
        robot_name: robot.name,
        links,
        joints,
    })
}

fn check_finite(
    path: &str,
    line: u32,
    element: &dyn Fn() -> String,
    field: &'static str,
    values: &[f64],
) -> Result<(), ModelError> {
    match values.iter().find(|v| !v.is_finite()) {
        None => Ok(()),
        Some(&value) => Err(ModelError::NonFinite {
            path: path.to_string(),
            line,
            element: element(),
            field,
            value,
        }),
    }
}

/// The roxmltree pass: line numbers of `<link>` and `<joint>` children of `<robot>` (in order),
/// `<inertial>` presence, and the text with filename-less `<texture/>` elements blanked out
/// (replaced by spaces, so line numbers stay valid).
type Scan = (Vec<ElementInfo>, Vec<ElementInfo>, String);

fn scan_xml(text: &str, path: &str) -> Result<Scan, ModelError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| {
        let pos = e.pos();
        ModelError::Xml {
            path: path.to_string(),
            line: pos.row,
            column: pos.col,
            message: e.to_string(),
        }
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(ModelError::NotUrdf {
            path: path.to_string(),
            message: format!(
                "the root element is <{}>, expected <robot>",
                root.tag_name().name()
            ),
        });
    }
    let line_of = |node: roxmltree::Node| doc.text_pos_at(node.range().start).row;
    let mut links = Vec::new();
    let mut joints = Vec::new();
    for child in root.children().filter(|n| n.is_element()) {
        match child.tag_name().name() {
            "link" => links.push(ElementInfo {
                line: line_of(child),
                has_inertial: child
                    .children()
                    .any(|n| n.is_element() && n.tag_name().name() == "inertial"),
            }),
            "joint" => joints.push(ElementInfo {
                line: line_of(child),
                has_inertial: false,
            }),
            _ => {}
        }
    }
    let mut cleaned = text.as_bytes().to_vec();
    for node in doc.descendants() {
        if node.is_element()
            && node.tag_name().name() == "texture"
            && node.attribute("filename").is_none()
        {
            for byte in &mut cleaned[node.range()] {
                if *byte != b'\n' {
                    *byte = b' ';
                }
            }
        }
    }
    // Only ASCII bytes of complete elements were replaced by ASCII spaces: still valid UTF-8.
    let cleaned = String::from_utf8(cleaned).map_err(|e| ModelError::NotUrdf {
        path: path.to_string(),
        message: format!("internal error while removing <texture/> elements: {e}"),
    })?;
    Ok((links, joints, cleaned))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn urdf(body: &str) -> String {
        format!("<?xml version=\"1.0\"?>\n<robot name=\"t\">\n{body}\n</robot>\n")
    }

    #[test]
    fn malformed_xml_names_line() {
        let err = parse_description(
            "<robot name=\"x\">\n<link name=\"a\">\n</robot>",
            "bad.urdf",
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("bad.urdf:"), "{msg}");
        assert!(msg.contains("malformed XML"), "{msg}");
    }

    #[test]
    fn texture_without_filename_is_accepted() {
        let text = urdf(
            "<link name=\"a\"><visual><geometry><box size=\"1 1 1\"/></geometry>\
             <material name=\"m\"><texture/></material></visual></link>",
        );
        let description = parse_description(&text, "t.urdf").unwrap();
        assert_eq!(description.links.len(), 1);
    }

    #[test]
    fn missing_inertial_is_distinguished_from_zero() {
        let text = urdf(
            "<link name=\"a\"/>\n<link name=\"b\"><inertial><mass value=\"0\"/>\
             <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial></link>\n\
             <joint name=\"j\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>",
        );
        let d = parse_description(&text, "t.urdf").unwrap();
        assert!(!d.links[0].has_inertial);
        assert!(d.links[1].has_inertial);
        assert_eq!(d.joints[0].line, 5);
    }

    #[test]
    fn missing_link_suggests_closest() {
        let text = urdf(
            "<link name=\"base\"/><link name=\"arm\"/>\n\
             <joint name=\"j\" type=\"revolute\"><parent link=\"bas\"/><child link=\"arm\"/>\
             <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>",
        );
        let msg = parse_description(&text, "t.urdf").unwrap_err().to_string();
        assert!(
            msg.contains("t.urdf:4: joint 'j' names parent link 'bas'"),
            "{msg}"
        );
        assert!(msg.contains("did you mean 'base'"), "{msg}");
    }

    #[test]
    fn negative_mass_and_nan_are_refused() {
        let neg = urdf(
            "<link name=\"a\"><inertial><mass value=\"-1\"/>\
             <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>",
        );
        let msg = parse_description(&neg, "t.urdf").unwrap_err().to_string();
        assert!(msg.contains("negative mass -1 kg"), "{msg}");
        let nan = urdf(
            "<link name=\"a\"><inertial><mass value=\"NaN\"/>\
             <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>",
        );
        let msg = parse_description(&nan, "t.urdf").unwrap_err().to_string();
        assert!(
            msg.contains("non-finite value NaN in <mass value>"),
            "{msg}"
        );
    }

    #[test]
    fn planar_joint_is_refused_clearly() {
        let text = urdf(
            "<link name=\"a\"/><link name=\"b\"/>\
             <joint name=\"p\" type=\"planar\"><parent link=\"a\"/><child link=\"b\"/></joint>",
        );
        let msg = parse_description(&text, "t.urdf").unwrap_err().to_string();
        assert!(msg.contains("joint 'p' is of type 'planar'"), "{msg}");
        assert!(msg.contains("does not support yet"), "{msg}");
    }
}
