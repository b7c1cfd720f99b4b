//! Newton across the stiction band (docs/contacts.md §4): a block sliding on flat ground comes to
//! rest, so its tangential velocity passes through the narrow band `|v_t| ≤ v_s` of regularised
//! friction, where the friction's slope grows by orders of magnitude. Without limiting the Newton
//! corrections, the iterates jumped across the band from one side to the other: at the fixed step
//! of 1 ms the run failed when the block stopped (Newton did not converge at t = 0.409 s), and the
//! adaptive step needed 9 335 Newton iterations and 804 matrix refreshes for 1 000 steps.
//!
//! Asserted here, at the fixed and at the adaptive step: the run completes, the block stops after
//! `v²/(2 μ g)` (0.5 %), no step fails, the adaptive step never subdivides, and Newton needs at most
//! two iterations per step on average (measured: 1.03).

use ribbon::model::{parse_description, LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::simulate;

const G: f64 = 9.81;
/// The closed form's tolerance (the issue's 0.5 %).
const DISTANCE_RELATIVE: f64 = 5e-3;
/// Newton iterations per step, on average, that the run may use (measured 1.03).
const MAX_ITERATIONS_PER_STEP: f64 = 2.0;

/// A 1 kg box of 0.2 m on prismatic joints `x` (along the ground) and `z` (up).
const SLIDER: &str = r#"<robot name="slider"><link name="world"/>
  <link name="carriage"/>
  <joint name="x" type="prismatic"><parent link="world"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="carriage"/><child link="body"/>
    <axis xyz="0 0 1"/><limit lower="-100" upper="100" effort="1" velocity="1"/></joint>
  <link name="body"><inertial><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link></robot>"#;

fn sliding_block(step_control: &str) -> (f64, f64, ribbon::integrate::HhtStats) {
    let (speed, mu, stiffness) = (2.0, 0.5, 1e6);
    // Resting on the ground: k δ^1.5 = m g.
    let resting_depth = (G / stiffness).powf(1.0 / 1.5);
    let sidecar = format!(
        r#"[scene]
duration = 1.0
step = 0.001
step_control = "{step_control}"
initial.q = {{ z = {} }}
initial.v = {{ x = {speed} }}
[scene.contact]
pairs = [["body", "ground"]]
stiffness = {stiffness}
friction = {mu}
[[scene.geometry]]
name = "ground"
type = "halfspace"
[outputs]
velocities = true
"#,
        0.1 - resting_depth
    );
    let mut model = Model::from_description(
        parse_description(SLIDER, "slider.urdf").expect("URDF parses"),
        LoadOptions::default(),
        "slider.urdf",
    )
    .expect("model builds");
    let file = parse_sidecar(&sidecar).expect("sidecar parses");
    let scene = Scene::resolve(&file, &model, "slider.toml", SceneOverrides::default())
        .expect("scene resolves");
    scene.apply_gravity(&mut model);
    let trajectory = simulate(model, &scene)
        .unwrap_or_else(|e| panic!("{step_control} step: the sliding block's run failed: {e}"));
    let column = |name: &str| {
        let i = trajectory
            .outputs
            .iter()
            .position(|o| o.name == name)
            .expect("output");
        *trajectory.values[i].last().expect("records")
    };
    let predicted = speed * speed / (2.0 * mu * G);
    let distance = column("q.x");
    eprintln!(
        "{step_control}: distance {distance:.6} m (closed form {predicted:.6} m), final speed {:.1e} m/s, {} Newton iterations for {} steps, {} limited",
        column("v.x"),
        trajectory.stats.newton_iterations,
        trajectory.stats.steps,
        trajectory.stats.limited_newton_updates
    );
    (
        (distance - predicted) / predicted,
        column("v.x"),
        trajectory.stats,
    )
}

#[test]
fn a_sliding_block_stops_at_the_fixed_and_the_adaptive_step() {
    for step_control in ["fixed", "adaptive"] {
        let (relative_error, final_speed, stats) = sliding_block(step_control);
        assert!(
            relative_error.abs() <= DISTANCE_RELATIVE,
            "{step_control}: sliding distance off by {relative_error:e} of v²/(2μg)"
        );
        assert!(
            final_speed.abs() < 1e-4,
            "{step_control}: the block must have stopped"
        );
        assert_eq!(stats.step_failures, 0, "{step_control}: {stats:?}");
        assert_eq!(stats.substeps, stats.steps, "{step_control}: {stats:?}");
        assert!(
            stats.limited_newton_updates > 0,
            "{step_control}: the stop should have needed a limited correction"
        );
        let per_step = stats.newton_iterations as f64 / stats.steps as f64;
        assert!(
            per_step <= MAX_ITERATIONS_PER_STEP,
            "{step_control}: {per_step:.2} Newton iterations per step ({stats:?})"
        );
    }
}
