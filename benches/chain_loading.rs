//! How loading grows with the number of links (issue 39, item 3): generated serial chains of
//! 1 000, 5 000, 10 000 and 50 000 links (`support/chain.rs`: one `<inertial>` and one revolute
//! joint per link), each phase timed as the best of `--rounds R` (default 3) and the exponent `p`
//! of `time ~ n^p` fitted by least squares over the sizes (log–log). Phases:
//!
//! - `load`: `Model::from_urdf_str` (XML, description, tree, refresh, nominal checks);
//! - `params`: `params::list` and every nominal value (what `ribbon params` lists);
//! - `scene`: `Scene::resolve` of the chain sidecar (the set-up `simulate` does before its
//!   integrator; the integrator's dense `nv × nv` matrices are quadratic in storage by design);
//! - `box`: `ParameterSpace::from_sidecar` with `*` patterns over every link's mass and `ixx` and
//!   every joint's origin height (d = 3 n), with its per-link consistency check;
//! - `ribbon params`: the binary on the URDF file, end to end (process, read, print).
//!
//! Run: `cargo bench --bench chain_loading [-- --rounds R] [--sizes 1000,5000,…]`. A table, not a
//! criterion group: the point is the exponent, from one run.

#[path = "support/chain.rs"]
mod chain;

use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use ribbon::params;
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::uncertainty::ParameterSpace;
use std::hint::black_box;
use std::process::Command;
use std::time::Instant;

const PHASES: [&str; 5] = ["load", "params", "scene", "box", "ribbon params"];

fn best_of<T>(rounds: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..rounds)
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The least-squares slope of `ln t` against `ln n`.
fn exponent(sizes: &[usize], times: &[f64]) -> f64 {
    let xs: Vec<f64> = sizes.iter().map(|&n| (n as f64).ln()).collect();
    let ys: Vec<f64> = times.iter().map(|t| t.ln()).collect();
    let count = xs.len() as f64;
    let (mx, my) = (
        xs.iter().sum::<f64>() / count,
        ys.iter().sum::<f64>() / count,
    );
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    sxy / sxx
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let rounds: usize = value("--rounds").and_then(|r| r.parse().ok()).unwrap_or(3);
    let sizes: Vec<usize> = value("--sizes")
        .map(|s| s.split(',').filter_map(|n| n.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![1_000, 5_000, 10_000, 50_000]);
    let dir = std::env::temp_dir().join(format!("ribbon-chain-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let sidecar = parse_sidecar(chain::CHAIN_SIDECAR).expect("the chain sidecar parses");
    // The registry and the box read the default environment (the chain's scene sets none).
    let environment = Environment::default();

    println!("chain loading, best of {rounds} (s)");
    println!(
        "{:>8}  {}",
        "links",
        PHASES.map(|p| format!("{p:>14}")).join("")
    );
    let mut table: Vec<[f64; 5]> = Vec::new();
    for &n in &sizes {
        let text = chain::chain_urdf(n);
        let path = dir.join(format!("chain{n}.urdf"));
        std::fs::write(&path, &text).expect("write the chain");
        let load = || Model::from_urdf_str(&text, "chain.urdf", LoadOptions::default());
        let model = load().expect("the chain loads");
        assert_eq!(model.nv, n);
        let t_load = best_of(rounds, load);
        let t_params = best_of(rounds, || {
            let listed = params::list(&model, &environment);
            let sum: f64 = listed
                .iter()
                .map(|p| params::get(&model, &environment, p.target))
                .sum();
            (listed.len(), sum)
        });
        let t_scene = best_of(rounds, || {
            Scene::resolve(&sidecar, &model, "chain.toml", SceneOverrides::default())
                .expect("the scene resolves")
        });
        let t_box = best_of(rounds, || {
            let space = ParameterSpace::from_sidecar(&sidecar, &model, &environment, "chain.toml")
                .expect("the box expands");
            assert_eq!(space.len(), 3 * n);
            space
        });
        let t_cli = best_of(rounds, || {
            let out = Command::new(env!("CARGO_BIN_EXE_ribbon"))
                .arg("params")
                .arg(&path)
                .output()
                .expect("run ribbon");
            assert!(out.status.success(), "ribbon params failed");
            out.stdout.len()
        });
        let row = [t_load, t_params, t_scene, t_box, t_cli];
        println!("{n:>8}  {}", row.map(|t| format!("{t:>14.4}")).join(""));
        table.push(row);
    }
    if sizes.len() >= 2 {
        let fitted: Vec<String> = (0..PHASES.len())
            .map(|p| {
                let times: Vec<f64> = table.iter().map(|row| row[p]).collect();
                format!("{:>14.2}", exponent(&sizes, &times))
            })
            .collect();
        println!("{:>8}  {}", "n^p: p", fitted.join(""));
    }
    let _ = std::fs::remove_dir_all(&dir);
}
