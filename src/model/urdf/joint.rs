//! `<joint>`: type, origin, parent and child, axis, limits, dynamics and mimic. `<calibration>`
//! and `<safety_controller>` are ignored (no effect on dynamics).

use super::origin::read_origin;
use super::version::UrdfVersion;
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
/// - up to URDF 1.1, `<limit lower upper>` default to 0; lower > upper loads with a note
///   (Pinocchio loads it as written; ribbon's `joint_limits` effect skips such a joint); `effort`
///   and `velocity` are required and must be ≥ 0, as for Pinocchio; URDF 1.2 changes these rules
///   as urdfdom does (see `read_limit`);
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
            let ([x, y, z], [roll, pitch, yaw]) =
                read_origin(reader, origin, &owner, "<origin>", "<origin rpy>")?;
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

    let bounded = matches!(
        joint_type,
        UrdfJointType::Revolute | UrdfJointType::Prismatic
    );
    let limit = reader.single(node, "limit", &owner, |reader, limit| {
        read_limit(reader, limit, &owner, bounded)
    })?;
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

/// Reads `<limit>` by the rules of the file's URDF version (`bounded`: the joint is revolute or
/// prismatic). Up to 1.1: `effort` and `velocity` are required, omitted `lower` and `upper` are 0.
/// From 1.2 (as urdfdom reads it): omitted `effort` and `velocity` are ∞ (no limit), a bounded
/// joint needs `lower` and `upper` with `lower ≤ upper`, and other joints read omitted ones as
/// ∓∞. `effort` and `velocity` are ≥ 0 in every version.
fn read_limit<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    owner: &str,
    bounded: bool,
) -> Result<Limit, ModelError> {
    let element = format!("{owner} <limit>");
    let since_1_2 = reader.version >= UrdfVersion::V1_2;
    let require = |attribute: &'static str, hint: &'static str| {
        reader.required(node, &element, attribute, hint).map(drop)
    };
    let read = |attribute: &'static str, omitted: f64| -> Result<f64, ModelError> {
        let field = format!("<limit {attribute}>");
        Ok(reader
            .number(node, owner, attribute, &field)?
            .unwrap_or(omitted))
    };
    let magnitude = |attribute: &'static str| -> Result<f64, ModelError> {
        let omitted = if since_1_2 {
            f64::INFINITY
        } else {
            require(
                attribute,
                "<limit> needs effort (N·m or N) and velocity (rad/s or m/s), as the URDF specification (before version 1.2) and Pinocchio require",
            )?;
            0.0
        };
        let value = read(attribute, omitted)?;
        if value < 0.0 {
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
    let (lower_omitted, upper_omitted) = if !since_1_2 {
        (0.0, 0.0)
    } else if bounded {
        const HINT: &str = "from URDF 1.2 on, revolute and prismatic joints give both lower and upper (Pinocchio refuses the file too)";
        require("lower", HINT)?;
        require("upper", HINT)?;
        (0.0, 0.0)
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    };
    let limit = Limit {
        lower: read("lower", lower_omitted)?,
        upper: read("upper", upper_omitted)?,
        effort: magnitude("effort")?,
        velocity: magnitude("velocity")?,
    };
    if since_1_2 && bounded && limit.lower > limit.upper {
        return Err(reader.bad_number(
            node,
            owner,
            "upper",
            node.attribute("upper").unwrap_or_default(),
            "≥ lower: from URDF 1.2 on, a revolute or prismatic joint needs lower ≤ upper (Pinocchio refuses the file too)",
        ));
    }
    Ok(limit)
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
