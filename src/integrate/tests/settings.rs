//! The settings' validation: α = 0 refused with constraint rows, bad settings as errors.
//!
//! Does not: step a system beyond what a refusal needs.

use super::*;

// ---------------------------------------------------------------------------------------------
// Settings
// ---------------------------------------------------------------------------------------------

#[test]
fn alpha_zero_with_constraints_is_refused() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings {
        alpha: 0.0,
        ..HhtSettings::default()
    };
    let err = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap_err();
    println!("{err}");
    assert!(matches!(
        err,
        IntegrateError::AlphaZeroWithConstraints { n_constraints: 1 }
    ));
    // Without constraints α = 0 is fine.
    assert!(settings.validate(0).is_ok());
}

#[test]
fn bad_settings_are_errors() {
    let base = HhtSettings::default();
    let bad = [
        HhtSettings { alpha: 0.1, ..base },
        HhtSettings {
            alpha: -0.34,
            ..base
        },
        HhtSettings {
            alpha: f64::NAN,
            ..base
        },
        HhtSettings {
            step_s: 0.0,
            ..base
        },
        HhtSettings {
            step_s: -1e-3,
            ..base
        },
        HhtSettings {
            step_s: f64::INFINITY,
            ..base
        },
        HhtSettings {
            step_s: f64::NAN,
            ..base
        },
        HhtSettings {
            reltol: 0.0,
            ..base
        },
        HhtSettings {
            abstol_position: -1.0,
            ..base
        },
        HhtSettings {
            abstol_multiplier: f64::NAN,
            ..base
        },
        HhtSettings {
            max_newton_iterations: 0,
            ..base
        },
    ];
    for s in bad {
        let err = s.validate(0).unwrap_err();
        println!("{err}");
    }
    assert!(HhtSettings {
        alpha: ALPHA_MIN,
        ..base
    }
    .validate(3)
    .is_ok());
    let c = base.validate(0).unwrap();
    assert!((c.gamma - 0.6).abs() < 1e-15 && (c.beta - 0.3025).abs() < 1e-15);
}
