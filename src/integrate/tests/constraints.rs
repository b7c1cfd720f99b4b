//! Constrained systems: the Cartesian pendulum's second order with a closed constraint, the
//! projection kept off the recursion, the prescribed motion's known multiplier, the scaled
//! iteration matrix's conditioning, and the consistent start with its errors.
//!
//! Does not: test the settings' validation (`settings.rs`) or failures (`failures.rs`).

use super::*;

// ---------------------------------------------------------------------------------------------
// Constraints: Cartesian pendulum, prescribed motion
// ---------------------------------------------------------------------------------------------

/// Errors at `duration` of one Cartesian-pendulum run: (position, velocity, λ) against the RK4
/// reference in θ, plus the run's statistics.
fn pendulum_errors(
    h: f64,
    projection: bool,
    feedback: bool,
    duration: f64,
) -> ([f64; 3], HhtStats) {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let [theta, theta_dot] = sys.reference(PENDULUM_THETA0, duration);
    let l = sys.length_m;
    let (x, y) = (l * theta.sin(), -l * theta.cos());
    let (vx, vy) = (l * theta.cos() * theta_dot, l * theta.sin() * theta_dot);
    let lambda = sys.lambda(theta, theta_dot);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings {
        velocity_projection: projection,
        ..tight_settings(-0.1, h)
    };
    let mut hht = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    hht.set_projection_feedback(feedback);
    for _ in 0..n_steps(duration, h) {
        hht.step(&mut sys).unwrap();
    }
    let s = hht.state();
    let errors = [
        ((s.q[0] - x).powi(2) + (s.q[1] - y).powi(2)).sqrt(),
        ((s.v[0] - vx).powi(2) + (s.v[1] - vy).powi(2)).sqrt(),
        (s.lambda[0] - lambda).abs(),
    ];
    (errors, *hht.stats())
}

#[test]
fn cartesian_pendulum_second_order_with_closed_constraint() {
    for projection in [true, false] {
        let mut errors = [Vec::new(), Vec::new(), Vec::new()];
        for h in ORDER_STEPS {
            let (e, st) = pendulum_errors(h, projection, false, 1.0);
            for k in 0..3 {
                errors[k].push(e[k]);
            }
            println!(
                "pendulum projection={projection} h = {h}: max|Φ| = {:.2e}, max|Φ_q q̇| = {:.2e} (unprojected {:.2e}), it/step {:.2}, max it {}, rounding-limited steps {}",
                st.max_constraint_violation,
                st.max_velocity_violation,
                st.max_velocity_violation_unprojected,
                st.newton_iterations as f64 / st.steps as f64,
                st.max_iterations_in_a_step,
                st.rounding_limited_steps
            );
            assert!(st.max_constraint_violation <= MAX_CONSTRAINT_VIOLATION);
            if projection {
                assert!(st.max_velocity_violation <= MAX_PROJECTED_VELOCITY_VIOLATION);
            }
        }
        for (name, e) in ["position", "velocity", "λ"].iter().zip(errors.iter()) {
            let r = ratios(e);
            let e_sci = sci(e);
            println!(
                "pendulum projection={projection}: {name} errors at 1 s {e_sci}, ratios {r:.3?}"
            );
            for ratio in r {
                assert!(
                    ratio >= MIN_SECOND_ORDER_RATIO,
                    "projection={projection} {name}: ratio {ratio}"
                );
            }
        }
    }
}

/// Regression pin: feeding the projected velocity back into the generalized-α recursion (the
/// textbook post-step projection) keeps positions second order but makes λ first order — the reason
/// the integrator projects only the reported velocity.
#[test]
fn projection_feedback_makes_multipliers_first_order() {
    let mut pos = Vec::new();
    let mut lam = Vec::new();
    for h in ORDER_STEPS {
        let (e, _) = pendulum_errors(h, true, true, 1.0);
        pos.push(e[0]);
        lam.push(e[2]);
    }
    let (rp, rl) = (ratios(&pos), ratios(&lam));
    let (pos_sci, lam_sci) = (sci(&pos), sci(&lam));
    println!("projection fed back: position errors {pos_sci} ratios {rp:.3?}; λ errors {lam_sci} ratios {rl:.3?}");
    assert!(rp.iter().all(|r| *r >= MIN_SECOND_ORDER_RATIO));
    assert!(rl.iter().all(|r| *r < MAX_FIRST_ORDER_RATIO));
}

#[test]
fn prescribed_motion_gives_known_multiplier() {
    let duration = 2.0;
    let make = || Prescribed {
        mass_kg: 2.0,
        stiffness: 5.0,
        damping: 0.3,
    };
    let lambda_scale = (0..=200)
        .map(|i| make().exact_lambda(i as f64 * 0.005).abs())
        .fold(0.0, f64::max);
    let qdd_scale = Prescribed::OMEGA * Prescribed::OMEGA;
    let mut errors_qdd = Vec::new();
    let mut errors_lambda = Vec::new();
    for h in [1e-3, 5e-4, 2.5e-4] {
        let mut sys = make();
        // Deliberately inconsistent start: the projection must put q, q̇ on the drive.
        let mut hht = HhtIntegrator::new(
            &mut sys,
            tight_settings(-0.2, h),
            0.0,
            &dvec(&[0.3]),
            &dvec(&[0.0]),
        )
        .unwrap();
        // Max relative errors over the second second (after the O(h) start transient of a_0 = q̈_0).
        let (mut eq, mut el): (f64, f64) = (0.0, 0.0);
        for _ in 0..n_steps(duration, h) {
            hht.step(&mut sys).unwrap();
            let s = hht.state();
            if s.t >= 1.0 {
                eq = eq.max((s.qdd[0] - Prescribed::exact_qdd(s.t)).abs() / qdd_scale);
                el = el.max((s.lambda[0] - sys.exact_lambda(s.t)).abs() / lambda_scale);
            }
        }
        println!(
            "prescribed α = −0.2, h = {h}: max over [1, 2] s of relative q̈ error {eq:.3e}, relative λ error {el:.3e}, max|Φ| {:.1e}, start iterations {}",
            hht.stats().max_constraint_violation,
            hht.stats().start_projection_iterations
        );
        errors_qdd.push(eq);
        errors_lambda.push(el);
    }
    let (rq, rl) = (ratios(&errors_qdd), ratios(&errors_lambda));
    println!("prescribed: q̈ ratios {rq:.3?}, λ ratios {rl:.3?}");
    for ratio in rq.iter().chain(rl.iter()) {
        assert!(*ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

/// Default settings on a constrained system across step sizes: no Newton failure down to h = 1e-5,
/// where `Δλ`'s rounding floor (~eps/(β'h²)) approaches the multiplier tolerance.
#[test]
fn constrained_defaults_converge_from_large_to_tiny_steps() {
    for h in [1e-2, 1e-3, 1e-4, 1e-5] {
        let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
        let (q0, v0) = pendulum_start();
        let settings = HhtSettings {
            step_s: h,
            ..HhtSettings::default()
        };
        let hht = simulate(&mut sys, settings, &q0, &v0, 2000.0 * h);
        let st = hht.stats();
        println!(
            "pendulum defaults h = {h:.0e}: 2000 steps, {:.2} it/step (max {}), refreshes {}, rounding-limited steps {}, max|Φ| {:.1e}",
            st.newton_iterations as f64 / st.steps as f64,
            st.max_iterations_in_a_step,
            st.refreshes,
            st.rounding_limited_steps,
            st.max_constraint_violation
        );
        assert!(st.max_constraint_violation <= MAX_CONSTRAINT_VIOLATION);
    }
}

// ---------------------------------------------------------------------------------------------
// Conditioning of the iteration matrix
// ---------------------------------------------------------------------------------------------

fn condition_number(a: &DMatrix<f64>) -> f64 {
    let sv = a.clone().singular_values();
    sv.max() / sv.min()
}

#[test]
fn scaled_iteration_matrix_stays_well_conditioned() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, _) = pendulum_start();
    let q = dvec(&q0);
    let v = dvec(&[0.5 * PENDULUM_THETA0.cos(), 0.5 * PENDULUM_THETA0.sin()]);
    let mut previous_unscaled = None;
    for exponent in 2..=6 {
        let h = 10f64.powi(-exponent);
        let settings = HhtSettings {
            step_s: h,
            ..HhtSettings::default()
        };
        let scaled = condition_number(
            &iteration_matrix(
                &mut sys,
                &settings,
                0.0,
                &q,
                &v,
                ConstraintRowScaling::Scaled,
            )
            .unwrap(),
        );
        let unscaled = condition_number(
            &iteration_matrix(
                &mut sys,
                &settings,
                0.0,
                &q,
                &v,
                ConstraintRowScaling::Unscaled,
            )
            .unwrap(),
        );
        println!("h = {h:.0e}: cond scaled {scaled:.3e}, unscaled {unscaled:.3e}");
        assert!(scaled < MAX_SCALED_CONDITION);
        if let Some(prev) = previous_unscaled {
            let growth = unscaled / prev;
            assert!(
                (UNSCALED_DECADE_GROWTH.0..UNSCALED_DECADE_GROWTH.1).contains(&growth),
                "growth per decade {growth}"
            );
        }
        previous_unscaled = Some(unscaled);
    }
}

// ---------------------------------------------------------------------------------------------
// Consistent start
// ---------------------------------------------------------------------------------------------

#[test]
fn consistent_start_projects_positions_velocities_and_solves_multipliers() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    // Off the circle, with a velocity that has a radial component.
    let q0 = dvec(&[0.9, -0.6]);
    let v0 = dvec(&[0.3, 0.4]);
    let start = consistent_start(&mut sys, 0.0, &q0, &v0).unwrap();
    let r = (start.q[0].powi(2) + start.q[1].powi(2)).sqrt();
    let radial_v = (start.q[0] * start.v[0] + start.q[1] * start.v[1]) / r;
    // Exact multiplier at the projected state: λ = m (|v|² − g y)/(2L²).
    let v2 = start.v.norm_squared();
    let lambda = (v2 - 9.81 * start.q[1]) / 2.0;
    println!(
        "consistent start: {} Gauss–Newton iterations, |Φ| {:.1e} → {:.1e}, radial v {radial_v:.1e}, λ {:.12} vs {lambda:.12}",
        start.projection_iterations, start.initial_violation, start.final_violation, start.lambda[0]
    );
    assert!(start.final_violation <= START_CONSTRAINT_TOL);
    assert!(radial_v.abs() < 1e-14);
    assert!((start.lambda[0] - lambda).abs() < 1e-12);
}

#[test]
fn redundant_rows_are_reported_not_solved() {
    let mut sys = CartesianPendulum::new(PendulumVariant::DuplicatedRow);
    let (q0, v0) = pendulum_start();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap_err();
    println!("{err}");
    assert!(
        matches!(err, IntegrateError::RedundantConstraints { .. }),
        "{err}"
    );
}

#[test]
fn impossible_closure_is_reported() {
    let mut sys = CartesianPendulum::new(PendulumVariant::CannotClose);
    let (q0, v0) = pendulum_start();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap_err();
    println!("{err}");
    assert!(matches!(err, IntegrateError::CannotClose { .. }), "{err}");
}
