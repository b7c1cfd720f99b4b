//! `<link>`: its name and `<inertial>`; `<visual>` and `<collision>` only for notes.

use super::geometry::{check_geometry_elements, read_collisions};
use super::origin::read_origin;
use super::xml::Reader;
use crate::model::description::{InertialSpec, LinkSpec};
use crate::model::error::ModelError;
use roxmltree::Node;

/// Reads one `<link>` element.
///
/// Errors, where Pinocchio would silently drop the `<inertial>` and load the link massless: an
/// `<inertial>` without `<mass value>` or without all six `<inertia>` attributes, a value that is
/// not a finite number, a negative mass. Dynamics depend on these values, so ribbon refuses rather
/// than guess.
pub(super) fn read_link<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
) -> Result<LinkSpec, ModelError> {
    let line = reader.line(node);
    let name = reader
        .required(node, "<link>", "name", "every link needs a unique name")?
        .to_string();
    let owner = format!("link '{name}'");
    let inertial = reader.single(node, "inertial", &owner, |reader, inertial| {
        read_inertial(reader, inertial, &name)
    })?;
    check_geometry_elements(reader, node, &owner);
    let collisions = read_collisions(reader, node);
    Ok(LinkSpec {
        collisions,
        has_inertial: inertial.is_some(),
        inertial: inertial.map_or(InertialSpec::default(), |read| read.value),
        name,
        line,
    })
}

fn read_inertial<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    link: &str,
) -> Result<InertialSpec, ModelError> {
    let owner = format!("link '{link}'");
    let element = format!("{owner} <inertial>");
    let origin = reader.single(node, "origin", &element, |reader, origin| {
        read_origin(
            reader,
            origin,
            &owner,
            "<inertial><origin>",
            "<inertial><origin rpy>",
        )
    })?;
    let (com, rpy) = origin.map_or(([0.0; 3], [0.0; 3]), |read| read.value);

    let mass = reader
        .single(node, "mass", &element, |reader, mass| {
            reader.required(
                mass,
                &format!("{owner} <mass>"),
                "value",
                "write <mass value=\"…\"/> in kg",
            )?;
            let value = reader
                .number(mass, &owner, "value", "<mass value>")?
                .unwrap_or_default();
            if value < 0.0 {
                return Err(ModelError::NegativeMass {
                    path: reader.path.to_string(),
                    line: reader.line(mass),
                    link: link.to_string(),
                    mass: value,
                });
            }
            Ok(value)
        })?
        .ok_or_else(|| ModelError::MissingElement {
            path: reader.path.to_string(),
            line: reader.line(node),
            element: element.clone(),
            child: "mass",
            hint: "write <mass value=\"…\"/> in kg (Pinocchio would load this link as massless)",
        })?
        .value;

    const MOMENTS: [&str; 6] = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
    let inertia = reader
        .single(node, "inertia", &element, |reader, inertia| {
            let mut values = [0.0; 6];
            for (value, attribute) in values.iter_mut().zip(MOMENTS) {
                reader.required(
                    inertia,
                    &format!("{owner} <inertia>"),
                    attribute,
                    "<inertia> needs all of ixx ixy ixz iyy iyz izz (kg·m², about the centre of mass)",
                )?;
                *value = reader
                    .number(inertia, &owner, attribute, "<inertia>")?
                    .unwrap_or_default();
            }
            Ok(values)
        })?
        .ok_or_else(|| ModelError::MissingElement {
            path: reader.path.to_string(),
            line: reader.line(node),
            element,
            child: "inertia",
            hint: "write <inertia ixx=… ixy=… ixz=… iyy=… iyz=… izz=…/> (kg·m², about the centre of mass; Pinocchio would drop this <inertial>)",
        })?
        .value;
    Ok(InertialSpec {
        mass,
        com,
        rpy,
        inertia,
    })
}
