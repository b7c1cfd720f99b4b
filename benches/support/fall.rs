//! The step benches' problem (`hht_step.rs`, `hht_batch.rs`): a robot's 1 s passive motion under
//! gravity, h = 1 ms, α = −0.1, no other effect — the same problem `benches/mujoco_timing.py` gives
//! MuJoCo. Three kinds of robot (issue 16 names them all):
//! - a fixed-base arm (our ur5, example-robot-data's ur5 and panda): a fall under gravity
//!   (0, 0, −9.81) from rest at [`REVOLUTE_Q0`] cycled over the revolute joints;
//! - the floating-base quadruped (`robots/quadruped`, no ground): the same joint angles, the base at
//!   [`QUADRUPED_BASE_XYZ`] spinning at [`QUADRUPED_BASE_W`] (body frame; in uniform gravity a body at
//!   rest would only translate, so the spin is what makes its joints move);
//! - the four-bar (`robots/four_bar`): its shipped sidecar's scene (gravity −y, the crank at
//!   2 rev/s, the loop closed by a planar pin: two constraint rows).
//!
//! Shared through `#[path]`.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use nalgebra::DVector;
use ribbon::model::{JointKind, LoadOptions, Model};
use ribbon::scene::{parse_sidecar, wants_floating_base, Scene, SceneOverrides};
use ribbon::simulate::RobotSystem;

/// Steps per trajectory: 1 s at h = 1 ms.
pub const STEPS_PER_FALL: u64 = 1000;

/// Whether step `k` (1-based) of a fall computes the reported velocity when a study records every
/// `record_every` steps: only the step into a record does.
pub fn reported_velocity(k: u64, record_every: u64) -> ribbon::integrate::ReportedVelocity {
    if k.is_multiple_of(record_every) {
        ribbon::integrate::ReportedVelocity::Computed
    } else {
        ribbon::integrate::ReportedVelocity::Skipped
    }
}

/// Initial revolute angles (rad), cycled over the revolute joints in coordinate order; prismatic joints
/// start at `PRISMATIC_Q0` (m). Within the joint limits of all three robots. Keep in sync with
/// `REVOLUTE_Q0` in benches/mujoco_timing.py.
pub const REVOLUTE_Q0: [f64; 7] = [0.3, -0.8, 0.5, -1.2, 0.4, 1.0, 0.7];
/// Initial prismatic positions, m.
pub const PRISMATIC_Q0: f64 = 0.02;
/// The quadruped's initial base position (m, world frame); keep in sync with mujoco_timing.py.
pub const QUADRUPED_BASE_XYZ: [f64; 3] = [0.0, 0.0, 0.461];
/// The quadruped's initial base angular velocity (rad/s, body frame = world frame at the start's
/// identity orientation; linear velocity 0); keep in sync with mujoco_timing.py.
pub const QUADRUPED_BASE_W: [f64; 3] = [0.4, -0.3, 0.2];

/// The robots the step benches time, as `(name, URDF path)`: the kernel benches' arms
/// (`reference_venv::benchmark_robots`), then the shipped quadruped (floating base) and four-bar
/// (a loop).
pub fn step_robots(root: &Path, arms: Vec<(String, PathBuf)>) -> Vec<(String, PathBuf)> {
    let mut robots = arms;
    robots.push((
        "ribbon-quadruped".to_string(),
        root.join("robots/quadruped/quadruped.urdf"),
    ));
    robots.push((
        "ribbon-four-bar".to_string(),
        root.join("robots/four_bar/four_bar.urdf"),
    ));
    robots
}

fn is_four_bar(path: &Path) -> bool {
    path.file_name().and_then(|n| n.to_str()) == Some("four_bar.urdf")
}

/// The sidecar of the bench problem for the robot at `path` (by file name; see the module doc).
fn problem_sidecar(path: &Path) -> String {
    match path.file_name().and_then(|n| n.to_str()) {
        Some("four_bar.urdf") => {
            std::fs::read_to_string(path.with_file_name("four_bar.uncertainty.toml"))
                .expect("robots/four_bar/four_bar.uncertainty.toml reads")
        }
        Some("quadruped.urdf") => format!(
            "[scene]\ngravity = [0.0, 0.0, -9.81]\nbase = \"floating\"\n\
             initial.base = {{ xyz = {QUADRUPED_BASE_XYZ:?}, rpy = [0.0, 0.0, 0.0], \
             v = [0.0, 0.0, 0.0], w = {QUADRUPED_BASE_W:?} }}\n"
        ),
        _ => "[scene]\ngravity = [0.0, 0.0, -9.81]\n".to_string(),
    }
}

/// The bench problem of the robot at `path`: its system, the scene, and the start `(q0, v0)`.
pub fn fall_problem(path: &Path) -> (RobotSystem, Scene, DVector<f64>, DVector<f64>) {
    let file = parse_sidecar(&problem_sidecar(path)).expect("sidecar parses");
    let floating_base = wants_floating_base(&file, "bench").expect("base type");
    let model = Model::from_urdf_file(path, LoadOptions { floating_base }).expect("robot loads");
    let scene = Scene::resolve(
        &file,
        &model,
        "bench",
        SceneOverrides {
            step_s: Some(1e-3),
            alpha: Some(-0.1),
            ..Default::default()
        },
    )
    .expect("scene resolves");
    let environment = scene.environment();
    let mut q0 = DVector::from_column_slice(&scene.initial_q);
    // The four-bar starts where its sidecar closes the loop; every other robot at REVOLUTE_Q0.
    if !is_four_bar(path) {
        let mut revolute = 0;
        for joint in &model.joints {
            match joint.kind {
                JointKind::Revolute => {
                    q0[joint.q_index] = REVOLUTE_Q0[revolute % REVOLUTE_Q0.len()];
                    revolute += 1;
                }
                JointKind::Prismatic => q0[joint.q_index] = PRISMATIC_Q0,
                JointKind::Floating => {}
            }
        }
    }
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let system = RobotSystem::new(model, environment, &scene);
    (system, scene, q0, v0)
}
