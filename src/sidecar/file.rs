//! The sidecar file `ROBOT.uncertainty.toml` as written (design contract), before it is checked
//! against a robot: read and parsed once ([`read_sidecar`], [`parse_sidecar`]) into typed values
//! that [`crate::scene`] and [`crate::uncertainty`] consume. Unknown keys are errors, so a typo
//! never silently does nothing.
//!
//! text ⇒ [`SidecarFile`] (serde for the sections; `[parameters]` as [`ParameterDeclaration`]s
//! with their intervals read, `[bind]` as [`BindDeclaration`]s, both in order of appearance and
//! expanded against a model by [`super::expand_parameters`])

use super::error::SidecarError;
use super::interval::{read_interval, IntervalSpec};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The whole sidecar file.
#[derive(Debug, Default)]
pub struct SidecarFile {
    /// `[parameters]`: interval parameters (paths, patterns and free symbols) in order of
    /// appearance.
    pub parameters: ParameterDeclarations,
    /// `[bind]`: model paths bound to expressions of the free symbols, in order of appearance.
    pub bind: Vec<BindDeclaration>,
    /// `[scene]`.
    pub scene: SceneSection,
    /// `[outputs]`.
    pub outputs: OutputsSection,
    /// `[analysis]`.
    pub analysis: AnalysisSection,
}

/// One `[parameters]` key and its interval, as written.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterDeclaration {
    /// The key: a parameter path, a pattern with `*` segments or a free symbol name.
    pub key: String,
    /// The line of the key in the sidecar (from 1), `None` for a declaration not read from a
    /// file ([`Extend`]): messages about the key name it ([`located`]).
    pub line: Option<usize>,
    /// The value as written (TOML), for messages.
    pub value: String,
    /// The interval read from the value, or why the value is no interval (a message without the
    /// key: the key is judged against the robot first, so that the errors of a file come in its
    /// order; see [`super::expand_parameters`]).
    pub interval: Result<IntervalSpec, String>,
}

/// The `[parameters]` declarations in order of appearance (a slice of [`ParameterDeclaration`]s).
/// More TOML key/value pairs can be added ([`Extend`]): each is read the way [`parse_sidecar`]
/// reads the file's, and a key already declared keeps its place and takes the new value, as in a
/// TOML table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParameterDeclarations(Vec<ParameterDeclaration>);

impl ParameterDeclaration {
    /// The declaration of `key = value` (on `line`), its interval read.
    fn read(key: String, line: Option<usize>, value: &toml::Value) -> Self {
        Self {
            interval: read_interval(value),
            value: value.to_string(),
            key,
            line,
        }
    }
}

impl ParameterDeclarations {
    /// Removes every declaration (a box built from scratch, e.g. by a test or a bench).
    pub fn clear(&mut self) {
        self.0.clear();
    }
}

impl std::ops::Deref for ParameterDeclarations {
    type Target = [ParameterDeclaration];

    fn deref(&self) -> &[ParameterDeclaration] {
        &self.0
    }
}

impl Extend<(String, toml::Value)> for ParameterDeclarations {
    fn extend<I: IntoIterator<Item = (String, toml::Value)>>(&mut self, pairs: I) {
        for (key, value) in pairs {
            self.insert(ParameterDeclaration::read(key, None, &value));
        }
    }
}

impl ParameterDeclarations {
    /// Adds `declaration`, or replaces the one with its key in place.
    fn insert(&mut self, declaration: ParameterDeclaration) {
        match self.0.iter_mut().find(|d| d.key == declaration.key) {
            Some(existing) => *existing = declaration,
            None => self.0.push(declaration),
        }
    }
}

/// One `[bind]` key and its expression, as written.
#[derive(Clone, Debug, PartialEq)]
pub struct BindDeclaration {
    /// The bound parameter path.
    pub key: String,
    /// The line of the key in the sidecar (from 1), `None` when not read from a file.
    pub line: Option<usize>,
    /// The expression's text, or the value as written (TOML) when it is not a string (refused
    /// when `[bind]` is resolved against the robot, after `[parameters]`).
    pub expression: Result<String, String>,
}

/// The file as serde reads it: `[parameters]` and `[bind]` as TOML tables whose keys keep their
/// place in the text, typed by [`parse_sidecar`].
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct WrittenSidecar {
    #[serde(default)]
    parameters: SpannedTable,
    #[serde(default)]
    bind: SpannedTable,
    #[serde(default)]
    scene: SceneSection,
    #[serde(default)]
    outputs: OutputsSection,
    #[serde(default)]
    analysis: AnalysisSection,
}

/// `[scene]`: what is simulated. Every key is optional (defaults in [`crate::scene::Scene`]).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSection {
    /// Simulated time, s.
    pub duration: Option<f64>,
    /// Fixed step, s.
    pub step: Option<f64>,
    /// HHT α in [−1/3, 0].
    pub alpha: Option<f64>,
    /// `"fixed"` or `"floating"`.
    pub base: Option<String>,
    /// Post-step velocity projection when there are constraint rows.
    pub velocity_projection: Option<bool>,
    /// `"fixed"` (default) or `"adaptive"`: how the integrator chooses its step.
    pub step_control: Option<String>,
    /// Local error tolerance of the adaptive step, rad or m per step.
    pub tolerance: Option<f64>,
    /// Coefficient of restitution of joint-limit impacts, 0 (plastic) to 1 (elastic).
    pub limit_restitution: Option<f64>,
    /// `"fresh"` (default) or `"reuse"`: whether the Newton matrix is factorised every step or kept
    /// across steps while Newton contracts well (docs/method.md §5).
    pub newton_matrix: Option<String>,
    /// Gravity in the world frame, m/s².
    pub gravity: Option<[f64; 3]>,
    /// Effect names.
    pub effects: Option<Vec<String>>,
    /// Initial state.
    #[serde(default)]
    pub initial: InitialSection,
    /// `[[scene.spring]]`.
    #[serde(default)]
    pub spring: Vec<SpringSection>,
    /// `[[scene.drive]]`: prescribed joint motions.
    #[serde(default)]
    pub drive: Vec<DriveSection>,
    /// `[[scene.loop]]`: loop closures.
    #[serde(default, rename = "loop")]
    pub loops: Vec<LoopSection>,
    /// `[scene.contact]`: which bodies may touch and the contact material (docs/contacts.md).
    pub contact: Option<ContactSection>,
    /// `[[scene.geometry]]`: fixed shapes of the scene (ground, boxes, an incline, a bump).
    #[serde(default)]
    pub geometry: Vec<GeometrySection>,
}

/// `[scene.contact]`: the pairs that may touch and one material for all of them.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    /// `[["foot", "ground"], …]`: link names or `[[scene.geometry]]` names.
    pub pairs: Vec<[String; 2]>,
    /// Hunt–Crossley stiffness `k`, N/m^exponent.
    pub stiffness: Option<f64>,
    /// Hunt–Crossley exponent `e` (≥ 1).
    pub exponent: Option<f64>,
    /// Hunt–Crossley dissipation `d`, s/m.
    pub damping: Option<f64>,
    /// Coulomb friction coefficient.
    pub friction: Option<f64>,
    /// Stiction velocity of the regularised friction, m/s.
    pub stiction_velocity: Option<f64>,
    /// Adaptive step only: a sub-step over which the deepest penetration grows by more than this
    /// is rejected, m.
    pub max_penetration: Option<f64>,
}

/// `[[scene.geometry]]`: a fixed shape placed in the world frame.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometrySection {
    /// Its name (used in `[scene.contact] pairs`).
    pub name: String,
    /// `box`, `sphere`, `cylinder`, `capsule`, `halfspace` or `heightfield`.
    #[serde(rename = "type")]
    pub shape_type: String,
    /// Box: full edge lengths `[x, y, z]`, m. Height field: the extent of its grid `[x, y]`, m.
    pub size: Option<Vec<f64>>,
    /// Height field: the heights, m, one array per row (rows along y, values along x).
    pub heights: Option<Vec<Vec<f64>>>,
    /// Height field: a CSV file of the heights (one row per line, values separated by commas),
    /// relative to the sidecar's directory; instead of `heights`.
    pub file: Option<String>,
    /// Sphere, cylinder, capsule: radius, m.
    pub radius: Option<f64>,
    /// Cylinder, capsule: length along the shape's z axis, m.
    pub length: Option<f64>,
    /// Position of the shape's frame in the world, m.
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation (URDF roll-pitch-yaw), rad.
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// `[[scene.drive]]`: `q_joint = f(t)` with the profile's parameters.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSection {
    /// Name of the drive (default: the joint's name); its output is `effort.NAME`.
    pub name: Option<String>,
    /// The driven joint.
    pub joint: String,
    /// `constant`, `ramp`, `sine` or `spline`.
    pub profile: String,
    /// constant and ramp: the value at t = 0 (rad or m).
    pub value: Option<f64>,
    /// ramp: rate (rad/s or m/s).
    pub rate: Option<f64>,
    /// sine: offset.
    pub offset: Option<f64>,
    /// sine: amplitude.
    pub amplitude: Option<f64>,
    /// sine: frequency, Hz.
    pub frequency: Option<f64>,
    /// sine: phase, rad.
    pub phase: Option<f64>,
    /// spline: `[[t, q], …]` with strictly increasing t.
    pub points: Option<Vec<[f64; 2]>>,
}

/// `[[scene.loop]]`: a point of `child` kept on the constrained directions of a point of `parent`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoopSection {
    /// Name (outputs `lambda.NAME.i`).
    pub name: String,
    /// `ball`, `planar_pin`, `planar_slider` or `slider`.
    #[serde(rename = "type")]
    pub loop_type: String,
    /// A link, or `"world"`.
    pub parent: String,
    /// The point in the parent link's frame, m.
    #[serde(default)]
    pub point_in_parent: [f64; 3],
    /// A link.
    pub child: String,
    /// The point in the child link's frame, m.
    #[serde(default)]
    pub point_in_child: [f64; 3],
    /// Planar types: the plane's normal, in the parent frame.
    pub normal: Option<[f64; 3]>,
    /// Slider types: the sliding direction, in the parent frame.
    pub axis: Option<[f64; 3]>,
}

/// `initial.q`, `initial.v`, `initial.base`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSection {
    /// Joint positions by joint name (rad or m).
    #[serde(default)]
    pub q: BTreeMap<String, f64>,
    /// Joint velocities by joint name (rad/s or m/s).
    #[serde(default)]
    pub v: BTreeMap<String, f64>,
    /// A floating base's initial pose and velocity.
    pub base: Option<BaseSection>,
}

/// `initial.base = { xyz, rpy, v, w }`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseSection {
    /// Position in the world frame, m.
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation as URDF roll-pitch-yaw, rad.
    #[serde(default)]
    pub rpy: [f64; 3],
    /// Linear velocity in the base frame, m/s.
    #[serde(default)]
    pub v: [f64; 3],
    /// Angular velocity in the base frame, rad/s.
    #[serde(default)]
    pub w: [f64; 3],
}

/// `[[scene.spring]]`: a linear joint spring-damper `τ = −stiffness · (q − rest) − damping · q̇` (a
/// PD position controller holding `rest`; `damping` extends the design contract).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSection {
    /// The joint.
    pub joint: String,
    /// N·m/rad or N/m.
    pub stiffness: f64,
    /// Rest position, rad or m (default 0).
    #[serde(default)]
    pub rest: f64,
    /// Damping, N·m·s/rad or N·s/m (default 0).
    #[serde(default)]
    pub damping: f64,
}

/// `joints = "all"` or a list of names.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum JointSelection {
    /// `"all"` (any other string is refused during validation).
    Keyword(String),
    /// Named joints.
    List(Vec<String>),
}

/// `[outputs]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputsSection {
    /// Which joints' positions are recorded (default all).
    pub joints: Option<JointSelection>,
    /// Record velocities `v.JOINT`.
    pub velocities: Option<bool>,
    /// Record accelerations `qdd.JOINT`.
    pub accelerations: Option<bool>,
    /// Record drive efforts `effort.DRIVE`.
    pub efforts: Option<bool>,
    /// Record constraint forces `lambda.LOOP.i`.
    pub constraint_forces: Option<bool>,
    /// Links whose world position is recorded (`frame.LINK.x|y|z`).
    pub frames: Option<Vec<String>>,
    /// Record the normal force of every declared contact pair (`contact.A.B.normal`, N).
    pub contact_forces: Option<bool>,
    /// Recording rate, Hz.
    pub rate: Option<f64>,
}

/// `[analysis]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisSection {
    /// Method name.
    pub method: Option<String>,
    /// Polynomial order.
    pub order: Option<usize>,
    /// `tensor` or `total`.
    pub design: Option<String>,
    /// The study's budget of model runs (`--max-runs` overrides it): for a scene whose study is
    /// known to need more than the default to be trusted.
    pub max_runs: Option<usize>,
}

/// A TOML table's entries in file order, each key with its byte range in the text.
#[derive(Debug, Default)]
struct SpannedTable(Vec<(toml::Spanned<String>, toml::Value)>);

impl<'de> Deserialize<'de> for SpannedTable {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> serde::de::Visitor<'de> for Entries {
            type Value = SpannedTable;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a table")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<SpannedTable, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry()? {
                    entries.push(entry);
                }
                Ok(SpannedTable(entries))
            }
        }
        deserializer.deserialize_map(Entries)
    }
}

/// The line (from 1) of byte `offset` of `text`.
fn line_of(text: &str, offset: usize) -> usize {
    1 + text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// `file:line` when the line is known, else `file`: where a message about one sidecar key points.
pub fn located(file: &str, line: Option<usize>) -> String {
    match line {
        Some(line) => format!("{file}:{line}"),
        None => file.to_string(),
    }
}

/// Parses sidecar text; the error is the TOML parser's message (with line and column). Every
/// `[parameters]` value is read as an interval here, once; every `[parameters]` and `[bind]` key
/// keeps its line for messages.
pub fn parse_sidecar(text: &str) -> Result<SidecarFile, String> {
    let written: WrittenSidecar = toml::from_str(text).map_err(|e| e.to_string())?;
    let line = |key: &toml::Spanned<String>| Some(line_of(text, key.span().start));
    let mut parameters = ParameterDeclarations::default();
    for (key, value) in &written.parameters.0 {
        parameters.insert(ParameterDeclaration::read(
            key.get_ref().clone(),
            line(key),
            value,
        ));
    }
    let bind = written
        .bind
        .0
        .into_iter()
        .map(|(key, value)| BindDeclaration {
            expression: match value {
                toml::Value::String(text) => Ok(text),
                other => Err(other.to_string()),
            },
            line: line(&key),
            key: key.into_inner(),
        })
        .collect();
    Ok(SidecarFile {
        parameters,
        bind,
        scene: written.scene,
        outputs: written.outputs,
        analysis: written.analysis,
    })
}

/// Reads and parses the sidecar file at `path`; also returns its text (attached to the outputs).
pub fn read_sidecar(path: &Path) -> Result<(SidecarFile, String), SidecarError> {
    let text = std::fs::read_to_string(path).map_err(|source| SidecarError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let file = parse_sidecar(&text).map_err(|message| SidecarError::Parse {
        path: path.display().to_string(),
        message,
    })?;
    Ok((file, text))
}
