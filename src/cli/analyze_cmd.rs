//! `ribbon analyze ROBOT.urdf [--uncertainty F] [--method M] [--order K] [--design tensor|total]
//! [--grid N] [--scan-grid N] [--samples N] [--seed S] [--threads N] [--keep-going] [--summary F]
//! [--csv F] [--out F.mcap] [--report DIR]`: bound envelopes. A progress line on stderr, a table on stdout.
//! Outputs are checked before anything runs. SIGINT/SIGTERM finish the current block, write what was
//! computed (MCAP marked partial) and exit 1; a second signal exits at once, removing the temporary
//! files.

use super::{
    check_finite, check_output_paths, install_interrupt, write_stdout, AnalyzeArgs, SceneArgs,
};
use crate::analysis::{
    has_sobol_indices, sobol_values_per_record, untrusted_advice, CheckReport, DesignKind,
    ForeignError, Method, Progress, RecordSchedule, SimulateHere, StageRecords, Study,
    StudyOptions, StudyPlan, StudyReport, ADAPTIVE_TOLERANCE, CHAOS_AMPLIFICATION,
    DEFAULT_MAX_RUNS, METHODS, TABLE_SOBOL_CONTRIBUTORS, TRUST_RELATIVE_MISFIT,
    TRUST_RESOLUTION_FACTOR,
};
use crate::distributed::{PlanFile, ShardError, ShardStages};
use crate::dynamics::Data;
use crate::output::mcap::McapMetadata;
use crate::output::{
    write_csv, EnvelopeLog, EnvelopeSeries, ParameterSummary, SensitivitySummary, SobolSummary,
    Summary,
};
use crate::scene::{
    check_threads, describe_limit_excursions, limit_excursions, outputs_at_enforced_limits,
    LimitExcursion, Scene,
};
use crate::setup::{print_message, Setup};
use crate::text::closest_suggestion;
use crate::uncertainty::ParameterSpace;
use crate::uq::Truncation;
use crate::Error;
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

/// Default polynomial order.
pub const DEFAULT_ORDER: usize = 4;
/// Default points per dimension of the true-model scan.
pub const DEFAULT_GRID: usize = 21;
/// Default Monte Carlo runs.
pub const DEFAULT_SAMPLES: usize = 1000;
/// Without a terminal, at most one progress line per this many seconds (after the first).
const PROGRESS_INTERVAL_S: f64 = 1.0;

fn bad(flag: &str, message: String) -> Error {
    Error::BadArgument {
        flag: flag.to_string(),
        message,
    }
}

/// Runs `ribbon analyze`.
pub fn run(args: &AnalyzeArgs) -> Result<(), Error> {
    run_study(args, None)
}

/// The design's records of a merge: the plan and the directory of its shards' record blocks.
pub struct MergeInput<'a> {
    /// The plan file.
    pub plan: &'a PlanFile,
    /// Its path.
    pub plan_path: &'a Path,
    /// The directory holding the record blocks.
    pub dir: &'a Path,
}

/// `analyze` (`merge` is `None`: the design is simulated here) or `merge` (the design's records are
/// read from the shards): the same stages and sinks either way.
pub fn run_study(args: &AnalyzeArgs, merge: Option<MergeInput>) -> Result<(), Error> {
    let started = Instant::now();
    check_output_paths(
        &args.scene,
        Some(&sidecar_path_of(&args.scene)),
        &[
            ("--summary", args.summary.as_ref()),
            ("--csv", args.csv.as_ref()),
            ("--out", args.out.as_ref()),
        ],
    )?;
    install_interrupt();
    let Setup {
        sidecar_path,
        sidecar,
        model,
        scene,
        space,
    } = prepare(&args.scene)?;
    let options = study_options(args, &sidecar.analysis)?;
    let report_stems = prepare_report(args, &sidecar_path, &scene)?;
    // Kept per record time: the envelope (time; lower, upper, nominal and an error estimate per
    // output) and, with --summary, its five copies per output; plus one block of samples.
    // Surrogate studies also keep their Sobol' indices (and, with --summary, a copy).
    let sobol = sobol_values_per_record(options.method, space.len());
    let per_output = 4 + sobol + if args.summary.is_some() { 5 + sobol } else { 0 };
    scene.check_memory(
        "analyze",
        (1 + scene.outputs.len() * per_output) as u64,
        (crate::analysis::BLOCK_VALUE_BUDGET * 8) as u64,
    )?;
    let robot = model.name().to_string();
    let study = Study::new(&model, &scene, &space, options.clone());
    let plan = study.plan()?;
    // Where the records of each stage come from: simulated here, or the shards' record blocks.
    let mut simulate_here = SimulateHere;
    let mut shard_stages;
    let stages: &mut dyn StageRecords = match &merge {
        Some(input) => {
            check_plan_matches(input.plan, input.plan_path, &study, &plan)?;
            shard_stages = ShardStages::new(input.plan, input.plan_path, input.dir);
            &mut shard_stages
        }
        None => &mut simulate_here,
    };
    let runs = plan.max_runs();
    eprintln!(
        "analyze: {} parameters, method {}{} ({}), design {}, {}{} model runs{} of {} s at h = {} s",
        space.len(),
        plan.method.name(),
        if options.method == Method::Auto { " (auto)" } else { "" },
        plan.method.bound_kind(),
        plan.design_name,
        if plan.screening_runs > 0 {
            format!("{} screening + ", plan.screening_runs)
        } else {
            String::new()
        },
        plan.design_runs,
        if plan.check_runs > 0 {
            format!(" + up to {} check runs", plan.check_runs)
        } else {
            String::new()
        },
        scene.duration_s,
        scene.step_s
    );
    if let Some(auto) = &plan.auto {
        eprintln!("auto: {}", auto.reason);
    }

    let interrupt = crate::interrupt::flag();

    let metadata = McapMetadata {
        robot: robot.clone(),
        method: plan.method.name().to_string(),
        order: order_of(plan.method, &options),
        runs,
        parameters_json: serde_json::to_string(&parameter_summaries(&space))
            .unwrap_or_else(|_| "[]".to_string()),
    };
    let mut log = match &args.out {
        Some(path) => Some(EnvelopeLog::create(
            path,
            &args.scene.urdf,
            Some(&sidecar_path),
            metadata,
            &scene.outputs,
            plan.method.family().is_some() || plan.method == Method::Taylor,
        )?),
        None => None,
    };
    if let (Some(log), true) = (log.as_mut(), has_sobol_indices(plan.method)) {
        let names: Vec<String> = space.dimensions().iter().map(|d| d.name.clone()).collect();
        log.add_sobol_channels(&names)?;
    }
    let kinematic_model = model;
    let mut data = Data::new(&kinematic_model);
    let mut reporter = ProgressReporter::new();
    let scans_a_surrogate = plan.method.locates_extremes();
    let report = study.run_stages(
        plan,
        stages,
        interrupt,
        &mut |progress| reporter.report(progress),
        &mut |block| match log.as_mut() {
            Some(log) => log
                .write_block(block, &kinematic_model, &mut data)
                .map_err(ForeignError::new),
            None => Ok(()),
        },
    )?;
    reporter.finish();
    let wall_seconds = started.elapsed().as_secs_f64();
    check_envelope_finite(&report)?;
    // What to do about untrusted outputs: said once, in the warning and in the exit-4 error.
    let advice = report
        .check
        .as_ref()
        .filter(|check| !check.untrusted_outputs.is_empty())
        .map(|check| advice(&report, check, &kinematic_model, &scene, space.len()));
    // Every warning goes to stderr now and into the report's page (`--report`).
    let mut warnings: Vec<String> = Vec::new();
    let excursions = limit_excursions(
        &kinematic_model,
        &scene,
        &report.envelope.outputs,
        &report.envelope.times,
        &report.envelope.lower,
        &report.envelope.upper,
    );
    if !excursions.is_empty() {
        let mut warning = describe_limit_excursions(&excursions, true);
        if let Some(check) = &report.check {
            let by_runs = limit_excursions(
                &kinematic_model,
                &scene,
                &report.envelope.outputs,
                &report.envelope.times,
                &report.envelope.runs_lower,
                &report.envelope.runs_upper,
            );
            warning += &untrusted_excursions_note(check, &excursions, &by_runs);
        }
        warnings.push(warning);
    }
    if let Some(check) = &report.check {
        note_below_resolution(&report, check);
        if let Some(advice) = &advice {
            warnings.push(untrusted_warning(&report, check, advice));
        }
    } else if scans_a_surrogate {
        // Only `--check-runs 0` leaves a scanned surrogate unchecked.
        eprintln!(
            "note: the surrogate was not checked against the true model (--check-runs 0), so nothing here says whether its envelopes can be trusted; leave --check-runs at its default to check them"
        );
    }
    if let Some(lyapunov) = report.lyapunov.filter(|l| l.is_chaotic()) {
        warnings.push(format!(
            "the nominal motion is chaotic: nearby trajectories separate at about {:.2} /s (largest Lyapunov exponent), so a small difference grows {:.1e}-fold over the {:.3} s horizon and a 1 % parameter change reaches order one after about {:.2} s. Past that time the envelopes describe chaos more than your parameters, and no surrogate in the parameters can follow them; shorten --duration, or check them with --method monte-carlo",
            lyapunov.exponent_per_s,
            lyapunov.amplification,
            lyapunov.horizon_s,
            lyapunov.predictability_horizon_s(0.01),
        ));
    }
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }

    if let Some(path) = &args.summary {
        summary(&robot, &options, &space, &report, excursions, wall_seconds).write(path)?;
    }
    if let Some(path) = &args.csv {
        write_envelope_csv(path, &report)?;
    }
    let foxglove_layout = log.as_ref().map(EnvelopeLog::foxglove_layout);
    if let Some(mut log) = log.take() {
        log.metadata_mut().runs = report.runs;
        log.finish(report.partial)?;
    }
    let table_text = table(&options, &space, &report, wall_seconds);
    if let (Some(dir), Some(stems)) = (&args.report, &report_stems) {
        write_report(
            dir,
            &robot,
            &report,
            &ReportText {
                table: &table_text,
                warnings: &warnings,
            },
            stems,
            foxglove_layout,
        )?;
    }
    eprintln!(
        "{} runs, {} steps, {} Newton iterations ({:.2} per step); simulate {:.3} s, fit + bound {:.3} s ({:.1} % of the total), {} threads, {} records per block; wall {:.3} s{}",
        report.runs,
        report.steps,
        report.newton_iterations,
        report.newton_iterations as f64 / report.steps.max(1) as f64,
        report.simulate_seconds,
        report.bound_seconds,
        100.0 * report.bound_seconds / wall_seconds.max(1e-12),
        report.threads,
        report.block_records,
        wall_seconds,
        peak_memory().map_or(String::new(), |bytes| format!("; peak memory {:.1} MiB", bytes as f64 / 1048576.0)),
    );
    write_stdout(&table_text)?;
    if report.partial {
        let done = crate::text::message_time(report.envelope.times.last().copied().unwrap_or(0.0));
        return Err(Error::Interrupted(format!(
            "stopped after t = {done} s of {} s; the envelopes computed so far were written (MCAP marked partial)",
            scene.duration_s
        )));
    }
    match (&report.check, advice) {
        (Some(check), Some(advice)) => Err(untrusted(&report, check, advice)),
        _ => Ok(()),
    }
}

/// What to do about the untrusted outputs of `report` ([`untrusted_advice`]); `model` and `scene`
/// tell which of them reach an enforced joint limit, `dimensions` is the number of parameters.
fn advice(
    report: &StudyReport,
    check: &CheckReport,
    model: &crate::model::Model,
    scene: &Scene,
    dimensions: usize,
) -> String {
    let e = &report.envelope;
    let at_stops = outputs_at_enforced_limits(
        model,
        scene,
        &e.outputs,
        &check.untrusted_outputs,
        &e.lower,
        &e.upper,
    );
    let names: Vec<&str> = at_stops
        .iter()
        .map(|&o| e.outputs[o].name.as_str())
        .collect();
    untrusted_advice(
        check,
        &e.times,
        dimensions,
        report.lyapunov.as_ref(),
        &names,
    )
}

/// The exit-4 error of a study whose check did not trust some outputs.
fn untrusted(report: &StudyReport, check: &CheckReport, advice: String) -> Error {
    let outputs = &report.envelope.outputs;
    let worst = check
        .untrusted_outputs
        .iter()
        .copied()
        .max_by(|&a, &b| check.relative_misfit[a].total_cmp(&check.relative_misfit[b]))
        .map_or_else(String::new, |o| {
            format!(
                "{}, {:.1} % of its width",
                outputs[o].name,
                100.0 * check.relative_misfit[o]
            )
        });
    Error::Untrusted {
        untrusted: check.untrusted_outputs.len(),
        total: outputs.len(),
        worst,
        advice,
    }
}

/// Refuses a plan that this ribbon, with these inputs, would not make: the same method, design,
/// box, outputs, record schedule and sample points, bit for bit (a different build or edited
/// inputs would merge records of another design).
pub fn check_plan_matches(
    plan: &PlanFile,
    plan_path: &Path,
    study: &Study,
    study_plan: &StudyPlan,
) -> Result<(), Error> {
    let body = &plan.body;
    let mismatch = |what: &str| {
        Error::from(ShardError::Plan {
            path: plan_path.to_path_buf(),
            message: format!(
                "its {what} differs from what this ribbon plans from the same inputs; make the plan again with this ribbon (`ribbon plan`)"
            ),
        })
    };
    let schedule = RecordSchedule::of(study.scene);
    let names: Vec<&str> = study
        .scene
        .outputs
        .iter()
        .map(|o| o.name.as_str())
        .collect();
    let parameters: Vec<&str> = study
        .space
        .dimensions()
        .iter()
        .map(|d| d.name.as_str())
        .collect();
    if body.method != study_plan.method.name() || body.design != study_plan.design_name {
        return Err(mismatch("method or design"));
    }
    if body.outputs != names || body.parameters != parameters || body.nq != study.model.nq {
        return Err(mismatch("outputs or parameters"));
    }
    if (
        body.n_steps,
        body.record_every,
        body.step_s.to_bits(),
        body.records,
    ) != (
        schedule.n_steps,
        schedule.record_every,
        schedule.step_bits,
        schedule.len(),
    ) {
        return Err(mismatch("record schedule"));
    }
    // A staged design's first stage is checked when the study reaches it (its points are chosen
    // by the study's first phase, not by the plan).
    let points = study.design_points(study_plan);
    if points.is_none() != body.staged.is_some() {
        return Err(mismatch("design (fixed or staged)"));
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    if points.is_some_and(|points| bits(&points) != bits(&plan.points()))
        || bits(&study.space.nominal_xi()) != bits(&body.nominal_xi)
        || body.check_runs != study_plan.check_runs
    {
        return Err(mismatch("sample list"));
    }
    Ok(())
}

/// Checks and creates `--report DIR` before the study runs: every file it will hold (one plot pair
/// per output) must be a valid output, distinct from the inputs and from `--summary`, `--csv` and
/// `--out`. Returns the plot file stems, one per output.
fn prepare_report(
    args: &AnalyzeArgs,
    sidecar_path: &Path,
    scene: &Scene,
) -> Result<Option<Vec<String>>, Error> {
    let Some(dir) = &args.report else {
        return Ok(None);
    };
    let stems = crate::output::report::file_stems(scene.outputs.iter().map(|o| o.name.as_str()));
    let files = crate::output::report::report_files(&stems, args.out.is_some());
    let names: Vec<&str> = files.iter().map(String::as_str).collect();
    let inputs = [
        ("URDF", args.scene.urdf.as_path()),
        ("sidecar", sidecar_path),
    ];
    crate::output::prepare_output_directory("--report", dir, &names, &inputs)?;
    let paths: Vec<std::path::PathBuf> = files.iter().map(|f| dir.join(f)).collect();
    let mut outputs: Vec<(&str, &Path)> = paths.iter().map(|p| ("--report", p.as_path())).collect();
    for (flag, path) in [
        ("--summary", &args.summary),
        ("--csv", &args.csv),
        ("--out", &args.out),
    ] {
        if let Some(path) = path {
            outputs.push((flag, path.as_path()));
        }
    }
    crate::output::check_outputs(&inputs, &outputs)?;
    Ok(Some(stems))
}

/// Most dots of true-model runs in one report plot.
const REPORT_TRUE_RUN_DOTS: usize = 40;

/// Writes `--report DIR` (docs/mcap.md §7): the table, a band plot per output, the log's layout.
/// The text a study printed, for its report page.
struct ReportText<'a> {
    /// The stdout table.
    table: &'a str,
    /// The warnings printed on stderr (without the `warning: ` prefix).
    warnings: &'a [String],
}

fn write_report(
    dir: &Path,
    robot: &str,
    report: &StudyReport,
    text: &ReportText<'_>,
    stems: &[String],
    foxglove_layout: Option<serde_json::Value>,
) -> Result<(), Error> {
    use crate::output::report::{write_analyze_report, AnalyzeReport, ReportOutput};
    let e = &report.envelope;
    // The check's true runs at the predicted extremes, per output.
    let mut true_runs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); e.outputs.len()];
    if let Some(check) = &report.check {
        for &(output, record, truth) in &check.checked {
            if let (Some(runs), Some(&t)) = (true_runs.get_mut(output), e.times.get(record)) {
                runs.push((t, truth));
            }
        }
    }
    // A dot per record would hide a narrow band: at most REPORT_TRUE_RUN_DOTS, evenly spread in time.
    for runs in &mut true_runs {
        runs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        if runs.len() > REPORT_TRUE_RUN_DOTS {
            let n = runs.len();
            *runs = (0..REPORT_TRUE_RUN_DOTS)
                .map(|k| runs[k * (n - 1) / (REPORT_TRUE_RUN_DOTS - 1)])
                .collect();
        }
    }
    let outputs = e
        .outputs
        .iter()
        .enumerate()
        .map(|(o, output)| ReportOutput {
            name: &output.name,
            unit: output.unit,
            lower: &e.lower[o],
            upper: &e.upper[o],
            nominal: &e.nominal[o],
            outer: e
                .outer
                .as_ref()
                .map(|(lower, upper)| (lower[o].as_slice(), upper[o].as_slice())),
            true_runs: &true_runs[o],
        })
        .collect();
    write_analyze_report(
        dir,
        &AnalyzeReport {
            title: format!(
                "ribbon analyze: {robot}{}",
                if report.partial {
                    " (partial: stopped early)"
                } else {
                    ""
                }
            ),
            table: text.table,
            warnings: text.warnings,
            times: &e.times,
            outputs,
            stems,
            bound_kind: report.method.bound_kind(),
            foxglove_layout,
        },
    )?;
    eprintln!("report written to {}", dir.display());
    Ok(())
}

/// The sidecar a study reads: `--uncertainty`, or `ROBOT.uncertainty.toml` beside the URDF.
pub fn sidecar_path_of(args: &SceneArgs) -> std::path::PathBuf {
    args.request().sidecar_path()
}

/// Refuses envelopes that hold a NaN or infinity (exit 1, naming the output and time) before
/// anything is written or printed.
fn check_envelope_finite(report: &StudyReport) -> Result<(), Error> {
    let e = &report.envelope;
    let mut names = Vec::with_capacity(4 * e.outputs.len());
    let mut columns: Vec<&[f64]> = Vec::with_capacity(4 * e.outputs.len());
    for (o, output) in e.outputs.iter().enumerate() {
        names.push(format!("{}.lower", output.name));
        names.push(format!("{}.nominal", output.name));
        names.push(format!("{}.upper", output.name));
        columns.push(&e.lower[o]);
        columns.push(&e.nominal[o]);
        columns.push(&e.upper[o]);
        if let Some(errors) = &e.error {
            names.push(format!("{}.error_estimate", output.name));
            columns.push(&errors[o]);
        }
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    check_finite("analyze", &names, &e.times, &columns)
}

/// Loads the URDF and its sidecar (`uncertainty`, or `ROBOT.uncertainty.toml` beside the URDF),
/// resolves the scene and the parameter box, checks that the nominal model can start the scene
/// (exit 2 naming the joints when it cannot), and prints the warnings ([`Setup::load`]).
pub fn prepare(args: &SceneArgs) -> Result<Setup, Error> {
    Setup::load(&args.request(), &mut print_message)
}

/// The study's options from the flags and the sidecar's `[analysis]` (flags first).
pub fn study_options(
    args: &AnalyzeArgs,
    section: &crate::scene::AnalysisSection,
) -> Result<StudyOptions, Error> {
    let method_name = args
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
    let design_name = args
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
    if method == Method::Auto && (args.design.is_some() || section.design.is_some()) {
        return Err(bad(
            "--design",
            "--method auto chooses the design itself; name a method (e.g. --method legendre-scan) to choose a design".to_string(),
        ));
    }
    let max_runs = max_runs_of(args.max_runs)?;
    let threads = check_threads("--threads", args.threads.unwrap_or(0))?;
    Ok(StudyOptions {
        method,
        order: args.order.or(section.order).unwrap_or(DEFAULT_ORDER),
        truncation,
        grid: args.grid.unwrap_or(DEFAULT_GRID),
        scan_grid: args.scan_grid,
        samples: args.samples.unwrap_or(DEFAULT_SAMPLES),
        seed: args.seed.unwrap_or(0),
        threads,
        keep_going: args.keep_going,
        check_runs: args.check_runs,
        design,
        max_runs,
    })
}

/// `--max-runs` (default [`DEFAULT_MAX_RUNS`]), refused below 2: a design and its nominal run.
pub fn max_runs_of(flag: Option<usize>) -> Result<usize, Error> {
    let max_runs = flag.unwrap_or(DEFAULT_MAX_RUNS);
    if max_runs < 2 {
        return Err(bad(
            "--max-runs",
            format!("{max_runs} runs cannot hold a design and its nominal run; give at least 2"),
        ));
    }
    Ok(max_runs)
}

/// The designs `--design` accepts.
pub const DESIGN_NAMES: &str = "tensor, total, sparse, regression, adaptive or screened";

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

fn order_of(method: Method, options: &StudyOptions) -> Option<usize> {
    match method {
        Method::Scan | Method::MonteCarlo => None,
        Method::Taylor => Some(1),
        _ => Some(options.order),
    }
}

fn parameter_summaries(space: &ParameterSpace) -> Vec<ParameterSummary> {
    space
        .dimensions()
        .iter()
        .map(|d| ParameterSummary {
            name: d.name.clone(),
            lower: d.lower,
            upper: d.upper,
            nominal: d.nominal,
            source: d.source.clone(),
            unit: d.unit.to_string(),
        })
        .collect()
}

fn summary(
    robot: &str,
    options: &StudyOptions,
    space: &ParameterSpace,
    report: &StudyReport,
    limit_excursions: Vec<LimitExcursion>,
    wall_seconds: f64,
) -> Summary {
    let e = &report.envelope;
    let mut summary = Summary {
        robot: robot.to_string(),
        method: report.method.name().to_string(),
        order: order_of(report.method, options),
        design: Some(report.design.to_string()),
        bound_kind: report.method.bound_kind().to_string(),
        sensitivities: sensitivities(space, report),
        parameters: parameter_summaries(space),
        samples: report.runs,
        excluded_samples: report
            .excluded
            .iter()
            .map(|f| serde_json::json!({"index": f.index, "xi": f.xi, "values": f.values, "time": f.time_s, "error": f.message}))
            .collect(),
        wall_seconds,
        outputs: e
            .outputs
            .iter()
            .enumerate()
            .map(|(o, output)| EnvelopeSeries {
                name: output.name.clone(),
                unit: output.unit.to_string(),
                time: e.times.clone(),
                lower: e.lower[o].clone(),
                upper: e.upper[o].clone(),
                nominal: e.nominal[o].clone(),
                error_estimate: e.error.as_ref().map(|errors| errors[o].clone()),
                outer_lower: e.outer.as_ref().map(|(lower, _)| lower[o].clone()),
                outer_upper: e.outer.as_ref().map(|(_, upper)| upper[o].clone()),
                runs_lower: runs_hull_series(&e.runs_lower, o),
                runs_upper: runs_hull_series(&e.runs_upper, o),
            })
            .collect(),
        stats: serde_json::json!({
            "partial": report.partial,
            "steps": report.steps,
            "newton_iterations": report.newton_iterations,
            "simulate_seconds": report.simulate_seconds,
            "bound_seconds": report.bound_seconds,
            "threads": report.threads,
            "block_records": report.block_records,
            "peak_memory_bytes": peak_memory(),
            "check": report.check.as_ref().map(|c| check_json(report, c, space.len())),
            "auto": report.auto.as_ref().map(|a| serde_json::json!({
                "requested": "auto",
                "design": report.design,
                "reason": a.reason,
                "screening_runs": a.screening_runs,
                "design_runs": a.design_runs,
            })),
            "adaptive": report.adaptive.as_ref().map(|a| serde_json::json!({
                "rounds": a.rounds,
                "runs": a.runs,
                "budget": a.budget,
                "max_degree": a.max_degree,
                "interactions": a.interactions,
                "largest_remaining_indicator": a.largest_remaining_indicator,
                "tolerance": ADAPTIVE_TOLERANCE,
                "stop": a.stop,
            })),
            "condition_number": report.condition_number,
            "inner_outer_gap": gap_json(report),
            "lyapunov": report.lyapunov.map(|l| serde_json::json!({
                "exponent_per_s": l.exponent_per_s,
                "amplification": l.amplification,
                "horizon_s": l.horizon_s,
                "chaotic": l.is_chaotic(),
                "chaos_amplification": CHAOS_AMPLIFICATION,
            })),
        }),
        sobol_indices: report
            .sobol
            .as_ref()
            .map(|series| SobolSummary::from_study(series, e, space)),
        limit_excursions,
    };
    // Only when the scene declares contacts: a summary without them keeps its keys.
    if let (Some(contacts), Some(stats)) = (&report.contacts, summary.stats.as_object_mut()) {
        stats.insert("contacts".to_string(), serde_json::json!(contacts));
    }
    summary
}

/// Per dimension, how much it moves the outputs, from what the study measured (issue 11 §2):
/// - `relative_slope`: the screening's largest secant slope `|y(e_j) − y(−e_j)|/2` (∂y/∂ξ across the
///   half-width) over outputs and times, relative to the output's largest envelope width;
/// - `importance`: the screening's share of an output's one-at-a-time spread;
/// - `total_index`: the largest total Sobol' index of the sparse surrogates, with where.
///
/// Sorted by the screening's rank where there was one, else by total index; `None` when the study
/// measured neither (tensor designs).
fn sensitivities(space: &ParameterSpace, report: &StudyReport) -> Option<Vec<SensitivitySummary>> {
    if report.screening.is_none() && report.total_index_max.is_none() {
        return None;
    }
    let e = &report.envelope;
    let widths: Vec<f64> = (0..e.outputs.len())
        .map(|o| {
            e.upper[o]
                .iter()
                .zip(&e.lower[o])
                .map(|(u, l)| u - l)
                .fold(0.0, f64::max)
        })
        .collect();
    let mut rows: Vec<SensitivitySummary> = space
        .dimensions()
        .iter()
        .enumerate()
        .map(|(j, dimension)| {
            let screened = report.screening.as_ref().map(|s| {
                let verdict = &s.dimensions()[j];
                let (slope, output) = (0..widths.len())
                    .filter(|&o| widths[o] > 0.0)
                    .map(|o| (s.max_slope(j, o) / widths[o], o))
                    .fold((0.0, 0), |best, x| if x.0 > best.0 { x } else { best });
                (slope, output, verdict.importance)
            });
            let total = report.total_index_max.as_ref().map(|t| t[j]);
            SensitivitySummary {
                name: dimension.name.clone(),
                rank: 0,
                relative_slope: screened.map(|s| s.0),
                slope_output: screened.map(|s| e.outputs[s.1].name.clone()),
                importance: screened.map(|s| s.2),
                total_index: total.map(|t| t.0),
                total_index_output: total.map(|t| e.outputs[t.1].name.clone()),
                total_index_time: total.and_then(|t| e.times.get(t.2).copied()),
            }
        })
        .collect();
    let mut order: Vec<usize> = match &report.ranking {
        Some(ranking) => ranking.clone(),
        None => (0..rows.len()).collect(),
    };
    if report.ranking.is_none() {
        order.sort_by(|&a, &b| {
            rows[b]
                .total_index
                .unwrap_or(0.0)
                .total_cmp(&rows[a].total_index.unwrap_or(0.0))
                .then(a.cmp(&b))
        });
    }
    for (rank, &j) in order.iter().enumerate() {
        rows[j].rank = rank + 1;
    }
    rows.sort_by_key(|r| r.rank);
    Some(rows)
}

/// Per output, the largest gap between the sparse surrogate's outer and inner bounds relative to
/// the envelope's width (what the inner search might have missed on the surrogate).
fn gap_json(report: &StudyReport) -> Option<serde_json::Value> {
    let e = &report.envelope;
    let (outer_lower, outer_upper) = e.outer.as_ref()?;
    let rows: Vec<serde_json::Value> = e
        .outputs
        .iter()
        .enumerate()
        .map(|(o, output)| {
            let width = e.upper[o]
                .iter()
                .zip(&e.lower[o])
                .map(|(u, l)| u - l)
                .fold(0.0, f64::max);
            let gap = (0..e.times.len())
                .map(|k| (e.lower[o][k] - outer_lower[o][k]).max(outer_upper[o][k] - e.upper[o][k]))
                .fold(0.0, f64::max);
            serde_json::json!({
                "name": output.name,
                "max_gap": gap,
                "relative_gap": if width > 0.0 { gap / width } else { 0.0 },
            })
        })
        .collect();
    Some(serde_json::Value::Array(rows))
}

/// The check's statistics for the summary: runs, candidates, and per output its misfit.
fn check_json(report: &StudyReport, check: &CheckReport, dim: usize) -> serde_json::Value {
    let outputs = &report.envelope.outputs;
    let e_times = &report.envelope.times;
    serde_json::json!({
        "runs": check.runs,
        "unique_candidates": check.unique_candidates,
        "complete": check.complete,
        "trusted": check.untrusted_outputs.is_empty(),
        "first_miss_time_s": check.first_miss_record.map(|r| e_times[r]),
        "checks_before_first_miss": check.checks_before_first_miss,
        "passes_until_time_s": check.passes_until_record.map(|r| e_times[r]),
        "untrusted_outputs": check.untrusted_outputs.iter().map(|&o| outputs[o].name.clone()).collect::<Vec<_>>(),
        "trust_relative_misfit": TRUST_RELATIVE_MISFIT,
        "trust_resolution_factor": TRUST_RESOLUTION_FACTOR,
        "below_resolution_outputs": check.below_resolution_outputs.iter().map(|&o| outputs[o].name.clone()).collect::<Vec<_>>(),
        "points_xi": check.points.chunks(dim.max(1)).collect::<Vec<_>>(),
        "outputs": outputs.iter().enumerate().map(|(o, output)| serde_json::json!({
            "name": output.name,
            "max_misfit": check.max_misfit[o],
            "relative_misfit": check.relative_misfit[o],
            "resolution": check.resolution[o],
        })).collect::<Vec<_>>(),
    })
}

/// Notes the outputs whose misfit, large against their width, is within the integrator's
/// resolution: numerical noise, not a failed surrogate.
fn note_below_resolution(report: &StudyReport, check: &CheckReport) {
    let outputs = &report.envelope.outputs;
    if check.below_resolution_outputs.is_empty() {
        return;
    }
    let listed: Vec<String> = check
        .below_resolution_outputs
        .iter()
        .take(5)
        .map(|&o| {
            format!(
                "{} ({:.1e} {unit} ≤ {:.1e} {unit})",
                outputs[o].name,
                check.max_misfit[o],
                check.resolution[o].unwrap_or(f64::NAN),
                unit = outputs[o].unit
            )
        })
        .collect();
    eprintln!(
        "note: {} output(s) miss by more than {:.0} % of their envelope width but by less than the integrator's resolution, so their envelopes are numerical noise, not a failed surrogate (docs/method.md §7): {}{}",
        check.below_resolution_outputs.len(),
        100.0 * TRUST_RELATIVE_MISFIT,
        listed.join(", "),
        if check.below_resolution_outputs.len() > 5 { ", …" } else { "" },
    );
}

/// The warning naming the outputs whose surrogates missed the true model at their predicted
/// extremes (some did), with what to do ([`advice`]).
fn untrusted_warning(report: &StudyReport, check: &CheckReport, advice: &str) -> String {
    let outputs = &report.envelope.outputs;
    let mut worst: Vec<usize> = check.untrusted_outputs.clone();
    worst.sort_by(|&a, &b| check.relative_misfit[b].total_cmp(&check.relative_misfit[a]));
    let listed: Vec<String> = worst
        .iter()
        .take(5)
        .map(|&o| {
            format!(
                "{} ({:.1} %)",
                outputs[o].name,
                100.0 * check.relative_misfit[o]
            )
        })
        .collect();
    let spread = worst
        .first()
        .and_then(|&o| runs_spread_where_widest(&report.envelope, o))
        .unwrap_or_default();
    format!(
        "the surrogate cannot be trusted for {} of {} outputs: true-model runs at its predicted extremes differ from it by more than {:.0} % of the envelope width: {}{}. The envelopes were widened to contain every true run, but they may still be too narrow{}; {}",
        worst.len(),
        outputs.len(),
        100.0 * TRUST_RELATIVE_MISFIT,
        listed.join(", "),
        if worst.len() > 5 { ", …" } else { "" },
        spread,
        advice,
    )
}

/// For the limit-excursion warning: which of `excursions` (found on the envelopes) are envelope
/// bounds of outputs whose surrogate the check does not trust, and how far the study's true runs
/// went there (`by_runs`: the excursions found on the hull of true runs); empty when none is.
fn untrusted_excursions_note(
    check: &CheckReport,
    excursions: &[LimitExcursion],
    by_runs: &[LimitExcursion],
) -> String {
    let untrusted: Vec<&LimitExcursion> = excursions
        .iter()
        .filter(|excursion| check.untrusted_outputs.contains(&excursion.output))
        .collect();
    if untrusted.is_empty() {
        return String::new();
    }
    let described: Vec<String> = untrusted
        .iter()
        .take(5)
        .map(
            |excursion| match by_runs.iter().find(|r| r.joint == excursion.joint) {
                Some(run) => format!(
                    "'{}' to {:.4} {} at t = {} s",
                    run.joint,
                    run.reached,
                    run.unit,
                    crate::text::message_time(run.time_s)
                ),
                None => format!("'{}' stayed within its limits", excursion.joint),
            },
        )
        .collect();
    format!(
        ". Of these, {} are bounds of surrogates the check does not trust (below); the study's true runs went: {}{}",
        untrusted.len(),
        described.join("; "),
        if untrusted.len() > 5 { "; …" } else { "" },
    )
}

/// Where output `o`'s envelope is widest, how much of it the study's true runs reached (`". Where
/// the envelope of q.x is widest (t = …, [l, u]), the study's true runs span [a, b], N % of it"`);
/// `None` without a positive width or without runs there. A small share means the surrogate
/// swings far past anything a true run did between its samples (the envelope is loose there, not
/// established); a share near 100 %, that the runs themselves reach its edges.
fn runs_spread_where_widest(envelope: &crate::analysis::Envelope, o: usize) -> Option<String> {
    let k = crate::analysis::widest_record(envelope, o)?;
    let width = envelope.upper[o][k] - envelope.lower[o][k];
    let (lowest, highest) = (
        *envelope.runs_lower.get(o)?.get(k)?,
        *envelope.runs_upper.get(o)?.get(k)?,
    );
    // Neither a zero or NaN width nor an empty hull (no run at that record) makes a share.
    let measurable = width > 0.0 && highest >= lowest;
    if !measurable {
        return None;
    }
    let output = &envelope.outputs[o];
    Some(format!(
        ". Where the envelope of {1} is widest (t = {0} s, [{2:.4e}, {3:.4e}] {unit}), the study's true runs span [{4:.4e}, {5:.4e}] {unit}, {6:.1} % of it",
        crate::text::message_time(envelope.times[k]),
        output.name,
        envelope.lower[o][k],
        envelope.upper[o][k],
        lowest,
        highest,
        100.0 * (highest - lowest) / width,
        unit = output.unit,
    ))
}

/// Output `o`'s series of the hull of true runs for the summary, when every record has one (every
/// record of a study has at least the nominal run; a record without any would hold ±∞, which JSON
/// cannot carry, so the series is then left out rather than the summary refused).
fn runs_hull_series(series: &[Vec<f64>], o: usize) -> Option<Vec<f64>> {
    series
        .get(o)
        .filter(|values| values.iter().all(|x| x.is_finite()))
        .cloned()
}

fn write_envelope_csv(path: &Path, report: &StudyReport) -> Result<(), Error> {
    let e = &report.envelope;
    let mut names = Vec::with_capacity(3 * e.outputs.len());
    let mut columns: Vec<&[f64]> = Vec::with_capacity(3 * e.outputs.len());
    for (o, output) in e.outputs.iter().enumerate() {
        names.push(format!("{}.lower", output.name));
        names.push(format!("{}.nominal", output.name));
        names.push(format!("{}.upper", output.name));
        columns.push(&e.lower[o]);
        columns.push(&e.nominal[o]);
        columns.push(&e.upper[o]);
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    Ok(write_csv(path, &e.times, &names, &columns)?)
}

fn table(
    options: &StudyOptions,
    space: &ParameterSpace,
    report: &StudyReport,
    wall_seconds: f64,
) -> String {
    let e = &report.envelope;
    let width = crate::text::name_column_width(e.outputs.iter().map(|o| o.name.as_str()));
    let mut text = format!(
        "{:<width$}  {:>8}  {:>13}  {:>9}  {:>13}  {:>13}\n",
        "output", "unit", "max width", "at t (s)", "lower there", "upper there"
    );
    for (o, output) in e.outputs.iter().enumerate() {
        let (k, w) = e.lower[o]
            .iter()
            .zip(&e.upper[o])
            .map(|(l, u)| u - l)
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |best, (k, w)| {
                if w > best.1 {
                    (k, w)
                } else {
                    best
                }
            });
        text.push_str(&format!(
            "{:<width$}  {:>8}  {:>13.6e}  {:>9.3}  {:>13.6e}  {:>13.6e}\n",
            output.name,
            output.unit,
            w,
            e.times.get(k).copied().unwrap_or(f64::NAN),
            e.lower[o].get(k).copied().unwrap_or(f64::NAN),
            e.upper[o].get(k).copied().unwrap_or(f64::NAN),
        ));
    }
    text.push_str(&format!(
        "method {} ({} bounds{}, design {}), {} model runs{}, {:.3} s wall{}\n",
        report.method.name(),
        report.method.bound_kind(),
        order_of(report.method, options).map_or(String::new(), |k| format!(", order {k}")),
        report.design,
        report.runs,
        report.check.as_ref().map_or(String::new(), |c| {
            // Outputs within the integrator's resolution are noise, not the surrogate's misfit.
            let worst = c
                .relative_misfit
                .iter()
                .enumerate()
                .filter(|(o, _)| !c.below_resolution_outputs.contains(o))
                .map(|(_, &m)| m)
                .fold(0.0, f64::max);
            format!(
                " ({} of them checking the surrogate's extremes: largest misfit {:.2e} of the width{}{})",
                c.runs,
                worst,
                if c.below_resolution_outputs.is_empty() {
                    String::new()
                } else {
                    format!(
                        " outside {} output(s) within the integrator's resolution",
                        c.below_resolution_outputs.len()
                    )
                },
                if c.untrusted_outputs.is_empty() { "" } else { ", NOT TRUSTED" }
            )
        }),
        wall_seconds,
        if report.excluded.is_empty() {
            String::new()
        } else {
            format!(", {} samples excluded", report.excluded.len())
        }
    ));
    if let Some(a) = &report.adaptive {
        text.push_str(&format!(
            "adaptive design: {} runs in {} rounds ({}), {} interaction terms, degree up to {}, largest term left {:.1e} of an output's spread\n",
            a.runs,
            a.rounds,
            match a.stop {
                "converged" => format!("converged below {ADAPTIVE_TOLERANCE:e}"),
                "budget" => format!("stopped by the budget of {} runs", a.budget),
                other => other.to_string(),
            },
            a.interactions,
            a.max_degree,
            a.largest_remaining_indicator
        ));
    }
    if let Some(series) = &report.sobol {
        let names: Vec<String> = space.dimensions().iter().map(|d| d.name.clone()).collect();
        text.push_str(&series.table(e, &names, TABLE_SOBOL_CONTRIBUTORS));
    }
    if let Some(rows) = sensitivities(space, report) {
        text.push_str(&format!(
            "most influential parameters (of {}):\n",
            rows.len()
        ));
        for row in rows.iter().take(TABLE_SENSITIVITIES) {
            let mut parts = Vec::new();
            if let (Some(slope), Some(output)) = (row.relative_slope, &row.slope_output) {
                parts.push(format!(
                    "slope × half-width {:.1} % of the width of {output}",
                    100.0 * slope
                ));
            }
            if let (Some(index), Some(output)) = (row.total_index, &row.total_index_output) {
                parts.push(format!("total Sobol' index {index:.3} on {output}"));
            }
            text.push_str(&format!(
                "  {:>3}. {}: {}\n",
                row.rank,
                row.name,
                parts.join("; ")
            ));
        }
    }
    text
}

/// Parameters listed in the stdout table's ranking.
const TABLE_SENSITIVITIES: usize = 5;

/// Peak resident memory of this process (Linux `VmHWM`), bytes.
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Progress on stderr: a rewritten line on a terminal, otherwise a line at most every
/// [`PROGRESS_INTERVAL_S`] (and always the first).
pub(super) struct ProgressReporter {
    terminal: bool,
    last_line_s: Option<f64>,
}

impl ProgressReporter {
    /// A reporter for stderr.
    pub(super) fn new() -> Self {
        Self {
            terminal: std::io::stderr().is_terminal(),
            last_line_s: None,
        }
    }

    /// Reports one block's progress.
    pub(super) fn report(&mut self, p: Progress) {
        let fraction = p.records_done as f64 / p.records_total.max(1) as f64;
        let eta = if fraction > 0.0 {
            p.elapsed_s * (1.0 - fraction) / fraction
        } else {
            f64::NAN
        };
        let line = format!(
            "progress: {} {}/{} record times ({:.0} %) of {} runs, {:.1} s elapsed, ETA {:.1} s",
            p.phase,
            p.records_done,
            p.records_total,
            100.0 * fraction,
            p.runs,
            p.elapsed_s,
            eta
        );
        if self.terminal {
            eprint!("\r{line}   ");
        } else if self
            .last_line_s
            .is_none_or(|last| p.elapsed_s - last >= PROGRESS_INTERVAL_S)
        {
            eprintln!("{line}");
            self.last_line_s = Some(p.elapsed_s);
        }
    }

    /// Ends the line on a terminal.
    pub(super) fn finish(&self) {
        if self.terminal {
            eprintln!();
        }
    }
}
