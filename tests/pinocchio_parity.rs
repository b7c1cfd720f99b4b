//! Pinocchio parity: `ribbon dynamics … --json` against Pinocchio 4.1 on the same states.
//!
//! Two layers:
//! - `parity_with_committed_pinocchio_fixtures` (offline, no Python): our own robots against
//!   `tests/fixtures/pinocchio/*.json`, made by `tests/reference/pin_dynamics.py` (the command that
//!   made each file is in its `command` field; rerun it from the crate root with the reference venv
//!   when a URDF in `robots/` changes).
//! - `parity_with_live_pinocchio`: builds the reference venv (tests/common), runs the script for
//!   example-robot-data robots and ours, nominal and perturbed with `--set`, and compares.
//!
//! Per state, one ribbon process computes everything (`--q --v --tau --qdd`); the layout of the
//! coordinates is mapped by joint name from ribbon's `joints` list, never assumed. Each quantity is
//! compared with `‖a − b‖∞ / max(‖b‖∞, 1)` (a = ribbon, b = Pinocchio). A table of the worst metric
//! per robot per quantity is printed (`-- --nocapture` to see it on success) and written to
//! `<target dir>/pinocchio-parity/<test>.txt`; on a failure, the worst state's ribbon command, both
//! sides' numbers and the reference file are written beside it.

mod common;

use serde_json::{json, Value};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

/// Agreement demanded per quantity, `‖a − b‖∞ / max(‖b‖∞, 1)`. Both sides evaluate the same
/// recursive algorithms in f64 in a different order; rounding differences of a few ulps grow with
/// the depth of the tree and the conditioning of M (aba), which leaves room for 1e-12-ish
/// discrepancies but nothing near 1e-9: a wrong term, sign, frame or parameter shows at ≥ 1e-6.
const PARITY_TOLERANCE: f64 = 1e-9;

/// A `--set` perturbation must change at least one quantity by this much (same metric) relative to
/// ribbon's nominal model, or the perturbed comparison would prove nothing.
const PERTURBATION_VISIBLE: f64 = 1e-6;

/// Random states per robot in the live test (the committed fixtures hold 10).
const LIVE_STATES_PER_ROBOT: usize = 20;
const LIVE_SEED: u64 = 0;

const QUANTITIES: [&str; 5] = ["mass_matrix", "bias", "qdd", "tau", "frames"];

/// One robot of the live test: `spec` is what pin_dynamics.py takes after `--robot`.
struct Case {
    spec: &'static str,
    name: &'static str,
    floating: bool,
    sets: &'static [&'static str],
}

const LIVE_CASES: &[Case] = &[
    Case {
        spec: "erd:ur5",
        name: "ur5",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "erd:ur5",
        name: "ur5 +set",
        floating: false,
        sets: &[
            "link.forearm_link.mass=2.6",
            "link.wrist_1_link.com.y=0.01",
            "joint.elbow_joint.origin.z=0.43",
        ],
    },
    Case {
        spec: "erd:panda",
        name: "panda",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "erd:panda",
        name: "panda +set",
        floating: false,
        sets: &[
            "link.panda_link3.mass=3.5",
            "link.panda_link5.com.z=-0.05",
            "joint.panda_joint4.origin.pitch=0.1",
        ],
    },
    Case {
        spec: "erd:talos_left_arm",
        name: "talos_left_arm",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "erd:double_pendulum",
        name: "double_pendulum",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "erd:solo12",
        name: "solo12 floating",
        floating: true,
        sets: &[],
    },
    Case {
        spec: "erd:solo12",
        name: "solo12 floating +set",
        floating: true,
        sets: &[
            "link.base_link.mass=1.5",
            "link.FL_UPPER_LEG.com.x=0.01",
            "joint.FR_KFE.origin.z=-0.17",
        ],
    },
    Case {
        spec: "erd:double_pendulum_continuous",
        name: "double_pendulum_continuous",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "erd:bravo7_no_ee",
        name: "bravo7_no_ee",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "robots/ur5/ur5.urdf",
        name: "robots/ur5",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "robots/ur5/ur5.urdf",
        name: "robots/ur5 +set",
        floating: false,
        sets: &[
            "link.forearm_link.mass=2.5",
            "link.upper_arm_link.com.z=0.12",
            "joint.wrist_1_joint.origin.yaw=0.2",
        ],
    },
    Case {
        spec: "robots/double_pendulum/double_pendulum.urdf",
        name: "robots/double_pendulum",
        floating: false,
        sets: &[],
    },
    Case {
        spec: "robots/double_pendulum/double_pendulum.urdf",
        name: "robots/double_pendulum +set",
        floating: false,
        sets: &[
            "link.bar2.mass=1.2",
            "link.bar1.com.x=0.55",
            "joint.j2.origin.x=1.05",
        ],
    },
];

#[test]
fn parity_with_live_pinocchio() {
    let python = common::reference_python();
    let out_dir = common::target_dir().join("pinocchio-parity");
    let reference_file = out_dir.join("live-reference.json");
    let script = common::manifest_dir().join("tests/reference/pin_dynamics.py");
    let mut args = vec![
        script.display().to_string(),
        format!("--seed={LIVE_SEED}"),
        format!("--states={LIVE_STATES_PER_ROBOT}"),
        format!("--out={}", reference_file.display()),
    ];
    for case in LIVE_CASES {
        args.push(format!("--robot={}", case.spec));
        args.push(format!("--name={}", case.name));
        if case.floating {
            args.push("--floating".into());
        }
        for set in case.sets {
            args.push(format!("--set={set}"));
        }
    }
    common::run_checked(&python, &args, "tests/reference/pin_dynamics.py");
    let reference = read_json(&reference_file);
    assert_eq!(
        reference["robots"].as_array().map(Vec::len),
        Some(LIVE_CASES.len()),
        "{}: expected one entry per live case",
        reference_file.display()
    );
    check_references(&[(reference_file, reference)], "live");
}

#[test]
fn parity_with_committed_pinocchio_fixtures() {
    let dir = common::manifest_dir().join("tests/fixtures/pinocchio");
    let files = common::files_with_extension(&dir, "json");
    assert!(
        !files.is_empty(),
        "no Pinocchio fixtures in {}: the offline parity layer would test nothing",
        dir.display()
    );
    let mut references = Vec::new();
    for file in files {
        let reference = read_json(&file);
        for robot in reference["robots"].as_array().expect("fixture: robots") {
            let urdf = common::manifest_dir().join(robot["urdf"].as_str().expect("fixture: urdf"));
            let bytes = fs::read(&urdf).unwrap_or_else(|e| {
                panic!("{}: cannot read {}: {e}", file.display(), urdf.display())
            });
            let expected = robot["urdf_fnv1a64"]
                .as_str()
                .expect("fixture: urdf_fnv1a64");
            assert_eq!(
                common::fnv1a64(&bytes),
                expected,
                "{} changed since the fixture {} was made from it: regenerate the fixture from the crate root with\n  \
                 target/reference-venv/bin/python {}\n(the venv: run `cargo test --release --test pinocchio_parity` once)",
                urdf.display(),
                file.display(),
                command_line(&reference["command"]),
            );
        }
        references.push((file, reference));
    }
    check_references(&references, "fixtures");
}

// ----------------------------------------------------------------------------------------------

fn read_json(path: &Path) -> Value {
    let text =
        fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{} is not valid JSON: {e}", path.display()))
}

fn command_line(command: &Value) -> String {
    command
        .as_array()
        .map(|parts| {
            parts
                .iter()
                .filter_map(Value::as_str)
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
        })
        .map(|parts| common::shell_line(Path::new(&parts[0]), &parts[1..]))
        .unwrap_or_else(|| "(no command recorded)".into())
}

fn floats(value: &Value, what: &str) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("{what}: expected an array, got {value}"))
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

fn matrix(value: &Value, what: &str) -> Vec<Vec<f64>> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("{what}: expected a list of rows, got {value}"))
        .iter()
        .map(|row| floats(row, what))
        .collect()
}

/// `‖a − b‖∞ / max(‖b‖∞, 1)`; infinite when the shapes differ or `a` is not finite.
fn metric(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() || a.iter().any(|x| !x.is_finite()) {
        return f64::INFINITY;
    }
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let scale = b.iter().map(|y| y.abs()).fold(1.0, f64::max);
    diff / scale
}

/// A ribbon joint and where its coordinates sit in the reference's vectors.
struct JointMap {
    ribbon_q: usize,
    ribbon_v: usize,
    ref_q: usize,
    ref_v: usize,
    nq: usize,
    nv: usize,
}

/// Maps ribbon's coordinate layout onto the reference's by joint name.
struct Layout {
    joints: Vec<JointMap>,
    nq: usize,
    nv: usize,
    /// For each ribbon v index, the reference's v index.
    v_of_ribbon: Vec<usize>,
}

impl Layout {
    fn new(ribbon: &Value, reference_robot: &Value, label: &str) -> Result<Layout, String> {
        let nq = ribbon["nq"].as_u64().ok_or("ribbon: no nq")? as usize;
        let nv = ribbon["nv"].as_u64().ok_or("ribbon: no nv")? as usize;
        let ref_nq = reference_robot["nq"].as_u64().unwrap() as usize;
        let ref_nv = reference_robot["nv"].as_u64().unwrap() as usize;
        if (nq, nv) != (ref_nq, ref_nv) {
            return Err(format!("{label}: ribbon has nq={nq} nv={nv}, Pinocchio (ribbon convention) nq={ref_nq} nv={ref_nv}"));
        }
        let mut by_name: HashMap<&str, &Value> = HashMap::new();
        for j in reference_robot["joints"].as_array().unwrap() {
            by_name.insert(j["name"].as_str().unwrap(), j);
        }
        let field = |j: &Value, k: &str| {
            j[k].as_u64()
                .map(|x| x as usize)
                .ok_or(format!("{label}: joint {j}: no {k}"))
        };
        let mut joints = Vec::new();
        let mut seen = Vec::new();
        for j in ribbon["joints"]
            .as_array()
            .ok_or("ribbon: no joints list")?
        {
            let name = j["name"].as_str().ok_or("ribbon: joint without a name")?;
            let (jq, jv) = (field(j, "nq")?, field(j, "nv")?);
            if jq == 0 && jv == 0 {
                continue; // a fixed joint, if ribbon lists them
            }
            let r = by_name.get(name).ok_or(format!(
                "{label}: ribbon's joint {name:?} ({j}) is not a Pinocchio joint"
            ))?;
            if (field(r, "nq")?, field(r, "nv")?) != (jq, jv) {
                return Err(format!(
                    "{label}: joint {name:?}: ribbon {j}, Pinocchio (ribbon convention) {r}"
                ));
            }
            joints.push(JointMap {
                ribbon_q: field(j, "q_index")?,
                ribbon_v: field(j, "v_index")?,
                ref_q: field(r, "q_index")?,
                ref_v: field(r, "v_index")?,
                nq: jq,
                nv: jv,
            });
            seen.push(name);
        }
        let missing: Vec<&str> = by_name
            .keys()
            .copied()
            .filter(|n| !seen.contains(n))
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "{label}: Pinocchio joints missing from ribbon's joints list: {missing:?}"
            ));
        }
        let mut v_of_ribbon = vec![usize::MAX; nv];
        let mut q_covered = vec![false; nq];
        for m in &joints {
            for k in 0..m.nv {
                *v_of_ribbon
                    .get_mut(m.ribbon_v + k)
                    .ok_or(format!("{label}: ribbon v_index out of range"))? = m.ref_v + k;
            }
            for k in 0..m.nq {
                *q_covered
                    .get_mut(m.ribbon_q + k)
                    .ok_or(format!("{label}: ribbon q_index out of range"))? = true;
            }
        }
        if v_of_ribbon.contains(&usize::MAX) || q_covered.contains(&false) {
            return Err(format!(
                "{label}: ribbon's joints do not cover every coordinate: {}",
                ribbon["joints"]
            ));
        }
        Ok(Layout {
            joints,
            nq,
            nv,
            v_of_ribbon,
        })
    }

    fn q_to_ribbon(&self, q_ref: &[f64]) -> Vec<f64> {
        let mut q = vec![0.0; self.nq];
        for m in &self.joints {
            q[m.ribbon_q..m.ribbon_q + m.nq].copy_from_slice(&q_ref[m.ref_q..m.ref_q + m.nq]);
        }
        q
    }

    fn v_to_ribbon(&self, v_ref: &[f64]) -> Vec<f64> {
        self.v_of_ribbon.iter().map(|&i| v_ref[i]).collect()
    }

    fn matrix_to_ribbon(&self, m_ref: &[Vec<f64>]) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.nv * self.nv);
        for &i in &self.v_of_ribbon {
            for &j in &self.v_of_ribbon {
                out.push(m_ref[i][j]);
            }
        }
        out
    }
}

/// Ribbon's and Pinocchio's values of every quantity at one state, flattened in ribbon's order.
fn quantities(
    ribbon: &Value,
    expected: &Value,
    layout: &Layout,
    links: &[&str],
    label: &str,
) -> BTreeMap<&'static str, (Vec<f64>, Vec<f64>)> {
    let mut out = BTreeMap::new();
    let ribbon_m: Vec<f64> = matrix(
        &ribbon["mass_matrix"],
        &format!("{label}: ribbon mass_matrix"),
    )
    .into_iter()
    .flat_map(|row| {
        if row.len() == layout.nv {
            row
        } else {
            vec![f64::NAN; layout.nv]
        }
    })
    .collect();
    out.insert(
        "mass_matrix",
        (
            ribbon_m,
            layout.matrix_to_ribbon(&matrix(&expected["mass_matrix"], "reference")),
        ),
    );
    for q in ["bias", "qdd", "tau"] {
        let r = if ribbon[q].is_null() {
            vec![]
        } else {
            floats(&ribbon[q], &format!("{label}: ribbon {q}"))
        };
        out.insert(
            q,
            (r, layout.v_to_ribbon(&floats(&expected[q], "reference"))),
        );
    }
    let (mut r_frames, mut p_frames) = (Vec::new(), Vec::new());
    for link in links {
        let p = &expected["frames"][link];
        p_frames.extend(floats(&p["position"], "reference"));
        p_frames.extend(matrix(&p["rotation"], "reference").concat());
        let r = &ribbon["frames"][link];
        if r.is_null() {
            r_frames.extend([f64::NAN; 12]); // a missing frame fails the comparison
        } else {
            r_frames.extend(floats(
                &r["position"],
                &format!("{label}: ribbon frame {link}"),
            ));
            r_frames
                .extend(matrix(&r["rotation"], &format!("{label}: ribbon frame {link}")).concat());
        }
    }
    out.insert("frames", (r_frames, p_frames));
    out
}

fn dynamics_args(urdf: &Path, robot: &Value, with_sets: bool) -> Vec<String> {
    let mut args = vec!["dynamics".to_string(), urdf.display().to_string()];
    if robot["floating"].as_bool().unwrap_or(false) {
        args.push("--floating".into());
    }
    if with_sets {
        for set in robot["set"].as_array().unwrap() {
            args.push("--set".into());
            args.push(set.as_str().unwrap().to_string());
        }
    }
    args
}

/// Worst case of one quantity over a robot's states.
#[derive(Default)]
struct Worst {
    metric: f64,
    state: usize,
    ribbon_args: Vec<String>,
    ribbon: Vec<f64>,
    pinocchio: Vec<f64>,
}

fn check_references(references: &[(PathBuf, Value)], test: &str) {
    let out_dir = common::target_dir().join("pinocchio-parity");
    fs::create_dir_all(&out_dir).unwrap();
    let mut table = String::new();
    writeln!(
        table,
        "Pinocchio parity ({test}): worst ‖ribbon − pin‖∞ / max(‖pin‖∞, 1) over the states; tolerance {PARITY_TOLERANCE:e}"
    )
    .unwrap();
    writeln!(
        table,
        "{:<30} {:>6} {:>11} {:>11} {:>11} {:>11} {:>11}",
        "robot",
        "states",
        QUANTITIES[0],
        QUANTITIES[1],
        QUANTITIES[2],
        QUANTITIES[3],
        QUANTITIES[4]
    )
    .unwrap();
    let mut failures = Vec::new();
    let mut overall_states = 0;

    for (file, reference) in references {
        for robot in reference["robots"].as_array().expect("reference: robots") {
            let label = robot["name"].as_str().unwrap().to_string();
            let urdf = common::manifest_dir().join(robot["urdf"].as_str().unwrap());
            let links: Vec<&str> = robot["links"]
                .as_array()
                .unwrap()
                .iter()
                .map(|l| l.as_str().unwrap())
                .collect();
            let states = robot["states"].as_array().unwrap();
            let has_sets = !robot["set"].as_array().unwrap().is_empty();

            // First call: ribbon's coordinate layout (and its model must load with these flags).
            let mut base_args = dynamics_args(&urdf, robot, true);
            base_args.push("--json".into());
            let neutral = common::ribbon_json(&base_args);
            let layout = match Layout::new(&neutral, robot, &label) {
                Ok(layout) => layout,
                Err(e) => {
                    writeln!(table, "{label:<30} layout mismatch: {e}").unwrap();
                    failures.push(format!(
                        "{label} ({}): {e}\n  ribbon command: {}",
                        file.display(),
                        common::shell_line(&common::ribbon_bin(), &base_args)
                    ));
                    continue;
                }
            };

            let mut worst: BTreeMap<&str, Worst> =
                QUANTITIES.iter().map(|q| (*q, Worst::default())).collect();
            for (index, state) in states.iter().enumerate() {
                let q = layout.q_to_ribbon(&floats(&state["q"], "reference q"));
                let v = layout.v_to_ribbon(&floats(&state["v"], "reference v"));
                let tau = layout.v_to_ribbon(&floats(&state["tau"], "reference tau"));
                let qdd = layout.v_to_ribbon(&floats(&state["qdd"], "reference qdd"));
                let mut args = dynamics_args(&urdf, robot, true);
                args.extend([
                    format!("--q={}", common::csv(&q)),
                    format!("--v={}", common::csv(&v)),
                    format!("--tau={}", common::csv(&tau)),
                    format!("--qdd={}", common::csv(&qdd)),
                    "--json".to_string(),
                ]);
                let ribbon = common::ribbon_json(&args);
                for (name, (r, p)) in
                    quantities(&ribbon, &state["expected"], &layout, &links, &label)
                {
                    let m = metric(&r, &p);
                    let w = worst.get_mut(name).unwrap();
                    if m > w.metric || (m.is_nan() && !w.metric.is_nan()) || index == 0 {
                        *w = Worst {
                            metric: m,
                            state: index,
                            ribbon_args: args.clone(),
                            ribbon: r,
                            pinocchio: p,
                        };
                    }
                }

                // The perturbation must matter: ribbon's nominal model, same state, must disagree.
                if has_sets && index == 0 {
                    let mut nominal_args = dynamics_args(&urdf, robot, false);
                    nominal_args.extend(args[args.len() - 5..].iter().cloned());
                    let nominal = common::ribbon_json(&nominal_args);
                    let visible = quantities(&nominal, &state["expected"], &layout, &links, &label)
                        .values()
                        .map(|(r, p)| metric(r, p))
                        .fold(0.0, f64::max);
                    if visible.is_finite() && visible < PERTURBATION_VISIBLE {
                        failures.push(format!(
                            "{label}: the --set perturbations {} change nothing visible (nominal ribbon vs perturbed Pinocchio: {visible:e} < {PERTURBATION_VISIBLE:e}); \
                             the perturbed comparison proves nothing\n  ribbon command: {}",
                            robot["set"],
                            common::shell_line(&common::ribbon_bin(), &nominal_args)
                        ));
                    }
                }
            }
            overall_states += states.len();

            let cell = |q: &str| {
                let m = worst[q].metric;
                let mark = if m <= PARITY_TOLERANCE { "" } else { "!" };
                format!("{m:.2e}{mark}")
            };
            writeln!(
                table,
                "{label:<30} {:>6} {:>11} {:>11} {:>11} {:>11} {:>11}",
                states.len(),
                cell("mass_matrix"),
                cell("bias"),
                cell("qdd"),
                cell("tau"),
                cell("frames")
            )
            .unwrap();

            for (quantity, w) in &worst {
                if w.metric <= PARITY_TOLERANCE {
                    continue;
                }
                let slug: String = format!("{test}-{label}-{quantity}")
                    .chars()
                    .map(|c| {
                        if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                            c
                        } else {
                            '_'
                        }
                    })
                    .collect();
                let detail_file = out_dir.join(format!("{slug}.json"));
                let detail = json!({
                    "robot": label,
                    "quantity": quantity,
                    "metric": w.metric,
                    "state_index": w.state,
                    "reference_file": file.display().to_string(),
                    "ribbon_command": common::shell_line(&common::ribbon_bin(), &w.ribbon_args),
                    "layout": "ribbon's coordinate order; mass_matrix row-major nv×nv; frames: per link in the reference's `links` order, position then rotation rows",
                    "links": links,
                    "ribbon": w.ribbon,
                    "pinocchio": w.pinocchio,
                    "difference": w.ribbon.iter().zip(&w.pinocchio).map(|(a, b)| a - b).collect::<Vec<_>>(),
                });
                fs::write(&detail_file, serde_json::to_string_pretty(&detail).unwrap()).unwrap();
                failures.push(format!(
                    "{label} {quantity}: metric {:e} > {PARITY_TOLERANCE:e} (worst at state {} of {})\n  ribbon command: {}\n  both sides' numbers: {}",
                    w.metric,
                    w.state,
                    file.display(),
                    common::shell_line(&common::ribbon_bin(), &w.ribbon_args),
                    detail_file.display()
                ));
            }
        }
    }
    writeln!(
        table,
        "{overall_states} states, {} failures",
        failures.len()
    )
    .unwrap();
    let table_file = out_dir.join(format!("{test}.txt"));
    fs::write(&table_file, &table).unwrap();
    println!("{table}");
    assert!(overall_states > 0, "no states were compared");
    assert!(
        failures.is_empty(),
        "Pinocchio parity ({test}) failed:\n{}\n\n{table}",
        failures.join("\n")
    );
}
