//! Errors of loading a URDF into a model. Each names the file, the line where there is one, the
//! element and the value, and says what to do.

use thiserror::Error;

/// Why a URDF could not become a [`Model`](super::Model).
#[derive(Debug, Error)]
pub enum ModelError {
    /// The file could not be read.
    #[error("cannot read '{path}': {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The file is not well-formed XML.
    #[error("{path}:{line}:{column}: malformed XML: {message}")]
    Xml {
        /// The file.
        path: String,
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The XML parser's description.
        message: String,
    },
    /// Well-formed XML that is not a URDF robot, or that urdf-rs rejects.
    #[error("{path}: not a valid URDF: {message}")]
    NotUrdf {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// Two links or two joints share a name.
    #[error("{path}:{line}: {kind} '{name}' is defined twice (first at line {first_line}); names must be unique")]
    Duplicate {
        /// The file.
        path: String,
        /// Line of the second definition.
        line: u32,
        /// Line of the first definition.
        first_line: u32,
        /// "link" or "joint".
        kind: &'static str,
        /// The repeated name.
        name: String,
    },
    /// A joint names a link the file does not define.
    #[error("{path}:{line}: joint '{joint}' names {role} link '{link}', which the file does not define{suggestion}")]
    MissingLink {
        /// The file.
        path: String,
        /// Line of the joint.
        line: u32,
        /// The joint.
        joint: String,
        /// "parent" or "child".
        role: &'static str,
        /// The missing link's name.
        link: String,
        /// "; did you mean '…'?" or empty.
        suggestion: String,
    },
    /// A link is the child of two joints.
    #[error("{path}:{line}: link '{link}' is the child of two joints, '{first}' and '{second}'; a URDF is a tree — declare closed loops as [[scene.loop]] in the sidecar instead")]
    TwoParents {
        /// The file.
        path: String,
        /// Line of the second joint.
        line: u32,
        /// The link.
        link: String,
        /// First parent joint.
        first: String,
        /// Second parent joint.
        second: String,
    },
    /// The joints form a cycle.
    #[error("{path}: the joints form a cycle through the links {links}; a URDF is a tree — remove one joint of the cycle and declare it as a [[scene.loop]] in the sidecar")]
    Cycle {
        /// The file.
        path: String,
        /// The links on or below the cycle.
        links: String,
    },
    /// The links do not form one connected tree.
    #[error("{path}: the robot has {count} root links ({links}); a URDF must be one connected tree — connect them with joints")]
    SeveralRoots {
        /// The file.
        path: String,
        /// How many links have no parent joint.
        count: usize,
        /// Their names.
        links: String,
    },
    /// A negative mass.
    #[error("{path}:{line}: link '{link}' has negative mass {mass} kg; a mass must be ≥ 0")]
    NegativeMass {
        /// The file.
        path: String,
        /// Line of the link.
        line: u32,
        /// The link.
        link: String,
        /// The mass given.
        mass: f64,
    },
    /// A NaN or infinite number.
    #[error("{path}:{line}: {element} has the non-finite value {value} in {field}; every number must be finite")]
    NonFinite {
        /// The file.
        path: String,
        /// Line of the element.
        line: u32,
        /// "link 'x'" or "joint 'y'".
        element: String,
        /// Which value.
        field: &'static str,
        /// The value as parsed.
        value: f64,
    },
    /// A joint type ribbon does not support yet.
    #[error("{path}:{line}: joint '{joint}' is of type '{joint_type}', which ribbon does not support yet; supported: revolute, continuous, prismatic, fixed, floating")]
    UnsupportedJoint {
        /// The file.
        path: String,
        /// Line of the joint.
        line: u32,
        /// The joint.
        joint: String,
        /// Its type.
        joint_type: String,
    },
    /// A moving joint with a zero axis.
    #[error(
        "{path}:{line}: joint '{joint}' has the zero axis (0 0 0); give a non-zero <axis xyz>"
    )]
    ZeroAxis {
        /// The file.
        path: String,
        /// Line of the joint.
        line: u32,
        /// The joint.
        joint: String,
    },
}
