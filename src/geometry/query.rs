//! The one boundary to `parry3d-f64` (docs/contacts.md §1): ribbon's nalgebra transforms become
//! parry's glam poses here, a cheap bounding-sphere test runs first, and parry answers the rest:
//! its `contact` query (one point) when a sphere is involved, its contact manifolds (up to
//! [`MAX_CONTACT_POINTS`] points) otherwise. Cylinders: parry's run along local y, URDF's along z, so a URDF cylinder is
//! given to parry with a quarter turn about x; capsules are built along z directly. Mesh hulls
//! are built here too (parry's `ConvexPolyhedron`), from vertices `mesh.rs` loaded.

use super::{normalized_or, Shape};
use crate::spatial::{Transform, Vec3};
use parry3d_f64::math::{Pose, Rotation, Vector};
use parry3d_f64::query::{
    self, ContactManifold, DefaultQueryDispatcher, PersistentQueryDispatcher,
};
use parry3d_f64::shape::{
    Ball, Capsule, ConvexPolyhedron, Cuboid, Cylinder, HalfSpace, HeightField, HeightFieldFlags,
};
use parry3d_f64::utils::Array2;

/// The convex hull of a collision mesh's vertices in its shape frame (docs/contacts.md §1,
/// "Meshes"): the shape parry queries, with its bounding radius and volume.
#[derive(Clone, Debug)]
pub struct ConvexHull {
    polyhedron: ConvexPolyhedron,
    bounding_radius: f64,
    volume: f64,
}

impl ConvexHull {
    /// The hull of `points` (m, shape frame), or `None` when parry finds none (fewer than four
    /// points not all on one plane, or non-finite coordinates).
    pub fn of_points(points: &[Vec3]) -> Option<ConvexHull> {
        if points.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
            return None;
        }
        let vectors: Vec<Vector> = points.iter().map(to_vector).collect();
        let polyhedron = ConvexPolyhedron::from_convex_hull(&vectors)?;
        let bounding_radius = polyhedron
            .points()
            .iter()
            .map(|p| p.length())
            .fold(0.0, f64::max);
        let volume = parry3d_f64::shape::Shape::mass_properties(&polyhedron, 1.0).mass();
        (volume.is_finite() && volume > 0.0).then_some(ConvexHull {
            polyhedron,
            bounding_radius,
            volume,
        })
    }

    /// Volume enclosed by the hull, m³.
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// Radius of the smallest sphere about the shape frame's origin that contains the hull, m.
    pub fn bounding_radius(&self) -> f64 {
        self.bounding_radius
    }

    /// The hull's vertices in the shape frame, m.
    pub fn vertices(&self) -> Vec<Vec3> {
        self.polyhedron
            .points()
            .iter()
            .map(|p| to_vec3(*p))
            .collect()
    }
}

impl PartialEq for ConvexHull {
    /// Two hulls are equal when their vertices are (parry builds the rest from them).
    fn eq(&self, other: &Self) -> bool {
        self.polyhedron.points() == other.polyhedron.points()
    }
}

/// A height field in its shape frame (docs/contacts.md §1, "Height fields"): a regular grid of
/// heights `z` over the rectangle `[−x/2, x/2] × [−y/2, y/2]`, rows along y (row 0 at `y = −y/2`),
/// columns along x (column 0 at `x = −x/2`), each cell split into two triangles; the solid lies
/// below the surface. Queried as parry's `HeightField` (its grid runs in x and z with heights along
/// y: it reaches parry with the quarter turn about x that cylinders take).
#[derive(Clone, Debug)]
pub struct HeightGrid {
    field: HeightField,
    heights: Vec<Vec<f64>>,
    size: [f64; 2],
    bounding_radius: f64,
}

impl HeightGrid {
    /// The grid of `heights` (m; `rows ≥ 2` rows of `columns ≥ 2` finite values each) over a
    /// rectangle of `size` (m, both > 0 and finite). `None` when any of that does not hold (the
    /// sidecar checks it first, naming the key).
    pub fn new(heights: Vec<Vec<f64>>, size: [f64; 2]) -> Option<HeightGrid> {
        let rows = heights.len();
        let columns = heights.first().map_or(0, Vec::len);
        let valid = rows >= 2
            && columns >= 2
            && heights
                .iter()
                .all(|row| row.len() == columns && row.iter().all(|h| h.is_finite()))
            && size.iter().all(|s| s.is_finite() && *s > 0.0);
        if !valid {
            return None;
        }
        // parry's row i runs along its z axis, which the quarter turn sends to −y: its row 0 is
        // ribbon's last row. Column-major storage.
        let data: Vec<f64> = (0..columns)
            .flat_map(|column| heights.iter().rev().map(move |row| row[column]))
            .collect();
        let field = HeightField::with_flags(
            Array2::new(rows, columns, data),
            Vector::new(size[0], 1.0, size[1]),
            HeightFieldFlags::FIX_INTERNAL_EDGES,
        );
        let highest = heights
            .iter()
            .flatten()
            .map(|h| h.abs())
            .fold(0.0, f64::max);
        let bounding_radius =
            (0.25 * size[0] * size[0] + 0.25 * size[1] * size[1] + highest * highest).sqrt();
        Some(HeightGrid {
            field,
            heights,
            size,
            bounding_radius,
        })
    }

    /// The heights, m, rows along y.
    pub fn heights(&self) -> &[Vec<f64>] {
        &self.heights
    }

    /// The extent along x and y, m.
    pub fn size(&self) -> [f64; 2] {
        self.size
    }
}

impl PartialEq for HeightGrid {
    /// Two grids are equal when their heights and sizes are.
    fn eq(&self, other: &Self) -> bool {
        self.heights == other.heights && self.size == other.size
    }
}

/// A contact between shape `a` and shape `b`, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPoint {
    /// Where the force acts: midway between the two surface points, m.
    pub point: Vec3,
    /// Unit normal pushing `a` away from `b`.
    pub normal: Vec3,
    /// Penetration depth `δ > 0`, m (the negative of parry's signed distance).
    pub depth: f64,
}

/// Most contact points one shape pair gives (docs/contacts.md §1, "Several points per pair"): a
/// face clipped against a face has at most eight corners; when parry reports more (a height field
/// under a large shape: one manifold per triangle), the deepest are kept.
pub const MAX_CONTACT_POINTS: usize = 8;

/// Distance below which two contact points of one pair from different manifolds are one point, m:
/// the same corner computed from two triangles differs by rounding (~1e-16 m on metre-sized
/// scenes); a nanometre is far above that and far below any feature of a robot or a terrain.
pub const DUPLICATE_POINT_M: f64 = 1e-9;

/// The contact points of one touching pair (between 1 and [`MAX_CONTACT_POINTS`]), each with its
/// own normal and depth; no allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactPoints {
    points: [ContactPoint; MAX_CONTACT_POINTS],
    len: usize,
}

impl ContactPoints {
    const UNUSED: ContactPoint = ContactPoint {
        point: Vec3::new(0.0, 0.0, 0.0),
        normal: Vec3::new(0.0, 0.0, 1.0),
        depth: 0.0,
    };

    /// No point yet.
    pub fn new() -> Self {
        Self {
            points: [Self::UNUSED; MAX_CONTACT_POINTS],
            len: 0,
        }
    }

    /// One point.
    pub fn one(point: ContactPoint) -> Self {
        let mut out = Self::new();
        out.push(point);
        out
    }

    /// Adds `point`; when full, it replaces the shallowest point if it is deeper.
    pub fn push(&mut self, point: ContactPoint) {
        if self.len < MAX_CONTACT_POINTS {
            self.points[self.len] = point;
            self.len += 1;
            return;
        }
        let (shallowest, _) =
            self.points
                .iter()
                .enumerate()
                .fold((0, f64::INFINITY), |(best, depth), (i, p)| {
                    if p.depth < depth {
                        (i, p.depth)
                    } else {
                        (best, depth)
                    }
                });
        if point.depth > self.points[shallowest].depth {
            self.points[shallowest] = point;
        }
    }

    /// Adds `point` unless a point within [`DUPLICATE_POINT_M`] of it is already there (then the
    /// deeper of the two is kept): two triangles of a height field both report the corner or edge
    /// crossing they share.
    pub fn push_unique(&mut self, point: ContactPoint) {
        let len = self.len;
        if let Some(existing) = self.points[..len]
            .iter_mut()
            .find(|p| (p.point - point.point).norm() <= DUPLICATE_POINT_M)
        {
            if point.depth > existing.depth {
                *existing = point;
            }
            return;
        }
        self.push(point);
    }

    /// The points, in parry's order.
    pub fn as_slice(&self) -> &[ContactPoint] {
        &self.points[..self.len]
    }

    /// Whether there is no point.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The largest penetration of the points, m (0 when there is none).
    pub fn deepest(&self) -> f64 {
        self.as_slice().iter().map(|p| p.depth).fold(0.0, f64::max)
    }
}

impl Default for ContactPoints {
    fn default() -> Self {
        Self::new()
    }
}

/// The result of one pair test.
// The points are kept inline (a few hundred bytes, returned once per pair test) rather than boxed:
// a box would allocate at every evaluation of a touching pair.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PairTest {
    /// The bounding spheres (or the sphere and the half-space) are apart: parry was not called.
    Apart,
    /// parry was called and found no penetration.
    Separated,
    /// parry found a penetration at one or more points.
    Touching(ContactPoints),
}

fn to_vector(v: &Vec3) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

fn to_vec3(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// ribbon's transform as parry's pose (rotation through a unit quaternion: exact to rounding).
fn to_pose(t: &Transform) -> Pose {
    let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(t.rotation),
    );
    let q = rotation.quaternion();
    Pose::from_parts(
        to_vector(&t.translation),
        Rotation::from_xyzw(q.i, q.j, q.k, q.w).normalize(),
    )
}

/// Radius of a sphere about the shape's origin that contains it (`∞` for a half-space).
pub(crate) fn bounding_radius(shape: &Shape) -> f64 {
    match *shape {
        Shape::Sphere { radius } => radius,
        Shape::Box { half_extents: h } => (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt(),
        Shape::Cylinder {
            radius,
            half_length,
        } => (radius * radius + half_length * half_length).sqrt(),
        Shape::Capsule {
            radius,
            half_length,
        } => radius + half_length,
        Shape::HalfSpace => f64::INFINITY,
        Shape::ConvexHull(ref hull) => hull.bounding_radius,
        Shape::HeightField(ref grid) => grid.bounding_radius,
    }
}

/// The quarter turn about x that takes parry's y axis to the URDF z axis.
fn y_to_z() -> Transform {
    Transform::new(
        crate::spatial::rotation_about_axis(&Vec3::x(), std::f64::consts::FRAC_PI_2),
        Vec3::zeros(),
    )
}

/// Tests shape `a` at `world_from_a` against shape `b` at `world_from_b`: a bounding-sphere test,
/// then parry's contact query. `a` must not be a half-space.
pub fn contact_between(
    a: &Shape,
    world_from_a: &Transform,
    b: &Shape,
    world_from_b: &Transform,
) -> PairTest {
    let radius_a = bounding_radius(a);
    match b {
        Shape::HalfSpace => {
            let normal = world_from_b.rotation.column(2).into_owned();
            let height = normal.dot(&(world_from_a.translation - world_from_b.translation));
            if height > radius_a {
                return PairTest::Apart;
            }
        }
        _ => {
            let gap = (world_from_a.translation - world_from_b.translation).norm();
            if gap > radius_a + bounding_radius(b) {
                return PairTest::Apart;
            }
        }
    }
    match narrow_phase(a, world_from_a, b, world_from_b) {
        Ok(points) if !points.is_empty() => PairTest::Touching(points),
        _ => PairTest::Separated,
    }
}

/// Whether a pair takes parry's one-point `contact` query: a sphere against anything its query
/// supports. A sphere touches a convex shape at one point, so a manifold would only cost more; this
/// keeps every sphere contact exactly what it was before manifolds (docs/contacts.md §1).
fn single_point_pair(a: &Shape, b: &Shape) -> bool {
    let sphere = |s: &Shape| matches!(s, Shape::Sphere { .. });
    let field = |s: &Shape| matches!(s, Shape::HeightField(_));
    (sphere(a) || sphere(b)) && !field(a) && !field(b)
}

/// parry's answer for `a` at `world_from_a` against `b` at `world_from_b`: the penetrating points,
/// or `Err` when parry has no query for the two kinds of shape.
fn narrow_phase(
    a: &Shape,
    world_from_a: &Transform,
    b: &Shape,
    world_from_b: &Transform,
) -> Result<ContactPoints, query::Unsupported> {
    // parry 0.31.1 answers `contact(support map, half-space)` with a wrong distance (a ball 1e-5
    // into the ground gave −0.19999 for radius 0.1) but (half-space, support map) correctly: ask
    // with the half-space first, in both queries, and turn the answer around (tested below).
    let b_first = matches!(b, Shape::HalfSpace);
    let single = single_point_pair(a, b);
    with_parry_shape(a, world_from_a, |shape_a, pose_a| {
        with_parry_shape(b, world_from_b, |shape_b, pose_b| {
            let (shape1, pose1, shape2, pose2) = if b_first {
                (shape_b, pose_b, shape_a, pose_a)
            } else {
                (shape_a, pose_a, shape_b, pose_b)
            };
            // parry's normals point from its first shape toward the second; the force on `a`
            // pushes `a` away from `b`.
            let toward_a = |normal1: Vector| {
                let n = normalized_or(to_vec3(normal1), Vec3::z());
                if b_first {
                    n
                } else {
                    -n
                }
            };
            let mut points = ContactPoints::new();
            if single {
                if let Some(contact) = query::contact(&pose1, shape1, &pose2, shape2, 0.0)? {
                    if contact.dist < 0.0 {
                        points.push(ContactPoint {
                            point: 0.5 * (to_vec3(contact.point1) + to_vec3(contact.point2)),
                            normal: toward_a(contact.normal1),
                            depth: -contact.dist,
                        });
                    }
                }
                return Ok(points);
            }
            // A fresh manifold list and workspace at every query: parry's persistent manifolds
            // would carry state from one evaluation to the next (and from one sample to another
            // on a study's thread); fresh ones make the answer a function of the placements only.
            let pos12 = pose1.inv_mul(&pose2);
            let mut manifolds: Vec<ContactManifold<(), ()>> = Vec::new();
            let mut workspace = None;
            DefaultQueryDispatcher.contact_manifolds(
                &pos12,
                shape1,
                shape2,
                0.0,
                &mut manifolds,
                &mut workspace,
            )?;
            for manifold in &manifolds {
                let sub1 = manifold.subshape_pos1().copied();
                let sub2 = manifold.subshape_pos2().copied();
                let frame1 = match sub1 {
                    Some(sub) => pose1 * sub,
                    None => pose1,
                };
                let frame2 = match sub2 {
                    Some(sub) => pose2 * sub,
                    None => pose2,
                };
                let normal = toward_a(frame1.rotation * manifold.local_n1);
                for contact in &manifold.points {
                    if contact.dist < 0.0 {
                        let point1 = to_vec3(frame1 * contact.local_p1);
                        let point2 = to_vec3(frame2 * contact.local_p2);
                        let point = ContactPoint {
                            point: 0.5 * (point1 + point2),
                            normal,
                            depth: -contact.dist,
                        };
                        if manifolds.len() > 1 {
                            points.push_unique(point);
                        } else {
                            points.push(point);
                        }
                    }
                }
            }
            Ok(points)
        })
    })
}

/// The distance between `a` at `world_from_a` and `b` at `world_from_b`, m: 0 when they touch,
/// `None` when parry has no distance query for the two kinds of shape. What a separated pair's
/// signed normal force continues through in a study (docs/contacts.md §7, "The signed force").
pub fn separation(
    a: &Shape,
    world_from_a: &Transform,
    b: &Shape,
    world_from_b: &Transform,
) -> Option<f64> {
    // The half-space first, as in `narrow_phase` (the distance is symmetric).
    let (first, world_from_first, second, world_from_second) = if matches!(b, Shape::HalfSpace) {
        (b, world_from_b, a, world_from_a)
    } else {
        (a, world_from_a, b, world_from_b)
    };
    with_parry_shape(first, world_from_first, |shape1, pose1| {
        with_parry_shape(second, world_from_second, |shape2, pose2| {
            query::distance(&pose1, shape1, &pose2, shape2)
                .ok()
                .map(|d| d.distance)
                .filter(|d| d.is_finite())
                .map(|d| d.max(0.0))
        })
    })
}

/// Whether parry computes contacts between shapes of these two kinds (probed once per pair when a
/// scene is resolved, so that an unsupported pair is refused instead of never touching).
pub fn supported(a: &Shape, b: &Shape) -> bool {
    let at = Transform::identity();
    narrow_phase(a, &at, b, &at).is_ok()
}

/// Calls `f` with parry's shape and pose for `shape` placed at `world_from_shape`.
fn with_parry_shape<R>(
    shape: &Shape,
    world_from_shape: &Transform,
    f: impl FnOnce(&dyn parry3d_f64::shape::Shape, Pose) -> R,
) -> R {
    match *shape {
        Shape::ConvexHull(ref hull) => f(&hull.polyhedron, to_pose(world_from_shape)),
        Shape::Sphere { radius } => f(&Ball::new(radius), to_pose(world_from_shape)),
        Shape::Box { half_extents: h } => f(
            &Cuboid::new(Vector::new(h[0], h[1], h[2])),
            to_pose(world_from_shape),
        ),
        Shape::Cylinder {
            radius,
            half_length,
        } => f(
            &Cylinder::new(half_length, radius),
            to_pose(&world_from_shape.compose(&y_to_z())),
        ),
        Shape::Capsule {
            radius,
            half_length,
        } => f(
            &Capsule::new_z(half_length, radius),
            to_pose(world_from_shape),
        ),
        Shape::HalfSpace => f(
            &HalfSpace::new(Vector::new(0.0, 0.0, 1.0)),
            to_pose(world_from_shape),
        ),
        Shape::HeightField(ref grid) => {
            f(&grid.field, to_pose(&world_from_shape.compose(&y_to_z())))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64, y: f64, z: f64) -> Transform {
        Transform::new(crate::spatial::Mat3::identity(), Vec3::new(x, y, z))
    }

    #[test]
    fn separation_of_a_sphere_above_the_ground_and_a_cylinder() {
        let ball = Shape::Sphere { radius: 0.1 };
        for height in [0.25, 1.0, 3.0] {
            let gap = separation(
                &ball,
                &at(1.0, 2.0, height),
                &Shape::HalfSpace,
                &at(0.0, 0.0, 0.0),
            )
            .expect("parry measures a sphere against a half-space");
            assert!((gap - (height - 0.1)).abs() < 1e-12, "{height}: {gap}");
        }
        let touching = separation(
            &ball,
            &at(0.0, 0.0, 0.05),
            &Shape::HalfSpace,
            &at(0.0, 0.0, 0.0),
        );
        assert_eq!(touching, Some(0.0));
        // A cylinder of radius 0.05 along y at the origin (the URDF's z axis turned to y by the
        // placement), the ball's centre 0.5 m above its axis.
        let rod = Shape::Cylinder {
            radius: 0.05,
            half_length: 1.0,
        };
        let across = Transform::new(
            crate::spatial::rotation_about_axis(&Vec3::x(), std::f64::consts::FRAC_PI_2),
            Vec3::zeros(),
        );
        let gap = separation(&ball, &at(0.0, 0.0, 0.5), &rod, &across).expect("convex pair");
        assert!((gap - 0.35).abs() < 1e-9, "{gap}");
    }

    #[test]
    fn sphere_on_ground_box_and_half_space() {
        let ball = Shape::Sphere { radius: 0.1 };
        let ground_box = Shape::Box {
            half_extents: [10.0, 10.0, 0.5],
        };
        for (ground, placement) in [
            (ground_box, at(0.0, 0.0, -0.5)),
            (Shape::HalfSpace, at(0.0, 0.0, 0.0)),
        ] {
            let PairTest::Touching(points) =
                contact_between(&ball, &at(1.0, 2.0, 0.09), &ground, &placement)
            else {
                panic!("no contact with {ground:?}");
            };
            // A sphere touches at one point.
            assert_eq!(points.as_slice().len(), 1, "{points:?}");
            let c = points.as_slice()[0];
            assert!((c.depth - 0.01).abs() < 1e-12, "{c:?}");
            assert!((c.normal - Vec3::z()).norm() < 1e-12, "{c:?}");
            assert!(
                (c.point - Vec3::new(1.0, 2.0, -0.005)).norm() < 1e-12,
                "{c:?}"
            );
            // Above the half-space the bounding test answers; above the big box parry does.
            let expected = match ground {
                Shape::HalfSpace => PairTest::Apart,
                _ => PairTest::Separated,
            };
            assert_eq!(
                contact_between(&ball, &at(1.0, 2.0, 0.2), &ground, &placement),
                expected
            );
        }
    }

    #[test]
    fn every_primitive_pair_is_supported() {
        let shapes = [
            Shape::Sphere { radius: 0.1 },
            Shape::Box {
                half_extents: [0.1, 0.2, 0.3],
            },
            Shape::Cylinder {
                radius: 0.1,
                half_length: 0.2,
            },
            Shape::Capsule {
                radius: 0.1,
                half_length: 0.2,
            },
        ];
        for a in &shapes {
            for b in shapes.iter().chain([&Shape::HalfSpace]) {
                assert!(supported(a, b), "{a:?} against {b:?}");
            }
            let PairTest::Touching(points) = contact_between(
                a,
                &at(0.0, 0.0, 0.05),
                &Shape::Box {
                    half_extents: [10.0, 10.0, 0.5],
                },
                &at(0.0, 0.0, -0.5),
            ) else {
                panic!("{a:?} 5 cm above a ground box's top must touch it");
            };
            for c in points.as_slice() {
                assert!((c.normal - Vec3::z()).norm() < 1e-6, "{a:?}: {c:?}");
            }
        }
    }

    #[test]
    fn urdf_cylinders_run_along_z() {
        // A cylinder standing on its end (URDF z up): its bottom face is 0.2 below its centre.
        let cylinder = Shape::Cylinder {
            radius: 0.05,
            half_length: 0.2,
        };
        let PairTest::Touching(points) = contact_between(
            &cylinder,
            &at(0.0, 0.0, 0.19),
            &Shape::HalfSpace,
            &at(0.0, 0.0, 0.0),
        ) else {
            panic!("a standing cylinder 0.19 above the ground must touch it");
        };
        // Its bottom face touches: several points, each 1 cm deep on the rim.
        assert!(points.as_slice().len() >= 3, "{points:?}");
        for c in points.as_slice() {
            assert!((c.depth - 0.01).abs() < 1e-9, "{c:?}");
            assert!((c.point.z + 0.005).abs() < 1e-9, "{c:?}");
            assert!(((c.point.x.powi(2) + c.point.y.powi(2)).sqrt() - 0.05).abs() < 1e-9);
        }
        let capsule = Shape::Capsule {
            radius: 0.05,
            half_length: 0.2,
        };
        let PairTest::Touching(points) = contact_between(
            &capsule,
            &at(0.0, 0.0, 0.24),
            &Shape::HalfSpace,
            &at(0.0, 0.0, 0.0),
        ) else {
            panic!("a standing capsule 0.24 above the ground must touch it");
        };
        assert_eq!(points.as_slice().len(), 1, "{points:?}");
        assert!((points.deepest() - 0.01).abs() < 1e-9, "{points:?}");
    }

    /// A flat height field under a sphere and a box: the sphere touches it at one point, as on a
    /// half-space; the box's face is clipped against each triangle it covers, so besides its four
    /// corners it gets the point where the cell's diagonal (y = x) crosses its edge x = 0.2, all at
    /// the box's depth with the upward normal.
    #[test]
    fn flat_height_field_touches_like_the_ground() {
        let flat = Shape::HeightField(std::sync::Arc::new(
            HeightGrid::new(vec![vec![0.0; 5]; 5], [4.0, 4.0]).expect("valid grid"),
        ));
        let at_origin = at(0.0, 0.0, 0.0);
        let PairTest::Touching(points) = contact_between(
            &Shape::Sphere { radius: 0.1 },
            &at(0.3, 0.2, 0.09),
            &flat,
            &at_origin,
        ) else {
            panic!("the sphere must touch the height field");
        };
        assert_eq!(points.as_slice().len(), 1, "{points:?}");
        let c = points.as_slice()[0];
        assert!((c.depth - 0.01).abs() < 1e-12 && (c.normal - Vec3::z()).norm() < 1e-12);
        let small = Shape::Box {
            half_extents: [0.1, 0.2, 0.05],
        };
        let PairTest::Touching(points) =
            contact_between(&small, &at(0.3, 0.2, 0.049), &flat, &at_origin)
        else {
            panic!("the box must touch the height field");
        };
        // parry reports 8 points, three of them repeats from the neighbouring triangle: kept once.
        let corners: Vec<(f64, f64)> = points
            .as_slice()
            .iter()
            .map(|c| (c.point.x, c.point.y))
            .collect();
        let expected = [(0.2, 0.0), (0.2, 0.2), (0.2, 0.4), (0.4, 0.0), (0.4, 0.4)];
        assert_eq!(corners.len(), expected.len(), "{corners:?}");
        for e in expected {
            assert!(
                corners
                    .iter()
                    .any(|c| (c.0 - e.0).abs() < 1e-12 && (c.1 - e.1).abs() < 1e-12),
                "{e:?} not in {corners:?}"
            );
        }
        for c in points.as_slice() {
            assert!((c.depth - 0.001).abs() < 1e-12, "{c:?}");
            assert!((c.normal - Vec3::z()).norm() < 1e-12, "{c:?}");
        }
    }

    /// A box lying flat on a half-space or on a ground box touches at its four bottom corners, each
    /// as deep as the box sinks; tilted about x it touches along one edge (two corners), deeper on
    /// the lower side only.
    #[test]
    fn a_flat_box_touches_at_its_four_corners() {
        let small = Shape::Box {
            half_extents: [0.1, 0.2, 0.05],
        };
        let ground_box = Shape::Box {
            half_extents: [10.0, 10.0, 0.5],
        };
        for (ground, placement) in [
            (Shape::HalfSpace, at(0.0, 0.0, 0.0)),
            (ground_box, at(0.0, 0.0, -0.5)),
        ] {
            let PairTest::Touching(points) =
                contact_between(&small, &at(1.0, 2.0, 0.049), &ground, &placement)
            else {
                panic!("the box must touch {ground:?}");
            };
            let mut corners: Vec<(f64, f64)> = points
                .as_slice()
                .iter()
                .map(|c| {
                    assert!((c.depth - 0.001).abs() < 1e-12, "{ground:?}: {c:?}");
                    assert!((c.normal - Vec3::z()).norm() < 1e-12, "{ground:?}: {c:?}");
                    assert!((c.point.z + 0.0005).abs() < 1e-12, "{ground:?}: {c:?}");
                    (c.point.x, c.point.y)
                })
                .collect();
            corners.sort_by(|p, q| p.partial_cmp(q).expect("finite"));
            let expected = [(0.9, 1.8), (0.9, 2.2), (1.1, 1.8), (1.1, 2.2)];
            assert_eq!(corners.len(), 4, "{ground:?}: {points:?}");
            for (c, e) in corners.iter().zip(expected) {
                assert!(
                    (c.0 - e.0).abs() < 1e-12 && (c.1 - e.1).abs() < 1e-12,
                    "{corners:?}"
                );
            }
        }
        // Tilted by 0.01 rad about x: the corners at y = −0.2 sink 2 mm more than the centre.
        let tilted = Transform::new(
            crate::spatial::rotation_about_axis(&Vec3::x(), 0.01),
            Vec3::new(0.0, 0.0, 0.05),
        );
        let PairTest::Touching(points) =
            contact_between(&small, &tilted, &Shape::HalfSpace, &at(0.0, 0.0, 0.0))
        else {
            panic!("the tilted box must touch");
        };
        assert_eq!(points.as_slice().len(), 2, "{points:?}");
        let expected = 0.2 * 0.01f64.sin() + 0.05 * 0.01f64.cos() - 0.05;
        for c in points.as_slice() {
            assert!((c.depth - expected).abs() < 1e-12, "{c:?} vs {expected}");
        }
    }
}
