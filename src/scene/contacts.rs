//! `[scene.contact]` and `[[scene.geometry]]`: which bodies may touch, the scene's fixed shapes and
//! the contact material (docs/contacts.md §5). Every bad value is named by its key.

use super::SceneError;
use crate::geometry::{ContactMaterial, GeometryModel, SceneObject, Shape};
use crate::model::Model;
use crate::sidecar::{ContactSection, GeometrySection};
use crate::spatial::Transform;

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
                let size = g.size.ok_or_else(|| invalid(&key, "type 'box' needs size = [x, y, z] (m)".to_string()))?;
                let mut half = [0.0; 3];
                for (h, s) in half.iter_mut().zip(size) {
                    *h = 0.5 * positive("size", Some(s))?;
                }
                Shape::Box { half_extents: half }
            }
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
                        "unknown shape '{other}'; known: box, sphere, cylinder, capsule, halfspace (meshes and height fields are not supported yet)"
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
