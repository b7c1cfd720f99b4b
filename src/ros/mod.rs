//! ROS robot descriptions: where a ROS package is on disk ([`package`]: `ROS_PACKAGE_PATH`,
//! `AMENT_PREFIX_PATH`, the usual source-tree layout), which resolves `package://` mesh URIs,
//! and xacro files recognised and refused with the command that expands them ([`xacro`]).
//!
//! Does not: run xacro (a Python tool; ribbon reads URDF only), or read meshes
//! (`geometry::mesh`).

pub mod package;
pub mod xacro;

pub use package::{find_package, package_search_note};
pub use xacro::{xacro_command, XacroMarkup};
