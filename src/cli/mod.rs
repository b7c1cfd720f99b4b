//! Command-line interface: clap types here, one handler per subcommand in its own file. Results go to
//! stdout, warnings and errors to stderr.

mod analyze_cmd;
mod compare_cmd;
mod dynamics_cmd;
mod init_cmd;
mod merge_cmd;
mod params_cmd;
mod plan_cmd;
mod run_cmd;
mod simulate_cmd;

pub use crate::set_flags::{
    apply_set_flags, apply_set_flags_with_symbols, parse_set, parse_vector,
};

use crate::study_front::{install_interrupt, SceneInputs};
use crate::Error;
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// ribbon: bound envelopes of robot motion under interval-uncertain masses, inertias and lengths.
#[derive(Debug, Parser)]
#[command(name = "ribbon", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// List every value of the robot that can be declared uncertain, with its nominal and unit.
    Params(ParamsArgs),
    /// Rigid-body dynamics at one state: mass matrix, bias forces, forward and inverse dynamics,
    /// frame placements.
    Dynamics(DynamicsArgs),
    /// One nominal trajectory with the scene of the sidecar (`ROBOT.uncertainty.toml`).
    Simulate(SimulateArgs),
    /// Bound envelopes of every output over time under the sidecar's interval parameters.
    Analyze(AnalyzeArgs),
    /// What accuracy costs in time: every method against a scan of the true model.
    Compare(CompareArgs),
    /// Plan a study for many machines: write the plan file (inputs' hashes, options, box, sample
    /// list, record schedule) and print the runs, bytes and expected wall time per shard.
    Plan(PlanArgs),
    /// Simulate one shard of a planned study into its record block file.
    Run(RunArgs),
    /// Write a first sidecar for a robot (`ROBOT.uncertainty.toml` beside the URDF, never
    /// overwritten): every link's mass ±5 % and centre of mass ±2 mm, the robot holding a pose
    /// inside its limits on PD joint controllers under gravity.
    Init(InitArgs),
    /// Merge the shards' record blocks into the study's outputs (the same as `analyze`); a
    /// screened or adaptive study that needs another stage gets its plan instead (exit 3).
    Merge(MergeArgs),
}

/// `ribbon init`.
#[derive(Debug, Args)]
pub struct InitArgs {
    /// The robot's URDF file.
    pub urdf: PathBuf,
    /// Put the root link on a floating joint (the sidecar then says `base = "floating"`).
    #[arg(long)]
    pub floating: bool,
    /// The sidecar to write (default: `ROBOT.uncertainty.toml` beside the URDF); an existing file
    /// is never overwritten.
    #[arg(long, value_name = "FILE", conflicts_with = "print")]
    pub out: Option<PathBuf>,
    /// Print the sidecar on stdout instead of writing a file.
    #[arg(long)]
    pub print: bool,
}

/// `ribbon plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The study, with the options of `analyze` (its outputs go to `merge`).
    #[command(flatten)]
    pub analyze: AnalyzeArgs,
    /// The plan file to write.
    #[arg(long, value_name = "FILE")]
    pub plan: PathBuf,
}

/// `ribbon run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The plan file (from `ribbon plan`).
    pub plan: PathBuf,
    /// This shard: K/N, K counted from 0 (e.g. 0/4 … 3/4).
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// The shard count, K read from SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX (both from 0).
    #[arg(long, value_name = "N")]
    pub shards: Option<usize>,
    /// The directory of the record blocks (created if missing); this shard writes
    /// `shard-K-of-N.records.mcap` there (a staged study: in `DIR/stage-S/`) and nothing else.
    #[arg(long, value_name = "DIR")]
    pub into: PathBuf,
    /// A staged study's stage to run, from 1 (default: the last one `merge` planned in DIR).
    #[arg(long, value_name = "S")]
    pub stage: Option<usize>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `ribbon merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The plan file.
    pub plan: PathBuf,
    /// The directory of the shards' record blocks.
    pub dir: PathBuf,
    /// Worker threads for the fits and the check runs (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write the summary JSON.
    #[arg(long, value_name = "FILE")]
    pub summary: Option<PathBuf>,
    /// Write the envelopes as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Write an MCAP log for Foxglove and rerun.
    #[arg(long, value_name = "FILE.mcap")]
    pub out: Option<PathBuf>,
    /// Write a report into this directory (as `analyze --report`).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

/// `ribbon compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The robot, its sidecar and scene overrides.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Write `report.md`, `compare.json` and SVG plots into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// The reference: scan (the true model on a grid; default for d ≤ 4), vertex (true runs at the
    /// sign vertices of central-difference gradients plus a greedy one-flip search; default above)
    /// or monte-carlo:N.
    #[arg(long, value_name = "KIND")]
    pub reference: Option<String>,
    /// Points per dimension of the reference scan (odd; default 21 for d ≤ 2, 11 for d ≥ 3).
    #[arg(long)]
    pub reference_grid: Option<usize>,
    /// Methods to compare (comma-separated); a surrogate method may name its design after a colon
    /// (`legendre-scan:adaptive`, `legendre-scan:screened`, `legendre-scan:sparse`; see `analyze
    /// --design`).
    #[arg(
        long,
        default_value = "legendre-scan,legendre-ia,chebyshev-scan,chebyshev-ia,taylor,monte-carlo"
    )]
    pub methods: String,
    /// Most model runs of `auto` above d = 4 and of the adaptive and screened designs (default
    /// 3000).
    #[arg(long, value_name = "N")]
    pub max_runs: Option<usize>,
    /// Orders of the surrogate methods (comma-separated).
    #[arg(long, default_value = "2,3,4,5")]
    pub orders: String,
    /// Monte Carlo sizes (comma-separated).
    #[arg(long, default_value = "30,100,300")]
    pub samples: String,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `ribbon analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
    /// The robot, its sidecar and scene overrides.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// auto | legendre-scan | legendre-ia | legendre-bernstein | chebyshev-scan | chebyshev-ia |
    /// taylor | scan | monte-carlo (default: the sidecar's `[analysis] method`, else auto: legendre-scan on the
    /// tensor grid for d ≤ 4, total degree k on a Leja sparse grid when it fits --max-runs, the
    /// dimension-adaptive design above).
    #[arg(long)]
    pub method: Option<String>,
    /// Polynomial order k of surrogate methods (default: `[analysis] order`, else 4).
    #[arg(long)]
    pub order: Option<usize>,
    /// tensor | total (the tensor Gauss grid, all terms or total degree) | sparse (Leja sparse grid,
    /// total degree k) | regression (Sobol' least squares, total degree k) | adaptive (Leja terms
    /// chosen by the runs, within --max-runs) | screened (star screening, then the most important
    /// parameters refined, within --max-runs); default tensor; `auto` chooses its own.
    #[arg(long)]
    pub design: Option<String>,
    /// Points per dimension of the true-model `scan` (odd; default 21).
    #[arg(long)]
    pub grid: Option<usize>,
    /// Points per dimension when scanning a surrogate (odd; default 21 for d ≤ 2, 11 for d ≥ 3).
    #[arg(long)]
    pub scan_grid: Option<usize>,
    /// Monte Carlo runs (default 1000).
    #[arg(long)]
    pub samples: Option<usize>,
    /// Monte Carlo seed (default 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Exclude failing samples and list them in the summary (scan and monte-carlo samples, and
    /// check runs).
    #[arg(long)]
    pub keep_going: bool,
    /// Most model runs `--method auto` plans above d = 4, and `--design adaptive|screened` (design,
    /// screening and check; default 3000). A study the check does not trust may add up to half as
    /// many again to refine its extremes on the true model, and twice its check runs to verify the
    /// shorter duration it advises.
    #[arg(long, value_name = "N")]
    pub max_runs: Option<usize>,
    /// True-model runs of the a-posteriori check at the surrogate's predicted extremes (every
    /// surrogate method and taylor; default: 10 % of the design's runs, at least 8; 0 turns it
    /// off, which the summary and the table say).
    #[arg(long, value_name = "N")]
    pub check_runs: Option<usize>,
    /// Split the box into elements (sub-boxes with their own surrogates and checks) where the
    /// a-posteriori check does not trust one surrogate: `auto` (default: on for `--method auto`),
    /// `on` (also `legendre-scan`) or `off` (one surrogate, as before).
    #[arg(long, value_name = "auto|on|off")]
    pub elements: Option<String>,
    /// Most elements (leaves) the box is split into (default 64).
    #[arg(long, value_name = "N")]
    pub max_elements: Option<usize>,
    /// Write the summary JSON.
    #[arg(long, value_name = "FILE")]
    pub summary: Option<PathBuf>,
    /// Write the envelopes as CSV (`t`, then `NAME.lower`, `NAME.nominal`, `NAME.upper` per output).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Write an MCAP log for Foxglove and rerun.
    #[arg(long, value_name = "FILE.mcap")]
    pub out: Option<PathBuf>,
    /// Write a report into this directory (created if missing): `report.md` with the table, a band
    /// plot per output (`<output>.svg`, `<output>.png`) and, with `--out`, `foxglove-layout.json`.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

/// `ribbon simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The robot, its sidecar (optional here: the defaults apply without one) and scene overrides.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Override one parameter (repeatable), e.g. `--set joint.elbow_joint.origin.z=0.43`, or give
    /// a free symbol of the sidecar, e.g. `--set r_wheel=0.3`: the `[bind]` expressions that use it
    /// are evaluated again (an explicit path wins over them).
    #[arg(long = "set", value_name = "PATH=VALUE", allow_hyphen_values = true)]
    pub set: Vec<String>,
    /// Write the recorded series as CSV (`t`, then one column per output).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Write the summary JSON (method "nominal", lower = upper = nominal).
    #[arg(long, value_name = "FILE")]
    pub summary: Option<PathBuf>,
    /// Write an MCAP log for Foxglove and rerun (envelopes, `/tf`, `/robot_description`).
    #[arg(long, value_name = "FILE.mcap")]
    pub out: Option<PathBuf>,
}

/// The robot, its sidecar and the scene overrides that `simulate`, `analyze` and `compare` share.
#[derive(Debug, Args)]
pub struct SceneArgs {
    /// The robot's URDF file.
    pub urdf: PathBuf,
    /// The sidecar file (default: `ROBOT.uncertainty.toml` beside the URDF).
    #[arg(long, value_name = "FILE")]
    pub uncertainty: Option<PathBuf>,
    /// Simulated time, s (overrides `[scene] duration`).
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Fixed step, s (overrides `[scene] step`).
    #[arg(long, value_name = "SECONDS")]
    pub step: Option<f64>,
    /// HHT α in [-1/3, 0] (overrides `[scene] alpha`).
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,
    /// Put the root link on a floating joint (same as `[scene] base = "floating"`).
    #[arg(long)]
    pub floating: bool,
}

impl SceneArgs {
    /// What [`crate::setup::Setup::load`] loads for these flags.
    pub fn request(&self) -> crate::setup::SetupRequest<'_> {
        crate::setup::SetupRequest {
            urdf: &self.urdf,
            uncertainty: self.uncertainty.as_deref(),
            floating: self.floating,
            overrides: self.overrides(),
        }
    }

    /// The command-line values that override the sidecar's `[scene]`.
    pub fn overrides(&self) -> crate::scene::SceneOverrides {
        crate::scene::SceneOverrides {
            duration_s: self.duration,
            step_s: self.step,
            alpha: self.alpha,
        }
    }

    /// The study front end's inputs for these flags.
    pub fn inputs(&self) -> SceneInputs {
        SceneInputs {
            urdf: self.urdf.clone(),
            uncertainty: self.uncertainty.clone(),
            overrides: self.overrides(),
            floating: self.floating,
        }
    }
}

/// `ribbon params`.
#[derive(Debug, Args)]
pub struct ParamsArgs {
    /// The robot's URDF file.
    pub urdf: PathBuf,
    /// Print JSON (`[{path, nominal, unit}]`, or with `--uncertainty` the expanded box) instead
    /// of a table.
    #[arg(long)]
    pub json: bool,
    /// Instead of every parameter, print the box this sidecar declares: d, every dimension with
    /// its bounds, nominal, unit and source key (patterns expanded), the bindings, then the notes.
    #[arg(long, value_name = "FILE")]
    pub uncertainty: Option<PathBuf>,
    /// Put the root link on a floating joint (`root_joint`).
    #[arg(long)]
    pub floating: bool,
}

/// `ribbon dynamics`.
#[derive(Debug, Args)]
pub struct DynamicsArgs {
    /// The robot's URDF file.
    pub urdf: PathBuf,
    /// Joint positions, comma-separated, one per coordinate (default: neutral configuration).
    #[arg(long, allow_hyphen_values = true, value_name = "Q1,Q2,…")]
    pub q: Option<String>,
    /// Joint velocities, comma-separated (default: zero).
    #[arg(long, allow_hyphen_values = true, value_name = "V1,V2,…")]
    pub v: Option<String>,
    /// Joint torques: also compute forward dynamics `qdd`.
    #[arg(long, allow_hyphen_values = true, value_name = "T1,T2,…")]
    pub tau: Option<String>,
    /// Joint accelerations: also compute inverse dynamics `tau`.
    #[arg(long, allow_hyphen_values = true, value_name = "A1,A2,…")]
    pub qdd: Option<String>,
    /// Override one parameter (repeatable), e.g. `--set link.forearm_link.mass=2.4`.
    #[arg(long = "set", value_name = "PATH=VALUE", allow_hyphen_values = true)]
    pub set: Vec<String>,
    /// Put the root link on a floating joint (`root_joint`).
    #[arg(long)]
    pub floating: bool,
    /// Print JSON instead of a readable report.
    #[arg(long)]
    pub json: bool,
}

/// Runs one parsed command line.
pub fn run(cli: Cli) -> Result<(), Error> {
    match cli.command {
        Command::Params(args) => params_cmd::run(&args),
        Command::Dynamics(args) => dynamics_cmd::run(&args),
        Command::Simulate(args) => simulate_cmd::run(&args),
        Command::Analyze(args) => analyze_cmd::run(&args),
        Command::Compare(args) => compare_cmd::run(&args),
        Command::Plan(args) => plan_cmd::run(&args),
        Command::Run(args) => run_cmd::run(&args),
        Command::Merge(args) => merge_cmd::run(&args),
        Command::Init(args) => init_cmd::run(&args),
    }
}

/// Prints the model's load warnings on stderr.
fn print_warnings(model: &crate::model::Model) {
    for warning in &model.warnings {
        eprintln!("warning: {warning}");
    }
}

/// Writes `text` to stdout ([`crate::output::write_stdout`]: a closed pipe is an error).
fn write_stdout(text: &str) -> Result<(), Error> {
    Ok(crate::output::write_stdout(text)?)
}
