//! `<joint>`: type, origin, parent and child, axis, limits, dynamics and mimic. `<calibration>`
//! and `<safety_controller>` are ignored (no effect on dynamics).

use super::xml::Reader;
use crate::model::description::{MimicSpec, UrdfJointType};
use crate::model::error::ModelError;
use roxmltree::Node;

/// A joint as written, before its links are resolved to indices.
pub(super) struct RawJoint {
    pub name: String,
    pub joint_type: UrdfJointType,
    pub parent: String,
    pub child: String,
    pub origin: [f64; 6],
    pub axis: [f64; 3],
    pub damping: f64,
    pub friction: f64,
    pub limits: [f64; 2],
    pub effort_velocity: [f64; 2],
    pub mimic: Option<MimicSpec>,
    pub line: u32,
}

/// `<limit>` as read.
#[derive(Clone, Copy, PartialEq)]
struct Limit {
    lower: f64,
    upper: f64,
    effort: f64,
    velocity: f64,
}

/// Reads one `<joint>` element.
///
/// Policy where the URDF leaves room (Pinocchio 4.1 is the reference, docs in the module above):
/// - a revolute or prismatic joint without `<limit>` loads unlimited, with a note (Pinocchio
///   refuses the file);
/// - `<limit lower upper>` default to 0; lower > upper loads with a note (Pinocchio loads it as
///   written; ribbon's `joint_limits` effect skips such a joint); `effort` and `velocity` are
///   required and must be ≥ 0, as for Pinocchio;
/// - negative `<dynamics damping>` or `friction` is an error: a negative damping adds energy in
///   the `joint_damping` effect, a negative friction is refused by Pinocchio too;
/// - a NaN or infinite value anywhere is an error (Pinocchio cannot read them either).
pub(super) fn read_joint<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
) -> Result<RawJoint, ModelError> {
    let line = reader.line(node);
    let name = reader
        .required(node, "<joint>", "name", "every joint needs a unique name")?
        .to_string();
    let owner = format!("joint '{name}'");
    let type_text = reader.required(
        node,
        &owner,
        "type",
        "use revolute, continuous, prismatic, fixed or floating",
    )?;
    let joint_type = match type_text {
        "revolute" => UrdfJointType::Revolute,
        "continuous" => UrdfJointType::Continuous,
        "prismatic" => UrdfJointType::Prismatic,
        "fixed" => UrdfJointType::Fixed,
        "floating" => UrdfJointType::Floating,
        "planar" => {
            return Err(ModelError::UnsupportedJoint {
                path: reader.path.to_string(),
                line,
                joint: name,
                joint_type: type_text.to_string(),
            })
        }
        other => {
            return Err(ModelError::UnknownJointType {
                path: reader.path.to_string(),
                line,
                joint: name,
                joint_type: other.to_string(),
            })
        }
    };

    let origin = reader
        .single(node, "origin", &owner, |reader, origin| {
            let xyz = reader.vector3(origin, &owner, "xyz", "<origin>")?;
            let rpy = reader.vector3(origin, &owner, "rpy", "<origin rpy>")?;
            let [x, y, z] = xyz.unwrap_or_default();
            let [roll, pitch, yaw] = rpy.unwrap_or_default();
            Ok([x, y, z, roll, pitch, yaw])
        })?
        .map_or([0.0; 6], |read| read.value);

    let mut link_of = |role: &'static str| -> Result<String, ModelError> {
        let read = reader.single(node, role, &owner, |reader, element| {
            Ok(reader
                .required(
                    element,
                    &format!("{owner} <{role}>"),
                    "link",
                    "write the link's name: <parent link=\"…\"/>, <child link=\"…\"/>",
                )?
                .to_string())
        })?;
        read.map(|read| read.value)
            .ok_or_else(|| ModelError::MissingElement {
                path: reader.path.to_string(),
                line,
                element: owner.clone(),
                child: role,
                hint: "every joint names its <parent link=\"…\"/> and <child link=\"…\"/>",
            })
    };
    let parent = link_of("parent")?;
    let child = link_of("child")?;

    let axis_read = reader.single(node, "axis", &owner, |reader, axis| {
        Ok(reader
            .vector3(axis, &owner, "xyz", "<axis>")?
            .unwrap_or([1.0, 0.0, 0.0]))
    })?;
    let axis = axis_read
        .as_ref()
        .map_or([1.0, 0.0, 0.0], |read| read.value);
    if joint_type.has_axis() && axis.iter().all(|a| *a == 0.0) {
        return Err(ModelError::ZeroAxis {
            path: reader.path.to_string(),
            line: axis_read.map_or(line, |read| read.line),
            joint: name,
        });
    }

    let limit = reader.single(node, "limit", &owner, |reader, limit| {
        read_limit(reader, limit, &owner)
    })?;
    let bounded = matches!(
        joint_type,
        UrdfJointType::Revolute | UrdfJointType::Prismatic
    );
    let (limits, effort_velocity) = match &limit {
        Some(read) => {
            let l = read.value;
            if bounded && l.lower > l.upper {
                reader.note(
                    read.line,
                    format!("{owner} <limit lower=\"{}\" upper=\"{}\">: lower > upper; loaded as written (as Pinocchio does), but the joint_limits effect will not act on this joint — swap the values if they are meant as a range", l.lower, l.upper),
                );
            }
            ([l.lower, l.upper], [l.effort, l.velocity])
        }
        None => {
            if bounded {
                reader.note(
                    line,
                    format!("{owner} is {type_text} but has no <limit> (the URDF specification requires one; Pinocchio refuses the file); read as unlimited"),
                );
            }
            ([f64::NEG_INFINITY, f64::INFINITY], [f64::INFINITY; 2])
        }
    };

    let (damping, friction) = reader
        .single(node, "dynamics", &owner, |reader, dynamics| {
            read_dynamics(reader, dynamics, &owner)
        })?
        .map_or((0.0, 0.0), |read| read.value);

    let mimic = reader
        .single(node, "mimic", &owner, |reader, mimic| {
            let leader = reader.required(
                mimic,
                &format!("{owner} <mimic>"),
                "joint",
                "name the joint this one follows: <mimic joint=\"…\"/>",
            )?;
            Ok(MimicSpec {
                joint: leader.to_string(),
                multiplier: reader
                    .number(mimic, &owner, "multiplier", "<mimic>")?
                    .unwrap_or(1.0),
                offset: reader
                    .number(mimic, &owner, "offset", "<mimic>")?
                    .unwrap_or(0.0),
            })
        })?
        .map(|read| read.value);

    Ok(RawJoint {
        name,
        joint_type,
        parent,
        child,
        origin,
        axis,
        damping,
        friction,
        limits,
        effort_velocity,
        mimic,
        line,
    })
}

fn read_limit<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    owner: &str,
) -> Result<Limit, ModelError> {
    let element = format!("{owner} <limit>");
    let value = |attribute: &'static str, required: bool| -> Result<f64, ModelError> {
        if required {
            reader.required(
                node,
                &element,
                attribute,
                "<limit> needs effort (N·m or N) and velocity (rad/s or m/s), as the URDF specification and Pinocchio require",
            )?;
        }
        let field = format!("<limit {attribute}>");
        let value = reader
            .number(node, owner, attribute, &field)?
            .unwrap_or_default();
        if required && value < 0.0 {
            return Err(ModelError::NegativeValue {
                path: reader.path.to_string(),
                line: reader.line(node),
                element: element.clone(),
                attribute,
                value,
                reason: "an effort or velocity limit is a magnitude and must be ≥ 0 (Pinocchio refuses it too)",
            });
        }
        Ok(value)
    };
    Ok(Limit {
        lower: value("lower", false)?,
        upper: value("upper", false)?,
        effort: value("effort", true)?,
        velocity: value("velocity", true)?,
    })
}

fn read_dynamics<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    owner: &str,
) -> Result<(f64, f64), ModelError> {
    let element = format!("{owner} <dynamics>");
    let damping = reader.number(node, owner, "damping", "<dynamics>")?;
    let friction = reader.number(node, owner, "friction", "<dynamics>")?;
    if damping.is_none() && friction.is_none() {
        let line = reader.line(node);
        reader.note(
            line,
            format!("{element} has neither damping nor friction; read as 0 (Pinocchio refuses this file)"),
        );
    }
    for (attribute, value, reason) in [
        (
            "damping",
            damping,
            "a negative damping adds energy to passive motion; viscous damping must be ≥ 0",
        ),
        (
            "friction",
            friction,
            "dry friction must be ≥ 0 (Pinocchio refuses negative friction too)",
        ),
    ] {
        if let Some(value) = value.filter(|v| *v < 0.0) {
            return Err(ModelError::NegativeValue {
                path: reader.path.to_string(),
                line: reader.line(node),
                element: element.clone(),
                attribute,
                value,
                reason,
            });
        }
    }
    Ok((damping.unwrap_or(0.0), friction.unwrap_or(0.0)))
}
