//! A study as a person asks for it — plain option structs, no command-line parser's types — and
//! the [`StudyOptions`] they make: the flags first, then the sidecar's `[analysis]`, then the
//! defaults, each refused value blamed on its flag (exit 2).
//!
//! ```text
//! StudyRequest { scene: SceneInputs, flags: StudyFlags, outputs: StudyOutputs }
//!   ⇒ study_options(flags, [analysis]) ⇒ StudyOptions (analysis/)
//! ```
//!
//! `cli/` fills these from its parsed arguments; `run` and `merge` rebuild them from a plan file
//! ([`StudyRequest::of_plan`]), so every study command reads options the same way. Does not: check
//! what the options plan (`analysis::StudyPlan::new` does, e.g. "--grid 4 must be odd").

use crate::analysis::{
    DesignKind, ElementsOptions, Method, StudyOptions, DEFAULT_MAX_ELEMENTS, DEFAULT_MAX_RUNS,
    METHODS,
};
use crate::distributed::{PlanFile, PlanOptions};
use crate::scene::{check_threads, AnalysisSection, SceneOverrides};
use crate::setup::SetupRequest;
use crate::text::closest_suggestion;
use crate::uq::Truncation;
use crate::Error;
use std::path::PathBuf;

/// Default polynomial order.
pub const DEFAULT_ORDER: usize = 4;
/// Default points per dimension of the true-model scan.
pub const DEFAULT_GRID: usize = 21;
/// Default Monte Carlo runs.
pub const DEFAULT_SAMPLES: usize = 1000;

/// The designs `--design` accepts.
pub const DESIGN_NAMES: &str = "tensor, total, sparse, regression, adaptive or screened";

/// The robot, its sidecar and the scene overrides of a study, as given.
#[derive(Clone, Debug, Default)]
pub struct SceneInputs {
    /// The robot's URDF file.
    pub urdf: PathBuf,
    /// The sidecar file (`None`: `ROBOT.uncertainty.toml` beside the URDF).
    pub uncertainty: Option<PathBuf>,
    /// Values that override the sidecar's `[scene]` (`--duration`, `--step`, `--alpha`).
    pub overrides: SceneOverrides,
    /// Put the root link on a floating joint (`--floating`).
    pub floating: bool,
}

impl SceneInputs {
    /// What [`crate::setup::Setup::load`] loads for these inputs.
    pub fn request(&self) -> SetupRequest<'_> {
        SetupRequest {
            urdf: &self.urdf,
            uncertainty: self.uncertainty.as_deref(),
            floating: self.floating,
            overrides: self.overrides,
        }
    }

    /// The sidecar a study reads: `uncertainty`, or `ROBOT.uncertainty.toml` beside the URDF.
    pub fn sidecar_path(&self) -> PathBuf {
        self.request().sidecar_path()
    }
}

/// The options of a study as given (`None`: not given, so the sidecar's `[analysis]` or the
/// default applies); the flags of `analyze` and `plan`.
#[derive(Clone, Debug, Default)]
pub struct StudyFlags {
    /// `--method`.
    pub method: Option<String>,
    /// `--order`.
    pub order: Option<usize>,
    /// `--design`.
    pub design: Option<String>,
    /// `--grid`.
    pub grid: Option<usize>,
    /// `--scan-grid`.
    pub scan_grid: Option<usize>,
    /// `--samples`.
    pub samples: Option<usize>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--threads` (`None`: all cores).
    pub threads: Option<usize>,
    /// `--keep-going`.
    pub keep_going: bool,
    /// `--max-runs`.
    pub max_runs: Option<usize>,
    /// `--check-runs`.
    pub check_runs: Option<usize>,
    /// `--elements`: `auto` (default: on for `--method auto`), `on` or `off`.
    pub elements: Option<String>,
    /// `--max-elements`.
    pub max_elements: Option<usize>,
}

/// Where a study's results go (`None`: not written).
#[derive(Clone, Debug, Default)]
pub struct StudyOutputs {
    /// `--summary`: the summary JSON.
    pub summary: Option<PathBuf>,
    /// `--csv`: the envelopes as CSV.
    pub csv: Option<PathBuf>,
    /// `--out`: the MCAP log.
    pub out: Option<PathBuf>,
    /// `--report`: the report directory.
    pub report: Option<PathBuf>,
}

impl StudyOutputs {
    /// The output files with the flags that name them (`--report` is a directory, checked apart).
    pub fn files(&self) -> [(&'static str, Option<&std::path::Path>); 3] {
        [
            ("--summary", self.summary.as_deref()),
            ("--csv", self.csv.as_deref()),
            ("--out", self.out.as_deref()),
        ]
    }
}

/// A whole study as asked for: its inputs, options and outputs.
#[derive(Clone, Debug, Default)]
pub struct StudyRequest {
    /// The robot, its sidecar and the scene overrides.
    pub scene: SceneInputs,
    /// The study's options.
    pub flags: StudyFlags,
    /// Its outputs.
    pub outputs: StudyOutputs,
}

impl StudyRequest {
    /// The study a plan file was made for (`--uncertainty` naming the planned sidecar), with
    /// `threads` and no outputs.
    pub fn of_plan(plan: &PlanFile, threads: Option<usize>) -> StudyRequest {
        let o = &plan.body.options;
        StudyRequest {
            scene: SceneInputs {
                urdf: plan.body.urdf.path.clone(),
                uncertainty: Some(plan.body.sidecar.path.clone()),
                overrides: SceneOverrides {
                    duration_s: o.duration,
                    step_s: o.step,
                    alpha: o.alpha,
                },
                floating: o.floating,
            },
            flags: StudyFlags {
                method: o.method.clone(),
                order: o.order,
                design: o.design.clone(),
                grid: o.grid,
                scan_grid: o.scan_grid,
                samples: o.samples,
                seed: o.seed,
                threads,
                keep_going: o.keep_going,
                max_runs: o.max_runs,
                check_runs: o.check_runs,
                elements: o.elements.clone(),
                max_elements: o.max_elements,
            },
            outputs: StudyOutputs::default(),
        }
    }

    /// The options a plan file keeps of this request (everything but the threads and the outputs),
    /// as given.
    pub fn plan_options(&self) -> PlanOptions {
        let (scene, flags) = (&self.scene, &self.flags);
        PlanOptions {
            duration: scene.overrides.duration_s,
            step: scene.overrides.step_s,
            alpha: scene.overrides.alpha,
            floating: scene.floating,
            method: flags.method.clone(),
            order: flags.order,
            design: flags.design.clone(),
            grid: flags.grid,
            scan_grid: flags.scan_grid,
            samples: flags.samples,
            seed: flags.seed,
            keep_going: flags.keep_going,
            max_runs: flags.max_runs,
            check_runs: flags.check_runs,
            elements: flags.elements.clone(),
            max_elements: flags.max_elements,
        }
    }
}

fn bad(flag: &str, message: String) -> Error {
    Error::BadArgument {
        flag: flag.to_string(),
        message,
    }
}

/// The study's options from the flags and the sidecar's `[analysis]` (flags first).
pub fn study_options(flags: &StudyFlags, section: &AnalysisSection) -> Result<StudyOptions, Error> {
    let method_name = flags
        .method
        .clone()
        .or_else(|| section.method.clone())
        .unwrap_or_else(|| "auto".to_string());
    let method = Method::parse(&method_name).ok_or_else(|| {
        let names: Vec<&str> = METHODS.iter().map(|(n, _)| *n).collect();
        bad(
            "--method",
            format!(
                "unknown method '{method_name}'{}; methods: {}",
                closest_suggestion(&method_name, names.iter().copied()),
                names.join(", ")
            ),
        )
    })?;
    let design_name = flags
        .design
        .clone()
        .or_else(|| section.design.clone())
        .unwrap_or_else(|| "tensor".to_string());
    let (truncation, design) = parse_design(&design_name).ok_or_else(|| {
        bad(
            "--design",
            format!(
                "'{design_name}' is not a design; use {DESIGN_NAMES} (or leave it to --method auto)"
            ),
        )
    })?;
    if method == Method::Auto && (flags.design.is_some() || section.design.is_some()) {
        return Err(bad(
            "--design",
            "--method auto chooses the design itself; name a method (e.g. --method legendre-scan) to choose a design".to_string(),
        ));
    }
    let max_runs = match (flags.max_runs, section.max_runs) {
        (None, Some(budget)) => max_runs_of(Some(budget), "[analysis] max_runs")?,
        (flag, _) => max_runs_of(flag, "--max-runs")?,
    };
    let threads = check_threads("--threads", flags.threads.unwrap_or(0))?;
    let elements = elements_of(flags, method)?;
    Ok(StudyOptions {
        method,
        order: flags.order.or(section.order).unwrap_or(DEFAULT_ORDER),
        truncation,
        grid: flags.grid.unwrap_or(DEFAULT_GRID),
        scan_grid: flags.scan_grid,
        samples: flags.samples.unwrap_or(DEFAULT_SAMPLES),
        seed: flags.seed.unwrap_or(0),
        threads,
        keep_going: flags.keep_going,
        check_runs: flags.check_runs,
        design,
        max_runs,
        elements,
    })
}

/// `--elements` and `--max-elements`: `auto` (the default) splits for `--method auto` only, `on`
/// for `legendre-scan` too; other methods refuse `on` (their bounds are not a surrogate scan that
/// a check can judge element by element).
pub fn elements_of(flags: &StudyFlags, method: Method) -> Result<ElementsOptions, Error> {
    let mode = flags.elements.as_deref().unwrap_or("auto");
    let enabled = match mode {
        "auto" => method == Method::Auto,
        "off" => false,
        "on" if matches!(method, Method::Auto | Method::LegendreScan) => true,
        "on" => {
            return Err(bad(
                "--elements",
                format!(
                    "elements split the box of a Legendre surrogate that is scanned: use them with --method auto or legendre-scan, not {}",
                    method.name()
                ),
            ))
        }
        other => {
            return Err(bad(
                "--elements",
                format!("'{other}' is not a choice; use auto (the default: on for --method auto), on or off"),
            ))
        }
    };
    let max_elements = flags.max_elements.unwrap_or(DEFAULT_MAX_ELEMENTS);
    if max_elements < 2 && flags.max_elements.is_some() {
        return Err(bad(
            "--max-elements",
            format!("{max_elements} element(s) cannot split anything; give at least 2, or --elements off"),
        ));
    }
    Ok(ElementsOptions {
        enabled,
        max_elements,
    })
}

/// `--max-runs` or `[analysis] max_runs` (default [`DEFAULT_MAX_RUNS`]; `name` is where the
/// value came from), refused below 2: a design and its nominal run.
pub fn max_runs_of(flag: Option<usize>, name: &str) -> Result<usize, Error> {
    let max_runs = flag.unwrap_or(DEFAULT_MAX_RUNS);
    if max_runs < 2 {
        return Err(bad(
            name,
            format!("{max_runs} runs cannot hold a design and its nominal run; give at least 2"),
        ));
    }
    Ok(max_runs)
}

/// A design's name → its truncation and kind (`None` for an unknown name).
pub fn parse_design(name: &str) -> Option<(Truncation, DesignKind)> {
    Some(match name {
        "tensor" => (Truncation::Tensor, DesignKind::Tensor),
        "total" => (Truncation::Total, DesignKind::Tensor),
        "sparse" => (Truncation::Total, DesignKind::Sparse),
        "regression" => (Truncation::Total, DesignKind::Regression),
        "adaptive" => (Truncation::Total, DesignKind::Adaptive),
        "screened" => (Truncation::Total, DesignKind::Screened),
        _ => return None,
    })
}

/// The polynomial order a study with `method` reports (summary, table, MCAP metadata): none for
/// `scan` and `monte-carlo`, 1 for `taylor`, the options' order for surrogates.
pub fn order_of(method: Method, options: &StudyOptions) -> Option<usize> {
    match method {
        Method::Scan | Method::MonteCarlo => None,
        Method::Taylor => Some(1),
        _ => Some(options.order),
    }
}
