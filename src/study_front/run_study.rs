//! The one driver of `analyze` and `merge`: a [`StudyRequest`] from its outputs checked to its
//! results written, the same stages and sinks whether the design's records are simulated here
//! (`analyze`) or read from the shards' record blocks (`merge`).
//!
//! ```text
//! check the outputs ⇒ load (Setup) ⇒ options ⇒ --report DIR checked ⇒ memory check ⇒ plan
//!   ⇒ "analyze: …" on stderr ⇒ MCAP log opened ⇒ the study's phases (progress on stderr; the
//!     finished envelopes into the log, block by block) ⇒ no NaN or infinity ⇒ warnings
//!   ⇒ summary, CSV, log closed, report page ⇒ statistics on stderr ⇒ the table on stdout
//!   ⇒ exit: 1 when interrupted, 4 when the check did not trust a surrogate
//! ```
//!
//! Does not: parse command lines (`cli/`), run phases (`analysis/`), or format files (`output/`).

use super::install_interrupt;
use super::options::{order_of, study_options, SceneInputs, StudyRequest};
use super::plan_match::check_plan_matches;
use super::progress::ProgressReporter;
use super::report_page::{prepare_report, write_report, ReportText};
use super::study_log::{close_log, LogHeader};
use super::table::table;
use super::warnings::{untrusted, warn, StudyWarnings};
use crate::analysis::{
    sobol_values_per_record, Envelope, ForeignError, Method, SimulateHere, StageRecords, Study,
    StudyOptions, StudyPlan, StudyReport, BLOCK_VALUE_BUDGET,
};
use crate::distributed::{PlanFile, ShardStages};
use crate::dynamics::Data;
use crate::output::{
    check_command_outputs, check_finite, peak_memory, write_csv, write_stdout, Summary,
};
use crate::scene::Scene;
use crate::setup::{print_message, Setup};
use crate::uncertainty::ParameterSpace;
use crate::Error;
use std::path::Path;
use std::time::Instant;

/// The design's records of a merge: the plan and the directory of its shards' record blocks.
pub struct MergeInput<'a> {
    /// The plan file.
    pub plan: &'a PlanFile,
    /// Its path.
    pub plan_path: &'a Path,
    /// The directory holding the record blocks.
    pub dir: &'a Path,
}

/// Loads the URDF and its sidecar (`uncertainty`, or `ROBOT.uncertainty.toml` beside the URDF),
/// resolves the scene and the parameter box, checks that the nominal model can start the scene
/// (exit 2 naming the joints when it cannot), and prints the warnings ([`Setup::load`]).
pub fn prepare(scene: &SceneInputs) -> Result<Setup, Error> {
    Setup::load(&scene.request(), &mut print_message)
}

/// `analyze` (`merge` is `None`: the design is simulated here) or `merge` (the design's records are
/// read from the shards): the same stages and sinks either way (module documentation).
pub fn run_study(request: &StudyRequest, merge: Option<MergeInput>) -> Result<(), Error> {
    let started = Instant::now();
    let outputs = &request.outputs;
    check_command_outputs(
        &request.scene.urdf,
        Some(&request.scene.sidecar_path()),
        &outputs.files(),
    )?;
    install_interrupt();
    let Setup {
        sidecar_path,
        sidecar,
        model,
        environment,
        scene,
        space,
    } = prepare(&request.scene)?;
    let options = study_options(&request.flags, &sidecar.analysis)?;
    let report_stems = prepare_report(&request.scene.urdf, outputs, &sidecar_path, &scene)?;
    // The summary is built with --summary or --report (the report's browser page reads it).
    check_study_memory(
        &scene,
        &options,
        &space,
        outputs.summary.is_some() || outputs.report.is_some(),
    )?;
    let robot = model.name().to_string();
    let study = Study::new(&model, &environment, &scene, &space, options.clone());
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
    announce(&plan, &options, &space, &scene);

    let interrupt = crate::interrupt::flag();
    let header = LogHeader::of_plan(&robot, &plan, &options, &space);
    let mut log = match &outputs.out {
        Some(path) => {
            Some(header.open(path, &request.scene.urdf, &sidecar_path, &scene.outputs)?)
        }
        None => None,
    };
    let kinematic_model = model;
    let mut data = Data::new(&kinematic_model);
    let mut reporter = ProgressReporter::new();
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
    check_envelope_finite(&report.envelope)?;
    let StudyWarnings {
        warnings,
        excursions,
        advice,
    } = warn(&report, &kinematic_model, &scene, &space);

    // The summary JSON's contents, also the numbers of the report's browser page.
    let summary = (outputs.summary.is_some() || outputs.report.is_some()).then(|| {
        let order = order_of(report.method, &options);
        let t_summary = Instant::now();
        let mut summary =
            Summary::of_study(&robot, order, &space, &report, excursions, wall_seconds);
        summary.set_summary_seconds(t_summary.elapsed().as_secs_f64());
        summary
    });
    if let (Some(path), Some(summary)) = (&outputs.summary, &summary) {
        summary.write(path)?;
    }
    if let Some(path) = &outputs.csv {
        write_envelope_csv(path, &report)?;
    }
    let foxglove_layout = match log.take() {
        Some(log) => Some(close_log(log, &report, &space)?),
        None => None,
    };
    let table_text = table(&options, &space, &report, wall_seconds);
    if let (Some(dir), Some(stems), Some(summary)) = (&outputs.report, &report_stems, &summary) {
        write_report(
            dir,
            &robot,
            &report,
            &ReportText {
                table: &table_text,
                warnings: &warnings,
                summary,
                log: outputs.out.as_deref(),
            },
            stems,
            foxglove_layout,
        )?;
    }
    print_statistics(&report, wall_seconds);
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

/// The study's plan on stderr: parameters, method, design, runs and horizon; what `auto` chose.
fn announce(plan: &StudyPlan, options: &StudyOptions, space: &ParameterSpace, scene: &Scene) {
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
}

/// The study's runs, steps, timings, threads, block size and peak memory on stderr. Fit + bound
/// is wall time, part of which may have run beside the simulation (said when it did); the share
/// of the threads' time its workers took (`stats.phase_seconds` design choice, fit, inner and
/// outer bound, Sobol' indices, in thread-seconds, over threads × wall) stays meaningful either
/// way.
fn print_statistics(report: &StudyReport, wall_seconds: f64) {
    let wall = wall_seconds.max(1e-12);
    let phases = &report.phase_seconds;
    let worker_seconds = phases.design_choice
        + phases.fit
        + phases.inner_bound
        + phases.outer_bound
        + phases.sobol_indices;
    let beside = if report.beside_simulation_seconds > 0.0 {
        format!(
            ", {:.3} s of it beside the simulation",
            report.beside_simulation_seconds
        )
    } else {
        String::new()
    };
    eprintln!(
        "{} runs, {} steps, {} Newton iterations ({:.2} per step); simulate {:.3} s, fit + bound {:.3} s ({:.1} % of the wall{beside}; its workers {:.3} thread-s, {:.1} % of the threads' time), {} threads, {} records per block; wall {:.3} s{}",
        report.runs,
        report.steps,
        report.newton_iterations,
        report.newton_iterations as f64 / report.steps.max(1) as f64,
        report.simulate_seconds,
        report.bound_seconds,
        100.0 * report.bound_seconds / wall,
        worker_seconds,
        100.0 * worker_seconds / (wall * report.threads.max(1) as f64),
        report.threads,
        report.block_records,
        wall_seconds,
        peak_memory().map_or(String::new(), |bytes| format!("; peak memory {:.1} MiB", bytes as f64 / 1048576.0)),
    );
}

/// The envelope's series as `NAME.lower`, `NAME.nominal`, `NAME.upper` per output and, with
/// `with_error`, `NAME.error_estimate` where the envelope has one.
fn envelope_columns(e: &Envelope, with_error: bool) -> (Vec<String>, Vec<&[f64]>) {
    let mut names = Vec::with_capacity(4 * e.outputs.len());
    let mut columns: Vec<&[f64]> = Vec::with_capacity(4 * e.outputs.len());
    for (o, output) in e.outputs.iter().enumerate() {
        names.push(format!("{}.lower", output.name));
        names.push(format!("{}.nominal", output.name));
        names.push(format!("{}.upper", output.name));
        columns.push(&e.lower[o]);
        columns.push(&e.nominal[o]);
        columns.push(&e.upper[o]);
        if let (true, Some(errors)) = (with_error, &e.error) {
            names.push(format!("{}.error_estimate", output.name));
            columns.push(&errors[o]);
        }
    }
    (names, columns)
}

/// Refuses a study whose memory would pass the budget (exit 2, before anything runs). Kept per
/// record time: the envelope (time; lower, upper, nominal and an error estimate per output) and,
/// `with_summary`, its five copies per output; plus one block of samples. Surrogate studies also
/// keep their Sobol' indices (and, with a summary, a copy).
pub fn check_study_memory(
    scene: &Scene,
    options: &StudyOptions,
    space: &ParameterSpace,
    with_summary: bool,
) -> Result<(), Error> {
    let sobol = sobol_values_per_record(options.method, space.len());
    let per_output = 4 + sobol + if with_summary { 5 + sobol } else { 0 };
    scene.check_memory(
        "analyze",
        (1 + scene.outputs.len() * per_output) as u64,
        (BLOCK_VALUE_BUDGET * 8) as u64,
    )?;
    Ok(())
}

/// Refuses envelopes that hold a NaN or infinity (exit 1, naming the output and time) before
/// anything is written or printed.
pub fn check_envelope_finite(envelope: &Envelope) -> Result<(), Error> {
    let (names, columns) = envelope_columns(envelope, true);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    Ok(check_finite("analyze", &names, &envelope.times, &columns)?)
}

/// `--csv`: `t`, then `NAME.lower`, `NAME.nominal`, `NAME.upper` per output; then, when the
/// check did not trust the study ([`StudyReport::shows_runs_hull`]), `NAME.runs_lower`,
/// `NAME.runs_upper` per output — at the end, so that every column a trusted study's CSV has
/// keeps its place (a script that reads columns by position reads the same ones).
pub fn write_envelope_csv(path: &Path, report: &StudyReport) -> Result<(), Error> {
    let envelope = &report.envelope;
    let (mut names, mut columns) = envelope_columns(envelope, false);
    if report.shows_runs_hull() {
        for (o, output) in envelope.outputs.iter().enumerate() {
            names.push(format!("{}.runs_lower", output.name));
            names.push(format!("{}.runs_upper", output.name));
            columns.push(&envelope.runs_lower[o]);
            columns.push(&envelope.runs_upper[o]);
        }
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    Ok(write_csv(path, &envelope.times, &names, &columns)?)
}
