//! ROS descriptions (issue 42 item 3, docs/ros.md): a xacro file, or a URDF with xacro markup
//! outside comments, is refused (exit 2) at the line of its first markup with the command that
//! expands it — the packages its `$(find PKG)` need, found in a checkout whose directory is not
//! named after its package, and the arguments without a default —; a URDF that only declares the
//! xacro namespace loads; `package://` mesh URIs resolve through the checkout's `package.xml` and
//! through `ROS_PACKAGE_PATH`, and a package found nowhere is an error naming the search.

mod common;

use common::{fresh_scratch_dir, ribbon_bin};
use std::fs;
use std::path::Path;
use std::process::{Command, Output};

/// A package directory `dir` whose `package.xml` names it `name`.
fn package(dir: &Path, name: &str) {
    fs::create_dir_all(dir).unwrap();
    fs::write(
        dir.join("package.xml"),
        format!("<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <name>{name}</name>\n  <version>1.0.0</version>\n</package>\n"),
    )
    .unwrap();
}

/// `ribbon ARGS` run in `dir` with `ROS_PACKAGE_PATH` set to `ros_package_path` (or removed).
fn ribbon_in(dir: &Path, args: &[&str], ros_package_path: Option<&Path>) -> Output {
    let mut command = Command::new(ribbon_bin());
    command
        .args(args)
        .current_dir(dir)
        .env_remove("ROS_PACKAGE_PATH")
        .env_remove("AMENT_PREFIX_PATH");
    if let Some(path) = ros_package_path {
        command.env("ROS_PACKAGE_PATH", path);
    }
    command.output().expect("ribbon runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// One link on a hinge, its collision a mesh given by `mesh_uri`.
fn one_link_urdf(mesh_uri: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<robot name="tiny" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <!-- expanded by xacro from <xacro:tiny prefix="${{prefix}}"/> -->
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1.0"/><origin xyz="0 0 -0.5"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial>
    <collision><origin xyz="0 0 -1"/><geometry><mesh filename="{mesh_uri}"/></geometry></collision>
  </link>
  <joint name="hinge" type="continuous"><parent link="base"/><child link="arm"/>
    <axis xyz="1 0 0"/></joint>
</robot>
"#
    )
}

/// A sidecar whose scene asks for contacts of `arm` with a ground far below (the mesh is loaded,
/// nothing touches).
const CONTACT_SIDECAR: &str = "[scene]\nduration = 0.01\n\n[scene.contact]\n\
pairs = [[\"arm\", \"ground\"]]\n\n[[scene.geometry]]\nname = \"ground\"\ntype = \"halfspace\"\n\
xyz = [0.0, 0.0, -5.0]\n";

#[test]
fn a_xacro_file_is_refused_with_the_command_that_expands_it() {
    let ws = fresh_scratch_dir("ros_descriptions", "xacro");
    // A workspace's src/ with a checkout named after its repository, not its package.
    let repo = ws.join("src").join("Tiny_Robot_Description");
    package(&repo, "tiny_description");
    fs::create_dir_all(repo.join("urdf")).unwrap();
    let xacro = repo.join("urdf").join("tiny.urdf.xacro");
    fs::write(
        &xacro,
        "<?xml version=\"1.0\"?>\n<robot name=\"tiny\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n\
         <!-- a comment with <xacro:nothing/> -->\n\
         <xacro:arg name=\"prefix\"/>\n<xacro:arg name=\"mass\" default=\"1.0\"/>\n\
         <xacro:include filename=\"$(find tiny_description)/urdf/tiny_macro.xacro\"/>\n\
         <xacro:include filename=\"$(find no_such_description)/urdf/other.xacro\"/>\n\
         <xacro:tiny prefix=\"$(arg prefix)\"/>\n</robot>\n",
    )
    .unwrap();
    let out = ribbon_in(
        &ws,
        &["params", "src/Tiny_Robot_Description/urdf/tiny.urdf.xacro"],
        None,
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(
        lines[0],
        "error: src/Tiny_Robot_Description/urdf/tiny.urdf.xacro:4: this is a xacro file, not a URDF (<xacro:arg>); ribbon reads URDF only",
        "{stderr}"
    );
    assert_eq!(
        lines[1],
        "  expand it with xacro, then run ribbon on tiny.urdf:"
    );
    assert_eq!(
        lines[2],
        "      xacro src/Tiny_Robot_Description/urdf/tiny.urdf.xacro prefix:=VALUE > tiny.urdf    # ROS 2, with the workspace holding its packages sourced"
    );
    let src = fs::canonicalize(ws.join("src")).unwrap();
    assert_eq!(
        lines[3],
        format!(
            "      ROS_PACKAGE_PATH={} xacro src/Tiny_Robot_Description/urdf/tiny.urdf.xacro prefix:=VALUE > tiny.urdf    # ROS 1 (xacro 1.x), any checkout",
            src.display()
        )
    );
    assert_eq!(
        lines[4],
        format!(
            "  its $(find) packages: tiny_description at {}",
            src.join("Tiny_Robot_Description").display()
        )
    );
    assert!(
        lines[5].starts_with(
            "  not found here: no_such_description (packages are looked up in ROS_PACKAGE_PATH"
        ),
        "{stderr}"
    );
    // Every detail line is indented under the one-line headline.
    assert!(lines[1..].iter().all(|l| l.starts_with("  ")), "{stderr}");

    // The same markup in a file named .urdf: refused at the line of the first markup.
    let urdf = ws.join("expression.urdf");
    fs::write(
        &urdf,
        one_link_urdf("package://tiny_description/meshes/cube.stl").replace(
            "<axis xyz=\"1 0 0\"/>",
            "<axis xyz=\"1 0 0\"/><origin rpy=\"0 ${pi/2} 0\"/>",
        ),
    )
    .unwrap();
    let out = ribbon_in(&ws, &["params", "expression.urdf"], None);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).starts_with(
            "error: expression.urdf:11: this is a xacro file, not a URDF (<origin rpy=\"0 ${pi/2} 0\">)"
        ),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn a_urdf_that_only_declares_xacro_loads_and_its_package_meshes_resolve() {
    let ws = fresh_scratch_dir("ros_descriptions", "packages");
    let repo = ws.join("src").join("Tiny_Robot_Description");
    package(&repo, "tiny_description");
    fs::create_dir_all(repo.join("meshes")).unwrap();
    fs::write(
        repo.join("meshes").join("cube.stl"),
        common::binary_stl(&common::cube(0.05)),
    )
    .unwrap();
    // The expanded URDF beside the workspace's src/: the package is one level below an ancestor.
    let urdf = ws.join("tiny.urdf");
    fs::write(
        &urdf,
        one_link_urdf("package://tiny_description/meshes/cube.stl"),
    )
    .unwrap();
    fs::write(ws.join("tiny.uncertainty.toml"), CONTACT_SIDECAR).unwrap();
    let out = ribbon_in(&ws, &["simulate", "tiny.urdf"], None);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));

    // Elsewhere, found only through ROS_PACKAGE_PATH (a directory holding the checkout).
    let away = fresh_scratch_dir("ros_descriptions", "packages_away");
    fs::copy(&urdf, away.join("tiny.urdf")).unwrap();
    fs::write(away.join("tiny.uncertainty.toml"), CONTACT_SIDECAR).unwrap();
    let out = ribbon_in(&away, &["simulate", "tiny.urdf"], None);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains(
            "mesh file 'package://tiny_description/meshes/cube.stl': cannot read the file"
        ) && stderr.contains("add the directory holding the package to ROS_PACKAGE_PATH"),
        "{stderr}"
    );
    let out = ribbon_in(&away, &["simulate", "tiny.urdf"], Some(&ws.join("src")));
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    // The mesh's hull is what contacts see: a wrong file would be refused, a missing one too.
    assert!(ribbon::geometry::resolve_mesh_path(
        urdf.to_str().unwrap(),
        "package://tiny_description/meshes/cube.stl"
    )
    .is_file());
}
