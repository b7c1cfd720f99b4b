//! The integrator's convergence order (scalar system with configuration-dependent mass, against
//! RK4; the Negrut form as the discriminating counter-example), the two residual paths, and the
//! energy behaviour on the linear oscillator and the scalar system.
//!
//! Does not: test constrained systems (`constraints.rs`) or stiff springs (`stiffness.rs`).

use super::*;

// ---------------------------------------------------------------------------------------------
// Convergence order
// ---------------------------------------------------------------------------------------------

#[test]
fn scalar_system_is_second_order_in_position() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    for alpha in [-0.1, -0.3] {
        let mut errors = Vec::new();
        let mut iterations = Vec::new();
        for h in ORDER_STEPS {
            let mut sys = Scalar::new();
            let hht = simulate(
                &mut sys,
                tight_settings(alpha, h),
                &[SCALAR_Q0],
                &[SCALAR_V0],
                1.0,
            );
            errors.push((hht.state().q[0] - reference).abs());
            iterations.push(hht.stats().newton_iterations as f64 / hht.stats().steps as f64);
        }
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!(
            "scalar α = {alpha}: |q(1) − q_ref| = {errors_sci}, ratios {r:.3?}, Newton it/step {iterations:.2?}"
        );
        for ratio in r {
            assert!(
                ratio >= MIN_SECOND_ORDER_RATIO,
                "α = {alpha}: ratio {ratio}"
            );
        }
    }
}

/// One step of the form printed by Negrut et al. (Chrono's `ChTimestepperHHT`) on the scalar system:
/// `M(q₁) q̈₁/(1+α) − Q₁ + α/(1+α) Q₀ = 0` with plain Newmark updates in `q̈` (`γ = ½ − α`,
/// `β = (1−α)²/4`). Scalar secant-Newton to rounding level.
fn negrut_scalar(alpha: f64, h: f64, duration: f64) -> f64 {
    let gamma = 0.5 - alpha;
    let beta = 0.25 * (1.0 - alpha) * (1.0 - alpha);
    let (mut q, mut v) = (SCALAR_Q0, SCALAR_V0);
    let mut qdd = Scalar::force(q, v) / Scalar::mass(q);
    for _ in 0..n_steps(duration, h) {
        let q0_force = Scalar::force(q, v);
        let kin = |a1: f64| {
            let q1 = q + h * v + h * h * ((0.5 - beta) * qdd + beta * a1);
            let v1 = v + h * ((1.0 - gamma) * qdd + gamma * a1);
            (q1, v1)
        };
        let residual = |a1: f64| {
            let (q1, v1) = kin(a1);
            Scalar::mass(q1) * a1 / (1.0 + alpha) - Scalar::force(q1, v1)
                + alpha / (1.0 + alpha) * q0_force
        };
        let mut a1 = qdd;
        for _ in 0..50 {
            let r = residual(a1);
            let d = 1e-7 * (1.0 + a1.abs());
            let slope = (residual(a1 + d) - r) / d;
            let delta = -r / slope;
            a1 += delta;
            if delta.abs() < 1e-15 * (1.0 + a1.abs()) {
                break;
            }
        }
        let (q1, v1) = kin(a1);
        q = q1;
        v = v1;
        qdd = a1;
    }
    q
}

/// The order test above discriminates: the Negrut/Chrono form (first order when M depends on q)
/// measures a ratio ≈ 2 on the same system, steps and reference.
#[test]
fn negrut_form_is_first_order_on_the_scalar_system() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    for alpha in [-0.1, -0.3] {
        let errors: Vec<f64> = ORDER_STEPS
            .iter()
            .map(|&h| (negrut_scalar(alpha, h, 1.0) - reference).abs())
            .collect();
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!("Negrut form α = {alpha}: errors {errors_sci}, ratios {r:.3?}");
        for ratio in r {
            assert!(ratio < MAX_FIRST_ORDER_RATIO, "α = {alpha}: ratio {ratio}");
        }
    }
}

/// The residual through `dynamics_residual` (inverse dynamics) and through `mass_matrix` + `forces`
/// give the same trajectory up to rounding.
#[test]
fn dynamics_residual_path_matches_mass_matrix_path() {
    /// Different summation order only: a few rounding units after 1000 steps.
    const SAME_TRAJECTORY: f64 = 1e-12;
    let settings = HhtSettings::default();
    let mut plain = Scalar::new();
    let mut rnea = Scalar {
        residual: true,
        ..Scalar::new()
    };
    let a = simulate(&mut plain, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
    let b = simulate(&mut rnea, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
    let dq = (a.state().q[0] - b.state().q[0]).abs();
    println!(
        "residual paths: |Δq| = {dq:.2e}, iterations {} vs {}",
        a.stats().newton_iterations,
        b.stats().newton_iterations
    );
    assert!(dq < SAME_TRAJECTORY);
}

/// Default settings (not the tight ones) are accurate enough for second order at 1 ms.
#[test]
fn default_tolerances_keep_second_order() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    let errors: Vec<f64> = ORDER_STEPS
        .iter()
        .map(|&h| {
            let mut sys = Scalar::new();
            let settings = HhtSettings {
                step_s: h,
                ..HhtSettings::default()
            };
            let hht = simulate(&mut sys, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
            (hht.state().q[0] - reference).abs()
        })
        .collect();
    let r = ratios(&errors);
    let errors_sci = sci(&errors);
    println!("scalar, default tolerances: errors {errors_sci}, ratios {r:.3?}");
    for ratio in r {
        assert!(ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

// ---------------------------------------------------------------------------------------------
// Linear oscillator and energy
// ---------------------------------------------------------------------------------------------

#[test]
fn damped_oscillator_matches_closed_form_at_second_order() {
    let osc = || Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI, // 1 Hz
        damping: 0.5,
    };
    let (q0, v0, duration) = (0.1, 0.3, 2.0);
    let exact = osc().exact(q0, v0, duration);
    for alpha in [-0.1, -0.3] {
        let errors: Vec<f64> = ORDER_STEPS
            .iter()
            .map(|&h| {
                let mut sys = osc();
                let hht = simulate(&mut sys, tight_settings(alpha, h), &[q0], &[v0], duration);
                (hht.state().q[0] - exact).abs()
            })
            .collect();
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!("damped oscillator α = {alpha}: errors {errors_sci}, ratios {r:.3?}");
        for ratio in r {
            assert!(
                ratio >= MIN_SECOND_ORDER_RATIO,
                "α = {alpha}: ratio {ratio}"
            );
        }
    }
}

/// α = 0 (trapezoidal) on an undamped oscillator: the energy error is O(h²) — on the linear
/// oscillator it is even zero up to rounding (the trapezoidal rule conserves quadratic invariants);
/// on the nonlinear scalar system it is O(h²) and bounded (no drift) over 20 s.
#[test]
fn energy_error_with_alpha_zero_is_second_order() {
    /// Energy error bound for the linear oscillator: rounding and Newton tolerance only.
    const LINEAR_ENERGY_REL: f64 = 1e-9;
    let mut osc = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI,
        damping: 0.0,
    };
    let settings = HhtSettings {
        alpha: 0.0,
        step_s: 1e-2,
        ..tight_settings(0.0, 1e-2)
    };
    let e0 = osc.energy(0.1, 0.0);
    let mut hht =
        HhtIntegrator::new(&mut osc, settings, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..n_steps(20.0, 1e-2) {
        hht.step(&mut osc).unwrap();
        let s = hht.state();
        worst = worst.max((osc.energy(s.q[0], s.v[0]) - e0).abs() / e0);
    }
    println!("linear oscillator, α = 0, h = 1e-2, 20 s: max relative energy error {worst:.2e}");
    assert!(worst < LINEAR_ENERGY_REL);

    let mut errors = Vec::new();
    for h in [1e-2, 5e-3, 2.5e-3] {
        let mut sys = Scalar::new();
        let e0 = Scalar::energy(SCALAR_Q0, SCALAR_V0);
        let mut hht = HhtIntegrator::new(
            &mut sys,
            tight_settings(0.0, h),
            0.0,
            &dvec(&[SCALAR_Q0]),
            &dvec(&[SCALAR_V0]),
        )
        .unwrap();
        let mut worst: f64 = 0.0;
        let mut final_error = 0.0;
        for _ in 0..n_steps(20.0, h) {
            hht.step(&mut sys).unwrap();
            let s = hht.state();
            final_error = Scalar::energy(s.q[0], s.v[0]) - e0;
            worst = worst.max(final_error.abs());
        }
        println!("scalar, α = 0, h = {h}: max |E − E0| over 20 s = {worst:.3e}, at 20 s {final_error:.3e}");
        errors.push(worst);
    }
    let r = ratios(&errors);
    println!("scalar energy error ratios {r:.3?}");
    for ratio in r {
        assert!(ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

/// Largest one-step rise of the oscillator's physical energy, relative to E0, with α = −0.3 and
/// h = T/100: measured 8.7e-6 (the state's energy oscillates about the monotone algorithmic energy
/// by O(h²)); a tenfold margin.
const MAX_STEP_ENERGY_RISE: f64 = 1e-4;

/// With α < 0 the linear oscillator loses energy (numerical damping of high frequencies), and never
/// gains any over the run. The physical energy `½mv² + ½kq²` of the step's state is not the
/// method's (monotone) algorithmic energy: within a period it may rise by a little from one step
/// to the next. How little is asserted: at most [`MAX_STEP_ENERGY_RISE`] of E0 per step.
#[test]
fn negative_alpha_dissipates_on_linear_oscillator() {
    let mut osc = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI,
        damping: 0.0,
    };
    let h = 1e-2;
    let e0 = osc.energy(0.1, 0.0);
    let mut hht = HhtIntegrator::new(
        &mut osc,
        tight_settings(-0.3, h),
        0.0,
        &dvec(&[0.1]),
        &dvec(&[0.0]),
    )
    .unwrap();
    let mut previous = e0;
    let mut max_rise: f64 = 0.0;
    let mut max_energy: f64 = 0.0;
    for _ in 0..n_steps(10.0, h) {
        hht.step(&mut osc).unwrap();
        let s = hht.state();
        let e = osc.energy(s.q[0], s.v[0]);
        max_rise = max_rise.max(e - previous);
        max_energy = max_energy.max(e);
        previous = e;
    }
    println!(
        "linear oscillator, α = −0.3, h = 1e-2: E(10 s)/E0 = {:.6}, max per-step rise {max_rise:.2e}, max E/E0 {:.8}",
        previous / e0,
        max_energy / e0
    );
    assert!(previous < e0);
    assert!(
        max_rise <= MAX_STEP_ENERGY_RISE * e0,
        "per-step rise {max_rise:e} of E0 = {e0:e}"
    );
    // Measured max E/E0 = 0.99999978: the state's energy never exceeds the initial one.
    assert!(max_energy < e0, "max E {max_energy:e} ≥ E0 = {e0:e}");
}
