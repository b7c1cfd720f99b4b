//! ribbon's `crba`, `rnea` and `forward_dynamics` timed exactly as `benches/pinocchio_cpp/timing.cpp`
//! times Pinocchio's kernels in C++: the same state (q_i = 0.3 + 0.1 i, v_i = 0.5 − 0.2 i,
//! a_i = −0.4 + 0.15 i, τ_i = 1.0 − 0.3 i), the minimum over RUNS of the mean of CALLS calls, one JSON
//! line on stdout. `benches/pinocchio_cpp.py` runs the two programs alternately and reports ratios.
//!
//! Also the batched kernels (`ribbon::dynamics::batch`, 4 lanes, the best instruction set the CPU
//! has): `batch_crba` and `batch_rnea` are **µs per sample** — CALLS / BATCH calls of a batch of BATCH
//! samples (masses 1 % apart, states shifted by 0.01 per sample: `support/batch_samples.rs`), the
//! mean time of one call divided by BATCH, minimum over RUNS.
//!
//! Usage: `cargo bench --bench kernel_timing -- URDF [CALLS] [RUNS] [KERNEL] [BATCH]` (BATCH
//! defaults to 32); with KERNEL (`crba`, `rnea`, `forward_dynamics`, `batch_crba`, `batch_rnea`;
//! `all` for every kernel, so that BATCH can follow) only that kernel runs and the others print −1 (for instruction counts: a batched kernel then
//! runs `CALLS / BATCH` calls, rounded down, at least one).

#[path = "support/batch_samples.rs"]
mod batch_samples;

use ribbon::dynamics::batch::{self, BatchData, Isa, LANES};
use ribbon::dynamics::{crba, forward_dynamics, rnea, Data};
use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

/// `offset + step · i` for i = 0 … n−1.
fn ramp(n: usize, offset: f64, step: f64) -> Vec<f64> {
    (0..n).map(|i| offset + step * i as f64).collect()
}

/// The minimum over `runs` of the mean time of `calls` calls of `kernel`, in microseconds.
fn best_mean_us(
    name: &str,
    only: Option<&str>,
    mut kernel: impl FnMut(),
    calls: u64,
    runs: u32,
) -> f64 {
    if only.is_some_and(|only| only != name) {
        return -1.0;
    }
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let start = Instant::now();
        for _ in 0..calls {
            kernel();
        }
        best = best.min(start.elapsed().as_secs_f64() * 1e6 / calls as f64);
    }
    best
}

/// A positional count: `default` when absent; a clear message and exit 2 when not a positive integer.
fn count_argument<T: std::str::FromStr + PartialOrd + From<u8>>(
    text: Option<&String>,
    name: &str,
    default: T,
) -> T {
    let Some(text) = text else {
        return default;
    };
    match text.parse::<T>() {
        Ok(value) if value >= T::from(1) => value,
        _ => {
            eprintln!("kernel_timing: {name} must be a positive integer, got '{text}'");
            std::process::exit(2);
        }
    }
}

fn main() {
    // `cargo bench` passes `--bench`; everything else is ours.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(urdf) = args.first() else {
        eprintln!(
            "usage: cargo bench --bench kernel_timing -- URDF [CALLS] [RUNS] [KERNEL] [BATCH]"
        );
        std::process::exit(2);
    };
    let calls: u64 = count_argument(args.get(1), "CALLS", 200_000);
    let runs: u32 = count_argument(args.get(2), "RUNS", 7);
    let only = args.get(3).map(String::as_str).filter(|k| *k != "all");
    let batch_size: usize = count_argument(args.get(4), "BATCH", 32);
    let model = match Model::from_urdf_file(&PathBuf::from(urdf), LoadOptions::default()) {
        Ok(model) => model,
        Err(error) => {
            eprintln!("kernel_timing: {urdf}: {error}");
            std::process::exit(2);
        }
    };
    let mut data = Data::new(&model);
    let gravity = Environment::default().gravity;
    let q = ramp(model.nq, 0.3, 0.1);
    let v = ramp(model.nv, 0.5, -0.2);
    let a = ramp(model.nv, -0.4, 0.15);
    let tau = ramp(model.nv, 1.0, -0.3);
    let crba_us = best_mean_us(
        "crba",
        only,
        || {
            black_box(crba(&model, &mut data, black_box(&q)));
        },
        calls,
        runs,
    );
    let rnea_us = best_mean_us(
        "rnea",
        only,
        || {
            black_box(rnea(
                &model,
                &gravity,
                &mut data,
                black_box(&q),
                black_box(&v),
                black_box(&a),
            ));
        },
        calls,
        runs,
    );
    let forward_us = best_mean_us(
        "forward_dynamics",
        only,
        || {
            let qdd = forward_dynamics(
                &model,
                &gravity,
                &mut data,
                black_box(&q),
                black_box(&v),
                black_box(&tau),
            )
            .expect("the benchmark state has a positive-definite mass matrix");
            black_box(qdd);
        },
        calls,
        runs,
    );
    let (batch_model, bq, bv, ba) = batch_samples::batch::<LANES>(&model, batch_size);
    let mut batch_data = BatchData::new(&batch_model);
    let batch_calls = (calls / batch_size as u64).max(1);
    let per_sample = |us: f64| if us < 0.0 { us } else { us / batch_size as f64 };
    let batch_crba_us = per_sample(best_mean_us(
        "batch_crba",
        only,
        || {
            batch::crba(&batch_model, &mut batch_data, black_box(&bq));
            black_box(&batch_data.mass_matrix);
        },
        batch_calls,
        runs,
    ));
    let batch_rnea_us = per_sample(best_mean_us(
        "batch_rnea",
        only,
        || {
            batch::rnea(
                &batch_model,
                &mut batch_data,
                black_box(&bq),
                black_box(&bv),
                black_box(&ba),
            );
            black_box(&batch_data.tau);
        },
        batch_calls,
        runs,
    ));
    println!(
        "{{\"nq\": {}, \"nv\": {}, \"calls_per_run\": {calls}, \"runs\": {runs}, \"batch\": {batch_size}, \"batch_calls_per_run\": {batch_calls}, \"lanes\": {LANES}, \"isa\": \"{}\", \"us\": {{\"crba\": {crba_us:.5}, \"rnea\": {rnea_us:.5}, \"forward_dynamics\": {forward_us:.5}, \"batch_crba\": {batch_crba_us:.5}, \"batch_rnea\": {batch_rnea_us:.5}}}}}",
        model.nq,
        model.nv,
        Isa::best().name()
    );
}
