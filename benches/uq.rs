//! Speed of the surrogate pipeline per output: fit (sum-factorised projection of 1 000 outputs at
//! once) and scan (default grid: 21 points per dimension for d ≤ 2, 11 for d ≥ 3, then Newton
//! refinement), Legendre, tensor truncation, k = 4, d = 2, 3, 4. Divide the reported time by 1 000
//! for the cost per output.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use ribbon::uq::{
    interval_bound, Design, Family, Projector, RangeMode, ScanOptions, Scanner, Surrogate,
    Truncation,
};

const N_OUTPUTS: usize = 1_000;
const ORDER: usize = 4;

/// splitmix64, for reproducible test functions without a `rand` dependency.
struct SplitMix64(u64);

impl SplitMix64 {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// Values of N_OUTPUTS smooth random-ish functions at the design points, run-major
/// (`n_points × N_OUTPUTS`): `Π_r cos(a_r ξ_r + b_r) + c ξ_1 ξ_d + e ξ_1²` with random a, b, c, e.
fn test_values(design: &Design) -> Vec<f64> {
    let d = design.dim();
    let mut rng = SplitMix64(0xBE7C);
    let params: Vec<(Vec<f64>, Vec<f64>, f64, f64)> = (0..N_OUTPUTS)
        .map(|_| {
            let a = (0..d).map(|_| rng.uniform(0.2, 1.5)).collect();
            let b = (0..d).map(|_| rng.uniform(-1.0, 1.0)).collect();
            (a, b, rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3))
        })
        .collect();
    let mut values = Vec::with_capacity(design.n_points() * N_OUTPUTS);
    for x in design.points().chunks_exact(d) {
        for (a, b, c, e) in &params {
            let prod: f64 = (0..d).map(|r| (a[r] * x[r] + b[r]).cos()).product();
            values.push(prod + c * x[0] * x[d - 1] + e * x[0] * x[0]);
        }
    }
    values
}

fn bench_fit_and_scan(c: &mut Criterion) {
    let mut group = c.benchmark_group("uq_1000_outputs_k4");
    group.sample_size(10);
    for dim in [2, 3, 4] {
        let design = Design::new(Family::Legendre, dim, ORDER, Truncation::Tensor).unwrap();
        let values = test_values(&design);
        let projector = Projector::new(design.clone()).unwrap();
        let options = ScanOptions::for_dim(dim);
        let mut scanner = Scanner::new(Family::Legendre, dim, ORDER, options).unwrap();
        let mut surrogate = Surrogate::zeros(&design);
        let coef = projector.fit(&values, N_OUTPUTS).unwrap();

        group.bench_function(format!("fit d={dim}"), |b| {
            b.iter(|| projector.fit(black_box(&values), N_OUTPUTS).unwrap())
        });
        group.bench_function(
            format!("scan d={dim} N={} +refine", options.points_per_dim),
            |b| {
                b.iter(|| {
                    let mut width = 0.0;
                    for o in 0..N_OUTPUTS {
                        surrogate.set_from_matrix(&design, &coef, o).unwrap();
                        width += scanner.scan(&surrogate).unwrap().bound.width();
                    }
                    width
                })
            },
        );
        group.bench_function(format!("interval bound d={dim}"), |b| {
            b.iter(|| {
                let mut width = 0.0;
                for o in 0..N_OUTPUTS {
                    surrogate.set_from_matrix(&design, &coef, o).unwrap();
                    width += interval_bound(&surrogate, RangeMode::Exact)
                        .unwrap()
                        .width();
                }
                width
            })
        });
        group.bench_function(
            format!("fit+scan d={dim} N={} +refine", options.points_per_dim),
            |b| {
                b.iter(|| {
                    let coef = projector.fit(black_box(&values), N_OUTPUTS).unwrap();
                    let mut width = 0.0;
                    for o in 0..N_OUTPUTS {
                        surrogate.set_from_matrix(&design, &coef, o).unwrap();
                        width += scanner.scan(&surrogate).unwrap().bound.width();
                    }
                    width
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench_fit_and_scan);
criterion_main!(benches);
