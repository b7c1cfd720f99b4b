//! Loop closures: a point of a child link kept on the constrained directions of a point of a parent
//! link (or the world). With `d = x_child − x_parent` in the world frame and `e_i` unit directions
//! fixed in the parent link frame (`e_i,w = R_parent e_i`):
//!
//! `Φ_i = e_i,w · d`,
//! `Φ_q,i = e_i,wᵀ (J_child − J_parent) + (e_i,w × d)ᵀ J_parent^ω`,
//! `Φ̈_i = e_i,w · d̈ + 2 ė_i,w · ḋ + ë_i,w · d`, with `ė = ω × e` and `ë = α × e + ω × (ω × e)`.
//!
//! Directions by type: `ball` x, y, z of the parent frame (3 rows); `planar_pin` two directions in
//! the plane of `normal` (2 rows); `planar_slider` `normal × axis` (1 row); `slider` two directions
//! orthogonal to `axis` (2 rows).

use crate::dynamics::Data;
use crate::model::{Joint, Model};
use crate::spatial::{Mat3, Motion, Transform, Vec3};
use nalgebra::DMatrix;

/// The kind of a loop closure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopKind {
    /// Coincident points (3 rows).
    Ball,
    /// Coincident points within a plane (2 rows).
    PlanarPin,
    /// A point on a line within a plane (1 row).
    PlanarSlider,
    /// A point on a line (2 rows).
    Slider,
}

impl LoopKind {
    /// Parses the sidecar spelling.
    pub fn parse(text: &str) -> Option<LoopKind> {
        match text {
            "ball" => Some(LoopKind::Ball),
            "planar_pin" => Some(LoopKind::PlanarPin),
            "planar_slider" => Some(LoopKind::PlanarSlider),
            "slider" => Some(LoopKind::Slider),
            _ => None,
        }
    }
}

/// A resolved loop closure.
#[derive(Clone, Debug)]
pub struct LoopClosure {
    /// Name (outputs `lambda.NAME.i`).
    pub name: String,
    /// Kind.
    pub kind: LoopKind,
    /// Parent link (index into `description.links`), `None` for the world.
    pub parent: Option<usize>,
    /// The point in the parent link frame, m.
    pub point_in_parent: Vec3,
    /// Child link.
    pub child: usize,
    /// The point in the child link frame, m.
    pub point_in_child: Vec3,
    /// Unit constrained directions in the parent link frame (1 to 3).
    pub directions: Vec<Vec3>,
}

/// A point of a link at the last kinematics: its body, its coordinates in the body frame and in the
/// world frame.
struct LinkPoint {
    body: Option<usize>,
    in_body: Vec3,
    in_world: Vec3,
}

fn link_point(model: &Model, data: &Data, link: Option<usize>, point: &Vec3) -> LinkPoint {
    let Some(link) = link else {
        return LinkPoint {
            body: None,
            in_body: *point,
            in_world: *point,
        };
    };
    let placement = &model.links[link];
    let in_body = placement.body_from_link.transform_point(point);
    let in_world = match placement.body {
        Some(b) => data.world_from_body[b].transform_point(&in_body),
        None => in_body,
    };
    LinkPoint {
        body: placement.body,
        in_body,
        in_world,
    }
}

/// A loop at the last kinematics: its point on the parent link (`a`) and on the child link (`b`),
/// the parent link's orientation in the world, and the gap `b − a` in the world frame.
struct LoopGeometry {
    a: LinkPoint,
    b: LinkPoint,
    rotation: Mat3,
    gap: Vec3,
}

/// Orientation of a link in the world.
fn world_rotation(model: &Model, data: &Data, link: Option<usize>) -> Mat3 {
    let Some(link) = link else {
        return Mat3::identity();
    };
    let placement = &model.links[link];
    match placement.body {
        Some(b) => data.world_from_body[b].rotation * placement.body_from_link.rotation,
        None => placement.body_from_link.rotation,
    }
}

/// The rows whose Jacobian entries one walk of a chain writes (a ball joint's three directions,
/// the most a loop has; more would be taken in groups of this many).
const MAX_LOOP_ROWS: usize = 3;

/// For each row `i < weights.len()`, adds `linear_i · J_point + angular_i · J^ω` of the chain from
/// the point's body to the root into `out[first_row + i, :]` (`J_point`: the point's linear
/// velocity Jacobian in the world frame; `J^ω`: its body's angular velocity Jacobian;
/// `weights[i] = (linear_i, angular_i)`). The chain is walked once, each joint column's world
/// motion computed once for every row.
fn add_chain(
    model: &Model,
    data: &Data,
    point: &LinkPoint,
    weights: &[(Vec3, Vec3)],
    first_row: usize,
    out: &mut DMatrix<f64>,
) {
    let point_in_world = &point.in_world;
    let mut current = point.body;
    while let Some(b) = current {
        let joint = &model.joints[b];
        for k in 0..joint.nv() {
            let column = world_subspace_column(&data.world_from_body[b], joint, k);
            let point_velocity = column.linear + column.angular.cross(point_in_world);
            for (i, (linear, angular)) in weights.iter().enumerate() {
                out[(first_row + i, joint.v_index + k)] +=
                    linear.dot(&point_velocity) + angular.dot(&column.angular);
            }
        }
        current = joint.parent;
    }
}

/// Column `k` of a joint's motion subspace in the world frame, `world_from_body · S[:, k]`. For a
/// revolute joint on a coordinate axis `e_a`, `R e_a` is `R`'s column `a` and the linear part
/// `R 0 + p × ω` is `p × ω`: the values of the general product, signs of zero aside (the sums of
/// zero products are left out). [`add_chain`] adds each Jacobian entry onto `+0`, and
/// `+0 + (−0) = +0`, so not even a sign of zero reaches `Φ_q`.
#[inline]
fn world_subspace_column(world_from_body: &Transform, joint: &Joint, k: usize) -> Motion {
    match joint.revolute_coordinate_axis() {
        Some(axis) => {
            let angular = world_from_body.rotation.column(axis).into_owned();
            Motion::new(world_from_body.translation.cross(&angular), angular)
        }
        None => world_from_body.act_motion(&joint.subspace_column(k)),
    }
}

impl LoopClosure {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.directions.len()
    }

    /// The loop's two points and the parent's orientation at the placements in `data`.
    fn geometry(&self, model: &Model, data: &Data) -> LoopGeometry {
        let a = link_point(model, data, self.parent, &self.point_in_parent);
        let b = link_point(model, data, Some(self.child), &self.point_in_child);
        let rotation = world_rotation(model, data, self.parent);
        let gap = b.in_world - a.in_world;
        LoopGeometry {
            a,
            b,
            rotation,
            gap,
        }
    }

    /// `out = Φ` of this loop (`dim rows`), from the placements in `data`.
    pub fn evaluate(&self, model: &Model, data: &Data, out: &mut [f64]) {
        self.values_at(&self.geometry(model, data), out);
    }

    /// Writes this loop's rows of `Φ_q` into `out` from row `first_row`, from the placements in `data`.
    pub fn jacobian(&self, model: &Model, data: &Data, first_row: usize, out: &mut DMatrix<f64>) {
        self.jacobian_at(
            model,
            data,
            &self.geometry(model, data),
            None,
            first_row,
            out,
        );
    }

    /// [`evaluate`](Self::evaluate) into `values` and [`jacobian`](Self::jacobian) into `out`
    /// from one evaluation of the loop's points (the same bits as the two calls).
    pub fn evaluate_with_jacobian(
        &self,
        model: &Model,
        data: &Data,
        values: &mut [f64],
        first_row: usize,
        out: &mut DMatrix<f64>,
    ) {
        let geometry = self.geometry(model, data);
        self.jacobian_at(model, data, &geometry, Some(values), first_row, out);
    }

    /// `Φ` of this loop from its geometry: the gap along each direction turned into the world.
    fn values_at(&self, geometry: &LoopGeometry, out: &mut [f64]) {
        for (value, e) in out.iter_mut().zip(&self.directions) {
            *value = (geometry.rotation * e).dot(&geometry.gap);
        }
    }

    /// This loop's rows of `Φ_q` from its geometry (the chains' placements read from `data`),
    /// and with `values` its `Φ` as [`Self::values_at`] computes it, from the same world
    /// directions.
    fn jacobian_at(
        &self,
        model: &Model,
        data: &Data,
        geometry: &LoopGeometry,
        mut values: Option<&mut [f64]>,
        first_row: usize,
        out: &mut DMatrix<f64>,
    ) {
        let LoopGeometry {
            a,
            b,
            rotation,
            gap: d,
        } = geometry;
        // Every entry gets the child chain's term, then the parent chain's, as row by row.
        for (chunk, directions) in self.directions.chunks(MAX_LOOP_ROWS).enumerate() {
            let rows = directions.len();
            let first = chunk * MAX_LOOP_ROWS;
            let mut child = [(Vec3::zeros(), Vec3::zeros()); MAX_LOOP_ROWS];
            let mut parent = [(Vec3::zeros(), Vec3::zeros()); MAX_LOOP_ROWS];
            for (i, e) in directions.iter().enumerate() {
                let e_world = rotation * e;
                if let Some(values) = values.as_deref_mut() {
                    values[first + i] = e_world.dot(d);
                }
                child[i] = (e_world, Vec3::zeros());
                // The parent's point moves with its body, and so do the directions (rotation term).
                parent[i] = (-e_world, e_world.cross(d));
            }
            add_chain(model, data, b, &child[..rows], first_row + first, out);
            add_chain(model, data, a, &parent[..rows], first_row + first, out);
        }
    }

    /// `out = −(Φ_q q̇)_q q̇` of this loop (`dim rows`), from the drift kinematics in `data`.
    pub fn acceleration_bias(&self, model: &Model, data: &Data, out: &mut [f64]) {
        let a = link_point(model, data, self.parent, &self.point_in_parent);
        let b = link_point(model, data, Some(self.child), &self.point_in_child);
        let rotation = world_rotation(model, data, self.parent);
        let d = b.in_world - a.in_world;
        // World velocity and drift acceleration of a point, and the angular velocity and drift
        // angular acceleration of its body.
        let motion = |point: &LinkPoint| match point.body {
            None => (Vec3::zeros(), Vec3::zeros(), Vec3::zeros(), Vec3::zeros()),
            Some(body) => {
                let r = data.world_from_body[body].rotation;
                let (v, a) = (data.velocity[body], data.acceleration[body]);
                let w = v.angular;
                let p = point.in_body;
                let velocity = v.linear + w.cross(&p);
                let acceleration = a.linear + a.angular.cross(&p) + w.cross(&velocity);
                (r * velocity, r * acceleration, r * w, r * a.angular)
            }
        };
        let (velocity_a, drift_a, omega, alpha) = motion(&a);
        let (velocity_b, drift_b, _, _) = motion(&b);
        let d_dot = velocity_b - velocity_a;
        let d_drift = drift_b - drift_a;
        for (value, e) in out.iter_mut().zip(&self.directions) {
            let e_world = rotation * e;
            let e_dot = omega.cross(&e_world);
            let e_drift = alpha.cross(&e_world) + omega.cross(&e_dot);
            *value = -(e_world.dot(&d_drift) + 2.0 * e_dot.dot(&d_dot) + e_drift.dot(&d));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::LoadOptions;

    /// The coordinate-axis shortcut has the values of the general product (`==` equates the two
    /// zeros and nothing else), for rotations with exact zeros and without, about each axis.
    #[test]
    fn coordinate_axis_column_has_the_values_of_the_general_product() {
        let urdf = r#"<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>
          <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
          <joint name="j" type="continuous"><parent link="a"/><child link="b"/>
          <axis xyz="0 0 1"/></joint></robot>"#;
        let model = Model::from_urdf_str(urdf, "r.urdf", LoadOptions::default()).unwrap();
        let placements = [
            Transform::from_xyz_rpy([0.1, -0.4, 0.7], [0.3, 0.2, -1.0]),
            Transform::from_xyz_rpy([0.0, -0.09, 0.0], [std::f64::consts::FRAC_PI_2, 0.0, 0.0]),
            Transform::from_xyz_rpy([1.5, 0.0, -2.0], [0.0, 0.0, 2.5]),
            Transform::identity(),
        ];
        for axis in 0..3 {
            let mut joint = model.joints[0].clone();
            let mut e = Vec3::zeros();
            e[axis] = 1.0;
            joint.set_axis(e);
            assert_eq!(joint.revolute_coordinate_axis(), Some(axis));
            for x in &placements {
                let shortcut = world_subspace_column(x, &joint, 0);
                let general = x.act_motion(&joint.subspace_column(0));
                assert_eq!(shortcut, general, "axis {axis}");
            }
        }
    }
}
