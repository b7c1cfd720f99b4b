//! Speed of the surrogate pipeline per output: fit (sum-factorised projection of 1 000 outputs at
//! once) and scan (default grid: 21 points per dimension for d ≤ 2, 11 for d ≥ 3, then Newton
//! refinement), Legendre, tensor truncation, k = 4, d = 2, 3, 4. Divide the reported time by 1 000
//! for the cost per output.
//!
//! Group `uq_high_dimension` (docs/high-dimension.md): total degree 2 at d = 60 (|Λ| = 1891) —
//! building the sparse grid, fitting 40 outputs on it and by least squares on 3 800 Sobol' points,
//! and the inner + outer bound of one output ([`BoxOptimizer`], built-in starts only and with 3
//! design points added); the large regression's one-time build is timed once and printed.

#[path = "support/split_mix64.rs"]
mod split_mix64;
use split_mix64::SplitMix64;

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use std::sync::Arc;
use std::time::Instant;

use ribbon::uq::{
    interval_bound, sobol_design, BoxBounds, BoxOptimizer, Design, Family, MultiIndexSet,
    Projector, RangeMode, Regression, ScanOptions, Scanner, SparseGrid, SparseSurrogate, Surrogate,
    Truncation,
};

const N_OUTPUTS: usize = 1_000;
const ORDER: usize = 4;

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

/// Outputs fitted together in the high-dimension group (a robot's joints and frames at one time).
const HD_OUTPUTS: usize = 40;

/// `HD_OUTPUTS` smooth responses at `points` (`n × d`), run-major: a linear part of O(1) slopes,
/// diagonal curvature ±0.3, a rank-one coupling `0.05 (s·ξ)²` and `sin(ξ1 ξ2 + o)`.
fn hd_values(points: &[f64], d: usize) -> Vec<f64> {
    let mut values = Vec::with_capacity(points.len() / d * HD_OUTPUTS);
    for x in points.chunks_exact(d) {
        for o in 0..HD_OUTPUTS {
            let of = o as f64;
            let (mut lin, mut quad, mut mix) = (0.0, 0.0, 0.0);
            for (r, &v) in x.iter().enumerate() {
                let rf = r as f64;
                lin += (rf * 0.37 + of).sin() * v;
                quad += 0.3 * (rf * 0.71 + of).cos() * v * v;
                mix += (rf * 1.3 + of).sin() * v;
            }
            values.push(lin + quad + 0.05 * mix * mix + (x[0] * x[1] + of).sin());
        }
    }
    values
}

fn bench_high_dimension(c: &mut Criterion) {
    let mut group = c.benchmark_group("uq_high_dimension");
    group.sample_size(10);
    let d = 60;
    let set = Arc::new(MultiIndexSet::total_degree(d, 2).unwrap());
    group.bench_function("sparse grid build d=60 k=2 (1891 points)", |b| {
        b.iter(|| SparseGrid::new(black_box(set.clone())).unwrap())
    });
    let grid = SparseGrid::new(set.clone()).unwrap();
    let grid_values = hd_values(grid.points(), d);
    let mut coef = vec![0.0; set.len() * HD_OUTPUTS];
    group.bench_function("sparse grid fit d=60 k=2, 40 outputs", |b| {
        b.iter(|| {
            grid.fit()
                .fit_into(black_box(&grid_values), HD_OUTPUTS, &mut coef)
                .unwrap()
        })
    });

    let n_points = 3800;
    let points = sobol_design(d, n_points, 0, &[]).unwrap();
    let started = Instant::now();
    let regression = Regression::new(set.clone(), points).unwrap();
    println!(
        "regression build d=60 k=2 (|Λ| = {}, n = {n_points}): {:.2} s, κ₂ = {:.2}",
        set.len(),
        started.elapsed().as_secs_f64(),
        regression.condition_number()
    );
    let reg_values = hd_values(regression.points(), d);
    group.bench_function("regression fit d=60 k=2 n=3800, 40 outputs", |b| {
        b.iter(|| {
            regression
                .fit()
                .fit_into(black_box(&reg_values), HD_OUTPUTS, &mut coef)
                .unwrap()
        })
    });

    grid.fit()
        .fit_into(&grid_values, HD_OUTPUTS, &mut coef)
        .unwrap();
    let surrogates: Vec<SparseSurrogate> = (0..HD_OUTPUTS)
        .map(|o| {
            let mut s = SparseSurrogate::zeros(set.clone());
            s.set_from_fit(&coef, HD_OUTPUTS, o).unwrap();
            s
        })
        .collect();
    // Three design points as extra starts (the centre and the first two one-sided moves), standing
    // in for the best design points the engine passes.
    let design_starts: Vec<f64> = grid.points()[..3 * d].to_vec();
    let mut optimizer = BoxOptimizer::new();
    let mut bounds = BoxBounds::default();
    for (name, starts) in [
        ("box bound d=60 k=2, per output, built-in starts", &[][..]),
        (
            "box bound d=60 k=2, per output, +3 design starts",
            &design_starts[..],
        ),
    ] {
        group.bench_function(name, |b| {
            let mut o = 0;
            b.iter(|| {
                optimizer
                    .bound_into(&surrogates[o % HD_OUTPUTS], starts, &mut bounds)
                    .unwrap();
                o += 1;
                bounds.gap()
            })
        });
    }
    group.bench_function("outer bound only d=60 k=2, per output", |b| {
        b.iter(|| optimizer.outer_bound(black_box(&surrogates[0])))
    });
    group.finish();
}

criterion_group!(benches, bench_fit_and_scan, bench_high_dimension);
criterion_main!(benches);
