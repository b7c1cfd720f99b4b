//! Issue 39, item 4: a `[bind]` value that is not finite or not possible at a sample of a study
//! is named — key, expression, symbol values — instead of surfacing as a non-finite mass matrix;
//! `simulate --set` takes the sidecar's free symbols and evaluates the `[bind]` expressions that
//! use them again. Every case spawns the binary.

mod common;

use common::{fresh_scratch_dir, ribbon_outcome, Outcome};
use std::path::{Path, PathBuf};

/// A pendulum whose bar's mass or `ixx` a `[bind]` expression of `k ∈ [-1, 1]` gives: `expression`
/// is valid at the box check's grid (k = -1, -0.5, 0, 0.5, 1) and impossible in (0.18, 0.32)
/// or (0.05, 0.45), where a scan grid of 21 points (0.2, 0.3, …) has samples. `scene` adds lines
/// to `[scene]`.
fn pendulum(
    dir: &Path,
    name: &str,
    key: &str,
    expression: &str,
    scene: &str,
) -> (PathBuf, PathBuf) {
    let urdf = dir.join(format!("{name}.urdf"));
    std::fs::write(
        &urdf,
        r#"<robot name="pend"><link name="world"/>
<link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="0.15"/>
<inertia ixx="0.0015" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.002"/></inertial></link>
<joint name="hinge" type="continuous"><parent link="world"/><child link="bar"/><axis xyz="0 0 1"/></joint></robot>
"#,
    )
    .expect("write URDF");
    let sidecar = dir.join(format!("{name}.uncertainty.toml"));
    std::fs::write(
        &sidecar,
        format!(
            "[parameters]\nk = [-1.0, 1.0]\n\n[bind]\n\"{key}\" = \"{expression}\"\n\n[scene]\nduration = 0.05\nstep = 0.001\ngravity = [0.0, -9.81, 0.0]\ninitial.q = {{ hinge = 0.5 }}\n{scene}"
        ),
    )
    .expect("write sidecar");
    (urdf, sidecar)
}

fn s(path: &Path) -> &str {
    path.to_str().expect("UTF-8 path")
}

fn scan(urdf: &Path, sidecar: &Path, extra: &[&str]) -> Outcome {
    let mut args = vec![
        "analyze",
        s(urdf),
        "--uncertainty",
        s(sidecar),
        "--method",
        "scan",
        "--grid",
        "21",
    ];
    args.extend_from_slice(extra);
    ribbon_outcome(&args)
}

#[test]
fn a_sample_with_an_impossible_bound_value_names_the_bind_key_its_expression_and_the_symbols() {
    let dir = fresh_scratch_dir("bind_failures", "samples");
    let cases = [
        (
            "nan",
            "link.bar.mass",
            "sqrt((k - 0.05) * (k - 0.45))",
            "gives NaN at k = ",
            "every parameter must be a finite number",
        ),
        (
            "negative",
            "link.bar.mass",
            "0.15 * (k - 0.05) * (k - 0.45) / 0.0225",
            "at k = ",
            "a mass must be ≥ 0",
        ),
        (
            "inertia",
            "link.bar.inertia.ixx",
            "0.002 - 0.00003 / ((k - 0.25) ^ 2 + 0.01)",
            "make the inertia of link 'bar'",
            "at k = ",
        ),
    ];
    // Samples go through the batched kernels (4 lanes) by default, one by one with the Newton
    // matrix kept across steps: both paths name the binding.
    let paths = [("batched", ""), ("scalar", "newton_matrix = \"reuse\"\n")];
    for ((name, key, expression, found, reason), (path, scene)) in cases
        .iter()
        .flat_map(|case| paths.iter().map(move |path| (*case, *path)))
    {
        let name = format!("{name}-{path}");
        let (urdf, sidecar) = pendulum(&dir, &name, key, expression, scene);
        let out = scan(&urdf, &sidecar, &[]);
        assert_eq!(out.code, Some(2), "{name}: {}", out.stderr);
        let named = format!("[bind] \"{key}\" = \"{expression}\"");
        for expected in [
            named.as_str(),
            found,
            reason,
            "narrow the symbols' intervals",
        ] {
            assert!(
                out.stderr.contains(expected),
                "{name}: no '{expected}' in: {}",
                out.stderr
            );
        }
        assert!(
            !out.stderr.contains("mass_matrix") && !out.stderr.contains("not positive definite"),
            "{name}: the integrator's words instead of the binding's: {}",
            out.stderr
        );
    }

    // With --keep-going the samples are left out, each excluded sample naming the binding.
    let (urdf, sidecar) = pendulum(
        &dir,
        "kept",
        "link.bar.mass",
        "sqrt((k - 0.05) * (k - 0.45))",
        "",
    );
    let summary = dir.join("summary.json");
    let out = scan(&urdf, &sidecar, &["--keep-going", "--summary", s(&summary)]);
    assert!(
        matches!(out.code, Some(0 | 4)),
        "{:?}: {}",
        out.code,
        out.stderr
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).expect("summary")).expect("JSON");
    let excluded = summary["excluded_samples"]
        .as_array()
        .expect("excluded samples");
    assert_eq!(
        excluded.len(),
        4,
        "k = 0.1 … 0.4 of the 21-point grid: {excluded:?}"
    );
    for sample in excluded {
        let message = sample["error"].as_str().unwrap_or_default();
        assert!(
            message.contains("[bind] \"link.bar.mass\"") && message.contains("gives NaN at k = 0."),
            "{message}"
        );
    }
}

fn simulate_csv(dir: &Path, name: &str, robot: &str, sets: &[&str]) -> Vec<u8> {
    let csv = dir.join(format!("{name}.csv"));
    let mut args = vec!["simulate", robot, "--duration", "0.2", "--csv", s(&csv)];
    for set in sets {
        args.extend(["--set", set]);
    }
    let out = ribbon_outcome(&args);
    assert_eq!(out.code, Some(0), "{sets:?}: {}", out.stderr);
    std::fs::read(&csv).expect("CSV")
}

#[test]
fn simulate_set_takes_the_sidecars_symbols() {
    let dir = fresh_scratch_dir("bind_failures", "set");
    let robot = "robots/double_pendulum/double_pendulum.urdf";
    // l2 = 2.5 writes every binding that uses l2, exactly as the four paths written by hand.
    let by_symbol = simulate_csv(&dir, "symbol", robot, &["l2=2.5"]);
    let inertia = format!("{}", 2.5 * 2.5 / 12.0);
    let by_paths = simulate_csv(
        &dir,
        "paths",
        robot,
        &[
            "joint.tip_joint.origin.x=2.5",
            "link.bar2.com.x=1.25",
            &format!("link.bar2.inertia.iyy={inertia}"),
            &format!("link.bar2.inertia.izz={inertia}"),
        ],
    );
    assert!(by_symbol == by_paths, "l2=2.5 differs from its four paths");
    let nominal = simulate_csv(&dir, "nominal", robot, &[]);
    assert!(by_symbol != nominal, "l2=2.5 changed nothing");
    // The nominal value of a symbol is the URDF's: nothing changes.
    let midpoint = simulate_csv(&dir, "midpoint", robot, &["l2=2"]);
    assert!(midpoint == nominal, "l2 at its midpoint changed the run");
    // An explicit path wins over a symbol's binding, whatever the order of the flags.
    let overridden = simulate_csv(&dir, "overridden", robot, &["link.bar2.com.x=1", "l2=2.5"]);
    let by_hand = simulate_csv(
        &dir,
        "by_hand",
        robot,
        &[
            "joint.tip_joint.origin.x=2.5",
            "link.bar2.com.x=1",
            &format!("link.bar2.inertia.iyy={inertia}"),
            &format!("link.bar2.inertia.izz={inertia}"),
        ],
    );
    assert!(overridden == by_hand, "the explicit path did not win");

    // The issue's case: the vehicle's wheel radius.
    let out = ribbon_outcome(&[
        "simulate",
        "robots/vehicle/vehicle.urdf",
        "--duration",
        "0.02",
        "--set",
        "r_wheel=0.3",
    ]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);

    // Unknown names still get the closest path or symbol.
    let out = ribbon_outcome(&["simulate", robot, "--duration", "0.2", "--set", "l3=2"]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert!(
        out.stderr
            .contains("unknown parameter 'l3'; did you mean 'l1'?"),
        "{}",
        out.stderr
    );
    let out = ribbon_outcome(&[
        "simulate",
        robot,
        "--duration",
        "0.2",
        "--set",
        "link.bar2.mas=2",
    ]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert!(
        out.stderr.contains("did you mean 'link.bar2.mass'?"),
        "{}",
        out.stderr
    );

    // A symbol value that makes a bound value impossible is refused, naming the binding.
    let (urdf, sidecar) = pendulum(
        &dir,
        "set",
        "link.bar.mass",
        "0.15 * (k - 0.05) * (k - 0.45) / 0.0225",
        "",
    );
    let out = ribbon_outcome(&[
        "simulate",
        s(&urdf),
        "--uncertainty",
        s(&sidecar),
        "--set",
        "k=0.25",
    ]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    for expected in [
        "[bind] \"link.bar.mass\" = \"0.15 * (k - 0.05) * (k - 0.45) / 0.0225\"",
        "at k = 0.25",
        "a mass must be ≥ 0",
        "give the symbols other values with --set",
    ] {
        assert!(
            out.stderr.contains(expected),
            "no '{expected}': {}",
            out.stderr
        );
    }
}

/// Issue 41: an error about one `[bind]` entry names the sidecar's line of its key
/// (`FILE:LINE: [bind] "KEY" …`): a key that is no path, a value that is no expression, an
/// expression with an unknown symbol, and a path declared in `[parameters]` too.
#[test]
fn errors_about_a_bind_entry_name_its_line() {
    let dir = fresh_scratch_dir("bind_failures", "lines");
    let urdf = common::manifest("robots/ur5/ur5.urdf");
    let head = "[parameters]\nk = [-1.0, 1.0]\n\n# bound values\n[bind]\n";
    let cases: [(&str, String, &str); 4] = [
        (
            "no_path",
            format!("{head}\"link.forearm_link.mas\" = \"2 + k\"\n"),
            "no_path.toml:6: [bind] \"link.forearm_link.mas\": ",
        ),
        (
            "no_string",
            format!("{head}\"link.forearm_link.com.x\" = \"0.1 * k\"\n\"link.forearm_link.mass\" = 2.0\n"),
            "no_string.toml:7: [bind] \"link.forearm_link.mass\" = 2.0: ",
        ),
        (
            "unknown_symbol",
            format!("{head}\n\"link.forearm_link.mass\" = \"2 + j\"\n"),
            "unknown_symbol.toml:7: [bind] \"link.forearm_link.mass\" = \"2 + j\": unknown symbol 'j'",
        ),
        (
            "twice",
            "[parameters]\n\"link.forearm_link.mass\" = { rel = 0.05 }\nk = [-1.0, 1.0]\n\n[bind]\n\"link.forearm_link.mass\" = \"2 + k\"\n".to_string(),
            "twice.toml:6: [bind] \"link.forearm_link.mass\": ",
        ),
    ];
    for (name, text, fragment) in cases {
        let sidecar = dir.join(format!("{name}.toml"));
        std::fs::write(&sidecar, text).expect("write sidecar");
        let out = ribbon_outcome(&["params", s(&urdf), "--uncertainty", s(&sidecar)]);
        assert_eq!(out.code, Some(2), "{name}: {}", out.stderr);
        assert!(
            out.stderr.contains(fragment),
            "{name}: expected '{fragment}' in: {}",
            out.stderr
        );
    }
}
