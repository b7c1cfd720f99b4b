//! The URDF-level description of a robot: every value a parameter can address, exactly as the file
//! states it (link frames, `<inertial>` blocks, joint origins and axes). The compiled [`Model`]
//! derives its tree quantities from this and is refreshed whenever a value here changes.
//!
//! [`Model`]: super::Model

use std::collections::HashMap;

/// The kind of a URDF joint that ribbon supports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrdfJointType {
    /// Rotation about `axis` within limits.
    Revolute,
    /// Rotation about `axis` without limits (one coordinate: the angle).
    Continuous,
    /// Translation along `axis`.
    Prismatic,
    /// No motion: the child link is merged into its parent body and kept as a frame.
    Fixed,
    /// Six degrees of freedom (position and unit quaternion).
    Floating,
}

impl UrdfJointType {
    /// The URDF spelling of the type.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Revolute => "revolute",
            Self::Continuous => "continuous",
            Self::Prismatic => "prismatic",
            Self::Fixed => "fixed",
            Self::Floating => "floating",
        }
    }

    /// Whether the joint has an axis (and so damping and friction parameters).
    pub fn has_axis(self) -> bool {
        matches!(self, Self::Revolute | Self::Continuous | Self::Prismatic)
    }
}

/// A link's `<inertial>`: mass, centre of mass and inertia tensor about it.
///
/// Policy for a link without `<inertial>`: it is massless (all zero), like Pinocchio and the URDF
/// specification; [`LinkSpec::has_inertial`] keeps the distinction for warnings and listings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InertialSpec {
    /// Mass (kg).
    pub mass: f64,
    /// `<origin xyz>`: the centre of mass in the link frame (m).
    pub com: [f64; 3],
    /// `<origin rpy>`: orientation of the inertia frame relative to the link frame (rad).
    pub rpy: [f64; 3],
    /// `ixx ixy ixz iyy iyz izz` about the centre of mass, in the inertia frame (kg·m²).
    pub inertia: [f64; 6],
}

impl InertialSpec {
    /// These values with the mass and the whole inertia tensor multiplied by `factor` (unitless),
    /// the centre of mass and the inertia frame unchanged: the `link.NAME.scale` parameter (a
    /// density error). `factor = 1` returns the values bitwise unchanged.
    #[inline]
    pub fn scaled(&self, factor: f64) -> InertialSpec {
        InertialSpec {
            mass: self.mass * factor,
            com: self.com,
            rpy: self.rpy,
            inertia: self.inertia.map(|entry| entry * factor),
        }
    }
}

/// One URDF `<link>`.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkSpec {
    /// The link's name.
    pub name: String,
    /// Whether the file gives an `<inertial>` element.
    pub has_inertial: bool,
    /// The inertial values (all zero without `<inertial>`).
    pub inertial: InertialSpec,
    /// The link's `<collision>` elements in file order (only contacts read them).
    pub collisions: Vec<CollisionSpec>,
    /// 1-based line of the `<link>` element in the file.
    pub line: u32,
}

/// One URDF `<collision>` element of a link: a shape placed in the link frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionSpec {
    /// `<collision name>` when given.
    pub name: Option<String>,
    /// `<origin>` as `[x, y, z, roll, pitch, yaw]` (m, rad): the shape's frame in the link frame.
    pub origin: [f64; 6],
    /// The shape and its sizes (sizes are parameters: `link.NAME.collision.K.radius`, …).
    pub shape: CollisionShape,
    /// 1-based line of the `<collision>` element.
    pub line: u32,
}

/// The shape of a `<collision><geometry>`, in URDF conventions (cylinders and capsules along the
/// shape frame's z axis, boxes centred on its origin).
#[derive(Clone, Debug, PartialEq)]
pub enum CollisionShape {
    /// `<sphere radius>`, m.
    Sphere {
        /// Radius, m.
        radius: f64,
    },
    /// `<box size>`: full edge lengths along x, y, z, m.
    Box {
        /// Edge lengths, m.
        size: [f64; 3],
    },
    /// `<cylinder radius length>`: axis along z, `length` end to end, m.
    Cylinder {
        /// Radius, m.
        radius: f64,
        /// Length along z, m.
        length: f64,
    },
    /// `<capsule radius length>`: a cylinder of `length` along z with hemispherical caps, m.
    Capsule {
        /// Radius, m.
        radius: f64,
        /// Length of the cylindrical part along z, m.
        length: f64,
    },
    /// `<mesh filename scale>`: loaded only when a scene declares contacts for its link
    /// (`crate::geometry`, docs/contacts.md §1).
    Mesh {
        /// The file name as written (`package://`, `file://`, absolute or relative to the URDF).
        filename: String,
        /// `scale` along x, y, z of the mesh frame (1 when absent), unitless.
        scale: [f64; 3],
    },
    /// A `<geometry>` ribbon could not read (the loader's note says why).
    Unreadable {
        /// What is wrong with it.
        reason: String,
    },
}

/// A `<mimic>` element: `q_self = multiplier · q_leader + offset`.
#[derive(Clone, Debug, PartialEq)]
pub struct MimicSpec {
    /// Name of the leading joint.
    pub joint: String,
    /// Multiplier (default 1).
    pub multiplier: f64,
    /// Offset (default 0).
    pub offset: f64,
}

/// One URDF `<joint>`.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSpec {
    /// The joint's name.
    pub name: String,
    /// The joint's type.
    pub joint_type: UrdfJointType,
    /// Index of the parent link in [`Description::links`].
    pub parent: usize,
    /// Index of the child link in [`Description::links`].
    pub child: usize,
    /// `<origin>` as `x y z roll pitch yaw` (m, rad): the joint frame in the parent link frame.
    pub origin: [f64; 6],
    /// `<axis xyz>` in the joint frame (normalised by the model; default `1 0 0`).
    pub axis: [f64; 3],
    /// `<dynamics damping>` (N·m·s/rad or N·s/m; 0 when absent).
    pub damping: f64,
    /// `<dynamics friction>` (N·m or N; 0 when absent).
    pub friction: f64,
    /// `<limit lower upper>` (rad or m); infinite when the file gives none.
    pub limits: [f64; 2],
    /// `<limit effort velocity>` (N·m or N, rad/s or m/s); infinite when the file gives none.
    pub effort_velocity: [f64; 2],
    /// `<mimic>`, when present on a moving joint.
    pub mimic: Option<MimicSpec>,
    /// 1-based line of the `<joint>` element in the file.
    pub line: u32,
}

/// A whole URDF robot as values.
#[derive(Clone, Debug, PartialEq)]
pub struct Description {
    /// `<robot name>`.
    pub robot_name: String,
    /// The URDF file's path as given to the loader (relative collision meshes are resolved against
    /// its directory).
    pub path: String,
    /// Links in file order.
    pub links: Vec<LinkSpec>,
    /// Joints in file order.
    pub joints: Vec<JointSpec>,
    /// Non-fatal findings of reading the file, each naming file, line and element (markup that
    /// does not affect dynamics and was ignored, repeated elements, unusual limits). A model built
    /// from this description starts its [`warnings`](super::Model::warnings) with them.
    pub notes: Vec<String>,
    /// The links' names to their indices, for [`Description::link_index`] (a search through the
    /// list per name made a sidecar with a key per link quadratic in the links).
    link_names: NameIndex,
    /// The joints' names to their indices, for [`Description::joint_index`].
    joint_names: NameIndex,
}

/// Names to indices, the first occurrence kept. A lookup trusts an index only when the name
/// there is the one asked for, and searches the list otherwise (a name not in the index, or a
/// list changed after the index was built), so it always answers as a search of the list would.
#[derive(Clone, Default, PartialEq)]
pub(crate) struct NameIndex(HashMap<String, usize>);

impl NameIndex {
    /// The index of every name of `names`, the first occurrence kept.
    pub fn of<'a>(names: impl Iterator<Item = &'a str>) -> NameIndex {
        let mut index = HashMap::new();
        for (i, name) in names.enumerate() {
            index.entry(name.to_string()).or_insert(i);
        }
        NameIndex(index)
    }

    /// The index of `name` among `count` names, `name_at(i)` giving the i-th.
    pub fn find<'a>(
        &self,
        name: &str,
        count: usize,
        name_at: impl Fn(usize) -> &'a str,
    ) -> Option<usize> {
        match self.0.get(name) {
            Some(&i) if i < count && name_at(i) == name => Some(i),
            _ => (0..count).find(|&i| name_at(i) == name),
        }
    }
}

impl std::fmt::Debug for NameIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NameIndex({} names)", self.0.len())
    }
}

impl Description {
    /// A description of `robot_name` (read from `path`) with its links, joints and notes.
    pub fn new(
        robot_name: String,
        path: String,
        links: Vec<LinkSpec>,
        joints: Vec<JointSpec>,
        notes: Vec<String>,
    ) -> Description {
        Description {
            link_names: NameIndex::of(links.iter().map(|l| l.name.as_str())),
            joint_names: NameIndex::of(joints.iter().map(|j| j.name.as_str())),
            robot_name,
            path,
            links,
            joints,
            notes,
        }
    }

    /// Index of the link with this name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        let links = &self.links;
        self.link_names
            .find(name, links.len(), |i| links[i].name.as_str())
    }

    /// Index of the joint with this name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        let joints = &self.joints;
        self.joint_names
            .find(name, joints.len(), |i| joints[i].name.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::NameIndex;

    fn find(index: &NameIndex, names: &[&str], name: &str) -> Option<usize> {
        index.find(name, names.len(), |i| names[i])
    }

    /// The index answers as a search of the list would: the first of repeated names, none for a
    /// missing one, and the list's answer when the list changed after the index was built.
    #[test]
    fn a_name_index_answers_as_a_search_of_the_list() {
        let names = ["a", "b", "a", "c"];
        let index = NameIndex::of(names.iter().copied());
        assert_eq!(find(&index, &names, "a"), Some(0));
        assert_eq!(find(&index, &names, "c"), Some(3));
        assert_eq!(find(&index, &names, "d"), None);
        let renamed = ["a", "x", "a", "c"];
        assert_eq!(find(&index, &renamed, "b"), None);
        assert_eq!(find(&index, &renamed, "x"), Some(1));
        let shorter = ["c"];
        assert_eq!(find(&index, &shorter, "c"), Some(0));
        assert_eq!(find(&index, &shorter, "a"), None);
    }
}
