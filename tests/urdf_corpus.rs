//! The URDF corpus: every file under `tests/urdf_corpus/` (public robot descriptions, sources and
//! licences in `tests/urdf_corpus/SOURCES.md`), loaded with a fixed and with a floating base, against
//! Pinocchio 4.1 live.
//!
//! For each file and base, one of:
//! - Pinocchio loads it and so does ribbon: dynamics parity at a few random states — mass matrix,
//!   bias, forward dynamics, inverse dynamics and every link's world placement — with
//!   `‖a − b‖∞ / max(‖b‖∞, 1) ≤ PARITY_TOLERANCE` (a = ribbon, b = Pinocchio); where Pinocchio's
//!   `aba` is not finite (a singular mass matrix), ribbon must refuse forward dynamics naming the
//!   cause ([`SINGULAR`]);
//! - ribbon refuses it: only with a message that starts `FILE:LINE:` and names the element, and only
//!   where [`REFUSALS`] says so — together with what Pinocchio says, so the table below is the
//!   record of every file either tool refuses;
//! - notes ([`NOTES`]): files that load with a note about markup that does not affect dynamics.
//!
//! One Python process (`tests/reference/pin_corpus.py`) computes Pinocchio's side for the whole
//! corpus; ribbon runs in this process through the library. A table of the worst metric per file is
//! printed (`-- --nocapture`) and written to `<target dir>/urdf-corpus/report.txt`.

mod common;

use ribbon::dynamics::{
    crba, forward_dynamics, forward_kinematics, nonlinear_effects, rnea, world_from_link, Data,
    DynamicsError,
};
use ribbon::model::{LoadOptions, Model};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

/// Agreement demanded per quantity (the same as tests/pinocchio_parity.rs, and for the same
/// reason: both sides run the same recursive algorithms in f64 in a different order; a wrong term,
/// frame or parameter shows at ≥ 1e-6).
const PARITY_TOLERANCE: f64 = 1e-9;

/// Pinocchio's mass matrix with its smallest eigenvalue below this fraction of its largest is
/// singular to working precision: forward dynamics there amplify round-off by ≥ 1e10, so neither
/// side's `aba` means anything. ribbon may refuse such a state (its Cholesky pivot tolerance,
/// `RELATIVE_PIVOT_TOLERANCE` = 1e-13 of the largest diagonal entry, decides) — then with the
/// explanation listed in [`SINGULAR`] — and must not refuse any other state.
const NEAR_SINGULAR_EIGENVALUE_RATIO: f64 = 1e-10;

/// Random states per file and base (Pinocchio's side; each is one crba, nle, aba, rnea and one
/// forward kinematics per tool).
const STATES: usize = 3;
const SEED: u64 = 0;

/// The corpus must stay a corpus: at least this many files from at least [`MIN_SOURCES`]
/// repositories (the first path component under `tests/urdf_corpus/`).
const MIN_FILES: usize = 50;
const MIN_SOURCES: usize = 4;

/// Files ribbon refuses (with a fixed and a floating base alike), with the start of ribbon's
/// message after `FILE:` and whether Pinocchio refuses the file too.
const REFUSALS: &[(&str, &str, Pinocchio)] = &[
    (
        "bullet3/bicycle/bike.urdf",
        "103: joint 'handlebar_to_frontwheel' <origin>: xyz=\"0.07, 0, -0.69\" is not three numbers",
        Pinocchio::Refuses,
    ),
    (
        "bullet3/biped/biped2d_pybullet.urdf",
        "115: joint 'torso_to_rightleg' <limit>: lower=\"-1.57.\" is not a number",
        Pinocchio::Refuses,
    ),
    (
        // Also ends in a NUL byte (a note): the joint type is the refusal, for both tools.
        "bullet3/humanoid/humanoid.urdf",
        "40: joint 'chest' has type 'spherical', which is not a URDF joint type",
        Pinocchio::Refuses,
    ),
    (
        // Unexpanded xacro: $(optenv …), refused as xacro with the command (docs/ros.md §1).
        "bullet3/husky/husky.urdf",
        "97: this is a xacro file, not a URDF (<origin rpy=\"$(optenv HUSKY_IMU_RPY 0 -1.5708 3.1416)\">); ribbon reads URDF only\n  expand it with xacro, then run ribbon on husky.expanded.urdf:",
        Pinocchio::Refuses,
    ),
    (
        "bullet3/quadruped/microtaur/microtaur.urdf",
        "300: joint 'dynamixel7_chassis_left' <origin>: rpy=\"-3.14159 1.57079 0 0\" is not three numbers",
        Pinocchio::Refuses,
    ),
    (
        "bullet3/spherical_joint_limit.urdf",
        "28: joint 'neck' has type 'spherical', which is not a URDF joint type",
        Pinocchio::Refuses,
    ),
    (
        // A deformable body (<deformable>), not a robot.
        "bullet3/torus_deform.urdf",
        "2: robot 'torus' has no <link> element",
        Pinocchio::Refuses,
    ),
    (
        "robot_properties_fingers/edu/trifingeredu_stage.urdf",
        "50: joint 'base_to_table' names parent link 'base_link', which the file does not define; did you mean 'table_link'?",
        Pinocchio::Refuses,
    ),
    (
        // A xacro-style macro file with no robot name (a note) and no link.
        "robot_properties_fingers/finger_macro.urdf",
        "6: robot 'finger_macro' has no <link> element",
        Pinocchio::Refuses,
    ),
    (
        "robot_properties_fingers/trifinger_stage.urdf",
        "53: joint 'base_to_table' names parent link 'base_link', which the file does not define; did you mean 'table_link'?",
        Pinocchio::Refuses,
    ),
];

/// Files whose mass matrix (with a floating base) is singular: ribbon's forward dynamics must say
/// why, with this text (the pivot fails at a child joint; the cause is the root).
const SINGULAR: &[(&str, &str)] = &[
    (
        "bullet3/cartpole.urdf",
        "joint 'slider_to_cart'): link 'slideBar' (on the floating joint 'root_joint') has no mass: joints 'root_joint', 'slider_to_cart' can move it while every body with inertia stays at rest",
    ),
    (
        "bullet3/differential/diff_ring.urdf",
        "link 'world' (on the floating joint 'root_joint') has no mass or inertia: joints 'root_joint', 'diff_ring_world' can move it",
    ),
    (
        "bullet3/pendulum5.urdf",
        "link 'world' (on the floating joint 'root_joint') has no mass or inertia: joints 'root_joint', 'joint0' can move it",
    ),
    (
        "bullet3/plane_implicit.urdf",
        "link 'planeLink' (on the floating joint 'root_joint') has no mass or inertia: joint 'root_joint' can move it",
    ),
    (
        "bullet3/toys/concave_box.urdf",
        "link 'base_link' (on the floating joint 'root_joint') has no mass: joint 'root_joint' can move it",
    ),
];

/// Notes that loading must give (the start of the note after `FILE:`), fixed base.
const NOTES: &[(&str, &str)] = &[
    (
        "bullet3/differential/diff_ring.urdf",
        "2: whitespace before the XML declaration <?xml …?>",
    ),
    (
        "bullet3/plane_implicit.urdf",
        "21: link 'planeLink' <collision>: unknown shape <plane> (line 25)",
    ),
    (
        "bullet3/quadruped/spirit40newer.urdf",
        "550: joint 'RL_lower_joint' repeats <axis> identically (first at line 546)",
    ),
    (
        "bullet3/racecar/racecar.urdf",
        "280: link 'laser' <visual>: <geometry> holds more than one element (<material> at line 284)",
    ),
    (
        "bullet3/racecar/racecar_differential.urdf",
        "13: link 'chassis' <visual>: <mesh scale=\"1 1 1 1\"> (line 16) is not three numbers",
    ),
    (
        "bullet3/toys/concave_box.urdf",
        "22: link 'base_link' <collision>: unknown shape <cdf> (line 25)",
    ),
];

/// What Pinocchio does with a file ribbon refuses.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Pinocchio {
    Refuses,
    Loads,
}

const QUANTITIES: [&str; 5] = ["mass_matrix", "bias", "qdd", "tau", "frames"];

fn corpus_dir() -> PathBuf {
    common::manifest_dir().join("tests/urdf_corpus")
}

#[test]
fn every_corpus_urdf_loads_as_in_pinocchio_or_is_refused_with_file_line_and_element() {
    let dir = corpus_dir();
    let files = common::files_with_extension(&dir, "urdf");
    let relative: Vec<String> = files
        .iter()
        .map(|f| f.strip_prefix(&dir).unwrap().display().to_string())
        .collect();
    let sources: BTreeSet<&str> = relative
        .iter()
        .map(|r| r.split('/').next().unwrap())
        .collect();
    assert!(
        relative.len() >= MIN_FILES && sources.len() >= MIN_SOURCES,
        "the corpus has {} files from {} sources ({sources:?}); it must keep ≥ {MIN_FILES} from ≥ {MIN_SOURCES}",
        relative.len(),
        sources.len()
    );
    check_sources_list(&relative);

    let reference = pinocchio_reference();
    let entries = reference["files"].as_array().expect("reference: files");
    assert_eq!(
        entries.len(),
        2 * relative.len(),
        "one reference entry per file and base"
    );

    let mut report = Report::default();
    for entry in entries {
        check_entry(entry, &dir, &mut report);
    }
    for (file, _, _) in REFUSALS {
        if !report.refused.contains(*file) {
            report.failures.push(format!(
                "{file}: listed in REFUSALS, but ribbon loads it (or it left the corpus): update the table"
            ));
        }
    }
    for (file, _) in SINGULAR {
        if !report.singular.contains(*file) {
            report.failures.push(format!(
                "{file}: listed in SINGULAR, but its floating-base mass matrix was not found singular: update the table"
            ));
        }
    }

    let text = report.render(relative.len());
    let out_dir = common::target_dir().join("urdf-corpus");
    fs::create_dir_all(&out_dir).unwrap();
    fs::write(out_dir.join("report.txt"), &text).unwrap();
    println!("{text}");
    assert!(
        report.failures.is_empty(),
        "URDF corpus: {} failure(s):\n{}\n\n{text}",
        report.failures.len(),
        report.failures.join("\n")
    );
}

/// Every corpus file appears in SOURCES.md (as a `| path |` table cell) and every listed file exists.
fn check_sources_list(relative: &[String]) {
    let path = corpus_dir().join("SOURCES.md");
    let text =
        fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let listed: BTreeSet<String> = text
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split('`').next())
        .filter(|p| p.ends_with(".urdf"))
        .map(str::to_string)
        .collect();
    let present: BTreeSet<String> = relative.iter().cloned().collect();
    let unlisted: Vec<&String> = present.difference(&listed).collect();
    let missing: Vec<&String> = listed.difference(&present).collect();
    assert!(
        unlisted.is_empty() && missing.is_empty(),
        "{}: every corpus file needs a row with its source and licence; not listed: {unlisted:?}; listed but absent: {missing:?}",
        path.display()
    );
}

fn pinocchio_reference() -> Value {
    let python = common::reference_python();
    let out = common::target_dir().join("urdf-corpus/reference.json");
    let script = common::manifest_dir().join("tests/reference/pin_corpus.py");
    let args = vec![
        script.display().to_string(),
        format!("--corpus={}", corpus_dir().display()),
        format!("--states={STATES}"),
        format!("--seed={SEED}"),
        format!("--out={}", out.display()),
    ];
    common::run_checked(&python, &args, "tests/reference/pin_corpus.py");
    let text =
        fs::read_to_string(&out).unwrap_or_else(|e| panic!("cannot read {}: {e}", out.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", out.display()))
}

#[derive(Default)]
struct Report {
    /// One line per file and base.
    rows: Vec<String>,
    failures: Vec<String>,
    refused: BTreeSet<String>,
    singular: BTreeSet<String>,
    compared: usize,
    states: usize,
    worst: f64,
}

impl Report {
    fn render(&self, files: usize) -> String {
        let mut text = String::new();
        writeln!(
            text,
            "URDF corpus: {files} files × 2 bases; {} models compared with Pinocchio at {} states (worst metric {:.2e}, tolerance {PARITY_TOLERANCE:e}); {} refused by ribbon; {} failures",
            self.compared,
            self.states,
            self.worst,
            self.refused.len(),
            self.failures.len()
        )
        .unwrap();
        writeln!(
            text,
            "{:<58} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9}  notes",
            "file (base)",
            "nv",
            QUANTITIES[0],
            QUANTITIES[1],
            QUANTITIES[2],
            QUANTITIES[3],
            QUANTITIES[4]
        )
        .unwrap();
        for row in &self.rows {
            writeln!(text, "{row}").unwrap();
        }
        text
    }
}

fn expected_refusal(file: &str) -> Option<(&'static str, Pinocchio)> {
    REFUSALS
        .iter()
        .find(|(f, _, _)| *f == file)
        .map(|(_, message, pinocchio)| (*message, *pinocchio))
}

fn check_entry(entry: &Value, dir: &Path, report: &mut Report) {
    let file = entry["file"].as_str().expect("reference: file");
    let floating = entry["floating"].as_bool().expect("reference: floating");
    let label = format!("{file} ({})", if floating { "floating" } else { "fixed" });
    let path = dir.join(file);
    let shown = path.display().to_string();
    let pinocchio_loads = entry["loaded"].as_bool().expect("reference: loaded");
    let pinocchio_says = entry["message"].as_str().unwrap_or("");
    let urdfdom: Vec<&str> = entry["urdfdom_printed"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();

    let loaded = Model::from_urdf_file(
        &path,
        LoadOptions {
            floating_base: floating,
        },
    );
    let model = match loaded {
        Err(error) => {
            let message = error.to_string();
            report.refused.insert(file.to_string());
            let pinocchio = if pinocchio_loads {
                Pinocchio::Loads
            } else {
                Pinocchio::Refuses
            };
            let located = message
                .strip_prefix(&shown)
                .and_then(|rest| rest.strip_prefix(':'))
                .and_then(|rest| rest.split(':').next())
                .is_some_and(|line| !line.is_empty() && line.chars().all(|c| c.is_ascii_digit()));
            if !located {
                report.failures.push(format!(
                    "{label}: ribbon's refusal does not start with FILE:LINE: — {message}"
                ));
            }
            let after_file = message
                .strip_prefix(&format!("{shown}:"))
                .unwrap_or(&message);
            match expected_refusal(file) {
                Some((expected, expected_pinocchio)) => {
                    if !after_file.starts_with(expected) {
                        report.failures.push(format!(
                            "{label}: ribbon refuses with\n    {after_file}\n  REFUSALS expects\n    {expected}"
                        ));
                    }
                    if expected_pinocchio != pinocchio {
                        report.failures.push(format!(
                            "{label}: REFUSALS says Pinocchio {expected_pinocchio:?} it, but Pinocchio {pinocchio:?} it ({pinocchio_says} {urdfdom:?})"
                        ));
                    }
                }
                None => report.failures.push(format!(
                    "{label}: ribbon refuses a file not listed in REFUSALS (Pinocchio {pinocchio:?} it: {pinocchio_says} {urdfdom:?}):\n    {after_file}"
                )),
            }
            report.rows.push(format!(
                "{label:<58} refused by ribbon: {after_file}\n{:<58} Pinocchio: {}",
                "",
                if pinocchio_loads {
                    "loads it".to_string()
                } else {
                    format!(
                        "refuses ({})",
                        urdfdom.first().copied().unwrap_or(pinocchio_says)
                    )
                }
            ));
            return;
        }
        Ok(model) => model,
    };
    if let Some((expected, _)) = expected_refusal(file) {
        report.failures.push(format!(
            "{label}: REFUSALS expects a refusal ({expected}), but ribbon loads it"
        ));
    }
    if !floating {
        for (_, note) in NOTES.iter().filter(|(f, _)| *f == file) {
            let wanted = format!("{shown}:{note}");
            if !model.warnings.iter().any(|w| w.starts_with(&wanted)) {
                report.failures.push(format!(
                    "{label}: expected the note\n    {wanted}\n  got {:#?}",
                    model.warnings
                ));
            }
        }
    }
    if !pinocchio_loads {
        report.rows.push(format!(
            "{label:<58} loaded by ribbon; Pinocchio refuses ({})",
            urdfdom.first().copied().unwrap_or(pinocchio_says)
        ));
        return;
    }
    if let Some(reason) = entry["ribbon_conversion"].as_str() {
        report
            .failures
            .push(format!("{label}: ribbon loads it, but {reason}"));
        return;
    }
    compare_dynamics(entry, &model, &label, file, floating, report);
}

/// Where a ribbon coordinate sits in the reference's vectors.
struct Layout {
    /// (ribbon q index, reference q index, nq) per joint.
    q: Vec<(usize, usize, usize)>,
    /// Reference v index of each ribbon v index.
    v_of_ribbon: Vec<usize>,
}

fn layout(entry: &Value, model: &Model) -> Result<Layout, String> {
    let nv = entry["nv"].as_u64().ok_or("reference: nv")? as usize;
    let nq = entry["nq"].as_u64().ok_or("reference: nq")? as usize;
    if (model.nq, model.nv) != (nq, nv) {
        return Err(format!(
            "ribbon nq={} nv={}, Pinocchio (ribbon convention) nq={nq} nv={nv}",
            model.nq, model.nv
        ));
    }
    let by_name: HashMap<&str, &Value> = entry["joints"]
        .as_array()
        .ok_or("reference: joints")?
        .iter()
        .filter_map(|j| Some((j["name"].as_str()?, j)))
        .collect();
    if by_name.len() != model.joints.len() {
        return Err(format!(
            "ribbon has {} moving joints, Pinocchio {}",
            model.joints.len(),
            by_name.len()
        ));
    }
    let mut q = Vec::new();
    let mut v_of_ribbon = vec![usize::MAX; model.nv];
    for joint in &model.joints {
        let r = by_name.get(joint.name.as_str()).ok_or(format!(
            "ribbon's joint '{}' is not a Pinocchio joint",
            joint.name
        ))?;
        let field = |k: &str| {
            r[k].as_u64()
                .map(|x| x as usize)
                .ok_or(format!("reference joint {r}: {k}"))
        };
        if (field("nq")?, field("nv")?) != (joint.nq(), joint.nv()) {
            return Err(format!(
                "joint '{}': ribbon nq={} nv={}, reference {r}",
                joint.name,
                joint.nq(),
                joint.nv()
            ));
        }
        q.push((joint.q_index, field("q_index")?, joint.nq()));
        for k in 0..joint.nv() {
            v_of_ribbon[joint.v_index + k] = field("v_index")? + k;
        }
    }
    Ok(Layout { q, v_of_ribbon })
}

fn floats(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
        .unwrap_or_default()
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
    diff / b.iter().map(|y| y.abs()).fold(1.0, f64::max)
}

fn compare_dynamics(
    entry: &Value,
    model: &Model,
    label: &str,
    file: &str,
    floating: bool,
    report: &mut Report,
) {
    let layout = match layout(entry, model) {
        Ok(layout) => layout,
        Err(e) => {
            report
                .failures
                .push(format!("{label}: layout mismatch: {e}"));
            return;
        }
    };
    let to_ribbon_q = |q_ref: &[f64]| {
        let mut q = vec![0.0; model.nq];
        for &(r, p, n) in &layout.q {
            q[r..r + n].copy_from_slice(&q_ref[p..p + n]);
        }
        q
    };
    let to_ribbon_v = |v_ref: &[f64]| {
        layout
            .v_of_ribbon
            .iter()
            .map(|&i| v_ref[i])
            .collect::<Vec<f64>>()
    };
    let mut worst: BTreeMap<&str, f64> = QUANTITIES.iter().map(|q| (*q, 0.0)).collect();
    let mut data = Data::new(model);
    // Pinocchio's model gravity, the default one: (0, 0, −9.81) m/s².
    let gravity = ribbon::spatial::Vec3::from(ribbon::environment::DEFAULT_GRAVITY);
    let mut singular_message = None;
    let mut near_singular_accepted = 0;
    let links: Vec<&str> = entry["links"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    let states = entry["states"].as_array().map_or(&[][..], Vec::as_slice);
    for state in states {
        let expected = &state["expected"];
        let q = to_ribbon_q(&floats(&state["q"]));
        let v = to_ribbon_v(&floats(&state["v"]));
        let tau = to_ribbon_v(&floats(&state["tau"]));
        let qdd = to_ribbon_v(&floats(&state["qdd"]));

        let reference_m: Vec<Vec<f64>> = expected["mass_matrix"]
            .as_array()
            .map(|rows| rows.iter().map(floats).collect())
            .unwrap_or_default();
        let mut m_ref = Vec::with_capacity(model.nv * model.nv);
        for &i in &layout.v_of_ribbon {
            for &j in &layout.v_of_ribbon {
                m_ref.push(reference_m[i][j]);
            }
        }
        let m: Vec<f64> = crba(model, &mut data, &q)
            .transpose()
            .iter()
            .copied()
            .collect();
        let mut record = |quantity: &'static str, value: f64| {
            let w = worst.get_mut(quantity).unwrap();
            if value > *w || value.is_nan() {
                *w = value;
            }
        };
        record("mass_matrix", metric(&m, &m_ref));
        let bias = nonlinear_effects(model, &gravity, &mut data, &q, &v).to_vec();
        record(
            "bias",
            metric(&bias, &to_ribbon_v(&floats(&expected["bias"]))),
        );
        let ratio = state["mass_matrix_eigenvalue_ratio"]
            .as_f64()
            .unwrap_or(1.0);
        let near_singular = ratio <= NEAR_SINGULAR_EIGENVALUE_RATIO || expected["qdd"].is_null();
        match forward_dynamics(model, &gravity, &mut data, &q, &v, &tau) {
            Ok(a) if !near_singular => {
                record("qdd", metric(a, &to_ribbon_v(&floats(&expected["qdd"]))));
            }
            Ok(_) if expected["qdd"].is_null() => report.failures.push(format!(
                "{label}: Pinocchio's aba is not finite (singular mass matrix), but ribbon's forward dynamics succeeded"
            )),
            Ok(_) => near_singular_accepted += 1,
            Err(e @ DynamicsError::SingularMassMatrix { .. }) if near_singular => {
                singular_message = Some(e.to_string());
            }
            Err(e) => report.failures.push(format!(
                "{label}: ribbon's forward dynamics failed where Pinocchio's mass matrix has eigenvalue ratio {ratio:e}: {e}"
            )),
        }
        let tau_out = rnea(model, &gravity, &mut data, &q, &v, &qdd).to_vec();
        record(
            "tau",
            metric(&tau_out, &to_ribbon_v(&floats(&expected["tau"]))),
        );
        forward_kinematics(model, &mut data, &q);
        let (mut ours, mut theirs) = (Vec::new(), Vec::new());
        for link in &links {
            let placement = &expected["frames"][*link];
            theirs.extend(floats(&placement["position"]));
            theirs.extend(
                placement["rotation"]
                    .as_array()
                    .map(|rows| rows.iter().flat_map(floats).collect::<Vec<_>>())
                    .unwrap_or_default(),
            );
            match model.description.link_index(link) {
                Some(l) => {
                    let t = world_from_link(model, &data, l);
                    ours.extend(t.translation.iter());
                    ours.extend(t.rotation.transpose().iter()); // row-major
                }
                None => ours.extend([f64::NAN; 12]),
            }
        }
        record("frames", metric(&ours, &theirs));
    }
    report.compared += 1;
    report.states += states.len();
    let mut notes = Vec::new();
    if let Some(message) = &singular_message {
        report.singular.insert(file.to_string());
        match SINGULAR.iter().find(|(f, _)| *f == file) {
            Some((_, expected)) if message.contains(expected) => {}
            Some((_, expected)) => report.failures.push(format!(
                "{label}: singular mass matrix explained as\n    {message}\n  SINGULAR expects\n    {expected}"
            )),
            None => report.failures.push(format!(
                "{label}: singular mass matrix (Pinocchio's aba not finite) not listed in SINGULAR: {message}"
            )),
        }
        notes.push("singular M: aba not compared".to_string());
    }
    if near_singular_accepted > 0 {
        notes.push(format!(
            "{near_singular_accepted} near-singular state(s): aba not compared"
        ));
    }
    if !floating && !model.warnings.is_empty() {
        notes.push(format!("{} warning(s)", model.warnings.len()));
    }
    for (quantity, value) in &worst {
        if value.is_nan() || *value > PARITY_TOLERANCE {
            report.failures.push(format!(
                "{label}: {quantity}: metric {value:e} > {PARITY_TOLERANCE:e}"
            ));
        }
        if value.is_finite() {
            report.worst = report.worst.max(*value);
        }
    }
    let cell = |q: &str| format!("{:.1e}", worst[q]);
    report.rows.push(format!(
        "{label:<58} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9}  {}",
        model.nv,
        cell("mass_matrix"),
        cell("bias"),
        cell("qdd"),
        cell("tau"),
        cell("frames"),
        notes.join("; ")
    ));
}
