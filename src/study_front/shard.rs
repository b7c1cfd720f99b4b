//! `run`: one shard of a planned study (docs/distributed.md §3) — the plan and its inputs
//! checked, the shard's range of the design's samples (and the nominal run in the first shard)
//! simulated into its record block `DIR/shard-K-of-N.records.mcap`, which appears only when the
//! shard is complete (written beside it and renamed); a re-run replaces only that shard's file. A
//! staged study's shard runs the last stage planned under DIR (or `--stage K`) into
//! `DIR/stage-K/shard-K-of-N.records.mcap` (docs/distributed.md §7).
//!
//! Does not: encode the record block (`distributed::RecordBlockWriter`).

use super::install_interrupt;
use super::options::{study_options, StudyRequest};
use super::plan_match::check_plan_matches;
use super::progress::ProgressReporter;
use super::run_study::prepare;
use crate::analysis::{DesignPartRequest, ForeignError, RecordSchedule, Study};
use crate::distributed::{
    shard_file_name, BlockHeader, BlockTrailer, PlanFile, RecordBlockWriter, ShardError, ShardSpec,
    Stage,
};
use crate::output::check_outputs;
use crate::Error;
use std::path::PathBuf;
use std::time::Instant;

/// What `run` is asked: the plan, which shard, where its record block goes, the stage, the
/// threads.
#[derive(Clone, Debug)]
pub struct ShardRequest {
    /// The plan file (from `ribbon plan`).
    pub plan: PathBuf,
    /// `--shard K/N`.
    pub shard: Option<String>,
    /// `--shards N`: K from the scheduler's index variable.
    pub shards: Option<usize>,
    /// The directory of the record blocks (created if missing).
    pub into: PathBuf,
    /// A staged study's stage to run, from 1 (`None`: the last one planned in `into`).
    pub stage: Option<usize>,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
}

/// Simulates one shard of a planned study into its record block (module documentation).
pub fn run_shard(args: &ShardRequest) -> Result<(), Error> {
    let started = Instant::now();
    let plan = PlanFile::read(&args.plan)?;
    let spec = match (&args.shard, args.shards) {
        (Some(text), None) => ShardSpec::parse(text)?,
        (None, Some(count)) => ShardSpec::from_environment(count, &|k| std::env::var(k).ok())?,
        (Some(_), Some(_)) => {
            return Err(ShardError::BadShard {
                flag: "--shards".to_string(),
                message: "give either --shard K/N or --shards N (K from the scheduler), not both"
                    .to_string(),
            }
            .into())
        }
        (None, None) => return Err(ShardError::BadShard {
            flag: "--shard".to_string(),
            message:
                "which shard? give --shard K/N (K from 0), or --shards N under Slurm or Kubernetes"
                    .to_string(),
        }
        .into()),
    };
    plan.body.urdf.check(&args.plan, "URDF")?;
    plan.body.sidecar.check(&args.plan, "sidecar")?;
    let request = StudyRequest::of_plan(&plan, args.threads);
    std::fs::create_dir_all(&args.into).map_err(|source| ShardError::Io {
        what: "create the shard directory",
        path: args.into.clone(),
        source,
    })?;
    // The stage to run: --stage, or the last one planned in DIR (stage 1 for a fixed design).
    let number = args
        .stage
        .unwrap_or_else(|| Stage::latest_number(&plan, &args.into));
    if number == 0 {
        return Err(ShardError::BadShard {
            flag: "--stage".to_string(),
            message: "stages are counted from 1".to_string(),
        }
        .into());
    }
    let stage = Stage::resolve(&plan, &args.plan, &args.into, number)?;
    std::fs::create_dir_all(&stage.directory).map_err(|source| ShardError::Io {
        what: "create the stage directory",
        path: stage.directory.clone(),
        source,
    })?;
    let path = stage.directory.join(shard_file_name(spec));
    check_outputs(
        &[
            ("URDF", plan.body.urdf.path.as_path()),
            ("sidecar", plan.body.sidecar.path.as_path()),
            ("plan", args.plan.as_path()),
        ],
        &[("--into", path.as_path())],
    )?;
    install_interrupt();
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
    check_plan_matches(&plan, &args.plan, &study, &study_plan)?;
    let points = &stage.points;
    let range = spec.samples(stage.samples);
    let with_nominal = spec.runs_nominal() && stage.nominal;
    let schedule = RecordSchedule::of(&setup.scene);
    let n_outputs = setup.scene.outputs.len();
    let header = BlockHeader {
        plan_hash: stage.hash.clone(),
        shard: spec.index,
        shards: spec.count,
        first_sample: range.start,
        end_sample: range.end,
        nominal: with_nominal,
        outputs: n_outputs,
        records: schedule.len(),
        nq: setup.model.nq,
    };
    eprintln!(
        "run: shard {}/{} of {}{}: samples {}..{}{} of {}, {} record times",
        spec.index,
        spec.count,
        if stage.staged {
            format!("stage {} ", stage.number)
        } else {
            String::new()
        },
        stage.hash,
        range.start,
        range.end,
        if with_nominal {
            " and the nominal run"
        } else {
            ""
        },
        stage.samples,
        schedule.len()
    );
    let mut writer = RecordBlockWriter::create(&path, header)?;
    let part_samples = range.len();
    let mut row: Vec<f64> = Vec::with_capacity(part_samples * n_outputs);
    let mut reporter = ProgressReporter::new();
    let part = study.simulate_design_part(
        &study_plan,
        DesignPartRequest {
            points,
            range: range.clone(),
            with_nominal,
        },
        crate::interrupt::flag(),
        &mut |progress| reporter.report(progress),
        &mut |first, count, records| {
            for r in 0..count {
                row.clear();
                for i in 0..part_samples {
                    if records.failed(i) {
                        // Left out by the merge from this block on, as by `analyze`.
                        row.extend(std::iter::repeat_n(0.0, n_outputs));
                    } else {
                        row.extend_from_slice(records.record(i, r));
                    }
                }
                let nominal = records
                    .nominal_index()
                    .map(|n| (records.record(n, r), records.nominal_positions(r)));
                writer
                    .write_record(schedule.time(first + r), &row, nominal)
                    .map_err(ForeignError::new)?;
            }
            Ok(())
        },
    )?;
    reporter.finish();
    if !part.complete {
        return Err(Error::Interrupted(format!(
            "shard {}/{} stopped before the end; no record block was written (run it again)",
            spec.index, spec.count
        )));
    }
    let failures = part.failures.len();
    let retried = part.retried.len();
    writer.finish(&BlockTrailer {
        complete: true,
        failures: part.failures,
        retried: part.retried,
        newton_iterations: part.newton_iterations,
        steps: part.steps,
        contacts: part.contacts,
    })?;
    let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "run: wrote {} ({size} bytes): {} runs, {} steps, {failures} samples excluded{}; simulate {:.3} s, wall {:.3} s",
        path.display(),
        part_samples + usize::from(with_nominal),
        part.steps,
        if retried > 0 {
            format!(", {retried} re-run with the adaptive step")
        } else {
            String::new()
        },
        part.simulate_seconds,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
