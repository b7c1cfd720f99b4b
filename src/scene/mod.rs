//! Scenes: what a run simulates and records, read from the sidecar `ROBOT.uncertainty.toml` and checked
//! against the robot.
//!
//! A [`Scene`] is fully resolved: joint names are indices, effects are flags, outputs know where their
//! numbers come from. Only what the scene declares is assembled by [`crate::effects`]. Drives,
//! loop closures and URDF mimic joints become constraint rows ([`crate::constraints`]).

mod budget;
mod constraints;
mod contacts;
mod limit_excursions;
mod outputs;
mod step_control;

pub use budget::{
    check_dense_matrices, check_step_count, check_threads, format_bytes, DENSE_MATRICES_PER_SYSTEM,
    MAX_STEPS, MAX_THREADS, MEMORY_BUDGET_BYTES, MIN_STEP_S,
};
pub use contacts::{SceneContacts, DEFAULT_MAX_PENETRATION_M};
pub use limit_excursions::{
    describe_limit_excursions, limit_excursions, outputs_at_enforced_limits, surrogate_ranges,
    LimitExcursion, ENFORCED_LIMIT_BOUND_MARGIN, LIMIT_CONTACT_TOLERANCE,
    LIMIT_EXCURSION_TOLERANCE,
};
pub use outputs::{clamp_to_range, Output, OutputKind};
// The file format lives in `crate::sidecar`; these re-exports keep `crate::scene::SidecarFile` and
// friends working for the study commands, benches and examples. `constraints` and `outputs` read
// their sections through `super::sidecar`.
use crate::sidecar;
pub use crate::sidecar::{
    parse_sidecar, read_sidecar, AnalysisSection, JointSelection, SidecarFile,
};

use crate::environment::Environment;
use crate::integrate::{check_alpha, ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS};
use crate::model::{JointKind, Model};
use crate::spatial::quaternion::write_xyzw;
use crate::spatial::rotation_from_rpy;
use crate::text::closest_suggestion;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Default simulated time, s.
pub const DEFAULT_DURATION_S: f64 = 1.0;
/// Default fixed step, s.
pub const DEFAULT_STEP_S: f64 = 1e-3;
/// Default HHT α.
pub const DEFAULT_ALPHA: f64 = -0.1;
/// Default recording rate, Hz.
pub const DEFAULT_RATE_HZ: f64 = 100.0;
/// Relative tolerance for "the rate divides 1/step" and "the step divides the duration": the values
/// are decimal fractions typed by people (0.001, 100), exact up to rounding.
pub const DIVISIBILITY_TOLERANCE: f64 = 1e-9;

/// The effects a scene can declare.
pub const EFFECT_NAMES: [&str; 5] = [
    "gravity",
    "joint_damping",
    "joint_friction",
    "joint_springs",
    "joint_limits",
];

/// A bad sidecar or scene value. Names the file, the key and what to do.
#[derive(Debug, Error)]
pub enum SceneError {
    /// A value that does not fit the robot or the rules.
    #[error("{path}: {key}: {message}")]
    Invalid {
        /// The file (or "command line").
        path: String,
        /// The key, e.g. `[scene] step`.
        key: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A command-line value (`--step`, `--threads`, …) that does not fit the rules: named by its
    /// flag, never blamed on the sidecar.
    #[error("{flag}: {message}")]
    Flag {
        /// The flag, e.g. `--step`.
        flag: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A robot too big for the dense matrices of its dynamics ([`check_dense_matrices`]).
    #[error("{urdf}: {message}")]
    TooManyCoordinates {
        /// The URDF file.
        urdf: String,
        /// The sizes and what to do.
        message: String,
    },
}

/// Where a scene value came from, so that a message names the flag or the sidecar key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A command-line flag (`--duration`).
    Flag(&'static str),
    /// A sidecar key (`[scene] duration`), given or left at its default.
    Key(&'static str),
}

impl Origin {
    /// The first of `flag` (if the flag was given), `key` in the sidecar.
    fn of<T>(flag_value: Option<T>, flag: &'static str, key: &'static str) -> Origin {
        if flag_value.is_some() {
            Origin::Flag(flag)
        } else {
            Origin::Key(key)
        }
    }

    /// The error for a bad value from here; `path` names the sidecar.
    pub fn error(self, path: &str, message: String) -> SceneError {
        match self {
            Origin::Flag(flag) => SceneError::Flag {
                flag: flag.to_string(),
                message,
            },
            Origin::Key(key) => SceneError::Invalid {
                path: path.to_string(),
                key: key.to_string(),
                message,
            },
        }
    }
}

/// Where the values that size a run came from (for messages about its size).
#[derive(Clone, Debug)]
pub struct SceneOrigins {
    /// The sidecar's name as messages show it.
    pub sidecar: String,
    /// `--duration` or `[scene] duration`.
    pub duration: Origin,
    /// `--step` or `[scene] step`.
    pub step: Origin,
    /// `--alpha` or `[scene] alpha`.
    pub alpha: Origin,
}

/// Effects that are simulated (only these are assembled).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EffectSet {
    /// Gravity (`[scene] gravity`).
    pub gravity: bool,
    /// URDF `<dynamics damping>`: `τ = −c q̇`.
    pub joint_damping: bool,
    /// URDF `<dynamics friction>`: smoothed Coulomb friction.
    pub joint_friction: bool,
    /// `[[scene.spring]]` joint springs.
    pub joint_springs: bool,
    /// Penalty spring-dampers at the URDF `<limit lower upper>`.
    pub joint_limits: bool,
}

/// A linear joint spring-damper `τ = −stiffness · (q − rest) − damping · q̇`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSpring {
    /// N·m·s/rad or N·s/m.
    pub damping: f64,
    /// Model joint index.
    pub joint: usize,
    /// N·m/rad or N/m.
    pub stiffness: f64,
    /// rad or m.
    pub rest: f64,
}

/// Command-line values that override the sidecar.
#[derive(Clone, Copy, Debug, Default)]
pub struct SceneOverrides {
    /// `--duration`, s.
    pub duration_s: Option<f64>,
    /// `--step`, s.
    pub step_s: Option<f64>,
    /// `--alpha`.
    pub alpha: Option<f64>,
}

/// A resolved scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Simulated time, s.
    pub duration_s: f64,
    /// Fixed step, s.
    pub step_s: f64,
    /// Number of steps (`duration / step`).
    pub n_steps: usize,
    /// HHT α.
    pub alpha: f64,
    /// Post-step velocity projection (with constraint rows).
    pub velocity_projection: bool,
    /// How the integrator chooses its step (`[scene] step_control`; default fixed).
    pub step_control: crate::integrate::StepControl,
    /// Local error tolerance of the adaptive step, rad or m per step (`[scene] tolerance`; default
    /// [`crate::integrate::DEFAULT_STEP_TOLERANCE`]).
    pub step_tolerance: f64,
    /// Coefficient of restitution of joint-limit impacts in `[0, 1]` (`[scene] limit_restitution`;
    /// default 0, plastic).
    pub limit_restitution: f64,
    /// Most halvings of a grid step by the integrator (sub-steps never below the smallest step,
    /// [`budget::MIN_STEP_S`]).
    pub max_step_halvings: u32,
    /// Whether the integrator keeps its Newton factorisation across steps (`[scene] newton_matrix
    /// = "reuse"`; default false, docs/method.md §5).
    pub reuse_newton_matrix: bool,
    /// Gravity in the world frame, m/s² (applied only when `effects.gravity`).
    pub gravity: [f64; 3],
    /// Simulated effects.
    pub effects: EffectSet,
    /// Joint springs.
    pub springs: Vec<JointSpring>,
    /// Initial positions, dim `nq`.
    pub initial_q: Vec<f64>,
    /// Initial velocities, dim `nv`.
    pub initial_v: Vec<f64>,
    /// The position coordinates the sidecar gave (`initial.q`, `initial.base`), ascending: the
    /// start projection reports when it changes them ([`crate::simulate::check_start`]).
    pub initial_q_given: Vec<usize>,
    /// The velocity coordinates the sidecar gave (`initial.v`, `initial.base`), ascending: the
    /// start projection reports when it changes them ([`crate::simulate::check_start`]).
    pub initial_v_given: Vec<usize>,
    /// Constraint rows: loops, URDF mimic joints, drives.
    pub constraints: crate::constraints::ConstraintSet,
    /// Recorded outputs, in order.
    pub outputs: Vec<Output>,
    /// `[scene.contact]` and `[[scene.geometry]]` (`None`: no contacts, nothing is ever queried).
    pub contact: Option<SceneContacts>,
    /// Recording rate, Hz.
    pub rate_hz: f64,
    /// Steps between records.
    pub record_every: usize,
    /// Where duration, step and α came from (for messages).
    pub origins: SceneOrigins,
}

/// The sidecar beside a URDF: `robots/ur5/ur5.urdf` → `robots/ur5/ur5.uncertainty.toml`.
pub fn default_sidecar_path(urdf: &Path) -> PathBuf {
    urdf.with_extension("uncertainty.toml")
}

/// Whether the sidecar asks for a floating base (`[scene] base`).
pub fn wants_floating_base(file: &SidecarFile, path: &str) -> Result<bool, SceneError> {
    match file.scene.base.as_deref() {
        None | Some("fixed") => Ok(false),
        Some("floating") => Ok(true),
        Some(other) => Err(SceneError::Invalid {
            path: path.to_string(),
            key: "[scene] base".to_string(),
            message: format!("'{other}' is not a base type; use \"fixed\" or \"floating\""),
        }),
    }
}

impl Scene {
    /// Resolves the sidecar's `[scene]` and `[outputs]` against `model`; `path` names the sidecar in
    /// messages.
    pub fn resolve(
        file: &SidecarFile,
        model: &Model,
        path: &str,
        overrides: SceneOverrides,
    ) -> Result<Scene, SceneError> {
        let invalid = |key: &str, message: String| SceneError::Invalid {
            path: path.to_string(),
            key: key.to_string(),
            message,
        };
        let s = &file.scene;
        let origins = SceneOrigins {
            sidecar: path.to_string(),
            duration: Origin::of(overrides.duration_s, "--duration", "[scene] duration"),
            step: Origin::of(overrides.step_s, "--step", "[scene] step"),
            alpha: Origin::of(overrides.alpha, "--alpha", "[scene] alpha"),
        };
        let duration_s = overrides
            .duration_s
            .or(s.duration)
            .unwrap_or(DEFAULT_DURATION_S);
        let step_s = overrides.step_s.or(s.step).unwrap_or(DEFAULT_STEP_S);
        let alpha = overrides.alpha.or(s.alpha).unwrap_or(DEFAULT_ALPHA);
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(origins
                .duration
                .error(path, format!("{duration_s} s must be a finite number > 0")));
        }
        if !(step_s.is_finite() && step_s > 0.0) {
            return Err(origins
                .step
                .error(path, format!("{step_s} s must be a finite number > 0")));
        }
        // The range alone here (no rows yet); the rows' stricter limit is checked once they are known.
        if check_alpha(alpha, 0).is_err() {
            return Err(origins.alpha.error(
                path,
                format!("{alpha} is outside the HHT range [-1/3, 0] (default -0.1)"),
            ));
        }
        // The step count is checked before it is used as a size: a subnormal step or a huge
        // duration is refused with the numbers, never run "forever".
        let steps = check_step_count(duration_s, step_s).map_err(|message| {
            let origin = match origins.step {
                Origin::Flag(_) => origins.step,
                Origin::Key(_) if step_s < MIN_STEP_S => origins.step,
                Origin::Key(_) => origins.duration,
            };
            origin.error(path, message)
        })?;
        let n_steps = steps.round() as usize;
        if n_steps == 0 || (steps - n_steps as f64).abs() > DIVISIBILITY_TOLERANCE * steps {
            let origin = match (origins.duration, origins.step) {
                (Origin::Key(_), Origin::Flag(_)) => origins.step,
                _ => origins.duration,
            };
            return Err(origin.error(
                path,
                format!("{duration_s} s is not a whole number of steps of {step_s} s"),
            ));
        }
        let rate_hz = file.outputs.rate.unwrap_or(DEFAULT_RATE_HZ);
        let per_record = 1.0 / (rate_hz * step_s);
        let record_every = per_record.round() as usize;
        if !(rate_hz.is_finite() && rate_hz > 0.0)
            || record_every == 0
            || (per_record - record_every as f64).abs() > DIVISIBILITY_TOLERANCE * per_record
        {
            let step_note = match origins.step {
                Origin::Flag(flag) => format!(" (the step {step_s} s is from {flag})"),
                Origin::Key(_) => String::new(),
            };
            return Err(invalid(
                "[outputs] rate",
                format!(
                    "{rate_hz} Hz must divide 1/step = {} Hz (a whole number of steps between records){step_note}",
                    1.0 / step_s
                ),
            ));
        }
        let gravity = s.gravity.unwrap_or(crate::environment::DEFAULT_GRAVITY);
        if gravity.iter().any(|g| !g.is_finite()) {
            return Err(invalid(
                "[scene] gravity",
                "every component must be finite".to_string(),
            ));
        }
        let mut effects = EffectSet::default();
        for name in s
            .effects
            .clone()
            .unwrap_or_else(|| vec!["gravity".to_string()])
        {
            match name.as_str() {
                "gravity" => effects.gravity = true,
                "joint_damping" => effects.joint_damping = true,
                "joint_friction" => effects.joint_friction = true,
                "joint_springs" => effects.joint_springs = true,
                "joint_limits" => effects.joint_limits = true,
                other => {
                    return Err(invalid(
                        "[scene] effects",
                        format!(
                            "unknown effect '{other}'{}; known: {}",
                            closest_suggestion(other, EFFECT_NAMES),
                            EFFECT_NAMES.join(", ")
                        ),
                    ))
                }
            }
        }
        let constraints = constraints::resolve(&s.drive, &s.loops, model, path)?;
        // In range by now, so a refusal is α too close to 0 (or 0) for constraint rows.
        if check_alpha(alpha, constraints.len()).is_err() {
            return Err(origins.alpha.error(
                path,
                format!(
                    "alpha = {alpha} is refused with constraint rows ({} here): |alpha| must be at least {ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS} (alpha ≤ -{ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS}) — closer to 0 the start transient of the accelerations and multipliers is barely damped and constraint forces come out wrong by up to 10× (docs/method.md §5); use alpha in [-1/3, -{ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS}], e.g. the default -0.1",
                    constraints.len()
                ),
            ));
        }
        let one_dof_joint = |key: &str, name: &str| -> Result<usize, SceneError> {
            let index = model.joint_index(name).ok_or_else(|| {
                invalid(
                    key,
                    format!(
                        "unknown joint '{name}'{}",
                        closest_suggestion(name, model.joints.iter().map(|j| j.name.as_str()))
                    ),
                )
            })?;
            if model.joints[index].kind == JointKind::Floating {
                return Err(invalid(
                    key,
                    format!("joint '{name}' is floating; set its state with initial.base"),
                ));
            }
            Ok(index)
        };
        let mut springs = Vec::with_capacity(s.spring.len());
        for spring in &s.spring {
            let joint = one_dof_joint("[[scene.spring]] joint", &spring.joint)?;
            let non_negative = |x: f64| x.is_finite() && x >= 0.0;
            if !(non_negative(spring.stiffness)
                && non_negative(spring.damping)
                && spring.rest.is_finite())
            {
                return Err(invalid(
                    "[[scene.spring]]",
                    format!(
                        "joint '{}': stiffness and damping must be finite and ≥ 0, rest finite",
                        spring.joint
                    ),
                ));
            }
            springs.push(JointSpring {
                joint,
                stiffness: spring.stiffness,
                rest: spring.rest,
                damping: spring.damping,
            });
        }
        if !springs.is_empty() && !effects.joint_springs {
            return Err(invalid(
                "[scene] effects",
                "[[scene.spring]] entries are declared but 'joint_springs' is not in effects; add it (or remove the springs)"
                    .to_string(),
            ));
        }
        let mut initial_q = model.neutral_configuration();
        let mut initial_v = vec![0.0; model.nv];
        let mut initial_q_given = Vec::new();
        for (name, value) in &s.initial.q {
            let j = one_dof_joint("[scene] initial.q", name)?;
            initial_q[model.joints[j].q_index] = *value;
            initial_q_given.push(model.joints[j].q_index);
        }
        // A mimic joint left out starts where its row puts it, not at its neutral position: the
        // least-norm start projection would move the given leader too (bullet3's xarm6 gripper,
        // its drive joint given at 0.425 rad and five followers at 0, started all six at
        // 0.425 / 6 = 0.0708 rad, and the springs of `ribbon init`'s starter, meant to hold the
        // pose, pulled the gripper 0.34 rad open in the first 0.2 s; docs/method.md §5).
        model.place_mimic_followers(&mut initial_q, &initial_q_given);
        let mut initial_v_given = Vec::new();
        for (name, value) in &s.initial.v {
            let j = one_dof_joint("[scene] initial.v", name)?;
            initial_v[model.joints[j].v_index] = *value;
            initial_v_given.push(model.joints[j].v_index);
        }
        if let Some(base) = &s.initial.base {
            let root = model
                .joints
                .iter()
                .find(|j| j.kind == JointKind::Floating && j.parent.is_none())
                .ok_or_else(|| {
                    invalid(
                        "[scene] initial.base",
                        "the robot has no floating base; set base = \"floating\" or remove initial.base".to_string(),
                    )
                })?;
            let rotation = nalgebra::Rotation3::from_matrix_unchecked(rotation_from_rpy(
                base.rpy[0],
                base.rpy[1],
                base.rpy[2],
            ));
            let quaternion = nalgebra::UnitQuaternion::from_rotation_matrix(&rotation);
            let (qi, vi) = (root.q_index, root.v_index);
            initial_q[qi..qi + 3].copy_from_slice(&base.xyz);
            write_xyzw(quaternion.quaternion(), &mut initial_q[qi + 3..qi + 7]);
            initial_v[vi..vi + 3].copy_from_slice(&base.v);
            initial_v[vi + 3..vi + 6].copy_from_slice(&base.w);
            initial_v_given.extend(vi..vi + 6);
            initial_q_given.extend(qi..qi + 7);
        }
        if initial_q.iter().chain(&initial_v).any(|x| !x.is_finite()) {
            return Err(invalid(
                "[scene] initial",
                "every value must be finite".to_string(),
            ));
        }
        if effects.joint_limits {
            check_initial_q_inside_limits(model, &initial_q, &s.initial.q, &invalid)?;
        }
        let step_values = step_control::resolve(s, effects.joint_limits, step_s, path)?;
        let mut outputs = outputs::resolve(&file.outputs, model, &constraints, path)?;
        let contact = contacts::resolve(s.contact.as_ref(), &s.geometry, model, path)?;
        outputs::add_contact_outputs(&file.outputs, contact.as_ref(), model, path, &mut outputs)?;
        if outputs.is_empty() {
            // A run with nothing to report would spend its time and print an empty table.
            let (why, or) = if model.nv == 0 {
                let joints = model.description.joints.len();
                (
                    format!(
                        "the robot has no moving joint ({joints} joint{} in the URDF, all fixed, and a fixed base) and [outputs] declares no frames",
                        if joints == 1 { "" } else { "s" }
                    ),
                    "set [scene] base = \"floating\" for a robot that flies or floats",
                )
            } else {
                (
                    "[outputs] selects no joints and declares no frames, constraint forces or contact outputs".to_string(),
                    "joints = \"all\"",
                )
            };
            return Err(invalid(
                "[outputs]",
                format!(
                    "nothing to output: {why}; declare frames = [\"LINK\", …] in [outputs], or {or}"
                ),
            ));
        }
        Ok(Scene {
            contact,
            duration_s,
            step_s,
            n_steps,
            alpha,
            velocity_projection: s.velocity_projection.unwrap_or(true),
            step_control: step_values.control,
            step_tolerance: step_values.tolerance,
            limit_restitution: step_values.limit_restitution,
            max_step_halvings: step_values.max_step_halvings,
            reuse_newton_matrix: step_values.reuse_newton_matrix,
            gravity,
            effects,
            springs,
            initial_q,
            initial_v,
            initial_q_given: {
                initial_q_given.sort_unstable();
                initial_q_given
            },
            initial_v_given: {
                initial_v_given.sort_unstable();
                initial_v_given
            },
            constraints,
            outputs,
            rate_hz,
            record_every,
            origins,
        })
    }

    /// The environment the scene puts its robot in: its gravity (even when the `gravity` effect is
    /// not declared: [`crate::simulate::RobotSystem::new`] zeroes it then) and its contact
    /// material. Parameters (`scene.gravity.*`, `scene.contact.*`) override these values.
    pub fn environment(&self) -> Environment {
        Environment {
            gravity: crate::spatial::Vec3::from(self.gravity),
            contact: self.contact.as_ref().map(|c| c.material),
        }
    }

    /// Whether step `k` (0 ..= n_steps) is recorded: every `record_every` steps, plus the last.
    pub fn records_step(&self, k: usize) -> bool {
        k.is_multiple_of(self.record_every) || k == self.n_steps
    }
}

/// With `joint_limits`, every limited 1-dof joint (not a mimic follower, whose start the
/// constraint sets) must start inside its URDF range: a start outside it puts the penalty spring
/// radians deep at t = 0 and throws the joint back at tens of rad/s (example-robot-data's Kinova
/// arm, whose neutral configuration is 0.8 rad outside two of its ranges, failed 0.13 s in; the
/// Panda's, outside `panda_joint4`'s, was flung back silently). Every joint outside is named at
/// once, with an `initial.q` that starts each on its nearest limit. `given` are the `initial.q`
/// entries, to name the key a value came from.
fn check_initial_q_inside_limits(
    model: &Model,
    initial_q: &[f64],
    given: &std::collections::BTreeMap<String, f64>,
    invalid: &dyn Fn(&str, String) -> SceneError,
) -> Result<(), SceneError> {
    let mut outside = Vec::new();
    let mut suggestion = Vec::new();
    let mut any_given = false;
    for joint in &model.joints {
        let Some(source) = joint.source else {
            continue;
        };
        if joint.kind == JointKind::Floating || joint.mimic.is_some() {
            continue;
        }
        let [lower, upper] = model.description.joints[source].limits;
        if !(lower.is_finite() && upper.is_finite() && lower < upper) {
            continue;
        }
        let x = initial_q[joint.q_index];
        if (lower..=upper).contains(&x) {
            continue;
        }
        let name = &joint.name;
        let from = if given.contains_key(name) {
            any_given = true;
            "initial.q"
        } else {
            "the neutral configuration"
        };
        outside.push(format!(
            "'{name}' at {x} ({from}) outside [{lower}, {upper}]"
        ));
        suggestion.push(format!("\"{name}\" = {}", x.clamp(lower, upper)));
    }
    if outside.is_empty() {
        return Ok(());
    }
    let key = if any_given {
        "[scene] initial.q"
    } else {
        "[scene] effects"
    };
    Err(invalid(
        key,
        format!(
            "'joint_limits' is declared, but {} joint(s) start outside their URDF limits, where the limit would throw them back at t = 0: {}; start them inside, e.g. [scene] initial.q = {{ {} }} (each on its nearest limit)",
            outside.len(),
            outside.join(", "),
            suggestion.join(", ")
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions};

    fn pendulum() -> Model {
        let text = r#"<robot name="p"><link name="w"/>
          <link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="0.08" iyz="0" izz="0.08"/></inertial></link>
          <joint name="hinge" type="revolute"><parent link="w"/><child link="bar"/><axis xyz="0 0 1"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
        Model::from_description(
            parse_description(text, "p.urdf").unwrap(),
            LoadOptions::default(),
            "p.urdf",
        )
        .unwrap()
    }

    fn resolve(text: &str) -> Result<Scene, SceneError> {
        let file = parse_sidecar(text).map_err(|message| SceneError::Invalid {
            path: "s.toml".into(),
            key: "(parse)".into(),
            message,
        })?;
        Scene::resolve(&file, &pendulum(), "s.toml", SceneOverrides::default())
    }

    /// Two limited joints whose neutral configuration (0) is outside both ranges, one free, and a
    /// mimic follower outside its range (its start is the constraint's).
    fn arm_outside_its_limits() -> Model {
        let link = |name: &str| {
            format!(
                r#"<link name="{name}"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
                <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.08" iyz="0" izz="0.08"/></inertial></link>"#
            )
        };
        let joint = |name: &str, parent: &str, child: &str, extra: &str| {
            format!(
                r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
                <origin xyz="1 0 0"/><axis xyz="0 0 1"/>{extra}</joint>"#
            )
        };
        let text = format!(
            r#"<robot name="a"><link name="w"/>{}{}{}{}{}{}{}{}</robot>"#,
            link("l1"),
            link("l2"),
            link("l3"),
            link("l4"),
            joint(
                "shoulder",
                "w",
                "l1",
                r#"<limit lower="0.5" upper="2" effort="1" velocity="1"/>"#
            ),
            joint(
                "elbow",
                "l1",
                "l2",
                r#"<limit lower="-2" upper="-0.1" effort="1" velocity="1"/>"#
            ),
            joint("wrist", "l2", "l3", ""),
            joint(
                "finger",
                "l3",
                "l4",
                r#"<limit lower="0.2" upper="1" effort="1" velocity="1"/><mimic joint="wrist"/>"#
            ),
        );
        Model::from_description(
            parse_description(&text, "a.urdf").unwrap(),
            LoadOptions::default(),
            "a.urdf",
        )
        .unwrap()
    }

    #[test]
    fn a_mimic_follower_left_out_of_initial_q_starts_at_its_leader() {
        let model = arm_outside_its_limits();
        let resolve_on = |text: &str| {
            let file = parse_sidecar(text).unwrap();
            Scene::resolve(&file, &model, "s.toml", SceneOverrides::default()).unwrap()
        };
        let q_of = |scene: &Scene, name: &str| {
            scene.initial_q[model.joints[model.joint_index(name).unwrap()].q_index]
        };
        // `finger` mimics `wrist` (multiplier 1, offset 0).
        let scene = resolve_on("[scene]\ninitial.q = { wrist = 0.7 }\n");
        assert_eq!(q_of(&scene, "finger"), 0.7);
        assert_eq!(q_of(&scene, "wrist"), 0.7);
        // Given, it is left as given (the start projection reports what it moves).
        let scene = resolve_on("[scene]\ninitial.q = { wrist = 0.7, finger = 0.3 }\n");
        assert_eq!(q_of(&scene, "finger"), 0.3);
        let finger = model.joints[model.joint_index("finger").unwrap()].q_index;
        assert!(scene.initial_q_given.contains(&finger));
    }

    #[test]
    fn joint_limits_refuse_a_start_outside_them_naming_every_joint() {
        let model = arm_outside_its_limits();
        let resolve_on = |text: &str| {
            let file = parse_sidecar(text).unwrap();
            Scene::resolve(&file, &model, "s.toml", SceneOverrides::default())
        };
        let limits = "[scene]\neffects = [\"joint_limits\"]\n";
        let message = resolve_on(limits).unwrap_err().to_string();
        assert!(
            message.contains("s.toml: [scene] effects")
                && message.contains("2 joint(s)")
                && message.contains("'shoulder' at 0 (the neutral configuration) outside [0.5, 2]")
                && message.contains("'elbow' at 0 (the neutral configuration) outside [-2, -0.1]")
                && message.contains(r#"initial.q = { "shoulder" = 0.5, "elbow" = -0.1 }"#)
                && !message.contains("finger")
                && !message.contains("wrist"),
            "{message}"
        );
        // A value given outside its range names initial.q; the suggestion, applied, resolves.
        let message = resolve_on(&format!(
            "{limits}initial.q = {{ shoulder = 3.0, elbow = -1.0 }}\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            message.contains("[scene] initial.q")
                && message.contains("'shoulder' at 3 (initial.q) outside [0.5, 2]")
                && !message.contains("elbow"),
            "{message}"
        );
        let suggested = format!("{limits}initial.q = {{ \"shoulder\" = 0.5, \"elbow\" = -0.1 }}\n");
        assert!(resolve_on(&suggested).is_ok());
        // Without the effect the start is the user's business.
        assert!(resolve_on("[scene]\neffects = [\"gravity\"]\n").is_ok());
    }

    #[test]
    fn defaults() {
        let scene = resolve("").unwrap();
        assert_eq!((scene.n_steps, scene.record_every), (1000, 10));
        assert!(scene.effects.gravity && !scene.effects.joint_damping);
        assert_eq!(scene.outputs.len(), 1);
        assert_eq!(scene.outputs[0].name, "q.hinge");
    }

    #[test]
    fn bad_values_are_named() {
        let cases = [
            (
                "[scene]\nstep = 0.0",
                "[scene] step: 0 s must be a finite number > 0",
            ),
            ("[scene]\nduration = -1.0", "[scene] duration: -1 s must be"),
            (
                "[scene]\nalpha = 0.2",
                "[scene] alpha: 0.2 is outside the HHT range",
            ),
            (
                "[outputs]\nrate = 300",
                "[outputs] rate: 300 Hz must divide 1/step = 1000 Hz",
            ),
            (
                "[scene]\neffects = [\"gravity\", \"joint_dampin\"]",
                "unknown effect 'joint_dampin'; did you mean 'joint_damping'?",
            ),
            (
                "[scene]\ninitial.q = { hinj = 0.1 }",
                "[scene] initial.q: unknown joint 'hinj'; did you mean 'hinge'?",
            ),
            ("[[scene.drive]]\njoint = \"hinj\"\nprofile = \"constant\"\nvalue = 0.0", "unknown joint 'hinj'; did you mean 'hinge'?"),
            ("[[scene.drive]]\njoint = \"hinge\"\nprofile = \"ramp\"\nvalue = 0.0", "profile 'ramp' needs `rate`"),
            ("[[scene.drive]]\njoint = \"hinge\"\nprofile = \"sin\"", "unknown profile 'sin'; did you mean 'sine'?"),
            ("[scene]\nalpha = 0.0\n[[scene.drive]]\njoint = \"hinge\"\nprofile = \"constant\"\nvalue = 0.0", "alpha = 0 is refused with constraint rows"),
            ("[[scene.loop]]\nname = \"c\"\ntype = \"planar_pin\"\nparent = \"world\"\nchild = \"bar\"", "type 'planar_pin' needs `normal`"),
            ("[[scene.loop]]\nname = \"c\"\ntype = \"hinge\"\nparent = \"world\"\nchild = \"bar\"", "unknown type 'hinge'"),
            ("[[scene.loop]]\nname = \"c\"\ntype = \"ball\"\nparent = \"wrld\"\nchild = \"bar\"", "unknown parent link 'wrld'"),
            ("[[scene.loop]]\nname = \"c\"\ntype = \"ball\"\nparent = \"w\"\nchild = \"w\"", "belong to the same rigid body"),
            (
                "[[scene.spring]]\njoint = \"hinge\"\nstiffness = 10.0",
                "'joint_springs' is not in effects",
            ),
            ("[scene]\nduration = 0.0015", "not a whole number of steps"),
        ];
        for (text, expected) in cases {
            let msg = resolve(text).unwrap_err().to_string();
            assert!(msg.contains(expected), "for {text:?}: {msg}");
        }
        let msg = resolve("[scene]\nstpe = 0.1").unwrap_err().to_string();
        assert!(msg.contains("stpe") && msg.contains("line 2"), "{msg}");
    }

    #[test]
    fn flags_are_blamed_not_the_sidecar() {
        let with = |overrides: SceneOverrides, text: &str| {
            let file = parse_sidecar(text).unwrap();
            Scene::resolve(&file, &pendulum(), "s.toml", overrides)
                .unwrap_err()
                .to_string()
        };
        let step = SceneOverrides {
            step_s: Some(-1e-3),
            ..SceneOverrides::default()
        };
        assert_eq!(
            with(step, ""),
            "--step: -0.001 s must be a finite number > 0"
        );
        let duration = SceneOverrides {
            duration_s: Some(f64::INFINITY),
            ..SceneOverrides::default()
        };
        assert!(with(duration, "").starts_with("--duration: inf s"));
        let alpha = SceneOverrides {
            alpha: Some(-0.5),
            ..SceneOverrides::default()
        };
        assert!(with(alpha, "").starts_with("--alpha: -0.5 is outside"));
        // A sidecar duration that --step does not divide blames the flag.
        let step = SceneOverrides {
            step_s: Some(0.3),
            ..SceneOverrides::default()
        };
        let m = with(step, "[scene]\nduration = 1.0");
        assert!(
            m.starts_with("--step: 1 s is not a whole number of steps of 0.3 s"),
            "{m}"
        );
        // The sidecar's own values are still blamed on the sidecar.
        let m = with(SceneOverrides::default(), "[scene]\nstep = -1.0");
        assert!(m.starts_with("s.toml: [scene] step: -1 s"), "{m}");
    }

    #[test]
    fn hopeless_sizes_are_refused_with_the_numbers() {
        let m = resolve("[scene]\nstep = 5e-324").unwrap_err().to_string();
        assert!(
            m.contains("[scene] step") && m.contains("below the smallest step"),
            "{m}"
        );
        let m = resolve("[scene]\nduration = 1e12").unwrap_err().to_string();
        assert!(
            m.contains("[scene] duration") && m.contains("1.000e15 steps"),
            "{m}"
        );
        let scene = resolve("[scene]\nduration = 1e5\nstep = 1e-4").unwrap();
        assert_eq!(scene.record_count(), 10_000_001);
        let m = scene
            .check_memory("simulate", 10_000, 0)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("10000001 record times") && m.contains("745.1 GiB") && m.contains("4.0 GiB"),
            "{m}"
        );
        assert_eq!(scene.check_memory("simulate", 2, 0).unwrap(), 160_000_016);
    }

    #[test]
    fn alpha_near_zero_is_refused_with_constraint_rows() {
        let drive = "[[scene.drive]]\njoint = \"hinge\"\nprofile = \"constant\"\nvalue = 0.0";
        for alpha in ["-1e-9", "-0.01", "-0.049"] {
            let m = resolve(&format!("[scene]\nalpha = {alpha}\n{drive}"))
                .unwrap_err()
                .to_string();
            assert!(m.contains("|alpha| must be at least 0.05"), "{m}");
        }
        assert!(resolve(&format!("[scene]\nalpha = -0.05\n{drive}")).is_ok());
        // Without constraint rows every alpha of the HHT range is accurate.
        assert!(resolve("[scene]\nalpha = -1e-9").is_ok());
    }

    #[test]
    fn an_output_named_twice_is_refused() {
        let m = resolve("[outputs]\njoints = [\"hinge\", \"hinge\"]")
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("[outputs] joints") && m.contains("'q.hinge' would be recorded twice"),
            "{m}"
        );
        let m = resolve("[outputs]\nframes = [\"bar\", \"bar\"]")
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("[outputs] frames") && m.contains("a link listed twice"),
            "{m}"
        );
    }

    #[test]
    fn records_every_step_and_the_last() {
        let scene = resolve("[scene]\nduration = 0.025\n[outputs]\nrate = 100").unwrap();
        let recorded: Vec<usize> = (0..=scene.n_steps)
            .filter(|k| scene.records_step(*k))
            .collect();
        assert_eq!(recorded, vec![0, 10, 20, 25]);
    }
}
