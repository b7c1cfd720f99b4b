//! Loading what every command that simulates needs, in one order: the sidecar, the URDF (on a
//! floating base when the sidecar or the flag asks), the scene and its environment (gravity,
//! contact material), and — for studies — the expanded parameter box and a check that the nominal
//! model can start the scene.
//!
//! `simulate` uses [`SceneSetup::load`] (a sidecar is optional there); `analyze`, `compare`, `plan`,
//! `run`, `merge` and the library examples use [`Setup::load`]. Warnings and notes are handed to a
//! callback as they arise, so a later error does not swallow them.

use crate::environment::Environment;
use crate::model::{LoadOptions, Model};
use crate::scene::{default_sidecar_path, wants_floating_base, Scene, SceneOverrides};
use crate::sidecar::{read_sidecar, SidecarFile};
use crate::uncertainty::ParameterSpace;
use crate::Error;
use std::path::{Path, PathBuf};

/// What to load: the robot, its sidecar and the scene flags.
#[derive(Clone, Debug)]
pub struct SetupRequest<'a> {
    /// The robot's URDF file.
    pub urdf: &'a Path,
    /// The sidecar (`--uncertainty`); `None`: `ROBOT.uncertainty.toml` beside the URDF.
    pub uncertainty: Option<&'a Path>,
    /// Put the root link on a floating joint (`--floating`, also `[scene] base = "floating"`).
    pub floating: bool,
    /// The command-line values that override the sidecar's `[scene]`.
    pub overrides: SceneOverrides,
}

impl SetupRequest<'_> {
    /// The sidecar this request reads: `uncertainty`, or `ROBOT.uncertainty.toml` beside the URDF.
    pub fn sidecar_path(&self) -> PathBuf {
        self.uncertainty
            .map(Path::to_path_buf)
            .unwrap_or_else(|| default_sidecar_path(self.urdf))
    }
}

/// What a message handed to the callback of [`Setup::load`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupMessage {
    /// Something the user should look at (`warning: …`).
    Warning,
    /// Information (`note: …`).
    Note,
}

/// A robot and its scene, without a parameter box (what `simulate` needs).
pub struct SceneSetup {
    /// The sidecar read, when there was one.
    pub sidecar_path: Option<PathBuf>,
    /// Its contents (the defaults without a sidecar).
    pub sidecar: SidecarFile,
    /// The nominal model.
    pub model: Model,
    /// The scene's environment (gravity, contact material; [`Scene::environment`]).
    pub environment: Environment,
    /// The scene.
    pub scene: Scene,
}

impl SceneSetup {
    /// Reads the sidecar when there is one (`request.uncertainty`, or the default path when it
    /// exists), loads the URDF and resolves the scene; model warnings go to `message`.
    pub fn load(
        request: &SetupRequest,
        message: &mut dyn FnMut(SetupMessage, &str),
    ) -> Result<SceneSetup, Error> {
        let sidecar_path = request
            .uncertainty
            .map(Path::to_path_buf)
            .or_else(|| Some(default_sidecar_path(request.urdf)).filter(|p| p.exists()));
        let (sidecar, sidecar_name) = match &sidecar_path {
            Some(path) => (read_sidecar(path)?.0, path.display().to_string()),
            None => (SidecarFile::default(), "(no sidecar)".to_string()),
        };
        let (model, scene) = load_model_and_scene(request, &sidecar, &sidecar_name, message)?;
        Ok(SceneSetup {
            sidecar_path,
            sidecar,
            model,
            environment: scene.environment(),
            scene,
        })
    }
}

/// A robot, its scene and its parameter box, checked and ready for a study.
pub struct Setup {
    /// The sidecar file read.
    pub sidecar_path: PathBuf,
    /// Its contents.
    pub sidecar: SidecarFile,
    /// The nominal model.
    pub model: Model,
    /// The scene's environment (gravity, contact material; [`Scene::environment`]).
    pub environment: Environment,
    /// The scene.
    pub scene: Scene,
    /// The interval parameters (the sidecar's `[parameters]` expanded, `[bind]` resolved).
    pub space: ParameterSpace,
}

impl Setup {
    /// Loads the URDF and its sidecar (required: a study without one is refused naming
    /// `--uncertainty`), resolves the scene and the parameter box, and checks that the nominal model
    /// can start the scene (exit 2 naming the joints when it cannot). Model and box warnings, box
    /// notes and what the start changed go to `message`, in that order.
    pub fn load(
        request: &SetupRequest,
        message: &mut dyn FnMut(SetupMessage, &str),
    ) -> Result<Setup, Error> {
        let sidecar_path = request.sidecar_path();
        if request.uncertainty.is_none() && !sidecar_path.exists() {
            return Err(Error::BadArgument {
                flag: "--uncertainty".to_string(),
                message: format!(
                    "no sidecar: '{}' does not exist. Write a first one with `ribbon init {}` (every link's mass and inertia ±5 % and centre of mass ±2 mm; the robot holding a pose inside its limits on PD joint controllers under gravity), edit it to your question, or pass --uncertainty FILE",
                    sidecar_path.display(),
                    request.urdf.display()
                ),
            });
        }
        let sidecar_name = sidecar_path.display().to_string();
        let (sidecar, _) = read_sidecar(&sidecar_path)?;
        let (model, scene) = load_model_and_scene(request, &sidecar, &sidecar_name, message)?;
        let environment = scene.environment();
        let space = ParameterSpace::from_sidecar(&sidecar, &model, &environment, &sidecar_name)?;
        for warning in space.warnings() {
            message(SetupMessage::Warning, warning);
        }
        for note in space.notes() {
            message(SetupMessage::Note, note);
        }
        for warning in crate::simulate::check_start(&model, &environment, &scene)? {
            message(SetupMessage::Warning, &warning);
        }
        Ok(Setup {
            sidecar_path,
            sidecar,
            model,
            environment,
            scene,
            space,
        })
    }
}

/// Prints a [`Setup`] message on stderr the way the commands do (`warning: …`, `note: …`).
pub fn print_message(kind: SetupMessage, text: &str) {
    match kind {
        SetupMessage::Warning => eprintln!("warning: {text}"),
        SetupMessage::Note => eprintln!("note: {text}"),
    }
}

/// The model on the base the sidecar or flag asks for, and the resolved scene.
fn load_model_and_scene(
    request: &SetupRequest,
    sidecar: &SidecarFile,
    sidecar_name: &str,
    message: &mut dyn FnMut(SetupMessage, &str),
) -> Result<(Model, Scene), Error> {
    let floating_base = request.floating || wants_floating_base(sidecar, sidecar_name)?;
    let model = Model::from_urdf_file(request.urdf, LoadOptions { floating_base })?;
    for warning in &model.warnings {
        message(SetupMessage::Warning, warning);
    }
    crate::scene::check_dense_matrices("simulating it", &model)?;
    let scene = Scene::resolve(sidecar, &model, sidecar_name, request.overrides)?;
    if let Some(contact) = &scene.contact {
        for note in &contact.geometry.notes {
            message(SetupMessage::Note, note);
        }
    }
    Ok((model, scene))
}
