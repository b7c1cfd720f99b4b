//! `ribbon simulate ROBOT.urdf [--uncertainty F] [--set …] [--duration T] [--step H] [--alpha A]
//! [--csv F] [--summary F] [--out F.mcap]`: one nominal trajectory. Statistics go to stderr, a table
//! to stdout. Outputs are checked before anything runs; SIGINT/SIGTERM stop the run after the
//! current step, write what was computed (marked partial) and exit 1; a second signal stops at
//! once, removing the temporary files.

use super::{install_interrupt, write_stdout, SimulateArgs};
use crate::dynamics::{forward_kinematics, Data};
use crate::model::Model;
use crate::nominal_run::{NominalCopies, NominalRun};
use crate::output::mcap::McapMetadata;
use crate::output::{write_csv, EnvelopeLog, EnvelopeSeries, Summary};
use crate::scene::{describe_limit_excursions, LimitExcursion, Scene};
use crate::setup::print_message;
use crate::simulate::Trajectory;
use crate::Error;
use std::time::Instant;

/// Runs `ribbon simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), Error> {
    let started = Instant::now();
    let sidecar_path = args
        .scene
        .uncertainty
        .clone()
        .or_else(|| Some(args.scene.request().sidecar_path()).filter(|p| p.exists()));
    crate::output::check_command_outputs(
        &args.scene.urdf,
        sidecar_path.as_deref(),
        &[
            ("--csv", args.csv.as_deref()),
            ("--summary", args.summary.as_deref()),
            ("--out", args.out.as_deref()),
        ],
    )?;
    install_interrupt();
    let copies = if args.summary.is_some() {
        NominalCopies::WithSummary
    } else {
        NominalCopies::TrajectoryOnly
    };
    let run = NominalRun::run(
        &args.scene.request(),
        &args.set,
        copies,
        crate::interrupt::flag(),
        &mut print_message,
    )?;
    let wall_seconds = started.elapsed().as_secs_f64();
    print_statistics(&run.trajectory, &run.scene, wall_seconds);
    run.check_finite()?;
    let excursions = run.limit_excursions();
    let NominalRun {
        model: kinematic_model,
        scene,
        environment: _,
        sidecar_path,
        trajectory,
    } = run;
    let robot = kinematic_model.name().to_string();
    let names: Vec<&str> = trajectory.outputs.iter().map(|o| o.name.as_str()).collect();
    let columns: Vec<&[f64]> = trajectory.values.iter().map(Vec::as_slice).collect();
    if !excursions.is_empty() {
        eprintln!("warning: {}", describe_limit_excursions(&excursions, false));
    }
    if let Some(path) = &args.csv {
        write_csv(path, &trajectory.times, &names, &columns)?;
    }
    if let Some(path) = &args.summary {
        summary(&robot, &trajectory, excursions, wall_seconds).write(path)?;
    }
    if let Some(path) = &args.out {
        write_log(
            path,
            args,
            sidecar_path.as_deref(),
            &robot,
            &kinematic_model,
            &trajectory,
        )?;
    }
    write_stdout(&table(&trajectory))?;
    if trajectory.partial {
        return Err(Error::Interrupted(format!(
            "stopped after t = {} s of {} s; the series computed so far were written (summary stats.partial = true, MCAP marked partial)",
            crate::text::message_time(trajectory.times.last().copied().unwrap_or(0.0)),
            scene.duration_s
        )));
    }
    Ok(())
}

/// The MCAP log of a nominal run: lower = nominal = upper, frames on `/tf` at every record time.
fn write_log(
    path: &std::path::Path,
    args: &SimulateArgs,
    sidecar: Option<&std::path::Path>,
    robot: &str,
    model: &Model,
    trajectory: &Trajectory,
) -> Result<(), Error> {
    let metadata = McapMetadata {
        robot: robot.to_string(),
        method: "nominal".to_string(),
        order: None,
        runs: 1,
        parameters_json: "[]".to_string(),
    };
    let mut log = EnvelopeLog::create(
        path,
        &args.scene.urdf,
        sidecar,
        metadata,
        &trajectory.outputs,
        false,
    )?;
    let mut data = Data::new(model);
    let mut row = vec![0.0; trajectory.outputs.len()];
    for (k, t) in trajectory.times.iter().enumerate() {
        for (value, series) in row.iter_mut().zip(&trajectory.values) {
            *value = series[k];
        }
        log.write_time(*t, &row, &row, &row, None)?;
        forward_kinematics(model, &mut data, &trajectory.positions[k]);
        log.write_frames(*t, model, &data)?;
    }
    Ok(log.finish(trajectory.partial)?)
}

fn print_statistics(trajectory: &Trajectory, scene: &Scene, wall_seconds: f64) {
    let s = &trajectory.stats;
    eprintln!(
        "simulated {} s{} in {} steps of {} s (alpha {}): {} Newton iterations ({:.2} per step, at most {}), {} factorisations, {} refreshes; {:.3} s wall",
        trajectory.times.last().copied().unwrap_or(0.0),
        if trajectory.partial {
            format!(" of {} s (interrupted)", scene.duration_s)
        } else {
            String::new()
        },
        s.steps,
        scene.step_s,
        scene.alpha,
        s.newton_iterations,
        s.newton_iterations as f64 / (s.steps.max(1)) as f64,
        s.max_iterations_in_a_step,
        s.factorisations,
        s.refreshes,
        wall_seconds
    );
    if s.substeps > s.steps || s.impacts > 0 || s.stiff_predictions > 0 {
        eprintln!(
            "step control: {} sub-steps for {} grid steps (smallest {:.3e} s; {} Newton failures and {} error rejections retried), {} joint-limit impacts, {} Newton matrices refactorised as an iterate crossed a limit, {} steps with the stiff-mode predictor",
            s.substeps,
            s.steps,
            s.smallest_step_s,
            s.step_failures,
            s.error_rejections,
            s.impacts,
            s.regime_refactorisations,
            s.stiff_predictions
        );
    }
    if s.limited_newton_updates > 0 {
        eprintln!(
            "contacts: {} Newton corrections shortened so as not to jump across the stiction band (docs/contacts.md §4)",
            s.limited_newton_updates
        );
    }
}

fn summary(
    robot: &str,
    trajectory: &Trajectory,
    limit_excursions: Vec<LimitExcursion>,
    wall_seconds: f64,
) -> Summary {
    let s = &trajectory.stats;
    let mut stats = serde_json::json!({
        "steps": s.steps,
        "newton_iterations": s.newton_iterations,
        "factorisations": s.factorisations,
        "refreshes": s.refreshes,
        "max_iterations_in_a_step": s.max_iterations_in_a_step,
        "substeps": s.substeps,
        "smallest_step_s": s.smallest_step_s,
        "step_failures": s.step_failures,
        "error_rejections": s.error_rejections,
        "impacts": s.impacts,
        "stiff_predictions": s.stiff_predictions,
        "partial": trajectory.partial,
        "state_rejections": s.state_rejections,
        "contacts": trajectory.contacts,
    });
    if s.regime_refactorisations > 0 {
        // Only with joint limits (docs/step-control.md §4); absent otherwise, as before.
        stats["regime_refactorisations"] = s.regime_refactorisations.into();
    }
    if trajectory.contacts.is_some() {
        // Only contacts limit Newton corrections (docs/contacts.md §4).
        stats["limited_newton_updates"] = s.limited_newton_updates.into();
    }
    Summary {
        robot: robot.to_string(),
        method: "nominal".to_string(),
        order: None,
        design: None,
        bound_kind: "nominal".to_string(),
        parameters: Vec::new(),
        sensitivities: None,
        samples: 1,
        excluded_samples: Vec::new(),
        retried_samples: Vec::new(),
        wall_seconds,
        outputs: trajectory
            .outputs
            .iter()
            .zip(&trajectory.values)
            .map(|(output, values)| EnvelopeSeries {
                name: output.name.clone(),
                unit: output.unit.to_string(),
                time: trajectory.times.clone(),
                lower: values.clone(),
                upper: values.clone(),
                nominal: values.clone(),
                error_estimate: None,
                outer_lower: None,
                outer_upper: None,
                runs_lower: None,
                runs_upper: None,
            })
            .collect(),
        stats,
        sobol_indices: None,
        limit_excursions,
    }
}

fn table(trajectory: &Trajectory) -> String {
    let width = crate::text::name_column_width(trajectory.outputs.iter().map(|o| o.name.as_str()));
    let mut text = format!(
        "{:<width$}  {:>8}  {:>13}  {:>13}  {:>13}  {:>13}\n",
        "output", "unit", "initial", "final", "min", "max"
    );
    for (output, values) in trajectory.outputs.iter().zip(&trajectory.values) {
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        text.push_str(&format!(
            "{:<width$}  {:>8}  {:>13.6e}  {:>13.6e}  {:>13.6e}  {:>13.6e}\n",
            output.name,
            output.unit,
            values.first().copied().unwrap_or(f64::NAN),
            values.last().copied().unwrap_or(f64::NAN),
            min,
            max
        ));
    }
    text
}
