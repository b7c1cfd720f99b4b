//! Criterion bench of what declared contacts cost when nothing touches (issue 13: goal ≤ 1.2×): the
//! shipped quadruped (floating base, 8 joints, 4 foot–ground pairs) falling for 0.2 s from 10 m, with
//! and without its `[scene.contact]` table, and a 1-dof ball (the worst case: the dynamics cost
//! almost nothing, so the pair tests weigh the most). Fixed step h = 1 ms. The ratio is printed
//! after the criterion groups; results in docs/contacts.md §4.
//!
//! For instruction counts (independent of machine load): `contacts once SCENE MODE` runs one
//! simulation of `SCENE` (`quadruped`, `ball`) with `MODE` (`none`, `declared`) and nothing else, e.g.
//! `valgrind --tool=callgrind target/release/deps/contacts-HASH once ball declared`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use criterion::Criterion;
use ribbon::model::{parse_description, LoadOptions, Model};
use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
use ribbon::simulate::simulate;

const BALL: &str = r#"<robot name="ball"><link name="world"/>
  <joint name="z" type="prismatic"><parent link="world"/><child link="body"/><axis xyz="0 0 1"/>
    <limit lower="-100" upper="100" effort="1" velocity="1"/></joint>
  <link name="body"><inertial><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <collision><geometry><sphere radius="0.1"/></geometry></collision></link></robot>"#;

const CONTACT_TABLE: &str = "[[scene.geometry]]\nname = \"ground\"\ntype = \"halfspace\"\n";

/// The two scenes (without, with contacts) of a robot: `scene` is the common `[scene]` text and
/// `pairs` the `[scene.contact]` table.
fn scenes(model: &Model, scene: &str, pairs: &str) -> (Scene, Scene) {
    let resolve = |text: &str| {
        Scene::resolve(
            &parse_sidecar(text).expect("bench sidecar parses"),
            model,
            "bench",
            SceneOverrides::default(),
        )
        .expect("bench scene resolves")
    };
    (
        resolve(scene),
        resolve(&format!("{scene}{pairs}{CONTACT_TABLE}")),
    )
}

fn quadruped() -> (Model, String, String) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots/quadruped/quadruped.urdf");
    let model = Model::from_urdf_file(
        &path,
        LoadOptions {
            floating_base: true,
        },
    )
    .expect("quadruped loads");
    let scene = "[scene]\nduration = 0.2\nstep = 0.001\nbase = \"floating\"\ninitial.base = { xyz = [0.0, 0.0, 10.0] }\n".to_string();
    let pairs = "[scene.contact]\npairs = [[\"foot_fl\", \"ground\"], [\"foot_fr\", \"ground\"], [\"foot_hl\", \"ground\"], [\"foot_hr\", \"ground\"]]\n".to_string();
    (model, scene, pairs)
}

fn ball() -> (Model, String, String) {
    let model = Model::from_description(
        parse_description(BALL, "ball.urdf").expect("ball parses"),
        LoadOptions::default(),
        "ball.urdf",
    )
    .expect("ball builds");
    let scene = "[scene]\nduration = 0.2\nstep = 0.001\ninitial.q = { z = 10.0 }\n".to_string();
    let pairs = "[scene.contact]\npairs = [[\"body\", \"ground\"]]\n".to_string();
    (model, scene, pairs)
}

/// Mean seconds of one run of `scene`, over `repeats` runs.
fn time_runs(model: &Model, scene: &Scene, repeats: u32) -> f64 {
    let environment = scene.environment();
    let start = Instant::now();
    for _ in 0..repeats {
        let trajectory = simulate(model.clone(), environment, scene).expect("bench run");
        std::hint::black_box(trajectory);
    }
    start.elapsed().as_secs_f64() / f64::from(repeats)
}

fn bench(c: &mut Criterion) {
    let mut ratios = Vec::new();
    for (name, (model, scene, pairs)) in [("quadruped", quadruped()), ("ball", ball())] {
        let (without, with) = scenes(&model, &scene, &pairs);
        let mut group = c.benchmark_group(format!("contacts_not_touching/{name}"));
        group.measurement_time(Duration::from_secs(3));
        group.sample_size(20);
        for (label, s) in [("none", &without), ("declared", &with)] {
            let environment = s.environment();
            group.bench_function(label, |b| {
                b.iter(|| simulate(model.clone(), environment, s).expect("bench run"))
            });
        }
        group.finish();
        // Interleaved repeats for the ratio, so that machine load hits both alike.
        let (mut t_without, mut t_with) = (0.0, 0.0);
        for _ in 0..5 {
            t_without += time_runs(&model, &without, 20);
            t_with += time_runs(&model, &with, 20);
        }
        ratios.push((name, t_with / t_without));
    }
    for (name, ratio) in ratios {
        println!("contacts declared but never touching / none, {name}: {ratio:.3}x");
    }
}

/// `once SCENE MODE`: one run, for callgrind; a bad argument gets a message and exit 2.
fn run_once(args: &[String]) {
    let usage = "usage: contacts once quadruped|ball none|declared";
    let (model, scene, pairs) = match args.first().map(String::as_str) {
        Some("quadruped") => quadruped(),
        Some("ball") => ball(),
        _ => {
            eprintln!("contacts: {usage}");
            std::process::exit(2);
        }
    };
    let (without, with) = scenes(&model, &scene, &pairs);
    let chosen = match args.get(1).map(String::as_str) {
        Some("none") => without,
        Some("declared") => with,
        _ => {
            eprintln!("contacts: {usage}");
            std::process::exit(2);
        }
    };
    let seconds = time_runs(&model, &chosen, 1);
    println!("one run: {seconds:.6} s");
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    if args.first().map(String::as_str) == Some("once") {
        run_once(&args[1..]);
        return;
    }
    let mut criterion = Criterion::default().configure_from_args();
    bench(&mut criterion);
    criterion.final_summary();
}
