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
    /// A result holds a NaN or an infinity: it is never written or printed (exit 1).
    #[error("{what}: output '{output}' is {value} at t = {} s; a non-finite number is never reported as a result, so nothing was written (the run overflowed: check the scene's values, or use a smaller step)", crate::text::message_time(*.time_s))]
    NonFiniteResult {
        /// Where it would have gone (`CSV 'out.csv'`, `summary 'x.json'`, `the table`).
        what: String,
        /// The output (series) name.
        output: String,
        /// The record time, s.
        time_s: f64,
        /// The value found (NaN or ±inf).
        value: f64,
    },
    /// A plan, a shard's record block or the set of shards was refused (`plan`, `run`, `merge`).
    #[error(transparent)]
    Shard(#[from] crate::distributed::ShardError),
    /// A study finished and wrote its results, but the a-posteriori check found the surrogate
    /// untrustworthy for some outputs (exit 4): its envelopes were widened to every true run made,
    /// yet may still be too narrow.
    #[error("the results were written, but the surrogate cannot be trusted for {untrusted} of {total} outputs (worst: {worst}): their envelopes may be too narrow, so this run exits with status {UNTRUSTED_EXIT_CODE}; {advice}")]
    Untrusted {
        /// Outputs the check did not trust.
        untrusted: usize,
        /// Outputs of the study.
        total: usize,
        /// The worst output and its misfit, e.g. `q.elbow (53.6 % of the width)`.
        worst: String,
        /// What to do ([`crate::analysis::untrusted_advice`]).
        advice: String,
    },
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
            | Error::Scene(_)
            | Error::Uncertainty(_)
            | Error::BadArgument { .. } => 2,
            Error::Integrate(source) => crate::simulate::integrate_exit_code(source),
            Error::Simulation(error) => error.exit_code(),
            Error::Dynamics(_) => 2,
            Error::Output { .. }
            | Error::NonFiniteResult { .. }
            | Error::Mcap(_)
            | Error::Interrupted(_) => 1,
            Error::Untrusted { .. } => UNTRUSTED_EXIT_CODE,
            Error::Study(
                crate::analysis::StudyError::BadOptions(_) | crate::analysis::StudyError::Uq(_),
            ) => 2,
            Error::Study(
                crate::analysis::StudyError::Sink(inner)
                | crate::analysis::StudyError::Records(inner),
            ) => inner.exit_code(),
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
