//! Failures named with time and step (NaN forces, dimension mismatches), the manifold update of a
//! rotor's unit complex number, restarts, allocation-free steps (through `alloc_counter`), and the
//! bound on sub-step attempts per grid step.
//!
//! Does not: install the counting allocator (`alloc_counter.rs`).

use super::*;

// ---------------------------------------------------------------------------------------------
// Failures, manifold, allocation, restart
// ---------------------------------------------------------------------------------------------

#[test]
fn nan_forces_are_reported_with_time_and_step() {
    let mut sys = Scalar {
        nan_after_s: 0.0505,
        ..Scalar::new()
    };
    let mut hht = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[SCALAR_Q0]),
        &dvec(&[SCALAR_V0]),
    )
    .unwrap();
    let err = (0..100)
        .find_map(|_| hht.step(&mut sys).err())
        .expect("fails");
    println!("{err}");
    match err {
        IntegrateError::NonFinite {
            step,
            quantity,
            index,
            ..
        } => {
            assert_eq!((step, quantity, index), (51, "forces", 0));
        }
        other => panic!("expected NonFinite, got {other}"),
    }
}

#[test]
fn manifold_update_matches_vector_update() {
    /// Same arithmetic up to the rotation's rounding (and atan2): a few rounding units per step.
    const SAME_TRAJECTORY: f64 = 1e-11;
    let theta0: f64 = 0.7;
    let settings = HhtSettings::default();
    let mut rotor = Rotor;
    let mut angle = AngleRotor;
    let a = simulate(
        &mut rotor,
        settings,
        &[theta0.cos(), theta0.sin()],
        &[0.2],
        2.0,
    );
    let b = simulate(&mut angle, settings, &[theta0], &[0.2], 2.0);
    let theta_a = a.state().q[1].atan2(a.state().q[0]);
    let d = (theta_a - b.state().q[0]).abs();
    println!(
        "manifold vs vector update after 2 s: |Δθ| = {d:.2e}, |q| − 1 = {:.1e}",
        a.state().q.norm() - 1.0
    );
    assert!(d < SAME_TRAJECTORY);
    assert!((a.state().v[0] - b.state().v[0]).abs() < SAME_TRAJECTORY);
}

#[test]
fn restart_reuses_workspace_and_reproduces_trajectory() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings::default();
    let mut hht = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    for _ in 0..300 {
        hht.step(&mut sys).unwrap();
    }
    let first = hht.state().clone();
    hht.restart(&mut sys, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    assert_eq!(hht.stats().steps, 0);
    for _ in 0..300 {
        hht.step(&mut sys).unwrap();
    }
    assert_eq!(&first, hht.state(), "bit-identical (determinism)");
}

#[test]
fn dimension_mismatch_is_an_error() {
    let mut sys = Scalar::new();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[1.0, 2.0]),
        &dvec(&[0.0]),
    )
    .unwrap_err();
    assert!(
        matches!(err, IntegrateError::DimensionMismatch { what: "q0", .. }),
        "{err}"
    );
    let mut hht = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[1.0]),
        &dvec(&[0.0]),
    )
    .unwrap();
    let mut other = CartesianPendulum::new(PendulumVariant::Plain);
    let err = hht.step(&mut other).unwrap_err();
    assert!(
        matches!(err, IntegrateError::DimensionMismatch { .. }),
        "{err}"
    );
}

#[test]
fn steps_allocate_nothing() {
    let mut scalar = Scalar::new();
    let mut hht = HhtIntegrator::new(
        &mut scalar,
        HhtSettings::default(),
        0.0,
        &dvec(&[SCALAR_Q0]),
        &dvec(&[SCALAR_V0]),
    )
    .unwrap();
    let before = alloc_counter::allocations();
    for _ in 0..200 {
        hht.step(&mut scalar).unwrap();
    }
    let tree = alloc_counter::allocations() - before;

    let mut pendulum = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let mut hht = HhtIntegrator::new(
        &mut pendulum,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap();
    let before = alloc_counter::allocations();
    for _ in 0..200 {
        hht.step(&mut pendulum).unwrap();
    }
    let constrained = alloc_counter::allocations() - before;
    println!("allocations in 200 steps: tree {tree}, constrained with projection {constrained}");
    assert_eq!((tree, constrained), (0, 0));
}

/// A tolerance no step can meet makes the adaptive step sub-step down to its floor; the attempts
/// within one grid step are capped, and the error says what happened.
#[test]
fn sub_step_attempts_per_grid_step_are_bounded() {
    let mut sys = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0,
        damping: 0.0,
    };
    let settings = HhtSettings {
        step_control: crate::integrate::StepControl::Adaptive,
        tolerance: 1e-300,
        ..HhtSettings::default()
    };
    let mut hht =
        HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&[1.0]), &dvec(&[0.0])).unwrap();
    let err = hht.step(&mut sys).unwrap_err();
    println!("{err}");
    assert!(
        matches!(err, IntegrateError::TooManySubsteps { attempts, .. } if attempts == crate::integrate::MAX_ATTEMPTS_PER_STEP)
    );
    assert!(err
        .to_string()
        .contains("smaller step or a looser tolerance"));
}

/// `q ⊕ δ = q + δ` needs `nq == nv`: a system with more position coordinates than velocities
/// and no [`PositionGroup`] is refused before the run, naming the mismatch.
#[test]
fn a_system_with_nq_above_nv_needs_a_position_group() {
    /// The [`Rotor`] of `tests.rs` (a unit complex number, nq = 2, nv = 1) without its group.
    struct RotorWithoutGroup;
    impl DaeSystem for RotorWithoutGroup {
        fn nq(&self) -> usize {
            2
        }
        fn nv(&self) -> usize {
            1
        }
        fn mass_matrix(
            &mut self,
            _t: f64,
            _q: &DVector<f64>,
            out: &mut DMatrix<f64>,
        ) -> Result<(), SystemError> {
            out[(0, 0)] = 1.0;
            Ok(())
        }
        fn forces(
            &mut self,
            _t: f64,
            q: &DVector<f64>,
            _v: &DVector<f64>,
            out: &mut DVector<f64>,
        ) -> Result<(), SystemError> {
            out[0] = -3.0 * q[1];
            Ok(())
        }
    }
    let (q0, v0) = (dvec(&[1.0, 0.0]), dvec(&[0.2]));
    let err = HhtIntegrator::new(
        &mut RotorWithoutGroup,
        HhtSettings::default(),
        0.0,
        &q0,
        &v0,
    )
    .unwrap_err();
    match err {
        IntegrateError::DimensionMismatch {
            what,
            expected: 1,
            got: 2,
        } => assert!(what.contains("without a position group"), "{what}"),
        other => panic!("expected DimensionMismatch of nq, got {other}"),
    }
    // With its group the same system runs.
    assert!(HhtIntegrator::new(&mut Rotor, HhtSettings::default(), 0.0, &q0, &v0).is_ok());
}
