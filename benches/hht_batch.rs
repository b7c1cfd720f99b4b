//! Per-sample cost of an HHT-I3 step when a study's samples step together (issue 16 item 3,
//! docs/batch.md §5): `BatchStepper` groups of 4 lanes (the batched CRBA and RNEA, every lane bitwise
//! the scalar step) at batch sizes 1, 4, 8 and 32, against the scalar step of one trajectory and
//! against MuJoCo's Euler step of the same robot, all in one run.
//!
//! The problem is `hht_step`'s (`support/fall.rs`): a 1 s passive fall under gravity, h = 1 ms,
//! α = −0.1; sample `s` of a batch has every link mass scaled by `1 + 0.01 s`
//! (`support/batch_samples.rs`), so the lanes' trajectories differ. A round is one whole fall of
//! every sample of the batch (the integrators restarted, untimed, before it); the figure is the best
//! of `--rounds` rounds (default 7) divided by samples × steps — µs per sample per step. Before the
//! timing, every lane's end state is compared bit for bit with a scalar run of the same sample.
//!
//! MuJoCo: `benches/mujoco_timing.py` (its `euler` µs per step; same robots, same start, h = 1 ms)
//! run by this bench with the Python of a venv made from `benches/requirements.txt` at
//! `target/mujoco-venv` (created on first use: ~1 min, needs PyPI), or the interpreter named by
//! `RIBBON_MUJOCO_PYTHON`; `--no-mujoco` skips it.
//!
//! ```text
//! cargo bench --bench hht_batch [-- --rounds R] [--no-mujoco] [--robot NAME]...
//! ```
//!
//! `-- --count-steps ROBOT SIZE` runs one fall of a batch of SIZE samples and nothing else, for
//! instruction counts under callgrind (`benches/step_instructions.py`).

#[path = "support/batch_samples.rs"]
mod batch_samples;
#[path = "support/fall.rs"]
mod fall;
#[path = "support/reference_venv.rs"]
mod reference_venv;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use fall::STEPS_PER_FALL;
use nalgebra::DVector;
use ribbon::dynamics::batch::LANES;
use ribbon::integrate::{Constraints, HhtIntegrator, HhtSettings};
use ribbon::scene::Scene;
use ribbon::simulate::{hht_settings, BatchStepCounts, BatchStepper, RobotSystem};

/// The batch sizes timed.
const BATCH_SIZES: [usize; 4] = [1, 4, 8, 32];

/// One robot's samples, stepped in groups of [`LANES`].
struct Batch {
    steppers: Vec<BatchStepper>,
    /// Lanes in use per stepper.
    active: Vec<Vec<bool>>,
    q0: DVector<f64>,
    v0: DVector<f64>,
}

impl Batch {
    fn new(
        template: &RobotSystem,
        scene: &Scene,
        settings: HhtSettings,
        (q0, v0): (&DVector<f64>, &DVector<f64>),
        size: usize,
    ) -> Self {
        let mut steppers = Vec::new();
        let mut active = Vec::new();
        for group in 0..size.div_ceil(LANES) {
            let lanes = LANES.min(size - group * LANES);
            let mut stepper = BatchStepper::new(template, lanes).expect("1–4 lanes");
            for lane in 0..lanes {
                let sample = group * LANES + lane;
                let system = stepper.system_mut(lane);
                *system = RobotSystem::new(
                    batch_samples::sample_model(&template.model, sample),
                    template.environment,
                    scene,
                );
                stepper.sync_lane(lane).expect("same tree");
                stepper
                    .start_lane(lane, settings, q0, v0)
                    .expect("consistent start");
            }
            steppers.push(stepper);
            active.push(vec![true; lanes]);
        }
        Self {
            steppers,
            active,
            q0: q0.clone(),
            v0: v0.clone(),
        }
    }

    fn restart(&mut self) {
        for stepper in &mut self.steppers {
            for lane in 0..stepper.lanes() {
                let (system, integrator) = stepper.lane_mut(lane);
                integrator
                    .expect("started")
                    .restart(system, 0.0, &self.q0, &self.v0)
                    .expect("restart");
            }
        }
    }

    /// One whole fall of every sample, every step computing the reported velocity; the time spent
    /// stepping.
    fn fall(&mut self) -> Duration {
        self.fall_recording_every(1)
    }

    /// One whole fall of every sample, only every `record_every`-th step computing the reported
    /// velocity (a study recording every `record_every` steps; [`ribbon::integrate::ReportedVelocity::Skipped`]
    /// between); the time spent stepping.
    fn fall_recording_every(&mut self, record_every: u64) -> Duration {
        self.restart();
        let start = Instant::now();
        for k in 1..=STEPS_PER_FALL {
            let report = fall::reported_velocity(k, record_every);
            for (stepper, active) in self.steppers.iter_mut().zip(&self.active) {
                let errors = stepper.step(active, report);
                assert!(
                    errors.iter().all(Option::is_none),
                    "the fall steps converge"
                );
            }
        }
        start.elapsed()
    }

    fn counts(&self) -> BatchStepCounts {
        let mut total = BatchStepCounts::default();
        for stepper in &self.steppers {
            total.batched += stepper.counts().batched;
            total.scalar += stepper.counts().scalar;
        }
        total
    }

    /// Every lane's state bits after the last fall.
    fn end_states(&mut self) -> Vec<Vec<u64>> {
        let mut states = Vec::new();
        for stepper in &mut self.steppers {
            for lane in 0..stepper.lanes() {
                let (_, integrator) = stepper.lane_mut(lane);
                states.push(state_bits(integrator.expect("started")));
            }
        }
        states
    }
}

fn state_bits(hht: &HhtIntegrator) -> Vec<u64> {
    let state = hht.state();
    [&state.q, &state.v, &state.qdd]
        .iter()
        .flat_map(|v| v.iter().map(|x| x.to_bits()))
        .collect()
}

/// Scalar steps of sample `sample` along the whole fall; returns the end state's bits.
fn scalar_end_state(
    template: &RobotSystem,
    scene: &Scene,
    settings: HhtSettings,
    (q0, v0): (&DVector<f64>, &DVector<f64>),
    sample: usize,
) -> Vec<u64> {
    let mut system = RobotSystem::new(
        batch_samples::sample_model(&template.model, sample),
        template.environment,
        scene,
    );
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, q0, v0).expect("consistent start");
    for _ in 0..STEPS_PER_FALL {
        hht.step(&mut system).expect("step converges");
    }
    state_bits(&hht)
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_string())
}

/// The Python that runs `mujoco_timing.py`: `RIBBON_MUJOCO_PYTHON`, else the venv at
/// `target/mujoco-venv`, made from `benches/requirements.txt` if missing.
fn mujoco_python(root: &Path) -> Result<PathBuf, String> {
    if let Some(python) = std::env::var_os("RIBBON_MUJOCO_PYTHON") {
        return Ok(PathBuf::from(python));
    }
    let venv = root.join("target/mujoco-venv");
    let python = venv.join("bin/python");
    if python.exists() {
        return Ok(python);
    }
    eprintln!(
        "hht_batch: creating {} from benches/requirements.txt (MuJoCo 4.0; once)",
        venv.display()
    );
    let made = Command::new("python3")
        .args(["-m", "venv"])
        .arg(&venv)
        .status()
        .map_err(|e| format!("python3 -m venv: {e}"))?;
    if !made.success() {
        return Err(format!("python3 -m venv {} failed", venv.display()));
    }
    let installed = Command::new(&python)
        .args(["-m", "pip", "install", "-q", "-r"])
        .arg(root.join("benches/requirements.txt"))
        .status()
        .map_err(|e| format!("pip: {e}"))?;
    if !installed.success() {
        let _ = std::fs::remove_dir_all(&venv);
        return Err("pip install -r benches/requirements.txt failed (needs PyPI)".to_string());
    }
    Ok(python)
}

/// MuJoCo's Euler µs per step for each robot, from `mujoco_timing.py`.
fn mujoco_euler(root: &Path, robots: &[(String, PathBuf)]) -> Result<Vec<(String, f64)>, String> {
    let python = mujoco_python(root)?;
    let mut command = Command::new(&python);
    command.current_dir(root).arg("benches/mujoco_timing.py");
    for (_, path) in robots {
        command.arg(path);
    }
    let output = command
        .output()
        .map_err(|e| format!("{}: {e}", python.display()))?;
    if !output.status.success() {
        return Err(format!(
            "mujoco_timing.py failed: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let json: serde_json::Value = serde_json::from_slice(&output.stdout)
        .map_err(|e| format!("mujoco_timing.py printed no JSON: {e}"))?;
    let results = json["results"]
        .as_array()
        .ok_or("mujoco_timing.py: no results")?;
    Ok(robots
        .iter()
        .zip(results)
        .filter_map(|((name, _), result)| {
            result["results"]["euler"]["us_per_step"]
                .as_f64()
                .map(|us| (name.clone(), us))
        })
        .collect())
}

/// `--count-steps ROBOT SIZE [--record-every K]`: one whole fall of a batch of SIZE samples of
/// ROBOT and nothing else (no MuJoCo, no timing, no scalar runs), every step computing the reported
/// velocity or only every K-th; for instruction counts under callgrind with `--toggle-collect` on
/// `BatchStepper::step` (`benches/step_instructions.py`).
fn count_steps(root: &Path, args: &[String]) {
    let usage = "usage: hht_batch --count-steps ROBOT SIZE [--record-every K]";
    let (Some(robot), Some(Ok(size))) = (args.first(), args.get(1).map(|s| s.parse::<usize>()))
    else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let robots = fall::step_robots(root, reference_venv::benchmark_robots(root));
    let Some((_, path)) = robots.iter().find(|(name, _)| name == robot) else {
        eprintln!("hht_batch: no robot '{robot}'; {usage}");
        std::process::exit(2);
    };
    if size == 0 {
        eprintln!("hht_batch: SIZE must be at least 1; {usage}");
        std::process::exit(2);
    }
    let record_every = match (args.get(2).map(String::as_str), args.get(3)) {
        (None, _) => 1,
        (Some("--record-every"), Some(k)) => match k.parse::<u64>() {
            Ok(k) if k >= 1 => k,
            _ => {
                eprintln!("hht_batch: --record-every needs a whole number of steps >= 1; {usage}");
                std::process::exit(2);
            }
        },
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    let (template, scene, q0, v0) = fall::fall_problem(path);
    let mut batch = Batch::new(&template, &scene, hht_settings(&scene), (&q0, &v0), size);
    batch.fall_recording_every(record_every);
    let counts = batch.counts();
    println!(
        "{{\"robot\": \"{robot}\", \"samples\": {size}, \"steps\": {STEPS_PER_FALL}, \"batched\": {}, \"scalar\": {}}}",
        counts.batched, counts.scalar
    );
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(at) = args.iter().position(|a| a == "--count-steps") {
        count_steps(&root, &args[at + 1..]);
        return;
    }
    let mut rounds = 7usize;
    let mut with_mujoco = true;
    let mut only: Vec<String> = Vec::new();
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--rounds" => {
                i += 1;
                rounds = args
                    .get(i)
                    .and_then(|r| r.parse().ok())
                    .filter(|&r| r > 0)
                    .unwrap_or_else(|| {
                        eprintln!("hht_batch: --rounds needs a positive whole number");
                        std::process::exit(2)
                    });
            }
            "--no-mujoco" => with_mujoco = false,
            "--robot" => {
                i += 1;
                match args.get(i) {
                    Some(name) => only.push(name.clone()),
                    None => {
                        eprintln!(
                            "hht_batch: --robot needs a name (ribbon-ur5, erd-ur5, erd-panda, ribbon-quadruped, ribbon-four-bar)"
                        );
                        std::process::exit(2)
                    }
                }
            }
            // `cargo bench` passes `--bench` to every bench binary.
            "--bench" => {}
            other => {
                eprintln!("hht_batch: unknown argument '{other}'; usage: cargo bench --bench hht_batch -- [--rounds R] [--no-mujoco] [--robot NAME]...");
                std::process::exit(2)
            }
        }
        i += 1;
    }
    let mut robots = fall::step_robots(&root, reference_venv::benchmark_robots(&root));
    if !only.is_empty() {
        robots.retain(|(name, _)| only.contains(name));
    }
    println!("hht_batch: load average at start {}", load_average());
    let mujoco = if with_mujoco {
        match mujoco_euler(&root, &robots) {
            Ok(list) => list,
            Err(message) => {
                eprintln!("hht_batch: MuJoCo not timed: {message}");
                Vec::new()
            }
        }
    } else {
        Vec::new()
    };
    println!("hht_batch: load average after MuJoCo {}", load_average());
    for (name, path) in &robots {
        let (template, scene, q0, v0) = fall::fall_problem(path);
        let settings = hht_settings(&scene);
        let mut batches: Vec<(usize, Batch)> = BATCH_SIZES
            .iter()
            .map(|&size| {
                (
                    size,
                    Batch::new(&template, &scene, settings, (&q0, &v0), size),
                )
            })
            .collect();
        // Bitwise check (untimed): every lane of the largest batch against its scalar run.
        let (largest, batch) = batches.last_mut().expect("batch sizes");
        let largest = *largest;
        batch.fall();
        let ends = batch.end_states();
        let bitwise = (0..largest)
            .all(|s| ends[s] == scalar_end_state(&template, &scene, settings, (&q0, &v0), s));
        let counts = batch.counts();
        let mut scalar_system =
            RobotSystem::new(template.model.clone(), template.environment, &scene);
        let mut scalar = HhtIntegrator::new(&mut scalar_system, settings, 0.0, &q0, &v0)
            .expect("consistent start");
        let mut best_scalar = Duration::MAX;
        let mut best = vec![Duration::MAX; batches.len()];
        for _ in 0..rounds {
            scalar
                .restart(&mut scalar_system, 0.0, &q0, &v0)
                .expect("restart");
            let start = Instant::now();
            for _ in 0..STEPS_PER_FALL {
                scalar.step(&mut scalar_system).expect("step converges");
            }
            best_scalar = best_scalar.min(start.elapsed());
            for (k, (_, batch)) in batches.iter_mut().enumerate() {
                best[k] = best[k].min(batch.fall());
            }
        }
        let per_step = |d: Duration, samples: usize| {
            d.as_secs_f64() * 1e6 / (samples as f64 * STEPS_PER_FALL as f64)
        };
        let scalar_us = per_step(best_scalar, 1);
        let mujoco_us = mujoco.iter().find(|(n, _)| n == name).map(|(_, us)| *us);
        let stats = scalar.stats();
        println!(
            "hht_batch/{name}: nv {}, rows {}; Newton iterations {:.2}/step; lane steps of the batch-{largest} check: {} batched, {} scalar; every lane bitwise its scalar run: {}",
            template.model.nv,
            template.n_constraints(),
            stats.newton_iterations as f64 / stats.steps.max(1) as f64,
            counts.batched,
            counts.scalar,
            if bitwise { "yes" } else { "NO" }
        );
        let mujoco_text = mujoco_us.map_or("not timed".to_string(), |us| format!("{us:.3} µs"));
        println!(
            "hht_batch/{name}: scalar step {scalar_us:.3} µs (MuJoCo Euler {mujoco_text}{})",
            mujoco_us.map_or(String::new(), |us| format!(", ratio {:.2}", scalar_us / us))
        );
        for (k, (size, _)) in batches.iter().enumerate() {
            let us = per_step(best[k], *size);
            println!(
                "hht_batch/{name}/batch-{size}: {us:.3} µs per sample per step; {:.2}× the scalar step{}",
                us / scalar_us,
                mujoco_us.map_or(String::new(), |m| format!(", {:.2}× MuJoCo's Euler step", us / m))
            );
        }
        if !bitwise {
            eprintln!("hht_batch/{name}: a batched lane differs from its scalar run");
            std::process::exit(1);
        }
    }
    println!("hht_batch: load average at end {}", load_average());
}
