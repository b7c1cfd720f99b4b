//! Errors of loading a URDF into a model. Each names the file, the line of the element at fault
//! (the file alone only when it cannot be read), the element and the value, and says what to do.

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
    /// Elements nested deeper than [`MAX_XML_DEPTH`](super::MAX_XML_DEPTH).
    #[error("{path}:{line}: <{element}> is nested {depth} elements deep{}; a URDF needs about ten levels and ribbon reads at most {limit} — this file is not a robot description (or is corrupt)", if *entities > 0 { format!(" (counting {entities} levels of markup in DOCTYPE entities, which expand in place)") } else { String::new() })]
    TooDeep {
        /// The file.
        path: String,
        /// Line of the first element beyond the limit.
        line: u32,
        /// Its tag name.
        element: String,
        /// Its depth (the root element is 1).
        depth: usize,
        /// The limit.
        limit: usize,
        /// Levels of markup inside DOCTYPE entity values, counted on top of the document's own.
        entities: usize,
    },
    /// A xacro file (named `*.xacro`, or with xacro markup outside comments): refused with the
    /// command that expands it (`crate::ros::xacro`).
    #[error("{path}:{line}: this is a xacro file, not a URDF ({what}); ribbon reads URDF only{}", details.iter().map(|l| format!("\n  {l}")).collect::<String>())]
    Xacro {
        /// The file.
        path: String,
        /// Line of the first markup (1 when the name alone tells).
        line: u32,
        /// The first markup, or the file name.
        what: String,
        /// What to do: the commands that expand it and the packages they need, one per line.
        details: Vec<String>,
    },
    /// The root element is not `<robot>`.
    #[error("{path}:{line}: the root element is <{found}>, expected <robot>; is this a URDF file (an SDF or MJCF file is not)?")]
    NotRobot {
        /// The file.
        path: String,
        /// Line of the root element.
        line: u32,
        /// The root element's tag name.
        found: String,
    },
    /// A robot without any link, or a description built in code without links.
    #[error("{path}: not a valid URDF: {message}")]
    NotUrdf {
        /// The file.
        path: String,
        /// What is wrong (with the line, where there is one).
        message: String,
    },
    /// A required attribute is missing.
    #[error("{path}:{line}: {element} has no {attribute} attribute; {hint}")]
    MissingAttribute {
        /// The file.
        path: String,
        /// Line of the element.
        line: u32,
        /// The element, with its owner (`joint 'j' <limit>`).
        element: String,
        /// The missing attribute.
        attribute: &'static str,
        /// What to write.
        hint: &'static str,
    },
    /// A required child element is missing.
    #[error("{path}:{line}: {element} has no <{child}> element; {hint}")]
    MissingElement {
        /// The file.
        path: String,
        /// Line of the element that lacks the child.
        line: u32,
        /// The element, with its owner (`link 'a' <inertial>`).
        element: String,
        /// The missing child's tag name.
        child: &'static str,
        /// What to write.
        hint: &'static str,
    },
    /// An attribute that should hold numbers does not.
    #[error("{path}:{line}: {element}: {attribute}=\"{text}\" is not {expected}")]
    BadNumber {
        /// The file.
        path: String,
        /// Line of the element.
        line: u32,
        /// The element, with its owner (`joint 'j' <origin>`).
        element: String,
        /// The attribute.
        attribute: &'static str,
        /// The attribute's text as written.
        text: String,
        /// What was expected ("a number", "three numbers separated by spaces").
        expected: &'static str,
    },
    /// An element given twice with different contents (identical repeats load with a note).
    #[error("{path}:{line}: {element} has a second <{child}> (line {line}) that differs from the first (line {first_line}); ribbon will not guess which one is meant — keep one")]
    ConflictingDuplicate {
        /// The file.
        path: String,
        /// Line of the second element.
        line: u32,
        /// Line of the first element.
        first_line: u32,
        /// The owner (`joint 'j'`).
        element: String,
        /// The repeated child's tag name.
        child: &'static str,
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
    #[error("{path}:{line}: joint '{joint}' names {role} link '{link}', which the file does not define{advice}")]
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
        /// What to do: "; did you mean '…'?", or how to define the link.
        advice: String,
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
    #[error("{path}:{line}: the joints form a cycle through the links {links}; a URDF is a tree — remove one joint of the cycle (joint '{joint}' is on it) and declare it as a [[scene.loop]] in the sidecar")]
    Cycle {
        /// The file.
        path: String,
        /// Line of `joint`.
        line: u32,
        /// A joint on or leading into the cycle.
        joint: String,
        /// The links on or below the cycle.
        links: String,
    },
    /// The links do not form one connected tree.
    #[error("{path}:{line}: the robot has {count} root links ({links}); a URDF must be one connected tree — connect them with joints")]
    SeveralRoots {
        /// The file.
        path: String,
        /// Line of the second root link.
        line: u32,
        /// How many links have no parent joint.
        count: usize,
        /// Their names, with their lines.
        links: String,
    },
    /// A negative mass.
    #[error("{path}:{line}: link '{link}' has negative mass {mass} kg; a mass must be ≥ 0")]
    NegativeMass {
        /// The file.
        path: String,
        /// Line of the `<mass>` element.
        line: u32,
        /// The link.
        link: String,
        /// The mass given.
        mass: f64,
    },
    /// A negative value where only values ≥ 0 are physical (damping, friction, effort, velocity).
    #[error("{path}:{line}: {element} has {attribute}=\"{value}\"; {reason}")]
    NegativeValue {
        /// The file.
        path: String,
        /// Line of the element.
        line: u32,
        /// The element, with its owner (`joint 'j' <dynamics>`).
        element: String,
        /// The attribute.
        attribute: &'static str,
        /// The value.
        value: f64,
        /// Why it must be ≥ 0 and what to do.
        reason: &'static str,
    },
    /// A NaN or infinite number.
    #[error("{path}:{line}: {element} has the non-finite value {value} in {field}; every number must be finite")]
    NonFinite {
        /// The file.
        path: String,
        /// Line of the element holding the value.
        line: u32,
        /// "link 'x'" or "joint 'y'".
        element: String,
        /// Which value (`<mass value>`, `<inertial><origin>`, `<limit lower>`, …).
        field: String,
        /// The value as parsed.
        value: f64,
    },
    /// A joint type the URDF specification does not define.
    #[error("{path}:{line}: joint '{joint}' has type '{joint_type}', which is not a URDF joint type; use revolute, continuous, prismatic, fixed, floating or planar")]
    UnknownJointType {
        /// The file.
        path: String,
        /// Line of the joint.
        line: u32,
        /// The joint.
        joint: String,
        /// The type as written.
        joint_type: String,
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
        /// Line of the `<axis>` element.
        line: u32,
        /// The joint.
        joint: String,
    },
}
