//! One deterministic run: a [`Model`](crate::model::Model) with its scene's effects as a
//! [`DaeSystem`](crate::integrate::DaeSystem) ([`RobotSystem`]), integrated by HHT-I3, recorded at
//! the scene's rate ([`Recorder`]); failures in the robot's words ([`SimulationError`]).
//!
//! `(model, scene) ⇒ RobotSystem ⇒ HhtIntegrator steps ⇒ Recorder rows ⇒ Trajectory`
//!
//! Sensitivities of every output to every dimension of a study's box at one point
//! ([`sensitivity_run`], by direct differentiation of the step; [`central_difference_run`], the
//! checked fallback): docs/sensitivities.md.

mod batch_step;
mod error;
mod lie;
mod parameters;
mod recorder;
mod run;
mod sensitivity;
mod system;

pub use batch_step::{BatchStepCounts, BatchStepper};
pub use error::{integrate_exit_code, FailureContext, SimulationError};
pub use lie::SERIES_MAX_ANGLE;
pub use parameters::{
    target_scale, ParameterDirections, THETA_FD_RELATIVE_STEP, THETA_FD_RELATIVE_STEP_UNCONSTRAINED,
};
pub use recorder::{InitialOrientations, Recorder};
pub use run::{
    check_start, hht_settings, initial_violation, simulate, simulate_interruptible, Trajectory,
    VELOCITY_PROJECTION_NOTE,
};
pub use sensitivity::{
    central_difference_run, central_difference_run_with, central_difference_settings,
    sensitivity_run, sensitivity_run_with, SensitivityRun, SensitivityRunError,
    SensitivityRunStats, CENTRAL_DIFFERENCE_STEP_XI,
};
pub use system::RobotSystem;
