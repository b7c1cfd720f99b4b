//! `compare`: what accuracy costs in time. Runs a reference made of true-model runs (a scan of
//! the true model for d ≤ 4, the vertex reference above, or Monte Carlo), then every method (and
//! order, and Monte Carlo size) on the same scene, and reports model runs, wall time and the
//! docs/method.md §4 error of each against the reference: a table on stdout and, with a report
//! directory, `report.md`, `compare.json` and plots (`compare_report.rs`).
//!
//! Does not: bound anything itself (each row is an ordinary study).

use super::compare_report::{render_table, write_report, Row, REPORT_FILES};
use super::install_interrupt;
use super::options::{max_runs_of, parse_design, SceneInputs, DESIGN_NAMES};
use super::run_study::prepare;
use crate::analysis::{
    DesignKind, ElementsOptions, Method, Study, StudyOptions, StudyReport, VertexReferenceOptions,
    BLOCK_VALUE_BUDGET,
};
use crate::output::{prepare_output_directory, write_stdout};
use crate::scene::check_threads;
use crate::setup::Setup;
use crate::uq::{envelope_error, Truncation};
use crate::Error;
use std::path::PathBuf;
use std::time::Instant;

/// The reference the methods are compared with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceKind {
    /// The true model on a uniform grid of `grid` points per dimension.
    Scan {
        /// Points per dimension (odd).
        grid: usize,
    },
    /// Sign vertices of central-difference gradients plus a greedy one-flip search
    /// ([`Study::vertex_reference`]).
    Vertex,
    /// The true model at `samples` seeded random points.
    MonteCarlo {
        /// Runs.
        samples: usize,
    },
}

/// Largest d for which `compare` defaults to a scan reference (11^4 = 14 641 runs).
pub const SCAN_REFERENCE_MAX_DIM: usize = 4;

impl ReferenceKind {
    /// How the table and report name it.
    pub fn label(self, d: usize) -> String {
        match self {
            ReferenceKind::Scan { grid } => format!("scan {grid}^{d} of the true model"),
            ReferenceKind::Vertex => {
                "vertex (true runs at the sign vertices of central-difference gradients, then greedy one-flip search)".to_string()
            }
            ReferenceKind::MonteCarlo { samples } => {
                format!("monte-carlo with {samples} true-model runs")
            }
        }
    }
}

/// `--reference scan|vertex|monte-carlo:N` (default: scan up to d = 4, vertex above).
fn parse_reference(text: Option<&str>, d: usize, grid: usize) -> Result<ReferenceKind, Error> {
    let bad = |message: String| Error::BadArgument {
        flag: "--reference".to_string(),
        message,
    };
    match text {
        None if d <= SCAN_REFERENCE_MAX_DIM => Ok(ReferenceKind::Scan { grid }),
        None => Ok(ReferenceKind::Vertex),
        Some("scan") => Ok(ReferenceKind::Scan { grid }),
        Some("vertex") => Ok(ReferenceKind::Vertex),
        Some(other) => match other.strip_prefix("monte-carlo:") {
            Some(n) => match n.parse::<usize>() {
                Ok(samples) if samples > 0 => Ok(ReferenceKind::MonteCarlo { samples }),
                _ => Err(bad(format!(
                    "'{other}': the number of runs after 'monte-carlo:' must be a whole number ≥ 1 (e.g. monte-carlo:20000)"
                ))),
            },
            None => Err(bad(format!(
                "'{other}' is not a reference; use scan, vertex or monte-carlo:N"
            ))),
        },
    }
}

/// A design named in `--methods` (`METHOD:DESIGN`): its name, truncation and kind.
type NamedDesign = (String, Truncation, DesignKind);

/// `METHOD` or `METHOD:DESIGN` of `--methods`.
fn parse_method_token(token: &str) -> Result<(Method, Option<NamedDesign>), Error> {
    let bad = |message: String| Error::BadArgument {
        flag: "--methods".to_string(),
        message,
    };
    let (name, design) = match token.split_once(':') {
        Some((name, design)) => (name, Some(design)),
        None => (token, None),
    };
    let method = Method::parse(name).ok_or_else(|| bad(format!("unknown method '{name}'")))?;
    let Some(design) = design else {
        return Ok((method, None));
    };
    if method.family().is_none() || method == Method::Auto {
        return Err(bad(format!(
            "'{token}': only a surrogate method (legendre-scan, legendre-ia, …) takes a design; auto chooses its own"
        )));
    }
    let (truncation, kind) = parse_design(design).ok_or_else(|| {
        bad(format!(
            "'{token}': '{design}' is not a design; use {DESIGN_NAMES}"
        ))
    })?;
    Ok((method, Some((design.to_string(), truncation, kind))))
}

fn parse_list(flag: &str, text: &str) -> Result<Vec<String>, Error> {
    let items: Vec<String> = text
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    if items.is_empty() {
        return Err(Error::BadArgument {
            flag: flag.to_string(),
            message: "give at least one value".to_string(),
        });
    }
    Ok(items)
}

fn parse_numbers(flag: &str, text: &str) -> Result<Vec<usize>, Error> {
    parse_list(flag, text)?
        .iter()
        .map(|item| {
            item.parse().map_err(|_| Error::BadArgument {
                flag: flag.to_string(),
                message: format!("'{item}' is not a whole number"),
            })
        })
        .collect()
}

/// An output whose reference envelope is never wider than this fraction of its magnitude is not
/// uncertain (a driven joint, a coordinate fixed by the constraints): its width is rounding noise,
/// and docs/method.md's relative error would divide by it.
pub const CERTAIN_OUTPUT_RELATIVE_WIDTH: f64 = 1e-9;

/// Outputs of the reference that carry uncertainty (see [`CERTAIN_OUTPUT_RELATIVE_WIDTH`]).
fn uncertain_outputs(reference: &StudyReport) -> Vec<usize> {
    let r = &reference.envelope;
    (0..r.outputs.len())
        .filter(|&o| {
            let width = r.upper[o]
                .iter()
                .zip(&r.lower[o])
                .map(|(u, l)| u - l)
                .fold(0.0, f64::max);
            let scale = r.nominal[o]
                .iter()
                .map(|x| x.abs())
                .fold(0.0, f64::max)
                .max(f64::MIN_POSITIVE);
            width > CERTAIN_OUTPUT_RELATIVE_WIDTH * scale
        })
        .collect()
}

/// Errors of `report` against `reference` over the uncertain outputs: (max over outputs of max,
/// mean over outputs of mean, the worst output).
struct Comparison {
    max_error: f64,
    mean_error: f64,
    worst_output: String,
    worst_time_s: f64,
    max_missed: f64,
}

fn compare_envelopes(report: &StudyReport, reference: &StudyReport) -> Comparison {
    let (r, e) = (&reference.envelope, &report.envelope);
    let mut comparison = Comparison {
        max_error: 0.0,
        mean_error: 0.0,
        worst_output: String::new(),
        worst_time_s: 0.0,
        max_missed: 0.0,
    };
    let (mut sum, mut count) = (0.0, 0);
    for o in uncertain_outputs(reference) {
        let Ok(error) = envelope_error(&e.lower[o], &e.upper[o], &r.lower[o], &r.upper[o]) else {
            continue;
        };
        if error.max > comparison.max_error || comparison.worst_output.is_empty() {
            comparison.max_error = error.max;
            comparison.worst_output = r.outputs[o].name.clone();
            comparison.worst_time_s = r.times.get(error.argmax).copied().unwrap_or(0.0);
        }
        comparison.max_missed = comparison.max_missed.max(error.max_missed);
        sum += error.mean;
        count += 1;
    }
    comparison.mean_error = if count > 0 { sum / count as f64 } else { 0.0 };
    comparison
}

/// What `compare` is asked, as given: the robot and scene, the report directory, the reference,
/// the methods and their settings (comma-separated lists, parsed in [`compare`]).
#[derive(Clone, Debug)]
pub struct CompareRequest {
    /// The robot, its sidecar and scene overrides.
    pub scene: SceneInputs,
    /// `--report DIR`.
    pub report: Option<PathBuf>,
    /// `--reference scan|vertex|monte-carlo:N`.
    pub reference: Option<String>,
    /// `--reference-grid`.
    pub reference_grid: Option<usize>,
    /// `--methods`: `METHOD` or `METHOD:DESIGN`, comma-separated.
    pub methods: String,
    /// `--max-runs`.
    pub max_runs: Option<usize>,
    /// `--orders`, comma-separated.
    pub orders: String,
    /// `--samples`, comma-separated.
    pub samples: String,
    /// `--threads` (`None`: all cores).
    pub threads: Option<usize>,
}

/// Runs every method against the reference and reports the table (module documentation).
pub fn compare(args: &CompareRequest) -> Result<(), Error> {
    if let Some(dir) = &args.report {
        let sidecar = args.scene.sidecar_path();
        prepare_output_directory(
            "--report",
            dir,
            &REPORT_FILES,
            &[("URDF", &args.scene.urdf), ("sidecar", &sidecar)],
        )?;
    }
    install_interrupt();
    let threads = check_threads("--threads", args.threads.unwrap_or(0))?;
    let Setup {
        model,
        environment,
        scene,
        space,
        ..
    } = prepare(&args.scene)?;
    // Kept per record time: the reference, the current and the best surrogate's envelopes (time;
    // lower, upper, nominal, error estimate per output).
    scene.check_memory(
        "compare",
        3 * (1 + 4 * scene.outputs.len() as u64),
        (BLOCK_VALUE_BUDGET * 8) as u64,
    )?;
    let d = space.len();
    let methods: Vec<(Method, Option<NamedDesign>)> = parse_list("--methods", &args.methods)?
        .iter()
        .map(|token| parse_method_token(token))
        .collect::<Result<_, _>>()?;
    let orders = parse_numbers("--orders", &args.orders)?;
    let samples = parse_numbers("--samples", &args.samples)?;
    let reference_grid = args.reference_grid.unwrap_or(if d <= 2 { 21 } else { 11 });
    let reference_kind = parse_reference(args.reference.as_deref(), d, reference_grid)?;
    let base = StudyOptions {
        method: Method::Scan,
        order: 4,
        truncation: Truncation::Tensor,
        grid: reference_grid,
        scan_grid: None,
        samples: 1000,
        seed: 0,
        threads,
        keep_going: false,
        check_runs: None,
        design: DesignKind::Tensor,
        max_runs: max_runs_of(args.max_runs, "--max-runs")?,
        elements: ElementsOptions::default(),
    };
    let interrupt = crate::interrupt::flag();
    let run_study = |options: StudyOptions| -> Result<(StudyReport, f64), Error> {
        let study = Study::new(&model, &environment, &scene, &space, options);
        let started = Instant::now();
        let report = study.run(interrupt, &mut |_| {}, &mut |_| Ok(()))?;
        if report.partial {
            // A comparison of partial envelopes would be wrong: nothing is written.
            return Err(Error::Interrupted(
                "stopped during a study; a comparison needs whole runs, so no report was written"
                    .to_string(),
            ));
        }
        Ok((report, started.elapsed().as_secs_f64()))
    };
    let reference_label = reference_kind.label(d);
    eprintln!("compare: reference {reference_label} …");
    let (reference, reference_seconds) = match reference_kind {
        ReferenceKind::Scan { .. } => run_study(base.clone())?,
        ReferenceKind::MonteCarlo { samples } => run_study(StudyOptions {
            method: Method::MonteCarlo,
            samples,
            ..base.clone()
        })?,
        ReferenceKind::Vertex => {
            let study = Study::new(&model, &environment, &scene, &space, base.clone());
            let started = Instant::now();
            let report = study.vertex_reference(
                VertexReferenceOptions::default(),
                interrupt,
                &mut |_| {},
            )?;
            if report.partial {
                return Err(Error::Interrupted(
                    "interrupted while computing the vertex reference; nothing was written"
                        .to_string(),
                ));
            }
            (report, started.elapsed().as_secs_f64())
        }
    };
    eprintln!("  {} runs in {reference_seconds:.3} s", reference.runs);

    let mut configurations: Vec<(Method, Option<usize>, Option<String>, StudyOptions)> = Vec::new();
    for (method, design) in &methods {
        let design_name = design.as_ref().map(|(name, _, _)| name.clone());
        let (truncation, design_kind) = design
            .as_ref()
            .map_or((Truncation::Tensor, DesignKind::Tensor), |(_, t, k)| {
                (*t, *k)
            });
        match method {
            Method::Scan => {}
            Method::Taylor => configurations.push((
                *method,
                Some(1),
                None,
                StudyOptions {
                    method: *method,
                    ..base.clone()
                },
            )),
            Method::MonteCarlo => {
                for n in &samples {
                    configurations.push((
                        *method,
                        Some(*n),
                        None,
                        StudyOptions {
                            method: *method,
                            samples: *n,
                            ..base.clone()
                        },
                    ));
                }
            }
            surrogate => {
                for k in &orders {
                    configurations.push((
                        *surrogate,
                        Some(*k),
                        design_name.clone(),
                        StudyOptions {
                            method: *surrogate,
                            order: *k,
                            truncation,
                            design: design_kind,
                            // `auto` compares as `analyze` runs it: with elements.
                            elements: ElementsOptions {
                                enabled: *surrogate == Method::Auto,
                                ..base.elements
                            },
                            ..base.clone()
                        },
                    ));
                }
            }
        }
    }
    let mut rows = Vec::with_capacity(configurations.len());
    let mut best_surrogate: Option<(String, StudyReport)> = None;
    for (method, setting, design, options) in configurations {
        let (report, seconds) = run_study(options)?;
        let Comparison {
            max_error,
            mean_error,
            worst_output,
            worst_time_s,
            max_missed,
        } = compare_envelopes(&report, &reference);
        let name = match &design {
            Some(design) => format!("{}:{design}", method.name()),
            None => method.name().to_string(),
        };
        let label = match (method, setting) {
            (Method::MonteCarlo, Some(n)) => format!("{name} N={n}"),
            (_, Some(k)) if method != Method::Taylor => format!("{name} k={k}"),
            _ => name.clone(),
        };
        eprintln!(
            "  {label}: {} runs, {seconds:.3} s, max error {max_error:.3e}",
            report.runs
        );
        if matches!(method, Method::LegendreScan | Method::Auto) {
            best_surrogate = Some((label.clone(), report.clone()));
        }
        rows.push(Row {
            method: name,
            design: report.design.to_string(),
            setting,
            bound_kind: method.bound_kind().to_string(),
            runs: report.runs,
            wall_seconds: seconds,
            max_error,
            mean_error,
            worst_output,
            worst_time_s,
            max_missed,
        });
    }

    let skipped: Vec<&str> = (0..reference.envelope.outputs.len())
        .filter(|o| !uncertain_outputs(&reference).contains(o))
        .map(|o| reference.envelope.outputs[o].name.as_str())
        .collect();
    let mut table = render_table(&rows, reference.runs, reference_seconds, &reference_label);
    if !skipped.is_empty() {
        table.push_str(&format!(
            "
not compared (no uncertainty: reference width ≤ {CERTAIN_OUTPUT_RELATIVE_WIDTH:e} of the value): {}
",
            skipped.join(", ")
        ));
    }
    if let Some(dir) = &args.report {
        write_report(
            dir,
            &table,
            &rows,
            &reference,
            reference_seconds,
            &reference_label,
            best_surrogate.as_ref(),
        )?;
        eprintln!("report written to {}", dir.display());
    }
    write_stdout(&table)?;
    Ok(())
}
