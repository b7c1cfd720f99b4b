//! Collision meshes (issue 13, "meshes"; docs/contacts.md §1): a URDF `<mesh>` collision becomes
//! the convex hull of its scaled vertices, rests like the primitive it hulls, and bad mesh files
//! are refused naming the URDF, the link, the collision index and the resolved path.

mod common;

use common::{binary_stl, cube};
use ribbon::model::{parse_description, LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::simulate;
use std::path::{Path, PathBuf};

/// Standard gravity of the scenes, m/s².
const G: f64 = 9.81;
/// Mass of the test body, kg.
const MASS: f64 = 1.0;
/// Contact stiffness of the scenes, N/m^1.5 (the default).
const STIFFNESS: f64 = 1e6;
/// Largest difference of resting heights between a hulled mesh and the primitive it equals, m
/// (the task's 1e-9 m).
const SAME_HEIGHT_M: f64 = 1e-9;
/// Relative tolerance of the resting normal force against m·g (as in tests/contacts.rs: the
/// motion after 3 s of damped settling is far below it).
const WEIGHT_RELATIVE: f64 = 1e-6;

/// Half edge of the test cube, m. 0.125 is exact in `f32` (mesh-loader's vertex type); 0.1 would
/// put the hull 1.5e-9 m away from a `<box size="0.2 …">` by rounding alone.
const HALF_EDGE: f64 = 0.125;

/// A fresh directory for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("meshes")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// An ASCII STL of `triangles`.
fn ascii_stl(triangles: &[[[f32; 3]; 3]]) -> String {
    let mut text = String::from("solid test\n");
    for triangle in triangles {
        text.push_str("facet normal 0 0 0\nouter loop\n");
        for v in triangle {
            text.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
        }
        text.push_str("endloop\nendfacet\n");
    }
    text.push_str("endsolid test\n");
    text
}

/// A tetrahedron whose base lies at z = `-base` (m) below its origin and whose apex is above.
fn tetrahedron(base: f32) -> Vec<[[f32; 3]; 3]> {
    let p = [
        [0.125, 0.0, -base],
        [-0.0625, 0.125, -base],
        [-0.0625, -0.125, -base],
        [0.0, 0.0, 0.125],
    ];
    vec![
        [p[0], p[2], p[1]],
        [p[0], p[1], p[3]],
        [p[1], p[2], p[3]],
        [p[2], p[0], p[3]],
    ]
}

/// A body of mass [`MASS`] on a vertical prismatic joint, carrying `collision`.
fn slider_urdf(collision: &str) -> String {
    format!(
        r#"<robot name="slider"><link name="world"/>
        <joint name="z" type="prismatic"><parent link="world"/><child link="body"/>
          <axis xyz="0 0 1"/><limit lower="-100" upper="100" effort="1" velocity="1"/></joint>
        <link name="body"><inertial><mass value="{MASS}"/>
          <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
          <collision><geometry>{collision}</geometry></collision></link></robot>"#
    )
}

/// The model of `urdf` as if read from `dir/robot.urdf` (relative meshes resolve against `dir`).
fn model_in(dir: &Path, urdf: &str) -> Model {
    let path = dir.join("robot.urdf").display().to_string();
    Model::from_description(
        parse_description(urdf, &path).expect("URDF parses"),
        LoadOptions::default(),
        &path,
    )
    .expect("model builds")
}

/// A damped drop onto a half-space ground from `z0`, 3 s. Adaptive step: a face landing flat touches
/// at its four corners, four times as stiff as one point, and at h = 1 ms the fixed step's Newton
/// fails at that touch-down with this damping (so does one point of 4e6 N/m^1.5;
/// docs/contacts.md §6).
fn resting_scene(z0: f64) -> String {
    format!(
        r#"[scene]
duration = 3.0
step = 1e-3
step_control = "adaptive"
gravity = [0.0, 0.0, -{G}]
initial.q = {{ z = {z0} }}
[scene.contact]
pairs = [["body", "ground"]]
stiffness = {STIFFNESS}
damping = 50.0
[[scene.geometry]]
name = "ground"
type = "halfspace"
[outputs]
contact_forces = true
"#
    )
}

fn resolve(model: &Model, sidecar: &str) -> Result<Scene, String> {
    let file = parse_sidecar(sidecar)?;
    Scene::resolve(&file, model, "test.toml", SceneOverrides::default()).map_err(|e| e.to_string())
}

/// Final height of the joint and final normal force of a damped drop.
fn rest(dir: &Path, collision: &str, z0: f64) -> (f64, f64) {
    let model = model_in(dir, &slider_urdf(collision));
    let scene = resolve(&model, &resting_scene(z0)).expect("scene resolves");
    let environment = scene.environment();
    let trajectory = simulate(model, environment, &scene).expect("simulation runs");
    let column = |name: &str| {
        let i = trajectory
            .outputs
            .iter()
            .position(|o| o.name == name)
            .unwrap_or_else(|| panic!("no output {name}"));
        *trajectory.values[i].last().expect("samples")
    };
    (column("q.z"), column("contact.body.ground.normal"))
}

/// Resting depth of the Hunt–Crossley contact under the weight shared by `points` contact points
/// (the tetrahedron's base: its 3 corners; a face of the cube: its 4), m.
fn resting_depth(points: u32) -> f64 {
    (MASS * G / (f64::from(points) * STIFFNESS)).powf(1.0 / 1.5)
}

#[test]
fn hulled_cube_rests_like_the_box_and_carries_the_weight() {
    let dir = scratch("cube");
    std::fs::write(dir.join("cube.stl"), binary_stl(&cube(HALF_EDGE as f32))).unwrap();
    let z0 = HALF_EDGE + 0.01;
    let (z_box, f_box) = rest(
        &dir,
        &format!(r#"<box size="{0} {0} {0}"/>"#, 2.0 * HALF_EDGE),
        z0,
    );
    let (z_mesh, f_mesh) = rest(&dir, r#"<mesh filename="cube.stl"/>"#, z0);
    eprintln!(
        "box rests at {z_box:.12} m, hulled cube at {z_mesh:.12} m (difference {:.3e} m); \
         normal forces {f_box:.9} N, {f_mesh:.9} N (m g = {} N)",
        z_mesh - z_box,
        MASS * G
    );
    assert!(
        (z_mesh - z_box).abs() < SAME_HEIGHT_M,
        "{z_mesh} vs {z_box}"
    );
    assert!(
        ((f_mesh - MASS * G) / (MASS * G)).abs() < WEIGHT_RELATIVE,
        "{f_mesh} N"
    );
    // And both at the closed-form resting height of a face on its four corners.
    assert!((z_mesh - (HALF_EDGE - resting_depth(4))).abs() < SAME_HEIGHT_M);
}

#[test]
fn scaled_mesh_rests_twice_as_high_above_its_origin() {
    let dir = scratch("scaled");
    let base = 0.0625;
    std::fs::write(dir.join("tetra.stl"), ascii_stl(&tetrahedron(base as f32))).unwrap();
    let (z1, f1) = rest(&dir, r#"<mesh filename="tetra.stl"/>"#, base + 0.01);
    let (z2, f2) = rest(
        &dir,
        r#"<mesh filename="tetra.stl" scale="2 2 2"/>"#,
        2.0 * base + 0.01,
    );
    // The base is a triangle face: its three corners share the weight (the body only moves in z).
    let depth = resting_depth(3);
    // The origin stands `base · scale` above the base, which sinks `depth` into the ground.
    let (above1, above2) = (z1 + depth, z2 + depth);
    eprintln!(
        "tetrahedron: origin {above1:.12} m above the contact plane, scaled by 2: {above2:.12} m; \
         forces {f1:.9} N, {f2:.9} N"
    );
    assert!((above1 - base).abs() < SAME_HEIGHT_M, "{above1}");
    assert!(
        (above2 - 2.0 * above1).abs() < SAME_HEIGHT_M,
        "{above2} vs {above1}"
    );
    for f in [f1, f2] {
        assert!(((f - MASS * G) / (MASS * G)).abs() < WEIGHT_RELATIVE, "{f}");
    }
}

fn mesh_error(dir: &Path, collision: &str) -> String {
    let model = model_in(dir, &slider_urdf(collision));
    resolve(&model, &resting_scene(0.5)).expect_err("the scene must be refused")
}

#[test]
fn bad_meshes_are_refused_naming_urdf_link_collision_and_path() {
    let dir = scratch("bad");
    let urdf = dir.join("robot.urdf").display().to_string();
    // Two triangles in the plane z = 0: no volume.
    let flat = [
        [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.1, 0.0]],
        [[0.0, 0.0, 0.0], [0.1, 0.1, 0.0], [0.0, 0.1, 0.0]],
    ];
    std::fs::write(dir.join("flat.stl"), binary_stl(&flat)).unwrap();
    std::fs::write(dir.join("empty.stl"), binary_stl(&[])).unwrap();
    std::fs::write(dir.join("foot.xyz"), "1 2 3\n").unwrap();
    let path_of = |name: &str| dir.join(name).display().to_string();
    let cases = [
        ("missing.stl", "cannot read the file"),
        ("flat.stl", "span no volume"),
        ("empty.stl", "has no vertices"),
        ("foot.xyz", "unsupported mesh format"),
    ];
    for (file, reason) in cases {
        let message = mesh_error(&dir, &format!(r#"<mesh filename="{file}"/>"#));
        eprintln!("{file}: {message}");
        for expected in [
            "[scene.contact] pairs",
            urdf.as_str(),
            "link 'body' <collision> 0 (line 6)",
            &format!("mesh file '{}'", path_of(file)),
            reason,
        ] {
            assert!(
                message.contains(expected),
                "{file}: '{expected}' not in: {message}"
            );
        }
    }
}

#[test]
fn broken_collision_meshes_cost_nothing_without_contacts() {
    let dir = scratch("no_contacts");
    let model = model_in(&dir, &slider_urdf(r#"<mesh filename="missing.stl"/>"#));
    let scene = resolve(&model, "[scene]\nduration = 0.01\nstep = 1e-3\n")
        .expect("a scene without contacts never reads collision meshes");
    assert!(scene.contact.is_none());
}

#[test]
fn a_concave_mesh_is_hulled_with_one_note() {
    let dir = scratch("concave");
    // Two tetrahedra apart from each other: a closed mesh that encloses far less than its hull.
    let mut triangles = tetrahedron(0.0625);
    let shifted: Vec<[[f32; 3]; 3]> = tetrahedron(0.0625)
        .iter()
        .map(|t| t.map(|v| [v[0] + 0.5, v[1], v[2]]))
        .collect();
    triangles.extend(shifted);
    std::fs::write(dir.join("pair.stl"), binary_stl(&triangles)).unwrap();
    let cube_dir = scratch("convex");
    std::fs::write(cube_dir.join("cube.stl"), binary_stl(&cube(0.125))).unwrap();
    let notes = |dir: &Path, file: &str| {
        let model = model_in(dir, &slider_urdf(&format!(r#"<mesh filename="{file}"/>"#)));
        let scene = resolve(&model, &resting_scene(0.5)).expect("scene resolves");
        scene.contact.expect("contacts").geometry.notes
    };
    let concave = notes(&dir, "pair.stl");
    eprintln!("{concave:?}");
    assert_eq!(concave.len(), 1, "{concave:?}");
    assert!(
        concave[0].contains("link 'body' <collision> 0")
            && concave[0].contains("over-approximates"),
        "{}",
        concave[0]
    );
    assert!(notes(&cube_dir, "cube.stl").is_empty());
}

#[test]
fn package_uris_resolve_against_the_urdf_ancestors() {
    let dir = scratch("package");
    let urdf_dir = dir.join("my_robot").join("urdf");
    let mesh_dir = dir.join("my_robot").join("meshes");
    std::fs::create_dir_all(&urdf_dir).unwrap();
    std::fs::create_dir_all(&mesh_dir).unwrap();
    std::fs::write(mesh_dir.join("cube.stl"), binary_stl(&cube(0.125))).unwrap();
    let urdf = urdf_dir.join("robot.urdf").display().to_string();
    let found = ribbon::geometry::resolve_mesh_path(&urdf, "package://my_robot/meshes/cube.stl");
    assert_eq!(
        std::fs::canonicalize(found).unwrap(),
        std::fs::canonicalize(mesh_dir.join("cube.stl")).unwrap()
    );
    // Relative and file:// names.
    assert_eq!(
        ribbon::geometry::resolve_mesh_path(&urdf, "../meshes/cube.stl"),
        urdf_dir.join("../meshes/cube.stl")
    );
    assert_eq!(
        ribbon::geometry::resolve_mesh_path(&urdf, "file:///tmp/x.stl"),
        PathBuf::from("/tmp/x.stl")
    );
}
