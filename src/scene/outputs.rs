//! Output names (design contract): `q.JOINT`, `v.JOINT`, `qdd.JOINT`, `frame.LINK.x|y|z`; a floating
//! base gives `q.BASE.x|y|z` and a rotation vector `q.BASE.rx|ry|rz` relative to its initial
//! orientation (quaternion components make meaningless envelopes), and `v.BASE.x…rz` in the base
//! frame.

use super::sidecar::{JointSelection, OutputsSection};
use super::SceneError;
use crate::model::{JointKind, Model};
use crate::text::closest_suggestion;

/// Where a recorded number comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// A 1-dof joint's position `q[q_index]`.
    Position {
        /// Index into q.
        q_index: usize,
    },
    /// A velocity coordinate `v[v_index]`.
    Velocity {
        /// Index into v.
        v_index: usize,
    },
    /// An acceleration coordinate `q̈[v_index]`.
    Acceleration {
        /// Index into v.
        v_index: usize,
    },
    /// Component `axis` of a URDF link's origin in the world frame.
    FramePosition {
        /// Index into `description.links`.
        link: usize,
        /// 0, 1, 2 for x, y, z.
        axis: usize,
    },
    /// Component `axis` of a floating joint's position.
    BasePosition {
        /// Model joint index.
        joint: usize,
        /// 0, 1, 2.
        axis: usize,
    },
    /// Component `axis` of a floating joint's rotation vector relative to its initial orientation.
    BaseRotation {
        /// Model joint index.
        joint: usize,
        /// 0, 1, 2.
        axis: usize,
    },
}

/// One recorded scalar series.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    /// Its name, e.g. `q.elbow_joint` or `frame.tool0.z`.
    pub name: String,
    /// Its unit.
    pub unit: &'static str,
    /// Where it comes from.
    pub kind: OutputKind,
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const ROTATION: [&str; 3] = ["rx", "ry", "rz"];

/// Resolves `[outputs]` against the model.
pub fn resolve(
    section: &OutputsSection,
    model: &Model,
    path: &str,
) -> Result<Vec<Output>, SceneError> {
    let invalid = |key: &str, message: String| SceneError::Invalid {
        path: path.to_string(),
        key: key.to_string(),
        message,
    };
    let joints: Vec<usize> = match &section.joints {
        None => (0..model.joints.len()).collect(),
        Some(JointSelection::Keyword(k)) if k == "all" => (0..model.joints.len()).collect(),
        Some(JointSelection::Keyword(other)) => {
            return Err(invalid(
                "[outputs] joints",
                format!("'{other}' is neither \"all\" nor a list of joint names"),
            ))
        }
        Some(JointSelection::List(names)) => names
            .iter()
            .map(|name| {
                model.joint_index(name).ok_or_else(|| {
                    invalid(
                        "[outputs] joints",
                        format!(
                            "unknown joint '{name}'{}",
                            closest_suggestion(name, model.joints.iter().map(|j| j.name.as_str()))
                        ),
                    )
                })
            })
            .collect::<Result<_, _>>()?,
    };
    let linear_unit = |kind: JointKind, angular: &'static str, linear: &'static str| match kind {
        JointKind::Prismatic => linear,
        _ => angular,
    };
    let mut outputs = Vec::new();
    for &j in &joints {
        let joint = &model.joints[j];
        if joint.kind == JointKind::Floating {
            for (axis, label) in XYZ.iter().enumerate() {
                outputs.push(Output {
                    name: format!("q.{}.{label}", joint.name),
                    unit: "m",
                    kind: OutputKind::BasePosition { joint: j, axis },
                });
            }
            for (axis, label) in ROTATION.iter().enumerate() {
                outputs.push(Output {
                    name: format!("q.{}.{label}", joint.name),
                    unit: "rad",
                    kind: OutputKind::BaseRotation { joint: j, axis },
                });
            }
        } else {
            outputs.push(Output {
                name: format!("q.{}", joint.name),
                unit: linear_unit(joint.kind, "rad", "m"),
                kind: OutputKind::Position {
                    q_index: joint.q_index,
                },
            });
        }
    }
    let mut per_velocity =
        |prefix: &str, angular: &'static str, linear: &'static str, acceleration: bool| {
            for &j in &joints {
                let joint = &model.joints[j];
                for k in 0..joint.nv() {
                    let v_index = joint.v_index + k;
                    let (name, unit) = if joint.kind == JointKind::Floating {
                        let label = if k < 3 { XYZ[k] } else { ROTATION[k - 3] };
                        (
                            format!("{prefix}.{}.{label}", joint.name),
                            if k < 3 { linear } else { angular },
                        )
                    } else {
                        (
                            format!("{prefix}.{}", joint.name),
                            linear_unit(joint.kind, angular, linear),
                        )
                    };
                    let kind = if acceleration {
                        OutputKind::Acceleration { v_index }
                    } else {
                        OutputKind::Velocity { v_index }
                    };
                    outputs.push(Output { name, unit, kind });
                }
            }
        };
    if section.velocities.unwrap_or(false) {
        per_velocity("v", "rad/s", "m/s", false);
    }
    if section.accelerations.unwrap_or(false) {
        per_velocity("qdd", "rad/s²", "m/s²", true);
    }
    for name in section.frames.iter().flatten() {
        let link = model.description.link_index(name).ok_or_else(|| {
            invalid(
                "[outputs] frames",
                format!(
                    "unknown link '{name}'{}",
                    closest_suggestion(
                        name,
                        model.description.links.iter().map(|l| l.name.as_str())
                    )
                ),
            )
        })?;
        for (axis, label) in XYZ.iter().enumerate() {
            outputs.push(Output {
                name: format!("frame.{name}.{label}"),
                unit: "m",
                kind: OutputKind::FramePosition { link, axis },
            });
        }
    }
    Ok(outputs)
}
