//! Second-order convergence of HHT-I3 on real robot trees, against references nobody here wrote:
//! Pinocchio ABA + RK4 at h = 1e-5 (`tests/reference/rk4_reference.py`, committed in
//! `tests/fixtures/rk4/` with the FNV-1a hash of the URDF it was computed from, checked here). Also
//! energy behaviour and a spring-damper against its closed form.

mod common;

use nalgebra::DVector;
use ribbon::dynamics::{crba, Data};
use ribbon::integrate::{HhtIntegrator, HhtSettings};
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::{simulate, RobotSystem};
use std::path::Path;

/// Halving h must divide the error by about 4; 3.5 leaves room for the reference's own error while
/// failing clearly for a first-order method (ratio 2).
const MIN_SECOND_ORDER_RATIO: f64 = 3.5;

fn sci(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.3e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn fixed(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.3}"))
        .collect::<Vec<_>>()
        .join(" ")
}

use common::manifest;

fn load(urdf: &str) -> Model {
    Model::from_urdf_file(&manifest(urdf), LoadOptions::default()).expect("robot loads")
}

fn scene(model: &Model, sidecar: &str, step: f64, alpha: f64) -> Scene {
    let file = parse_sidecar(sidecar).expect("sidecar parses");
    let overrides = SceneOverrides {
        step_s: Some(step),
        alpha: Some(alpha),
        ..SceneOverrides::default()
    };
    Scene::resolve(&file, model, "test", overrides).expect("scene resolves")
}

/// Max over the fixture's record times and joints of |q_hht − q_ref|.
fn error_against_fixture(urdf: &str, fixture: &str, gravity: &str, step: f64, alpha: f64) -> f64 {
    let reference: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(manifest(fixture)).expect("fixture exists"))
            .expect("json");
    // The fixture was computed from this very URDF (regenerate it when the URDF changes).
    let urdf_bytes = std::fs::read(manifest(urdf)).expect("urdf");
    assert_eq!(
        reference["urdf_fnv1a64"].as_str(),
        Some(common::fnv1a64(&urdf_bytes).as_str()),
        "{fixture} was computed from another {urdf}: rerun tests/reference/rk4_reference.py"
    );
    let model = load(urdf);
    let sidecar = format!("[scene]\nduration = 1.0\ngravity = {gravity}\n[outputs]\nrate = 100");
    let scene = scene(&model, &sidecar, step, alpha);
    let environment = scene.environment();
    let trajectory = simulate(model, environment, &scene).expect("simulation runs");
    let mut worst: f64 = 0.0;
    for record in reference["records"].as_array().expect("records") {
        let t = record["t"].as_f64().unwrap();
        let k = trajectory
            .times
            .iter()
            .position(|x| (x - t).abs() < 1e-9)
            .unwrap_or_else(|| panic!("t = {t} recorded"));
        for (name, value) in record["q"].as_object().unwrap() {
            let i = trajectory
                .outputs
                .iter()
                .position(|o| o.name == format!("q.{name}"))
                .unwrap_or_else(|| panic!("output q.{name}"));
            worst = worst.max((trajectory.values[i][k] - value.as_f64().unwrap()).abs());
        }
    }
    worst
}

fn assert_second_order(urdf: &str, fixture: &str, gravity: &str) {
    for alpha in [-0.1, -0.3] {
        let errors: Vec<f64> = [2e-3, 1e-3, 5e-4]
            .iter()
            .map(|h| error_against_fixture(urdf, fixture, gravity, *h, alpha))
            .collect();
        let ratios = [errors[0] / errors[1], errors[1] / errors[2]];
        println!(
            "{urdf} alpha {alpha}: errors {}, ratios {}",
            sci(&errors),
            fixed(&ratios)
        );
        for ratio in ratios {
            assert!(
                ratio >= MIN_SECOND_ORDER_RATIO,
                "{urdf} alpha {alpha}: error ratio {ratio:.3} < {MIN_SECOND_ORDER_RATIO} (errors {errors:?})"
            );
        }
    }
}

#[test]
fn double_pendulum_is_second_order_against_pinocchio_rk4() {
    assert_second_order(
        "robots/double_pendulum/double_pendulum.urdf",
        "tests/fixtures/rk4/double_pendulum.json",
        "[0.0, -9.81, 0.0]",
    );
}

#[test]
fn ur5_passive_fall_is_second_order_against_pinocchio_rk4() {
    assert_second_order(
        "robots/ur5/ur5.urdf",
        "tests/fixtures/rk4/ur5.json",
        "[0.0, 0.0, -9.81]",
    );
}

/// Kinetic plus potential energy of the double pendulum (gravity −y) at the integrator's state.
fn energy(system: &mut RobotSystem, q: &DVector<f64>, v: &DVector<f64>) -> f64 {
    let model = &system.model;
    let mass_matrix = crba(model, &mut system.data, q.as_slice()).clone();
    let kinetic = 0.5 * v.dot(&(&mass_matrix * v));
    ribbon::dynamics::forward_kinematics(model, &mut system.data, q.as_slice());
    let potential: f64 = model
        .bodies
        .iter()
        .enumerate()
        .map(|(b, body)| {
            let com = body.inertia.com().unwrap_or_default();
            let world_com = system.data.world_from_body[b].transform_point(&com);
            -body.inertia.mass * system.environment.gravity.dot(&world_com)
        })
        .sum();
    kinetic + potential
}

fn energy_series(alpha: f64, step: f64, duration: f64) -> Vec<f64> {
    let model = load("robots/double_pendulum/double_pendulum.urdf");
    let sidecar = format!("[scene]\nduration = {duration}\ngravity = [0.0, -9.81, 0.0]");
    let scene = scene(&model, &sidecar, step, alpha);
    let environment = scene.environment();
    let mut system = RobotSystem::new(model, environment, &scene);
    let settings = HhtSettings {
        alpha,
        step_s: step,
        ..HhtSettings::default()
    };
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    let mut series = Vec::with_capacity(scene.n_steps + 1);
    for k in 0..=scene.n_steps {
        if k > 0 {
            hht.step(&mut system).expect("step");
        }
        let (q, v) = (hht.state().q.clone(), hht.state().v.clone());
        series.push(energy(&mut system, &q, &v));
    }
    series
}

#[test]
fn trapezoidal_energy_error_is_second_order() {
    // α = 0 on a conservative system: no numerical dissipation, the energy error is O(h²).
    let max_error = |h: f64| {
        let e = energy_series(0.0, h, 2.0);
        e.iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max)
    };
    let errors = [max_error(2e-3), max_error(1e-3), max_error(5e-4)];
    let ratios = [errors[0] / errors[1], errors[1] / errors[2]];
    println!(
        "alpha 0 energy errors {}, ratios {}",
        sci(&errors),
        fixed(&ratios)
    );
    for ratio in ratios {
        assert!(
            ratio >= MIN_SECOND_ORDER_RATIO,
            "energy error ratio {ratio} (errors {errors:?})"
        );
    }
}

#[test]
fn numerical_damping_does_not_pump_energy_over_20_s() {
    // α < 0: energy may rise in single steps on a nonlinear system, but its trend over 20 s must not
    // rise: the least-squares slope is ≤ 0 within its standard error.
    let e = energy_series(-0.1, 1e-3, 20.0);
    let n = e.len() as f64;
    let t: Vec<f64> = (0..e.len()).map(|k| k as f64 * 1e-3).collect();
    let (t_mean, e_mean) = (t.iter().sum::<f64>() / n, e.iter().sum::<f64>() / n);
    let sxx: f64 = t.iter().map(|x| (x - t_mean).powi(2)).sum();
    let slope = t
        .iter()
        .zip(&e)
        .map(|(x, y)| (x - t_mean) * (y - e_mean))
        .sum::<f64>()
        / sxx;
    let intercept = e_mean - slope * t_mean;
    let residual: f64 = t
        .iter()
        .zip(&e)
        .map(|(x, y)| (y - intercept - slope * x).powi(2))
        .sum();
    let standard_error = (residual / (n - 2.0) / sxx).sqrt();
    let rises = e.windows(2).filter(|w| w[1] > w[0]).count();
    println!("alpha -0.1, 20 s: slope {slope:.3e} J/s ± {standard_error:.3e}, {rises} single-step rises, E0 {:.6}, E(20) {:.6}", e[0], e[e.len() - 1]);
    assert!(
        slope <= standard_error,
        "energy trend rises: slope {slope} > standard error {standard_error}"
    );
}

#[test]
fn spring_damper_pendulum_matches_closed_form() {
    // A one-joint bar without gravity, with a joint spring and URDF damping: exactly linear, so the
    // closed form of the damped oscillator is the reference.
    let urdf = r#"<robot name="p"><link name="w"/>
      <link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0.1666666666666667" iyz="0" izz="0.1666666666666667"/></inertial></link>
      <joint name="hinge" type="continuous"><parent link="w"/><child link="bar"/><axis xyz="0 0 1"/>
      <dynamics damping="0.4" friction="0"/></joint></robot>"#;
    let model = Model::from_description(
        ribbon::model::parse_description(urdf, "p.urdf").unwrap(),
        LoadOptions::default(),
        "p.urdf",
    )
    .unwrap();
    // I about the hinge = 1/6 + 2·0.25 = 2/3 kg·m²; no gravity: I θ̈ + c θ̇ + k θ = 0 exactly.
    let (inertia, c, k, theta0): (f64, f64, f64, f64) = (2.0 / 3.0, 0.4, 6.0, 0.3);
    let sidecar = format!(
        "[scene]\nduration = 2.0\neffects = [\"joint_damping\", \"joint_springs\"]\ninitial.q = {{ hinge = {theta0} }}\n\
         [[scene.spring]]\njoint = \"hinge\"\nstiffness = {k}\n[outputs]\nrate = 100"
    );
    let omega0 = (k / inertia).sqrt();
    let zeta = c / (2.0 * (k * inertia).sqrt());
    let omega_d = omega0 * (1.0 - zeta * zeta).sqrt();
    let exact = |t: f64| {
        theta0
            * (-zeta * omega0 * t).exp()
            * ((omega_d * t).cos() + zeta * omega0 / omega_d * (omega_d * t).sin())
    };
    let mut errors = Vec::new();
    for h in [2e-3, 1e-3, 5e-4] {
        let scene = scene(&model, &sidecar, h, -0.1);
        let trajectory = simulate(model.clone(), scene.environment(), &scene).expect("runs");
        let error = trajectory
            .times
            .iter()
            .zip(&trajectory.values[0])
            .map(|(t, q)| (q - exact(*t)).abs())
            .fold(0.0, f64::max);
        errors.push(error);
    }
    let ratios = [errors[0] / errors[1], errors[1] / errors[2]];
    println!(
        "spring-damper errors {}, ratios {}",
        sci(&errors),
        fixed(&ratios)
    );
    // HHT's error for this oscillator: O((ω h)²) relative; at h = 1e-3, ω = 3 rad/s: ~1e-5 of θ0.
    assert!(
        errors[1] < 1e-5 * theta0 * 10.0,
        "error at h = 1e-3: {}",
        errors[1]
    );
    for ratio in ratios {
        assert!(
            ratio >= MIN_SECOND_ORDER_RATIO,
            "ratio {ratio} (errors {errors:?})"
        );
    }
}

/// Centre of mass of the whole robot (world frame) and its velocity, from the body velocities that
/// `nonlinear_effects` leaves in `data`.
fn com_and_velocity(
    system: &mut RobotSystem,
    q: &DVector<f64>,
    v: &DVector<f64>,
) -> (nalgebra::Vector3<f64>, nalgebra::Vector3<f64>) {
    ribbon::dynamics::nonlinear_effects(
        &system.model,
        &system.environment.gravity,
        &mut system.data,
        q.as_slice(),
        v.as_slice(),
    );
    ribbon::dynamics::forward_kinematics(&system.model, &mut system.data, q.as_slice());
    let (mut moment, mut momentum, mut mass) =
        (nalgebra::Vector3::zeros(), nalgebra::Vector3::zeros(), 0.0);
    for (b, body) in system.model.bodies.iter().enumerate() {
        let c = body.inertia.com().unwrap_or_default();
        let world_from_body = system.data.world_from_body[b];
        let velocity = system.data.velocity[b];
        moment += world_from_body.transform_point(&c) * body.inertia.mass;
        momentum += world_from_body.rotation
            * (velocity.linear + velocity.angular.cross(&c))
            * body.inertia.mass;
        mass += body.inertia.mass;
    }
    (moment / mass, momentum / mass)
}

/// Distance of the floating ur5's centre of mass from its exact parabola after 0.5 s of tumbling.
fn floating_fall_com_error(step: f64) -> f64 {
    let model = Model::from_urdf_file(
        &manifest("robots/ur5/ur5.urdf"),
        LoadOptions {
            floating_base: true,
        },
    )
    .unwrap();
    let sidecar = "[scene]\nduration = 0.5\nbase = \"floating\"\n\
                   initial.base = { xyz = [0.0, 0.0, 1.0], rpy = [0.1, 0.2, 0.3], v = [0.3, 0.0, 0.1], w = [0.5, -0.2, 0.1] }\n\
                   initial.v = { elbow_joint = 1.0 }";
    let scene = scene(&model, sidecar, step, -0.1);
    let environment = scene.environment();
    let mut system = RobotSystem::new(model, environment, &scene);
    let settings = HhtSettings {
        alpha: -0.1,
        step_s: step,
        ..HhtSettings::default()
    };
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    let (q_start, v_start) = (hht.state().q.clone(), hht.state().v.clone());
    let (com0, com_velocity0) = com_and_velocity(&mut system, &q_start, &v_start);
    for _ in 0..scene.n_steps {
        hht.step(&mut system).expect("step");
    }
    let (q, v) = (hht.state().q.clone(), hht.state().v.clone());
    let norm = q.rows(3, 4).norm();
    assert!((norm - 1.0).abs() < 1e-12, "quaternion norm {norm}");
    let t = scene.duration_s;
    let expected =
        com0 + com_velocity0 * t + nalgebra::Vector3::new(0.0, 0.0, -9.81) * (0.5 * t * t);
    let (com, _) = com_and_velocity(&mut system, &q, &v);
    (com - expected).norm()
}

#[test]
fn floating_base_stays_normalised_and_falls_freely() {
    // A floating ur5 tumbling in free fall: whatever its joints do, the exact centre of mass follows
    // c0 + v0 t + g t²/2 and the base quaternion stays unit (asserted inside). The integrator's
    // deviation from the parabola is discretisation error and must fall as h².
    let errors: Vec<f64> = [1e-3, 5e-4, 2.5e-4]
        .iter()
        .map(|h| floating_fall_com_error(*h))
        .collect();
    let ratios = [errors[0] / errors[1], errors[1] / errors[2]];
    println!(
        "floating ur5 COM errors {} m, ratios {}",
        sci(&errors),
        fixed(&ratios)
    );
    assert!(errors[0] < 1e-5, "COM error at h = 1e-3: {} m", errors[0]);
    for ratio in ratios {
        assert!(
            ratio >= MIN_SECOND_ORDER_RATIO,
            "ratio {ratio} (errors {errors:?})"
        );
    }
}

#[test]
fn data_is_reusable_across_models_of_same_shape() {
    // A sanity check the analysis relies on: Data built for one model works for a perturbed copy.
    let model = load("robots/ur5/ur5.urdf");
    let mut data = Data::new(&model);
    let q = vec![0.1; model.nq];
    let m1 = crba(&model, &mut data, &q).clone();
    let mut heavier = model.clone();
    heavier.description.links[3].inertial.mass *= 1.1;
    heavier.refresh();
    let m2 = crba(&heavier, &mut data, &q).clone();
    assert!((&m1 - &m2).amax() > 1e-6);
    // Reused, the Data gives exactly what a fresh one gives for the perturbed model (nothing of the
    // first model is left in it), and back again.
    let fresh = crba(&heavier, &mut Data::new(&heavier), &q).clone();
    assert_eq!(m2, fresh);
    let back = crba(&model, &mut data, &q).clone();
    assert_eq!(back, m1);
}

/// Largest change of any recorded value that `[scene] newton_matrix = "reuse"` may cause on the
/// ur5 scene over its 2 s: a reused matrix accepts iterates anywhere below the Newton position
/// tolerance (1e-10 rad) instead of overshooting it, and that difference may accumulate over the
/// 2000 steps; 1e-7 is a thousand times the tolerance, far below any envelope width.
const REUSE_MAX_CHANGE: f64 = 1e-7;

/// The sidecar key reaches the integrator: with `newton_matrix = "reuse"` the ur5 (springs, no
/// constraint rows) factorises far less often and records the same trajectory to Newton noise.
#[test]
fn newton_matrix_reuse_from_the_sidecar_saves_factorisations_and_keeps_the_trajectory() {
    let dir = common::target_dir().join("tests-newton-matrix-reuse");
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let shipped =
        std::fs::read_to_string(manifest("robots/ur5/ur5.uncertainty.toml")).expect("ur5 sidecar");
    assert!(
        shipped.contains("\n[scene]\n"),
        "the ur5 sidecar has a [scene] table"
    );
    let reuse_sidecar = dir.join("ur5.reuse.uncertainty.toml");
    std::fs::write(
        &reuse_sidecar,
        shipped.replacen("\n[scene]\n", "\n[scene]\nnewton_matrix = \"reuse\"\n", 1),
    )
    .expect("write sidecar");
    let run = |sidecar: &Path, name: &str| {
        let summary = dir.join(format!("{name}.json"));
        let csv = dir.join(format!("{name}.csv"));
        let path = |p: &Path| p.to_string_lossy().into_owned();
        common::run_checked(
            &common::ribbon_bin(),
            &common::args([
                "simulate".to_string(),
                path(&manifest("robots/ur5/ur5.urdf")),
                "--uncertainty".to_string(),
                path(sidecar),
                "--summary".to_string(),
                path(&summary),
                "--csv".to_string(),
                path(&csv),
            ]),
            "simulate of the ur5",
        );
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(summary).expect("summary"))
                .expect("JSON");
        let values: Vec<f64> = std::fs::read_to_string(csv)
            .expect("CSV")
            .lines()
            .skip(1)
            .flat_map(|line| {
                line.split(',')
                    .map(|v| v.parse::<f64>().expect("a number"))
                    .collect::<Vec<_>>()
            })
            .collect();
        (
            stats["stats"]["factorisations"]
                .as_u64()
                .expect("factorisations"),
            values,
        )
    };
    let (fresh_factorisations, fresh) = run(&manifest("robots/ur5/ur5.uncertainty.toml"), "fresh");
    let (reuse_factorisations, reused) = run(&reuse_sidecar, "reuse");
    assert_eq!(fresh.len(), reused.len());
    let change = fresh
        .iter()
        .zip(&reused)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!(
        "factorisations {fresh_factorisations} fresh, {reuse_factorisations} reused; largest change {change:.2e}"
    );
    assert!(
        reuse_factorisations * 2 < fresh_factorisations,
        "{reuse_factorisations} factorisations with reuse, {fresh_factorisations} without"
    );
    assert!(change <= REUSE_MAX_CHANGE, "largest change {change:e}");
}
