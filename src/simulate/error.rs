//! [`SimulationError`]: why a run failed, in the robot's words — the joint, link, loop or drive to
//! blame and the likely cause — and whether the input is at fault (exit 2: the run cannot even
//! start) or the run failed on its way (exit 1).

use crate::constraints::ConstraintSet;
use crate::dynamics::{crba, joint_of_velocity, Data};
use crate::integrate::{IntegrateError, WorstEntry};
use crate::model::{JointKind, Model};
use crate::scene::Scene;

/// Why a run failed, with the constraint rows and joints named.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    /// The declared constraints cannot hold: they cannot be closed from the initial state, or some
    /// rows are redundant. Bad input.
    #[error("{message}")]
    Constraints {
        /// What is wrong, naming the loop, drive or mimic joint.
        message: String,
    },
    /// The model cannot be simulated from its initial state (a singular mass matrix at t = 0):
    /// bad input.
    #[error("the run cannot start: {message}")]
    Start {
        /// What is wrong, naming the joints and links and the likely cause.
        message: String,
    },
    /// The integration failed (divergence, NaN, singular matrix), with the row or joint named when
    /// one is to blame.
    #[error("simulation failed: {message}")]
    Integrate {
        /// The integrator's error (names time and step).
        source: IntegrateError,
        /// The integrator's message in the robot's words: joints instead of coordinate numbers,
        /// rows by name, and the likely cause.
        message: String,
    },
}

/// What a failed run knew, so that its error can name joints and causes.
#[derive(Clone, Copy, Debug)]
pub struct FailureContext<'a> {
    /// The model that was simulated (its parameters applied).
    pub model: &'a Model,
    /// The scene.
    pub scene: &'a Scene,
    /// The last configuration reached (the initial one for a failure at the start), dim `nq`.
    pub q: &'a [f64],
    /// `max |Φ(q0)|` of the initial state (see [`super::initial_violation`]).
    pub initial_violation: f64,
}

/// Above this `max |Φ(q0)|` (m or rad) the initial state is "not closed": the start projection has
/// real work to do, and rows that turn dependent during it mean the loop cannot close.
const CLOSED_AT_START: f64 = 1e-6;

/// A joint whose column of the mass matrix is below this fraction of its largest diagonal entry
/// moves (practically) no mass or inertia: a pivot that small is what the factorisations call
/// singular too (`SINGULAR_PIVOT_RELATIVE` is 1e-13 relative to the largest entry).
const MASSLESS_RELATIVE: f64 = 1e-10;

/// A coordinate takes part in a singular motion when its component in the null vector is at least
/// this fraction of the largest component.
const NULL_MOTION_SHARE: f64 = 0.1;

/// A combined motion of two or more joints is "nearly dependent" (their motions nearly the same,
/// as in a gimbal lock) when the inertia it moves — the smallest eigenvalue of `M` — is below this
/// fraction of the smallest effective inertia `M_jj` of the joints taking part: a light link moved
/// by one joint alone has a small eigenvalue too, but close to its own `M_jj`. 1e-2 is two joint
/// motions within ~8° of each other (measured: example-robot-data's human, whose shoulders and
/// hips are three revolute joints with massless links between, fails at 5e-3 and 4e-7).
const NEARLY_DEPENDENT_MOTION: f64 = 1e-2;

impl SimulationError {
    /// The exit code: 2 when the input is at fault — the constraints cannot hold, or the run fails
    /// at its start (step 0: the initial state, its projection, the initial acceleration) — and 1
    /// when a run that started fails later.
    pub fn exit_code(&self) -> u8 {
        match self {
            SimulationError::Constraints { .. } | SimulationError::Start { .. } => 2,
            SimulationError::Integrate { source, .. } => integrate_exit_code(source),
        }
    }

    /// Names the rows an integrator error points at (without the model: row names only). Prefer
    /// [`from_failure`](Self::from_failure), which also names joints and likely causes.
    /// `initial_violation` is `max |Φ(q0)|`: rows that become dependent while a far-off loop is
    /// being closed mean the loop cannot close (the projection stretched the linkage into a
    /// singular pose), not that the rows are redundant.
    pub fn from_integrate(
        source: IntegrateError,
        constraints: &ConstraintSet,
        initial_violation: f64,
    ) -> SimulationError {
        match &source {
            IntegrateError::RedundantConstraints { row, .. } if initial_violation > CLOSED_AT_START => {
                SimulationError::Constraints {
                    message: format!(
                        "the constraints cannot be closed from the initial state: {} is violated by {initial_violation:.3e} at t = 0 and the rows become dependent while closing it (the linkage stretches into a singular pose: the points cannot meet); check the loop's points, link lengths and initial.q ({source})",
                        constraints.row_name(*row)
                    ),
                }
            }
            IntegrateError::CannotClose { worst_row, violation, .. } => SimulationError::Constraints {
                message: format!(
                    "the constraints cannot be closed from the initial state: {} is still violated by {violation:.3e} after the start projection; check the loop's points and initial.q ({source})",
                    constraints.row_name(*worst_row)
                ),
            },
            IntegrateError::RedundantConstraints { row, .. } => SimulationError::Constraints {
                message: format!(
                    "redundant constraint rows: {} depends on the others; declare loops with the rows they really constrain (a planar pin is 2 rows, not a 3-row ball), and do not drive a joint that a loop or mimic already fixes ({source})",
                    constraints.row_name(*row)
                ),
            },
            IntegrateError::NewtonNotConverged { worst: WorstEntry::Constraint { index: row, .. }, .. } => {
                let message = format!("{source}; worst row: {}", constraints.row_name(*row));
                SimulationError::Integrate { source, message }
            }
            _ => SimulationError::Integrate {
                message: source.to_string(),
                source,
            },
        }
    }

    /// Names the joints, links, loops and drives an integrator error points at, with the likely
    /// cause: a singular mass matrix at the start becomes [`SimulationError::Start`] naming the
    /// motion that moves no inertia (a massless floating root, a massless leaf), a Newton failure
    /// names the joint instead of "velocity coordinate N" (with its effective inertia, and its
    /// spring's period against the step when it has one), a drive row names its joint.
    pub fn from_failure(source: IntegrateError, context: &FailureContext) -> SimulationError {
        let FailureContext {
            model,
            scene,
            q,
            initial_violation,
        } = *context;
        if let IntegrateError::SingularMatrix { step, index, .. } = &source {
            if singular_mass_motion(model, q).is_none() && !scene.constraints.is_empty() {
                // M is regular: the column where elimination broke down names the unknown, a
                // joint's acceleration or a row's multiplier (LU pivots rows, not columns).
                let at = match index.checked_sub(model.nv) {
                    None => format!("joint {}", coordinate_name(model, *index)),
                    Some(row) => format!(
                        "{}{}",
                        scene.constraints.row_name(row),
                        drive_joint(model, &scene.constraints, row)
                    ),
                };
                let message = format!(
                    "{source}; it breaks down at {at}. Likely cause: the constraint rows are (nearly) dependent here — the linkage is at or near a singular pose (a dead point), or the step of {} s is too large for the motion: try a smaller --step",
                    scene.step_s
                );
                return if *step == 0 {
                    SimulationError::Constraints { message }
                } else {
                    SimulationError::Integrate { source, message }
                };
            }
            if let Some((motion, causes)) = singular_mass_motion(model, q) {
                let at_start = *step == 0;
                let negative = negative_inertia_causes(model);
                let body = if negative.is_empty() {
                    format!(
                        "the mass matrix is singular{}: {motion} moves no mass or inertia{}{causes}",
                        if at_start { " at the initial state" } else { "" },
                        if causes.is_empty() {
                            "; give the links it moves an <inertial>"
                        } else {
                            ": "
                        },
                    )
                } else {
                    format!(
                        "the mass matrix is not positive definite{}: {motion} moves a negative mass or inertia: {} (from the URDF or the parameter values of this run; a mass or an inertia must be positive: narrow the box or fix the value)",
                        if at_start { " at the initial state" } else { "" },
                        negative.join("; ")
                    )
                };
                return if at_start {
                    SimulationError::Start {
                        message: format!("{body} ({source})"),
                    }
                } else {
                    SimulationError::Integrate {
                        message: format!("{source}; {body}"),
                        source,
                    }
                };
            }
        }
        match &source {
            IntegrateError::NewtonNotConverged {
                worst:
                    worst @ WorstEntry::Coordinate {
                        index,
                        weighted_correction,
                    },
                ..
            } => {
                // "velocity coordinate N (…)" becomes the joint's name, with the likely cause.
                let (name, details, cause) = describe_coordinate(model, scene, q, *index);
                // Joints whose motions line up (a gimbal lock) explain the failure better than the
                // step size does.
                let cause = nearly_dependent_motion(model, q).unwrap_or(cause);
                let joint = format!(
                    "{name} (velocity coordinate {index}, weighted correction {weighted_correction:.3e}{details})"
                );
                let mut message = format!(
                    "{}. Likely cause: {cause}",
                    source.to_string().replace(&worst.to_string(), &joint)
                );
                if scene.contact.is_some()
                    && scene.step_control == crate::integrate::StepControl::Fixed
                {
                    // docs/contacts.md §6: a touch-down, or a sliding contact coming to stick, changes
                    // the contact's slope by orders of magnitude within one fixed step.
                    message.push_str(
                        ". With contacts declared, the fixed step often fails like this at a touch-down or where a sliding contact sticks (docs/contacts.md §6): set [scene] step_control = \"adaptive\", which retries such steps at half size, or a larger [scene.contact] stiction_velocity",
                    );
                } else if scene.effects.joint_limits
                    && scene.step_control == crate::integrate::StepControl::Fixed
                {
                    if let Some(at_limit) = joint_at_limit(model, q) {
                        // Just after a plastic impact the rest of the arm whips on (found on the
                        // SO-101 arm: fixed 2 ms fails, 1 ms and adaptive 2 ms run).
                        message.push_str(&format!(
                            ". Joint '{at_limit}' is at its limit: just after a joint stops at its limit the rest of the mechanism can move faster than one fixed step resolves; set [scene] step_control = \"adaptive\", which retries such steps at smaller sizes (or take a smaller --step)"
                        ));
                    }
                }
                SimulationError::Integrate { source, message }
            }
            IntegrateError::NewtonNotConverged {
                worst: WorstEntry::Constraint { index: row, .. },
                ..
            } => {
                let message = format!(
                    "{source}; worst row: {}{}",
                    scene.constraints.row_name(*row),
                    drive_joint(model, &scene.constraints, *row)
                );
                SimulationError::Integrate { source, message }
            }
            IntegrateError::RedundantConstraints { row, .. }
            | IntegrateError::CannotClose { worst_row: row, .. } => {
                let joint = drive_joint(model, &scene.constraints, *row);
                match Self::from_integrate(source, &scene.constraints, initial_violation) {
                    SimulationError::Constraints { message } => SimulationError::Constraints {
                        message: if joint.is_empty() {
                            message
                        } else {
                            format!("{message}; the row is the drive{joint}")
                        },
                    },
                    other => other,
                }
            }
            _ => Self::from_integrate(source, &scene.constraints, initial_violation),
        }
    }
}

/// 2 for an integrator error at the start (step 0) or a settings error, 1 otherwise.
pub fn integrate_exit_code(source: &IntegrateError) -> u8 {
    match source {
        IntegrateError::InvalidAlpha { .. }
        | IntegrateError::AlphaZeroWithConstraints { .. }
        | IntegrateError::AlphaTooCloseToZero { .. }
        | IntegrateError::InvalidStep { .. }
        | IntegrateError::InvalidSetting { .. }
        | IntegrateError::DimensionMismatch { .. }
        | IntegrateError::CannotClose { .. }
        | IntegrateError::RedundantConstraints { .. } => 2,
        IntegrateError::System { step, .. }
        | IntegrateError::NonFinite { step, .. }
        | IntegrateError::SingularMatrix { step, .. } => {
            if *step == 0 {
                2
            } else {
                1
            }
        }
        IntegrateError::NewtonNotConverged { .. } | IntegrateError::TooManySubsteps { .. } => 1,
    }
}

/// `" on joint 'J'"` when `row` is a drive's row, else empty.
/// A joint counts as "at its limit" for the fixed-step advice within this distance of it (rad or
/// m): a limit reached in the last step or pressed into, not one a joint merely approaches.
const AT_LIMIT_DISTANCE: f64 = 1e-2;

/// The first 1-dof joint with a URDF limit within [`AT_LIMIT_DISTANCE`] of (or past) it at `q`.
fn joint_at_limit<'a>(model: &'a Model, q: &[f64]) -> Option<&'a str> {
    model
        .joints
        .iter()
        .filter(|joint| joint.kind != JointKind::Floating)
        .find(|joint| {
            let Some(source) = joint.source else {
                return false;
            };
            let [lower, upper] = model.description.joints[source].limits;
            let Some(&x) = q.get(joint.q_index) else {
                return false;
            };
            (lower.is_finite() && x - lower < AT_LIMIT_DISTANCE)
                || (upper.is_finite() && upper - x < AT_LIMIT_DISTANCE)
        })
        .map(|joint| joint.name.as_str())
}

fn drive_joint(model: &Model, constraints: &ConstraintSet, row: usize) -> String {
    let first_drive = constraints.len() - constraints.drives.len();
    match row
        .checked_sub(first_drive)
        .and_then(|i| constraints.drives.get(i))
    {
        Some(drive) => format!(" on joint '{}'", joint_of_velocity(model, drive.v_index)),
        None => String::new(),
    }
}

/// The name of velocity coordinate `index`: `'elbow'`, or `'root_joint' (angular z)` for a floating
/// joint's coordinates.
fn coordinate_name(model: &Model, index: usize) -> String {
    const FLOATING: [&str; 6] = [
        "linear x",
        "linear y",
        "linear z",
        "angular x",
        "angular y",
        "angular z",
    ];
    match model
        .joints
        .iter()
        .find(|j| (j.v_index..j.v_index + j.nv()).contains(&index))
    {
        Some(joint) if joint.kind == JointKind::Floating => {
            format!("'{}' ({})", joint.name, FLOATING[index - joint.v_index])
        }
        Some(joint) => format!("'{}'", joint.name),
        None => format!("velocity coordinate {index}"),
    }
}

/// The mass matrix at `q` (a fresh workspace: this is the error path).
fn mass_matrix(model: &Model, q: &[f64]) -> Option<nalgebra::DMatrix<f64>> {
    if q.len() != model.nq || q.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let mut data = Data::new(model);
    crba(model, &mut data, q);
    Some(data.mass_matrix.clone())
}

/// When `M(q)` is singular: the joints of the motion that moves no inertia (its null vector) and
/// the likely causes (massless floating root, massless leaves). `None` when M is regular.
fn singular_mass_motion(model: &Model, q: &[f64]) -> Option<(String, String)> {
    let mass = mass_matrix(model, q)?;
    let scale = mass.diagonal().amax();
    if scale <= 0.0 {
        return Some((
            "every joint".to_string(),
            "no link of the robot has mass or inertia; give the links <inertial> elements"
                .to_string(),
        ));
    }
    let mode = smallest_mass_mode(mass)?;
    if mode.inertia > MASSLESS_RELATIVE * scale {
        return None;
    }
    Some((
        motion_name(model, &mode.coordinates),
        massless_causes(model),
    ))
}

/// The motion of `M`'s smallest eigenvalue: that inertia and the velocity coordinates taking part
/// (component at least [`NULL_MOTION_SHARE`] of the largest).
struct SmallestMassMode {
    inertia: f64,
    coordinates: Vec<usize>,
}

fn smallest_mass_mode(mass: nalgebra::DMatrix<f64>) -> Option<SmallestMassMode> {
    let eigen = nalgebra::SymmetricEigen::new(mass);
    let (smallest, value) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let null = eigen.eigenvectors.column(smallest);
    let largest = null.amax();
    Some(SmallestMassMode {
        inertia: *value,
        coordinates: (0..null.len())
            .filter(|i| null[*i].abs() >= NULL_MOTION_SHARE * largest)
            .collect(),
    })
}

/// "joint 'a'" or "the combined motion of joints 'a', 'b'".
fn motion_name(model: &Model, coordinates: &[usize]) -> String {
    let joints: Vec<String> = coordinates
        .iter()
        .map(|&i| coordinate_name(model, i))
        .collect();
    match joints.as_slice() {
        [one] => format!("joint {one}"),
        many => format!("the combined motion of joints {}", many.join(", ")),
    }
}

/// When `M(q)` is nearly singular because two or more joints' motions are nearly the same (a
/// gimbal lock of joints with massless links between them): the likely cause of a Newton failure
/// there, in words — the joints, how little the combined motion moves, the massless links on the
/// chain between them, and what to change. `None` when no such motion exists at `q`.
fn nearly_dependent_motion(model: &Model, q: &[f64]) -> Option<String> {
    let mass = mass_matrix(model, q)?;
    let diagonal: Vec<f64> = mass.diagonal().iter().copied().collect();
    let mode = smallest_mass_mode(mass)?;
    if mode.coordinates.len() < 2 {
        return None;
    }
    let alone = mode
        .coordinates
        .iter()
        .map(|&i| diagonal[i])
        .fold(f64::INFINITY, f64::min);
    if !(alone > 0.0 && mode.inertia < NEARLY_DEPENDENT_MOTION * alone) {
        return None;
    }
    // The bodies of the joints taking part, and the massless ones on the chain between them.
    let bodies: Vec<usize> = mode
        .coordinates
        .iter()
        .filter_map(|&i| {
            model
                .joints
                .iter()
                .position(|j| (j.v_index..j.v_index + j.nv()).contains(&i))
        })
        .collect();
    let mut massless = Vec::new();
    for &b in &bodies {
        let mut current = Some(b);
        while let Some(c) = current {
            // Up to the topmost joint taking part, not past it.
            if c != b
                && !bodies
                    .iter()
                    .any(|&other| other == c || is_descendant(model, c, other))
            {
                break;
            }
            if body_is_massless(model, c) && !massless.contains(&c) {
                massless.push(c);
            }
            current = model.joints[c].parent;
        }
    }
    massless.sort_unstable();
    let links: Vec<String> = massless
        .iter()
        .map(|&b| format!("'{}'", model.description.links[model.bodies[b].link].name))
        .collect();
    let between = if links.is_empty() {
        String::new()
    } else {
        format!(" across links that carry no inertia ({})", links.join(", "))
    };
    Some(format!(
        "the mass matrix is nearly singular at the last accepted state: {} moves almost no inertia ({:.3e}, {:.1e} of the least any of these joints moves alone) — their motions are lining up{between}, a gimbal lock. Give {} inertia — the lighter they are, the faster this motion and the smaller the step it needs (step_control = \"adaptive\" finds it) — or keep the joints away from the alignment (joint limits, another start)",
        motion_name(model, &mode.coordinates),
        mode.inertia,
        mode.inertia / alone,
        if links.is_empty() { "the links these joints move" } else { "those links" },
    ))
}

/// Links whose mass or principal inertia is negative with this model's values (the URDF's, or a
/// parameter point's: a mass interval reaching below zero), named with the value.
fn negative_inertia_causes(model: &Model) -> Vec<String> {
    let mut causes = Vec::new();
    for (l, link) in model.description.links.iter().enumerate() {
        let spec = model.effective_inertial(l);
        let [ixx, _, _, iyy, _, izz] = spec.inertia;
        if spec.mass < 0.0 {
            causes.push(format!("link '{}' has mass {} kg", link.name, spec.mass));
        } else if ixx < 0.0 || iyy < 0.0 || izz < 0.0 {
            causes.push(format!(
                "link '{}' has inertia ixx = {ixx}, iyy = {iyy}, izz = {izz} kg·m²",
                link.name
            ));
        }
    }
    causes
}

/// Whether body `b` carries no mass and no rotational inertia.
fn body_is_massless(model: &Model, b: usize) -> bool {
    let inertia = &model.bodies[b].inertia;
    inertia.mass == 0.0 && inertia.rotational.abs().max() == 0.0
}

/// Likely causes of a singular mass matrix found in the model: a massless floating root, and
/// massless leaves (a moving body without mass and inertia and without children that carry any).
fn massless_causes(model: &Model) -> String {
    let mut causes = Vec::new();
    let link_name = |b: usize| model.description.links[model.bodies[b].link].name.as_str();
    for (b, joint) in model.joints.iter().enumerate() {
        if joint.kind == JointKind::Floating && joint.parent.is_none() && body_is_massless(model, b)
        {
            causes.push(format!(
                "the floating base link '{}' has no mass and no inertia (a massless floating root: the joints at the root then duplicate the base's own motion); give '{}' an <inertial>, or fix the base",
                link_name(b),
                link_name(b)
            ));
        }
    }
    for (b, joint) in model.joints.iter().enumerate() {
        if joint.kind == JointKind::Floating {
            continue;
        }
        let subtree_massless = (b..model.joints.len())
            .filter(|&c| c == b || is_descendant(model, c, b))
            .all(|c| body_is_massless(model, c));
        let is_leaf = !model.joints.iter().any(|j| j.parent == Some(b));
        if subtree_massless {
            causes.push(format!(
                "link '{}' moved by {} joint '{}' has no mass and no inertia{} (a massless {}): nothing resists the joint; give '{}' an <inertial>, or make the joint fixed",
                link_name(b),
                joint.type_name,
                joint.name,
                if is_leaf { "" } else { ", nor do the links below it" },
                if is_leaf { "leaf" } else { "branch" },
                link_name(b)
            ));
        }
    }
    causes.join("; ")
}

/// Whether body `c` lies below body `ancestor` in the tree.
fn is_descendant(model: &Model, c: usize, ancestor: usize) -> bool {
    let mut parent = model.joints[c].parent;
    while let Some(p) = parent {
        if p == ancestor {
            return true;
        }
        parent = model.joints[p].parent;
    }
    false
}

/// A Newton failure's worst coordinate in the robot's words: `(name, details, likely cause)` —
/// the joint, its effective inertia `M_jj` at `q` (and its spring's period against the step when it
/// has one), and what to change.
/// Steps per period of a joint spring below which the step does not resolve it (the advice asks
/// for a step of at most a twentieth of the period).
const STEPS_PER_SPRING_PERIOD: f64 = 20.0;

fn describe_coordinate(
    model: &Model,
    scene: &Scene,
    q: &[f64],
    index: usize,
) -> (String, String, String) {
    let name = format!("joint {}", coordinate_name(model, index));
    let h = scene.step_s;
    let Some(mass) = mass_matrix(model, q) else {
        return (
            name,
            String::new(),
            format!("try a smaller step than {h} s"),
        );
    };
    let inertia = mass[(index, index)];
    if inertia <= MASSLESS_RELATIVE * mass.diagonal().amax() {
        return (
            name,
            format!(", effective inertia {inertia:.3e}"),
            "the joint moves no mass or inertia here: give the links it moves an <inertial>"
                .to_string(),
        );
    }
    let owner = joint_of_velocity(model, index);
    let spring = scene
        .springs
        .iter()
        .find(|s| model.joints[s.joint].name == owner && s.stiffness > 0.0);
    // The spring is the likely cause only when the step does not resolve its period; a step
    // already below a twentieth of it (the quadruped's knees at touch-down) points elsewhere.
    let spring = spring.filter(|s| {
        STEPS_PER_SPRING_PERIOD * h > std::f64::consts::TAU * (inertia / s.stiffness).sqrt()
    });
    if let Some(spring) = spring {
        let period = std::f64::consts::TAU * (inertia / spring.stiffness).sqrt();
        return (
            name,
            format!(
                ", effective inertia {inertia:.3e}, spring stiffness {:.3e}: period {period:.3e} s",
                spring.stiffness
            ),
            format!(
                "the spring is too stiff for the step of {h} s or the inertia too small: use a step below {:.1e} s (a twentieth of the period), or check the inertia",
                period / STEPS_PER_SPRING_PERIOD
            ),
        );
    }
    (
        name,
        format!(", effective inertia {inertia:.3e} at the last accepted state"),
        format!(
            "the motion of this joint is too fast or too stiff for the step of {h} s: try a smaller --step, or check its links' inertia and the forces on it"
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions};

    /// A shoulder built like example-robot-data's human: three revolute joints about z, x and y
    /// with massless links between them, carrying an arm. With the x joint at ±90° the z and y
    /// axes coincide (a gimbal lock).
    const SHOULDER: &str = r#"<robot name="shoulder">
  <link name="torso"/>
  <link name="upperarm_virtual"/>
  <link name="upperarm_virtual_2"/>
  <link name="upperarm"><inertial><origin xyz="0 0 -0.15"/><mass value="2"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.004"/></inertial></link>
  <joint name="shoulder_Z" type="revolute"><parent link="torso"/><child link="upperarm_virtual"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="shoulder_X" type="revolute"><parent link="upperarm_virtual"/>
    <child link="upperarm_virtual_2"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="shoulder_Y" type="revolute"><parent link="upperarm_virtual_2"/>
    <child link="upperarm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"#;

    fn shoulder() -> Model {
        let description = parse_description(SHOULDER, "shoulder.urdf").unwrap();
        Model::from_description(description, LoadOptions::default(), "shoulder.urdf").unwrap()
    }

    #[test]
    fn a_gimbal_lock_is_named_with_its_joints_and_massless_links() {
        let model = shoulder();
        let half_pi = std::f64::consts::FRAC_PI_2;
        // 0.5° from the alignment: the z and y joints move nearly the same way.
        let near = [0.3, half_pi - 0.5_f64.to_radians(), -0.2];
        let message = nearly_dependent_motion(&model, &near).expect("nearly dependent");
        for needle in [
            "'shoulder_Z'",
            "'shoulder_Y'",
            "'upperarm_virtual'",
            "'upperarm_virtual_2'",
            "gimbal lock",
        ] {
            assert!(message.contains(needle), "{needle} missing: {message}");
        }
        assert!(
            !message.contains("'upperarm'"),
            "the arm carries inertia: {message}"
        );
        // Far from the alignment the shoulder is regular: no such diagnosis.
        assert_eq!(nearly_dependent_motion(&model, &[0.3, 0.4, -0.2]), None);
    }

    /// Small inertia alone is not a gimbal lock: a heavy link carrying two light ones (1e-6 and
    /// 1e-6 kg·m² about parallel axes) has a smallest eigenvalue 1e-5 of the largest, moved by
    /// both light joints together, but at 0.38 of the least either moves alone.
    #[test]
    fn light_links_are_not_a_gimbal_lock() {
        let text = r#"<robot name="light">
  <link name="base"/>
  <link name="heavy"><inertial><origin xyz="0.15 0 0"/><mass value="3"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
  <link name="light"><inertial><mass value="1e-9"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>
  <link name="lighter"><inertial><mass value="1e-9"/>
    <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>
  <joint name="a" type="continuous"><parent link="base"/><child link="heavy"/><axis xyz="0 0 1"/></joint>
  <joint name="b" type="continuous"><parent link="heavy"/><child link="light"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="c" type="continuous"><parent link="light"/><child link="lighter"/>
    <origin xyz="0.01 0 0"/><axis xyz="0 0 1"/></joint>
</robot>"#;
        let description = parse_description(text, "t.urdf").unwrap();
        let model = Model::from_description(description, LoadOptions::default(), "t.urdf").unwrap();
        let q = [0.2, 0.7, -0.4];
        let mass = mass_matrix(&model, &q).unwrap();
        assert!(mass.clone().symmetric_eigenvalues().min() < 1e-4 * mass.diagonal().max());
        let mode = smallest_mass_mode(mass).unwrap();
        assert_eq!(mode.coordinates, vec![1, 2], "both light joints take part");
        assert_eq!(nearly_dependent_motion(&model, &q), None);
    }
}
