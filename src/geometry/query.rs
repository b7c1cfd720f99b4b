//! The one boundary to `parry3d-f64` (docs/contacts.md §1): ribbon's nalgebra transforms become
//! parry's glam poses here, a cheap bounding-sphere test runs first, and parry's `contact` query
//! answers the rest. Cylinders: parry's run along local y, URDF's along z, so a URDF cylinder is
//! given to parry with a quarter turn about x; capsules are built along z directly. Mesh hulls
//! are built here too (parry's `ConvexPolyhedron`), from vertices `mesh.rs` loaded.

use super::{normalized_or, Shape};
use crate::spatial::{Transform, Vec3};
use parry3d_f64::math::{Pose, Rotation, Vector};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, ConvexPolyhedron, Cuboid, Cylinder, HalfSpace};

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

/// The result of one pair test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PairTest {
    /// The bounding spheres (or the sphere and the half-space) are apart: parry was not called.
    Apart,
    /// parry was called and found no penetration.
    Separated,
    /// parry found a penetration.
    Touching(ContactPoint),
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
    // parry 0.31.1 answers (support map, half-space) with a wrong distance (a ball 1e-5 into the
    // ground gave −0.19999 for radius 0.1) but (half-space, support map) correctly: ask in that
    // order and swap the answer (tested below).
    let b_is_half_space = matches!(b, Shape::HalfSpace);
    let result = with_parry_shape(a, world_from_a, |shape_a, pose_a| {
        with_parry_shape(b, world_from_b, |shape_b, pose_b| {
            if b_is_half_space {
                query::contact(&pose_b, shape_b, &pose_a, shape_a, 0.0)
            } else {
                query::contact(&pose_a, shape_a, &pose_b, shape_b, 0.0)
            }
        })
    });
    match result {
        Ok(Some(contact)) if contact.dist < 0.0 => {
            let point1 = to_vec3(contact.point1);
            let point2 = to_vec3(contact.point2);
            // parry's normal1 points from its first shape toward the second; the force on a
            // pushes a away from b.
            let normal = if b_is_half_space {
                normalized_or(to_vec3(contact.normal1), Vec3::z())
            } else {
                normalized_or(-to_vec3(contact.normal1), Vec3::z())
            };
            PairTest::Touching(ContactPoint {
                point: 0.5 * (point1 + point2),
                normal,
                depth: -contact.dist,
            })
        }
        _ => PairTest::Separated,
    }
}

/// Whether parry computes contacts between shapes of these two kinds (probed once per pair when a
/// scene is resolved, so that an unsupported pair is refused instead of never touching).
pub fn supported(a: &Shape, b: &Shape) -> bool {
    let at = Transform::identity();
    with_parry_shape(a, &at, |shape_a, pose_a| {
        with_parry_shape(b, &at, |shape_b, pose_b| {
            if matches!(b, Shape::HalfSpace) {
                query::contact(&pose_b, shape_b, &pose_a, shape_a, 1.0).is_ok()
            } else {
                query::contact(&pose_a, shape_a, &pose_b, shape_b, 1.0).is_ok()
            }
        })
    })
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64, y: f64, z: f64) -> Transform {
        Transform::new(crate::spatial::Mat3::identity(), Vec3::new(x, y, z))
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
            let PairTest::Touching(c) =
                contact_between(&ball, &at(1.0, 2.0, 0.09), &ground, &placement)
            else {
                panic!("no contact with {ground:?}");
            };
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
            let PairTest::Touching(c) = contact_between(
                a,
                &at(0.0, 0.0, 0.05),
                &Shape::Box {
                    half_extents: [10.0, 10.0, 0.5],
                },
                &at(0.0, 0.0, -0.5),
            ) else {
                panic!("{a:?} 5 cm above a ground box's top must touch it");
            };
            assert!((c.normal - Vec3::z()).norm() < 1e-6, "{a:?}: {c:?}");
        }
    }

    #[test]
    fn urdf_cylinders_run_along_z() {
        // A cylinder standing on its end (URDF z up): its bottom face is 0.2 below its centre.
        let cylinder = Shape::Cylinder {
            radius: 0.05,
            half_length: 0.2,
        };
        let PairTest::Touching(c) = contact_between(
            &cylinder,
            &at(0.0, 0.0, 0.19),
            &Shape::HalfSpace,
            &at(0.0, 0.0, 0.0),
        ) else {
            panic!("a standing cylinder 0.19 above the ground must touch it");
        };
        assert!((c.depth - 0.01).abs() < 1e-9, "{c:?}");
        let capsule = Shape::Capsule {
            radius: 0.05,
            half_length: 0.2,
        };
        let PairTest::Touching(c) = contact_between(
            &capsule,
            &at(0.0, 0.0, 0.24),
            &Shape::HalfSpace,
            &at(0.0, 0.0, 0.0),
        ) else {
            panic!("a standing capsule 0.24 above the ground must touch it");
        };
        assert!((c.depth - 0.01).abs() < 1e-9, "{c:?}");
    }
}
