//! The parameter registry: every value of a model that can be declared uncertain, addressed by a
//! dotted path (design contract):
//!
//! - `link.NAME.mass`, `link.NAME.com.{x,y,z}`, `link.NAME.inertia.{ixx,ixy,ixz,iyy,iyz,izz}` — the
//!   URDF `<inertial>` (inertia about the COM, in the inertial frame);
//! - `link.NAME.scale` — one unitless factor (nominal 1) on the link's mass and whole inertia
//!   tensor together, COM unchanged: a density error ([`crate::model::Model::inertial_scales`]).
//!   It multiplies whatever mass and inertia values the link has, including declared ones;
//! - `joint.NAME.origin.{x,y,z,roll,pitch,yaw}`, `joint.NAME.axis.{x,y,z}`, `joint.NAME.damping`,
//!   `joint.NAME.friction` (axis, damping and friction only on moving joints);
//! - `scene.gravity.{x,y,z}`;
//! - with contacts declared (`[scene.contact]`, docs/contacts.md): `scene.contact.{stiffness,
//!   exponent, damping, friction, stiction_velocity}` and the sizes of links' `<collision>`
//!   primitives, `link.NAME.collision.K.{radius, length, size.x, size.y, size.z}` (`K` counts the
//!   link's `<collision>` elements from 0; only the fields its shape has).
//!
//! `NAME` is everything between the kind prefix and a known field suffix, so names containing dots
//! or slashes (`joint_0.0`, `iris__/imu_link`) work. A path resolves once to a [`ParamTarget`];
//! writing values through targets ([`apply`]) allocates nothing.
//!
//! The `scene.*` paths address the scene's [`Environment`], the others the [`Model`]: every
//! function that reads or writes values takes both.

use crate::environment::Environment;
use crate::model::{Model, UrdfJointType};
use crate::text::closest_suggestion;
use thiserror::Error;

/// A resolved parameter: which value of the model it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamTarget {
    /// Mass of link `0` (index into `description.links`).
    LinkMass(usize),
    /// The `link.NAME.scale` factor of link `0` (unitless, nominal 1): multiplies its mass and
    /// inertia tensor ([`crate::model::Model::inertial_scales`]).
    LinkScale(usize),
    /// Component `1` (x, y, z) of link `0`'s centre of mass.
    LinkCom(usize, usize),
    /// Component `1` (ixx, ixy, ixz, iyy, iyz, izz) of link `0`'s inertia.
    LinkInertia(usize, usize),
    /// Component `1` (x, y, z, roll, pitch, yaw) of joint `0`'s origin (index into
    /// `description.joints`).
    JointOrigin(usize, usize),
    /// Component `1` of joint `0`'s axis.
    JointAxis(usize, usize),
    /// Joint `0`'s viscous damping.
    JointDamping(usize),
    /// Joint `0`'s Coulomb friction.
    JointFriction(usize),
    /// Component `0` of gravity.
    Gravity(usize),
    /// Field `0` of the contact material ([`CONTACT_FIELDS`]: stiffness, exponent, damping,
    /// friction, stiction velocity).
    Contact(usize),
    /// Size field `2` ([`COLLISION_FIELDS`]: radius, length, size.x, size.y, size.z) of collision
    /// element `1` of link `0`.
    CollisionSize(usize, usize, usize),
}

/// The fields of `scene.contact.*`, in [`ParamTarget::Contact`] order.
pub const CONTACT_FIELDS: [&str; 5] = [
    "stiffness",
    "exponent",
    "damping",
    "friction",
    "stiction_velocity",
];
const CONTACT_PATHS: [&str; 5] = [
    "contact.stiffness",
    "contact.exponent",
    "contact.damping",
    "contact.friction",
    "contact.stiction_velocity",
];
/// The size fields of `link.NAME.collision.K.*`, in [`ParamTarget::CollisionSize`] order.
pub const COLLISION_FIELDS: [&str; 5] = ["radius", "length", "size.x", "size.y", "size.z"];

/// The size fields collision `k` of link `l` has (indices into [`COLLISION_FIELDS`]).
fn collision_fields(model: &Model, l: usize, k: usize) -> &'static [usize] {
    use crate::model::CollisionShape;
    match model.description.links[l].collisions[k].shape {
        CollisionShape::Sphere { .. } => &[0],
        CollisionShape::Cylinder { .. } | CollisionShape::Capsule { .. } => &[0, 1],
        CollisionShape::Box { .. } => &[2, 3, 4],
        CollisionShape::Mesh { .. } | CollisionShape::Unreadable { .. } => &[],
    }
}

/// One listed parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    /// Its dotted path.
    pub path: String,
    /// What it writes.
    pub target: ParamTarget,
    /// Its unit (`kg`, `m`, `rad`, `kg·m²`, …; `""` for unitless).
    pub unit: &'static str,
}

/// Why a parameter path or value was refused.
#[derive(Debug, Error)]
pub enum ParamError {
    /// No such parameter.
    #[error("unknown parameter '{path}'{suggestion}; `ribbon params ROBOT.urdf` lists them all")]
    Unknown {
        /// The path given.
        path: String,
        /// "; did you mean '…'?" or empty.
        suggestion: String,
    },
    /// The path names a real element that does not have that value.
    #[error("parameter '{path}' does not exist: {reason}")]
    NotApplicable {
        /// The path given.
        path: String,
        /// Why.
        reason: String,
    },
    /// A value that no model can have.
    #[error("parameter '{path}' cannot be {value}: {reason}")]
    InvalidValue {
        /// The path.
        path: String,
        /// The value.
        value: f64,
        /// Why.
        reason: &'static str,
    },
}

const COM_FIELDS: [&str; 3] = ["x", "y", "z"];
const INERTIA_FIELDS: [&str; 6] = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
const ORIGIN_FIELDS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
// The field parts of paths, as whole strings (so that `field_of` can return `&'static str`).
const COM_PATHS: [&str; 3] = ["com.x", "com.y", "com.z"];
const INERTIA_PATHS: [&str; 6] = [
    "inertia.ixx",
    "inertia.ixy",
    "inertia.ixz",
    "inertia.iyy",
    "inertia.iyz",
    "inertia.izz",
];
const ORIGIN_PATHS: [&str; 6] = [
    "origin.x",
    "origin.y",
    "origin.z",
    "origin.roll",
    "origin.pitch",
    "origin.yaw",
];
const AXIS_PATHS: [&str; 3] = ["axis.x", "axis.y", "axis.z"];
const GRAVITY_PATHS: [&str; 3] = ["gravity.x", "gravity.y", "gravity.z"];

/// The parts of a dotted path: `kind.NAME.field` (`link.forearm_link.com.x`: kind `link`, name
/// `forearm_link`, field `com.x`) or `kind.field` without a name (`scene.gravity.z`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathParts<'a> {
    /// `link`, `joint` or `scene`.
    pub kind: &'static str,
    /// The link or joint name (may contain dots and slashes); `None` for `scene` paths.
    pub name: Option<&'a str>,
    /// The field, possibly dotted: `mass`, `scale`, `com.x`, `origin.roll`, `gravity.z`, ….
    pub field: &'static str,
}

/// The parts of a target's path (see [`PathParts`]); [`path_of`] joins them with dots.
pub fn parts_of(model: &Model, target: ParamTarget) -> PathParts<'_> {
    let link = |l: usize| Some(model.description.links[l].name.as_str());
    let joint = |j: usize| Some(model.description.joints[j].name.as_str());
    let (kind, name, field) = match target {
        ParamTarget::LinkMass(l) => ("link", link(l), "mass"),
        ParamTarget::LinkScale(l) => ("link", link(l), "scale"),
        ParamTarget::LinkCom(l, c) => ("link", link(l), COM_PATHS[c]),
        ParamTarget::LinkInertia(l, c) => ("link", link(l), INERTIA_PATHS[c]),
        ParamTarget::JointOrigin(j, c) => ("joint", joint(j), ORIGIN_PATHS[c]),
        ParamTarget::JointAxis(j, c) => ("joint", joint(j), AXIS_PATHS[c]),
        ParamTarget::JointDamping(j) => ("joint", joint(j), "damping"),
        ParamTarget::JointFriction(j) => ("joint", joint(j), "friction"),
        ParamTarget::Gravity(c) => ("scene", None, GRAVITY_PATHS[c]),
        ParamTarget::Contact(c) => ("scene", None, CONTACT_PATHS[c]),
        // The element number is part of the path ([`path_of`]); the field part names the size.
        ParamTarget::CollisionSize(l, _, c) => ("link", link(l), COLLISION_FIELDS[c]),
    };
    PathParts { kind, name, field }
}

/// The dotted path of a target.
pub fn path_of(model: &Model, target: ParamTarget) -> String {
    if let ParamTarget::CollisionSize(l, k, c) = target {
        return format!(
            "link.{}.collision.{k}.{}",
            model.description.links[l].name, COLLISION_FIELDS[c]
        );
    }
    let parts = parts_of(model, target);
    match parts.name {
        Some(name) => format!("{}.{name}.{}", parts.kind, parts.field),
        None => format!("{}.{}", parts.kind, parts.field),
    }
}

/// The unit of a target's value.
pub fn unit_of(model: &Model, target: ParamTarget) -> &'static str {
    let prismatic = |j: usize| model.description.joints[j].joint_type == UrdfJointType::Prismatic;
    match target {
        ParamTarget::LinkMass(_) => "kg",
        ParamTarget::LinkScale(_) => "",
        ParamTarget::LinkCom(..) => "m",
        ParamTarget::LinkInertia(..) => "kg·m²",
        ParamTarget::JointOrigin(_, c) if c < 3 => "m",
        ParamTarget::JointOrigin(..) => "rad",
        ParamTarget::JointAxis(..) => "",
        ParamTarget::JointDamping(j) if prismatic(j) => "N·s/m",
        ParamTarget::JointDamping(_) => "N·m·s/rad",
        ParamTarget::JointFriction(j) if prismatic(j) => "N",
        ParamTarget::JointFriction(_) => "N·m",
        ParamTarget::Gravity(_) => "m/s²",
        ParamTarget::Contact(0) => "N/m^e",
        ParamTarget::Contact(2) => "s/m",
        ParamTarget::Contact(4) => "m/s",
        ParamTarget::Contact(_) => "",
        ParamTarget::CollisionSize(..) => "m",
    }
}

/// Every parameter of the model, in a stable order (the registry order): links (file order) with
/// mass, COM, inertia and scale; joints (file order) with origin, then axis, damping and friction
/// for moving joints; gravity.
///
/// Links without `<inertial>` are listed too (nominal 0, scale 1): declaring their mass is how a
/// payload is added to a frame such as `tool0`.
pub fn list(model: &Model, environment: &Environment) -> Vec<ParamInfo> {
    let mut targets = Vec::new();
    for l in 0..model.description.links.len() {
        targets.push(ParamTarget::LinkMass(l));
        targets.extend((0..3).map(|c| ParamTarget::LinkCom(l, c)));
        targets.extend((0..6).map(|c| ParamTarget::LinkInertia(l, c)));
        targets.push(ParamTarget::LinkScale(l));
    }
    for (j, spec) in model.description.joints.iter().enumerate() {
        targets.extend((0..6).map(|c| ParamTarget::JointOrigin(j, c)));
        if spec.joint_type.has_axis() {
            targets.extend((0..3).map(|c| ParamTarget::JointAxis(j, c)));
            targets.push(ParamTarget::JointDamping(j));
            targets.push(ParamTarget::JointFriction(j));
        }
    }
    targets.extend((0..3).map(ParamTarget::Gravity));
    if environment.contact.is_some() {
        targets.extend((0..CONTACT_FIELDS.len()).map(ParamTarget::Contact));
        for (l, link) in model.description.links.iter().enumerate() {
            for k in 0..link.collisions.len() {
                targets.extend(
                    collision_fields(model, l, k)
                        .iter()
                        .map(|&c| ParamTarget::CollisionSize(l, k, c)),
                );
            }
        }
    }
    targets
        .into_iter()
        .map(|target| ParamInfo {
            path: path_of(model, target),
            target,
            unit: unit_of(model, target),
        })
        .collect()
}

/// Resolves a dotted path; an unknown one gets the closest path of the registry as a suggestion.
pub fn resolve(
    model: &Model,
    environment: &Environment,
    path: &str,
) -> Result<ParamTarget, ParamError> {
    resolve_without_suggestion(model, environment, path).map_err(|error| match error {
        ParamError::Unknown { path, .. } => ParamError::Unknown {
            suggestion: closest_suggestion(
                &path,
                list(model, environment)
                    .iter()
                    .map(|p| p.path.as_str())
                    .collect::<Vec<_>>(),
            ),
            path,
        },
        other => other,
    })
}

/// [`resolve`] without the suggestion for an unknown path (its search of the whole registry costs
/// as much as listing it), for callers that try a key as a path and read it otherwise when it is
/// none.
pub fn resolve_without_suggestion(
    model: &Model,
    environment: &Environment,
    path: &str,
) -> Result<ParamTarget, ParamError> {
    let unknown = || ParamError::Unknown {
        path: path.to_string(),
        suggestion: String::new(),
    };
    if let Some(field) = path.strip_prefix("scene.gravity.") {
        return COM_FIELDS
            .iter()
            .position(|f| *f == field)
            .map(ParamTarget::Gravity)
            .ok_or_else(unknown);
    }
    if let Some(field) = path.strip_prefix("scene.contact.") {
        let c = CONTACT_FIELDS
            .iter()
            .position(|f| *f == field)
            .ok_or_else(unknown)?;
        if environment.contact.is_none() {
            return Err(ParamError::NotApplicable {
                path: path.to_string(),
                reason: "the scene declares no contacts; add a [scene.contact] table".to_string(),
            });
        }
        return Ok(ParamTarget::Contact(c));
    }
    if let Some(target) = resolve_collision(model, path)? {
        return Ok(target);
    }
    if let Some(rest) = path.strip_prefix("link.") {
        let mut fields: Vec<(String, u8, usize)> =
            vec![("mass".to_string(), 0, 0), ("scale".to_string(), 3, 0)];
        fields.extend(
            COM_FIELDS
                .iter()
                .enumerate()
                .map(|(c, f)| (format!("com.{f}"), 1, c)),
        );
        fields.extend(
            INERTIA_FIELDS
                .iter()
                .enumerate()
                .map(|(c, f)| (format!("inertia.{f}"), 2, c)),
        );
        for (field, kind, c) in fields {
            let Some(l) = name_before(rest, &field).and_then(|n| model.description.link_index(n))
            else {
                continue;
            };
            return Ok(match kind {
                0 => ParamTarget::LinkMass(l),
                1 => ParamTarget::LinkCom(l, c),
                2 => ParamTarget::LinkInertia(l, c),
                _ => ParamTarget::LinkScale(l),
            });
        }
        return Err(unknown());
    }
    if let Some(rest) = path.strip_prefix("joint.") {
        let description = &model.description;
        let mut fields: Vec<(String, u8, usize)> = ORIGIN_FIELDS
            .iter()
            .enumerate()
            .map(|(c, f)| (format!("origin.{f}"), 0u8, c))
            .collect();
        fields.extend(
            COM_FIELDS
                .iter()
                .enumerate()
                .map(|(c, f)| (format!("axis.{f}"), 1u8, c)),
        );
        fields.push(("damping".to_string(), 2, 0));
        fields.push(("friction".to_string(), 3, 0));
        for (field, kind, c) in fields {
            let Some(j) = name_before(rest, &field).and_then(|n| description.joint_index(n)) else {
                continue;
            };
            let spec = &description.joints[j];
            if kind > 0 && !spec.joint_type.has_axis() {
                return Err(ParamError::NotApplicable {
                    path: path.to_string(),
                    reason: format!(
                        "joint '{}' is {} and has no axis, damping or friction",
                        spec.name,
                        spec.joint_type.as_str()
                    ),
                });
            }
            return Ok(match kind {
                0 => ParamTarget::JointOrigin(j, c),
                1 => ParamTarget::JointAxis(j, c),
                2 => ParamTarget::JointDamping(j),
                _ => ParamTarget::JointFriction(j),
            });
        }
        return Err(unknown());
    }
    Err(unknown())
}

/// `link.NAME.collision.K.FIELD` (`None` when the path has another form).
fn resolve_collision(model: &Model, path: &str) -> Result<Option<ParamTarget>, ParamError> {
    let Some(rest) = path.strip_prefix("link.") else {
        return Ok(None);
    };
    for (c, field) in COLLISION_FIELDS.iter().enumerate() {
        let Some(before) = rest.strip_suffix(field).and_then(|r| r.strip_suffix('.')) else {
            continue;
        };
        let Some((name, number)) = before.rsplit_once(".collision.") else {
            continue;
        };
        let (Some(l), Ok(k)) = (model.description.link_index(name), number.parse::<usize>()) else {
            continue;
        };
        let not_applicable = |reason: String| ParamError::NotApplicable {
            path: path.to_string(),
            reason,
        };
        let n = model.description.links[l].collisions.len();
        if k >= n {
            return Err(not_applicable(format!(
                "link '{name}' has {n} <collision> element(s), numbered from 0"
            )));
        }
        if !collision_fields(model, l, k).contains(&c) {
            return Err(not_applicable(format!(
                "<collision> {k} of link '{name}' (line {}) has no {field}",
                model.description.links[l].collisions[k].line
            )));
        }
        return Ok(Some(ParamTarget::CollisionSize(l, k, c)));
    }
    Ok(None)
}

/// `NAME` in `NAME.field`, when `rest` ends with `.field`.
fn name_before<'a>(rest: &'a str, field: &str) -> Option<&'a str> {
    rest.strip_suffix(field).and_then(|n| n.strip_suffix('.'))
}

/// The current value of a target.
pub fn get(model: &Model, environment: &Environment, target: ParamTarget) -> f64 {
    let d = &model.description;
    match target {
        ParamTarget::LinkMass(l) => d.links[l].inertial.mass,
        ParamTarget::LinkScale(l) => model.inertial_scales[l],
        ParamTarget::LinkCom(l, c) => d.links[l].inertial.com[c],
        ParamTarget::LinkInertia(l, c) => d.links[l].inertial.inertia[c],
        ParamTarget::JointOrigin(j, c) => d.joints[j].origin[c],
        ParamTarget::JointAxis(j, c) => d.joints[j].axis[c],
        ParamTarget::JointDamping(j) => d.joints[j].damping,
        ParamTarget::JointFriction(j) => d.joints[j].friction,
        ParamTarget::Gravity(c) => environment.gravity[c],
        ParamTarget::Contact(c) => environment.contact.map_or(0.0, |m| contact_field(&m, c)),
        ParamTarget::CollisionSize(l, k, c) => {
            *collision_value(&mut d.links[l].collisions[k].shape.clone(), c)
        }
    }
}

/// Field `c` ([`CONTACT_FIELDS`]) of a contact material.
fn contact_field(m: &crate::environment::ContactMaterial, c: usize) -> f64 {
    match c {
        0 => m.stiffness,
        1 => m.exponent,
        2 => m.damping,
        3 => m.friction,
        _ => m.stiction_velocity,
    }
}

/// The size field `c` ([`COLLISION_FIELDS`]) of a collision shape (a shape without it — excluded
/// by [`resolve`] — gives a scratch value).
fn collision_value(shape: &mut crate::model::CollisionShape, c: usize) -> &mut f64 {
    use crate::model::CollisionShape;
    match (shape, c) {
        (CollisionShape::Sphere { radius }, _)
        | (CollisionShape::Cylinder { radius, .. }, 0)
        | (CollisionShape::Capsule { radius, .. }, 0) => radius,
        (CollisionShape::Cylinder { length, .. }, _)
        | (CollisionShape::Capsule { length, .. }, _) => length,
        (CollisionShape::Box { size }, c) => &mut size[c.clamp(2, 4) - 2],
        (CollisionShape::Mesh { .. } | CollisionShape::Unreadable { .. }, _) => {
            unreachable!("resolve() gives no size target for a mesh or an unreadable collision")
        }
    }
}

/// Writes one value into the model's description or the environment (not yet into the model's
/// derived tree: call [`Model::refresh`] after the last write, or use [`apply`]).
#[inline]
pub fn set(model: &mut Model, environment: &mut Environment, target: ParamTarget, value: f64) {
    let d = &mut model.description;
    match target {
        ParamTarget::LinkMass(l) => d.links[l].inertial.mass = value,
        ParamTarget::LinkScale(l) => model.inertial_scales[l] = value,
        ParamTarget::LinkCom(l, c) => d.links[l].inertial.com[c] = value,
        ParamTarget::LinkInertia(l, c) => d.links[l].inertial.inertia[c] = value,
        ParamTarget::JointOrigin(j, c) => d.joints[j].origin[c] = value,
        ParamTarget::JointAxis(j, c) => d.joints[j].axis[c] = value,
        ParamTarget::JointDamping(j) => d.joints[j].damping = value,
        ParamTarget::JointFriction(j) => d.joints[j].friction = value,
        ParamTarget::Gravity(c) => environment.gravity[c] = value,
        ParamTarget::Contact(c) => {
            if let Some(m) = environment.contact.as_mut() {
                *match c {
                    0 => &mut m.stiffness,
                    1 => &mut m.exponent,
                    2 => &mut m.damping,
                    3 => &mut m.friction,
                    _ => &mut m.stiction_velocity,
                } = value;
            }
        }
        ParamTarget::CollisionSize(l, k, c) => {
            *collision_value(&mut d.links[l].collisions[k].shape, c) = value;
        }
    }
}

/// Writes `values[i]` into `targets[i]` for all `i`, then refreshes the tree. Allocates nothing.
pub fn apply(
    model: &mut Model,
    environment: &mut Environment,
    targets: &[ParamTarget],
    values: &[f64],
) {
    for (target, value) in targets.iter().zip(values) {
        set(model, environment, *target, *value);
    }
    model.refresh();
}

/// Checks that a single value is possible for its target (finite; mass, damping and friction ≥ 0;
/// a scale > 0 — a scale of 0 would delete the link's mass, a negative one make it negative).
pub fn validate_value(model: &Model, target: ParamTarget, value: f64) -> Result<(), ParamError> {
    let invalid = |reason| ParamError::InvalidValue {
        path: path_of(model, target),
        value,
        reason,
    };
    if !value.is_finite() {
        return Err(invalid("every parameter must be a finite number"));
    }
    match target {
        ParamTarget::LinkMass(_) if value < 0.0 => Err(invalid("a mass must be ≥ 0")),
        ParamTarget::LinkScale(_) if value <= 0.0 => Err(invalid(
            "a scale must be > 0 (it multiplies the link's mass and inertia)",
        )),
        ParamTarget::JointDamping(_) if value < 0.0 => Err(invalid("damping must be ≥ 0")),
        ParamTarget::JointFriction(_) if value < 0.0 => Err(invalid("friction must be ≥ 0")),
        ParamTarget::Contact(0) if value <= 0.0 => Err(invalid("a contact stiffness must be > 0")),
        ParamTarget::Contact(1) if value < 1.0 => Err(invalid(
            "the Hunt–Crossley exponent must be ≥ 1 (1: linear, 1.5: Hertz)",
        )),
        ParamTarget::Contact(2) if value < 0.0 => Err(invalid("contact damping must be ≥ 0")),
        ParamTarget::Contact(3) if value < 0.0 => {
            Err(invalid("a friction coefficient must be ≥ 0"))
        }
        ParamTarget::Contact(4) if value <= 0.0 => Err(invalid("a stiction velocity must be > 0")),
        ParamTarget::CollisionSize(..) if value <= 0.0 => {
            Err(invalid("a collision size must be > 0"))
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions};

    fn model() -> Model {
        let text = r#"<robot name="r"><link name="world"/>
          <link name="iris__/imu_link"><inertial><mass value="2"/><origin xyz="0.1 0 0"/>
          <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
          <joint name="joint_0.0" type="prismatic"><parent link="world"/><child link="iris__/imu_link"/>
          <origin xyz="0 0 1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
          <link name="tip"/><joint name="fix" type="fixed"><parent link="iris__/imu_link"/><child link="tip"/></joint>
          </robot>"#;
        Model::from_description(
            parse_description(text, "r.urdf").unwrap(),
            LoadOptions::default(),
            "r.urdf",
        )
        .unwrap()
    }

    #[test]
    fn names_with_dots_and_slashes_resolve() {
        let m = model();
        let e = Environment::default();
        assert_eq!(
            resolve(&m, &e, "link.iris__/imu_link.mass").unwrap(),
            ParamTarget::LinkMass(1)
        );
        assert_eq!(
            resolve(&m, &e, "link.iris__/imu_link.com.x").unwrap(),
            ParamTarget::LinkCom(1, 0)
        );
        assert_eq!(
            resolve(&m, &e, "link.iris__/imu_link.inertia.iyz").unwrap(),
            ParamTarget::LinkInertia(1, 4)
        );
        assert_eq!(
            resolve(&m, &e, "joint.joint_0.0.origin.z").unwrap(),
            ParamTarget::JointOrigin(0, 2)
        );
        assert_eq!(
            resolve(&m, &e, "joint.joint_0.0.damping").unwrap(),
            ParamTarget::JointDamping(0)
        );
        assert_eq!(
            resolve(&m, &e, "scene.gravity.z").unwrap(),
            ParamTarget::Gravity(2)
        );
    }

    #[test]
    fn every_listed_path_resolves_to_itself() {
        let m = model();
        let e = Environment::default();
        let listed = list(&m, &e);
        for p in &listed {
            assert_eq!(resolve(&m, &e, &p.path).unwrap(), p.target, "{}", p.path);
        }
        // Not vacuous: every kind of target is listed, every path once.
        let kinds = [
            ParamTarget::LinkMass(1),
            ParamTarget::LinkScale(1),
            ParamTarget::LinkCom(1, 0),
            ParamTarget::LinkInertia(1, 5),
            ParamTarget::JointOrigin(0, 5),
            ParamTarget::JointAxis(0, 2),
            ParamTarget::JointDamping(0),
            ParamTarget::JointFriction(0),
            ParamTarget::Gravity(2),
        ];
        for kind in kinds {
            assert!(
                listed.iter().any(|p| p.target == kind),
                "{kind:?} not listed"
            );
        }
        let mut paths: Vec<&str> = listed.iter().map(|p| p.path.as_str()).collect();
        paths.sort_unstable();
        paths.dedup();
        assert_eq!(paths.len(), listed.len(), "a path listed twice");
    }

    #[test]
    fn unknown_paths_get_suggestions() {
        let m = model();
        let e = Environment::default();
        let msg = resolve(&m, &e, "joint.joint_0.0.orgin.z")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("did you mean 'joint.joint_0.0.origin.z'"),
            "{msg}"
        );
        let msg = resolve(&m, &e, "joint.fix.axis.x").unwrap_err().to_string();
        assert!(msg.contains("joint 'fix' is fixed"), "{msg}");
    }

    #[test]
    fn scale_is_a_parameter_like_any_other() {
        let mut m = model();
        let mut e = Environment::default();
        let target = resolve(&m, &e, "link.iris__/imu_link.scale").unwrap();
        assert_eq!(target, ParamTarget::LinkScale(1));
        assert_eq!(path_of(&m, target), "link.iris__/imu_link.scale");
        assert_eq!((get(&m, &e, target), unit_of(&m, target)), (1.0, ""));
        let listed: Vec<String> = list(&m, &e).into_iter().map(|p| p.path).collect();
        let mass = listed.iter().position(|p| p == "link.iris__/imu_link.mass");
        let scale = listed
            .iter()
            .position(|p| p == "link.iris__/imu_link.scale");
        // Registry order within a link: mass, com, inertia, scale.
        assert_eq!(scale, mass.map(|m| m + 10));
        apply(&mut m, &mut e, &[target], &[1.5]);
        assert_eq!(m.bodies[0].inertia.mass, 3.0);
        assert_eq!(m.description.links[1].inertial.mass, 2.0);
        for bad in [0.0, -1.0, f64::NAN] {
            let message = validate_value(&m, target, bad).unwrap_err().to_string();
            assert!(
                message.contains("link.iris__/imu_link.scale")
                    && (message.contains("a scale must be > 0") || bad.is_nan()),
                "{message}"
            );
        }
    }

    #[test]
    fn apply_changes_the_tree() {
        let mut m = model();
        let mut e = Environment::default();
        let targets = [
            resolve(&m, &e, "link.iris__/imu_link.mass").unwrap(),
            resolve(&m, &e, "joint.joint_0.0.origin.z").unwrap(),
        ];
        apply(&mut m, &mut e, &targets, &[3.0, 2.0]);
        assert_eq!(m.bodies[0].inertia.mass, 3.0);
        assert_eq!(m.joints[0].parent_from_joint.translation.z, 2.0);
        assert!(validate_value(&m, targets[0], -1.0).is_err());
    }
}
