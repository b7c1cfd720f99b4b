//! Stiff springs: the diagonal Newton terms a system reports make modified Newton converge where
//! it otherwise fails or needs more iterations.
//!
//! Does not: test convergence order (`order.rs`).

use super::*;

// ---------------------------------------------------------------------------------------------
// Stiff spring: the diagonal Newton terms
// ---------------------------------------------------------------------------------------------

fn stiff() -> Oscillator {
    Oscillator {
        mass_kg: 1e-3,
        stiffness: 1e6,
        damping: 0.0,
    }
}

#[test]
fn stiff_spring_converges_with_diagonal_terms() {
    /// Linear problem + exact diagonal Jacobian: Newton converges in one correction, a second
    /// confirms; allow one more.
    const MAX_ITERATIONS_PER_STEP: usize = 3;
    let mut sys = stiff();
    let hht = simulate(&mut sys, HhtSettings::default(), &[0.1], &[0.0], 1.0);
    let st = hht.stats();
    println!(
        "stiff spring with diagonal terms: {} steps, {} iterations (max {} per step), {} factorisations, {} refreshes, q(1) = {:.3e}",
        st.steps, st.newton_iterations, st.max_iterations_in_a_step, st.factorisations, st.refreshes, hht.state().q[0]
    );
    assert!(st.max_iterations_in_a_step <= MAX_ITERATIONS_PER_STEP);
    assert_eq!(st.refreshes, 0);
    assert!(hht.state().q[0].abs() <= 0.1, "stable");
}

#[test]
fn stiff_spring_fails_without_diagonal_terms() {
    let mut sys = stiff();
    // The fixed step reports the failure at once.
    let settings = HhtSettings {
        newton_diagonal_terms: false,
        ..HhtSettings::default()
    };
    let mut hht =
        HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    let err = hht.step(&mut sys).unwrap_err();
    println!("stiff spring without diagonal terms: {err}");
    match err {
        IntegrateError::NewtonNotConverged { step, t, worst, .. } => {
            assert_eq!(step, 1);
            assert!((t - 1e-3).abs() < 1e-15);
            assert!(matches!(worst, WorstEntry::Coordinate { index: 0, .. }));
        }
        other => panic!("expected NewtonNotConverged, got {other}"),
    }
    assert_eq!(hht.state().step, 0, "state left at t_n on failure");

    // The adaptive step retries a failed sub-step with half its size: the same step succeeds as
    // sub-steps, and says so.
    let retry = HhtSettings {
        newton_diagonal_terms: false,
        newton_matrix: crate::integrate::NewtonMatrix::Diagonal,
        step_control: crate::integrate::StepControl::Adaptive,
        ..HhtSettings::default()
    };
    let mut sys = stiff();
    let mut hht = HhtIntegrator::new(&mut sys, retry, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    hht.step(&mut sys).expect("halving rescues the step");
    let st = hht.stats();
    println!(
        "without diagonal terms, halving: {} failed attempts, {} sub-steps, smallest {:.3e} s",
        st.step_failures, st.substeps, st.smallest_step_s
    );
    assert!(st.step_failures > 0 && st.substeps > 1);
    assert!(!hht.control().last_step_plain);
    assert!((hht.state().t - 1e-3).abs() < 1e-15, "ends on the grid");
}

/// A moderately stiff spring that plain modified Newton still handles, but at a cost: count the
/// iterations with and without the diagonal terms.
#[test]
fn moderate_spring_needs_more_iterations_without_diagonal_terms() {
    let moderate = || Oscillator {
        mass_kg: 1e-3,
        stiffness: 1e3,
        damping: 0.05,
    };
    let mut counts = Vec::new();
    for diagonal in [true, false] {
        let settings = HhtSettings {
            newton_diagonal_terms: diagonal,
            max_newton_iterations: 50,
            ..HhtSettings::default()
        };
        let mut sys = moderate();
        let hht = simulate(&mut sys, settings, &[0.1], &[0.0], 0.5);
        let st = hht.stats();
        println!(
            "spring k = 1e3 on 1e-3 kg, diagonal terms {diagonal}: {:.2} iterations/step (max {})",
            st.newton_iterations as f64 / st.steps as f64,
            st.max_iterations_in_a_step
        );
        counts.push(st.newton_iterations);
    }
    assert!(counts[1] >= 2 * counts[0], "{counts:?}");
}
