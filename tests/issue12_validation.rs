//! Issue 12 §2, §5, §6 and its "Smaller" list, through the binary: hopeless settings are refused up
//! front with the numbers (a subnormal step ran "forever", a huge duration aborted on an 800 GB
//! allocation with exit 134, 100 000 threads hung), a flag error names the flag (it was blamed on
//! the sidecar), α near 0 with constraint rows is refused (multipliers off by up to 10× their
//! size), singular mass matrices and Newton failures name the joint and the likely cause, and
//! `simulate`, `analyze` and `dynamics` use the same exit codes (2: the input cannot start; 1: a run
//! that started failed).

mod common;

use common::{ribbon_outcome, Outcome};

use std::path::PathBuf;

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("issue12_validation");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write temp file");
    path
}

fn assert_exit(out: &Outcome, code: i32, fragments: &[&str]) {
    assert_eq!(out.code, Some(code), "exit code; stderr: {}", out.stderr);
    for fragment in fragments {
        assert!(
            out.stderr.contains(fragment),
            "expected '{fragment}' in: {}",
            out.stderr
        );
    }
    if code != 0 {
        assert!(out.stdout.is_empty(), "nothing on stdout: {}", out.stdout);
    }
}

const DOUBLE_PENDULUM: &str = "robots/double_pendulum/double_pendulum.urdf";
const SLIDER_CRANK: &str = "robots/slider_crank/slider_crank.urdf";

#[test]
fn a_subnormal_or_tiny_step_is_refused_with_the_numbers() {
    for command in ["simulate", "analyze"] {
        let out = ribbon_outcome(&[command, DOUBLE_PENDULUM, "--step", "5e-324"]);
        assert_exit(
            &out,
            2,
            &["--step: a step of 5e-324 s is below the smallest step 1e-9 s"],
        );
        let out = ribbon_outcome(&[
            command,
            DOUBLE_PENDULUM,
            "--step",
            "2e-9",
            "--duration",
            "10",
        ]);
        assert_exit(&out, 2, &["--step:", "5.000e9 steps", "limit of 1e9"]);
    }
}

#[test]
fn a_huge_duration_is_refused_not_an_allocation_abort() {
    for command in ["simulate", "analyze"] {
        // Before: exit 134, "memory allocation of 800000000016 bytes failed".
        let out = ribbon_outcome(&[command, DOUBLE_PENDULUM, "--duration", "1e9"]);
        assert_exit(&out, 2, &["--duration:", "1.000e12 steps", "MAX_STEPS"]);
        // Within the step limit but not within memory: the bytes are named.
        let out = ribbon_outcome(&[command, DOUBLE_PENDULUM, "--duration", "1e6"]);
        assert_exit(
            &out,
            2,
            &[
                "--duration:",
                "100000001 record times",
                "GiB in memory",
                "budget of 4.0 GiB",
            ],
        );
    }
}

#[test]
fn absurd_thread_counts_are_refused() {
    let out = ribbon_outcome(&[
        "analyze",
        DOUBLE_PENDULUM,
        "--threads",
        "100000",
        "--duration",
        "0.1",
    ]);
    assert_exit(
        &out,
        2,
        &["--threads: 100000 worker threads", "limit of 1024"],
    );
    let out = ribbon_outcome(&[
        "compare",
        DOUBLE_PENDULUM,
        "--threads",
        "5000",
        "--duration",
        "0.1",
    ]);
    assert_exit(&out, 2, &["--threads: 5000 worker threads"]);
}

#[test]
fn a_flag_error_names_the_flag_not_the_sidecar() {
    let out = ribbon_outcome(&["simulate", "robots/ur5/ur5.urdf", "--step=-0.001"]);
    assert_exit(
        &out,
        2,
        &["error: --step: -0.001 s must be a finite number > 0"],
    );
    assert!(!out.stderr.contains("uncertainty.toml"), "{}", out.stderr);
    let out = ribbon_outcome(&["analyze", DOUBLE_PENDULUM, "--duration=nan"]);
    assert_exit(
        &out,
        2,
        &["error: --duration: NaN s must be a finite number > 0"],
    );
    let out = ribbon_outcome(&["simulate", DOUBLE_PENDULUM, "--alpha=-0.5"]);
    assert_exit(&out, 2, &["error: --alpha: -0.5 is outside the HHT range"]);
    let out = ribbon_outcome(&["simulate", DOUBLE_PENDULUM, "--duration", "0.0015"]);
    assert_exit(
        &out,
        2,
        &["error: --duration: 0.0015 s is not a whole number of steps"],
    );
}

/// Before: α = −1e-9 … −1e-3 was accepted with constraint rows and gave constraint forces off by up
/// to ten times their size (see `ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`).
#[test]
fn alpha_near_zero_with_constraint_rows_is_refused() {
    for alpha in ["--alpha=-1e-9", "--alpha=-0.001", "--alpha=-0.04"] {
        let out = ribbon_outcome(&["simulate", SLIDER_CRANK, alpha]);
        assert_exit(
            &out,
            2,
            &["--alpha:", "refused with constraint rows", "at least 0.05"],
        );
        let out = ribbon_outcome(&["analyze", SLIDER_CRANK, alpha]);
        assert_exit(&out, 2, &["--alpha:", "at least 0.05"]);
    }
    let out = ribbon_outcome(&[
        "simulate",
        SLIDER_CRANK,
        "--alpha=-0.05",
        "--duration",
        "0.05",
    ]);
    assert_exit(&out, 0, &[]);
    // Without constraint rows α near 0 stays accurate and allowed.
    let out = ribbon_outcome(&[
        "simulate",
        DOUBLE_PENDULUM,
        "--alpha=-1e-9",
        "--duration",
        "0.05",
    ]);
    assert_exit(&out, 0, &[]);
}

const MASSLESS_LEAF: &str = r#"<robot name="leaf"><link name="base"/>
  <link name="upper"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="hand"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="wrist" type="revolute"><origin xyz="1 0 0"/><parent link="upper"/><child link="hand"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
</robot>"#;

const MASSLESS_ROOT: &str = r#"<robot name="float"><link name="base"/>
  <link name="upper"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
</robot>"#;

/// The spring advice of a Newton failure names the spring only when the step does not resolve
/// its period: the double pendulum's elbow on a 1e10 N·m/rad spring released 1 rad away (period
/// 7.3e-5 s at h = 1 ms) is told to take a step below 3.6e-6 s; the quadruped's knees (300 N·m/rad,
/// period 28 ms, resolved by 1 ms) failing at touch-down under the fixed step are not blamed on
/// their springs (the message used to ask for a step "below 1.4e-3 s" at 1e-3 s) but on the
/// contact, with the adaptive step.
#[test]
fn the_spring_advice_names_the_spring_only_when_the_step_does_not_resolve_it() {
    let stiff = temp_file(
        "stiff_elbow.toml",
        "[scene]\nduration = 0.1\neffects = [\"gravity\", \"joint_springs\"]\n\
         [[scene.spring]]\njoint = \"j2\"\nstiffness = 1e10\nrest = 1.0\n",
    );
    let out = ribbon_outcome(&[
        "simulate",
        "robots/double_pendulum/double_pendulum.urdf",
        "--uncertainty",
        stiff.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        1,
        &[
            "joint 'j2'",
            "spring stiffness 1.000e10: period 7.255e-5 s",
            "the spring is too stiff for the step of 0.001 s",
            "use a step below 3.6e-6 s",
        ],
    );
    let quadruped = std::fs::read_to_string("robots/quadruped/quadruped.uncertainty.toml")
        .expect("the shipped quadruped sidecar");
    assert!(quadruped.contains("step_control = \"adaptive\""));
    let fixed = temp_file(
        "quadruped_fixed.toml",
        &quadruped.replace("step_control = \"adaptive\"", "step_control = \"fixed\""),
    );
    let out = ribbon_outcome(&[
        "simulate",
        "robots/quadruped/quadruped.urdf",
        "--uncertainty",
        fixed.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        1,
        &["Newton did not converge", "step_control = \"adaptive\""],
    );
    assert!(
        !out.stderr.contains("spring is too stiff"),
        "{}",
        out.stderr
    );
}

/// A negative mass reaches the dynamics only through the library (the URDF reader, `--set` and a
/// study's box check refuse one); its start failure must name the link and its negative value,
/// not blame a missing `<inertial>`.
#[test]
fn a_negative_mass_at_the_start_is_named_as_such() {
    use ribbon::model::{parse_description, LoadOptions, Model};
    use ribbon::scene::{parse_sidecar, Scene, SceneOverrides};
    let mut model = Model::from_description(
        parse_description(MASSLESS_ROOT, "float.urdf").expect("parses"),
        LoadOptions::default(),
        "float.urdf",
    )
    .expect("loads");
    let upper = model
        .description
        .links
        .iter()
        .position(|l| l.name == "upper")
        .expect("link 'upper'");
    model.inertial_scales[upper] = -15.0;
    model.refresh();
    let scene = Scene::resolve(
        &parse_sidecar("").expect("empty sidecar"),
        &model,
        "s.toml",
        SceneOverrides::default(),
    )
    .expect("scene");
    let message = ribbon::simulate::check_start(&model, &scene.environment(), &scene)
        .expect_err("a negative mass cannot start")
        .to_string();
    assert!(
        message.contains("not positive definite at the initial state")
            && message.contains("link 'upper' has mass -15 kg")
            && !message.contains("give the links it moves an <inertial>"),
        "{message}"
    );
}

/// Before: `simulate` exited 1 with "singular mass matrix … pivot 1" where `dynamics` exited 2
/// naming the joint; a massless floating root blamed 'shoulder'.
#[test]
fn a_singular_mass_matrix_names_the_joint_and_cause_with_exit_2_everywhere() {
    let leaf = temp_file("massless_leaf.urdf", MASSLESS_LEAF);
    let leaf = leaf.to_str().unwrap();
    let out = ribbon_outcome(&["simulate", leaf]);
    assert_exit(
        &out,
        2,
        &[
            "the run cannot start",
            "joint 'wrist' moves no mass or inertia",
            "link 'hand' moved by revolute joint 'wrist' has no mass and no inertia (a massless leaf)",
        ],
    );
    let out = ribbon_outcome(&["dynamics", leaf, "--tau=0,0"]);
    assert_exit(&out, 2, &["joint 'wrist'"]);
    let sidecar = temp_file(
        "massless_leaf.uncertainty.toml",
        "[parameters]\n\"link.upper.mass\" = { rel = 0.1 }\n",
    );
    let out = ribbon_outcome(&["analyze", leaf, "--uncertainty", sidecar.to_str().unwrap()]);
    assert_exit(&out, 2, &["the run cannot start", "(a massless leaf)"]);

    // A box whose corner makes M singular (a mass of 1e298 beside one of 1 kg): that sample
    // cannot start, and it is the input's fault (exit 2; it was 1).
    let wide = temp_file(
        "wide_mass.toml",
        "[parameters]\n\"link.bar1.mass\" = [1e-300, 1e300]\n[scene]\nduration = 0.1\n",
    );
    let out = ribbon_outcome(&[
        "analyze",
        DOUBLE_PENDULUM,
        "--uncertainty",
        wide.to_str().unwrap(),
    ]);
    assert_exit(&out, 2, &["failed at t = 0 s", "singular"]);

    let root = temp_file("massless_root.urdf", MASSLESS_ROOT);
    let out = ribbon_outcome(&["simulate", root.to_str().unwrap(), "--floating"]);
    assert_exit(
        &out,
        2,
        &[
            "the combined motion of joints 'root_joint' (angular z), 'shoulder'",
            "the floating base link 'base' has no mass and no inertia (a massless floating root",
        ],
    );
}

/// Before: "worst: velocity coordinate 1".
#[test]
fn a_newton_failure_names_the_joint_and_exits_1() {
    let sidecar = temp_file(
        "fast_elbow.toml",
        "[scene]\nduration = 0.1\ninitial.v = { j2 = 1e3 }\n",
    );
    let out = ribbon_outcome(&[
        "simulate",
        DOUBLE_PENDULUM,
        "--uncertainty",
        sidecar.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        1,
        &[
            "Newton did not converge",
            "worst: joint 'j2' (velocity coordinate 1",
            "effective inertia",
            "Likely cause:",
            "smaller --step",
        ],
    );
    assert!(
        !out.stderr.contains("worst: velocity coordinate"),
        "{}",
        out.stderr
    );
}

/// Before: 12.57 rad/s silently became 4.35 rad/s.
#[test]
fn an_initial_velocity_the_loop_forbids_is_reported_with_the_numbers() {
    let text = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots/four_bar/four_bar.uncertainty.toml"),
    )
    .unwrap();
    let start = text.find("initial.v").expect("the sidecar gives initial.v");
    let end = start + text[start..].find('\n').unwrap();
    let crank_only = format!(
        "{}initial.v = {{ crank_joint = 12.566370614359172 }}{}",
        &text[..start],
        &text[end..]
    );
    let sidecar = temp_file("four_bar_crank_only.toml", &crank_only);
    let out = ribbon_outcome(&[
        "simulate",
        "robots/four_bar/four_bar.urdf",
        "--uncertainty",
        sidecar.to_str().unwrap(),
        "--duration",
        "0.01",
    ]);
    assert_exit(
        &out,
        0,
        &[
            "warning:",
            "initial.v does not satisfy the constraint rows",
            "crank_joint 12.566370614359172 → 4.349898",
            "also give coupler_joint = -16.755160819",
            "rocker_joint = -4.188790204",
        ],
    );
    // The shipped sidecar gives those velocities: no warning.
    let out = ribbon_outcome(&[
        "simulate",
        "robots/four_bar/four_bar.urdf",
        "--duration",
        "0.01",
    ]);
    assert_exit(&out, 0, &[]);
    assert!(!out.stderr.contains("initial.v"), "{}", out.stderr);
}

/// A given position the rows do not allow is reported as a given velocity is: before, a crank
/// angle the loop could not take was silently moved by the start projection.
#[test]
fn an_initial_position_the_loop_forbids_is_reported_with_the_numbers() {
    let text = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots/four_bar/four_bar.uncertainty.toml"),
    )
    .unwrap();
    let given = "initial.q = { crank_joint = 0.0,";
    assert!(text.contains(given), "the sidecar gives the crank's angle");
    let moved_crank = text.replace(given, "initial.q = { crank_joint = 0.3,");
    let sidecar = temp_file("four_bar_moved_crank.toml", &moved_crank);
    let out = ribbon_outcome(&[
        "simulate",
        "robots/four_bar/four_bar.urdf",
        "--uncertainty",
        sidecar.to_str().unwrap(),
        "--duration",
        "0.01",
    ]);
    assert_exit(
        &out,
        0,
        &[
            "warning:",
            "initial.q does not satisfy the constraint rows",
            "crank_joint 0.3 → ",
            "coupler_joint 0.9479697413828937 → ",
        ],
    );
    // The shipped sidecar closes the loop: no warning.
    let out = ribbon_outcome(&[
        "simulate",
        "robots/four_bar/four_bar.urdf",
        "--duration",
        "0.01",
    ]);
    assert!(!out.stderr.contains("initial.q"), "{}", out.stderr);
}

/// A URDF mimic joint left out of `initial.q` starts at its leader's position (times the
/// multiplier, plus the offset), on bullet3's xarm6 with its gripper (five followers of
/// `drive_joint`) and the starter sidecar `ribbon init` writes: before, the start projection
/// averaged the six joints to 0.425 / 6 rad, and the starter's springs pulled the gripper open.
#[test]
fn mimic_joints_left_out_of_initial_q_start_at_their_leader() {
    let dir = common::fresh_scratch_dir("issue12_validation", "mimic_start");
    let urdf = dir.join("xarm6_with_gripper.urdf");
    std::fs::copy(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/urdf_corpus/bullet3/xarm/xarm6_with_gripper.urdf"),
        &urdf,
    )
    .unwrap();
    let urdf = urdf.to_str().unwrap();
    assert_exit(&ribbon_outcome(&["init", urdf]), 0, &[]);
    let starter = std::fs::read_to_string(dir.join("xarm6_with_gripper.uncertainty.toml")).unwrap();
    assert!(
        starter.contains("drive_joint = 0.425") && !starter.contains("left_finger_joint ="),
        "the starter gives the leader only:\n{starter}"
    );
    let csv = dir.join("start.csv");
    let out = ribbon_outcome(&[
        "simulate",
        urdf,
        "--duration",
        "0.01",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_exit(&out, 0, &[]);
    assert!(!out.stderr.contains("initial.q"), "{}", out.stderr);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let first: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    for joint in [
        "drive_joint",
        "left_finger_joint",
        "left_inner_knuckle_joint",
        "right_outer_knuckle_joint",
        "right_finger_joint",
        "right_inner_knuckle_joint",
    ] {
        let column = header
            .iter()
            .position(|h| *h == format!("q.{joint}"))
            .unwrap_or_else(|| panic!("no q.{joint} in {header:?}"));
        assert_eq!(first[column], 0.425, "{joint} at t = 0");
    }
}

#[test]
fn two_outputs_with_one_name_are_refused() {
    let sidecar = temp_file(
        "twice.toml",
        "[outputs]\njoints = [\"j1\", \"j2\", \"j1\"]\n",
    );
    let out = ribbon_outcome(&[
        "simulate",
        DOUBLE_PENDULUM,
        "--uncertainty",
        sidecar.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        2,
        &["[outputs] joints", "output 'q.j1' would be recorded twice"],
    );
}

/// Before: `dynamics --v=1e200,1e200` printed `bias NaN NaN` (JSON `null`) with exit 0.
#[test]
fn nan_is_never_printed_with_exit_0() {
    let json = ribbon_outcome(&["dynamics", DOUBLE_PENDULUM, "--v=1e200,1e200", "--json"]);
    let table = ribbon_outcome(&["dynamics", DOUBLE_PENDULUM, "--v=1e200,1e200"]);
    for out in [json, table] {
        assert_exit(
            &out,
            2,
            &["the bias forces C(q, v) v + g(q): NaN at coordinate 0 (joint 'j1')"],
        );
    }
}

/// A drive that cannot hold names its joint: redundant with the loop (exit 2), or too fast for the
/// step (exit 1, where the message said only "pivot 5").
#[test]
fn drive_errors_name_the_joint() {
    let text = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("robots/slider_crank/slider_crank.uncertainty.toml"),
    )
    .unwrap();
    let redundant = text.replacen(
        "[[scene.loop]]",
        "[[scene.drive]]\nname = \"push\"\njoint = \"slider_joint\"\nprofile = \"constant\"\nvalue = 0.5\n\n[[scene.loop]]",
        1,
    );
    let sidecar = temp_file("slider_crank_redundant_drive.toml", &redundant);
    let out = ribbon_outcome(&[
        "simulate",
        SLIDER_CRANK,
        "--uncertainty",
        sidecar.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        2,
        &[
            "redundant constraint rows: drive 'push'",
            "the drive on joint 'slider_joint'",
        ],
    );
    // 1000 revolutions per second: 6.3 rad per 1 ms step.
    let fast = text.replace("rate = 6.283185307179586", "rate = 6283.185307179586");
    assert_ne!(fast, text, "the sidecar's drive rate was found");
    let sidecar = temp_file("slider_crank_fast_drive.toml", &fast);
    let out = ribbon_outcome(&[
        "simulate",
        SLIDER_CRANK,
        "--uncertainty",
        sidecar.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        1,
        &[
            "drive 'motor' on joint 'crank_joint'",
            "Likely cause:",
            "smaller --step",
        ],
    );
}

/// Before: a 100 000-deep `[bind]` chain overflowed the stack (exit 134); then it was refused but
/// the message quoted the whole 200 kB expression. Now: exit 2, the depth named, the expression
/// quoted by its ends.
#[test]
fn a_hostile_expression_is_refused_with_a_short_message() {
    let chain = format!("l1{}", "^1".repeat(100_000));
    let sidecar = temp_file(
        "hostile_chain.toml",
        &format!("[parameters]\nl1 = [0.99, 1.01]\n[bind]\n\"joint.j2.origin.x\" = \"{chain}\"\n"),
    );
    let out = ribbon_outcome(&[
        "analyze",
        DOUBLE_PENDULUM,
        "--uncertainty",
        sidecar.to_str().unwrap(),
    ]);
    assert_exit(
        &out,
        2,
        &["nests deeper than 256 levels", "(200002 characters)"],
    );
    assert!(
        out.stderr.len() < 2000,
        "{} bytes of stderr",
        out.stderr.len()
    );
}
