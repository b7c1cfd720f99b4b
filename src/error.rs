//! The crate-level error: every module's error, plus bad command-line values, each mapped to the
//! documented exit code (0 ok, 1 failure, 2 bad arguments or bad input, 3 another stage to run,
//! 4 results written but not trusted).

use crate::dynamics::DynamicsError;
use crate::integrate::IntegrateError;
use crate::model::ModelError;
use crate::params::ParamError;
use crate::scene::SceneError;
use thiserror::Error;

/// Exit status of a study whose results were written but whose surrogate the a-posteriori check
/// did not trust for some outputs ([`Error::Untrusted`]).
pub const UNTRUSTED_EXIT_CODE: u8 = 4;

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
    /// The sidecar could not be read or parsed.
    #[error(transparent)]
    Sidecar(#[from] crate::sidecar::SidecarError),
    /// A scene value is bad.
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
    /// An output was refused before anything ran, could not be written, or would have held a NaN
    /// or an infinity.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A plan, a shard's record block or the set of shards was refused (`plan`, `run`, `merge`).
    #[error(transparent)]
    Shard(#[from] crate::distributed::ShardError),
    /// A study finished and wrote its results, but the a-posteriori check found the surrogate
    /// untrustworthy for some outputs, or true runs outside an outer bound (exit 4): its envelopes
    /// were widened to every true run made, yet may still be too narrow.
    #[error("the results were written, but {finding} for {untrusted} of {total} outputs (worst: {worst}): {consequence}, so this run exits with status {UNTRUSTED_EXIT_CODE}; {advice}")]
    Untrusted {
        /// What the check found, e.g. `the surrogate cannot be trusted` or `the outer bound of
        /// the surrogate was broken by the true model`.
        finding: &'static str,
        /// What that means for the envelopes, e.g. `their envelopes may be too narrow`.
        consequence: &'static str,
        /// Outputs the check did not trust.
        untrusted: usize,
        /// Outputs of the study.
        total: usize,
        /// The worst output and its misfit, e.g. `q.elbow (53.6 % of the width)`.
        worst: String,
        /// What to do ([`crate::analysis::untrusted_advice`]).
        advice: String,
    },
}

/// The exit code of an error a study's part (a sink, a record source) gave it: the part's own
/// when it is one of ribbon's output or shard errors, else 1 (a run that started failed).
fn foreign_exit_code(part: &crate::analysis::ForeignError) -> u8 {
    if let Some(error) = part.downcast_ref::<crate::output::OutputError>() {
        error.exit_code()
    } else if let Some(error) = part.downcast_ref::<crate::distributed::ShardError>() {
        error.exit_code()
    } else {
        1
    }
}

impl Error {
    /// The process exit code for this error, the same rule for every command:
    /// - 2 — the input is at fault and nothing ran: bad arguments, files or values, an output path
    ///   that would destroy something, and a model that cannot even start (a singular mass matrix
    ///   or a non-finite value at the initial state, constraints that cannot close, a `dynamics`
    ///   query that fails);
    /// - 1 — a run that started failed later (Newton divergence, a NaN after t = 0, a failing
    ///   sample of a study), was interrupted, or its results could not be written;
    /// - 3 — not a failure: `merge` planned the next stage of a staged study and wrote no output
    ///   ([`crate::distributed::NEXT_STAGE_EXIT_CODE`]);
    /// - 4 — a study wrote its results but its surrogate is not trusted for some outputs
    ///   ([`UNTRUSTED_EXIT_CODE`]): a bound that may be wrong never exits 0.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Model(_)
            | Error::Param(_)
            | Error::Sidecar(_)
            | Error::Scene(_)
            | Error::Uncertainty(_)
            | Error::BadArgument { .. } => 2,
            Error::Integrate(source) => crate::simulate::integrate_exit_code(source),
            Error::Simulation(error) => error.exit_code(),
            Error::Dynamics(_) => 2,
            Error::Output(error) => error.exit_code(),
            Error::Interrupted(_) => 1,
            Error::Untrusted { .. } => UNTRUSTED_EXIT_CODE,
            Error::Study(
                crate::analysis::StudyError::BadOptions(_) | crate::analysis::StudyError::Uq(_),
            ) => 2,
            Error::Study(
                crate::analysis::StudyError::Sink(part)
                | crate::analysis::StudyError::Records(part),
            ) => foreign_exit_code(part),
            Error::Shard(error) => error.exit_code(),
            // A sample that fails at t = 0 failed its consistent start: its parameters make a
            // model that cannot start (the nominal one is checked before the study).
            Error::Study(crate::analysis::StudyError::SampleFailed { failure, .. })
                if failure.time_s == 0.0 =>
            {
                2
            }
            Error::Study(_) => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{ForeignError, StudyError};
    use crate::distributed::ShardError;
    use crate::output::OutputError;
    use std::path::PathBuf;

    #[test]
    fn a_part_error_keeps_its_exit_code_and_message_inside_a_study_error() {
        let truncated = || ShardError::Truncated {
            path: PathBuf::from("shard-0-of-2.records.mcap"),
            message: "it ends after record 3".to_string(),
            command: "ribbon run study.plan --shard 0/2 --into shards".to_string(),
        };
        let records = Error::from(StudyError::Records(ForeignError::new(truncated())));
        assert_eq!(records.exit_code(), 2);
        assert_eq!(records.to_string(), Error::from(truncated()).to_string());
        let write = || OutputError::Write {
            what: "MCAP 'out.mcap'".to_string(),
            source: std::io::Error::other("disk full"),
        };
        let sink = Error::from(StudyError::Sink(ForeignError::new(write())));
        assert_eq!(sink.exit_code(), 1);
        assert_eq!(sink.to_string(), Error::from(write()).to_string());
        let bad_path = OutputError::BadPath {
            flag: "--out".to_string(),
            message: "is the URDF".to_string(),
        };
        let sink = Error::from(StudyError::Sink(ForeignError::new(bad_path)));
        assert_eq!(sink.exit_code(), 2);
        // A part's error ribbon does not know: the run failed.
        let other = Error::from(StudyError::Sink(ForeignError::new(std::fmt::Error)));
        assert_eq!(other.exit_code(), 1);
    }
}
