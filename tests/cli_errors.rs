//! End-to-end: bad input gets a clear error naming file, element and value, and exit code 2 — never a
//! panic. Each case spawns the binary.

mod common;

use common::{ribbon_outcome, Outcome};

use std::path::PathBuf;

/// Writes a URDF into a fresh temporary directory under target/ and returns its path.
fn temp_urdf(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_errors");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write temp urdf");
    path
}

fn assert_input_error(outcome: &Outcome, fragments: &[&str]) {
    assert_eq!(
        outcome.code,
        Some(2),
        "exit code; stderr: {}",
        outcome.stderr
    );
    assert!(
        outcome.stdout.is_empty(),
        "nothing on stdout: {}",
        outcome.stdout
    );
    for fragment in fragments {
        assert!(
            outcome.stderr.contains(fragment),
            "expected '{fragment}' in: {}",
            outcome.stderr
        );
    }
}

const ARM: &str = r#"<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0.5 0 0"/><mass value="MASS"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="PARENT"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
</robot>
"#;

fn arm(mass: &str, parent: &str) -> String {
    ARM.replace("MASS", mass).replace("PARENT", parent)
}

#[test]
fn malformed_xml_names_file_and_line() {
    let path = temp_urdf(
        "malformed.urdf",
        "<robot name=\"x\">\n  <link name=\"a\">\n</robot>\n",
    );
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(&out, &["malformed.urdf:3:", "malformed XML"]);
}

#[test]
fn missing_file_is_reported() {
    let out = ribbon_outcome(&["params", "robots/does_not_exist.urdf"]);
    assert_input_error(&out, &["cannot read 'robots/does_not_exist.urdf'"]);
}

#[test]
fn joint_naming_missing_link() {
    let path = temp_urdf("missing_link.urdf", &arm("1", "bse"));
    let out = ribbon_outcome(&["dynamics", path.to_str().unwrap()]);
    assert_input_error(
        &out,
        &[
            "missing_link.urdf:6:",
            "joint 'shoulder' names parent link 'bse'",
            "did you mean 'base'",
        ],
    );
}

#[test]
fn cycle_is_refused() {
    let text = r#"<robot name="c"><link name="a"/><link name="b"/>
      <joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
      <joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#;
    let path = temp_urdf("cycle.urdf", text);
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(&out, &["cycle.urdf", "form a cycle", "[[scene.loop]]"]);
}

#[test]
fn negative_mass_is_refused() {
    let path = temp_urdf("negative_mass.urdf", &arm("-2.5", "base"));
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(
        &out,
        &[
            "negative_mass.urdf:4:",
            "link 'upper' has negative mass -2.5 kg",
        ],
    );
}

#[test]
fn non_finite_value_is_refused() {
    let path = temp_urdf("nan.urdf", &arm("NaN", "base"));
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(
        &out,
        &["nan.urdf:4:", "link 'upper'", "non-finite value NaN"],
    );
    let path = temp_urdf("inf.urdf", &arm("1", "base").replace("0.5 0 0", "inf 0 0"));
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(
        &out,
        &["inf.urdf:4:", "non-finite value inf in <inertial><origin>"],
    );
}

#[test]
fn unknown_parameter_suggests_closest() {
    let out = ribbon_outcome(&[
        "dynamics",
        "robots/ur5/ur5.urdf",
        "--set",
        "link.forarm_link.mass=2.4",
    ]);
    assert_input_error(
        &out,
        &[
            "unknown parameter 'link.forarm_link.mass'",
            "did you mean 'link.forearm_link.mass'",
        ],
    );
    let out = ribbon_outcome(&[
        "dynamics",
        "robots/ur5/ur5.urdf",
        "--set=link.forearm_link.mass=-1",
    ]);
    assert_input_error(
        &out,
        &["'link.forearm_link.mass' cannot be -1", "mass must be ≥ 0"],
    );
}

#[test]
fn vector_of_wrong_length() {
    let out = ribbon_outcome(&["dynamics", "robots/ur5/ur5.urdf", "--q=0.1,0.2"]);
    assert_input_error(
        &out,
        &[
            "--q: expected 6 comma-separated numbers",
            "shoulder_pan_joint",
            "got 2",
        ],
    );
    let out = ribbon_outcome(&[
        "dynamics",
        "robots/double_pendulum/double_pendulum.urdf",
        "--v=1,abc",
    ]);
    assert_input_error(&out, &["--v: element 2 ('abc') is not a number"]);
}

#[test]
fn non_unit_quaternion_is_refused_and_near_unit_is_normalised() {
    let base = "--q=0,0,0,0,0,0,0.9,0,0,0,0,0,0";
    let out = ribbon_outcome(&["dynamics", "robots/ur5/ur5.urdf", "--floating", base]);
    assert_input_error(
        &out,
        &[
            "--q: the quaternion of 'root_joint'",
            "has norm 0.9",
            "unit quaternion",
        ],
    );
    let near = "--q=0,0,0,0,0,0,1.0000001,0,0,0,0,0,0";
    let out = ribbon_outcome(&[
        "dynamics",
        "robots/ur5/ur5.urdf",
        "--floating",
        near,
        "--json",
    ]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
}

#[test]
fn planar_joint_is_not_supported_yet() {
    let path = temp_urdf(
        "planar.urdf",
        &arm("1", "base").replace("type=\"revolute\"", "type=\"planar\""),
    );
    let out = ribbon_outcome(&["params", path.to_str().unwrap()]);
    assert_input_error(
        &out,
        &[
            "planar.urdf:6:",
            "joint 'shoulder' is of type 'planar'",
            "not support yet",
        ],
    );
}

#[test]
fn singular_mass_matrix_is_a_clear_error() {
    let text = r#"<robot name="s"><link name="a"/><link name="b"/>
      <joint name="massless" type="continuous"><parent link="a"/><child link="b"/></joint></robot>"#;
    let path = temp_urdf("singular.urdf", text);
    let out = ribbon_outcome(&["dynamics", path.to_str().unwrap(), "--tau=1"]);
    assert_input_error(&out, &["mass matrix is singular", "joint 'massless'"]);
    assert!(
        out.stderr.contains("warning:") && out.stderr.contains("no mass and no inertia"),
        "{}",
        out.stderr
    );
}

#[test]
fn usage_errors_exit_2() {
    let out = ribbon_outcome(&["dynamics"]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    let out = ribbon_outcome(&["frobnicate"]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
}

#[test]
fn bad_scene_input_is_refused_with_exit_2() {
    let cases = [
        (
            "unknown_joint.toml",
            "[scene]\ninitial.q = { elbow = 0.3 }\n",
            vec![
                "[scene] initial.q",
                "unknown joint 'elbow'",
                "did you mean 'elbow_joint'",
            ],
        ),
        (
            "unknown_effect.toml",
            "[scene]\neffects = [\"gravity\", \"friction\"]\n",
            vec![
                "[scene] effects",
                "unknown effect 'friction'",
                "joint_friction",
            ],
        ),
        (
            "zero_step.toml",
            "[scene]\nstep = 0.0\n",
            vec!["[scene] step", "must be a finite number > 0"],
        ),
        (
            "negative_duration.toml",
            "[scene]\nduration = -1.0\n",
            vec!["[scene] duration", "must be a finite number > 0"],
        ),
        (
            "bad_rate.toml",
            "[outputs]\nrate = 300\n",
            vec!["[outputs] rate", "must divide 1/step"],
        ),
        (
            "bad_alpha.toml",
            "[scene]\nalpha = -0.5\n",
            vec!["[scene] alpha", "outside the HHT range [-1/3, 0]"],
        ),
        (
            "typo_key.toml",
            "[scene]\ndurration = 1.0\n",
            vec!["durration", "line 2"],
        ),
        (
            "unknown_frame.toml",
            "[outputs]\nframes = [\"tool\"]\n",
            vec![
                "[outputs] frames",
                "unknown link 'tool'",
                "did you mean 'tool0'",
            ],
        ),
    ];
    for (name, text, fragments) in cases {
        let path = temp_urdf(name, text);
        let out = ribbon_outcome(&[
            "simulate",
            "robots/ur5/ur5.urdf",
            "--uncertainty",
            path.to_str().unwrap(),
        ]);
        assert_input_error(&out, &fragments);
        assert!(
            out.stderr.contains(name),
            "the message names the file: {}",
            out.stderr
        );
    }
    // Command-line overrides are checked the same way, and blamed on the flag, not the sidecar.
    let out = ribbon_outcome(&["simulate", "robots/ur5/ur5.urdf", "--step=-0.001"]);
    assert_input_error(&out, &["--step: -0.001 s must be a finite number > 0"]);
    assert!(
        !out.stderr.contains("ur5.uncertainty.toml"),
        "{}",
        out.stderr
    );
}

/// A robot whose joints are all fixed, on a fixed base (example-robot-data's `iris_simple`, a
/// drone, is one): with the default outputs (every joint) there is nothing to report. Both
/// commands refuse before running, saying why and what to declare — `analyze` used to run its
/// 26 runs and fail with an internal "fit: outputs is empty".
#[test]
fn a_robot_with_nothing_to_output_is_refused_before_running() {
    let text = r#"<robot name="rigid">
  <link name="body"><inertial><mass value="1.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.02"/></inertial></link>
  <link name="rotor"><inertial><mass value="0.1"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
  <joint name="rotor_mount" type="fixed"><parent link="body"/><child link="rotor"/>
    <origin xyz="0.2 0 0"/></joint>
</robot>"#;
    let urdf = temp_urdf("rigid.urdf", text);
    let sidecar = temp_urdf(
        "rigid.uncertainty.toml",
        "[parameters]\n\"link.rotor.mass\" = { rel = 0.05 }\n[scene]\nduration = 0.1\n",
    );
    for command in ["simulate", "analyze"] {
        let out = ribbon_outcome(&[
            command,
            urdf.to_str().unwrap(),
            "--uncertainty",
            sidecar.to_str().unwrap(),
        ]);
        assert_input_error(
            &out,
            &[
                "rigid.uncertainty.toml: [outputs]: nothing to output",
                "no moving joint (1 joint in the URDF, all fixed, and a fixed base)",
                "frames = [",
                "base = \"floating\"",
            ],
        );
    }
    // A robot that moves, with [outputs] selecting nothing: the same refusal, its own advice.
    let arm_urdf = temp_urdf("nothing_arm.urdf", &arm("1", "base"));
    let empty = temp_urdf(
        "nothing_arm.uncertainty.toml",
        "[scene]\nduration = 0.1\n[outputs]\njoints = []\n",
    );
    let out = ribbon_outcome(&[
        "simulate",
        arm_urdf.to_str().unwrap(),
        "--uncertainty",
        empty.to_str().unwrap(),
    ]);
    assert_input_error(
        &out,
        &[
            "[outputs]: nothing to output: [outputs] selects no joints",
            "or joints = \"all\"",
        ],
    );
    // With a frame declared there is something to report: the run goes through.
    let framed = temp_urdf(
        "rigid_framed.uncertainty.toml",
        "[parameters]\n\"link.rotor.mass\" = { rel = 0.05 }\n[scene]\nduration = 0.1\n\
         [outputs]\nframes = [\"rotor\"]\n",
    );
    let out = ribbon_outcome(&[
        "simulate",
        urdf.to_str().unwrap(),
        "--uncertainty",
        framed.to_str().unwrap(),
    ]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
}

/// A study without a sidecar is refused naming `--uncertainty` and the command that writes a
/// start; `ribbon init` writes it (never over an existing file), `ribbon params` lists the box it
/// declares, and the study it makes runs and is trusted.
#[test]
fn a_missing_sidecar_is_refused_with_a_start_that_works() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_errors_no_sidecar");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let urdf = dir.join("dp.urdf");
    std::fs::copy(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("robots/double_pendulum/double_pendulum.urdf"),
        &urdf,
    )
    .expect("copy urdf");
    let urdf = urdf.to_str().unwrap();
    let refused = ribbon_outcome(&["analyze", urdf]);
    let init_command = format!("ribbon init {urdf}");
    assert_input_error(
        &refused,
        &[
            "--uncertainty",
            "no sidecar",
            "dp.uncertainty.toml",
            &init_command,
        ],
    );
    let written = ribbon_outcome(&["init", urdf]);
    assert_eq!(written.code, Some(0), "{}", written.stderr);
    let sidecar = dir.join("dp.uncertainty.toml");
    let text = std::fs::read_to_string(&sidecar).expect("init wrote the sidecar");
    for part in [
        "joint_springs",
        "joint_limits",
        "[[scene.spring]]",
        "joint = \"j1\"",
    ] {
        assert!(text.contains(part), "{part} not in the start:\n{text}");
    }
    // Never over an existing file: the second init is refused and the file is unchanged.
    let again = ribbon_outcome(&["init", urdf]);
    assert_input_error(&again, &["--out", "already exists"]);
    assert_eq!(std::fs::read_to_string(&sidecar).unwrap(), text);
    let listed = ribbon_outcome(&["params", urdf, "--uncertainty", sidecar.to_str().unwrap()]);
    assert_eq!(listed.code, Some(0), "{}", listed.stderr);
    for dimension in [
        "link.bar1.scale",
        "link.bar2.scale",
        "link.bar1.com.x",
        "link.bar2.com.z",
    ] {
        assert!(
            listed.stdout.contains(dimension),
            "{dimension} not in the box: {}",
            listed.stdout
        );
    }
    // And the study it makes runs, trusted.
    let study = ribbon_outcome(&["analyze", urdf, "--duration", "0.2"]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
}

/// `[analysis] max_runs` is the study's budget unless `--max-runs` is given; a budget below 2 is
/// refused naming where it came from.
#[test]
fn the_sidecar_sets_the_run_budget_and_the_flag_overrides_it() {
    // d = 72: `--method auto` takes the dimension-adaptive design, which spends the budget.
    let sidecar = std::fs::read_to_string(common::manifest(
        "robots/ur5/ur5.all-values.uncertainty.toml",
    ))
    .expect("ur5 sidecar");
    assert!(!sidecar.contains("[analysis]"));
    let with_budget = |budget: &str| {
        let text = format!("{sidecar}\n[analysis]\nmax_runs = {budget}\n");
        temp_urdf(&format!("budget_{budget}.toml"), &text)
    };
    let small = with_budget("1");
    let small = small.to_str().unwrap();
    let out = ribbon_outcome(&["analyze", "robots/ur5/ur5.urdf", "--uncertainty", small]);
    assert_input_error(&out, &["[analysis] max_runs", "give at least 2"]);
    let out = ribbon_outcome(&[
        "analyze",
        "robots/ur5/ur5.urdf",
        "--uncertainty",
        small,
        "--max-runs",
        "1",
    ]);
    assert_input_error(&out, &["--max-runs", "give at least 2"]);
    // `--method auto` plans within the sidecar's budget, and the flag's wins over it. An
    // untrusted study may refine its extremes with up to half the budget beyond it
    // (docs/method.md §12) and check its horizon with up to twice its check runs (§7): the runs
    // planned, and the refinement's and the horizon check's, are counted apart.
    let runs_of = |extra: &[&str]| -> (u64, u64) {
        let tight = with_budget("200");
        let summary = tight.with_extension("json");
        let mut args = vec![
            "analyze",
            "robots/ur5/ur5.urdf",
            "--uncertainty",
            tight.to_str().unwrap(),
            "--method",
            "auto",
            "--duration",
            "0.1",
            "--summary",
            summary.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = ribbon_outcome(&args);
        assert!(matches!(out.code, Some(0) | Some(4)), "{}", out.stderr);
        assert!(
            !out.stderr.contains("over --max-runs 3000"),
            "{}",
            out.stderr
        );
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        let samples = summary["samples"].as_u64().expect("samples");
        let refined = summary["stats"]
            .get("refinement")
            .map_or(0, |r| r["runs"].as_u64().expect("refinement runs"));
        let check = &summary["stats"]["check"];
        let horizon = check
            .get("horizon")
            .map_or(0, |h| h["runs"].as_u64().expect("horizon runs"));
        let checks_before = check["runs"].as_u64().expect("check runs") - horizon;
        assert!(horizon <= 2 * checks_before + 6, "{check}");
        (samples - refined - horizon, refined)
    };
    let (within_sidecar, refined) = runs_of(&[]);
    assert!(
        within_sidecar <= 200 && refined <= 100,
        "{within_sidecar} runs and {refined} refining for a budget of 200"
    );
    let (with_flag, refined) = runs_of(&["--max-runs", "400"]);
    assert!(
        with_flag > 200 && with_flag <= 400 && refined <= 200,
        "--max-runs 400 gave {with_flag} runs and {refined} refining"
    );
}
