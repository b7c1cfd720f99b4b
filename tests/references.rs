//! The large-d references of `ribbon compare` (`--reference vertex`, `--reference monte-carlo:N`):
//! made of true-model runs only, so they are inner bounds that ribbon's envelopes must contain up to
//! their own error.

mod common;

use ribbon::analysis::{Method, Study, StudyOptions, VertexReferenceOptions};
use ribbon::uq::Truncation;
use std::process::Command;
use std::sync::atomic::AtomicBool;

/// Rounding slack when comparing envelopes of runs made by the same code (m or rad).
const ROUNDING: f64 = 1e-12;

#[test]
fn the_vertex_reference_is_inside_the_legendre_envelope_and_contains_the_nominal_run() {
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        "robots/ur5/ur5.uncertainty.toml",
        0.5,
    );
    let (model, scene, space) = (setup.model, setup.scene, setup.space);
    let study = Study {
        model,
        environment: scene.environment(),
        scene: &scene,
        space: &space,
        options: StudyOptions {
            method: Method::LegendreScan,
            order: 4,
            truncation: Truncation::Tensor,
            grid: 21,
            scan_grid: None,
            samples: 0,
            seed: 0,
            threads: 0,
            keep_going: false,
            check_runs: None,
            elements: ribbon::analysis::ElementsOptions::default(),
            design: ribbon::analysis::DesignKind::Tensor,
            max_runs: ribbon::analysis::DEFAULT_MAX_RUNS,
        },
    };
    let interrupt = AtomicBool::new(false);
    let vertex = study
        .vertex_reference(VertexReferenceOptions::default(), &interrupt, &mut |_| {})
        .unwrap();
    let legendre = study.run(&interrupt, &mut |_| {}, &mut |_| Ok(())).unwrap();
    let d = space.len();
    // 2d + 1 gradient runs, the nominal run, at most 2^d vertices, then flips.
    assert!(vertex.runs >= 2 * d + 2, "{}", vertex.runs);
    let (v, l) = (&vertex.envelope, &legendre.envelope);
    assert_eq!(v.times, l.times);
    let errors = l.error.as_ref().expect("legendre-scan has error estimates");
    let mut strictly_wider = 0;
    for (o, output_errors) in errors.iter().enumerate() {
        for (k, error) in output_errors.iter().enumerate() {
            let slack = error + ROUNDING;
            assert!(
                v.lower[o][k] >= l.lower[o][k] - slack && v.upper[o][k] <= l.upper[o][k] + slack,
                "{} at t = {}: vertex [{}, {}] outside legendre-scan [{}, {}] ± {slack:e}",
                v.outputs[o].name,
                v.times[k],
                v.lower[o][k],
                v.upper[o][k],
                l.lower[o][k],
                l.upper[o][k]
            );
            // The vertex hull contains the nominal run.
            assert!(v.lower[o][k] <= v.nominal[o][k] && v.nominal[o][k] <= v.upper[o][k]);
            if v.upper[o][k] - v.lower[o][k] > ROUNDING {
                strictly_wider += 1;
            }
        }
    }
    assert!(strictly_wider > 0, "the vertex reference has a width");
}

#[test]
fn a_bad_reference_is_refused_naming_the_flag() {
    for (reference, expected) in [
        ("vertx", "'vertx' is not a reference"),
        ("monte-carlo:0", "must be a whole number ≥ 1"),
        ("monte-carlo:many", "must be a whole number ≥ 1"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_ribbon"))
            .args([
                "compare",
                "robots/double_pendulum/double_pendulum.urdf",
                "--reference",
                reference,
            ])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("--reference") && stderr.contains(expected),
            "{stderr}"
        );
    }
}

#[test]
fn a_bad_method_design_token_is_refused_naming_the_flag() {
    for (methods, expected) in [
        ("auto:adaptive", "auto chooses its own"),
        ("monte-carlo:sparse", "only a surrogate method"),
        ("legendre-scan:adaptiv", "'adaptiv' is not a design"),
        ("legendr-scan", "unknown method 'legendr-scan'"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_ribbon"))
            .args([
                "compare",
                "robots/double_pendulum/double_pendulum.urdf",
                "--methods",
                methods,
            ])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("--methods") && stderr.contains(expected),
            "{stderr}"
        );
    }
}

#[test]
fn compare_refuses_a_run_budget_that_cannot_hold_a_design() {
    let out = Command::new(env!("CARGO_BIN_EXE_ribbon"))
        .args([
            "compare",
            "robots/double_pendulum/double_pendulum.urdf",
            "--max-runs",
            "1",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--max-runs") && stderr.contains("give at least 2"),
        "{stderr}"
    );
}
