//! The geometry model of contacts (docs/contacts.md §1), beside [`crate::model`] the way Pinocchio
//! keeps a `GeometryModel` beside its `Model`: shapes attached to links (from URDF `<collision>`)
//! and fixed scene shapes (from `[[scene.geometry]]`), the pairs the sidecar allows to touch, and
//! per-evaluation placements computed from the body placements the dynamics already has.
//!
//! Collision sizes are read from `model.description` at every query, so that a parameter
//! (`link.NAME.collision.K.radius`, …) takes effect without rebuilding anything. Queries go through
//! `parry3d-f64` (`query.rs`, the only file that sees parry's glam types).

mod mesh;
mod query;

pub use mesh::{resolve_mesh_path, CONCAVITY_NOTE_RELATIVE};
use query::bounding_radius;
pub use query::{
    contact_between, separation, supported, ContactPoint, ContactPoints, ConvexHull, HeightGrid,
    PairTest, DUPLICATE_POINT_M, MAX_CONTACT_POINTS,
};
use std::sync::Arc;

use crate::model::{CollisionShape, Model};
use crate::spatial::{Transform, Vec3};
use thiserror::Error;

pub use crate::environment::{
    ContactMaterial, DEFAULT_CONTACT_DAMPING, DEFAULT_CONTACT_EXPONENT, DEFAULT_CONTACT_FRICTION,
    DEFAULT_CONTACT_STIFFNESS, DEFAULT_STICTION_VELOCITY,
};

/// Relative margin of [`GeometryModel::provably_apart`]: the gap between bounding spheres must
/// exceed this times the lengths the sphere centres are computed from (m) before a pair is skipped.
/// The cheap and the full computation of a centre differ by rounding only (a few ulps, ~1e-15 of
/// those lengths, for rotation matrices whose entries are at most 1 in size); 1e-9 leaves a factor
/// of about a million, and costs nothing: it is a nanometre on a metre-sized robot.
pub const BOUNDING_TEST_MARGIN: f64 = 1e-9;

/// A shape in its own frame, in URDF conventions: box centred on the origin; cylinder and capsule
/// along z; half-space `z ≤ 0` (outward normal +z); a mesh's convex hull in the mesh frame.
#[derive(Clone, Debug, PartialEq)]
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
    /// The convex hull of a collision mesh's scaled vertices (docs/contacts.md §1, "Meshes"),
    /// shared: loaded once per scene.
    ConvexHull(Arc<ConvexHull>),
    /// A height field (docs/contacts.md §1, "Height fields"): a grid of heights over a rectangle
    /// of its frame's x–y plane, the solid below; scene geometry only.
    HeightField(Arc<HeightGrid>),
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

/// The convex hull of mesh `<collision>` number `collision` of link `link`.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkHull {
    /// The URDF link (index into `description.links`).
    pub link: usize,
    /// The collision element of that link.
    pub collision: usize,
    /// The hull (scaled, in the collision frame).
    pub hull: Arc<ConvexHull>,
}

/// The shapes and pairs of one scene; only [`GeometryModel::pairs`] are ever queried.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeometryModel {
    /// Scene objects.
    pub scene: Vec<SceneObject>,
    /// Declared pairs, expanded to shapes (a link with two `<collision>` elements gives two pairs).
    pub pairs: Vec<ContactPair>,
    /// Hulls of the mesh collisions of the links in `pairs`, loaded once by
    /// [`GeometryModel::new`] (no other mesh is ever read).
    pub hulls: Vec<LinkHull>,
    /// One note per hulled mesh that encloses less than its hull (a concave mesh: contacts see the
    /// larger hull), naming the link, the file and both volumes. The commands print them as
    /// `note: …` (through [`crate::setup`]'s message callback).
    pub notes: Vec<String>,
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
    /// A mesh `<collision>` that cannot become a convex hull (file missing or unreadable,
    /// unsupported format, no vertices, all vertices on one plane).
    #[error(
        "{urdf}: link '{link}' <collision> {collision} (line {line}), mesh file '{path}': {reason}"
    )]
    Mesh {
        /// The URDF file.
        urdf: String,
        /// The link.
        link: String,
        /// Index of the `<collision>` element in the link (0 = first).
        collision: usize,
        /// Its line in the URDF.
        line: u32,
        /// The path the mesh file name resolved to.
        path: String,
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

/// The primitive shape of collision `collision` of link `link` at the model's current values.
///
/// Errors: meshes (they are loaded once by [`GeometryModel::new`]; ask
/// [`GeometryModel::shape_of`]), unreadable markup, sizes that are not finite and > 0.
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
        CollisionShape::Mesh { filename, .. } => {
            return Err(unsupported(format!(
                "<mesh filename=\"{filename}\"> is loaded by the scene's geometry model \
                 (GeometryModel::new), not here"
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
            hulls: Vec::new(),
            notes: Vec::new(),
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
    fn attachments(&mut self, model: &Model, name: &str) -> Result<Vec<Attachment>, GeometryError> {
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
            self.load_hull(model, link, collision)?;
            self.link_shape(model, link, collision)?;
        }
        Ok((0..n)
            .map(|collision| Attachment::Link { link, collision })
            .collect())
    }

    /// Loads the hull of collision `collision` of `link` when it is a mesh not loaded yet.
    fn load_hull(
        &mut self,
        model: &Model,
        link: usize,
        collision: usize,
    ) -> Result<(), GeometryError> {
        let spec = &model.description.links[link];
        let element = &spec.collisions[collision];
        let CollisionShape::Mesh { filename, scale } = &element.shape else {
            return Ok(());
        };
        if self.hull_of(link, collision).is_some() {
            return Ok(());
        }
        let urdf = &model.description.path;
        let loaded =
            mesh::load_mesh(urdf, filename, *scale).map_err(|problem| GeometryError::Mesh {
                urdf: urdf.clone(),
                link: spec.name.clone(),
                collision,
                line: element.line,
                path: problem.path,
                reason: problem.reason,
            })?;
        if let Some((hull_volume, mesh_volume)) = loaded.concave {
            let note = format!(
                "{urdf}: link '{}' <collision> {collision} (line {}), mesh '{}': contacts use its convex hull ({hull_volume:.6e} m³), which over-approximates the mesh ({mesh_volume:.6e} m³ enclosed, {:.1} % of the hull; docs/contacts.md §1)",
                spec.name,
                element.line,
                loaded.path,
                100.0 * mesh_volume / hull_volume
            );
            self.notes.push(note);
        }
        self.hulls.push(LinkHull {
            link,
            collision,
            hull: Arc::new(loaded.hull),
        });
        Ok(())
    }

    /// The loaded hull of mesh collision `collision` of `link`, if any.
    fn hull_of(&self, link: usize, collision: usize) -> Option<&Arc<ConvexHull>> {
        self.hulls
            .iter()
            .find(|h| h.link == link && h.collision == collision)
            .map(|h| &h.hull)
    }

    /// The shape of collision `collision` of `link`: its loaded hull for a mesh, else
    /// [`link_shape`] at the model's current sizes.
    fn link_shape(
        &self,
        model: &Model,
        link: usize,
        collision: usize,
    ) -> Result<Shape, GeometryError> {
        match self.hull_of(link, collision) {
            Some(hull) => Ok(Shape::ConvexHull(Arc::clone(hull))),
            None => link_shape(model, link, collision),
        }
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
                Attachment::Scene(i) => Ok((self.scene[i].shape.clone(), *frame)),
                Attachment::Link { link, collision } => {
                    let shape = self.link_shape(model, link, collision)?;
                    let world_from_link = model.links[link].world_from_link(world_from_body);
                    Ok((shape, world_from_link.compose(frame)))
                }
            }
        };
        Ok([
            side(pair.a, &pair.link_from_a)?,
            side(pair.b, &pair.link_from_b)?,
        ])
    }

    /// Whether `pair` provably passes no bounding-sphere test at the body placements
    /// `world_from_body`: a cheaper test than [`contact_between`]'s first step, which never answers
    /// `true` where that step would let the pair through to parry (docs/contacts.md §4, "A cheaper
    /// first test"). `false` means "test it".
    ///
    /// Only the centres of the bounding spheres are computed, as `R_wb (R_bl t_lc + t_bl) + t_wb`
    /// instead of composing the two rotations first; the two orders differ by rounding only, far
    /// below [`BOUNDING_TEST_MARGIN`] times the lengths involved, which the gap must exceed.
    #[inline]
    pub fn provably_apart(
        &self,
        model: &Model,
        world_from_body: &[Transform],
        pair: &ContactPair,
    ) -> bool {
        let Some((radius_a, centre_a, scale_a)) =
            self.bounding_sphere(model, world_from_body, pair.a, &pair.link_from_a)
        else {
            return false;
        };
        let (radius_b, centre_b, scale_b, half_space_normal) = match pair.b {
            Attachment::Scene(i) => {
                let object = &self.scene[i];
                let t = &pair.link_from_b;
                let normal = matches!(object.shape, Shape::HalfSpace)
                    .then(|| t.rotation.column(2).into_owned());
                let radius = if normal.is_some() {
                    0.0
                } else {
                    bounding_radius(&object.shape)
                };
                (radius, t.translation, sum_abs(&t.translation), normal)
            }
            Attachment::Link { .. } => {
                let Some((radius, centre, scale)) =
                    self.bounding_sphere(model, world_from_body, pair.b, &pair.link_from_b)
                else {
                    return false;
                };
                (radius, centre, scale, None)
            }
        };
        let margin = BOUNDING_TEST_MARGIN * (1.0 + scale_a + scale_b + radius_a + radius_b);
        let gap = match half_space_normal {
            Some(normal) => normal.dot(&(centre_a - centre_b)) - radius_a,
            None => (centre_a - centre_b).norm() - radius_a - radius_b,
        };
        // NaN anywhere makes the comparison false: then the full test runs.
        gap > margin
    }

    /// Bounding radius, world centre and a length scale (the sum of the absolute coordinates of
    /// the translations the centre is made of, m) of a link's shape; `None` for a scene shape or
    /// a mesh. The radius is [`query`]'s bounding radius of [`link_shape`]'s shape, computed the
    /// same way from the sizes without checking them (invalid sizes make the full test answer "no
    /// contact" too).
    #[inline]
    fn bounding_sphere(
        &self,
        model: &Model,
        world_from_body: &[Transform],
        attachment: Attachment,
        link_from_shape: &Transform,
    ) -> Option<(f64, Vec3, f64)> {
        let Attachment::Link { link, collision } = attachment else {
            return None;
        };
        let shape = match model.description.links[link].collisions[collision].shape {
            CollisionShape::Sphere { radius } => Shape::Sphere { radius },
            CollisionShape::Box { size } => Shape::Box {
                half_extents: [0.5 * size[0], 0.5 * size[1], 0.5 * size[2]],
            },
            CollisionShape::Cylinder { radius, length } => Shape::Cylinder {
                radius,
                half_length: 0.5 * length,
            },
            CollisionShape::Capsule { radius, length } => Shape::Capsule {
                radius,
                half_length: 0.5 * length,
            },
            _ => return None,
        };
        let radius = bounding_radius(&shape);
        let placement = &model.links[link];
        let in_body = placement
            .body_from_link
            .transform_point(&link_from_shape.translation);
        let scale =
            sum_abs(&link_from_shape.translation) + sum_abs(&placement.body_from_link.translation);
        Some(match placement.body {
            Some(b) => {
                let world_from = &world_from_body[b];
                (
                    radius,
                    world_from.transform_point(&in_body),
                    scale + sum_abs(&world_from.translation),
                )
            }
            None => (radius, in_body, scale),
        })
    }

    /// The shape of `attachment` at the model's current sizes.
    pub fn shape_of(&self, model: &Model, attachment: Attachment) -> Result<Shape, GeometryError> {
        match attachment {
            Attachment::Scene(i) => Ok(self.scene[i].shape.clone()),
            Attachment::Link { link, collision } => self.link_shape(model, link, collision),
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
            Attachment::Scene(i) => {
                Ok((self.scene[i].shape.clone(), self.scene[i].world_from_shape))
            }
            Attachment::Link { link, collision } => {
                let shape = self.link_shape(model, link, collision)?;
                let world_from_link = model.links[link].world_from_link(world_from_body);
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

/// `|x| + |y| + |z|` of `v` (an upper bound of its length), m.
fn sum_abs(v: &Vec3) -> f64 {
    v.x.abs() + v.y.abs() + v.z.abs()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, Data};
    use crate::model::{parse_description, LoadOptions};

    /// An arm swinging a box (offset collision origin, on a link fixed to the moving body) and a
    /// capsule over a tilted half-space and a sphere.
    const ARM: &str = r#"<robot name="arm"><link name="world"/>
      <joint name="lift" type="prismatic"><parent link="world"/><child link="carriage"/>
        <axis xyz="0 0 1"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>
      <link name="carriage"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
      <joint name="swing" type="revolute"><parent link="carriage"/><child link="upper"/>
        <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0.6 0 0.8"/>
        <limit lower="-10" upper="10" effort="1" velocity="1"/></joint>
      <link name="upper"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
        <collision><origin xyz="0.7 -0.1 0.05" rpy="0.4 0.5 0.6"/>
          <geometry><capsule radius="0.05" length="0.3"/></geometry></collision></link>
      <joint name="weld" type="fixed"><parent link="upper"/><child link="hand"/>
        <origin xyz="0.9 0.1 -0.2" rpy="0.1 0.2 0.3"/></joint>
      <link name="hand"><collision><origin xyz="0.05 0.02 -0.01" rpy="0.7 0.1 -0.3"/>
        <geometry><box size="0.1 0.2 0.05"/></geometry></collision></link></robot>"#;

    /// The cheap test never skips a pair that the full bounding-sphere test lets through to parry,
    /// over configurations sweeping every pair across its boundary in steps of 1e-12 m and more.
    #[test]
    fn provably_apart_never_skips_a_pair_the_full_test_keeps() {
        let model = Model::from_description(
            parse_description(ARM, "arm.urdf").unwrap(),
            LoadOptions::default(),
            "arm.urdf",
        )
        .unwrap();
        let scene = vec![
            SceneObject {
                name: "slope".into(),
                shape: Shape::HalfSpace,
                world_from_shape: Transform::from_xyz_rpy([0.3, -0.2, 0.0], [0.2, -0.1, 0.0]),
            },
            SceneObject {
                name: "post".into(),
                shape: Shape::Sphere { radius: 0.25 },
                world_from_shape: Transform::from_xyz_rpy([1.0, 0.5, 0.2], [0.0, 0.0, 0.0]),
            },
        ];
        let names = |a: &str, b: &str| [a.to_string(), b.to_string()];
        let geometry = GeometryModel::new(
            &model,
            scene,
            &[
                names("upper", "slope"),
                names("hand", "slope"),
                names("upper", "post"),
                names("hand", "post"),
            ],
        )
        .unwrap();
        let mut data = Data::new(&model);
        let (mut skipped, mut kept_near_boundary) = (0, 0);
        for i in 0..400 {
            let swing = -3.0 + 0.015 * f64::from(i);
            for j in 0..200 {
                // Heights around every boundary: coarse, then fine steps.
                let lift = -1.5 + 0.015 * f64::from(j) + 1e-12 * f64::from(i % 7);
                forward_kinematics(&model, &mut data, &[lift, swing]);
                for pair in &geometry.pairs {
                    let [(a, world_from_a), (b, world_from_b)] = geometry
                        .placed_pair(&model, &data.world_from_body, pair)
                        .unwrap();
                    let full = contact_between(&a, &world_from_a, &b, &world_from_b);
                    if geometry.provably_apart(&model, &data.world_from_body, pair) {
                        skipped += 1;
                        assert_eq!(full, PairTest::Apart, "lift {lift}, swing {swing}");
                    } else if full == PairTest::Apart {
                        kept_near_boundary += 1;
                    }
                }
            }
        }
        // Both answers occur, and the margin rarely costs a full test.
        assert!(skipped > 100_000, "{skipped}");
        assert!(kept_near_boundary < 100, "{kept_near_boundary}");
        // At the boundary itself: bisect the lift at which the full test of a pair on the slope
        // flips, then step across it by 1e-13 m.
        for pair in geometry
            .pairs
            .iter()
            .filter(|p| p.b == Attachment::Scene(0))
        {
            for i in 0..20 {
                let swing = -3.0 + 0.3 * f64::from(i);
                let mut apart_at = |lift: f64| {
                    forward_kinematics(&model, &mut data, &[lift, swing]);
                    let [(a, wa), (b, wb)] = geometry
                        .placed_pair(&model, &data.world_from_body, pair)
                        .unwrap();
                    (
                        contact_between(&a, &wa, &b, &wb) == PairTest::Apart,
                        geometry.provably_apart(&model, &data.world_from_body, pair),
                    )
                };
                let (mut low, mut high) = (-5.0, 5.0);
                assert!(!apart_at(low).0 && apart_at(high).0);
                for _ in 0..200 {
                    let mid = 0.5 * (low + high);
                    if apart_at(mid).0 {
                        high = mid;
                    } else {
                        low = mid;
                    }
                }
                for k in -1000..=1000 {
                    let (full_apart, skipped) = apart_at(high + 1e-13 * f64::from(k));
                    assert!(!skipped || full_apart, "swing {swing}, step {k}");
                }
            }
        }
    }
}
