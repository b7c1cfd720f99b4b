//! URDF → [`Model`]: the kinematic tree in joint coordinates.
//!
//! A [`Model`] is a constant description of the robot (per-thread work buffers live in
//! [`crate::dynamics::Data`]). It keeps the URDF-level values ([`Description`]) that parameters
//! address, and the tree quantities derived from them ([`Model::refresh`] recomputes those after a
//! parameter change, without allocating).
//!
//! Tree rules:
//! - every link reached through a moving joint starts a **body**; links reached through fixed joints
//!   are merged into their parent's body (inertia rotated and shifted) and kept as frames;
//! - with a fixed base, the root link and everything fixed to it are the world (they carry no
//!   dynamics); with a floating base ([`LoadOptions::floating_base`]) the root link is a body on a
//!   6-dof joint named `root_joint`;
//! - coordinates are ordered by a depth-first traversal of the tree, children in file order;
//! - a continuous joint has one coordinate (the angle); a floating joint has 7 (x y z, quaternion
//!   x y z w) and 6 velocities (linear then angular, in the body frame) — Pinocchio's convention;
//! - mimic joints are kept as independent coordinates here, with their relation recorded.
//!
//! Not supported yet: planar and spherical joints (refused with a clear error).

mod consistency;
mod description;
mod error;
mod singular;
mod urdf;

pub use consistency::{check_inertia, InertiaViolation, INERTIA_RELATIVE_TOLERANCE};
use description::NameIndex;
pub use description::{
    CollisionShape, CollisionSpec, Description, InertialSpec, JointSpec, LinkSpec, MimicSpec,
    UrdfJointType,
};
pub use error::ModelError;
pub use singular::{explain_null_motion, NULL_DIRECTION_RELATIVE_THRESHOLD};
pub use urdf::{parse_description, read_description, MAX_XML_DEPTH};

use crate::spatial::{
    rotation_about_axis, rotation_about_axis_given_sin_cos, rotation_from_rpy, Force, Inertia,
    Mat3, Motion, Transform, Vec3,
};
use std::path::Path;

/// Name of the 6-dof joint that `--floating` puts between the world and the root link.
pub const ROOT_JOINT_NAME: &str = "root_joint";

/// How to turn a URDF into a model.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadOptions {
    /// Put the root link on a floating (6-dof) joint named [`ROOT_JOINT_NAME`] (default: fixed).
    pub floating_base: bool,
}

/// The motion a joint allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the joint axis (URDF revolute or continuous): one coordinate (rad).
    Revolute,
    /// Translation along the joint axis: one coordinate (m).
    Prismatic,
    /// Free motion: position and unit quaternion (x y z w); velocity linear then angular in the
    /// child frame.
    Floating,
}

/// A moving joint of the tree; joint `i` moves body `i`.
#[derive(Clone, Debug)]
pub struct Joint {
    /// The joint's name (`root_joint` for the floating base).
    pub name: String,
    /// What motion it allows.
    pub kind: JointKind,
    /// The URDF type name (`revolute`, `continuous`, `prismatic`, `floating`).
    pub type_name: &'static str,
    /// The parent body, `None` for the world.
    pub parent: Option<usize>,
    /// Index of the first coordinate in `q`.
    pub q_index: usize,
    /// Index of the first velocity coordinate in `v`.
    pub v_index: usize,
    /// The URDF joint it comes from (`None` for `root_joint`).
    pub source: Option<usize>,
    /// Placement of the joint frame in the parent body frame (derived; see [`Model::refresh`]).
    pub parent_from_joint: Transform,
    /// Unit axis in the joint frame (derived; read with [`Joint::axis`], set with
    /// [`Joint::set_axis`]).
    axis: Vec3,
    /// `Some(k)` when `axis` is exactly the coordinate axis `e_k` (kept with `axis` by
    /// [`Joint::set_axis`]; see [`Joint::revolute_coordinate_axis`]).
    axis_index: Option<usize>,
    /// `q = multiplier · q_leader + offset` for a URDF mimic joint (leader: a joint index).
    pub mimic: Option<(usize, f64, f64)>,
}

/// A moving rigid body: one link plus every link fixed to it.
#[derive(Clone, Debug)]
pub struct Body {
    /// The link that starts the body.
    pub link: usize,
    /// Merged spatial inertia about the body origin, in the body frame (derived).
    pub inertia: Inertia,
}

/// Where a URDF link sits in the tree.
#[derive(Clone, Copy, Debug)]
pub struct LinkPlacement {
    /// The body the link belongs to, `None` for the world.
    pub body: Option<usize>,
    /// The fixed joint that attaches it to its parent link, if it was merged.
    pub fixed_parent: Option<(usize, usize)>,
    /// The link frame in its body's frame (derived).
    pub body_from_link: Transform,
}

impl LinkPlacement {
    /// The link frame in the world: `world_from_body[b] ∘ body_from_link` of the body `b` it is
    /// fixed to, `body_from_link` itself for a link on the world. `world_from_body` is indexed by
    /// body (a forward-kinematics pass's placements).
    pub fn world_from_link(&self, world_from_body: &[Transform]) -> Transform {
        match self.body {
            Some(b) => world_from_body[b].compose(&self.body_from_link),
            None => self.body_from_link,
        }
    }
}

/// A robot as a kinematic tree with its parameters' values.
#[derive(Clone, Debug)]
pub struct Model {
    /// The URDF values every parameter addresses.
    pub description: Description,
    /// The `link.NAME.scale` factor of every link (unitless, same order as `description.links`,
    /// 1 after loading): [`Model::refresh`] multiplies the link's mass and whole inertia tensor by
    /// it (COM unchanged), on top of the values in `description` — so a scale and an explicit
    /// mass or inertia value multiply. Kept beside the description because the URDF has no such
    /// value.
    pub inertial_scales: Vec<f64>,
    /// Moving joints in coordinate order.
    pub joints: Vec<Joint>,
    /// The moving joints' names to their indices ([`Model::joint_index`]).
    joint_names: NameIndex,
    /// Moving bodies; body `i` is moved by joint `i`.
    pub bodies: Vec<Body>,
    /// One entry per URDF link, same order as `description.links`.
    pub links: Vec<LinkPlacement>,
    /// Link indices in an order where every link comes after its parent.
    link_order: Vec<usize>,
    /// Index of the root link.
    pub root_link: usize,
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of velocity coordinates.
    pub nv: usize,
    /// Whether the root is on a floating joint.
    pub floating_base: bool,
    /// Non-fatal findings of loading (inertia violations, massless moving links, ignored mimics).
    pub warnings: Vec<String>,
}

impl Joint {
    /// Number of position coordinates (1, or 7 for a floating joint).
    pub fn nq(&self) -> usize {
        match self.kind {
            JointKind::Floating => 7,
            _ => 1,
        }
    }

    /// Number of velocity coordinates (1, or 6 for a floating joint).
    pub fn nv(&self) -> usize {
        match self.kind {
            JointKind::Floating => 6,
            _ => 1,
        }
    }

    /// The joint's own motion `joint_from_child` for coordinates `q` (`q: dim self.nq()`).
    #[inline]
    pub fn joint_transform(&self, q: &[f64]) -> Transform {
        match self.kind {
            JointKind::Revolute => {
                Transform::new(rotation_about_axis(&self.axis, q[0]), Vec3::zeros())
            }
            JointKind::Prismatic => Transform::new(Mat3::identity(), self.axis * q[0]),
            JointKind::Floating => {
                let quaternion = crate::spatial::quaternion::quaternion_from_xyzw(&q[3..7]);
                let rotation = nalgebra::UnitQuaternion::new_unchecked(quaternion);
                Transform::new(
                    *rotation.to_rotation_matrix().matrix(),
                    Vec3::new(q[0], q[1], q[2]),
                )
            }
        }
    }

    /// `parent_from_child` for coordinates `q` (`q: dim self.nq()`).
    #[inline]
    pub fn parent_from_child(&self, q: &[f64]) -> Transform {
        match self.revolute_coordinate_axis() {
            Some(k) => self
                .parent_from_joint
                .compose_rotation_about_coordinate_axis(k, q[0]),
            None => self.parent_from_joint.compose(&self.joint_transform(q)),
        }
    }

    /// [`Joint::parent_from_child`] of a revolute joint from the sine and cosine of its angle (as
    /// [`crate::spatial::trig::sin_cos`] gives them): the same bits. The caller checks the kind.
    /// (`parent_from_child` keeps its own two-arm match: routed through this function it cost our
    /// ur5's HHT step 421 instructions and the four-bar's 223, by how the compiler then inlined.)
    #[inline]
    pub fn revolute_parent_from_child(&self, sin: f64, cos: f64) -> Transform {
        debug_assert_eq!(self.kind, JointKind::Revolute);
        match self.axis_index {
            Some(k) => self
                .parent_from_joint
                .compose_rotation_about_coordinate_axis_given_sin_cos(k, sin, cos),
            None => self.parent_from_joint.compose(&Transform::new(
                rotation_about_axis_given_sin_cos(&self.axis, sin, cos),
                Vec3::zeros(),
            )),
        }
    }

    /// `Some(k)` for a revolute joint whose axis is exactly the coordinate axis `e_k` of its frame
    /// (k ∈ {0, 1, 2}; most URDFs put every axis on `z`), else `None`. The kernels then leave out
    /// the products by the joint motion's zero entries (docs/batch.md §7); the result has the bits
    /// of the general formulas (signs of zero aside). Kept with the axis by [`Joint::set_axis`], so
    /// a parameter that moves the axis off `e_k` takes the general path at once.
    #[inline]
    pub fn revolute_coordinate_axis(&self) -> Option<usize> {
        if self.kind != JointKind::Revolute {
            return None;
        }
        self.axis_index
    }

    /// Unit axis in the joint frame (derived from the URDF's `<axis>` by [`Model::refresh`]).
    #[inline]
    pub fn axis(&self) -> &Vec3 {
        &self.axis
    }

    /// Sets the unit axis in the joint frame (`axis` must have unit length) and whether it is a
    /// coordinate axis ([`Joint::revolute_coordinate_axis`]).
    pub fn set_axis(&mut self, axis: Vec3) {
        self.axis = axis;
        self.axis_index = coordinate_axis_index(&axis);
    }

    /// Joint motion `S v` in the child frame (`v: dim self.nv()`).
    #[inline]
    pub fn motion(&self, v: &[f64]) -> Motion {
        match self.kind {
            JointKind::Revolute => Motion::new(Vec3::zeros(), self.axis * v[0]),
            JointKind::Prismatic => Motion::new(self.axis * v[0], Vec3::zeros()),
            JointKind::Floating => {
                Motion::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
            }
        }
    }

    /// Column `k` of the motion subspace `S` (`k < self.nv()`).
    #[inline]
    pub fn subspace_column(&self, k: usize) -> Motion {
        match self.kind {
            JointKind::Revolute => Motion::new(Vec3::zeros(), self.axis),
            JointKind::Prismatic => Motion::new(self.axis, Vec3::zeros()),
            JointKind::Floating => {
                let mut m = Motion::zero();
                if k < 3 {
                    m.linear[k] = 1.0;
                } else {
                    m.angular[k - 3] = 1.0;
                }
                m
            }
        }
    }

    /// Generalised force `Sᵀ f` written into `out` (`out: dim self.nv()`).
    #[inline]
    pub fn project_force(&self, force: &Force, out: &mut [f64]) {
        match self.kind {
            JointKind::Revolute => out[0] = self.axis.dot(&force.angular),
            JointKind::Prismatic => out[0] = self.axis.dot(&force.linear),
            JointKind::Floating => {
                out[..3].copy_from_slice(force.linear.as_slice());
                out[3..6].copy_from_slice(force.angular.as_slice());
            }
        }
    }
}

/// `Some(k)` when `axis` is exactly the coordinate axis `e_k` (`−0` counts as `0`).
#[inline]
fn coordinate_axis_index(axis: &Vec3) -> Option<usize> {
    let [x, y, z] = [axis.x, axis.y, axis.z];
    if x == 0.0 && y == 0.0 && z == 1.0 {
        Some(2)
    } else if x == 1.0 && y == 0.0 && z == 0.0 {
        Some(0)
    } else if x == 0.0 && y == 1.0 && z == 0.0 {
        Some(1)
    } else {
        None
    }
}

/// Spatial inertia of a link's `<inertial>` in the link frame: the tensor rotated by the inertial
/// frame's rpy (`R I Rᵀ`) and shifted to the link origin.
pub fn link_inertia(inertial: &InertialSpec) -> Inertia {
    let [ixx, ixy, ixz, iyy, iyz, izz] = inertial.inertia;
    let in_inertia_frame = Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let rotation = rotation_from_rpy(inertial.rpy[0], inertial.rpy[1], inertial.rpy[2]);
    let about_com = rotation * in_inertia_frame * rotation.transpose();
    let com = Vec3::new(inertial.com[0], inertial.com[1], inertial.com[2]);
    Inertia::from_com(inertial.mass, com, about_com)
}

/// A joint on the cycle above `start` (a link that is on or below a cycle of parent joints): walks
/// up through parent joints until a link repeats. Iterative, at most one step per link.
fn joint_on_cycle(
    parent_joint: &[Option<usize>],
    description: &Description,
    start: usize,
) -> usize {
    let mut seen = vec![false; parent_joint.len()];
    let mut link = start;
    let mut last_joint = 0;
    while let Some(joint) = parent_joint[link] {
        if seen[link] {
            return joint;
        }
        seen[link] = true;
        last_joint = joint;
        link = description.joints[joint].parent;
    }
    last_joint
}

/// The `<origin>` of a URDF joint as a transform.
pub fn joint_origin(spec: &JointSpec) -> Transform {
    let o = spec.origin;
    Transform::from_xyz_rpy([o[0], o[1], o[2]], [o[3], o[4], o[5]])
}

impl Model {
    /// Loads a URDF file.
    pub fn from_urdf_file(path: &Path, options: LoadOptions) -> Result<Model, ModelError> {
        let description = read_description(path)?;
        Model::from_description(description, options, &path.display().to_string())
    }

    /// Loads URDF text; `path` is only used in messages.
    pub fn from_urdf_str(
        text: &str,
        path: &str,
        options: LoadOptions,
    ) -> Result<Model, ModelError> {
        Model::from_description(parse_description(text, path)?, options, path)
    }

    /// Builds the tree from a description; `path` is only used in messages.
    pub fn from_description(
        description: Description,
        options: LoadOptions,
        path: &str,
    ) -> Result<Model, ModelError> {
        let n_links = description.links.len();
        if n_links == 0 {
            return Err(ModelError::NotUrdf {
                path: path.to_string(),
                message: "the robot has no <link>".to_string(),
            });
        }
        // Parent joint of every link; a link may have only one.
        let mut parent_joint: Vec<Option<usize>> = vec![None; n_links];
        for (j, joint) in description.joints.iter().enumerate() {
            if let Some(first) = parent_joint[joint.child] {
                return Err(ModelError::TwoParents {
                    path: path.to_string(),
                    line: joint.line,
                    link: description.links[joint.child].name.clone(),
                    first: description.joints[first].name.clone(),
                    second: joint.name.clone(),
                });
            }
            parent_joint[joint.child] = Some(j);
        }
        let roots: Vec<usize> = (0..n_links)
            .filter(|&l| parent_joint[l].is_none())
            .collect();
        let link_names: Vec<String> = description
            .links
            .iter()
            .map(|l| format!("'{}'", l.name))
            .collect();
        let name_list = |indices: &[usize]| {
            indices
                .iter()
                .map(|&l| link_names[l].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let root_link = match roots.as_slice() {
            [] => {
                let all: Vec<usize> = (0..n_links).collect();
                let joint = joint_on_cycle(&parent_joint, &description, 0);
                return Err(ModelError::Cycle {
                    path: path.to_string(),
                    line: description.joints[joint].line,
                    joint: description.joints[joint].name.clone(),
                    links: name_list(&all),
                });
            }
            [root] => *root,
            several => {
                return Err(ModelError::SeveralRoots {
                    path: path.to_string(),
                    line: description.links[several[1]].line,
                    count: several.len(),
                    links: name_list(several),
                })
            }
        };
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); n_links];
        for (j, joint) in description.joints.iter().enumerate() {
            children[joint.parent].push(j);
        }

        let mut model = Model {
            description,
            inertial_scales: vec![1.0; n_links],
            joints: Vec::new(),
            joint_names: NameIndex::default(),
            bodies: Vec::new(),
            links: vec![
                LinkPlacement {
                    body: None,
                    fixed_parent: None,
                    body_from_link: Transform::identity(),
                };
                n_links
            ],
            link_order: Vec::with_capacity(n_links),
            root_link,
            nq: 0,
            nv: 0,
            floating_base: options.floating_base,
            warnings: Vec::new(),
        };
        model.warnings = model.description.notes.clone();
        let root_body = if options.floating_base {
            model.push_joint(
                ROOT_JOINT_NAME.to_string(),
                JointKind::Floating,
                "floating",
                None,
                None,
                root_link,
            );
            Some(0)
        } else {
            None
        };
        model.links[root_link].body = root_body;
        // Depth-first traversal, children in file order: a body (and its coordinates) is created
        // when its link is visited, so coordinates follow the same depth-first order.
        let mut stack: Vec<(usize, Option<usize>)> = vec![(root_link, None)];
        while let Some((link, via)) = stack.pop() {
            if let Some(j) = via {
                let spec = &model.description.joints[j];
                let parent_body = model.links[spec.parent].body;
                if spec.joint_type == UrdfJointType::Fixed {
                    model.links[link].body = parent_body;
                    model.links[link].fixed_parent = Some((j, spec.parent));
                    if spec.mimic.is_some() {
                        model.warnings.push(format!(
                            "{path}:{}: the <mimic> on fixed joint '{}' is ignored (a fixed joint has no coordinate)",
                            spec.line, spec.name
                        ));
                    }
                } else {
                    let (kind, type_name) = match spec.joint_type {
                        UrdfJointType::Prismatic => (JointKind::Prismatic, "prismatic"),
                        UrdfJointType::Floating => (JointKind::Floating, "floating"),
                        UrdfJointType::Continuous => (JointKind::Revolute, "continuous"),
                        _ => (JointKind::Revolute, "revolute"),
                    };
                    let name = spec.name.clone();
                    let new_body = model.bodies.len();
                    model.push_joint(name, kind, type_name, parent_body, Some(j), link);
                    model.links[link].body = Some(new_body);
                }
            }
            model.link_order.push(link);
            // Push in reverse so the first child is visited first.
            for &j in children[link].iter().rev() {
                stack.push((model.description.joints[j].child, Some(j)));
            }
        }
        if model.link_order.len() < n_links {
            let mut reached = vec![false; n_links];
            for &l in &model.link_order {
                reached[l] = true;
            }
            let unreached: Vec<usize> = (0..n_links).filter(|&l| !reached[l]).collect();
            let joint = joint_on_cycle(&parent_joint, &model.description, unreached[0]);
            return Err(ModelError::Cycle {
                path: path.to_string(),
                line: model.description.joints[joint].line,
                joint: model.description.joints[joint].name.clone(),
                links: name_list(&unreached),
            });
        }
        model.joint_names = NameIndex::of(model.joints.iter().map(|j| j.name.as_str()));
        model.resolve_mimics(path);
        model.refresh();
        model.check_nominal_consistency(path);
        Ok(model)
    }

    fn push_joint(
        &mut self,
        name: String,
        kind: JointKind,
        type_name: &'static str,
        parent: Option<usize>,
        source: Option<usize>,
        link: usize,
    ) {
        let joint = Joint {
            name,
            kind,
            type_name,
            parent,
            q_index: self.nq,
            v_index: self.nv,
            source,
            parent_from_joint: Transform::identity(),
            axis: Vec3::x(),
            axis_index: coordinate_axis_index(&Vec3::x()),
            mimic: None,
        };
        self.nq += joint.nq();
        self.nv += joint.nv();
        self.joints.push(joint);
        self.bodies.push(Body {
            link,
            inertia: Inertia::zero(),
        });
    }

    /// Records each moving joint's `<mimic>` relation. A mimic naming no moving joint (or itself)
    /// is ignored with a warning, as Pinocchio does: the joint then moves independently.
    fn resolve_mimics(&mut self, path: &str) {
        for i in 0..self.joints.len() {
            let Some(source) = self.joints[i].source else {
                continue;
            };
            let spec = &self.description.joints[source];
            let Some(mimic) = &spec.mimic else { continue };
            let leader = self.joint_index(&mimic.joint);
            match leader {
                Some(leader) if leader != i && self.joints[leader].nv() == 1 => {
                    self.joints[i].mimic = Some((leader, mimic.multiplier, mimic.offset));
                }
                _ => self.warnings.push(format!(
                    "{path}:{}: joint '{}' mimics '{}', which is not a moving joint of this robot (the mimic is ignored: '{}' moves independently){}",
                    spec.line,
                    spec.name,
                    mimic.joint,
                    spec.name,
                    crate::text::closest_suggestion(&mimic.joint, self.joints.iter().map(|j| j.name.as_str())),
                )),
            }
        }
    }

    /// Recomputes every derived quantity (link placements in their bodies, joint placements and
    /// axes, merged body inertias) from [`Model::description`]. Call after changing a value there.
    /// Allocates nothing.
    pub fn refresh(&mut self) {
        for &link in &self.link_order {
            self.links[link].body_from_link = match self.links[link].fixed_parent {
                None => Transform::identity(),
                Some((joint, parent_link)) => self.links[parent_link]
                    .body_from_link
                    .compose(&joint_origin(&self.description.joints[joint])),
            };
        }
        for body in &mut self.bodies {
            body.inertia = Inertia::zero();
        }
        for ((spec, placement), &scale) in self
            .description
            .links
            .iter()
            .zip(&self.links)
            .zip(&self.inertial_scales)
        {
            if let Some(body) = placement.body {
                let inertia = placement
                    .body_from_link
                    .act_inertia(&link_inertia(&spec.inertial.scaled(scale)));
                self.bodies[body].inertia += inertia;
            }
        }
        for joint in &mut self.joints {
            let Some(source) = joint.source else { continue };
            let spec = &self.description.joints[source];
            joint.parent_from_joint = self.links[spec.parent]
                .body_from_link
                .compose(&joint_origin(spec));
            let axis = Vec3::from(spec.axis);
            let norm = axis.norm();
            if norm > 0.0 {
                joint.set_axis(axis / norm);
            }
        }
    }

    /// The inertial values link `link` contributes to its body: its `<inertial>` with
    /// [`Model::inertial_scales`] applied (mass and inertia tensor times the scale).
    pub fn effective_inertial(&self, link: usize) -> InertialSpec {
        self.description.links[link]
            .inertial
            .scaled(self.inertial_scales[link])
    }

    /// Index of the moving joint with this name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        let joints = &self.joints;
        self.joint_names
            .find(name, joints.len(), |i| joints[i].name.as_str())
    }

    /// Puts every URDF mimic follower whose position coordinate is not in `kept` where its row
    /// puts it, `q = multiplier · q_leader + offset` (`q`: dim nq). A follower of a follower takes
    /// its leader's placed value: each pass settles one more link of such a chain.
    pub fn place_mimic_followers(&self, q: &mut [f64], kept: &[usize]) {
        for _ in 0..self.joints.len() {
            let mut moved = false;
            for joint in &self.joints {
                let Some((leader, multiplier, offset)) = joint.mimic else {
                    continue;
                };
                if kept.contains(&joint.q_index) {
                    continue;
                }
                let placed = multiplier * q[self.joints[leader].q_index] + offset;
                if q[joint.q_index] != placed {
                    q[joint.q_index] = placed;
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
    }

    /// The neutral configuration: all coordinates 0, identity quaternions (`dim nq`).
    pub fn neutral_configuration(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.nq];
        for joint in &self.joints {
            if joint.kind == JointKind::Floating {
                q[joint.q_index + 6] = 1.0;
            }
        }
        q
    }

    /// The robot's name (`<robot name>`).
    pub fn name(&self) -> &str {
        &self.description.robot_name
    }

    /// Warnings for inertias that are not physical at the nominal values, and for moving bodies
    /// without mass (docs/method.md §6: warn, do not refuse — Pinocchio loads these files).
    fn check_nominal_consistency(&mut self, path: &str) {
        for spec in &self.description.links {
            if !spec.has_inertial {
                continue;
            }
            if let Some(about_com) = link_inertia(&spec.inertial).inertia_about_com() {
                if let Some(violation) = check_inertia(&about_com) {
                    self.warnings.push(format!(
                        "{path}:{}: the inertia of link '{}' {violation}; no rigid body has it (loaded anyway, as Pinocchio does)",
                        spec.line, spec.name
                    ));
                }
            }
        }
        // The links with mass of every body, in link order (one pass over the links: a pass per
        // body made loading quadratic in the number of links).
        let mut massive_links: Vec<Vec<usize>> = vec![Vec::new(); self.bodies.len()];
        for (l, placement) in self.links.iter().enumerate() {
            if let Some(b) = placement.body {
                if self.description.links[l].inertial.mass > 0.0 {
                    massive_links[b].push(l);
                }
            }
        }
        for (b, body) in self.bodies.iter().enumerate() {
            let merged: Vec<&str> = massive_links[b]
                .iter()
                .map(|&l| self.description.links[l].name.as_str())
                .collect();
            let link = &self.description.links[body.link];
            let floating = self.joints[b].kind == JointKind::Floating;
            if floating && singular::is_massless(self, b) {
                let below = singular::first_moving_child(self, b).map_or(
                    String::new(),
                    |c| format!(", and joint '{}' can move the rest of the robot while '{}' moves the other way at no cost", self.joints[c].name, link.name),
                );
                self.warnings.push(format!(
                    "{path}:{}: link '{}' is on the floating joint '{}' but has no mass or inertia{below}: the mass matrix is singular (a massless floating base); give '{}' an <inertial> (its real mass) or load it with a fixed base",
                    link.line, link.name, self.joints[b].name, link.name
                ));
            } else if singular::is_massless(self, b) {
                self.warnings.push(format!(
                    "{path}:{}: link '{}' moves (joint '{}') but has no mass and no inertia; the mass matrix is singular unless bodies below it carry inertia",
                    link.line, link.name, self.joints[b].name
                ));
            } else if merged.len() > 1 {
                if let Some(violation) = body
                    .inertia
                    .inertia_about_com()
                    .and_then(|i| check_inertia(&i))
                {
                    self.warnings.push(format!(
                        "{path}: the merged inertia of links {} (body of link '{}') {violation}",
                        merged.join(", "),
                        link.name
                    ));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str, floating_base: bool) -> Result<Model, ModelError> {
        let description = parse_description(text, "t.urdf")?;
        Model::from_description(description, LoadOptions { floating_base }, "t.urdf")
    }

    const CHAIN: &str = r#"<robot name="chain">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0.5 0 0" rpy="0 0 0"/><mass value="2"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.2"/></inertial></link>
  <link name="a_tip"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="b"/>
  <joint name="ja" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 2"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="a"/><child link="a_tip"/><origin xyz="1 0 0"/></joint>
  <joint name="jb" type="prismatic"><parent link="a_tip"/><child link="b"/><origin xyz="0 0 0.5"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"#;

    /// The coordinate-axis shortcut follows the axis: a refresh that tilts it off `e_z` (a
    /// parameter) takes the general path, one that puts it back the shortcut, and a prismatic joint
    /// never has it.
    #[test]
    fn coordinate_axis_follows_the_axis() {
        let mut model = load(CHAIN, false).unwrap();
        assert_eq!(model.joints[0].revolute_coordinate_axis(), Some(2));
        assert_eq!(model.joints[1].revolute_coordinate_axis(), None);
        model.description.joints[0].axis = [0.0, 1e-3, 1.0];
        model.refresh();
        assert_eq!(model.joints[0].revolute_coordinate_axis(), None);
        let tilted = model.joints[0].parent_from_child(&[0.7]);
        let general = model.joints[0]
            .parent_from_joint
            .compose(&model.joints[0].joint_transform(&[0.7]));
        assert_eq!(tilted.rotation, general.rotation);
        model.description.joints[0].axis = [1.0, 0.0, 0.0];
        model.refresh();
        assert_eq!(model.joints[0].revolute_coordinate_axis(), Some(0));
        assert_eq!(*model.joints[0].axis(), Vec3::x());
    }

    #[test]
    fn fixed_children_merge_with_parallel_axis_inertia() {
        let model = load(CHAIN, false).unwrap();
        assert_eq!((model.nq, model.nv, model.bodies.len()), (2, 2, 2));
        let a = &model.bodies[0].inertia;
        assert_eq!(a.mass, 3.0);
        // COM: (2·0.5 + 1·1)/3.
        assert!((a.com().unwrap() - Vec3::new(2.0 / 3.0, 0.0, 0.0)).norm() < 1e-15);
        // Joint jb hangs off the merged body at (1, 0, 0.5); its axis is normalised.
        let jb = &model.joints[1];
        assert_eq!(jb.parent, Some(0));
        assert!((jb.parent_from_joint.translation - Vec3::new(1.0, 0.0, 0.5)).norm() < 1e-15);
        assert!((model.joints[0].axis() - Vec3::z()).norm() < 1e-15);
        // The massless moving link b is reported.
        assert!(
            model.warnings.iter().any(|w| w.contains("link 'b' moves")),
            "{:?}",
            model.warnings
        );
    }

    #[test]
    fn floating_base_adds_root_joint() {
        let model = load(CHAIN, true).unwrap();
        assert_eq!(model.joints[0].name, ROOT_JOINT_NAME);
        assert_eq!((model.nq, model.nv), (9, 8));
        assert_eq!(model.neutral_configuration()[6], 1.0);
    }

    #[test]
    fn inertial_rotation_is_applied() {
        // A rod along the inertial frame's x, turned 90° about z, lies along the link's y axis.
        let text = r#"<robot name="r"><link name="w"/>
          <link name="rod"><inertial><origin xyz="0 0 0" rpy="0 0 1.5707963267948966"/><mass value="1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
          <joint name="j" type="continuous"><parent link="w"/><child link="rod"/></joint></robot>"#;
        let model = load(text, false).unwrap();
        let i = model.bodies[0].inertia.rotational;
        assert!((i[(0, 0)] - 1.0).abs() < 1e-15 && i[(1, 1)].abs() < 1e-15);
    }

    #[test]
    fn structural_errors_are_named() {
        let two_parents = r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
          <joint name="j1" type="fixed"><parent link="a"/><child link="c"/></joint>
          <joint name="j2" type="fixed"><parent link="b"/><child link="c"/></joint></robot>"#;
        let msg = load(two_parents, false).unwrap_err().to_string();
        assert!(
            msg.contains("link 'c' is the child of two joints, 'j1' and 'j2'"),
            "{msg}"
        );
        let cycle = r#"<robot name="r"><link name="a"/><link name="b"/>
          <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
          <joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#;
        let msg = load(cycle, false).unwrap_err().to_string();
        assert!(msg.contains("form a cycle"), "{msg}");
        let cycle_beside_root = r#"<robot name="r"><link name="root"/><link name="a"/><link name="b"/>
          <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
          <joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#;
        let msg = load(cycle_beside_root, false).unwrap_err().to_string();
        assert!(
            msg.contains("form a cycle through the links 'a', 'b'"),
            "{msg}"
        );
        let two_roots = r#"<robot name="r"><link name="a"/><link name="b"/></robot>"#;
        let msg = load(two_roots, false).unwrap_err().to_string();
        assert!(msg.contains("2 root links ('a', 'b')"), "{msg}");
    }

    #[test]
    fn mimic_on_fixed_joint_and_unknown_leader_warn() {
        let fixed = r#"<robot name="r"><link name="a"/><link name="b"/>
          <joint name="j" type="fixed"><parent link="a"/><child link="b"/><mimic joint="x"/></joint></robot>"#;
        let model = load(fixed, false).unwrap();
        assert!(model
            .warnings
            .iter()
            .any(|w| w.contains("<mimic> on fixed joint 'j' is ignored")));
        let bad = r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
          <joint name="j1" type="continuous"><parent link="a"/><child link="b"/></joint>
          <joint name="j2" type="continuous"><parent link="b"/><child link="c"/><mimic joint="j0"/></joint></robot>"#;
        let model = load(bad, false).unwrap();
        let warning = model
            .warnings
            .iter()
            .find(|w| w.contains("joint 'j2' mimics 'j0'"))
            .expect("warned");
        assert!(
            warning.contains("did you mean 'j1'") && warning.contains("moves independently"),
            "{warning}"
        );
        assert!(model.joints[1].mimic.is_none());
    }
}
