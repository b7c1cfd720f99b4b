//! Speed evidence of `ribbon analyze`: every method against a true-model `scan` reference on the
//! ur5 holding a pose (robots/ur5/ur5.uncertainty.toml's scene: PD gains as joint spring-dampers,
//! released at t = 0), 1 s at h = 1 ms, with d = 2, 3, 4 interval parameters:
//!
//! - d = 2: `link.wrist_3_link.mass` ∈ [0.15, 1.2] kg (payload), `link.wrist_3_link.com.z` ∈
//!   [-0.002, 0.04] m;
//! - d = 3: + `s` ∈ [0.95, 1.05], bound to the other moving links' masses and inertias (as shipped);
//! - d = 4: + `joint.elbow_joint.origin.x` = { rel = 0.01 } (the upper-arm length a2 = 0.425 m).
//!
//! For each d: the `scan` reference (11^d by default), then legendre-scan k = 2, 3, 4, legendre-ia
//! k = 4, chebyshev-scan k = 4, taylor and monte-carlo at a few sample counts. Per method: model
//! runs, wall time, simulate / fit + bound split, and the error of docs/method.md §4
//! (`ribbon::uq::envelope_error`) against the reference: per output the max and the mean over time;
//! the table shows the worst output of each (outputs whose reference width is below 1e-12 at every
//! time are skipped and named). Studies shorter than 1 s are run 3 times and the fastest is shown. Also legendre-scan's runs against a 21^d scan, its fit + bound share,
//! and 1-thread vs 2-thread wall times (legendre-scan k = 4 and the reference scan).
//!
//! Run (≈ 4 min on 2 cores; results and discussion in benches/ANALYSIS.md):
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-analysis cargo bench -j 1 --bench analysis_methods
//! ```
//!
//! Environment: `ANALYSIS_DIMS` (default `2,3,4`), `ANALYSIS_REF_GRID` (points per dimension of the
//! reference, default 11; `ANALYSIS_REF_GRID_D4` overrides it for d = 4), `ANALYSIS_REF_1THREAD_MAX_D`
//! (largest d whose reference is also timed on 1 thread, default 4), `ANALYSIS_FINE_MAX_D` (largest
//! d that also runs a 21^d scan, to measure the reference's own resolution, default 3),
//! `ANALYSIS_MC` (Monte Carlo sample counts, default `100,400,1600,6400,25600`), `ANALYSIS_OUT`
//! (directory of the JSON files, default `$CARGO_TARGET_DIR` or `target`). Writes
//! `analysis_methods.json` (every row), `ur5_d3_scan_reference.json` (the d = 3 11^3 reference
//! envelope, for benches/mujoco_monte_carlo.py) and `ur5_d3_scan21_reference.json` (the 21^3 one).

use ribbon::analysis::{Method, Study, StudyOptions, StudyReport};
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::uncertainty::ParameterSpace;
use ribbon::uq::{envelope_error, Truncation};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

const DURATION_S: f64 = 1.0;
const STEP_S: f64 = 1e-3;
/// Reference widths at or below this (at every time) make the relative error meaningless: skipped.
const ZERO_WIDTH: f64 = 1e-12;

/// The `[parameters]` / `[bind]` part of the sidecar for `d` parameters.
fn parameter_tables(d: usize) -> String {
    let mut text = String::from(
        "[parameters]\n\
         \"link.wrist_3_link.mass\"  = [0.15, 1.2]\n\
         \"link.wrist_3_link.com.z\" = [-0.002, 0.04]\n",
    );
    if d >= 3 {
        text.push_str("s = [0.95, 1.05]\n");
    }
    if d >= 4 {
        text.push_str("\"joint.elbow_joint.origin.x\" = { rel = 0.01 }\n");
    }
    if d >= 3 {
        text.push_str(
            "[bind]\n\
             \"link.shoulder_link.mass\"        = \"s * 3.7\"\n\
             \"link.shoulder_link.inertia.ixx\" = \"s * 0.0102675\"\n\
             \"link.shoulder_link.inertia.iyy\" = \"s * 0.0102675\"\n\
             \"link.shoulder_link.inertia.izz\" = \"s * 0.00666\"\n\
             \"link.upper_arm_link.mass\"        = \"s * 8.393\"\n\
             \"link.upper_arm_link.inertia.ixx\" = \"s * 0.0151074\"\n\
             \"link.upper_arm_link.inertia.iyy\" = \"s * 0.133885835417\"\n\
             \"link.upper_arm_link.inertia.izz\" = \"s * 0.133885835417\"\n\
             \"link.forearm_link.mass\"        = \"s * 2.33\"\n\
             \"link.forearm_link.inertia.ixx\" = \"s * 0.0029125\"\n\
             \"link.forearm_link.inertia.iyy\" = \"s * 0.031330745469\"\n\
             \"link.forearm_link.inertia.izz\" = \"s * 0.031330745469\"\n\
             \"link.wrist_1_link.mass\"        = \"s * 1.219\"\n\
             \"link.wrist_1_link.inertia.ixx\" = \"s * 0.0019504\"\n\
             \"link.wrist_1_link.inertia.iyy\" = \"s * 0.0019504\"\n\
             \"link.wrist_1_link.inertia.izz\" = \"s * 0.0009752\"\n\
             \"link.wrist_2_link.mass\"        = \"s * 1.219\"\n\
             \"link.wrist_2_link.inertia.ixx\" = \"s * 0.0019504\"\n\
             \"link.wrist_2_link.inertia.iyy\" = \"s * 0.0019504\"\n\
             \"link.wrist_2_link.inertia.izz\" = \"s * 0.0009752\"\n",
        );
    }
    text
}

/// The problem of dimension `d`: model, scene (its environment: [`Scene::environment`]), parameter
/// space.
struct Problem {
    d: usize,
    model: Model,
    scene: Scene,
    space: ParameterSpace,
    sidecar: String,
}

fn problem(root: &Path, d: usize) -> Problem {
    let shipped = std::fs::read_to_string(root.join("robots/ur5/ur5.uncertainty.toml"))
        .expect("read robots/ur5/ur5.uncertainty.toml");
    // Keep the shipped scene (PD-held pose), outputs and analysis sections; replace the parameters.
    let scene_part = &shipped[shipped
        .find("[scene]")
        .expect("[scene] in the shipped sidecar")..];
    let sidecar = format!("{}\n{scene_part}", parameter_tables(d));
    let file = parse_sidecar(&sidecar).expect("parse the bench sidecar");
    let model = Model::from_urdf_file(
        &root.join("robots/ur5/ur5.urdf"),
        LoadOptions {
            floating_base: false,
        },
    )
    .expect("load ur5");
    let overrides = SceneOverrides {
        duration_s: Some(DURATION_S),
        step_s: Some(STEP_S),
        alpha: None,
    };
    let name = format!("bench sidecar d = {d}");
    let scene = Scene::resolve(&file, &model, &name, overrides).expect("resolve the scene");
    let environment = scene.environment();
    let space =
        ParameterSpace::from_sidecar(&file, &model, &environment, &name).expect("parameter space");
    assert_eq!(space.len(), d);
    Problem {
        d,
        model,
        scene,
        space,
        sidecar,
    }
}

#[derive(Clone, Copy)]
struct Config {
    method: Method,
    order: usize,
    grid: usize,
    samples: usize,
    threads: usize,
}

impl Config {
    fn new(method: Method) -> Self {
        Config {
            method,
            order: 4,
            grid: 11,
            samples: 1000,
            threads: 2,
        }
    }
    fn order(mut self, k: usize) -> Self {
        self.order = k;
        self
    }
    fn grid(mut self, n: usize) -> Self {
        self.grid = n;
        self
    }
    fn samples(mut self, n: usize) -> Self {
        self.samples = n;
        self
    }
    fn threads(mut self, t: usize) -> Self {
        self.threads = t;
        self
    }
    fn label(&self) -> String {
        match self.method {
            Method::Scan => format!("scan {}^d", self.grid),
            Method::MonteCarlo => format!("monte-carlo N={}", self.samples),
            Method::Taylor => "taylor (1st order)".to_string(),
            m => format!("{} k={}", m.name(), self.order),
        }
    }
}

/// Runs one study; returns the report and its wall time (plan, simulation, fit, bound).
fn run(p: &Problem, c: Config) -> (StudyReport, f64) {
    let study = Study {
        model: p.model.clone(),
        environment: p.scene.environment(),
        scene: &p.scene,
        space: &p.space,
        options: StudyOptions {
            method: c.method,
            order: c.order,
            truncation: Truncation::Tensor,
            grid: c.grid,
            scan_grid: None,
            samples: c.samples,
            seed: 0,
            threads: c.threads,
            keep_going: false,
            check_runs: None,
            elements: ribbon::analysis::ElementsOptions::default(),
            design: ribbon::analysis::DesignKind::Tensor,
            max_runs: ribbon::analysis::DEFAULT_MAX_RUNS,
        },
    };
    let started = Instant::now();
    let report = study
        .run(&AtomicBool::new(false), &mut |_| {}, &mut |_| Ok(()))
        .unwrap_or_else(|e| panic!("{} at d = {}: {e}", c.label(), p.d));
    let wall = started.elapsed().as_secs_f64();
    assert!(!report.partial);
    (report, wall)
}

/// [`run`], repeated up to 3 times while a run takes under 1 s: the fastest (least disturbed by other
/// processes on the machine).
fn run_best(p: &Problem, c: Config) -> (StudyReport, f64) {
    let mut best = run(p, c);
    let mut reps = 1;
    while reps < 3 && best.1 < 1.0 {
        let next = run(p, c);
        if next.1 < best.1 {
            best = next;
        }
        reps += 1;
    }
    best
}

/// Error against the reference: (max over outputs of max_t e, max over outputs of mean_t e, worst
/// output by max, per-output (name, max, mean)).
fn error(
    report: &StudyReport,
    reference: &StudyReport,
) -> (f64, f64, String, Vec<(String, f64, f64)>) {
    let (e, r) = (&report.envelope, &reference.envelope);
    assert_eq!(e.times.len(), r.times.len());
    let mut per_output = Vec::new();
    let (mut max, mut mean, mut worst) = (0.0_f64, 0.0_f64, String::new());
    for o in 0..r.outputs.len() {
        let width = r.lower[o]
            .iter()
            .zip(&r.upper[o])
            .map(|(l, u)| u - l)
            .fold(0.0_f64, f64::max);
        if width <= ZERO_WIDTH {
            continue;
        }
        let err = envelope_error(&e.lower[o], &e.upper[o], &r.lower[o], &r.upper[o])
            .expect("envelope_error");
        if err.max > max {
            max = err.max;
            worst = r.outputs[o].name.clone();
        }
        mean = mean.max(err.mean);
        per_output.push((r.outputs[o].name.clone(), err.max, err.mean));
    }
    (max, mean, worst, per_output)
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn loadavg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

fn envelope_json(report: &StudyReport) -> serde_json::Value {
    let e = &report.envelope;
    json!({
        "time": e.times,
        "outputs": e.outputs.iter().enumerate().map(|(o, out)| json!({
            "name": out.name, "unit": out.unit,
            "lower": e.lower[o], "upper": e.upper[o], "nominal": e.nominal[o],
        })).collect::<Vec<_>>(),
    })
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse.
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out_dir = std::env::var_os("ANALYSIS_OUT")
        .or_else(|| std::env::var_os("CARGO_TARGET_DIR"))
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    std::fs::create_dir_all(&out_dir).expect("create the output directory");
    let dims: Vec<usize> = std::env::var("ANALYSIS_DIMS")
        .unwrap_or_else(|_| "2,3,4".to_string())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let ref_grid = env_usize("ANALYSIS_REF_GRID", 11);
    let ref_grid_d4 = env_usize("ANALYSIS_REF_GRID_D4", ref_grid);
    let ref_1thread_max_d = env_usize("ANALYSIS_REF_1THREAD_MAX_D", 4);
    let fine_max_d = env_usize("ANALYSIS_FINE_MAX_D", 3);
    let mc_samples: Vec<usize> = std::env::var("ANALYSIS_MC")
        .unwrap_or_else(|_| "100,400,1600,6400,25600".to_string())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let bench_started = Instant::now();

    println!(
        "# ribbon analyze: method comparison on ur5 (PD-held pose, 1 s, h = 1 ms, 101 records)"
    );
    println!(
        "# machine: {} cores; loadavg at start {}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        loadavg()
    );

    // Cost of one run: 20 nominal-ish runs (Monte Carlo, 1 thread).
    {
        let p = problem(&root, 2);
        let (r, wall) = run(&p, Config::new(Method::MonteCarlo).samples(20).threads(1));
        println!(
            "# one ur5 run (1 s, 1000 steps, 1 thread): {:.2} ms ({} runs in {:.3} s; {:.2} Newton iterations per step)",
            1e3 * wall / r.runs as f64,
            r.runs,
            wall,
            r.newton_iterations as f64 / r.steps.max(1) as f64
        );
    }

    let mut rows_json = Vec::new();
    let mut threads_json = Vec::new();
    let mut summary_lines = Vec::new();
    let mut thread_lines = Vec::new();
    for &d in &dims {
        let p = problem(&root, d);
        let grid = if d >= 4 { ref_grid_d4 } else { ref_grid };
        println!();
        println!(
            "## d = {d}: parameters {:?}; outputs {}; reference scan {grid}^{d} = {} runs (loadavg {})",
            p.space.dimensions().iter().map(|x| x.name.clone()).collect::<Vec<_>>(),
            p.scene.outputs.len(),
            grid.pow(d as u32),
            loadavg()
        );
        let ref_config = Config::new(Method::Scan).grid(grid);
        let (reference, ref_wall) = run(&p, ref_config);
        let skipped: Vec<String> = reference
            .envelope
            .outputs
            .iter()
            .enumerate()
            .filter(|(o, _)| {
                reference.envelope.lower[*o]
                    .iter()
                    .zip(&reference.envelope.upper[*o])
                    .all(|(l, u)| u - l <= ZERO_WIDTH)
            })
            .map(|(_, out)| out.name.clone())
            .collect();
        println!("outputs of zero reference width (skipped): {skipped:?}");
        println!("max reference width per output:");
        for (o, out) in reference.envelope.outputs.iter().enumerate() {
            let w = reference.envelope.lower[o]
                .iter()
                .zip(&reference.envelope.upper[o])
                .map(|(l, u)| u - l)
                .fold(0.0_f64, f64::max);
            println!("  {:<26} {:>12.4e} {}", out.name, w, out.unit);
        }
        if d == 3 {
            let path = out_dir.join("ur5_d3_scan_reference.json");
            let doc = json!({
                "robot": "ur5", "method": "scan", "grid": grid, "runs": reference.runs,
                "duration_s": DURATION_S, "step_s": STEP_S,
                "parameters": p.space.dimensions().iter().map(|x| json!({
                    "name": x.name, "lower": x.lower, "upper": x.upper, "nominal": x.nominal})).collect::<Vec<_>>(),
                "sidecar": p.sidecar,
                "envelope": envelope_json(&reference),
            });
            std::fs::write(&path, serde_json::to_string(&doc).unwrap()).expect("write reference");
            println!("wrote {}", path.display());
        }

        let mut configs = vec![
            Config::new(Method::LegendreScan).order(2),
            Config::new(Method::LegendreScan).order(3),
            Config::new(Method::LegendreScan).order(4),
            Config::new(Method::LegendreIa).order(4),
            Config::new(Method::ChebyshevScan).order(4),
            Config::new(Method::Taylor),
        ];
        for &n in &mc_samples {
            configs.push(Config::new(Method::MonteCarlo).samples(n));
        }
        println!();
        println!(
            "| d | method | kind | runs | wall s | simulate s | fit+bound s | fit+bound % | err max % | err mean % | worst output |"
        );
        println!("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|");
        let row = |label: &str,
                   kind: &str,
                   r: &StudyReport,
                   wall: f64,
                   err: Option<(f64, f64, String)>| {
            let (emax, emean, worst) = err.map_or(
                ("—".to_string(), "—".to_string(), "—".to_string()),
                |(a, b, w)| (format!("{:.3}", 100.0 * a), format!("{:.3}", 100.0 * b), w),
            );
            format!(
                "| {d} | {label} | {kind} | {} | {:.3} | {:.3} | {:.4} | {:.2} | {emax} | {emean} | {worst} |",
                r.runs,
                wall,
                r.simulate_seconds,
                r.bound_seconds,
                100.0 * r.bound_seconds / wall,
            )
        };
        println!(
            "{}",
            row(&ref_config.label(), "reference", &reference, ref_wall, None)
        );
        rows_json.push(json!({
            "d": d, "method": "scan", "label": ref_config.label(), "grid": grid, "runs": reference.runs,
            "wall_s": ref_wall, "simulate_s": reference.simulate_seconds, "bound_s": reference.bound_seconds,
            "threads": reference.threads, "loadavg": loadavg(),
        }));
        let mut ls4: Option<(StudyReport, f64)> = None;
        for c in configs {
            let (r, wall) = run_best(&p, c);
            let (emax, emean, worst, per_output) = error(&r, &reference);
            println!(
                "{}",
                row(
                    &c.label(),
                    c.method.bound_kind(),
                    &r,
                    wall,
                    Some((emax, emean, worst.clone()))
                )
            );
            rows_json.push(json!({
                "d": d, "method": c.method.name(), "label": c.label(), "order": c.order,
                "samples": if c.method == Method::MonteCarlo { Some(c.samples) } else { None },
                "runs": r.runs, "wall_s": wall, "simulate_s": r.simulate_seconds,
                "bound_s": r.bound_seconds, "bound_share": r.bound_seconds / wall,
                "threads": r.threads, "error_max": emax, "error_mean": emean, "worst_output": worst,
                "per_output": per_output.iter().map(|(n, a, b)| json!({"name": n, "max": a, "mean": b})).collect::<Vec<_>>(),
                "loadavg": loadavg(),
            }));
            if c.method == Method::LegendreScan && c.order == 4 {
                ls4 = Some((r, wall));
            }
        }
        let (ls4, ls4_wall) = ls4.expect("legendre-scan k = 4 ran");
        let (ls_err, ls_mean, _, _) = error(&ls4, &reference);
        // The reference's own resolution: a 21^d scan against it, and legendre-scan against the 21^d.
        if d <= fine_max_d {
            let fine_config = Config::new(Method::Scan).grid(21);
            let (fine, fine_wall) = run(&p, fine_config);
            let (fe, fm, fw, _) = error(&fine, &reference);
            println!(
                "{}",
                row(
                    &fine_config.label(),
                    "reference (fine)",
                    &fine,
                    fine_wall,
                    Some((fe, fm, fw.clone()))
                )
            );
            let (le, lm, lw, _) = error(&ls4, &fine);
            let (re, rm, rw, _) = error(&reference, &fine);
            println!(
                "against the 21^{d} scan: legendre-scan k=4 err max {:.3} % (mean {:.3} %, worst {lw}); the {grid}^{d} reference err max {:.3} % (mean {:.3} %, worst {rw})",
                100.0 * le, 100.0 * lm, 100.0 * re, 100.0 * rm
            );
            rows_json.push(json!({
                "d": d, "method": "scan", "label": fine_config.label(), "grid": 21, "runs": fine.runs,
                "wall_s": fine_wall, "simulate_s": fine.simulate_seconds, "bound_s": fine.bound_seconds,
                "threads": fine.threads, "error_max": fe, "error_mean": fm, "worst_output": fw,
                "legendre_scan_k4_vs_fine": {"max": le, "mean": lm},
                "reference_vs_fine": {"max": re, "mean": rm}, "loadavg": loadavg(),
            }));
            if d == 3 {
                let path = out_dir.join("ur5_d3_scan21_reference.json");
                let doc = json!({"robot": "ur5", "method": "scan", "grid": 21, "runs": fine.runs,
                    "envelope": envelope_json(&fine)});
                std::fs::write(&path, serde_json::to_string(&doc).unwrap())
                    .expect("write fine reference");
            }
        }
        let runs21 = 21usize.pow(d as u32) + 1;
        summary_lines.push(format!(
            "| {d} | {} | {} | {:.1}× | {:.1}× | {:.3} | {:.3} | {:.3} | {:.2} | {:.1}× |",
            ls4.runs,
            runs21,
            runs21 as f64 / ls4.runs as f64,
            reference.runs as f64 / ls4.runs as f64,
            100.0 * ls_err,
            100.0 * ls_mean,
            ls4_wall,
            100.0 * ls4.bound_seconds / ls4_wall,
            ref_wall / ls4_wall,
        ));

        // Thread scaling: legendre-scan k = 4 (best of 3 on each count, it is short) and the reference.
        let best = |c: Config, reps: usize| -> f64 {
            (0..reps)
                .map(|_| run(&p, c).1)
                .fold(f64::INFINITY, f64::min)
        };
        let ls_1 = best(Config::new(Method::LegendreScan).threads(1), 3);
        let ls_2 = best(Config::new(Method::LegendreScan).threads(2), 3);
        thread_lines.push(format!(
            "| {d} | legendre-scan k=4 (best of 3) | {} | {ls_1:.3} | {ls_2:.3} | {:.2}× |",
            ls4.runs,
            ls_1 / ls_2
        ));
        threads_json.push(
            json!({"d": d, "method": "legendre-scan", "order": 4, "runs": ls4.runs,
            "wall_1_thread_s": ls_1, "wall_2_threads_s": ls_2}),
        );
        if d <= ref_1thread_max_d {
            let (r1, ref_1) = run(&p, ref_config.threads(1));
            thread_lines.push(format!(
                "| {d} | {} (once each) | {} | {ref_1:.3} | {ref_wall:.3} | {:.2}× |",
                ref_config.label(),
                r1.runs,
                ref_1 / ref_wall
            ));
            threads_json.push(
                json!({"d": d, "method": "scan", "grid": grid, "runs": r1.runs,
                "wall_1_thread_s": ref_1, "wall_2_threads_s": ref_wall}),
            );
        }
        println!(
            "(d = {d} done at {:.0} s; loadavg {})",
            bench_started.elapsed().as_secs_f64(),
            loadavg()
        );
    }

    println!();
    println!("## legendre-scan k = 4 against the scans");
    println!("| d | runs | runs of 21^d scan | 21^d / runs | reference / runs | err max % | err mean % | wall s | fit+bound % | reference wall / wall |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for l in &summary_lines {
        println!("{l}");
    }
    println!();
    println!("## threads (wall seconds)");
    println!("| d | method | runs | 1 thread | 2 threads | speed-up |");
    println!("|---|---|---:|---:|---:|---:|");
    for l in &thread_lines {
        println!("{l}");
    }
    println!();
    println!(
        "# total bench time {:.0} s; loadavg at end {}",
        bench_started.elapsed().as_secs_f64(),
        loadavg()
    );
    let path = out_dir.join("analysis_methods.json");
    let doc = json!({"rows": rows_json, "threads": threads_json, "total_s": bench_started.elapsed().as_secs_f64()});
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).expect("write json");
    println!("# wrote {}", path.display());
}
