//! Fit + bound of a sparse design, phase by phase, before and after issue 40 — in one run, so the
//! ratios do not depend on the machine's load of the moment.
//!
//! The problem stands in for the d = 72 all-values ur5 study's design phase: a total-degree-2 Leja
//! grid in d = 72 (|Λ| = 2 701 runs), 9 outputs over 50 record times, each output a smooth function
//! of ξ whose slopes turn slowly with time — `Σ_r a_r(t) ξ_r + Σ_r b_r ξ_r² + Σ c_rs ξ_r ξ_s +
//! 0.05 cos(ξ_1 + t)`, a few strong parameters and many weak ones (as the study's Sobol' indices
//! show), the extremes at vertices in most coordinates.
//!
//! - **before**: each record gathered from the runs' rows and fitted alone (`LinearFit::fit_into`,
//!   as the adaptive rounds did), each output's inner bound from
//!   seven starts shared by both sides (the centre, both sign vertices, the two lowest and the two
//!   highest design points: `BoxOptimizer::bound_into`, as the engine did);
//! - **after**: every record fitted at once from the runs' rows (`LinearFit::fit_rows_into`, as the
//!   adaptive rounds do now; each coefficient the same to the bit), each side from its own vertex, its best design point and where the previous
//!   record time's extreme was (`BoxOptimizer::inner_bound_per_side_into`, as
//!   `analysis/sparse_bounds.rs` does), then the outer bound (`BoxOptimizer::enclose`);
//! - Sobol' indices alike in both.
//!
//! Printed: the best of `--rounds` rounds (default 3) per phase, the ratio after/before, and how far
//! the after envelopes are from the before ones (largest |difference| over an output's largest
//! width). One thread: the study runs the same work on every thread it has.
//!
//! ```text
//! cargo bench --bench sparse_bounding [-- --rounds R]
//! ```

#[path = "support/split_mix64.rs"]
mod split_mix64;
use split_mix64::SplitMix64;

use std::sync::Arc;
use std::time::Instant;

use ribbon::uq::{BoxBounds, BoxOptimizer, MultiIndexSet, SparseGrid, SparseSurrogate};

const DIM: usize = 72;
const OUTPUTS: usize = 9;
const RECORDS: usize = 50;
/// The engine's design starts per side (analysis::DESIGN_STARTS_PER_SIDE after; 2 before).
const STARTS_AFTER: usize = ribbon::analysis::DESIGN_STARTS_PER_SIDE;
const STARTS_BEFORE: usize = 2;

/// One output's response: slopes `a_r cos(ω_r t + φ_r)`, curvatures, a few products.
struct Response {
    slope: Vec<(f64, f64, f64)>,
    curvature: Vec<f64>,
    products: Vec<(usize, usize, f64)>,
}

impl Response {
    fn random(rng: &mut SplitMix64) -> Response {
        let slope = (0..DIM)
            .map(|r| {
                // A few strong parameters, many weak ones.
                let size = if r % 17 == 0 { 1.0 } else { 0.02 };
                (
                    size * rng.uniform(0.5, 1.0),
                    rng.uniform(0.5, 3.0),
                    rng.uniform(-1.0, 1.0),
                )
            })
            .collect();
        let curvature = (0..DIM).map(|_| rng.uniform(-0.01, 0.01)).collect();
        let products = (0..12)
            .map(|i| (i * 5 % DIM, (i * 11 + 3) % DIM, rng.uniform(-0.05, 0.05)))
            .filter(|(r, s, _)| r != s)
            .collect();
        Response {
            slope,
            curvature,
            products,
        }
    }

    fn at(&self, x: &[f64], t: f64) -> f64 {
        let mut y = 0.05 * (x[0] + t).cos();
        for (r, (&(a, omega, phi), &b)) in self.slope.iter().zip(&self.curvature).enumerate() {
            y += a * (omega * t + phi).cos() * x[r] + b * x[r] * x[r];
        }
        for &(r, s, c) in &self.products {
            y += c * x[r] * x[s];
        }
        y
    }
}

/// Per phase, seconds of one round.
#[derive(Clone, Copy, Default)]
struct Phases {
    fit: f64,
    inner: f64,
    outer: f64,
    sobol: f64,
}

impl Phases {
    fn best(self, other: Phases) -> Phases {
        Phases {
            fit: self.fit.min(other.fit),
            inner: self.inner.min(other.inner),
            outer: self.outer.min(other.outer),
            sobol: self.sobol.min(other.sobol),
        }
    }

    fn total(&self) -> f64 {
        self.fit + self.inner + self.outer + self.sobol
    }
}

/// `(lower, upper)` per record and output, record-major.
type Envelopes = Vec<(f64, f64)>;

/// The `k` lowest and the `k` highest design points by value (ties by index).
fn best_points(values: &[f64], o: usize, k: usize) -> (Vec<usize>, Vec<usize>) {
    let n = values.len() / OUTPUTS;
    let mut order: Vec<usize> = (0..n).collect();
    let value = |p: usize| values[p * OUTPUTS + o];
    order.sort_by(|&a, &b| value(a).total_cmp(&value(b)).then(a.cmp(&b)));
    (order[..k].to_vec(), order[n - k..].to_vec())
}

fn before(grid: &SparseGrid, runs: &[Vec<f64>], records: &[Vec<f64>]) -> (Phases, Envelopes) {
    let set = grid.set();
    let mut phases = Phases::default();
    let mut envelopes = Vec::with_capacity(RECORDS * OUTPUTS);
    let mut surrogate = SparseSurrogate::zeros(Arc::clone(set));
    let mut optimizer = BoxOptimizer::new();
    let mut bounds = BoxBounds::default();
    let mut coefficients = vec![0.0; set.len() * OUTPUTS];
    for (r, values) in records.iter().enumerate() {
        let lap = Instant::now();
        let gathered: Vec<f64> = runs
            .iter()
            .flat_map(|run| run[r * OUTPUTS..(r + 1) * OUTPUTS].to_vec())
            .collect();
        grid.fit()
            .fit_into(&gathered, OUTPUTS, &mut coefficients)
            .unwrap();
        phases.fit += lap.elapsed().as_secs_f64();
        for o in 0..OUTPUTS {
            surrogate.set_from_fit(&coefficients, OUTPUTS, o).unwrap();
            let lap = Instant::now();
            let (lowest, highest) = best_points(values, o, STARTS_BEFORE);
            let starts: Vec<f64> = lowest
                .iter()
                .chain(&highest)
                .flat_map(|&p| grid.point(p).to_vec())
                .collect();
            optimizer
                .inner_bound_into(&surrogate, &starts, &mut bounds)
                .unwrap();
            let lap = next(&mut phases.inner, lap);
            optimizer.enclose(&surrogate, &mut bounds);
            let lap = next(&mut phases.outer, lap);
            std::hint::black_box(surrogate.sobol_indices());
            next(&mut phases.sobol, lap);
            envelopes.push((bounds.lower, bounds.upper));
        }
    }
    (phases, envelopes)
}

fn after(grid: &SparseGrid, runs: &[Vec<f64>], records: &[Vec<f64>]) -> (Phases, Envelopes) {
    let set = grid.set();
    let mut phases = Phases::default();
    let lap = Instant::now();
    let rows: Vec<&[f64]> = runs.iter().map(Vec::as_slice).collect();
    let width = RECORDS * OUTPUTS;
    let mut coefficients = vec![0.0; set.len() * width];
    grid.fit().fit_rows_into(&rows, &mut coefficients).unwrap();
    phases.fit += lap.elapsed().as_secs_f64();
    let mut envelopes = vec![(0.0, 0.0); RECORDS * OUTPUTS];
    let mut surrogate = SparseSurrogate::zeros(Arc::clone(set));
    let mut optimizer = BoxOptimizer::new();
    let mut bounds = BoxBounds::default();
    let mut column = vec![0.0; set.len()];
    for o in 0..OUTPUTS {
        let mut previous: Option<(Vec<f64>, Vec<f64>)> = None;
        for (r, values) in records.iter().enumerate() {
            let lap = Instant::now();
            for (t, c) in column.iter_mut().enumerate() {
                *c = coefficients[t * width + r * OUTPUTS + o];
            }
            surrogate.set_coefficients(&column).unwrap();
            let lap = next(&mut phases.fit, lap);
            let (lowest, highest) = best_points(values, o, STARTS_AFTER);
            let mut lower: Vec<f64> = lowest
                .iter()
                .flat_map(|&p| grid.point(p).to_vec())
                .collect();
            let mut upper: Vec<f64> = highest
                .iter()
                .flat_map(|&p| grid.point(p).to_vec())
                .collect();
            if let Some((argmin, argmax)) = &previous {
                lower.extend_from_slice(argmin);
                upper.extend_from_slice(argmax);
            }
            optimizer
                .inner_bound_per_side_into(&surrogate, &lower, &upper, &mut bounds)
                .unwrap();
            previous = Some((bounds.argmin.clone(), bounds.argmax.clone()));
            let lap = next(&mut phases.inner, lap);
            optimizer.enclose(&surrogate, &mut bounds);
            let lap = next(&mut phases.outer, lap);
            std::hint::black_box(surrogate.sobol_indices());
            next(&mut phases.sobol, lap);
            envelopes[r * OUTPUTS + o] = (bounds.lower, bounds.upper);
        }
    }
    (phases, envelopes)
}

/// Adds the time since `lap` to `phase`; returns now.
fn next(phase: &mut f64, lap: Instant) -> Instant {
    let now = Instant::now();
    *phase += now.duration_since(lap).as_secs_f64();
    now
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .and_then(|i| args.get(i + 1))
        .map_or(3, |v| v.parse().expect("--rounds N"));
    let grid = SparseGrid::new(Arc::new(MultiIndexSet::total_degree(DIM, 2).unwrap())).unwrap();
    let mut rng = SplitMix64(0x5EED_0040);
    let responses: Vec<Response> = (0..OUTPUTS).map(|_| Response::random(&mut rng)).collect();
    // values[r]: record r, row-major `points × outputs`.
    let records: Vec<Vec<f64>> = (0..RECORDS)
        .map(|r| {
            let t = 0.04 * r as f64;
            grid.points()
                .chunks_exact(DIM)
                .flat_map(|x| responses.iter().map(move |y| y.at(x, t)))
                .collect()
        })
        .collect();
    // The runs' rows, as a study keeps them: run p's values at every record.
    let runs: Vec<Vec<f64>> = (0..grid.n_points())
        .map(|p| {
            records
                .iter()
                .flat_map(|values| values[p * OUTPUTS..(p + 1) * OUTPUTS].to_vec())
                .collect()
        })
        .collect();
    println!(
        "sparse bounding: d = {DIM}, |Λ| = {} (total degree 2), {OUTPUTS} outputs × {RECORDS} records, best of {rounds} rounds, one thread",
        grid.n_points()
    );
    let (mut old, mut new) = (None::<Phases>, None::<Phases>);
    let (mut old_envelopes, mut new_envelopes) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        let (phases, envelopes) = before(&grid, &runs, &records);
        old = Some(old.map_or(phases, |p| p.best(phases)));
        old_envelopes = envelopes;
        let (phases, envelopes) = after(&grid, &runs, &records);
        new = Some(new.map_or(phases, |p| p.best(phases)));
        new_envelopes = envelopes;
    }
    let (old, new) = (old.expect("rounds ≥ 1"), new.expect("rounds ≥ 1"));
    println!(
        "{:<14} {:>10} {:>10} {:>8}",
        "phase", "before s", "after s", "ratio"
    );
    for (name, b, a) in [
        ("fit", old.fit, new.fit),
        ("inner bound", old.inner, new.inner),
        ("outer bound", old.outer, new.outer),
        ("Sobol' indices", old.sobol, new.sobol),
        ("fit + bound", old.total(), new.total()),
    ] {
        println!("{name:<14} {b:>10.4} {a:>10.4} {:>8.3}", a / b);
    }
    for o in 0..OUTPUTS {
        let at = |e: &Envelopes, r: usize| e[r * OUTPUTS + o];
        let width = (0..RECORDS)
            .map(|r| at(&old_envelopes, r).1 - at(&old_envelopes, r).0)
            .fold(0.0, f64::max);
        // Inner bounds: wider is a more extreme value found, narrower one the search missed.
        let (mut wider, mut narrower) = (0.0_f64, 0.0_f64);
        for r in 0..RECORDS {
            let (b, a) = (at(&old_envelopes, r), at(&new_envelopes, r));
            for change in [b.0 - a.0, a.1 - b.1] {
                wider = wider.max(change);
                narrower = narrower.max(-change);
            }
        }
        println!(
            "output {o}: after vs before, widest widening {:.2e}, widest narrowing {:.2e} of the width",
            wider / width,
            narrower / width
        );
    }
}
