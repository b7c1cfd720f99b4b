//! Tests of `RobotSystem` on the shipped robots: the residual after the mass matrix equals the
//! plain residual bit for bit, the hot paths and the sensitivity steps allocate nothing, and the
//! SE(3) exponential of the floating base's update.

use super::*;
use crate::integrate::tests::alloc_counter::allocations;
use crate::integrate::{HhtIntegrator, HhtSettings};
use crate::model::{LoadOptions, Model};
use crate::scene::{read_sidecar, SceneOverrides};
use crate::spatial::Mat3;

fn robot(name: &str) -> (RobotSystem, Scene) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(name);
    let model =
        Model::from_urdf_file(&root.join(format!("{name}.urdf")), LoadOptions::default()).unwrap();
    let (file, _) = read_sidecar(&root.join(format!("{name}.uncertainty.toml"))).unwrap();
    let scene = Scene::resolve(&file, &model, name, SceneOverrides::default()).unwrap();
    (RobotSystem::new(model, scene.environment(), &scene), scene)
}

/// The residual after a mass matrix reuses its placements only at its configuration, and gives
/// the plain residual's bits either way, even when other calls moved `data` in between.
#[test]
fn residual_after_mass_matrix_equals_the_plain_residual_bitwise() {
    let (mut system, _) = robot("ur5");
    let n = system.model.nv;
    let q1 = DVector::from_fn(n, |i, _| 0.3 + 0.1 * i as f64);
    let q2 = DVector::from_fn(n, |i, _| -0.2 + 0.15 * i as f64);
    let v = DVector::from_fn(n, |i, _| 0.5 - 0.2 * i as f64);
    let qdd = DVector::from_fn(n, |i, _| -0.4 + 0.15 * i as f64);
    let mut mass = DMatrix::zeros(n, n);
    let bits = |x: &DVector<f64>| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let plain = |system: &mut RobotSystem, q: &DVector<f64>| {
        let mut out = DVector::zeros(n);
        system
            .dynamics_residual(0.0, q, &v, &qdd, &mut out)
            .unwrap();
        out
    };
    let (at_q1, at_q2) = (plain(&mut system, &q1), plain(&mut system, &q2));
    assert_ne!(bits(&at_q1), bits(&at_q2));
    let mut out = DVector::zeros(n);
    // At the mass matrix's q, with `data` left at another q by a residual in between.
    system.mass_matrix(0.0, &q1, &mut mass).unwrap();
    plain(&mut system, &q2);
    system
        .dynamics_residual_after_mass_matrix(0.0, &q1, &v, &qdd, &mut out)
        .unwrap();
    assert_eq!(bits(&out), bits(&at_q1));
    // Once more at the same q: the placements went back into `data` and are not held any
    // more, so this one computes them, with the same bits.
    system
        .dynamics_residual_after_mass_matrix(0.0, &q1, &v, &qdd, &mut out)
        .unwrap();
    assert_eq!(bits(&out), bits(&at_q1));
    // At another q: the plain residual there, not the mass matrix's placements.
    system.mass_matrix(0.0, &q1, &mut mass).unwrap();
    system
        .dynamics_residual_after_mass_matrix(0.0, &q2, &v, &qdd, &mut out)
        .unwrap();
    assert_eq!(bits(&out), bits(&at_q2));
}

/// The hot path of a study allocates nothing: dynamics kernels, a step with effects (ur5: springs
/// and dampers) and with constraint rows (slider-crank: a loop and a drive), and applying a
/// parameter point.
#[test]
fn hot_paths_allocate_nothing() {
    for name in ["ur5", "slider_crank"] {
        let (mut system, scene) = robot(name);
        let q0 = DVector::from_column_slice(&scene.initial_q);
        let v0 = DVector::from_column_slice(&scene.initial_v);
        let settings = HhtSettings {
            alpha: scene.alpha,
            step_s: scene.step_s,
            ..HhtSettings::default()
        };
        let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).unwrap();
        hht.step(&mut system).unwrap();
        let (q, v) = (q0.as_slice().to_vec(), v0.as_slice().to_vec());
        let before = allocations();
        for _ in 0..100 {
            hht.step(&mut system).unwrap();
        }
        crba(&system.model, &mut system.data, &q);
        rnea(
            &system.model,
            &system.environment.gravity,
            &mut system.data,
            &q,
            &v,
            &v,
        );
        nonlinear_effects(
            &system.model,
            &system.environment.gravity,
            &mut system.data,
            &q,
            &v,
        );
        let used = allocations() - before;
        assert_eq!(
            used, 0,
            "{name}: {used} allocations in 100 steps and the kernels"
        );
    }
    let (mut system, _) = robot("double_pendulum");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/double_pendulum");
    let (file, _) = read_sidecar(&root.join("double_pendulum.uncertainty.toml")).unwrap();
    let space = crate::uncertainty::ParameterSpace::from_sidecar(
        &file,
        &system.model,
        &system.environment,
        "dp",
    )
    .unwrap();
    let xi = [0.3, -0.7];
    let before = allocations();
    space.apply(&mut system.model, &mut system.environment, &xi);
    assert_eq!(allocations() - before, 0, "ParameterSpace::apply allocated");
}

/// A forward-sensitivity step allocates nothing either: ur5 (springs, inertial and symbol
/// directions) and slider-crank (loop and drive, directions that move the loop's geometry, the
/// projected velocity's sensitivity).
#[test]
fn sensitivity_steps_allocate_nothing() {
    use crate::integrate::HhtSensitivity;
    for name in ["ur5", "slider_crank"] {
        let (mut system, scene) = robot(name);
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("robots")
            .join(name);
        let (file, _) = read_sidecar(&root.join(format!("{name}.uncertainty.toml"))).unwrap();
        let space = crate::uncertainty::ParameterSpace::from_sidecar(
            &file,
            &system.model,
            &system.environment,
            name,
        )
        .unwrap();
        let xi = space.nominal_xi();
        space.apply(&mut system.model, &mut system.environment, &xi);
        let mut list = Vec::new();
        let directions: Vec<_> = (0..space.len())
            .map(|j| {
                space.target_derivatives(&xi, j, &mut list);
                list.clone()
            })
            .collect();
        system.set_parameter_directions(&directions);
        let q0 = DVector::from_column_slice(&scene.initial_q);
        let v0 = DVector::from_column_slice(&scene.initial_v);
        let settings = crate::integrate::HhtSettings {
            projection_keeps_newton_mass: false,
            ..crate::simulate::hht_settings(&scene)
        };
        let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).unwrap();
        let mut sensitivity = HhtSensitivity::new(&mut system, &hht, &q0, &v0).unwrap();
        sensitivity.step(&mut system, &mut hht).unwrap();
        let before = allocations();
        for _ in 0..50 {
            sensitivity.step(&mut system, &mut hht).unwrap();
            sensitivity.reported_velocity(&mut system, &hht).unwrap();
        }
        let used = allocations() - before;
        assert_eq!(
            used, 0,
            "{name}: {used} allocations in 50 sensitivity steps"
        );
    }
}

#[test]
fn se3_exp_of_pure_rotation_and_translation() {
    let (t, r) = se3_exp(&Vec3::new(1.0, 2.0, 3.0), &Vec3::zeros());
    assert_eq!(t, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(*r.to_rotation_matrix().matrix(), Mat3::identity());
    // A screw: rotate π/2 about z while moving 1 along x (body frame) sweeps a quarter circle.
    let (t, r) = se3_exp(
        &Vec3::new(1.0, 0.0, 0.0),
        &Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
    );
    let radius = 2.0 / std::f64::consts::PI;
    assert!((t - Vec3::new(radius, radius, 0.0)).norm() < 1e-12, "{t}");
    assert!((r * Vec3::x() - Vec3::y()).norm() < 1e-12);
    assert!((r.quaternion().norm() - 1.0).abs() < 1e-15);
}

/// The quaternion form against the matrix exponential `I + a [ω]× + b [ω]×²` and
/// `V = I + b [ω]× + c [ω]×²` (closed forms with `sin θ`, `cos θ`), on both sides of the series
/// switch and at large angles.
#[test]
fn se3_exp_matches_the_matrix_exponential() {
    for (scale, tolerance) in [
        (1e-6, 1e-15),
        (9e-5, 1e-15),
        (2e-4, 1e-13),
        (0.3, 1e-14),
        (2.9, 1e-13),
    ] {
        let angular = Vec3::new(0.6, -0.48, 0.64) * scale;
        let linear = Vec3::new(0.3, 1.1, -0.7);
        let theta = angular.norm();
        let skew = angular.cross_matrix();
        let (sin, cos) = theta.sin_cos();
        let rotation =
            Mat3::identity() + skew * (sin / theta) + skew * skew * ((1.0 - cos) / (theta * theta));
        let v = Mat3::identity()
            + skew * ((1.0 - cos) / (theta * theta))
            + skew * skew * ((theta - sin) / (theta * theta * theta));
        let (t, r) = se3_exp(&linear, &angular);
        let r = *r.to_rotation_matrix().matrix();
        assert!(
            (r - rotation).amax() < tolerance,
            "θ {theta}: rotation off by {:e}",
            (r - rotation).amax()
        );
        // Below ~1e-3 rad the reference's own (θ − sin θ)/θ³ has lost its digits to cancellation.
        if theta > 1e-3 {
            let expected = v * linear;
            assert!(
                (t - expected).amax() < tolerance,
                "θ {theta}: translation off by {:e}",
                (t - expected).amax()
            );
        } else {
            assert!((t - (linear + angular.cross(&linear) * 0.5)).amax() < theta * theta);
        }
    }
}
