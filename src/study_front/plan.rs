//! `plan`: the first stage of a distributed study (docs/distributed.md §2, §6): the plan file
//! (the inputs' hashes, the options as given, the box, the design's sample list — or a staged
//! design's first stage, found by running the study until it needs records — and the record
//! schedule), written atomically; then one line on stdout with the runs, the record-block bytes
//! and the expected wall time per shard from a short calibration run.
//!
//! Does not: simulate the design (`run` does), or encode the plan file (`distributed::PlanFile`).

use super::options::{study_options, StudyRequest};
use super::run_study::prepare;
use crate::analysis::{
    BlockOutcome, FirstStage, PendingStage, RecordSchedule, Study, StudyError, StudyPlan,
};
use crate::distributed::{InputFile, PlanBody, PlanFile, StagedDesign};
use crate::output::{check_command_outputs, write_atomically, write_stdout};
use crate::Error;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Steps of each calibration run (fewer when the horizon is shorter).
pub const CALIBRATION_STEPS: usize = 500;
/// Repetitions of the calibration; the fastest counts (a shared machine's load only slows runs
/// down).
pub const CALIBRATION_REPEATS: usize = 3;
/// Design samples the calibration runs, spread over the sample list (corners of the box can need
/// more Newton iterations than its centre).
pub const CALIBRATION_RUNS: usize = 4;
/// Shard counts the plan line estimates the wall time for.
const ESTIMATED_SHARD_COUNTS: [usize; 4] = [1, 4, 16, 64];
/// Bytes of an MCAP message record besides its data (opcode, length, channel, sequence, times).
const MESSAGE_OVERHEAD_BYTES: u64 = 9 + 2 + 4 + 8 + 8;

/// Plans `request`'s study into the plan file `plan_path` (module documentation).
pub fn plan_study(request: &StudyRequest, plan_path: &Path) -> Result<(), Error> {
    let outputs = &request.outputs;
    for (flag, given) in [
        ("--summary", outputs.summary.is_some()),
        ("--csv", outputs.csv.is_some()),
        ("--out", outputs.out.is_some()),
        ("--report", outputs.report.is_some()),
    ] {
        if given {
            return Err(Error::BadArgument {
                flag: flag.to_string(),
                message: "outputs are written by `ribbon merge PLAN DIR`, not by `plan`; give the flag to merge".to_string(),
            });
        }
    }
    let sidecar_path = request.scene.sidecar_path();
    check_command_outputs(
        &request.scene.urdf,
        Some(&sidecar_path),
        &[("--plan", Some(plan_path))],
    )?;
    let setup = prepare(&request.scene)?;
    let options = study_options(&request.flags, &setup.sidecar.analysis)?;
    let study = Study::new(
        &setup.model,
        &setup.environment,
        &setup.scene,
        &setup.space,
        options,
    );
    let study_plan = study.plan()?;
    // A design that chooses runs from earlier runs (screened, adaptive) runs in stages: the plan
    // holds stage 1, as far as the study gets without any record (docs/distributed.md §7).
    let (points, staged) = match study.design_points(&study_plan) {
        Some(points) => (points, None),
        None => {
            let first = first_stage(&study, &study_plan)?;
            let staged = StagedDesign {
                phase: first.phase.to_string(),
                nominal: first.nominal,
            };
            (first.points, Some(staged))
        }
    };
    let d = setup.space.len();
    let schedule = RecordSchedule::of(&setup.scene);
    let samples = points.len() / d.max(1);
    let body = PlanBody {
        urdf: InputFile::of(&request.scene.urdf)?,
        sidecar: InputFile::of(&sidecar_path)?,
        options: request.plan_options(),
        method: study_plan.method.name().to_string(),
        design: study_plan.design_name.to_string(),
        parameters: setup
            .space
            .dimensions()
            .iter()
            .map(|dim| dim.name.clone())
            .collect(),
        outputs: setup.scene.outputs.iter().map(|o| o.name.clone()).collect(),
        nq: setup.model.nq,
        n_steps: schedule.n_steps,
        record_every: schedule.record_every,
        step_s: schedule.step_s(),
        records: schedule.len(),
        samples,
        points_xi: points.chunks(d.max(1)).map(<[f64]>::to_vec).collect(),
        nominal_xi: setup.space.nominal_xi(),
        check_runs: study_plan.check_runs,
        staged: staged.clone(),
    };
    let plan = PlanFile::new(body);
    write_atomically(plan_path, "plan", plan.to_json().as_bytes())?;

    // The cost model: record-block bytes exactly (besides a few kB of headers per shard), and
    // the wall time from the nominal run's first steps on one core.
    let n_outputs = setup.scene.outputs.len() as u64;
    let records = schedule.len() as u64;
    let nominal_run = staged.as_ref().is_none_or(|s| s.nominal);
    let data_bytes = records
        * if nominal_run {
            2 * MESSAGE_OVERHEAD_BYTES
                + 8 * (samples as u64 * n_outputs + n_outputs + setup.model.nq as u64)
        } else {
            MESSAGE_OVERHEAD_BYTES + 8 * samples as u64 * n_outputs
        };
    let mut seconds_per_step = f64::INFINITY;
    for _ in 0..CALIBRATION_REPEATS {
        seconds_per_step = seconds_per_step.min(calibrate(&study, &schedule, &points)?);
    }
    let run_seconds = seconds_per_step * schedule.n_steps as f64;
    let per_shard: Vec<String> = ESTIMATED_SHARD_COUNTS
        .iter()
        .map(|&n| {
            let runs = samples.div_ceil(n) + usize::from(nominal_run);
            format!("N={n}: {}", duration(runs as f64 * run_seconds))
        })
        .collect();
    let runs_text = match &staged {
        None => format!("{samples} design runs + the nominal run in shards"),
        Some(s) => format!(
            "stage 1 of the staged {} design: {samples} {} runs{} in shards, then `merge` plans each later stage from the records before it (up to {} design runs in all)",
            study_plan.design_name,
            s.phase,
            if nominal_run { " + the nominal run" } else { "" },
            study_plan.screening_runs + study_plan.design_runs.saturating_sub(1)
        ),
    };
    write_stdout(&format!(
        "plan {}: {runs_text} (merge adds up to {} check runs and 2 chaos runs), {} record times of {} outputs; record blocks {} in all (+ ~2 kB per shard); calibration {:.3e} s per step per run ⇒ expected wall time per shard on one core: {}; written to {}\n",
        plan.plan_hash,
        study_plan.check_runs,
        records,
        n_outputs,
        bytes(data_bytes),
        seconds_per_step,
        per_shard.join(", "),
        plan_path.display()
    ))?;
    Ok(())
}

/// Stage 1 of a staged design: the study run with no records at all stops at its first stage,
/// naming its points — the same code that chooses them in `analyze`.
fn first_stage(study: &Study, study_plan: &StudyPlan) -> Result<PendingStage, Error> {
    let interrupt = AtomicBool::new(false);
    match study.run_stages(
        study_plan.clone(),
        &mut FirstStage,
        &interrupt,
        &mut |_| {},
        &mut |_| Ok(()),
    ) {
        Err(StudyError::StageNeeded(pending)) => Ok(*pending),
        Err(other) => Err(other.into()),
        Ok(_) => Err(Error::Study(StudyError::BadOptions(format!(
            "internal: the {} design ran without a stage",
            study_plan.design_name
        )))),
    }
}

/// Seconds per integrator step of one run: [`CALIBRATION_RUNS`] design samples spread over the
/// sample list, through their first [`CALIBRATION_STEPS`] steps after their start, on one thread
/// (0 when every one of them fails).
fn calibrate(study: &Study, schedule: &RecordSchedule, points: &[f64]) -> Result<f64, Error> {
    let d = study.space.len().max(1);
    let samples = points.len() / d;
    let runs = CALIBRATION_RUNS.min(samples).max(1);
    let chosen: Vec<f64> = (0..runs)
        .flat_map(|k| {
            let i = k * samples.saturating_sub(1) / (runs - 1).max(1);
            points[i * d..(i + 1) * d].iter().copied()
        })
        .collect();
    let mut lockstep = study.lockstep(&chosen, None);
    let threads = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| StudyError::Threads {
            threads: 1,
            message: e.to_string(),
        })?;
    // Record 0 holds the consistent start (a one-off cost per run, not per step): timed apart.
    let interrupt = AtomicBool::new(false);
    let start = lockstep.advance(0, 1, &threads, &interrupt);
    let records = (CALIBRATION_STEPS.div_ceil(schedule.record_every) + 1).min(schedule.len());
    let started = Instant::now();
    let outcome = if records > 1 {
        lockstep.advance(1, records - 1, &threads, &interrupt)
    } else {
        start
    };
    let seconds = started.elapsed().as_secs_f64();
    let steps = (schedule.step_of(records - 1) * runs).max(1);
    // A sample that fails (possible with --keep-going) stops early: its steps are not counted.
    if start != BlockOutcome::Complete || outcome != BlockOutcome::Complete {
        return Err(Error::Interrupted(
            "internal: the calibration runs did not finish".to_string(),
        ));
    }
    let failed = lockstep.failures().len();
    if failed == runs {
        return Ok(0.0);
    }
    let steps = (steps / runs * (runs - failed)).max(1);
    Ok(seconds / steps as f64)
}

fn duration(seconds: f64) -> String {
    if seconds < 10.0 {
        format!("{seconds:.3} s")
    } else if seconds < 120.0 {
        format!("{seconds:.1} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

fn bytes(n: u64) -> String {
    let n = n as f64;
    if n < 1e6 {
        format!("{:.1} kB", n / 1e3)
    } else if n < 1e9 {
        format!("{:.1} MB", n / 1e6)
    } else {
        format!("{:.2} GB", n / 1e9)
    }
}
