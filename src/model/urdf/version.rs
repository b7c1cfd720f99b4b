//! `<robot version>`: the URDF version, on which two readings depend (as in urdfdom, and so in
//! Pinocchio 4.1): version 1.1 adds `quat_xyzw` to `<origin>` (read by `super::origin`), version
//! 1.2 makes `effort` and `velocity` of `<limit>` optional (no limit) and requires
//! `lower ≤ upper` on revolute and prismatic joints (read by `super::joint`).

use crate::model::error::ModelError;
use roxmltree::Node;

/// A URDF version `major.minor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct UrdfVersion {
    major: u32,
    minor: u32,
}

impl UrdfVersion {
    /// The version of a file without a `version` attribute.
    pub const V1_0: Self = Self::new(1, 0);
    /// Adds `quat_xyzw` to `<origin>`.
    pub const V1_1: Self = Self::new(1, 1);
    /// Omitted limits mean no limit; revolute and prismatic joints need `lower ≤ upper`.
    pub const V1_2: Self = Self::new(1, 2);
    /// The newest version ribbon (and Pinocchio 4.1) reads.
    const NEWEST: Self = Self::V1_2;

    const fn new(major: u32, minor: u32) -> Self {
        Self { major, minor }
    }
}

/// Reads `version` of the `<robot>` element `root`: 1.0 without the attribute; otherwise it must
/// be `major.minor` (decimal digits) between 1.0 and 1.2. Any other value is an error naming the
/// line: a newer version may change what a value means, so ribbon does not guess (Pinocchio
/// refuses these files too). `path` and `line` (the root's) name the file and line in that error.
pub(super) fn read_version(root: Node, path: &str, line: u32) -> Result<UrdfVersion, ModelError> {
    let Some(text) = root.attribute("version") else {
        return Ok(UrdfVersion::V1_0);
    };
    let number = |part: &str| {
        (!part.is_empty() && part.bytes().all(|b| b.is_ascii_digit()))
            .then(|| part.parse::<u32>().ok())
            .flatten()
    };
    let version = text
        .trim()
        .split_once('.')
        .and_then(|(major, minor)| Some(UrdfVersion::new(number(major)?, number(minor)?)));
    match version {
        Some(v) if (UrdfVersion::V1_0..=UrdfVersion::NEWEST).contains(&v) => Ok(v),
        _ => Err(ModelError::BadNumber {
            path: path.to_string(),
            line,
            element: "<robot>".to_string(),
            attribute: "version",
            text: text.to_string(),
            expected: "a URDF version ribbon reads: 1.0, 1.1 or 1.2 (Pinocchio 4.1 reads the same; without the attribute a file is 1.0)",
        }),
    }
}
