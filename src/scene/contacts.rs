//! `[scene.contact]` and `[[scene.geometry]]`: which bodies may touch, the scene's fixed shapes and
//! the contact material (docs/contacts.md §5). Every bad value is named by its key.

use super::SceneError;
use crate::geometry::{ContactMaterial, GeometryModel, HeightGrid, SceneObject, Shape};
use crate::model::Model;
use crate::sidecar::{ContactSection, GeometrySection};
use crate::spatial::Transform;
use std::sync::Arc;

/// Default of `[scene.contact] max_penetration`, m: the adaptive step rejects a sub-step over which
/// the deepest penetration grows by more (1 mm: twice the resting depth of 1 kg on the default
/// stiffness; a 1 m/s touch-down penetrates 1 mm in one 1 ms step).
pub const DEFAULT_MAX_PENETRATION_M: f64 = 1e-3;

/// The scene's contacts, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneContacts {
    /// Shapes and pairs.
    pub geometry: GeometryModel,
    /// The material (nominal values; parameters `scene.contact.*` override them in the model).
    pub material: ContactMaterial,
    /// Adaptive step: the largest growth of the deepest penetration over one sub-step, m.
    pub max_penetration_m: f64,
}

pub(super) fn resolve(
    contact: Option<&ContactSection>,
    geometry: &[GeometrySection],
    model: &Model,
    path: &str,
) -> Result<Option<SceneContacts>, SceneError> {
    let invalid = |key: &str, message: String| SceneError::Invalid {
        path: path.to_string(),
        key: key.to_string(),
        message,
    };
    let Some(contact) = contact else {
        if let Some(g) = geometry.first() {
            return Err(invalid(
                "[[scene.geometry]]",
                format!(
                    "'{}' is declared but there is no [scene.contact] table naming it in pairs; add one (or remove the geometry)",
                    g.name
                ),
            ));
        }
        return Ok(None);
    };
    let mut scene = Vec::with_capacity(geometry.len());
    for g in geometry {
        let key = format!("[[scene.geometry]] '{}'", g.name);
        if g.name.is_empty() || scene.iter().any(|s: &SceneObject| s.name == g.name) {
            return Err(invalid(
                &key,
                "every geometry needs a unique, non-empty name".to_string(),
            ));
        }
        if model.description.link_index(&g.name).is_some() {
            return Err(invalid(
                &key,
                format!(
                    "'{}' is also a link of the robot; give the geometry another name",
                    g.name
                ),
            ));
        }
        let positive = |what: &str, x: Option<f64>| -> Result<f64, SceneError> {
            match x {
                Some(x) if x.is_finite() && x > 0.0 => Ok(x),
                Some(x) => Err(invalid(
                    &format!("{key} {what}"),
                    format!("{x} must be a finite number > 0 (m)"),
                )),
                None => Err(invalid(
                    &key,
                    format!("type '{}' needs {what}", g.shape_type),
                )),
            }
        };
        let shape = match g.shape_type.as_str() {
            "box" => {
                let size = match g.size.as_deref() {
                    Some(size) if size.len() == 3 => size,
                    _ => return Err(invalid(&key, "type 'box' needs size = [x, y, z] (m)".to_string())),
                };
                let mut half = [0.0; 3];
                for (h, s) in half.iter_mut().zip(size) {
                    *h = 0.5 * positive("size", Some(*s))?;
                }
                Shape::Box { half_extents: half }
            }
            "heightfield" => height_field(g, &key, path)?,
            "sphere" => Shape::Sphere { radius: positive("radius", g.radius)? },
            "cylinder" => Shape::Cylinder {
                radius: positive("radius", g.radius)?,
                half_length: 0.5 * positive("length", g.length)?,
            },
            "capsule" => Shape::Capsule {
                radius: positive("radius", g.radius)?,
                half_length: 0.5 * positive("length", g.length)?,
            },
            "halfspace" => Shape::HalfSpace,
            other => {
                return Err(invalid(
                    &format!("{key} type"),
                    format!(
                        "unknown shape '{other}'; known: box, sphere, cylinder, capsule, halfspace, heightfield (scene meshes are not supported yet)"
                    ),
                ))
            }
        };
        if g.xyz.iter().chain(&g.rpy).any(|x| !x.is_finite()) {
            return Err(invalid(&key, "xyz and rpy must be finite".to_string()));
        }
        scene.push(SceneObject {
            name: g.name.clone(),
            shape,
            world_from_shape: Transform::from_xyz_rpy(g.xyz, g.rpy),
        });
    }
    let defaults = ContactMaterial::default();
    let value = |name: &str, given: Option<f64>, default: f64, minimum: f64, strict: bool| {
        let x = given.unwrap_or(default);
        let ok = x.is_finite() && if strict { x > minimum } else { x >= minimum };
        if ok {
            Ok(x)
        } else {
            Err(invalid(
                &format!("[scene.contact] {name}"),
                format!(
                    "{x} must be a finite number {} {minimum}",
                    if strict { ">" } else { "≥" }
                ),
            ))
        }
    };
    let material = ContactMaterial {
        stiffness: value(
            "stiffness",
            contact.stiffness,
            defaults.stiffness,
            0.0,
            true,
        )?,
        exponent: value("exponent", contact.exponent, defaults.exponent, 1.0, false)?,
        damping: value("damping", contact.damping, defaults.damping, 0.0, false)?,
        friction: value("friction", contact.friction, defaults.friction, 0.0, false)?,
        stiction_velocity: value(
            "stiction_velocity",
            contact.stiction_velocity,
            defaults.stiction_velocity,
            0.0,
            true,
        )?,
    };
    let max_penetration_m = value(
        "max_penetration",
        contact.max_penetration,
        DEFAULT_MAX_PENETRATION_M,
        0.0,
        true,
    )?;
    if contact.pairs.is_empty() {
        return Err(invalid(
            "[scene.contact] pairs",
            "no pair is declared; list the bodies that may touch, e.g. pairs = [[\"foot\", \"ground\"]]".to_string(),
        ));
    }
    let geometry = GeometryModel::new(model, scene, &contact.pairs)
        .map_err(|e| invalid("[scene.contact] pairs", e.to_string()))?;
    Ok(Some(SceneContacts {
        geometry,
        material,
        max_penetration_m,
    }))
}

/// `type = "heightfield"` (docs/contacts.md §1, "Height fields"): `size = [x, y]` and the heights,
/// inline (`heights = [[…], …]`) or from a CSV `file` relative to the sidecar's directory; at least
/// 2 rows of at least 2 finite values each, every row as long as the first.
fn height_field(g: &GeometrySection, key: &str, path: &str) -> Result<Shape, SceneError> {
    let invalid = |key: String, message: String| SceneError::Invalid {
        path: path.to_string(),
        key,
        message,
    };
    let size = match g.size.as_deref() {
        Some([x, y]) if [x, y].iter().all(|s| s.is_finite() && **s > 0.0) => [*x, *y],
        Some(other) => {
            return Err(invalid(
                format!("{key} size"),
                format!("{other:?} must be two finite numbers > 0: the grid's extent [x, y] in m"),
            ))
        }
        None => {
            return Err(invalid(
                key.to_string(),
                "type 'heightfield' needs size = [x, y] (m), the extent of its grid".to_string(),
            ))
        }
    };
    let (heights, source) = match (&g.heights, &g.file) {
        (Some(heights), None) => (heights.clone(), format!("{key} heights")),
        (None, Some(file)) => {
            let resolved = std::path::Path::new(path)
                .parent()
                .unwrap_or(std::path::Path::new(""))
                .join(file);
            let shown = resolved.display().to_string();
            let text = std::fs::read_to_string(&resolved).map_err(|e| {
                invalid(
                    format!("{key} file"),
                    format!("cannot read '{shown}' (resolved against the sidecar's directory): {e}"),
                )
            })?;
            (
                parse_heights_csv(&text)
                    .map_err(|message| invalid(format!("{key} file"), format!("{shown}: {message}")))?,
                format!("{key} file '{shown}'"),
            )
        }
        (Some(_), Some(_)) => {
            return Err(invalid(
                key.to_string(),
                "give the heights either inline (heights = [[…], …]) or as a CSV file (file = \"…\"), not both".to_string(),
            ))
        }
        (None, None) => {
            return Err(invalid(
                key.to_string(),
                "type 'heightfield' needs heights = [[…], …] (m, one array per row along y) or file = \"heights.csv\"".to_string(),
            ))
        }
    };
    check_heights(&heights).map_err(|message| invalid(source.clone(), message))?;
    HeightGrid::new(heights, size)
        .map(|grid| Shape::HeightField(Arc::new(grid)))
        .ok_or_else(|| invalid(source, "not a valid grid of heights".to_string()))
}

/// Rows ≥ 2, columns ≥ 2, every row as long as the first, finite values.
fn check_heights(heights: &[Vec<f64>]) -> Result<(), String> {
    if heights.len() < 2 {
        return Err(format!(
            "{} row(s): a height field needs at least 2 rows",
            heights.len()
        ));
    }
    let columns = heights[0].len();
    if columns < 2 {
        return Err(format!(
            "row 1 has {columns} value(s): a height field needs at least 2 columns"
        ));
    }
    for (r, row) in heights.iter().enumerate() {
        if row.len() != columns {
            return Err(format!(
                "row {} has {} values, row 1 has {columns}: every row needs the same number",
                r + 1,
                row.len()
            ));
        }
        if let Some(c) = row.iter().position(|h| !h.is_finite()) {
            return Err(format!(
                "row {}, value {}: {} is not a finite height (m)",
                r + 1,
                c + 1,
                row[c]
            ));
        }
    }
    Ok(())
}

/// The rows of a heights CSV: one row per line, values separated by commas; empty lines and lines
/// starting with `#` are skipped. Errors name the line (1-based).
fn parse_heights_csv(text: &str) -> Result<Vec<Vec<f64>>, String> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let row = line
            .split(',')
            .enumerate()
            .map(|(c, field)| {
                let field = field.trim();
                match field.parse::<f64>() {
                    Ok(h) if h.is_finite() => Ok(h),
                    _ => Err(format!(
                        "line {}, value {}: '{field}' is not a finite number (heights in m, separated by commas)",
                        n + 1,
                        c + 1
                    )),
                }
            })
            .collect::<Result<Vec<f64>, String>>()?;
        if let Some(first) = rows.first().map(Vec::len) {
            if row.len() != first {
                return Err(format!(
                    "line {} has {} values, the first row has {first}: every row needs the same number",
                    n + 1,
                    row.len()
                ));
            }
        }
        rows.push(row);
    }
    Ok(rows)
}
