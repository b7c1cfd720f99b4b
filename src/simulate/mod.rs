//! One deterministic run: a [`Model`](crate::model::Model) with its scene's effects as a
//! [`DaeSystem`](crate::integrate::DaeSystem) ([`RobotSystem`]), integrated by HHT-I3, recorded at
//! the scene's rate ([`Recorder`]); failures in the robot's words ([`SimulationError`]).
//!
//! `(model, scene) ⇒ RobotSystem ⇒ HhtIntegrator steps ⇒ Recorder rows ⇒ Trajectory`

mod error;
mod recorder;
mod run;
mod system;

pub use error::{integrate_exit_code, FailureContext, SimulationError};
pub use recorder::{InitialOrientations, Recorder};
pub use run::{
    check_start, hht_settings, initial_violation, simulate, simulate_interruptible, Trajectory,
    VELOCITY_PROJECTION_NOTE,
};
pub use system::RobotSystem;
