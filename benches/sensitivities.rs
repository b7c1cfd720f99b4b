//! What sensitivities cost: the time of one forward-sensitivity run (`sensitivity_run`: direct
//! differentiation of the HHT-I3 step, docs/sensitivities.md) and of the central-difference
//! fallback (`central_difference_run`: 2d + 1 runs), each divided by the time of one plain run of
//! the same scene, on the ur5 holding its pose (robots/ur5/ur5.uncertainty.toml's scene: PD joint
//! spring-dampers, gravity, 2 s at h = 1 ms, joints and the tool frame recorded at 100 Hz), for two
//! boxes built in code:
//!
//! - d = 10: the six moving links' masses (±3 %), the payload's COM height (`wrist_3_link.com.z`,
//!   ±2 mm) and three joint origins (elbow x, wrist 1 z, wrist 2 y; ±0.5 mm);
//! - d = 60: every moving link's mass (±3 %), COM x/y/z (±2 mm) and inertia ixx/iyy/izz (±3 %: ±5 % would let the forearm's
//!   principal moments violate the triangle inequality at a corner, which the box check refuses),
//!   and every moving joint's origin x/y/z (±0.5 mm): 6 + 18 + 18 + 18.
//!
//! A study does not run its points one by one but in lock-step batches (`LockStep`: every sample
//! advanced step by step together, with batched kernels where the scene allows), so each d also
//! times the central-difference points `ξ` and `ξ ± h e_j` as one lock-step batch, and gives the
//! sensitivity run's time over one lock-step run's share of it — what a gradient costs in the
//! runs a refinement budget counts (docs/method.md §12).
//!
//! Every time is the fastest of `SENS_BENCH_REPEATS` (default 3) runs, on one thread. The central
//! differences are timed twice: at the scene's Newton tolerances (the bare cost of 2d + 1 runs) and
//! at [`central_difference_settings`] (the checked fallback as shipped, with tolerances near
//! rounding). Per d, the table shows seconds and the ratio to the plain run; it also prints the
//! sensitivity run's counters (solves, residual evaluations for the Jacobians) and the machine's
//! load average, since the machine is shared.
//!
//! Run (≈ 1 min on 2 cores; results in docs/sensitivities.md §9):
//!
//! ```text
//! cargo bench --bench sensitivities
//! ```
//!
//! Environment: `SENS_BENCH_REPEATS` (default 3), `SENS_BENCH_DIMS` (default `10,60`),
//! `SENS_BENCH_OUT` (directory of `sensitivities.json`, default `$CARGO_TARGET_DIR` or `target`).

use ribbon::analysis::{LockStep, RecordSchedule};
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{parse_sidecar, read_sidecar, Scene, SceneOverrides};
use ribbon::sidecar::SidecarFile;
use ribbon::simulate::{
    central_difference_run_with, central_difference_settings, hht_settings, sensitivity_run,
    simulate, RobotSystem, CENTRAL_DIFFERENCE_STEP_XI,
};
use ribbon::uncertainty::ParameterSpace;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// The moving links of the ur5, in tree order.
const LINKS: [&str; 6] = [
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
];

/// The moving joints of the ur5, in tree order.
const JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// The `[parameters]` table of the d-dimensional box (d = 10 or 60).
fn parameters(d: usize) -> SidecarFile {
    let mut lines = Vec::new();
    for link in LINKS {
        lines.push(format!("\"link.{link}.mass\" = {{ rel = 0.03 }}"));
    }
    if d == 10 {
        lines.push("\"link.wrist_3_link.com.z\" = { abs = 0.002 }".to_string());
        for path in [
            "joint.elbow_joint.origin.x",
            "joint.wrist_1_joint.origin.z",
            "joint.wrist_2_joint.origin.y",
        ] {
            lines.push(format!("\"{path}\" = {{ abs = 0.0005 }}"));
        }
    } else {
        for link in LINKS {
            for axis in ["x", "y", "z"] {
                lines.push(format!("\"link.{link}.com.{axis}\" = {{ abs = 0.002 }}"));
            }
            for entry in ["ixx", "iyy", "izz"] {
                lines.push(format!(
                    "\"link.{link}.inertia.{entry}\" = {{ rel = 0.03 }}"
                ));
            }
        }
        for joint in JOINTS {
            for axis in ["x", "y", "z"] {
                lines.push(format!(
                    "\"joint.{joint}.origin.{axis}\" = {{ abs = 0.0005 }}"
                ));
            }
        }
    }
    parse_sidecar(&format!("[parameters]\n{}", lines.join("\n"))).expect("parameters parse")
}

/// The fastest of `repeats` timings of `f`, s.
fn fastest(repeats: usize, mut f: impl FnMut()) -> f64 {
    (0..repeats)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_string())
}

fn out_dir() -> PathBuf {
    if let Ok(dir) = std::env::var("SENS_BENCH_OUT") {
        return PathBuf::from(dir);
    }
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("target"),
    }
}

fn main() {
    let repeats: usize = std::env::var("SENS_BENCH_REPEATS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let dims: Vec<usize> = std::env::var("SENS_BENCH_DIMS")
        .unwrap_or_else(|_| "10,60".to_string())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5");
    let (file, _) = read_sidecar(&root.join("ur5.uncertainty.toml")).expect("sidecar");
    let model =
        Model::from_urdf_file(&root.join("ur5.urdf"), LoadOptions::default()).expect("ur5 loads");
    let scene = Scene::resolve(&file, &model, "ur5", SceneOverrides::default()).expect("scene");
    let environment = scene.environment();
    println!(
        "# ur5 sensitivities: {} s at h = {} s, {} outputs at {} Hz; fastest of {repeats}; load \
         average before: {}",
        scene.duration_s,
        scene.step_s,
        scene.outputs.len(),
        scene.rate_hz,
        load_average()
    );
    println!();
    println!(
        "| d | plain run (s) | sensitivity run (s) | ratio | central differences, 2d + 1 runs (s) | \
         ratio | checked fallback, tight Newton (s) | ratio | lock-step batch of 2d + 1 (s) | \
         sensitivity run / lock-step run |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let n_records = RecordSchedule::of(&scene).len();
    let mut rows = Vec::new();
    for d in dims {
        if d != 10 && d != 60 {
            eprintln!("d = {d}: only 10 and 60 are built; skipped");
            continue;
        }
        let space = ParameterSpace::from_sidecar(&parameters(d), &model, &environment, "bench")
            .expect("box");
        assert_eq!(space.len(), d);
        let xi = space.nominal_xi();
        let plain = fastest(repeats, || {
            let run = simulate(model.clone(), environment, &scene).expect("plain run");
            std::hint::black_box(run);
        });
        let mut stats = None;
        let direct = fastest(repeats, || {
            let run = sensitivity_run(model.clone(), environment, &scene, &space, &xi)
                .expect("sensitivity run");
            stats = run.stats.sensitivity;
            std::hint::black_box(run);
        });
        let central = fastest(repeats, || {
            let run = central_difference_run_with(
                model.clone(),
                environment,
                &scene,
                &space,
                &xi,
                CENTRAL_DIFFERENCE_STEP_XI,
                hht_settings(&scene),
            )
            .expect("central differences");
            std::hint::black_box(run);
        });
        let checked = fastest(repeats, || {
            let run = central_difference_run_with(
                model.clone(),
                environment,
                &scene,
                &space,
                &xi,
                CENTRAL_DIFFERENCE_STEP_XI,
                central_difference_settings(&scene),
            )
            .expect("central differences");
            std::hint::black_box(run);
        });
        // The central differences' points, as a study would run them: one lock-step batch.
        let mut points = xi.clone();
        for j in 0..2 * d {
            let mut point = xi.clone();
            point[j / 2] += if j % 2 == 0 { 1.0 } else { -1.0 } * CENTRAL_DIFFERENCE_STEP_XI;
            points.extend_from_slice(&point);
        }
        let batch = fastest(repeats, || {
            let template = RobotSystem::new(model.clone(), environment, &scene);
            let mut lockstep = LockStep::new(
                template,
                &space,
                &scene,
                hht_settings(&scene),
                &points,
                None,
            );
            let outcome = lockstep.advance(0, n_records, &pool, &AtomicBool::new(false));
            assert!(
                (0..2 * d + 1).all(|i| !lockstep.failed(i)),
                "lock-step batch failed"
            );
            std::hint::black_box(outcome);
        });
        let per_lockstep_run = batch / (2 * d + 1) as f64;
        println!(
            "| {d} | {plain:.4} | {direct:.4} | {:.1} | {central:.4} | {:.1} | {checked:.4} | {:.1} | \
             {batch:.4} | {:.1} |",
            direct / plain,
            central / plain,
            checked / plain,
            direct / per_lockstep_run
        );
        let stats = stats.expect("sensitivity statistics");
        rows.push(json!({
            "d": d,
            "plain_seconds": plain,
            "sensitivity_seconds": direct,
            "sensitivity_ratio": direct / plain,
            "central_difference_seconds": central,
            "central_difference_ratio": central / plain,
            "checked_fallback_seconds": checked,
            "checked_fallback_ratio": checked / plain,
            "lockstep_batch_seconds": batch,
            "sensitivity_per_lockstep_run": direct / per_lockstep_run,
            "steps": stats.steps,
            "solves": stats.solves,
            "jacobian_residual_evaluations": stats.jacobian_residual_evaluations,
        }));
        eprintln!(
            "d = {d}: {} steps, {} solves, {} residual evaluations for K_t and D_t",
            stats.steps, stats.solves, stats.jacobian_residual_evaluations
        );
    }
    println!();
    println!("load average after: {}", load_average());
    let path = out_dir().join("sensitivities.json");
    let text = serde_json::to_string_pretty(&json!({ "rows": rows })).expect("json");
    match std::fs::write(&path, text) {
        Ok(()) => println!("wrote {}", path.display()),
        Err(e) => eprintln!("could not write {}: {e}", path.display()),
    }
}
