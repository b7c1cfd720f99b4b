//! Reusing the Newton matrix across steps (opt-in), on the shipped ur5's scene: it saves
//! factorisations within the Newton tolerance, travels with the trajectory, and first corrections
//! accepted by the carried contraction stay within the tolerance.
//!
//! Does not: test the default fresh matrix (`order.rs`, `constraints.rs`).

use super::*;

// ---------------------------------------------------------------------------------------------
// Reusing the Newton matrix across steps (opt-in)
// ---------------------------------------------------------------------------------------------

/// Largest difference of the ur5's positions (rad) after 0.5 s of its own scene between the reused
/// and the fresh Newton matrix: both are converged to the position tolerance (1e-10 per step), so
/// over 500 steps they may part by a few hundred times that, not more.
const REUSE_MAX_POSITION_DIFFERENCE: f64 = 1e-7;

/// The ur5 of the shipped robots with its scene (springs and dampers on the joints, no rows).
fn shipped_ur5() -> (crate::simulate::RobotSystem, crate::scene::Scene) {
    shipped_scene("ur5")
}

#[test]
fn reused_newton_matrix_saves_factorisations_at_the_newton_tolerance() {
    let (mut system, scene) = shipped_ur5();
    let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
    let fresh = crate::simulate::hht_settings(&scene);
    assert!(!fresh.reuse_newton_matrix, "the reuse is opt-in");
    let reuse = HhtSettings {
        reuse_newton_matrix: true,
        ..fresh
    };
    let mut run = |settings: HhtSettings| {
        let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
        for _ in 0..500 {
            hht.step(&mut system).expect("step");
        }
        (hht.state().q.clone(), *hht.stats())
    };
    let (q_fresh, s_fresh) = run(fresh);
    let (q_reuse, s_reuse) = run(reuse);
    let difference = (&q_reuse - &q_fresh).amax();
    println!(
        "ur5 0.5 s: fresh {} factorisations, {} iterations; reused {} factorisations, {} iterations; max |Δq| {difference:.2e} rad",
        s_fresh.factorisations, s_fresh.newton_iterations, s_reuse.factorisations, s_reuse.newton_iterations
    );
    assert_eq!(s_fresh.factorisations, 500);
    assert!(s_reuse.factorisations < s_fresh.factorisations);
    assert!(difference > 0.0 && difference <= REUSE_MAX_POSITION_DIFFERENCE);
}

/// The stored factorisation travels with the trajectory: a trajectory swapped out for another one
/// and back continues bitwise as if it had never left (a study's samples do not depend on which
/// samples a thread advanced in between).
#[test]
fn reused_newton_matrix_travels_with_the_trajectory() {
    let (mut system, scene) = shipped_ur5();
    let settings = HhtSettings {
        reuse_newton_matrix: true,
        ..crate::simulate::hht_settings(&scene)
    };
    let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
    let mut other_q0 = q0.clone();
    other_q0[1] += 0.3;
    let mut alone = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    for _ in 0..200 {
        alone.step(&mut system).expect("step");
    }
    let mut shared = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    let mut other = HhtIntegrator::new(&mut system, settings, 0.0, &other_q0, &v0)
        .expect("start")
        .trajectory();
    for _ in 0..100 {
        shared.step(&mut system).expect("step");
    }
    shared.swap_trajectory(&mut other).expect("same dimensions");
    for _ in 0..37 {
        shared.step(&mut system).expect("step");
    }
    shared.swap_trajectory(&mut other).expect("same dimensions");
    for _ in 0..100 {
        shared.step(&mut system).expect("step");
    }
    // Vacuous unless some steps reused the matrix.
    assert!(alone.stats().factorisations < 200);
    assert_eq!(shared.state(), alone.state());
    assert_eq!(shared.stats().factorisations, alone.stats().factorisations);
}

/// A shipped robot in its own scene's environment, for runs of the integrator alone.
fn shipped_scene(dir: &str) -> (crate::simulate::RobotSystem, crate::scene::Scene) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(dir);
    let model = crate::model::Model::from_urdf_file(
        &root.join(format!("{dir}.urdf")),
        crate::model::LoadOptions::default(),
    )
    .expect("robot loads");
    let (file, _) = crate::scene::read_sidecar(&root.join(format!("{dir}.uncertainty.toml")))
        .expect("sidecar reads");
    let scene =
        crate::scene::Scene::resolve(&file, &model, dir, crate::scene::SceneOverrides::default())
            .expect("scene resolves");
    (
        crate::simulate::RobotSystem::new(model, scene.environment(), &scene),
        scene,
    )
}

/// How much tighter the reference runs of the first-correction test converge.
const TIGHT_NEWTON_FACTOR: f64 = 1e-3;

/// A step accepted after its first correction by the last step's contraction (docs/step-control.md
/// §2, "Accepting the first correction") is within the Newton tolerance: over 1 s of the shipped
/// ur5, double pendulum, four-bar and slider-crank scenes, the positions stay within one step's
/// position tolerance (`reltol · max|q| + abstol_position`) of a run converged 1000× tighter, while
/// the acceptance saves iterations. (Since the predictor chooses its order per entry, the double
/// pendulum's first correction is within tolerance at every step and the rule is never asked; the
/// loop scenes and the ur5 still use it.)
#[test]
fn first_corrections_accepted_by_the_carried_contraction_stay_within_the_tolerance() {
    let mut scenes_using_the_rule = 0;
    for dir in ["ur5", "double_pendulum", "four_bar", "slider_crank"] {
        let (mut system, scene) = shipped_scene(dir);
        let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
        let settings = crate::simulate::hht_settings(&scene);
        let tight = HhtSettings {
            reltol: settings.reltol * TIGHT_NEWTON_FACTOR,
            abstol_position: settings.abstol_position * TIGHT_NEWTON_FACTOR,
            abstol_multiplier: settings.abstol_multiplier * TIGHT_NEWTON_FACTOR,
            accept_by_carried_contraction: false,
            ..settings
        };
        let mut run = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
        let mut reference = HhtIntegrator::new(&mut system, tight, 0.0, &q0, &v0).expect("start");
        let (mut max_difference, mut max_q): (f64, f64) = (0.0, 0.0);
        for _ in 0..1000 {
            run.step(&mut system).expect("step");
            reference.step(&mut system).expect("step");
            max_difference = max_difference.max((&run.state().q - &reference.state().q).amax());
            max_q = max_q.max(reference.state().q.amax());
        }
        let one_step_tolerance = settings.reltol * max_q + settings.abstol_position;
        let stats = run.stats();
        println!(
            "{dir}: {} Newton iterations in 1000 steps, {} accepted by the carried contraction; max |Δq| {max_difference:.2e} against one step's tolerance {one_step_tolerance:.2e}",
            stats.newton_iterations, stats.carried_rate_acceptances
        );
        if stats.carried_rate_acceptances > 0 {
            scenes_using_the_rule += 1;
        }
        // The reference must not depend on the rule under test.
        assert_eq!(
            reference.stats().carried_rate_acceptances,
            0,
            "{dir}: the tight reference accepted a first correction by the carried contraction"
        );
        assert!(
            max_difference <= one_step_tolerance,
            "{dir}: {max_difference:e} > {one_step_tolerance:e}"
        );
    }
    assert!(
        scenes_using_the_rule >= 3,
        "only {scenes_using_the_rule} of the four scenes accepted a first correction by the carried contraction"
    );
}
