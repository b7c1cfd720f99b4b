//! One nominal trajectory as a library call — what `ribbon simulate` runs between checking its
//! outputs and writing them, so that the command and the Python package (`ribbon.simulate`) load,
//! check and simulate the same way.
//!
//! ```text
//! SceneSetup::load ⇒ --set (paths, or the sidecar's free symbols) ⇒ memory check ⇒ start check
//!   ⇒ simulate (stops after the step at which `interrupt` is set) ⇒ NominalRun
//!   ⇒ check_finite, limit_excursions (asked by the caller, in its order)
//! ```
//!
//! Does not: check or write output files, print statistics, or install signal handlers (the
//! callers do).

use crate::environment::Environment;
use crate::model::Model;
use crate::scene::{limit_excursions, LimitExcursion, Scene};
use crate::set_flags::apply_set_flags_with_symbols;
use crate::setup::{SceneSetup, SetupMessage, SetupRequest};
use crate::simulate::{simulate_interruptible, Trajectory};
use crate::Error;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

/// A nominal run and what it ran on.
pub struct NominalRun {
    /// The model the run started from (`--set` applied).
    pub model: Model,
    /// The environment the run started from (the scene's, `--set` applied).
    pub environment: Environment,
    /// The scene.
    pub scene: Scene,
    /// The sidecar read, when there was one.
    pub sidecar_path: Option<PathBuf>,
    /// The recorded trajectory (`partial` when interrupted).
    pub trajectory: Trajectory,
}

/// What a nominal run keeps beside its trajectory: the summary's per-output copies or none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NominalCopies {
    /// Only the trajectory is kept.
    TrajectoryOnly,
    /// A summary JSON will copy every output four times (time, lower, upper, nominal).
    WithSummary,
}

impl NominalRun {
    /// Loads the robot and scene of `request`, applies `set` (`PATH=VALUE`, or a free symbol of
    /// the sidecar, as `simulate --set`), checks the memory and the start, and simulates,
    /// stopping after the step at which `interrupt` is set. Warnings go to `message`.
    pub fn run(
        request: &SetupRequest,
        set: &[String],
        copies: NominalCopies,
        interrupt: &AtomicBool,
        message: &mut dyn FnMut(SetupMessage, &str),
    ) -> Result<NominalRun, Error> {
        let SceneSetup {
            mut model,
            mut environment,
            scene,
            sidecar,
            sidecar_path,
        } = SceneSetup::load(request, message)?;
        let sidecar_name = sidecar_path.as_ref().map(|p| p.display().to_string());
        let symbols = sidecar_name.as_deref().map(|name| (&sidecar, name));
        apply_set_flags_with_symbols(&mut model, &mut environment, set, symbols)?;
        // Kept per record time: the time, the configuration, every output, and the summary's four
        // copies of each output (time, lower, upper, nominal).
        let per_output = 1 + match copies {
            NominalCopies::TrajectoryOnly => 0,
            NominalCopies::WithSummary => 4,
        };
        scene.check_memory(
            "simulate",
            (1 + model.nq + scene.outputs.len() * per_output) as u64,
            0,
        )?;
        for warning in crate::simulate::check_start(&model, &environment, &scene)? {
            message(SetupMessage::Warning, &warning);
        }
        let trajectory = simulate_interruptible(model.clone(), environment, &scene, interrupt)?;
        Ok(NominalRun {
            model,
            environment,
            scene,
            sidecar_path,
            trajectory,
        })
    }

    /// The outputs' names.
    pub fn output_names(&self) -> Vec<&str> {
        self.trajectory
            .outputs
            .iter()
            .map(|o| o.name.as_str())
            .collect()
    }

    /// Refuses a trajectory that holds a NaN or infinity (exit 1, naming the output and time).
    pub fn check_finite(&self) -> Result<(), Error> {
        let columns: Vec<&[f64]> = self.trajectory.values.iter().map(Vec::as_slice).collect();
        Ok(crate::output::check_finite(
            "simulate",
            &self.output_names(),
            &self.trajectory.times,
            &columns,
        )?)
    }

    /// The joints whose recorded positions passed URDF limits the scene does not enforce.
    pub fn limit_excursions(&self) -> Vec<LimitExcursion> {
        let t = &self.trajectory;
        limit_excursions(
            &self.model,
            &self.scene,
            &t.outputs,
            &t.times,
            &t.values,
            &t.values,
        )
    }
}
