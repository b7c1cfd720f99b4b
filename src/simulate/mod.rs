//! One deterministic run: a [`Model`](crate::model::Model) with its scene's effects as a
//! [`DaeSystem`](crate::integrate::DaeSystem) ([`RobotSystem`]), integrated by HHT-I3, recorded at
//! the scene's rate ([`Recorder`]).
//!
//! `(model, scene) ⇒ RobotSystem ⇒ HhtIntegrator steps ⇒ Recorder rows ⇒ Trajectory`

mod recorder;
mod run;
mod system;

pub use recorder::{InitialOrientations, Recorder};
pub use run::{hht_settings, initial_violation, simulate, SimulationError, Trajectory};
pub use system::RobotSystem;
