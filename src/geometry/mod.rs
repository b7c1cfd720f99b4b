//! The geometry model of contacts (docs/contacts.md §1), beside [`crate::model`] the way Pinocchio
//! keeps a `GeometryModel` beside its `Model`: shapes attached to links (from URDF `<collision>`)
//! and fixed scene shapes (from `[[scene.geometry]]`), the pairs the sidecar allows to touch, and
//! per-evaluation placements computed from the body placements the dynamics already has.
//!
//! Collision sizes are read from `model.description` at every query, so that a parameter
//! (`link.NAME.collision.K.radius`, …) takes effect without rebuilding anything. Queries go through
//! `parry3d-f64` (`query.rs`, the only file that sees parry's glam types).

mod query;

pub use query::{contact_between, supported, ContactPoint, PairTest};

use crate::model::{CollisionShape, Model};
use crate::spatial::{Transform, Vec3};
use thiserror::Error;

/// Contact material of a scene: Hunt–Crossley normal force and regularised Coulomb friction
/// (docs/contacts.md §2–§3). One material for every declared pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMaterial {
    /// `k` of `f_n = k δ^e (1 + d δ̇)`, N/m^e (N/m^1.5 for the Hertz exponent).
    pub stiffness: f64,
    /// Exponent `e` of the penetration (1.5: Hertz; 1: linear), unitless, ≥ 1.
    pub exponent: f64,
    /// Hunt–Crossley dissipation `d`, s/m (restitution `e(v)` from docs/contacts.md §2).
    pub damping: f64,
    /// Coulomb friction coefficient `μ`, unitless, ≥ 0.
    pub friction: f64,
    /// Stiction velocity `v_s` of the regularised friction `−μ f_n v_t / √(|v_t|² + v_s²)`, m/s.
    pub stiction_velocity: f64,
}

/// Default contact stiffness, N/m^1.5: a 1 kg body rests on a sphere of it about 0.2 mm deep
/// (`(m g / k)^(2/3)`), Drake's default penetration allowance is 1 mm.
pub const DEFAULT_CONTACT_STIFFNESS: f64 = 1e6;
/// Default Hunt–Crossley exponent (Hertz contact of a sphere).
pub const DEFAULT_CONTACT_EXPONENT: f64 = 1.5;
/// Default Hunt–Crossley dissipation, s/m: restitution ≈ 0.6 at 1 m/s (docs/contacts.md §2);
/// Drake documents values of order 1 s/m for its point contact's `hunt_crossley_dissipation`.
pub const DEFAULT_CONTACT_DAMPING: f64 = 0.5;
/// Default friction coefficient (Chrono's default static and sliding friction, 0.6).
pub const DEFAULT_CONTACT_FRICTION: f64 = 0.6;
/// Default stiction velocity, m/s (Drake's default stiction tolerance is 1e-3 m/s; ribbon's
/// implicit integrator affords ten times less creep).
pub const DEFAULT_STICTION_VELOCITY: f64 = 1e-4;

impl Default for ContactMaterial {
    fn default() -> Self {
        Self {
            stiffness: DEFAULT_CONTACT_STIFFNESS,
            exponent: DEFAULT_CONTACT_EXPONENT,
            damping: DEFAULT_CONTACT_DAMPING,
            friction: DEFAULT_CONTACT_FRICTION,
            stiction_velocity: DEFAULT_STICTION_VELOCITY,
        }
    }
}

/// A primitive shape in its own frame, in URDF conventions: box centred on the origin; cylinder
/// and capsule along z; half-space `z ≤ 0` (outward normal +z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A sphere of radius `radius`, m.
    Sphere {
        /// Radius, m.
        radius: f64,
    },
    /// A box with half edge lengths along x, y, z, m.
    Box {
        /// Half edge lengths, m.
        half_extents: [f64; 3],
    },
    /// A cylinder along z, m.
    Cylinder {
        /// Radius, m.
        radius: f64,
        /// Half of its length along z, m.
        half_length: f64,
    },
    /// A capsule along z (a segment of length `2 half_length` swept by a sphere), m.
    Capsule {
        /// Radius, m.
        radius: f64,
        /// Half the length of its segment, m.
        half_length: f64,
    },
    /// The half-space `z ≤ 0` of its frame (a ground without edges).
    HalfSpace,
}

/// A shape with its placement in the world frame.
pub type PlacedShape = (Shape, Transform);

/// A fixed shape of the scene (`[[scene.geometry]]`), placed in the world frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// Its name in the sidecar.
    pub name: String,
    /// Its shape.
    pub shape: Shape,
    /// Its frame in the world frame.
    pub world_from_shape: Transform,
}

/// What a geometry object is attached to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Attachment {
    /// `<collision>` number `collision` of URDF link `link` (indices into `description.links` and
    /// its `collisions`).
    Link {
        /// The URDF link.
        link: usize,
        /// The collision element of that link.
        collision: usize,
    },
    /// Scene object `0` (index into [`GeometryModel::scene`]).
    Scene(usize),
}

/// One pair of shapes that may touch: `a` is always on a link, `b` on a link or in the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPair {
    /// The first shape (on a link).
    pub a: Attachment,
    /// The second shape.
    pub b: Attachment,
    /// `a`'s shape frame in its link frame (its `<collision><origin>`; not a parameter, so kept).
    pub link_from_a: Transform,
    /// `b`'s shape frame in its link frame, or in the world for a scene shape.
    pub link_from_b: Transform,
}

/// The shapes and pairs of one scene; only [`GeometryModel::pairs`] are ever queried.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeometryModel {
    /// Scene objects.
    pub scene: Vec<SceneObject>,
    /// Declared pairs, expanded to shapes (a link with two `<collision>` elements gives two pairs).
    pub pairs: Vec<ContactPair>,
}

/// Why a contact declaration was refused.
#[derive(Debug, Error, PartialEq)]
pub enum GeometryError {
    /// A name in `pairs` that is neither a link nor a scene object.
    #[error("'{name}' is neither a link of the robot nor a [[scene.geometry]] name{suggestion}")]
    UnknownBody {
        /// The name given.
        name: String,
        /// "; did you mean '…'?" or empty.
        suggestion: String,
    },
    /// A link named in a pair without any `<collision>`.
    #[error("link '{link}' has no <collision> element; give it one (sphere, box, cylinder or capsule) or remove the pair")]
    NoCollision {
        /// The link.
        link: String,
    },
    /// A `<collision>` ribbon cannot use.
    #[error("link '{link}' <collision> at line {line}: {reason}")]
    UnsupportedCollision {
        /// The link.
        link: String,
        /// Its line in the URDF.
        line: u32,
        /// What is wrong and what to do.
        reason: String,
    },
    /// A pair ribbon cannot evaluate (two scene objects, a link with itself).
    #[error("pair ['{a}', '{b}']: {reason}")]
    BadPair {
        /// First name.
        a: String,
        /// Second name.
        b: String,
        /// Why.
        reason: String,
    },
}

/// The shape of collision `collision` of link `link` at the model's current values.
///
/// Errors: meshes (not supported yet), unreadable markup, sizes that are not finite and > 0.
pub fn link_shape(model: &Model, link: usize, collision: usize) -> Result<Shape, GeometryError> {
    let spec = &model.description.links[link];
    let element = &spec.collisions[collision];
    let unsupported = |reason: String| GeometryError::UnsupportedCollision {
        link: spec.name.clone(),
        line: element.line,
        reason,
    };
    let positive = |what: &str, x: f64| {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(unsupported(format!(
                "{what} = {x} must be a finite number > 0 m"
            )))
        }
    };
    Ok(match &element.shape {
        CollisionShape::Sphere { radius } => Shape::Sphere {
            radius: positive("radius", *radius)?,
        },
        CollisionShape::Box { size } => Shape::Box {
            half_extents: [
                0.5 * positive("size x", size[0])?,
                0.5 * positive("size y", size[1])?,
                0.5 * positive("size z", size[2])?,
            ],
        },
        CollisionShape::Cylinder { radius, length } => Shape::Cylinder {
            radius: positive("radius", *radius)?,
            half_length: 0.5 * positive("length", *length)?,
        },
        CollisionShape::Capsule { radius, length } => Shape::Capsule {
            radius: positive("radius", *radius)?,
            half_length: 0.5 * positive("length", *length)?,
        },
        CollisionShape::Mesh { filename } => {
            return Err(unsupported(format!(
                "<mesh filename=\"{filename}\">: meshes are not supported for contacts yet; \
                 give the link a primitive <collision> (sphere, box, cylinder or capsule)"
            )))
        }
        CollisionShape::Unreadable { reason } => return Err(unsupported(reason.clone())),
    })
}

/// The frame of collision `collision` of link `link` in that link's frame (its `<origin>`).
pub fn link_from_collision(model: &Model, link: usize, collision: usize) -> Transform {
    let o = model.description.links[link].collisions[collision].origin;
    Transform::from_xyz_rpy([o[0], o[1], o[2]], [o[3], o[4], o[5]])
}

impl GeometryModel {
    /// Builds the geometry of `pairs` (names of links or of `scene` objects; each link expands to
    /// all its `<collision>` elements). Checks that every shape is supported at the model's
    /// current sizes.
    pub fn new(
        model: &Model,
        scene: Vec<SceneObject>,
        pairs: &[[String; 2]],
    ) -> Result<GeometryModel, GeometryError> {
        let mut out = GeometryModel {
            scene,
            pairs: Vec::new(),
        };
        for [a, b] in pairs {
            let left = out.attachments(model, a)?;
            let right = out.attachments(model, b)?;
            let bad = |reason: &str| GeometryError::BadPair {
                a: a.clone(),
                b: b.clone(),
                reason: reason.to_string(),
            };
            if a == b {
                return Err(bad("a body cannot touch itself"));
            }
            let on_link = |x: &Attachment| matches!(x, Attachment::Link { .. });
            let (first, second) = match (left.first(), right.first()) {
                (Some(l), _) if on_link(l) => (&left, &right),
                (_, Some(r)) if on_link(r) => (&right, &left),
                _ => {
                    return Err(bad(
                        "two scene objects never move; name a link in every pair",
                    ))
                }
            };
            for x in first {
                for y in second {
                    if let (Attachment::Link { link: l1, .. }, Attachment::Link { link: l2, .. }) =
                        (x, y)
                    {
                        if model.links[*l1].body == model.links[*l2].body {
                            return Err(bad(
                                "both links are on one rigid body (joined by fixed joints); they cannot move against each other",
                            ));
                        }
                    }
                    let pair = ContactPair {
                        a: *x,
                        b: *y,
                        link_from_a: out.frame_of(model, *x),
                        link_from_b: out.frame_of(model, *y),
                    };
                    if !supported(&out.shape_of(model, *x)?, &out.shape_of(model, *y)?) {
                        return Err(bad(&format!(
                            "parry cannot compute contacts between {} and {}",
                            out.describe(model, *x),
                            out.describe(model, *y)
                        )));
                    }
                    if !out.pairs.contains(&pair) {
                        out.pairs.push(pair);
                    }
                }
            }
        }
        Ok(out)
    }

    /// The shapes a pair name stands for.
    fn attachments(&self, model: &Model, name: &str) -> Result<Vec<Attachment>, GeometryError> {
        if let Some(i) = self.scene.iter().position(|s| s.name == name) {
            return Ok(vec![Attachment::Scene(i)]);
        }
        let Some(link) = model.description.link_index(name) else {
            let names = model
                .description
                .links
                .iter()
                .map(|l| l.name.as_str())
                .chain(self.scene.iter().map(|s| s.name.as_str()));
            return Err(GeometryError::UnknownBody {
                name: name.to_string(),
                suggestion: crate::text::closest_suggestion(name, names),
            });
        };
        let n = model.description.links[link].collisions.len();
        if n == 0 {
            return Err(GeometryError::NoCollision {
                link: name.to_string(),
            });
        }
        for collision in 0..n {
            link_shape(model, link, collision)?;
        }
        Ok((0..n)
            .map(|collision| Attachment::Link { link, collision })
            .collect())
    }

    /// The shape frame of `attachment` in its link frame (a scene shape: in the world frame).
    fn frame_of(&self, model: &Model, attachment: Attachment) -> Transform {
        match attachment {
            Attachment::Scene(i) => self.scene[i].world_from_shape,
            Attachment::Link { link, collision } => link_from_collision(model, link, collision),
        }
    }

    /// Shape and world placement of both sides of `pair` (see [`GeometryModel::placed`]), with
    /// the pair's stored shape frames.
    pub fn placed_pair(
        &self,
        model: &Model,
        world_from_body: &[Transform],
        pair: &ContactPair,
    ) -> Result<[PlacedShape; 2], GeometryError> {
        let side = |attachment: Attachment,
                    frame: &Transform|
         -> Result<(Shape, Transform), GeometryError> {
            match attachment {
                Attachment::Scene(i) => Ok((self.scene[i].shape, *frame)),
                Attachment::Link { link, collision } => {
                    let shape = link_shape(model, link, collision)?;
                    let placement = &model.links[link];
                    let world_from_link = match placement.body {
                        Some(b) => world_from_body[b].compose(&placement.body_from_link),
                        None => placement.body_from_link,
                    };
                    Ok((shape, world_from_link.compose(frame)))
                }
            }
        };
        Ok([
            side(pair.a, &pair.link_from_a)?,
            side(pair.b, &pair.link_from_b)?,
        ])
    }

    /// The shape of `attachment` at the model's current sizes.
    pub fn shape_of(&self, model: &Model, attachment: Attachment) -> Result<Shape, GeometryError> {
        match attachment {
            Attachment::Scene(i) => Ok(self.scene[i].shape),
            Attachment::Link { link, collision } => link_shape(model, link, collision),
        }
    }

    /// The shape and world placement of `attachment` at the model's current values and the body
    /// placements of the last kinematics pass in `world_from_body` (one per body).
    pub fn placed(
        &self,
        model: &Model,
        world_from_body: &[Transform],
        attachment: Attachment,
    ) -> Result<(Shape, Transform), GeometryError> {
        match attachment {
            Attachment::Scene(i) => Ok((self.scene[i].shape, self.scene[i].world_from_shape)),
            Attachment::Link { link, collision } => {
                let shape = link_shape(model, link, collision)?;
                let placement = &model.links[link];
                let world_from_link = match placement.body {
                    Some(b) => world_from_body[b].compose(&placement.body_from_link),
                    None => placement.body_from_link,
                };
                Ok((
                    shape,
                    world_from_link.compose(&link_from_collision(model, link, collision)),
                ))
            }
        }
    }

    /// The body that moves `attachment` (`None`: the world or the scene).
    pub fn body_of(model: &Model, attachment: Attachment) -> Option<usize> {
        match attachment {
            Attachment::Scene(_) => None,
            Attachment::Link { link, .. } => model.links[link].body,
        }
    }

    /// A readable name of `attachment` (`link 'foot'`, `scene object 'ground'`).
    pub fn describe(&self, model: &Model, attachment: Attachment) -> String {
        match attachment {
            Attachment::Scene(i) => format!("scene object '{}'", self.scene[i].name),
            Attachment::Link { link, .. } => {
                format!("link '{}'", model.description.links[link].name)
            }
        }
    }
}

/// The unit vector `v / |v|`, or `fallback` when `|v|` is not a usable length.
pub(crate) fn normalized_or(v: Vec3, fallback: Vec3) -> Vec3 {
    let n = v.norm();
    if n.is_finite() && n > 1e-300 {
        v / n
    } else {
        fallback
    }
}
