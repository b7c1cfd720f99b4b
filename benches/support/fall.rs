//! The step benches' problem (`hht_step.rs`, `hht_batch.rs`): a robot's 1 s passive fall under
//! gravity (0, 0, −9.81) from a non-trivial rest configuration, h = 1 ms, α = −0.1, no other
//! effect — the same problem `benches/mujoco_timing.py` gives MuJoCo. Shared through `#[path]`.

#![allow(dead_code)]

use std::path::Path;

use nalgebra::DVector;
use ribbon::model::{JointKind, LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::RobotSystem;

/// Steps per trajectory: 1 s at h = 1 ms.
pub const STEPS_PER_FALL: u64 = 1000;

/// Initial revolute angles (rad), cycled over the revolute joints in coordinate order; prismatic joints
/// start at `PRISMATIC_Q0` (m). Within the joint limits of all three robots. Keep in sync with
/// `REVOLUTE_Q0` in benches/mujoco_timing.py.
pub const REVOLUTE_Q0: [f64; 7] = [0.3, -0.8, 0.5, -1.2, 0.4, 1.0, 0.7];
/// Initial prismatic positions, m.
pub const PRISMATIC_Q0: f64 = 0.02;

/// The fall of the robot at `path`: its system (gravity only), the scene, and the start `(q0, v0)`.
pub fn fall_problem(path: &Path) -> (RobotSystem, Scene, DVector<f64>, DVector<f64>) {
    let model = Model::from_urdf_file(path, LoadOptions::default()).expect("robot loads");
    let file = parse_sidecar("[scene]\ngravity = [0.0, 0.0, -9.81]\n").expect("sidecar parses");
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
    let mut model = model;
    scene.apply_gravity(&mut model);
    let mut q0 = DVector::from_column_slice(&scene.initial_q);
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
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let system = RobotSystem::new(model, &scene);
    (system, scene, q0, v0)
}
