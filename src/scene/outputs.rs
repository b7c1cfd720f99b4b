//! Output names (design contract): `q.JOINT`, `v.JOINT`, `qdd.JOINT`, `frame.LINK.x|y|z`; a floating
//! base gives `q.BASE.x|y|z` and a rotation vector `q.BASE.rx|ry|rz` relative to its initial
//! orientation (quaternion components make meaningless envelopes), and `v.BASE.x…rz` in the base
//! frame.

use super::sidecar::{JointSelection, OutputsSection};
use super::SceneError;
use crate::constraints::ConstraintSet;
use crate::model::{JointKind, Model};
use crate::text::closest_suggestion;

/// Where a recorded number comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OutputKind {
    /// A 1-dof joint's position `q[q_index]`.
    Position {
        /// Index into q.
        q_index: usize,
    },
    /// A velocity coordinate `v[v_index]`.
    Velocity {
        /// Index into v.
        v_index: usize,
    },
    /// An acceleration coordinate `q̈[v_index]`.
    Acceleration {
        /// Index into v.
        v_index: usize,
    },
    /// Component `axis` of a URDF link's origin in the world frame.
    FramePosition {
        /// Index into `description.links`.
        link: usize,
        /// 0, 1, 2 for x, y, z.
        axis: usize,
    },
    /// Component `axis` of a floating joint's position.
    BasePosition {
        /// Model joint index.
        joint: usize,
        /// 0, 1, 2.
        axis: usize,
    },
    /// Component `axis` of a floating joint's rotation vector relative to its initial orientation.
    BaseRotation {
        /// Model joint index.
        joint: usize,
        /// 0, 1, 2.
        axis: usize,
    },
    /// The normal force of declared contact pair `pair` (index into the scene's contact pairs), N;
    /// 0 while the pair is apart.
    ContactNormalForce {
        /// Index into `GeometryModel::pairs`.
        pair: usize,
    },
    /// `sign · λ[row]`: a drive's effort and a loop's reaction force use `−λ`, a mimic row `λ`.
    Multiplier {
        /// Constraint row.
        row: usize,
        /// −1 or +1.
        sign: f64,
    },
}

impl OutputKind {
    /// The interval every value of this output lies in by the model's construction, whatever the
    /// parameters, where there is one narrower than the reals: a contact's normal force never
    /// pulls (`f_n ≥ 0`, docs/contacts.md), so `[0, ∞)`. A bound may be clipped to it without
    /// leaving out any true value (docs/method.md §12, "known ranges"). Joint positions at
    /// enforced limits are not clipped: the penalty of a resting limit lets a joint a little
    /// past it.
    pub fn known_range(&self) -> Option<(f64, f64)> {
        match self {
            OutputKind::ContactNormalForce { .. } => Some((0.0, f64::INFINITY)),
            _ => None,
        }
    }

    /// The output's value for a value a study recorded (`Recorder::for_study`): the recorded
    /// value clamped to [`OutputKind::known_range`]. A study's contact normal force is recorded
    /// signed (`−k·gap^e` while the pair is apart), and `max(0, ·)` of it is the force; every
    /// other output is recorded as it is reported. The clamp is monotone, so the clamp of a
    /// bound of the recorded value bounds the output (docs/contacts.md §7, "The signed force").
    #[inline]
    pub fn reported(&self, recorded: f64) -> f64 {
        clamp_to_range(recorded, self.known_range())
    }
}

/// `value` clamped to `range` (`(lowest, highest)`; `None`: unchanged). A NaN stays NaN, for the
/// finiteness checks downstream to catch.
#[inline]
pub fn clamp_to_range(value: f64, range: Option<(f64, f64)>) -> f64 {
    match range {
        Some((lowest, highest)) => value.clamp(lowest, highest),
        None => value,
    }
}

/// One recorded scalar series.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    /// Its name, e.g. `q.elbow_joint` or `frame.tool0.z`: the parts joined by dots.
    pub name: String,
    /// The parts of the name (`["q", "joint_0.0"]`): the separating dots are the ones between parts,
    /// so names that contain dots still map to an unambiguous MCAP topic.
    pub parts: Vec<String>,
    /// Its unit.
    pub unit: &'static str,
    /// Where it comes from.
    pub kind: OutputKind,
}

/// Owned name parts.
fn parts(items: &[&str]) -> Vec<String> {
    items.iter().map(|s| s.to_string()).collect()
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const ROTATION: [&str; 3] = ["rx", "ry", "rz"];

/// Resolves `[outputs]` against the model.
pub fn resolve(
    section: &OutputsSection,
    model: &Model,
    constraints: &ConstraintSet,
    path: &str,
) -> Result<Vec<Output>, SceneError> {
    let invalid = |key: &str, message: String| SceneError::Invalid {
        path: path.to_string(),
        key: key.to_string(),
        message,
    };
    let joints: Vec<usize> = match &section.joints {
        None => (0..model.joints.len()).collect(),
        Some(JointSelection::Keyword(k)) if k == "all" => (0..model.joints.len()).collect(),
        Some(JointSelection::Keyword(other)) => {
            return Err(invalid(
                "[outputs] joints",
                format!("'{other}' is neither \"all\" nor a list of joint names"),
            ))
        }
        Some(JointSelection::List(names)) => names
            .iter()
            .map(|name| {
                model.joint_index(name).ok_or_else(|| {
                    invalid(
                        "[outputs] joints",
                        format!(
                            "unknown joint '{name}'{}",
                            closest_suggestion(name, model.joints.iter().map(|j| j.name.as_str()))
                        ),
                    )
                })
            })
            .collect::<Result<_, _>>()?,
    };
    let linear_unit = |kind: JointKind, angular: &'static str, linear: &'static str| match kind {
        JointKind::Prismatic => linear,
        _ => angular,
    };
    let mut outputs = Vec::new();
    for &j in &joints {
        let joint = &model.joints[j];
        if joint.kind == JointKind::Floating {
            for (axis, label) in XYZ.iter().enumerate() {
                outputs.push(Output {
                    name: format!("q.{}.{label}", joint.name),
                    parts: parts(&["q", &joint.name, label]),
                    unit: "m",
                    kind: OutputKind::BasePosition { joint: j, axis },
                });
            }
            for (axis, label) in ROTATION.iter().enumerate() {
                outputs.push(Output {
                    name: format!("q.{}.{label}", joint.name),
                    parts: parts(&["q", &joint.name, label]),
                    unit: "rad",
                    kind: OutputKind::BaseRotation { joint: j, axis },
                });
            }
        } else {
            outputs.push(Output {
                name: format!("q.{}", joint.name),
                parts: parts(&["q", &joint.name]),
                unit: linear_unit(joint.kind, "rad", "m"),
                kind: OutputKind::Position {
                    q_index: joint.q_index,
                },
            });
        }
    }
    let mut per_velocity =
        |prefix: &str, angular: &'static str, linear: &'static str, acceleration: bool| {
            for &j in &joints {
                let joint = &model.joints[j];
                for k in 0..joint.nv() {
                    let v_index = joint.v_index + k;
                    let (name_parts, unit) = if joint.kind == JointKind::Floating {
                        let label = if k < 3 { XYZ[k] } else { ROTATION[k - 3] };
                        (
                            parts(&[prefix, &joint.name, label]),
                            if k < 3 { linear } else { angular },
                        )
                    } else {
                        (
                            parts(&[prefix, &joint.name]),
                            linear_unit(joint.kind, angular, linear),
                        )
                    };
                    let kind = if acceleration {
                        OutputKind::Acceleration { v_index }
                    } else {
                        OutputKind::Velocity { v_index }
                    };
                    outputs.push(Output {
                        name: name_parts.join("."),
                        parts: name_parts,
                        unit,
                        kind,
                    });
                }
            }
        };
    if section.velocities.unwrap_or(false) {
        per_velocity("v", "rad/s", "m/s", false);
    }
    if section.accelerations.unwrap_or(false) {
        per_velocity("qdd", "rad/s²", "m/s²", true);
    }
    let unit_of_coordinate = |v_index: usize, rotational: &'static str, linear: &'static str| {
        let joint = model.joints.iter().find(|j| j.v_index == v_index);
        match joint.map(|j| j.kind) {
            Some(JointKind::Prismatic) => linear,
            _ => rotational,
        }
    };
    let loop_rows: usize = constraints.loops.iter().map(|l| l.rows()).sum();
    if section.efforts.unwrap_or(false) {
        let first = loop_rows + constraints.mimics.len();
        for (i, drive) in constraints.drives.iter().enumerate() {
            outputs.push(Output {
                name: format!("effort.{}", drive.name),
                parts: parts(&["effort", &drive.name]),
                unit: unit_of_coordinate(drive.v_index, "N·m", "N"),
                kind: OutputKind::Multiplier {
                    row: first + i,
                    sign: -1.0,
                },
            });
        }
    }
    if section.constraint_forces.unwrap_or(false) {
        let mut row = 0;
        for closure in &constraints.loops {
            for i in 0..closure.rows() {
                outputs.push(Output {
                    name: format!("lambda.{}.{i}", closure.name),
                    parts: parts(&["lambda", &closure.name, &i.to_string()]),
                    unit: "N",
                    kind: OutputKind::Multiplier { row, sign: -1.0 },
                });
                row += 1;
            }
        }
        for mimic in &constraints.mimics {
            outputs.push(Output {
                name: format!("lambda.mimic.{}", mimic.joint),
                parts: parts(&["lambda", "mimic", &mimic.joint]),
                unit: unit_of_coordinate(mimic.follower.1, "N·m", "N"),
                kind: OutputKind::Multiplier { row, sign: 1.0 },
            });
            row += 1;
        }
    }
    for name in section.frames.iter().flatten() {
        let link = model.description.link_index(name).ok_or_else(|| {
            invalid(
                "[outputs] frames",
                format!(
                    "unknown link '{name}'{}",
                    closest_suggestion(
                        name,
                        model.description.links.iter().map(|l| l.name.as_str())
                    )
                ),
            )
        })?;
        for (axis, label) in XYZ.iter().enumerate() {
            outputs.push(Output {
                name: format!("frame.{name}.{label}"),
                parts: parts(&["frame", name, label]),
                unit: "m",
                kind: OutputKind::FramePosition { link, axis },
            });
        }
    }
    refuse_duplicates(&outputs, path)?;
    Ok(outputs)
}

/// `[outputs] contact_forces = true`: one `contact.A.B.normal` output (N) per declared contact pair,
/// named by the link or scene object on each side, appended to `outputs`. Refused without
/// `[scene.contact]`.
pub fn add_contact_outputs(
    section: &OutputsSection,
    contact: Option<&super::SceneContacts>,
    model: &Model,
    path: &str,
    outputs: &mut Vec<Output>,
) -> Result<(), SceneError> {
    if !section.contact_forces.unwrap_or(false) {
        return Ok(());
    }
    let Some(contact) = contact else {
        return Err(SceneError::Invalid {
            path: path.to_string(),
            key: "[outputs] contact_forces".to_string(),
            message: "there are no contact pairs to record: declare them in [scene.contact] \
                      (see docs/contacts.md), or remove contact_forces"
                .to_string(),
        });
    };
    let name_of = |attachment: crate::geometry::Attachment| match attachment {
        crate::geometry::Attachment::Scene(i) => contact.geometry.scene[i].name.clone(),
        crate::geometry::Attachment::Link { link, .. } => {
            model.description.links[link].name.clone()
        }
    };
    for (pair, declared) in contact.geometry.pairs.iter().enumerate() {
        let (a, b) = (name_of(declared.a), name_of(declared.b));
        outputs.push(Output {
            name: format!("contact.{a}.{b}.normal"),
            parts: parts(&["contact", &a, &b, "normal"]),
            unit: "N",
            kind: OutputKind::ContactNormalForce { pair },
        });
    }
    refuse_duplicates(outputs, path)
}

/// Two outputs with one name would be two CSV columns, summary entries and MCAP topics that no
/// reader can tell apart: refused, naming the key that repeats it.
fn refuse_duplicates(outputs: &[Output], path: &str) -> Result<(), SceneError> {
    let mut seen = std::collections::HashSet::with_capacity(outputs.len());
    for output in outputs {
        if !seen.insert(output.name.as_str()) {
            let (key, what) = match output.parts[0].as_str() {
                "frame" => ("[outputs] frames", "a link listed twice"),
                "effort" => ("[[scene.drive]] name", "two drives with one name"),
                "lambda" => (
                    "[[scene.loop]] name",
                    "two loops (or a loop and a mimic joint) with one name",
                ),
                _ => ("[outputs] joints", "a joint listed twice"),
            };
            return Err(SceneError::Invalid {
                path: path.to_string(),
                key: key.to_string(),
                message: format!(
                    "output '{}' would be recorded twice ({what}); give each once, with its own name",
                    output.name
                ),
            });
        }
    }
    Ok(())
}
