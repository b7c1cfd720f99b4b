//! Per-sample cost of the batched CRBA and RNEA (`ribbon::dynamics::batch`) against the scalar
//! kernels, in one run: our ur5 and, when the reference venv exists, example-robot-data's ur5 and
//! panda. The samples differ in link masses (1 % apart) and state (`support/batch_samples.rs`).
//!
//! Every reported time is **nanoseconds per sample**: a batched measurement runs the batch kernel
//! `iters` times and reports the elapsed time divided by the batch size (`iter_custom`), so its
//! figure compares directly with `scalar` (one call, one sample). Ids:
//! `batch_kernels/ROBOT/KERNEL/scalar`, `…/b{SIZE}-w{W}-{ISA}` for batch sizes 1, 4, 8, 32 at the
//! default width of 4 lanes with the baseline (SSE2) and AVX2 instruction sets, and sizes 32 at
//! widths 2 and 8 (the SIMD choice, docs/batch.md §3).
//!
//! Run: `cargo bench --bench batch_kernels` (defaults: warm-up 0.5 s, measurement 1.5 s per id;
//! criterion's `--warm-up-time`/`--measurement-time` override them).

#[path = "support/batch_samples.rs"]
mod batch_samples;
#[path = "support/reference_venv.rs"]
mod reference_venv;

use criterion::{criterion_group, criterion_main, Criterion};
use ribbon::dynamics::batch::{self, BatchData, Isa};
use ribbon::dynamics::{crba, rnea, Data};
use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn robots() -> Vec<(String, PathBuf)> {
    reference_venv::benchmark_robots(&PathBuf::from(env!("CARGO_MANIFEST_DIR")))
}

/// Which kernel a measurement runs.
#[derive(Clone, Copy)]
enum Kernel {
    Crba,
    Rnea,
}

impl Kernel {
    fn name(self) -> &'static str {
        match self {
            Kernel::Crba => "crba",
            Kernel::Rnea => "rnea",
        }
    }
}

/// Registers `…/b{size}-w{W}-{isa}`: nanoseconds per sample of one batch call.
fn bench_batch<const W: usize>(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    base: &Model,
    kernel: Kernel,
    size: usize,
    isa: Isa,
) {
    let (mut model, q, v, a) = batch_samples::batch::<W>(base, size);
    model.isa = isa;
    let mut data = BatchData::new(&model);
    let id = format!("b{size}-w{W}-{}", isa.name());
    group.bench_function(id, |b| {
        b.iter_custom(|iters| {
            let start = Instant::now();
            for _ in 0..iters {
                match kernel {
                    Kernel::Crba => batch::crba(&model, &mut data, black_box(&q)),
                    Kernel::Rnea => batch::rnea(
                        &model,
                        &mut data,
                        black_box(&q),
                        black_box(&v),
                        black_box(&a),
                    ),
                }
                black_box(&data.mass_matrix);
                black_box(&data.tau);
            }
            start.elapsed() / size as u32
        })
    });
}

fn batch_kernels(c: &mut Criterion) {
    let mut isas = vec![Isa::baseline()];
    isas.extend(Isa::avx2());
    for (name, path) in robots() {
        let base = Model::from_urdf_file(&path, LoadOptions::default()).expect("robot loads");
        for kernel in [Kernel::Crba, Kernel::Rnea] {
            let mut group = c.benchmark_group(format!("batch_kernels/{name}/{}", kernel.name()));
            group
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_millis(1500));
            let mut data = Data::new(&base);
            let gravity = Environment::default().gravity;
            let q = batch_samples::sample_ramp(base.nq, 0.3, 0.1, 0);
            let v = batch_samples::sample_ramp(base.nv, 0.5, -0.2, 0);
            let a = batch_samples::sample_ramp(base.nv, -0.4, 0.15, 0);
            group.bench_function("scalar", |b| {
                b.iter(|| match kernel {
                    Kernel::Crba => {
                        black_box(crba(&base, &mut data, black_box(&q)));
                    }
                    Kernel::Rnea => {
                        black_box(rnea(
                            &base,
                            &gravity,
                            &mut data,
                            black_box(&q),
                            black_box(&v),
                            black_box(&a),
                        ));
                    }
                })
            });
            for &isa in &isas {
                for size in [1, 4, 8, 32] {
                    bench_batch::<4>(&mut group, &base, kernel, size, isa);
                }
                bench_batch::<2>(&mut group, &base, kernel, 32, isa);
                bench_batch::<8>(&mut group, &base, kernel, 32, isa);
            }
            group.finish();
        }
    }
}

criterion_group!(benches, batch_kernels);
criterion_main!(benches);
