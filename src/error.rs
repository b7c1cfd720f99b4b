//! The crate-level error: every module's error, plus bad command-line values, each mapped to the
//! documented exit code (0 ok, 1 failure, 2 bad arguments or bad input).

use crate::dynamics::DynamicsError;
use crate::integrate::IntegrateError;
use crate::model::ModelError;
use crate::params::ParamError;
use crate::scene::SceneError;
use thiserror::Error;

/// Any error ribbon reports.
#[derive(Debug, Error)]
pub enum Error {
    /// The URDF could not be loaded.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A parameter path or value was refused.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The interval parameters of the sidecar are bad.
    #[error(transparent)]
    Uncertainty(#[from] crate::uncertainty::UncertaintyError),
    /// The sidecar or a scene value is bad.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The integrator failed (names time, step and what diverged).
    #[error("simulation failed: {0}")]
    Integrate(#[from] IntegrateError),
    /// A simulation failed or its constraints cannot hold.
    #[error(transparent)]
    Simulation(#[from] crate::simulate::SimulationError),
    /// A dynamics computation failed.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// A command-line value is malformed or inconsistent with the robot.
    #[error("{flag}: {message}")]
    BadArgument {
        /// The flag (`--q`, `--set`, …).
        flag: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A study could not run or finish.
    #[error(transparent)]
    Study(#[from] crate::analysis::StudyError),
    /// The run was interrupted (SIGINT/SIGTERM); what was computed has been written.
    #[error("interrupted: {0}")]
    Interrupted(String),
    /// Writing the MCAP log failed.
    #[error(transparent)]
    Mcap(#[from] crate::output::mcap::McapError),
    /// Writing a result failed.
    #[error("cannot write {what}: {source}")]
    Output {
        /// What was being written.
        what: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

impl Error {
    /// The process exit code for this error: 2 for bad arguments or bad input, 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Model(_)
            | Error::Param(_)
            | Error::Scene(_)
            | Error::Uncertainty(_)
            | Error::BadArgument { .. } => 2,
            Error::Integrate(
                IntegrateError::InvalidAlpha { .. }
                | IntegrateError::AlphaZeroWithConstraints { .. }
                | IntegrateError::InvalidStep { .. }
                | IntegrateError::InvalidSetting { .. },
            ) => 2,
            Error::Integrate(_) => 1,
            Error::Simulation(crate::simulate::SimulationError::Constraints { .. }) => 2,
            Error::Simulation(crate::simulate::SimulationError::Integrate { source, .. }) => {
                match source {
                    IntegrateError::InvalidAlpha { .. }
                    | IntegrateError::AlphaZeroWithConstraints { .. }
                    | IntegrateError::InvalidStep { .. }
                    | IntegrateError::InvalidSetting { .. } => 2,
                    _ => 1,
                }
            }
            Error::Dynamics(DynamicsError::SingularMassMatrix { .. }) => 2,
            Error::Dynamics(_) | Error::Output { .. } | Error::Mcap(_) | Error::Interrupted(_) => 1,
            Error::Study(
                crate::analysis::StudyError::BadOptions(_) | crate::analysis::StudyError::Uq(_),
            ) => 2,
            Error::Study(crate::analysis::StudyError::Sink(inner)) => inner.exit_code(),
            Error::Study(_) => 1,
        }
    }
}
