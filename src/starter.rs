//! A first sidecar for a robot that has none: a box and a scene a roboticist would ask about.
//!
//! `ribbon analyze ROBOT.urdf` without a sidecar used to offer only a box (every link's mass scale
//! and centre of mass); the scene it then ran was the default one, a limp fall from `q = 0` with no
//! limits — a robot sliding onto its stops or swinging through singular poses, which no surrogate
//! in the parameters follows (issue 38 measured a Panda's envelopes at 10⁴ rad). This module writes
//! the scene a person means when they ask "how far can my arm drift?":
//!
//! - the box: every link's mass and inertia scale ±5 % and every centre of mass ±2 mm;
//! - a pose inside every URDF limit ([`starting_position`]: 0 where that is well inside, else the
//!   middle of the range);
//! - the arm holding that pose on PD joint controllers — spring-dampers whose rest is the pose,
//!   tuned per joint ([`pd_gains`]) to the joint's own inertia at the pose and to the gravity torque
//!   it must hold, critically damped — under gravity, with `joint_limits` enforced;
//! - the joint positions and the world position of the tip link (the deepest link of the tree).
//!
//! It does not choose a motion (a trajectory to track is the user's), contacts, loops or drives;
//! mimic joints stay constraint rows and get no controller of their own. The text says what the
//! scene is, so that a user edits it rather than trusts it blindly.

use crate::dynamics::{crba, nonlinear_effects, Data};
use crate::environment::DEFAULT_GRAVITY;
use crate::model::{JointKind, Model};
use crate::spatial::Vec3;
use std::fmt::Write as _;

/// Each joint's controller is tuned to this natural frequency about the held pose, Hz: stiff
/// enough to hold an arm like a position-controlled robot does, slow against the 1 ms step
/// (`ω h ≈ 0.03`).
pub const PD_FREQUENCY_HZ: f64 = 5.0;

/// The controllers are critically damped (damping ratio 1): the sag settles without ringing.
pub const PD_DAMPING_RATIO: f64 = 1.0;

/// Largest static sag of a joint under gravity at the held pose, rad or m: a joint whose gravity
/// torque needs more stiffness than [`PD_FREQUENCY_HZ`] gives gets that much, so the pose held
/// stays within this of the commanded one and far from the limits.
pub const MAX_GRAVITY_SAG: f64 = 0.02;

/// For a joint with finite limits, the largest sag is also at most this fraction of its range
/// (a gripper finger's 4 cm stroke allows 2 mm).
pub const MAX_SAG_RANGE_FRACTION: f64 = 0.05;

/// A joint starts at 0 when 0 is at least this fraction of its range inside both limits;
/// otherwise at the middle of its range.
pub const LIMIT_MARGIN_FRACTION: f64 = 0.1;

/// Smallest stiffness written, N·m/rad or N/m: a joint that moves (almost) no inertia still gets
/// a controller that holds it.
pub const MIN_STIFFNESS: f64 = 1e-3;

/// The simulated time of the starter scene, s: the sag and its settling (a few periods at
/// [`PD_FREQUENCY_HZ`]) and a second of holding.
pub const STARTER_DURATION_S: f64 = 1.5;

/// One joint's controller of the starter scene.
#[derive(Clone, Debug, PartialEq)]
pub struct JointController {
    /// The joint's name.
    pub joint: String,
    /// The commanded (and initial) position, rad or m.
    pub rest: f64,
    /// Stiffness, N·m/rad or N/m.
    pub stiffness: f64,
    /// Damping, N·m·s/rad or N·s/m.
    pub damping: f64,
}

/// The starter scene of a model: its controllers, in coordinate order, and the tip link.
#[derive(Clone, Debug, PartialEq)]
pub struct StarterScene {
    /// One controller per independent 1-dof joint.
    pub controllers: Vec<JointController>,
    /// The link whose world position the starter records (the deepest link), when the model has
    /// a moving joint.
    pub tip_link: Option<String>,
    /// Whether the model stands on a floating base (its base then falls freely: said in the text).
    pub floating_base: bool,
}

/// Where joint `index` of `model` starts: 0 when it lies [`LIMIT_MARGIN_FRACTION`] of the range
/// inside both limits (or the joint has no finite limits), else the middle of the range.
pub fn starting_position(model: &Model, index: usize) -> f64 {
    let joint = &model.joints[index];
    let Some(source) = joint.source else {
        return 0.0;
    };
    let [lower, upper] = model.description.joints[source].limits;
    if !(lower.is_finite() && upper.is_finite() && lower < upper) {
        return 0.0;
    }
    let margin = LIMIT_MARGIN_FRACTION * (upper - lower);
    if lower + margin <= 0.0 && 0.0 <= upper - margin {
        0.0
    } else {
        0.5 * (lower + upper)
    }
}

/// The PD gains `(stiffness, damping)` of a joint with effective inertia `inertia` (`M_jj` at the
/// held pose, kg·m² or kg) that must hold `gravity_torque` (N·m or N) with a static sag of at
/// most `allowed_sag` (rad or m; see [`allowed_sag`]): the stiffness of a [`PD_FREQUENCY_HZ`]
/// oscillator, raised where the gravity torque would otherwise sag the joint further; critical
/// damping `2 ζ √(k M_jj)`.
pub fn pd_gains(inertia: f64, gravity_torque: f64, allowed_sag: f64) -> (f64, f64) {
    let omega = 2.0 * std::f64::consts::PI * PD_FREQUENCY_HZ;
    let stiffness = (inertia * omega * omega)
        .max(gravity_torque.abs() / allowed_sag)
        .max(MIN_STIFFNESS);
    let damping = 2.0 * PD_DAMPING_RATIO * (stiffness * inertia.max(0.0)).sqrt();
    (round_significant(stiffness), round_significant(damping))
}

/// The largest static sag joint `index` of `model` may have: [`MAX_GRAVITY_SAG`], and at most
/// [`MAX_SAG_RANGE_FRACTION`] of its range where it has finite limits.
pub fn allowed_sag(model: &Model, index: usize) -> f64 {
    let range = model.joints[index]
        .source
        .map(|source| model.description.joints[source].limits)
        .filter(|[lower, upper]| lower.is_finite() && upper.is_finite() && lower < upper)
        .map_or(f64::INFINITY, |[lower, upper]| upper - lower);
    MAX_GRAVITY_SAG.min(MAX_SAG_RANGE_FRACTION * range)
}

/// `value` to three significant digits (gains read as a person would write them).
fn round_significant(value: f64) -> f64 {
    if value == 0.0 || !value.is_finite() {
        return value;
    }
    let digits = 2 - value.abs().log10().floor() as i32;
    let scale = 10f64.powi(digits);
    (value * scale).round() / scale
}

impl StarterScene {
    /// The starter scene of `model` (under [`DEFAULT_GRAVITY`], which the scene it writes keeps:
    /// it sets no `gravity`): every independent 1-dof
    /// joint at [`starting_position`], held there by [`pd_gains`] from the model's mass matrix
    /// and gravity torques at that pose.
    pub fn of(model: &Model) -> StarterScene {
        let mut q = model.neutral_configuration();
        let held: Vec<usize> = (0..model.joints.len())
            .filter(|&j| {
                model.joints[j].kind != JointKind::Floating && model.joints[j].mimic.is_none()
            })
            .collect();
        for &j in &held {
            q[model.joints[j].q_index] = starting_position(model, j);
        }
        // Mimic joints follow their leaders at the pose (as the scene starts them).
        model.place_mimic_followers(&mut q, &[]);
        let mut data = Data::new(model);
        let inertia_diagonal: Vec<f64> = {
            let m = crba(model, &mut data, &q);
            (0..model.nv).map(|i| m[(i, i)]).collect()
        };
        let v = vec![0.0; model.nv];
        let gravity = Vec3::from(DEFAULT_GRAVITY);
        let gravity_torques = nonlinear_effects(model, &gravity, &mut data, &q, &v).to_vec();
        let controllers = held
            .iter()
            .map(|&j| {
                let joint = &model.joints[j];
                let (stiffness, damping) = pd_gains(
                    inertia_diagonal[joint.v_index],
                    gravity_torques[joint.v_index],
                    allowed_sag(model, j),
                );
                JointController {
                    joint: joint.name.clone(),
                    rest: round_significant_position(q[joint.q_index]),
                    stiffness,
                    damping,
                }
            })
            .collect();
        StarterScene {
            controllers,
            tip_link: tip_link(model),
            floating_base: model.floating_base,
        }
    }

    /// The starter sidecar as TOML text, commented so that a person knows what it declares;
    /// `robot` names the URDF in the header.
    pub fn sidecar_text(&self, robot: &str) -> String {
        let mut text = String::new();
        let _ = writeln!(
            text,
            "# A first study of {robot}, written by `ribbon init`: edit it to the question you have."
        );
        text.push_str(
            "# The box: every link's mass and inertia known to ±5 %, every centre of mass to ±2 mm.\n\
             [parameters]\n\
             \"link.*.scale\" = { rel = 0.05 }\n\
             \"link.*.com.*\" = { abs = 0.002 }\n\n",
        );
        text.push_str("[scene]\n");
        let _ = writeln!(text, "duration = {STARTER_DURATION_S}");
        text.push_str("step = 0.001\n");
        text.push_str(
            "# The robot holds a pose inside its URDF limits on PD joint controllers (spring-dampers\n\
             # whose rest is the pose, tuned to each joint's inertia there, critically damped) and is\n\
             # released under gravity at t = 0: the envelopes show how far the uncertain masses make\n\
             # it sag and settle. Joint limits are enforced (stops with impacts).\n",
        );
        if self.floating_base {
            text.push_str(
                "# The base floats: nothing holds it, so the whole robot also falls freely.\n\
                 base = \"floating\"\n",
            );
        }
        text.push_str("effects = [\"gravity\", \"joint_springs\", \"joint_limits\"]\n");
        let pose: Vec<String> = self
            .controllers
            .iter()
            .filter(|c| c.rest != 0.0)
            .map(|c| format!("{} = {}", toml_key(&c.joint), c.rest))
            .collect();
        let _ = writeln!(text, "initial.q = {{ {} }}", pose.join(", "));
        for controller in &self.controllers {
            let _ = write!(
                text,
                "\n[[scene.spring]]\njoint = {}\nstiffness = {:?}\ndamping = {:?}\nrest = {:?}\n",
                toml_string(&controller.joint),
                controller.stiffness,
                controller.damping,
                controller.rest
            );
        }
        text.push_str("\n[outputs]\njoints = \"all\"\n");
        if let Some(tip) = &self.tip_link {
            let _ = writeln!(text, "frames = [{}]", toml_string(tip));
        }
        text
    }
}

/// A pose angle to four decimals (the middle of a URDF range such as `-1.5708`).
fn round_significant_position(value: f64) -> f64 {
    let rounded = (value * 1e4).round() / 1e4;
    if rounded == 0.0 {
        0.0
    } else {
        rounded
    }
}

/// Parts of link names that mark a tool frame, in order of preference (compared in lower case):
/// UR's `tool0`, Franka's `panda_hand_tcp`, `ee_link`, `end_effector`, `flange`.
const TOOL_NAME_PARTS: [&str; 5] = ["tcp", "tool0", "ee_link", "end_effector", "flange"];

/// The link whose position the starter records: a link named like a tool frame
/// ([`TOOL_NAME_PARTS`]) when there is one, else the deepest link of the tree (most moving joints
/// between it and the root; the first in file order among equals).
fn tip_link(model: &Model) -> Option<String> {
    let depth_of_body = |body: usize| {
        let mut depth = 0;
        let mut joint = Some(body);
        while let Some(j) = joint {
            depth += 1;
            joint = model.joints[j].parent;
        }
        depth
    };
    let moving: Vec<(usize, usize)> = model
        .links
        .iter()
        .enumerate()
        .filter_map(|(link, placement)| placement.body.map(|body| (link, depth_of_body(body))))
        .collect();
    let name = |link: usize| model.description.links[link].name.clone();
    for part in TOOL_NAME_PARTS {
        if let Some(&(link, _)) = moving
            .iter()
            .find(|&&(link, _)| name(link).to_lowercase().contains(part))
        {
            return Some(name(link));
        }
    }
    let deepest = moving.iter().map(|&(_, depth)| depth).max()?;
    moving
        .iter()
        .find(|&&(_, depth)| depth == deepest)
        .map(|&(link, _)| name(link))
}

/// A TOML key: bare when it is one, quoted otherwise (joint names with dots or slashes).
fn toml_key(name: &str) -> String {
    let bare = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare {
        name.to_string()
    } else {
        toml_string(name)
    }
}

/// A TOML basic string.
fn toml_string(text: &str) -> String {
    let mut quoted = String::with_capacity(text.len() + 2);
    quoted.push('"');
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(quoted, "\\u{:04X}", c as u32);
            }
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_follow_the_frequency_and_the_gravity_floor() {
        let omega = 2.0 * std::f64::consts::PI * PD_FREQUENCY_HZ;
        // No gravity load: the oscillator at PD_FREQUENCY_HZ, critically damped.
        let (k, c) = pd_gains(2.0, 0.0, MAX_GRAVITY_SAG);
        assert!((k - 2.0 * omega * omega).abs() <= 5e-3 * k, "{k}");
        assert!((c - 2.0 * (k * 2.0_f64).sqrt()).abs() <= 5e-3 * c, "{c}");
        // A heavy gravity load raises the stiffness so the sag stays within MAX_GRAVITY_SAG.
        let (k, _) = pd_gains(0.01, 50.0, MAX_GRAVITY_SAG);
        assert!(50.0 / k <= MAX_GRAVITY_SAG * 1.005, "{k}");
        // A joint without inertia still gets a (small) controller.
        let (k, c) = pd_gains(0.0, 0.0, MAX_GRAVITY_SAG);
        assert_eq!((k, c), (MIN_STIFFNESS, 0.0));
    }

    #[test]
    fn keys_and_strings_are_valid_toml() {
        assert_eq!(toml_key("panda_joint1"), "panda_joint1");
        assert_eq!(toml_key("joint_0.0"), "\"joint_0.0\"");
        assert_eq!(toml_string("a\"b\\c"), "\"a\\\"b\\\\c\"");
        let table: toml::Table =
            toml::from_str(&format!("{} = 1", toml_key("iris__/imu.joint"))).unwrap();
        assert!(table.contains_key("iris__/imu.joint"));
    }

    #[test]
    fn three_significant_digits() {
        assert_eq!(round_significant(1234.5), 1230.0);
        assert_eq!(round_significant(0.0123456), 0.0123);
        assert_eq!(round_significant(-98.76), -98.8);
    }
}
