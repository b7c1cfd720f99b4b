//! Criterion benches of the dynamics kernels (CRBA, RNEA, forward dynamics) per call, on our ur5 and on
//! the example-robot-data ur5 and panda when the reference venv exists (`target/reference-venv`,
//! created by `cargo test --release`). Compare with `python benches/pinocchio_timing.py` run in the same
//! session: see README "Speed".

#[path = "support/reference_venv.rs"]
mod reference_venv;

use criterion::{criterion_group, criterion_main, Criterion};
use ribbon::dynamics::{crba, forward_dynamics, rnea, Data};
use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use std::hint::black_box;
use std::path::PathBuf;

fn robots() -> Vec<(String, PathBuf)> {
    reference_venv::benchmark_robots(&PathBuf::from(env!("CARGO_MANIFEST_DIR")))
}

/// A deterministic, non-trivial state: q_i = 0.3 + 0.1 i, v_i = 0.5 − 0.2 i, …
fn state(n: usize, offset: f64, step: f64) -> Vec<f64> {
    (0..n).map(|i| offset + step * i as f64).collect()
}

fn dynamics(c: &mut Criterion) {
    for (name, path) in robots() {
        let model = Model::from_urdf_file(&path, LoadOptions::default()).expect("robot loads");
        let mut data = Data::new(&model);
        let gravity = Environment::default().gravity;
        let q = state(model.nq, 0.3, 0.1);
        let v = state(model.nv, 0.5, -0.2);
        let a = state(model.nv, -0.4, 0.15);
        let tau = state(model.nv, 1.0, -0.3);
        c.bench_function(&format!("crba/{name}"), |b| {
            b.iter(|| {
                crba(&model, &mut data, black_box(&q));
            })
        });
        c.bench_function(&format!("rnea/{name}"), |b| {
            b.iter(|| {
                rnea(
                    &model,
                    &gravity,
                    &mut data,
                    black_box(&q),
                    black_box(&v),
                    black_box(&a),
                );
            })
        });
        c.bench_function(&format!("forward_dynamics/{name}"), |b| {
            b.iter(|| {
                forward_dynamics(
                    &model,
                    &gravity,
                    &mut data,
                    black_box(&q),
                    black_box(&v),
                    black_box(&tau),
                )
                .expect("positive definite");
            })
        });
    }
}

criterion_group!(benches, dynamics);
criterion_main!(benches);
