//! `<visual>`, `<collision>` and `<material>`: they do not affect dynamics, so nothing here is an
//! error. What urdfdom (Pinocchio's URDF parser) would reject — it then drops the element and
//! loads the rest — or silently skip becomes a note naming the line, so that a user who also loads
//! the file elsewhere knows what to fix.

use super::xml::{parse_vector3, Reader};
use crate::model::description::{CollisionShape, CollisionSpec};
use roxmltree::Node;

/// The shapes of `<geometry>` and the attributes each requires.
const SHAPES: [(&str, &[&str]); 5] = [
    ("box", &["size"]),
    ("cylinder", &["radius", "length"]),
    ("capsule", &["radius", "length"]),
    ("sphere", &["radius"]),
    ("mesh", &["filename"]),
];

/// Notes on every `<visual>` and `<collision>` of the link `node` (`owner` is `link 'a'`).
pub(super) fn check_geometry_elements<'input>(
    reader: &mut Reader<'_, 'input>,
    node: Node<'_, 'input>,
    owner: &str,
) {
    for kind in ["visual", "collision"] {
        for element in reader.children(node, kind) {
            let problems = problems(reader, element, kind);
            let line = reader.line(element);
            for problem in problems {
                reader.note(
                    line,
                    format!("{owner} <{kind}>: {problem} (ignored: {kind} markup does not affect dynamics)"),
                );
            }
        }
    }
}

/// A note for a top-level `<material>` without a name (urdfdom rejects it; nothing uses it).
pub(super) fn check_material<'input>(reader: &mut Reader<'_, 'input>, node: Node<'_, 'input>) {
    if node.attribute("name").is_none() {
        let line = reader.line(node);
        reader.note(
            line,
            "<material> without a name (ignored: materials do not affect dynamics)".to_string(),
        );
    }
}

fn problems<'input>(
    reader: &Reader<'_, 'input>,
    element: Node<'_, 'input>,
    kind: &str,
) -> Vec<String> {
    let mut found = Vec::new();
    for origin in reader.children(element, "origin") {
        for attribute in ["xyz", "rpy"] {
            if let Some(text) = origin.attribute(attribute) {
                if parse_vector3(text).is_none() {
                    found.push(format!(
                        "<origin {attribute}=\"{text}\"> (line {}) is not three numbers",
                        reader.line(origin)
                    ));
                }
            }
        }
    }
    let geometries = reader.children(element, "geometry");
    match geometries.first() {
        None => found.push("no <geometry>".to_string()),
        Some(geometry) => {
            if let Some(problem) = shape_problem(reader, *geometry) {
                found.push(problem);
            }
        }
    }
    if kind == "visual" {
        let materials = reader.children(element, "material");
        if let Some(first) = materials.first() {
            if first.attribute("name").is_none() {
                found.push(format!(
                    "<material> (line {}) has no name",
                    reader.line(*first)
                ));
            }
        }
        for extra in materials.iter().skip(1) {
            found.push(format!(
                "a second <material> (line {}); only the first is read",
                reader.line(*extra)
            ));
        }
    }
    found
}

fn shape_problem<'input>(
    reader: &Reader<'_, 'input>,
    geometry: Node<'_, 'input>,
) -> Option<String> {
    let Some(shape) = geometry.children().find(|n| n.is_element()) else {
        return Some("<geometry> holds no shape".to_string());
    };
    let name = shape.tag_name().name();
    let line = reader.line(shape);
    if let Some(extra) = geometry.children().filter(|n| n.is_element()).nth(1) {
        return Some(format!(
            "<geometry> holds more than one element (<{}> at line {}); only the first, <{name}>, is read",
            extra.tag_name().name(),
            reader.line(extra)
        ));
    }
    let Some((_, required)) = SHAPES.iter().find(|(s, _)| *s == name) else {
        return Some(format!(
            "unknown shape <{name}> (line {line}); URDF shapes are box, cylinder, capsule, sphere and mesh"
        ));
    };
    for attribute in *required {
        let Some(text) = shape.attribute(*attribute) else {
            return Some(format!("<{name}> (line {line}) has no {attribute}"));
        };
        let valid = match *attribute {
            "filename" => true,
            "size" => parse_vector3(text).is_some(),
            _ => text.parse::<f64>().is_ok_and(f64::is_finite),
        };
        if !valid {
            return Some(format!(
                "<{name} {attribute}=\"{text}\"> (line {line}) is not valid"
            ));
        }
    }
    if name == "mesh" {
        if let Some(scale) = shape.attribute("scale") {
            if parse_vector3(scale).is_none() {
                return Some(format!(
                    "<mesh scale=\"{scale}\"> (line {line}) is not three numbers"
                ));
            }
        }
    }
    None
}

/// The `<collision>` elements of the link `node`, in file order. Lenient like the notes above: an
/// element whose `<origin>` or `<geometry>` cannot be read is kept as
/// [`CollisionShape::Unreadable`] (with the note's reason), so that only a scene that declares
/// contacts for this link refuses it, naming the element.
pub(super) fn read_collisions<'input>(
    reader: &Reader<'_, 'input>,
    node: Node<'_, 'input>,
) -> Vec<CollisionSpec> {
    reader
        .children(node, "collision")
        .into_iter()
        .map(|element| {
            let line = reader.line(element);
            let problems = problems(reader, element, "collision");
            let mut origin = [0.0; 6];
            if let Some(o) = reader.children(element, "origin").first() {
                for (k, attribute) in ["xyz", "rpy"].into_iter().enumerate() {
                    if let Some(v) = o.attribute(attribute).and_then(parse_vector3) {
                        origin[3 * k..3 * k + 3].copy_from_slice(&v);
                    }
                }
            }
            let shape = if problems.is_empty() {
                read_shape(reader, element)
            } else {
                CollisionShape::Unreadable {
                    reason: problems.join("; "),
                }
            };
            CollisionSpec {
                name: element.attribute("name").map(str::to_string),
                origin,
                shape,
                line,
            }
        })
        .collect()
}

/// The shape of a `<collision>` whose markup [`problems`] found valid.
fn read_shape<'input>(reader: &Reader<'_, 'input>, element: Node<'_, 'input>) -> CollisionShape {
    let unreadable = |reason: &str| CollisionShape::Unreadable {
        reason: reason.to_string(),
    };
    let Some(geometry) = reader.children(element, "geometry").first().copied() else {
        return unreadable("no <geometry>");
    };
    let Some(shape) = geometry.children().find(|n| n.is_element()) else {
        return unreadable("<geometry> holds no shape");
    };
    let number = |attribute: &str| {
        shape
            .attribute(attribute)
            .and_then(|t| t.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    match shape.tag_name().name() {
        "sphere" => CollisionShape::Sphere {
            radius: number("radius"),
        },
        "box" => match shape.attribute("size").and_then(parse_vector3) {
            Some(size) => CollisionShape::Box { size },
            None => unreadable("<box size> is not three numbers"),
        },
        "cylinder" => CollisionShape::Cylinder {
            radius: number("radius"),
            length: number("length"),
        },
        "capsule" => CollisionShape::Capsule {
            radius: number("radius"),
            length: number("length"),
        },
        "mesh" => match shape.attribute("scale").map(parse_vector3) {
            Some(None) => unreadable("<mesh scale> is not three numbers"),
            scale => CollisionShape::Mesh {
                filename: shape.attribute("filename").unwrap_or_default().to_string(),
                scale: scale.flatten().unwrap_or([1.0; 3]),
            },
        },
        other => unreadable(&format!("unknown shape <{other}>")),
    }
}
