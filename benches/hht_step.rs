//! Criterion bench of one HHT-I3 step (h = 1 ms, α = −0.1, gravity only) on our ur5 and on the
//! example-robot-data ur5 and panda when the reference venv exists (`target/reference-venv`, created by
//! `cargo test --release`). The number is "µs per step of a 1 s passive fall": the integrator runs a
//! 1000-step trajectory from a non-trivial rest configuration, is restarted (outside the timed region)
//! every 1000 steps, and criterion's per-iteration time is the mean cost of a step along that
//! trajectory. Compare with `benches/mujoco_timing.py` (MuJoCo's `rollout` per step) run in the same
//! session: see benches/README.md.
//!
//! Before the timing, each robot's full 1 s fall is run once and its Newton statistics printed
//! (iterations per step, factorisations) so that the per-step time can be read against the work done;
//! then once more through a wrapper that counts and times every call into the system (`Profiled`:
//! CRBA for `mass_matrix`, RNEA for `dynamics_residual`, the constraint rows) to split a step into
//! dynamics and the integrator's own work (factorisation, solves, bookkeeping); and the size of the
//! first Newton correction is estimated for two predictors (the integrator's `q̈_{n+1} = q̈_n` and a
//! linear extrapolation `2 q̈_n − q̈_{n−1}`), in units of the Newton tolerance.
//!
//! First of all, the adaptive step's cost against the fixed step on the shipped robots with their own
//! scenes, as a ratio (`step_control/NAME`, docs/step-control.md §5).

#[path = "support/fall.rs"]
mod fall;
#[path = "support/reference_venv.rs"]
mod reference_venv;

use fall::STEPS_PER_FALL;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{criterion_group, Criterion};
use nalgebra::{DMatrix, DVector};
use ribbon::integrate::{
    Constraints, DaeSystem, HhtIntegrator, HhtSettings, InverseDynamics, NewtonDiagonal,
    PositionGroup, PositionScale, StepControl, SystemError,
};
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::{hht_settings, RobotSystem};

fn robots() -> Vec<(String, PathBuf)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    fall::step_robots(&root, reference_venv::benchmark_robots(&root))
}

/// One robot ready to step: the system, the integrator and the start state.
struct Fall {
    system: RobotSystem,
    hht: HhtIntegrator,
    q0: DVector<f64>,
    v0: DVector<f64>,
    /// Steps taken since the last restart.
    done: u64,
}

impl Fall {
    /// The robot at `path` with the default settings (a fresh Newton matrix at every step).
    fn new(path: &Path) -> Self {
        Self::with_reuse(path, false)
    }

    /// The robot at `path`; with `reuse_newton_matrix` the opt-in reuse of the Newton matrix
    /// across steps ([`HhtSettings::reuse_newton_matrix`]).
    fn with_reuse(path: &Path, reuse_newton_matrix: bool) -> Self {
        let (mut system, scene, q0, v0) = fall::fall_problem(path);
        let settings = HhtSettings {
            reuse_newton_matrix,
            ..hht_settings(&scene)
        };
        let hht =
            HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("consistent start");
        Self {
            system,
            hht,
            q0,
            v0,
            done: 0,
        }
    }

    fn restart(&mut self) {
        self.hht
            .restart(&mut self.system, 0.0, &self.q0, &self.v0)
            .expect("restart");
        self.done = 0;
    }

    /// Takes `n` steps along the fall, restarting (untimed) at the end of each 1 s trajectory, and
    /// returns the time spent in `step` alone.
    fn timed_steps(&mut self, n: u64) -> Duration {
        let mut total = Duration::ZERO;
        let mut remaining = n;
        while remaining > 0 {
            if self.done == STEPS_PER_FALL {
                self.restart();
            }
            let batch = remaining.min(STEPS_PER_FALL - self.done);
            let start = Instant::now();
            for _ in 0..batch {
                self.hht.step(&mut self.system).expect("step converges");
            }
            total += start.elapsed();
            self.done += batch;
            remaining -= batch;
        }
        total
    }
}

/// Runs one full 1 s fall and prints what the integrator did.
fn report(name: &str, fall: &mut Fall) {
    fall.restart();
    let start = Instant::now();
    for _ in 0..STEPS_PER_FALL {
        fall.hht.step(&mut fall.system).expect("step converges");
    }
    let wall = start.elapsed();
    fall.done = STEPS_PER_FALL;
    let stats = *fall.hht.stats();
    let steps = stats.steps.max(1) as f64;
    let q0: Vec<String> = fall
        .system
        .model
        .joints
        .iter()
        .map(|j| format!("{}={}", j.name, fall.q0[j.q_index]))
        .collect();
    eprintln!(
        "hht_step/{name}: nq {} nv {} constraint rows {}; q0 [{}]",
        fall.system.model.nq,
        fall.system.model.nv,
        fall.hht.state().lambda.len(),
        q0.join(", ")
    );
    eprintln!(
        "hht_step/{name}: 1 s fall = {} steps, Newton iterations {} ({:.2}/step, max {} in a step), \
         factorisations {} ({:.2}/step), refreshes {}, projection factorisations {}; \
         this first (cold) run took {:.1} µs/step; q(1 s) = {:?}",
        stats.steps,
        stats.newton_iterations,
        stats.newton_iterations as f64 / steps,
        stats.max_iterations_in_a_step,
        stats.factorisations,
        stats.factorisations as f64 / steps,
        stats.refreshes,
        stats.projection_factorisations,
        wall.as_secs_f64() * 1e6 / steps,
        fall.hht
            .state()
            .q
            .iter()
            .map(|x| (x * 1e6).round() / 1e6)
            .collect::<Vec<_>>()
    );
}

/// Counters of one system method: calls and time spent inside (timer overhead included).
#[derive(Default, Clone, Copy)]
struct Counter {
    calls: u64,
    time: Duration,
}

/// A [`DaeSystem`] that delegates to a [`RobotSystem`] and counts and times every evaluation.
struct Profiled<'a> {
    inner: &'a mut RobotSystem,
    counters: [Counter; PROFILED],
}

/// The system calls the profile counts.
const PROFILED: usize = 9;

const METHODS: [&str; PROFILED] = [
    "mass_matrix (CRBA)",
    "forces",
    "dynamics_residual (RNEA)",
    "newton_diagonal",
    "constraints",
    "constraint_jacobian",
    "constraint_time_derivative",
    "integrate_position",
    "constraints_and_jacobian (one kinematics pass)",
];

impl Profiled<'_> {
    fn timed<R>(&mut self, index: usize, f: impl FnOnce(&mut RobotSystem) -> R) -> R {
        let start = Instant::now();
        let result = f(self.inner);
        let counter = &mut self.counters[index];
        counter.time += start.elapsed();
        counter.calls += 1;
        result
    }
}

impl DaeSystem for Profiled<'_> {
    fn nq(&self) -> usize {
        self.inner.nq()
    }
    fn nv(&self) -> usize {
        self.inner.nv()
    }
    fn mass_matrix(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.timed(0, |s| s.mass_matrix(t, q, out))
    }
    fn forces(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(1, |s| s.forces(t, q, v, out))
    }
    fn as_inverse_dynamics(&mut self) -> Option<&mut dyn InverseDynamics> {
        if self.inner.as_inverse_dynamics().is_some() {
            Some(self)
        } else {
            None
        }
    }
    fn as_constraints(&mut self) -> Option<&mut dyn Constraints> {
        Some(self)
    }
    /// `&self`: not timed (a vector addition for these robots); counted through the integrator's
    /// statistics instead.
    fn as_position_group(&self) -> Option<&dyn PositionGroup> {
        self.inner.as_position_group()
    }
    fn as_position_scale(&self) -> Option<&dyn PositionScale> {
        self.inner.as_position_scale()
    }
    fn as_newton_diagonal(&mut self) -> Option<&mut dyn NewtonDiagonal> {
        if self.inner.as_newton_diagonal().is_some() {
            Some(self)
        } else {
            None
        }
    }
}

impl Constraints for Profiled<'_> {
    fn n_constraints(&self) -> usize {
        self.inner.n_constraints()
    }
    fn constraints(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(4, |s| s.constraints(t, q, out))
    }
    fn constraint_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.timed(5, |s| s.constraint_jacobian(t, q, out))
    }
    fn constraints_and_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        phi: &mut DVector<f64>,
        phi_q: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.timed(8, |s| s.constraints_and_jacobian(t, q, phi, phi_q))
    }
    fn constraint_time_derivative(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(6, |s| s.constraint_time_derivative(t, q, out))
    }
    fn constraint_acceleration_bias(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.inner.constraint_acceleration_bias(t, q, v, out)
    }
}

impl NewtonDiagonal for Profiled<'_> {
    fn newton_diagonal(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DVector<f64>,
        damping_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(3, |s| {
            s.as_newton_diagonal()
                .ok_or("the robot stopped providing its Newton diagonal")?
                .newton_diagonal(t, q, v, stiffness_out, damping_out)
        })
    }
}

impl InverseDynamics for Profiled<'_> {
    fn dynamics_residual(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(2, |s| s.dynamics_residual(t, q, v, qdd, out))
    }

    fn dynamics_residual_after_mass_matrix(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.timed(2, |s| {
            s.dynamics_residual_after_mass_matrix(t, q, v, qdd, out)
        })
    }
}

/// Cost of one `Instant::now()` … `elapsed()` pair, to subtract from the timed calls.
fn timer_overhead() -> Duration {
    let n = 100_000u32;
    let start = Instant::now();
    let mut sink = Duration::ZERO;
    for _ in 0..n {
        let t = Instant::now();
        sink += t.elapsed();
    }
    std::hint::black_box(sink);
    start.elapsed() / n
}

/// Runs a 1 s fall through [`Profiled`] (three times, keeping the fastest) and prints µs per step
/// of each system method and of the rest (the integrator's own work), plus the predictor estimate.
fn profile(name: &str, fall: &mut Fall, settings: HhtSettings) {
    let overhead = timer_overhead();
    let mut best: Option<(Duration, [Counter; PROFILED])> = None;
    let mut history: Vec<DVector<f64>> = Vec::with_capacity(STEPS_PER_FALL as usize + 1);
    let mut scales: Vec<DVector<f64>> = Vec::with_capacity(STEPS_PER_FALL as usize + 1);
    let (q0, v0) = (fall.q0.clone(), fall.v0.clone());
    for run in 0..3 {
        let mut system = Profiled {
            inner: &mut fall.system,
            counters: [Counter::default(); PROFILED],
        };
        let mut hht =
            HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("consistent start");
        system.counters = [Counter::default(); PROFILED];
        let mut total = Duration::ZERO;
        for _ in 0..STEPS_PER_FALL {
            if run == 0 {
                history.push(hht.state().qdd.clone());
                let mut scale = DVector::zeros(system.nv());
                if let Some(position_scale) = system.as_position_scale() {
                    position_scale.position_scale(&hht.state().q, &mut scale);
                }
                scales.push(scale);
            }
            let start = Instant::now();
            hht.step(&mut system).expect("step converges");
            total += start.elapsed();
        }
        if run == 0 {
            history.push(hht.state().qdd.clone());
        }
        if best.as_ref().is_none_or(|(t, _)| total < *t) {
            best = Some((total, system.counters));
        }
    }
    let (total, counters) = best.expect("three runs");
    let steps = STEPS_PER_FALL as f64;
    let per_step = |d: Duration| d.as_secs_f64() * 1e6 / steps;
    let mut system_time = Duration::ZERO;
    let mut parts = Vec::new();
    for (method, counter) in METHODS.iter().zip(counters) {
        if counter.calls == 0 {
            continue;
        }
        let net = counter.time.saturating_sub(overhead * counter.calls as u32);
        system_time += net;
        parts.push(format!(
            "{method} {:.2}/step {:.3} µs/step ({:.3} µs/call)",
            counter.calls as f64 / steps,
            per_step(net),
            net.as_secs_f64() * 1e6 / counter.calls as f64
        ));
    }
    let timed_calls: u64 = counters.iter().map(|c| c.calls).sum();
    let rest = total
        .saturating_sub(system_time)
        .saturating_sub(overhead * timed_calls as u32);
    eprintln!(
        "hht_step/{name}: profile of a 1 s fall (fastest of 3, timer overhead {:.0} ns/call \
         subtracted): total {:.3} µs/step = {}; integrator's own work (factorisation, solves, \
         residual bookkeeping, WRMS test) {:.3} µs/step",
        overhead.as_secs_f64() * 1e9,
        per_step(total),
        parts.join(" + "),
        per_step(rest)
    );

    // First Newton correction ≈ q̈_{n+1} − predictor, measured as the integrator's test does:
    // WRMS of β'h² Δq̈ with ewt_i = 1 / (reltol · scale_i + abstol).
    let c = ribbon::integrate::HhtCoefficients::new(settings.alpha, settings.step_s);
    let beta_h2 = c.beta_h2();
    let wrms = |n: usize, predicted: &DVector<f64>| -> f64 {
        let scale = &scales[n];
        let error = &history[n + 1] - predicted;
        let sum: f64 = error
            .iter()
            .zip(scale.iter())
            .map(|(e, s)| {
                let x = beta_h2 * e / (settings.reltol * s + settings.abstol_position);
                x * x
            })
            .sum();
        (sum / error.len() as f64).sqrt()
    };
    let mut constant = Vec::new();
    let mut linear = Vec::new();
    for n in 1..STEPS_PER_FALL as usize {
        constant.push(wrms(n, &history[n]));
        linear.push(wrms(n, &(&history[n] * 2.0 - &history[n - 1])));
    }
    let median = |mut x: Vec<f64>| {
        x.sort_by(f64::total_cmp);
        x[x.len() / 2]
    };
    eprintln!(
        "hht_step/{name}: first Newton correction / tolerance (median over the fall): predictor \
         q̈_n {:.1e}, linear extrapolation 2q̈_n − q̈_(n−1) {:.1e} (converged when < 1)",
        median(constant),
        median(linear)
    );
}

fn hht_step(c: &mut Criterion) {
    compare_step_control();
    for (name, path) in robots() {
        let mut fall = Fall::new(&path);
        report(&name, &mut fall);
        let settings = *fall.hht.settings();
        profile(&name, &mut fall, settings);
        fall.restart();
        c.bench_function(&format!("hht_step/{name}"), |b| {
            b.iter_custom(|iters| fall.timed_steps(iters))
        });
        let mut reusing = Fall::with_reuse(&path, true);
        report(&format!("{name}/reuse"), &mut reusing);
        reusing.restart();
        c.bench_function(&format!("hht_step/{name}/reuse"), |b| {
            b.iter_custom(|iters| reusing.timed_steps(iters))
        });
    }
}

criterion_group!(benches, hht_step);

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(at) = args.iter().position(|a| a == "--count-steps") {
        count_steps(&args[at + 1..]);
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}

/// `hht_step --count-steps ROBOT STEPS [fresh|reuse] [--record-every K]`: only the fall of ROBOT
/// (a name of [`robots`]), restarted, then STEPS steps (0 ..= 1000) with the Newton matrix
/// factorised at every step (the default settings) or reused across steps (the opt-in
/// [`HhtSettings::reuse_newton_matrix`]); prints the statistics and exits. Every step computes the
/// reported velocity, or, with `--record-every K`, only every K-th (a study recording every K
/// steps: [`ribbon::integrate::ReportedVelocity::Skipped`] between). Run under `valgrind --tool=callgrind` with
/// `--toggle-collect` on `HhtIntegrator::advance_grid_step` (benches/step_instructions.py), or
/// with STEPS = 1000 and 0: the difference of the two instruction counts over 1000 is the
/// instructions per step (benches/README.md).
fn count_steps(args: &[String]) {
    let usage = "usage: hht_step --count-steps ROBOT STEPS [fresh|reuse] [--record-every K]";
    let (Some(robot), Some(steps)) = (args.first(), args.get(1)) else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let Ok(steps) = steps.parse::<u64>() else {
        eprintln!("hht_step: STEPS must be a whole number of steps, got '{steps}'; {usage}");
        std::process::exit(2);
    };
    if steps > STEPS_PER_FALL {
        eprintln!("hht_step: STEPS must be at most {STEPS_PER_FALL} (one 1 s fall), got {steps}");
        std::process::exit(2);
    }
    let mut reuse = false;
    let mut record_every = 1u64;
    let mut rest = args[2..].iter();
    while let Some(arg) = rest.next() {
        match arg.as_str() {
            "fresh" => reuse = false,
            "reuse" => reuse = true,
            "--record-every" => match rest.next().map(|k| k.parse::<u64>()) {
                Some(Ok(k)) if k >= 1 => record_every = k,
                _ => {
                    eprintln!(
                        "hht_step: --record-every needs a whole number of steps >= 1; {usage}"
                    );
                    std::process::exit(2);
                }
            },
            other => {
                eprintln!("hht_step: expected 'fresh', 'reuse' or '--record-every K', got '{other}'; {usage}");
                std::process::exit(2);
            }
        }
    }
    let Some((_, path)) = robots().into_iter().find(|(name, _)| name == robot) else {
        eprintln!("hht_step: no robot '{robot}' (ribbon-ur5, erd-ur5, erd-panda, ribbon-quadruped, ribbon-four-bar; the erd robots need the reference venv)");
        std::process::exit(2);
    };
    let mut fall = Fall::with_reuse(&path, reuse);
    fall.restart();
    for k in 1..=steps {
        let report = fall::reported_velocity(k, record_every);
        fall.hht
            .advance(&mut fall.system, report)
            .expect("step converges");
    }
    let stats = fall.hht.stats();
    println!(
        "{{\"robot\": \"{robot}\", \"reuse\": {reuse}, \"steps\": {}, \"newton_iterations\": {}, \"factorisations\": {}, \"projection_factorisations\": {}, \"refreshes\": {}}}",
        stats.steps, stats.newton_iterations, stats.factorisations, stats.projection_factorisations, stats.refreshes
    );
}

/// The cost of the adaptive step against the fixed one on the shipped robots with their own scenes
/// (issue 12 §3: within 10 %): each scene's whole run, fixed and adaptive alternately, best of
/// `REPEATS` each, at the default tolerance and at 1e-6; printed as a ratio with the sub-steps and
/// the largest error measure the adaptive run saw (≤ 1 means no sub-step was needed). On a loaded
/// machine the wall-clock ratio is noisy (0.67–1.20 measured for identical work); the instruction
/// counts of docs/step-control.md §5 are the stable number.
fn compare_step_control() {
    const REPEATS: usize = 7;
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots");
    for name in ["ur5", "double_pendulum", "four_bar", "slider_crank"] {
        let dir = root.join(name);
        let model =
            Model::from_urdf_file(&dir.join(format!("{name}.urdf")), LoadOptions::default())
                .expect("robot loads");
        let text = std::fs::read_to_string(dir.join(format!("{name}.uncertainty.toml")))
            .expect("sidecar reads");
        let file = parse_sidecar(&text).expect("sidecar parses");
        let scene =
            Scene::resolve(&file, &model, name, SceneOverrides::default()).expect("scene resolves");
        let environment = scene.environment();
        let q0 = DVector::from_column_slice(&scene.initial_q);
        let v0 = DVector::from_column_slice(&scene.initial_v);
        for tolerance in [hht_settings(&scene).tolerance, 1e-6] {
            let mut best = [Duration::MAX; 2];
            let mut stats = [None, None];
            for _ in 0..REPEATS {
                for (k, control) in [StepControl::Fixed, StepControl::Adaptive]
                    .into_iter()
                    .enumerate()
                {
                    let mut system = RobotSystem::new(model.clone(), environment, &scene);
                    let settings = HhtSettings {
                        step_control: control,
                        tolerance,
                        ..hht_settings(&scene)
                    };
                    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0)
                        .expect("consistent start");
                    let start = Instant::now();
                    for _ in 0..scene.n_steps {
                        hht.step(&mut system).expect("step converges");
                    }
                    best[k] = best[k].min(start.elapsed());
                    stats[k] = Some(*hht.stats());
                }
            }
            let adaptive = stats[1].expect("ran");
            println!(
            "step_control/{name}: {} steps; fixed {:.3} ms, adaptive {:.3} ms: ratio {:.3}; adaptive sub-steps {}, largest error measure {:.2e} (tolerance {:.0e})",
            scene.n_steps,
            best[0].as_secs_f64() * 1e3,
            best[1].as_secs_f64() * 1e3,
            best[1].as_secs_f64() / best[0].as_secs_f64(),
            adaptive.substeps,
            adaptive.max_error_estimate,
            tolerance
        );
        }
    }
}
